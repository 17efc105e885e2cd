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
 *   bench_query_accuracy [--draws N] [--no-mh]
 * Prints a Markdown table per dataset. */
#include "bench_data.h"
#include "mim_index.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { N_COND = 6, N_METHOD = 5 };
static const char *const cond_name[N_COND] = {"no noise", "noise 1 cm", "noise 3 cm", "1 missing", "2 missing",
                                              "3 missing"};
static const uint32_t ds[4] = {20, 40, 60, 70};

static uint64_t rng_state = 12345;
static double uniform(void)
{
    rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return ((rng_state >> 11) + 0.5) / 9007199254740992.0;
}
static double gauss(void) { return sqrt(-2 * log(uniform())) * cos(2 * M_PI * uniform()); }

/* A query frame for condition c, draw r: noise or missing landmarks. */
static void make_frame(const float *lm, uint32_t L, int c, float *out, uint8_t *present)
{
    memcpy(out, lm, sizeof(float) * 3 * L);
    memset(present, 1, L);
    if (c == 1 || c == 2) {
        double sigma = c == 1 ? 0.01 : 0.03;
        for (uint32_t i = 0; i < 3 * L; i++) out[i] += (float)(sigma * gauss());
    } else if (c >= 3) {
        uint32_t miss = (uint32_t)c - 2;
        for (uint32_t m = 0; m < miss;) {
            uint32_t l = (uint32_t)(uniform() * L) % L;
            if (!present[l]) continue;
            present[l] = 0;
            out[3 * l] = out[3 * l + 1] = out[3 * l + 2] = NAN;
            m++;
        }
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

static void run_dataset(const char *name, bench_dataset_t *d, int draws)
{
    uint32_t S = d->subjects, P = d->poses, n = S * P, L = d->map.count, nf = mim_index_angle_count(L);
    float *lm = malloc(sizeof(float) * 3 * L * n), *angles = malloc(sizeof(float) * (size_t)n * nf);
    char (*subj)[16] = malloc(16 * n), (*pose)[16] = malloc(16 * n);
    const char **sp = malloc(sizeof(char *) * n), **pp = malloc(sizeof(char *) * n);
    uint64_t *ids = malloc(sizeof(uint64_t) * n);
    uint32_t *train = malloc(sizeof(uint32_t) * n);
    float ymin = INFINITY, ymax = -INFINITY;
    for (uint32_t t = 0; t < n; t++) {
        for (uint32_t l = 0; l < L; l++) {
            memcpy(lm + 3 * (L * t + l), d->pos[t] + 3 * d->map.vertex[l], 12);
            float y = lm[3 * (L * t + l) + 1];
            ymin = y < ymin ? y : ymin, ymax = y > ymax ? y : ymax;
        }
        snprintf(subj[t], 16, "s%u", t / P);
        snprintf(pose[t], 16, "p%u", t % P);
        sp[t] = subj[t], pp[t] = pose[t], ids[t] = t + 1;
    }
    fprintf(stderr, "%s: %u subjects x %u poses, %u landmarks, landmark height span %.2f (units: metres)\n", name, S, P,
            L, ymax - ymin);
    /* hits[method][cond], tests[cond] */
    double hits[N_METHOD][N_COND] = {{0}}, tests[N_COND] = {0}, cv[4] = {0}, Cs[4][4] = {{0}};
    double build_s = 0;
    int builds = 0;
    float *frame = malloc(sizeof(float) * 3 * L), *qa = malloc(sizeof(float) * nf);
    uint8_t *present = malloc(L);
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
        for (uint32_t t = 0; t < n; t++) mim_index_angles(lm + 3 * L * t, NULL, L, angles + (size_t)t * nf);
        mim_index_t *ix[4] = {0};
        for (int di = 0; di < 4; di++) {
            mim_index_input_t in = {ntrain, L, tlm, tid, tsp, tpp, d->map.mirror};
            mim_index_options_t o = {.features = ds[di]};
            mim_index_report_t rep;
            mim_error_t err = {0};
            if (mim_index_build(&ix[di], &in, &o, &rep, &err)) {
                fprintf(stderr, "%s: build failed: %s\n", name, mim_error_text(&err));
                exit(2);
            }
            build_s += rep.seconds, builds++;
            cv[di] += rep.cv_accuracy / S;
            Cs[di][0] += log10(rep.C) / S;
        }
        for (uint32_t p = 0; p < P; p++) {
            uint32_t t = s * P + p;
            for (int c = 0; c < N_COND; c++) {
                int nd = c == 0 ? 1 : draws;
                for (int r = 0; r < nd; r++) {
                    make_frame(lm + 3 * L * t, L, c, frame, present);
                    tests[c]++;
                    for (int di = 0; di < 4; di++) {
                        mim_index_query_options_t qo = {.k = 1};
                        mim_index_answer_t a;
                        mim_index_hit_t h;
                        mim_error_t err = {0};
                        if (mim_index_query(ix[di], frame, present, &qo, &a, &h, &err) == 0 && a.n_hits)
                            hits[di][c] += !strcmp(h.pose, pose[t]);
                    }
                    mim_index_angles(frame, present, L, qa);
                    uint32_t arg = nn_all(angles, train, ntrain, nf, qa);
                    hits[4][c] += !strcmp(pose[arg], pose[t]);
                }
            }
        }
        for (int di = 0; di < 4; di++) mim_index_close(&ix[di]);
        free(tlm), free(tsp), free(tpp), free(tid);
    }
    printf("\n### %s (%u subjects x %u poses, leave one subject out, %d draws per noisy/missing frame)\n\n", name, S, P,
           draws);
    printf("| condition | d = 20 | d = 40 | d = 60 | d = 70 | 1-NN, all %u angles |\n|---|---|---|---|---|---|\n", nf);
    for (int c = 0; c < N_COND; c++) {
        printf("| %s |", cond_name[c]);
        for (int m = 0; m < N_METHOD; m++) printf(" %.3f |", hits[m][c] / tests[c]);
        printf("\n");
    }
    printf("\nMean cross-validation accuracy of the SVMs on the training subjects: d=20 %.3f, d=40 %.3f, d=60 %.3f, "
           "d=70 %.3f; mean log10(C) %.2f/%.2f/%.2f/%.2f; mean build %.3f s.\n",
           cv[0], cv[1], cv[2], cv[3], Cs[0][0], Cs[1][0], Cs[2][0], Cs[3][0], build_s / builds);
    fflush(stdout);
    free(lm), free(angles), free(subj), free(pose), free(sp), free(pp), free(ids), free(train), free(frame), free(qa);
    free(present);
}

int main(int argc, char **argv)
{
    int draws = 5, mh = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--draws") && i + 1 < argc) draws = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--no-mh")) mh = 0;
        else {
            fprintf(stderr, "usage: bench_query_accuracy [--draws N] [--no-mh]\n");
            return 2;
        }
    }
    if (draws < 1) draws = 1;
    bench_dataset_t d;
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
    return 0;
}
