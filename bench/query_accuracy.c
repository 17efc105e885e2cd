/* Recognition accuracy (seed 000, Section 4.2; issue 4): leave one subject
 * out on synth (generated here, 8 subjects x 12 poses) and on
 * ../shared/data/mh-bodies when present. For each subject, the index is
 * built from the other subjects only (feature selection, SVM
 * cross-validation and all), and each of the subject's meshes is queried
 * with its landmarks; a hit is a first result whose pose label is the true
 * one. Reported in the same run: mimic (descriptor + SVM + k-NN) at d = 20,
 * 40, 60, 70; the baseline plain 1-NN over all candidate angles; Gaussian
 * landmark noise of 1 cm and 3 cm (sigma per coordinate); 1, 2 and 3
 * missing landmarks (random, several draws per frame).
 *
 * Issue 15 adds the hard set (hard_set.c: 8 synth subjects x 40 poses, 5
 * designed poses each with 7 variants that turn one or two joints by 12-20
 * degrees, every body with its own +-3 degree jitter) at 0, 1, 2 and 3 cm
 * of noise and 1-3 missing landmarks, columns: mimic's default index
 * (noise augmentation, angle weighting, k-NN vote, shape discriminants
 * for every frame), the same answering by its SVMs alone, the angle
 * discriminants (the default before, whole frames), the index of
 * item 1 (augmentation only) and the index without noise augmentation
 * (issue 4's), the 1-NN baseline; --sweep 1 / 2 (item
 * 1: augmentation, d) and 3 / 4 (item 2: the vote, the weighting) run the
 * other settings measured for the choices. Columns with the same build
 * options share one index per fold; every run draws the same frames, so
 * columns of different runs compare. Per fold, stderr gets each index's
 * C, gamma, cross-validation accuracy and build time.
 * The issue-4 sets run with the default index at d = 20, 40, 60, 70.
 *
 * Every row also gets the Bayes bound (own_nearest): what a classifier
 * that knew the query subject's own bodies and the noise would score, the
 * ceiling no method can pass. --hard-spread F scales the variants' turns
 * (F = 2: 24-40 degrees apart); --sweep 5 runs the default index alone
 * (its discriminants and its SVMs) and the angle discriminants, --sweep 6
 * no index (baseline and bounds only), --sweep 7 the shape and the angle
 * discriminants alone (C and gamma given: fast). --proportions body builds
 * every index without the landmark skeleton, so that frames keep their
 * bodies' proportions (the default before canonical proportions). On the hard set two
 * references have the jitter unknown (jitter_ml, from --jitters D other
 * jitters of every body, default 128; 0 leaves them out).
 *
 *   bench_query_accuracy [--draws N] [--no-mh] [--no-hard | --hard-only] [--sweep 1-7]
 *                        [--proportions canonical|body]
 *                        [--hard-subjects S] [--hard-poses P] [--hard-spread F] [--jitters D]
 * Prints a Markdown table per dataset. */
#include "bench_data.h"
#include "hard_set.h"
#include "mim_index.h"

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_COND = 8, MAX_METHOD = 24 };

/* A condition: Gaussian noise of sigma (metres, per coordinate) or some
 * missing landmarks. */
typedef struct {
    const char *name;
    double sigma;
    uint32_t missing;
} cond_t;
static const cond_t cond_issue4[] = {{"no noise", 0, 0},  {"noise 1 cm", 0.01, 0}, {"noise 3 cm", 0.03, 0},
                                     {"1 missing", 0, 1}, {"2 missing", 0, 2},     {"3 missing", 0, 3}};
static const cond_t cond_hard[] = {{"no noise", 0, 0},   {"noise 1 cm", 0.01, 0}, {"noise 2 cm", 0.02, 0},
                                   {"noise 3 cm", 0.03, 0}, {"1 missing", 0, 1},   {"2 missing", 0, 2},
                                   {"3 missing", 0, 3}};

/* A column: mimic's index built with these options. */
typedef struct {
    const char *label;
    mim_index_options_t o;
    mim_index_query_options_t q; /* k is always 1; a column whose build options equal an earlier column's
                                    queries that column's index */
} method_t;
static const method_t methods_issue4[] = {{"d = 20", {.features = 20}, {0}},
                                          {"d = 40", {.features = 40}, {0}},
                                          {"d = 60", {.features = 60}, {0}},
                                          {"d = 70", {.features = 70}, {0}}};
/* The hard set: the default index (with and without the k-NN vote), the
 * index of issue 15's item 1 (augmentation, no angle weighting, no vote),
 * the issue-4 index (no augmentation), and with --sweep the other settings
 * measured for issue 15. Sweeps 1 and 2 (item 1: the augmentation, d) run
 * without the weighting and the vote, as they were measured. */
#define NOVOTE {.vote_below = -1}
#define VOTE(b, k, t) {.vote_below = b, .vote_k = k, .vote_classes = t}
static const method_t methods_hard[] = {
    {"default (d = 60, noise 0.025 x4, weight 0.5, vote < 0.5, shape discriminants)", {0}, {0}},
    {"without the discriminants (SVMs, vote < 0.5)", {0}, {.svm_above = -1}},
    {"angle discriminants (the default before)",
     {.shape_noise = -1, .discriminant_noise = MIM_INDEX_DISCRIMINANT_NOISE_MEASURED},
     {0}},
    {"no weighting, no vote (item 1)", {.weight = -1, .shape_noise = -1}, NOVOTE},
    {"no augmentation (issue 4)", {.noise = -1, .shape_noise = -1}, NOVOTE}};
/* the discriminants alone, fast (C and gamma given: no cross-validation;
 * the SVMs are not asked) */
static const method_t methods_sweep7[] = {
    {"shape discriminants", {.C = 100, .gamma = 0.2}, {0}},
    {"angle discriminants",
     {.C = 100, .gamma = 0.2, .shape_noise = -1, .discriminant_noise = MIM_INDEX_DISCRIMINANT_NOISE_MEASURED},
     {0}},
};
static const method_t methods_sweep1[] = {
    {"default (d = 60, noise 0.025 x4)", {.weight = -1, .shape_noise = -1}, NOVOTE},
    {"no augmentation (issue 4)", {.noise = -1, .shape_noise = -1}, NOVOTE},
    {"noise 0.05 x4", {.noise = 0.05, .augment = 4, .weight = -1, .shape_noise = -1}, NOVOTE},
    {"noise 0.075 x4", {.noise = 0.075, .augment = 4, .weight = -1, .shape_noise = -1}, NOVOTE},
    {"noise 0.05 x2", {.noise = 0.05, .augment = 2, .weight = -1, .shape_noise = -1}, NOVOTE},
};
static const method_t methods_sweep2[] = {
    {"d = 40 augmented", {.features = 40, .weight = -1, .shape_noise = -1}, NOVOTE},
    {"d = 100 augmented", {.features = 100, .weight = -1, .shape_noise = -1}, NOVOTE},
    {"d = 100, no augmentation", {.features = 100, .noise = -1, .shape_noise = -1}, NOVOTE},
    {"d = 20 augmented", {.features = 20, .weight = -1, .shape_noise = -1}, NOVOTE},
};
/* issue 15, item 2: the k-NN vote's settings, on the index without weighting */
static const method_t methods_sweep3[] = {
    {"no vote", {.weight = -1, .shape_noise = -1}, NOVOTE},
    {"vote < 0.5 k5 T3", {.weight = -1, .shape_noise = -1}, VOTE(0.5, 5, 3)},
    {"vote < 0.5 k1 T3", {.weight = -1, .shape_noise = -1}, VOTE(0.5, 1, 3)},
    {"vote < 0.3 k5 T3", {.weight = -1, .shape_noise = -1}, VOTE(0.3, 5, 3)},
    {"vote < 0.7 k5 T3", {.weight = -1, .shape_noise = -1}, VOTE(0.7, 5, 3)},
    {"vote always k5 T3", {.weight = -1, .shape_noise = -1}, VOTE(2, 5, 3)},
    {"vote < 0.5 k9 T5", {.weight = -1, .shape_noise = -1}, VOTE(0.5, 9, 5)},
};
/* issue 15, item 2: the angle weighting's power, with and without the vote */
static const method_t methods_sweep4[] = {
    {"no weighting, no vote", {.weight = -1, .shape_noise = -1}, NOVOTE},
    {"weight 0.5, no vote", {.weight = 0.5, .shape_noise = -1}, NOVOTE},
    {"weight 0.75, no vote", {.weight = 0.75, .shape_noise = -1}, NOVOTE},
    {"weight 1, no vote", {.weight = 1, .shape_noise = -1}, NOVOTE},
    {"no weighting, vote < 0.5 k5 T3", {.weight = -1, .shape_noise = -1}, VOTE(0.5, 5, 3)},
    {"weight 0.5, vote < 0.5 k5 T3 (default)", {.weight = 0.5, .shape_noise = -1}, VOTE(0.5, 5, 3)},
    {"weight 0.75, vote < 0.5 k5 T3", {.weight = 0.75, .shape_noise = -1}, VOTE(0.5, 5, 3)},
};

static uint64_t rng_state = 12345;
static double uniform(void)
{
    rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return ((rng_state >> 11) + 0.5) / 9007199254740992.0;
}
static double gauss(void) { return sqrt(-2 * log(uniform())) * cos(2 * M_PI * uniform()); }

/* A query frame for condition c: noise or missing landmarks. */
static void make_frame(const float *lm, uint32_t L, const cond_t *c, float *out, uint8_t *present)
{
    memcpy(out, lm, sizeof(float) * 3 * L);
    memset(present, 1, L);
    if (c->sigma > 0)
        for (uint32_t i = 0; i < 3 * L; i++) out[i] += (float)(c->sigma * gauss());
    for (uint32_t m = 0; m < c->missing;) {
        uint32_t l = (uint32_t)(uniform() * L) % L;
        if (!present[l]) continue;
        present[l] = 0;
        out[3 * l] = out[3 * l + 1] = out[3 * l + 2] = NAN;
        m++;
    }
}

/* Plain 1-NN over all candidate angles (NaN angles of the query left out,
 * the partial distance rescaled). */
static uint32_t nn_all(const float *angles, const uint32_t *train, uint32_t ntrain, uint32_t nf, const float *q)
{
    double best = INFINITY;
    uint32_t arg = 0;
    for (uint32_t i = 0; i < ntrain; i++) {
        const float *a = angles + (size_t)train[i] * nf;
        double s = 0;
        uint32_t used = 0;
        for (uint32_t f = 0; f < nf; f++) {
            if (isnan(q[f]) || isnan(a[f])) continue;
            s += (double)(q[f] - a[f]) * (q[f] - a[f]);
            used++;
        }
        s = used ? s * nf / used : INFINITY;
        if (s < best) best = s, arg = train[i];
    }
    return arg;
}

/* The Bayes bound: the pose of the query subject's own body (of the P it
 * was drawn from, noiseless) nearest the frame in landmark space, over the
 * present landmarks. With Gaussian noise of one sigma on every coordinate
 * and the poses equally likely, this is the maximum-likelihood decision
 * with everything known (the subject's exact bodies, the noise model), so
 * no classifier of single frames beats it in expectation: its accuracy is
 * the ceiling of a row. */
static uint32_t own_nearest(const float *lm, uint32_t s, uint32_t P, uint32_t L, const float *frame,
                            const uint8_t *present)
{
    double best = INFINITY;
    uint32_t arg = 0;
    for (uint32_t p = 0; p < P; p++) {
        const float *b = lm + 3 * (size_t)L * (s * P + p);
        double d2 = 0;
        for (uint32_t l = 0; l < L; l++)
            if (present[l])
                for (int c = 0; c < 3; c++) d2 += (double)(frame[3 * l + c] - b[3 * l + c]) * (frame[3 * l + c] - b[3 * l + c]);
        if (d2 < best) best = d2, arg = p;
    }
    return arg;
}

/* Two references with the jitter unknown (the hard set only), from D
 * other jitters of every body: each body's landmarks as a Gaussian (the
 * draws' mean and covariance: the jitter's spread through the skinning,
 * linear for +-3 degrees), plus the frame's noise sigma (with a 5 mm floor,
 * so that a noiseless frame still has a likelihood) on every coordinate,
 * marginalised to the present landmarks. own != 0: the query subject's
 * body in each pose (its proportions known, not its jitter): the
 * maximum-likelihood pose under that model. own == 0: an equal mixture of
 * the other subjects' bodies in each pose (what a classifier that knew the
 * generator and the training subjects exactly, but not the query's body,
 * would decide; a reference, not a proof, since the population is those
 * S - 1 subjects). */
typedef struct {
    uint32_t S, P, L, D;
    double *mean, *cov; /* per body (s * P + p): [3L], [3L x 3L] */
} jitter_model_t;

static void jitter_model_make(jitter_model_t *m, const float *redrawn, uint32_t D, uint32_t S, uint32_t P, uint32_t L)
{
    uint32_t n = 3 * L;
    m->S = S, m->P = P, m->L = L, m->D = D;
    m->mean = calloc((size_t)S * P * n, sizeof(double));
    m->cov = calloc((size_t)S * P * n * n, sizeof(double));
    for (size_t t = 0; t < (size_t)S * P; t++) {
        double *mu = m->mean + t * n, *C = m->cov + t * n * n;
        for (uint32_t d = 0; d < D; d++)
            for (uint32_t i = 0; i < n; i++) mu[i] += redrawn[(t * D + d) * n + i] / D;
        for (uint32_t d = 0; d < D; d++) {
            const float *x = redrawn + (t * D + d) * n;
            for (uint32_t i = 0; i < n; i++)
                for (uint32_t j = 0; j < n; j++) C[i * n + j] += (x[i] - mu[i]) * (x[j] - mu[j]) / (D - 1);
        }
    }
}

static void jitter_model_free(jitter_model_t *m) { free(m->mean), free(m->cov); }

/* log N(frame; body t's Gaussian + var I) over the present coordinates, up
 * to the constant every pose shares. */
static double jitter_loglik(const jitter_model_t *m, size_t t, const float *frame, const uint8_t *present, double var)
{
    uint32_t n = 3 * m->L, k = 0, idx[3 * MIM_LANDMARKS_MAX];
    for (uint32_t i = 0; i < n; i++)
        if (present[i / 3]) idx[k++] = i;
    double A[(3 * MIM_LANDMARKS_MAX) * (3 * MIM_LANDMARKS_MAX)], r[3 * MIM_LANDMARKS_MAX];
    const double *mu = m->mean + t * n, *C = m->cov + t * n * n;
    for (uint32_t a = 0; a < k; a++) {
        r[a] = frame[idx[a]] - mu[idx[a]];
        for (uint32_t b = 0; b < k; b++) A[a * k + b] = C[idx[a] * n + idx[b]] + (a == b ? var : 0);
    }
    if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', (lapack_int)k, A, (lapack_int)k)) return -INFINITY;
    double logdet = 0, q = 0;
    for (uint32_t a = 0; a < k; a++) { /* forward substitution: L z = r, q = |z|^2 */
        double z = r[a];
        for (uint32_t b = 0; b < a; b++) z -= A[a * k + b] * r[b];
        r[a] = z / A[a * k + a];
        q += r[a] * r[a], logdet += 2 * log(A[a * k + a]);
    }
    return -0.5 * (q + logdet);
}

static uint32_t jitter_ml(const jitter_model_t *m, uint32_t s, int own, const float *frame, const uint8_t *present,
                          double sigma)
{
    double var = sigma * sigma + 0.005 * 0.005, best = -INFINITY;
    uint32_t arg = 0;
    for (uint32_t p = 0; p < m->P; p++) {
        double mx = -INFINITY, sum = 0; /* log of the mixture's sum, one pass */
        for (uint32_t o = own ? s : 0; o < (own ? s + 1 : m->S); o++) {
            if (!own && o == s) continue;
            double e = jitter_loglik(m, (size_t)o * m->P + p, frame, present, var);
            if (e > mx) sum = sum * exp(mx - e) + 1, mx = e;
            else sum += exp(e - mx);
        }
        double ll = mx + log(sum);
        if (ll > best) best = ll, arg = p;
    }
    return arg;
}

/* One set: S subjects x P poses of L landmarks (lm, [(s * P + p) * L * 3]). */
typedef struct {
    const char *name;
    uint32_t S, P, L;
    const float *lm;
    const float *redrawn; /* hard set: D other jitters of every body (jitter_ml), or NULL */
    uint32_t D;
    const uint32_t *mirror;
    const int32_t *parent; /* the landmark skeleton, or NULL */
    const cond_t *cond;
    int n_cond;
    const method_t *method;
    int n_method;
} set_t;

/* --proportions body: the indexes take each body as it is (no skeleton) */
static int body_proportions;

static void run_set(const set_t *set, int draws)
{
    uint32_t S = set->S, P = set->P, n = S * P, L = set->L, nf = mim_index_angle_count(L);
    int NC = set->n_cond, NM = set->n_method;
    const float *lm = set->lm;
    float *angles = malloc(sizeof(float) * (size_t)n * nf);
    char (*subj)[16] = malloc(16 * n), (*pose)[16] = malloc(16 * n);
    const char **sp = malloc(sizeof(char *) * n), **pp = malloc(sizeof(char *) * n);
    uint64_t *ids = malloc(sizeof(uint64_t) * n);
    uint32_t *train = malloc(sizeof(uint32_t) * n);
    float ymin = INFINITY, ymax = -INFINITY;
    for (uint32_t t = 0; t < n; t++) {
        for (uint32_t l = 0; l < L; l++) {
            float y = lm[3 * (L * t + l) + 1];
            ymin = y < ymin ? y : ymin, ymax = y > ymax ? y : ymax;
        }
        snprintf(subj[t], 16, "s%u", t / P);
        snprintf(pose[t], 16, "p%u", t % P);
        sp[t] = subj[t], pp[t] = pose[t], ids[t] = t + 1;
        mim_index_angles(lm + 3 * L * t, NULL, L, angles + (size_t)t * nf);
    }
    fprintf(stderr, "%s: %u subjects x %u poses, %u landmarks, landmark height span %.2f (units: metres)\n", set->name,
            S, P, L, ymax - ymin);
    /* hits[method][cond] (then the 1-NN, the Bayes bound and the two
     * jitter-unknown bounds), tests[cond] */
    double hits[MAX_METHOD + 4][MAX_COND] = {{0}}, tests[MAX_COND] = {0}, cv[MAX_METHOD] = {0}, lc[MAX_METHOD] = {0};
    double build_s[MAX_METHOD] = {0}, qtime[MAX_METHOD] = {0}, nq[MAX_METHOD] = {0};
    float *frame = malloc(sizeof(float) * 3 * L), *qa = malloc(sizeof(float) * nf);
    uint8_t *present = malloc(L);
    jitter_model_t jm = {0};
    if (set->redrawn) jitter_model_make(&jm, set->redrawn, set->D, S, P, L);
    for (uint32_t s = 0; s < S; s++) {
        uint32_t ntrain = 0;
        for (uint32_t t = 0; t < n; t++)
            if (t / P != s) train[ntrain++] = t;
        /* training set for the index: the other subjects */
        float *tlm = malloc(sizeof(float) * 3 * L * ntrain);
        const char **tsp = malloc(sizeof(char *) * ntrain), **tpp = malloc(sizeof(char *) * ntrain);
        uint64_t *tid = malloc(sizeof(uint64_t) * ntrain);
        for (uint32_t i = 0; i < ntrain; i++) {
            memcpy(tlm + 3 * L * i, lm + 3 * L * train[i], sizeof(float) * 3 * L);
            tsp[i] = sp[train[i]], tpp[i] = pp[train[i]], tid[i] = ids[train[i]];
        }
        mim_index_t *ix[MAX_METHOD] = {0};
        int same[MAX_METHOD];
        for (int mi = 0; mi < NM; mi++) {
            same[mi] = mi;
            for (int mj = 0; mj < mi; mj++)
                if (same[mi] == mi && !memcmp(&set->method[mi].o, &set->method[mj].o, sizeof set->method[mi].o))
                    same[mi] = mj;
            if (same[mi] != mi) {
                build_s[mi] = build_s[same[mi]], cv[mi] = cv[same[mi]], lc[mi] = lc[same[mi]];
                continue;
            }
            mim_index_input_t in = {ntrain, L, tlm, tid, tsp, tpp, set->mirror,
                                    body_proportions ? NULL : set->parent};
            mim_index_report_t rep;
            mim_error_t err = {0};
            if (mim_index_build(&ix[mi], &in, &set->method[mi].o, &rep, &err)) {
                fprintf(stderr, "%s: build failed: %s\n", set->name, mim_error_text(&err));
                exit(2);
            }
            fprintf(stderr, "fold %u: %s: C %g gamma %.4g cv %.3f, %.1f s\n", s, set->method[mi].label, rep.C, rep.gamma,
                    rep.cv_accuracy, rep.seconds);
            build_s[mi] += rep.seconds / S;
            cv[mi] += rep.cv_accuracy / S;
            lc[mi] += log10(rep.C) / S;
        }
        for (uint32_t p = 0; p < P; p++) {
            uint32_t t = s * P + p;
            for (int c = 0; c < NC; c++) {
                int nd = set->cond[c].sigma > 0 || set->cond[c].missing ? draws : 1;
                for (int r = 0; r < nd; r++) {
                    make_frame(lm + 3 * L * t, L, &set->cond[c], frame, present);
                    tests[c]++;
                    for (int mi = 0; mi < NM; mi++) {
                        mim_index_query_options_t qo = set->method[mi].q;
                        qo.k = 1;
                        mim_index_answer_t a;
                        mim_index_hit_t h;
                        mim_error_t err = {0};
                        double tq = mim_now();
                        int qrc = mim_index_query(ix[same[mi]], frame, present, &qo, &a, &h, &err);
                        qtime[mi] += mim_now() - tq, nq[mi]++;
                        if (qrc == 0 && a.n_hits)
                            hits[mi][c] += !strcmp(h.pose, pose[t]);
                    }
                    mim_index_angles(frame, present, L, qa);
                    uint32_t arg = nn_all(angles, train, ntrain, nf, qa);
                    hits[NM][c] += !strcmp(pose[arg], pose[t]);
                    hits[NM + 1][c] += own_nearest(lm, s, P, L, frame, present) == p;
                    if (set->redrawn) {
                        double sg = set->cond[c].sigma;
                        hits[NM + 2][c] += jitter_ml(&jm, s, 1, frame, present, sg) == p;
                        hits[NM + 3][c] += jitter_ml(&jm, s, 0, frame, present, sg) == p;
                    }
                }
            }
        }
        for (int mi = 0; mi < NM; mi++) mim_index_close(&ix[mi]);
        free(tlm), free(tsp), free(tpp), free(tid);
    }
    printf("\n### %s (%u subjects x %u poses, leave one subject out, %d draws per noisy/missing frame; %s "
           "proportions)\n\n",
           set->name, S, P, draws, body_proportions || !set->parent ? "the bodies'" : "canonical");
    printf("| condition |");
    for (int mi = 0; mi < NM; mi++) printf(" %s |", set->method[mi].label);
    printf(" 1-NN, all %u angles | Bayes bound (own bodies known) |", nf);
    int nb = set->redrawn ? 2 : 0;
    if (nb)
        printf(" own proportions, jitter unknown (%u draws) | other subjects' bodies, jitter unknown |", set->D);
    printf("\n|---|");
    for (int mi = 0; mi <= NM + 1 + nb; mi++) printf("---|");
    printf("\n");
    for (int c = 0; c < NC; c++) {
        printf("| %s |", set->cond[c].name);
        for (int m = 0; m <= NM + 1 + nb; m++) printf(" %.3f |", hits[m][c] / tests[c]);
        printf("\n");
    }
    printf("\nPer column: mean cross-validation accuracy of the SVMs on the training subjects; mean log10(C); mean "
           "build (s):");
    for (int mi = 0; mi < NM; mi++)
        printf("%s %s %.3f / %.2f / %.3f", mi ? ";" : "", set->method[mi].label, cv[mi], lc[mi], build_s[mi]);
    printf(".\n\nMean query (us, all conditions):");
    for (int mi = 0; mi < NM; mi++) printf("%s %s %.1f", mi ? ";" : "", set->method[mi].label, 1e6 * qtime[mi] / nq[mi]);
    printf(".\n");
    fflush(stdout);
    free(angles), free(subj), free(pose), free(sp), free(pp), free(ids), free(train), free(frame), free(qa);
    free(present);
    jitter_model_free(&jm);
}

/* A body dataset's landmarks, for run_set. */
static float *dataset_landmarks(const bench_dataset_t *d)
{
    uint32_t n = d->subjects * d->poses, L = d->map.count;
    float *lm = malloc(sizeof(float) * 3 * L * n);
    for (uint32_t t = 0; t < n; t++)
        for (uint32_t l = 0; l < L; l++) memcpy(lm + 3 * (L * t + l), d->pos[t] + 3 * d->map.vertex[l], 12);
    return lm;
}

static void run_dataset(const char *name, bench_dataset_t *d, int draws)
{
    float *lm = dataset_landmarks(d);
    int32_t parent[MIM_LANDMARKS_MAX];
    const int skeleton = !mim_index_skeleton(&d->map, parent);
    set_t set = {name,         d->subjects,   d->poses, d->map.count, lm, NULL, 0, d->map.mirror,
                 skeleton ? parent : NULL, cond_issue4, 6, methods_issue4, 4};
    run_set(&set, draws);
    free(lm);
}

static int run_hard(uint32_t S, uint32_t P, double spread, int sweep, int draws, uint32_t jitters)
{
    bench_hard_t h;
    mim_error_t err = {0};
    if (bench_hard_make_draws(&h, S, P, 3000, 1, spread, jitters, &err)) {
        fprintf(stderr, "hard set: %s\n", mim_error_text(&err));
        return 2;
    }
    char name[96];
    snprintf(name, sizeof name, "hard (synth seed 1, nearby poses, variants x%g: %g-%g degrees)", spread, 12 * spread,
             20 * spread);
    set_t set = {name, S, P, h.n_landmarks, h.landmarks, h.redrawn, h.draws, h.mirror, h.parent, cond_hard, 7,
                 methods_hard, (int)(sizeof methods_hard / sizeof *methods_hard)};
    if (sweep == 5) set.n_method = 3; /* the default, its SVMs alone, the angle discriminants */
    if (sweep == 6) set.n_method = 0; /* the baselines and bounds only */
    if (sweep == 7) set.method = methods_sweep7, set.n_method = sizeof methods_sweep7 / sizeof *methods_sweep7;
    if (sweep == 1) set.method = methods_sweep1, set.n_method = sizeof methods_sweep1 / sizeof *methods_sweep1;
    if (sweep == 2) set.method = methods_sweep2, set.n_method = sizeof methods_sweep2 / sizeof *methods_sweep2;
    if (sweep == 3) set.method = methods_sweep3, set.n_method = sizeof methods_sweep3 / sizeof *methods_sweep3;
    if (sweep == 4) set.method = methods_sweep4, set.n_method = sizeof methods_sweep4 / sizeof *methods_sweep4;
    run_set(&set, draws);
    bench_hard_free(&h);
    return 0;
}

int main(int argc, char **argv)
{
    int draws = 5, mh = 1, hard = 1, easy = 1, sweep = 0;
    uint32_t hs = 8, hp = 40, jitters = 128;
    double spread = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--draws") && i + 1 < argc) draws = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--no-mh")) mh = 0;
        else if (!strcmp(argv[i], "--proportions") && i + 1 < argc) body_proportions = !strcmp(argv[++i], "body");
        else if (!strcmp(argv[i], "--no-hard")) hard = 0;
        else if (!strcmp(argv[i], "--hard-only")) easy = 0;
        else if (!strcmp(argv[i], "--sweep") && i + 1 < argc) sweep = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--hard-subjects") && i + 1 < argc) hs = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--hard-poses") && i + 1 < argc) hp = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--hard-spread") && i + 1 < argc) spread = atof(argv[++i]);
        else if (!strcmp(argv[i], "--jitters") && i + 1 < argc) jitters = (uint32_t)atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_query_accuracy [--draws N] [--no-mh] [--no-hard | --hard-only] [--sweep 1-7] "
                            "[--hard-subjects S] [--hard-poses P] [--hard-spread F] [--jitters D] "
                            "[--proportions canonical|body]\n");
            return 2;
        }
    }
    if (draws < 1) draws = 1;
    if (hs < 2 || hp < 2 || hp > 1000 || !(spread > 0 && spread <= 3) || (jitters && jitters < 2) || jitters > 1024) {
        fprintf(stderr, "bench_query_accuracy: the hard set needs 2+ subjects, 2..1000 poses, a spread in (0, 3] and "
                        "0 or 2..1024 jitters\n");
        return 2;
    }
    bench_dataset_t d;
    if (easy) {
        if (bench_load_synth(&d, 8, 12, 3000)) {
            fprintf(stderr, "synth failed\n");
            return 2;
        }
        run_dataset("synth (seed 1)", &d, draws);
        bench_dataset_free(&d);
        char buf[4096];
        if (mh) {
            int rc = bench_load_mh(&d, bench_mh_dir(buf, sizeof buf));
            if (rc == 0) {
                run_dataset("mh-bodies", &d, draws);
                bench_dataset_free(&d);
            } else {
                printf("\n(mh-bodies not found at %s: skipped)\n", buf);
            }
        }
    }
    return hard ? run_hard(hs, hp, spread, sweep, draws, jitters) : 0;
}
