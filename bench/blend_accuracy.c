/* Transfer from several templates (issue 15): one template against the k
 * nearest blended, each with and without the segment correction, on body
 * data the index has never seen. Prints figures; never passes or fails.
 *
 * Setting, strict leave one subject out: for each subject A, the
 * recognition index is built from the other subjects only (mim_index_build,
 * defaults); A's 16 landmarks in pose p (p != 0) are the query and the
 * solve's targets; the avatar is A in pose 0; the truth is A in pose p.
 * The templates are the index's hits for the query (k = 8 asked): exactly
 * what `mimic transfer --landmarks` retrieves. The segment correction needs
 * A's skin (the vest skeleton's bones, default smoothing), as the
 * orientation drive does. Errors: per-vertex distances in mm, pooled, and
 * by region (each vertex's heaviest segment).
 *
 * Methods: the single nearest template (the default before issue 15); the
 * first k hits (k = 2, 3, 5, all) blended, weights equal or by inverse
 * query distance; and each with the segment correction. Every method
 * iterates as mimic's default does (least squares, damping 0.5, early
 * stop). Times: the frames' preparation (correction and blend; the
 * templates' own frames are computed once, as the session caches them)
 * and the whole key frame, median over the runs.
 *
 * usage: bench_blend_accuracy [--vertices N] [--mh DIR | --no-mh] [--iterations N]
 *   --iterations N: N solves, no early stop (default: mimic's iteration) */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_index.h"
#include "mim_transfer.h"
#include "mim_vest_kinematics.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define K_ASK 8
enum { W_EQUAL, W_INVERSE, N_WEIGHTING };
static const uint32_t ks[] = {1, 2, 3, 5, K_ASK};
#define N_K (sizeof ks / sizeof ks[0])
#define N_METHOD (N_K * N_WEIGHTING * 2)
enum { X_LANDMARKS, X_LANDMARKS_NEAREST, N_EXTRA }; /* the rows after the blends */
static const char *const extra_names[N_EXTRA] = {
    "avatar's rest frames turned by the landmark skeleton's segment rotations",
    "those, blended with the nearest template's (equal weights)"};
#define MAX_RUNS 4096

typedef struct row {
    bench_err_t e;
    double rsum[BENCH_REGIONS];
    uint64_t rcnt[BENCH_REGIONS];
    double *t_prep, *t_key;
    uint32_t runs;
} row_t;

static int method_index(uint32_t ki, int weighting, int corrected)
{
    return (int)((ki * N_WEIGHTING + (uint32_t)weighting) * 2 + (uint32_t)corrected);
}

static void method_name(uint32_t ki, int weighting, int corrected, char *buf, size_t size)
{
    char who[64];
    if (ks[ki] == K_ASK)
        snprintf(who, sizeof who, "all hits (<= %d)", K_ASK);
    else
        snprintf(who, sizeof who, "%u nearest", ks[ki]);
    snprintf(buf, size, "%s%s%s", ks[ki] == 1 ? "nearest template" : who,
             ks[ki] == 1 ? "" : weighting == W_EQUAL ? ", equal weights" : ", 1/distance weights",
             corrected ? " + segment correction" : "");
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One key frame's errors and times (t0 .. t1 the frames, .. t2 the solve). */
static void record(row_t *r, const float *out, const float *truth, const uint8_t *region, uint32_t n, double t0,
                   double t1, double t2)
{
    if (r->runs < MAX_RUNS)
        r->t_prep[r->runs] = 1000 * (t1 - t0), r->t_key[r->runs] = 1000 * (t2 - t0);
    r->runs++;
    for (uint32_t i = 0; i < n; i++) {
        double dx = out[3 * i] - truth[3 * i], dy = out[3 * i + 1] - truth[3 * i + 1], dz = out[3 * i + 2] - truth[3 * i + 2];
        double mm = 1000 * sqrt(dx * dx + dy * dy + dz * dz);
        bench_err_add_mm(&r->e, mm);
        r->rsum[region[i]] += mm, r->rcnt[region[i]]++;
    }
}

static void print_row(row_t *r, const char *name)
{
    uint32_t nr = r->runs < MAX_RUNS ? r->runs : MAX_RUNS;
    qsort(r->t_prep, nr, sizeof(double), cmp_double);
    qsort(r->t_key, nr, sizeof(double), cmp_double);
    printf("| %s | %.2f | %.2f |", name, bench_err_mean(&r->e), bench_err_p95(&r->e));
    for (int g = 0; g < BENCH_REGIONS; g++)
        printf(" %.2f |", r->rcnt[g] ? r->rsum[g] / (double)r->rcnt[g] : 0.0);
    printf(" %.3f | %.3f |\n", r->t_prep[nr / 2], r->t_key[nr / 2]);
}

static int run_set(const bench_dataset_t *d, void *user)
{
    const mim_xfer_options_t *xo = user;
    mim_error_t err = {0};
    const uint32_t n = d->n, L = d->map.count, S = d->subjects, P = d->poses;
    mim_xfer_topology_t *topo = NULL;
    mim_xfer_solver_t *ls = NULL;
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err) ||
        mim_xfer_solver_open(&ls, topo, d->map.vertex, L, NULL, &err)) {
        fprintf(stderr, "bench: %s\n", mim_error_text(&err));
        return 1;
    }
    /* every body's landmarks and frames, once */
    const uint32_t T = S * P;
    float *lm = malloc(sizeof(float) * 3 * L * T);
    double **F = calloc(T, sizeof *F);
    for (uint32_t t = 0; t < T; t++) {
        for (uint32_t l = 0; l < L; l++)
            memcpy(lm + 3 * (L * t + l), d->pos[t] + 3 * (size_t)d->map.vertex[l], 3 * sizeof(float));
        F[t] = malloc(9 * sizeof(double) * n);
        mim_xfer_frames(topo, d->pos[t], F[t]);
    }
    row_t rows[N_METHOD + N_EXTRA];
    memset(rows, 0, sizeof rows);
    for (uint32_t m = 0; m < N_METHOD + N_EXTRA; m++) {
        bench_err_init(&rows[m].e);
        rows[m].t_prep = malloc(MAX_RUNS * sizeof(double));
        rows[m].t_key = malloc(MAX_RUNS * sizeof(double));
    }
    double *W = malloc(3 * sizeof(double) * n), *Fa = malloc(9 * sizeof(double) * n);
    double *Fc[K_ASK], *Fb = malloc(9 * sizeof(double) * n);
    for (int j = 0; j < K_ASK; j++)
        Fc[j] = malloc(9 * sizeof(double) * n);
    float *out = malloc(3 * sizeof(float) * n);
    mim_xfer_skin_t *skin = malloc(sizeof *skin * n);
    uint8_t *region = malloc(n);
    uint64_t *ids = malloc(sizeof(uint64_t) * T);
    char (*subj)[16] = malloc(16 * T), (*pose)[16] = malloc(16 * T);
    const char **sp = malloc(sizeof(char *) * T), **pp = malloc(sizeof(char *) * T);
    uint32_t queries = 0, same_pose_hits = 0, hits_total = 0, right_class = 0;
    for (uint32_t t = 0; t < T; t++) {
        snprintf(subj[t], 16, "s%u", t / P), snprintf(pose[t], 16, "p%u", t % P);
        sp[t] = subj[t], pp[t] = pose[t], ids[t] = t + 1;
    }
    int rc = 1;
    for (uint32_t a = 0; a < S; a++) {
        const float *rest = d->pos[a * P];
        mim_mesh_t mesh = {n, d->n_faces, (float *)rest, d->faces};
        mim_vest_skeleton_t sk;
        double bones[MIM_SEGMENTS * 6];
        if (mim_vest_skeleton_estimate(&sk, &mesh, &d->map, &err))
            goto fail;
        mim_vest_skeleton_bones(&sk, bones);
        if (mim_xfer_skin_from_bones(topo, rest, bones, MIM_SEGMENTS, MIM_XFER_DEFAULT_SKIN_SMOOTHING, skin, &err))
            goto fail;
        for (uint32_t i = 0; i < n; i++)
            region[i] = (uint8_t)bench_region_of_segment(skin[i].bone[0]);
        mim_xfer_frames(topo, rest, Fa);
        mim_xfer_encode(topo, rest, Fa, W);
        /* the index of the other subjects */
        uint32_t ntrain = 0;
        float *tlm = malloc(sizeof(float) * 3 * L * T);
        const char **tsp = malloc(sizeof(char *) * T), **tpp = malloc(sizeof(char *) * T);
        uint64_t *tid = malloc(sizeof(uint64_t) * T);
        for (uint32_t t = 0; t < T; t++)
            if (t / P != a) {
                memcpy(tlm + 3 * L * ntrain, lm + 3 * L * t, sizeof(float) * 3 * L);
                tsp[ntrain] = sp[t], tpp[ntrain] = pp[t], tid[ntrain] = ids[t], ntrain++;
            }
        mim_index_input_t in = {ntrain, L, tlm, tid, tsp, tpp, d->map.mirror};
        mim_index_t *ix = NULL;
        int brc = mim_index_build(&ix, &in, NULL, NULL, &err);
        free(tlm), free(tsp), free(tpp), free(tid);
        if (brc)
            goto fail;
        for (uint32_t p = 1; p < P; p++) {
            const uint32_t q = a * P + p;
            const float *truth = d->pos[q], *u = lm + 3 * L * q;
            mim_index_query_options_t qo = {.k = K_ASK};
            mim_index_answer_t ans;
            mim_index_hit_t hits[K_ASK];
            if (mim_index_query(ix, u, NULL, &qo, &ans, hits, &err) || !ans.n_hits) {
                mim_index_close(&ix);
                goto fail;
            }
            queries++;
            right_class += !strcmp(hits[0].pose, pose[q]);
            for (uint32_t h = 0; h < ans.n_hits; h++)
                same_pose_hits += !strcmp(hits[h].pose, pose[q]), hits_total++;
            for (uint32_t ki = 0; ki < N_K; ki++)
                for (int wt = 0; wt < N_WEIGHTING; wt++)
                    for (int corrected = 0; corrected < 2; corrected++) {
                        if (ks[ki] == 1 && wt != W_EQUAL)
                            continue;
                        row_t *r = &rows[method_index(ki, wt, corrected)];
                        uint32_t k = ks[ki] < ans.n_hits ? ks[ki] : ans.n_hits;
                        double w[K_ASK];
                        const double *src[K_ASK];
                        double t0 = mim_now();
                        for (uint32_t j = 0; j < k; j++) {
                            const uint32_t t = (uint32_t)hits[j].id - 1;
                            w[j] = wt == W_EQUAL ? 1.0 : 1.0 / (hits[j].distance + 1e-3);
                            src[j] = F[t];
                            if (corrected) {
                                mim_quat R[MIM_SEGMENTS];
                                if (mim_xfer_segment_correction(&d->map, lm + 3 * L * t, u, R, &err)) {
                                    mim_index_close(&ix);
                                    goto fail;
                                }
                                mim_xfer_skin_frames(n, skin, F[t], R, Fc[j]);
                                src[j] = Fc[j];
                            }
                        }
                        const double *frames = src[0];
                        if (k > 1) {
                            mim_xfer_frames_blend(n, k, src, w, Fb);
                            frames = Fb;
                        }
                        double t1 = mim_now();
                        if (mim_xfer_transfer(ls, W, n, frames, u, L, xo, out, NULL, &err)) {
                            mim_index_close(&ix);
                            goto fail;
                        }
                        record(r, out, truth, region, n, t0, t1, mim_now());
                    }
            /* the avatar's own frames, turned as its landmark skeleton
             * onto the targets (no template); then blended with the nearest */
            for (int x = 0; x < N_EXTRA; x++) {
                double t0 = mim_now();
                mim_quat R[MIM_SEGMENTS];
                if (mim_xfer_segment_correction(&d->map, lm + 3 * L * (a * P), u, R, &err)) {
                    mim_index_close(&ix);
                    goto fail;
                }
                mim_xfer_skin_frames(n, skin, Fa, R, Fc[0]);
                const double *frames = Fc[0];
                if (x == X_LANDMARKS_NEAREST) {
                    const double *src[2] = {Fc[0], F[hits[0].id - 1]};
                    mim_xfer_frames_blend(n, 2, src, NULL, Fb);
                    frames = Fb;
                }
                double t1 = mim_now();
                if (mim_xfer_transfer(ls, W, n, frames, u, L, xo, out, NULL, &err)) {
                    mim_index_close(&ix);
                    goto fail;
                }
                record(&rows[N_METHOD + x], out, truth, region, n, t0, t1, mim_now());
            }
        }
        mim_index_close(&ix);
        fprintf(stderr, "%s: subject %u of %u\n", d->name, a + 1, S);
    }
    printf("\n### %s: %u vertices, %u subjects x %u poses, %u queries (leave one subject out)\n\n", d->name, n, S, P,
           queries);
    printf("The index's first hit has the true pose in %u of %u queries; %u of its %u hits (k = %d asked) do.\n\n",
           right_class, queries, same_pose_hits, hits_total, K_ASK);
    printf("| method | mean mm | p95 mm |");
    for (int g = 0; g < BENCH_REGIONS; g++)
        printf(" %s |", bench_region_names[g]);
    printf(" frames ms | key frame ms |\n|---|---:|---:|");
    for (int g = 0; g < BENCH_REGIONS; g++)
        printf("---:|");
    printf("---:|---:|\n");
    for (uint32_t ki = 0; ki < N_K; ki++)
        for (int wt = 0; wt < N_WEIGHTING; wt++)
            for (int corrected = 0; corrected < 2; corrected++) {
                row_t *r = &rows[method_index(ki, wt, corrected)];
                if (!r->runs)
                    continue;
                char name[200];
                method_name(ki, wt, corrected, name, sizeof name);
                print_row(r, name);
            }
    for (int x = 0; x < N_EXTRA; x++)
        print_row(&rows[N_METHOD + x], extra_names[x]);
    rc = 0;
fail:
    if (rc)
        fprintf(stderr, "bench: %s\n", mim_error_text(&err));
    for (uint32_t m = 0; m < N_METHOD + N_EXTRA; m++)
        bench_err_free(&rows[m].e), free(rows[m].t_prep), free(rows[m].t_key);
    for (uint32_t t = 0; t < T; t++)
        free(F[t]);
    for (int j = 0; j < K_ASK; j++)
        free(Fc[j]);
    free(F), free(lm), free(W), free(Fa), free(Fb), free(out), free(skin), free(region), free(ids), free(subj),
        free(pose), free(sp), free(pp);
    mim_xfer_solver_close(&ls);
    mim_xfer_topology_close(&topo);
    return rc;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    mim_xfer_options_t xo = {0};
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i))
            continue;
        if (!strcmp(argv[i], "--iterations") && i + 1 < argc) {
            xo.max_iterations = (uint32_t)strtoul(argv[++i], NULL, 10);
            xo.tol = -1, xo.no_early_stop = 1;
        } else {
            fprintf(stderr, "usage: %s [--vertices N] [--mh DIR | --no-mh] [--iterations N]\n", argv[0]);
            return 2;
        }
    }
    printf("iterations: %s\n", xo.max_iterations ? "fixed" : "mimic's default");
    return bench_sets_run(&sets, 4, 12, run_set, &xo);
}
