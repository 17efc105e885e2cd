/* Registration accuracy and time (issue 13; register/: landmark-guided
 * non-rigid ICP after Amberg et al. 2007). Prints figures; never passes or
 * fails.
 *
 * Ground truth by re-triangulation: the target is a body of the data set
 * decimated with OpenMesh's quadric decimater (tests/support/
 * retriangulate.h) and put in a random vertex order, so that it shares no
 * connectivity with the store, while the true place of every store vertex
 * is the original body's vertex. The target's subject is left out of the
 * index (strict leave-one-subject-out); its 16 landmarks are the original
 * body's landmark vertices. The start comes from the recognition index as
 * in mimic ingest --register (mim_ingest_start_template): of its 8 nearest
 * in the pose class, the one whose landmarks a similarity brings closest
 * to the target's (mim_reg_likest); --start index takes the index's
 * nearest, --proportions body an index whose angles see proportions.
 *
 * Rows: mimic's registration (similarity fit, transfer, non-rigid ICP),
 * the baseline of the same code without ICP (landmark-guided Laplacian
 * editing of the nearest template), and mimic's with the hands and feet
 * fitted as the rest (extremity weight 1). Correspondence also by body
 * region (each vertex by its nearest landmark). Correspondence error: per-vertex
 * distance to the truth, pooled over all vertices of all targets. Surface
 * distance: of every result vertex to the target's surface. Seconds: per
 * mesh, one core, median.
 *
 * usage: bench_register [--vertices N] [--mh DIR | --no-mh] [--target-vertices N]
 *                       [--subjects K] [--poses P] [--proportions canonical|body]
 *                       [--start likest|index]
 * The default target keeps 30 % of the vertices (mh-bodies: 13,380 -> 4,014). */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_index.h"
#include "mim_ingest.h"
#include "mim_register.h"
#include "mim_transfer.h"
#include "retriangulate.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NM 3 /* methods: mimic's, the baseline, mimic's with the extremities fitted as the rest */

typedef struct args {
    uint32_t target_vertices, subjects, poses;
    int body_proportions; /* --proportions body: indexes whose angles see each body's own proportions */
    int index_start;      /* --start index: from the index's nearest, not the likest of its nearest */
} args_t;

typedef struct row {
    double *corr, *surf, *secs;
    size_t n_corr, n_surf, n_secs;
    double region_sum[MIM_REG_REGIONS];
    uint64_t region_n[MIM_REG_REGIONS];
} row_t;

/* Each vertex's body region (mim_reg_region_names) by its nearest landmark
 * on the set's first body, as register/ reports distortion. */
static void vertex_regions(const bench_dataset_t *d, uint8_t *region)
{
    static const char *const of[][2] = {{"head", "head"},       {"l_elbow", "arms"}, {"r_elbow", "arms"},
                                        {"l_wrist", "hands"},   {"r_wrist", "hands"}, {"l_hip", "legs"},
                                        {"r_hip", "legs"},      {"l_knee", "legs"},  {"r_knee", "legs"},
                                        {"l_ankle", "feet"},    {"r_ankle", "feet"}};
    int lm_region[MIM_LANDMARKS_MAX];
    for (uint32_t l = 0; l < d->map.count; l++) {
        lm_region[l] = 1; /* the torso */
        for (size_t k = 0; k < sizeof of / sizeof *of; k++)
            if (!strcmp(d->map.names[l], of[k][0]))
                for (int g = 0; g < MIM_REG_REGIONS; g++)
                    if (!strcmp(of[k][1], mim_reg_region_names[g])) lm_region[l] = g;
    }
    const float *b = d->pos[0];
    for (uint32_t i = 0; i < d->n; i++) {
        double best = INFINITY;
        for (uint32_t l = 0; l < d->map.count; l++) {
            const float *q = b + 3 * (size_t)d->map.vertex[l];
            double e = 0;
            for (int c = 0; c < 3; c++) e += (b[3 * i + c] - q[c]) * (b[3 * i + c] - q[c]);
            if (e < best) best = e, region[i] = (uint8_t)lm_region[l];
        }
    }
}

static void row_push(double **v, size_t *n, double x)
{
    *v = realloc(*v, (*n + 1) * sizeof **v);
    (*v)[(*n)++] = x;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double mean(const double *v, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < n; i++) s += v[i];
    return n ? s / n : NAN;
}

static double p95(double *v, size_t n)
{
    qsort(v, n, sizeof *v, cmp_d);
    return n ? v[(size_t)floor(0.95 * (n - 1))] : NAN;
}

static int run_set(const bench_dataset_t *d, void *user)
{
    const args_t *a = user;
    uint32_t S = a->subjects && a->subjects < d->subjects ? a->subjects : d->subjects;
    uint32_t P = a->poses && a->poses < d->poses ? a->poses : d->poses;
    uint32_t n = d->n, L = d->map.count;
    uint32_t tv = a->target_vertices ? a->target_vertices : (uint32_t)(0.3 * n);
    mim_error_t err = {0};
    mim_xfer_topology_t *topo = NULL;
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err)) {
        fprintf(stderr, "%s: %s\n", d->name, mim_error_text(&err));
        return 1;
    }
    mim_reg_t *reg[NM] = {NULL, NULL, NULL};
    mim_reg_options_t ro[NM] = {{0}, {.no_icp = 1}, {.extremity_weight = -1}};
    for (int m = 0; m < NM; m++)
        if (mim_reg_open(&reg[m], topo, &d->map, &ro[m], &err)) {
            fprintf(stderr, "%s: %s\n", d->name, mim_error_text(&err));
            return 1;
        }
    row_t rows[NM] = {{0}};
    double target_v = 0, iters = 0, picked_same_pose = 0;
    uint32_t runs = 0;
    float *out = malloc(sizeof(float) * 3 * n), *lm = malloc(sizeof(float) * 3 * L);
    float *tlm = malloc(sizeof(float) * 3 * L * d->subjects * d->poses);
    uint64_t *ids = malloc(sizeof(uint64_t) * d->subjects * d->poses);
    const char **sp = malloc(sizeof(char *) * d->subjects * d->poses), **pp = malloc(sizeof(char *) * d->subjects * d->poses);
    char (*lab)[2][16] = malloc(sizeof *lab * d->subjects * d->poses);
    double *dist = malloc(sizeof(double) * n);
    uint8_t *region = malloc(n);
    vertex_regions(d, region);
    for (uint32_t s = 0; s < S; s++) {
        uint32_t nt = 0;
        for (uint32_t t = 0; t < d->subjects * d->poses; t++) {
            if (t / d->poses == s) continue;
            for (uint32_t l = 0; l < L; l++) memcpy(tlm + 3 * (L * nt + l), d->pos[t] + 3 * d->map.vertex[l], 12);
            snprintf(lab[nt][0], 16, "s%u", t / d->poses), snprintf(lab[nt][1], 16, "p%u", t % d->poses);
            sp[nt] = lab[nt][0], pp[nt] = lab[nt][1], ids[nt] = t + 1, nt++;
        }
        int32_t parent[MIM_LANDMARKS_MAX]; /* as mimic index: canonical proportions */
        mim_index_input_t in = {nt, L, tlm, ids, sp, pp, d->map.mirror,
                                a->body_proportions || mim_index_skeleton(&d->map, parent) ? NULL : parent};
        mim_index_t *ix = NULL;
        if (mim_index_build(&ix, &in, NULL, NULL, &err)) {
            fprintf(stderr, "%s: index: %s\n", d->name, mim_error_text(&err));
            return 1;
        }
        for (uint32_t p = 0; p < P; p++) {
            const float *truth = d->pos[s * d->poses + p];
            mim_mesh_t body = {n, d->n_faces, (float *)truth, d->faces}, dec = {0}, target = {0};
            if (rt_decimate(&body, tv, &dec) || rt_shuffle(&dec, 1000 + s * 100 + p, &target, NULL)) {
                fprintf(stderr, "%s: re-triangulation failed\n", d->name);
                return 1;
            }
            mim_mesh_free(&dec);
            target_v += target.n_vertices;
            for (uint32_t l = 0; l < L; l++) memcpy(lm + 3 * l, truth + 3 * d->map.vertex[l], 12);
            /* where mimic register starts (mim_ingest_start_template): of
             * the index's nearest in the pose class, the body most like
             * the target's (--start index: the index's nearest) */
            mim_index_answer_t ans;
            mim_index_hit_t hits[MIM_INGEST_CANDIDATES];
            mim_index_query_options_t qo = {.k = a->index_start ? 1 : MIM_INGEST_CANDIDATES};
            if (mim_index_query(ix, lm, NULL, &qo, &ans, hits, &err) || !ans.n_hits) {
                fprintf(stderr, "%s: query: %s\n", d->name, mim_error_text(&err));
                return 1;
            }
            float cand[MIM_INGEST_CANDIDATES * 3 * MIM_LANDMARKS_MAX];
            for (uint32_t c = 0; c < ans.n_hits; c++)
                for (uint32_t l = 0; l < L; l++)
                    memcpy(cand + ((size_t)c * L + l) * 3, d->pos[hits[c].id - 1] + 3 * d->map.vertex[l], 12);
            uint32_t best = 0;
            if (ans.n_hits > 1 && mim_reg_likest(lm, L, cand, ans.n_hits, &best, NULL)) best = 0;
            const mim_index_hit_t hit = hits[best];
            picked_same_pose += (hit.id - 1) % d->poses == p;
            const float *tmpl = d->pos[hit.id - 1];
            for (int m = 0; m < NM; m++) {
                mim_reg_report_t rep;
                if (mim_reg_run(reg[m], tmpl, &target, lm, "target", out, &rep, &err)) {
                    fprintf(stderr, "%s: s%u p%u: %s\n", d->name, s, p, mim_error_text(&err));
                    return 1;
                }
                for (uint32_t i = 0; i < n; i++) {
                    double dx = out[3 * i] - truth[3 * i], dy = out[3 * i + 1] - truth[3 * i + 1],
                           dz = out[3 * i + 2] - truth[3 * i + 2];
                    double e = 1000 * sqrt(dx * dx + dy * dy + dz * dz);
                    row_push(&rows[m].corr, &rows[m].n_corr, e);
                    rows[m].region_sum[region[i]] += e, rows[m].region_n[region[i]]++;
                }
                if (mim_reg_surface_distance(&target, out, n, dist, &err)) return 1;
                for (uint32_t i = 0; i < n; i++) row_push(&rows[m].surf, &rows[m].n_surf, 1000 * dist[i]);
                row_push(&rows[m].secs, &rows[m].n_secs, rep.seconds);
                if (m == 0) iters += rep.iterations;
            }
            runs++;
            mim_mesh_free(&target);
            fprintf(stderr, "\r%s: %u/%u targets", d->name, runs, S * P);
        }
        mim_index_close(&ix);
    }
    fprintf(stderr, "\n");
    printf("\n### %s: %u targets (%u subjects left out x %u poses), targets of %.0f vertices on average, store "
           "connectivity %u vertices; nearest template of the same pose for %.0f %%; %.1f ICP steps on average\n\n",
           d->name, runs, S, P, target_v / runs, n, 100.0 * picked_same_pose / runs, iters / runs);
    printf("| method | correspondence mean (mm) | correspondence p95 (mm) | surface distance mean (mm) | surface "
           "distance p95 (mm) | seconds per mesh (median) |\n|---|---|---|---|---|---|\n");
    const char *names[NM] = {"mimic register (similarity, transfer, non-rigid ICP)",
                             "baseline: landmark-guided Laplacian editing of the nearest template, no ICP",
                             "mimic register with the hands and feet fitted as the rest (extremity weight 1)"};
    for (int m = 0; m < NM; m++) {
        double cm = mean(rows[m].corr, rows[m].n_corr), sm = mean(rows[m].surf, rows[m].n_surf);
        printf("| %s | %.1f | %.1f | %.2f | %.2f | %.3f |\n", names[m], cm, p95(rows[m].corr, rows[m].n_corr), sm,
               p95(rows[m].surf, rows[m].n_surf), bench_median(rows[m].secs, (int)rows[m].n_secs));
        free(rows[m].corr), free(rows[m].surf), free(rows[m].secs);
    }
    printf("\ncorrespondence mean by region (mm; each vertex by its nearest landmark):\n\n| method |");
    for (int g = 0; g < MIM_REG_REGIONS; g++) printf(" %s |", mim_reg_region_names[g]);
    printf("\n|---|---:|---:|---:|---:|---:|---:|\n");
    for (int m = 0; m < NM; m++) {
        printf("| %s |", names[m]);
        for (int g = 0; g < MIM_REG_REGIONS; g++)
            printf(" %.1f |", rows[m].region_n[g] ? rows[m].region_sum[g] / (double)rows[m].region_n[g] : NAN);
        printf("\n");
    }
    for (int m = 0; m < NM; m++) mim_reg_close(&reg[m]);
    mim_xfer_topology_close(&topo);
    free(out), free(lm), free(tlm), free(ids), free(sp), free(pp), free(lab), free(dist), free(region);
    return 0;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    args_t a = {0};
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i)) continue;
        if (!strcmp(argv[i], "--target-vertices") && i + 1 < argc) a.target_vertices = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--subjects") && i + 1 < argc) a.subjects = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--poses") && i + 1 < argc) a.poses = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--proportions") && i + 1 < argc) a.body_proportions = !strcmp(argv[++i], "body");
        else if (!strcmp(argv[i], "--start") && i + 1 < argc) a.index_start = !strcmp(argv[++i], "index");
        else {
            fprintf(stderr, "usage: %s [--vertices N] [--mh DIR | --no-mh] [--target-vertices N] [--subjects K] "
                            "[--poses P] [--proportions canonical|body] [--start likest|index]\n", argv[0]);
            return 2;
        }
    }
    return bench_sets_run(&sets, 4, 12, run_set, &a);
}
