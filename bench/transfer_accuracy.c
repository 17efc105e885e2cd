/* Pose transfer accuracy and timings (issue 3, points 3 and 8; seed 000
 * Section 3.4). Prints figures; never passes or fails.
 *
 * Setting: avatar = subject A in pose 0; landmarks = A's 16 landmark
 * vertices in pose p; template = subject B != A in pose p; ground truth = A
 * in pose p (same connectivity). Errors are per-vertex distances in mm,
 * pooled over all vertices of all pairs (A != B, p != 0).
 *
 * Timings are in bench/transfer.c.
 *
 * usage: bench_transfer_accuracy [--vertices N] [--mh DIR | --no-mh] [--pairs-max K] [--settle S]
 *   --settle S: the default row's mim_xfer_options_t.settle (< 0: none; the
 *   row "before issue 31" never settles, whatever S)
 * The mh-bodies folder defaults to $MIMIC_SHARED_DATA/mh-bodies, else
 * ../shared/data/mh-bodies beside the source tree; it is skipped when absent. */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_synth.h"
#include "mim_transfer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAXIT 10

typedef struct stat {
    const char *name;
    bench_err_t e; /* pooled per-vertex errors (bench_data.h) */
    double iters;
    uint64_t runs;
} stat_t;

enum { M_BASE1, M_BASE2, M_PAPER, M_LS10, M_DEFAULT, M_NO_SETTLE, M_LS_D1, M_LS_D07, M_LS_D05R1, M_LS_D05R07, M_SQ_DEF, M_LS2, M_LS3, M_ANCHOR, M_RETARGET, M_COUNT };
static const char *method_names[M_COUNT] = {
    "baseline 1: B moved to landmark centroid",
    "baseline 2: Laplacian editing, avatar rest frames",
    "paper: square, hard constraints, 10 it",
    "least squares, 10 it, no damping, no early stop",
    "mimic default (least squares, damping 0.5, stop ratio 0.5, settle)",
    "mimic default before issue 31 (no settle: tol 0.1 mm alone)",
    "least squares, damping 1 (none), stop ratio 1",
    "least squares, damping 0.7, stop ratio 1",
    "least squares, damping 0.5, stop ratio 1",
    "least squares, damping 0.5, stop ratio 0.7",
    "square, mimic defaults (early stop)",
    "least squares, 2 it, no damping",
    "least squares, 3 it, no damping",
    "mode (a) template only, the paper's way: pelvis anchor alone, LS defaults",
    "mode (a) template only, mimic: landmarks retargeted from the template, LS defaults",
};

static double settle; /* --settle: the default row's (0: mimic's default) */

static int run_accuracy(const bench_dataset_t *d, uint32_t pairs_max)
{
    mim_error_t err = {0};
    const uint32_t n = d->n, c = d->map.count;
    mim_xfer_topology_t *topo = NULL;
    mim_xfer_solver_t *sq = NULL, *ls = NULL, *an = NULL;
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err))
        goto fail;
    mim_xfer_solver_options_t so_sq = {.formulation = MIM_XFER_SQUARE}, so_ls = {0};
    if (mim_xfer_solver_open(&sq, topo, d->map.vertex, c, &so_sq, &err) ||
        mim_xfer_solver_open(&ls, topo, d->map.vertex, c, &so_ls, &err) ||
        mim_xfer_solver_open(&an, topo, &d->map.vertex[2], 1, &so_ls, &err))
        goto fail;

    stat_t st[M_COUNT];
    memset(st, 0, sizeof st);
    for (int m = 0; m < M_COUNT; m++) {
        st[m].name = method_names[m];
        bench_err_init(&st[m].e);
    }
    double err_ls[MAXIT] = {0}, err_sq[MAXIT] = {0};
    uint64_t pairs = 0;
    double *W = malloc(3 * (size_t)n * sizeof(double));
    double *Fa = malloc(9 * (size_t)n * sizeof(double));
    double *Ft = malloc(9 * (size_t)n * sizeof(double));
    float *out = malloc(3 * (size_t)n * sizeof(float));
    float *targets = malloc(3 * (size_t)c * sizeof(float));
    double e_it[MAXIT];
    /* error by body region: each vertex belongs to its nearest landmark on
     * the avatar's rest pose; for the default and the paper's formulation */
    uint32_t *region = malloc((size_t)n * sizeof *region);
    double reg_sum[2][MIM_LANDMARKS_MAX] = {{0}};
    uint64_t reg_cnt[MIM_LANDMARKS_MAX] = {0};

    for (uint32_t a = 0; a < d->subjects; a++) {
        const float *rest = d->pos[a * d->poses];
        mim_xfer_frames(topo, rest, Fa);
        mim_xfer_encode(topo, rest, Fa, W);
        for (uint32_t i = 0; i < n; i++) {
            double best = INFINITY;
            for (uint32_t k = 0; k < c; k++) {
                const float *l = rest + 3 * (size_t)d->map.vertex[k];
                double dx = rest[3 * i] - l[0], dy = rest[3 * i + 1] - l[1], dz = rest[3 * i + 2] - l[2];
                double dd = dx * dx + dy * dy + dz * dz;
                if (dd < best)
                    best = dd, region[i] = k;
            }
        }
        for (uint32_t b = 0; b < d->subjects; b++) {
            if (b == a)
                continue;
            for (uint32_t p = 1; p < d->poses; p++) {
                if (pairs_max && pairs >= pairs_max)
                    continue;
                const float *truth = d->pos[a * d->poses + p];
                const float *tmpl = d->pos[b * d->poses + p];
                double ca[3] = {0}, cb[3] = {0};
                for (uint32_t k = 0; k < c; k++)
                    for (int q = 0; q < 3; q++) {
                        targets[3 * k + q] = truth[3 * (size_t)d->map.vertex[k] + q];
                        ca[q] += targets[3 * k + q] / c;
                        cb[q] += tmpl[3 * (size_t)d->map.vertex[k] + q] / c;
                    }
                /* mode (a), mimic: landmarks retargeted from the template onto
                 * A's proportions; like the pelvis-anchor row it is placed at
                 * the true pelvis (translation is all it takes from A's pose) */
                float retarget[3 * MIM_LANDMARKS_MAX];
                if (mim_xfer_retarget_landmarks(&d->map, rest, tmpl, retarget, &err))
                    goto fail;
                float shift[3];
                for (int q = 0; q < 3; q++)
                    shift[q] = targets[6 + q] - retarget[6 + q];
                for (uint32_t k = 0; k < c; k++)
                    for (int q = 0; q < 3; q++)
                        retarget[3 * k + q] += shift[q];
                /* baseline 1 */
                for (uint32_t i = 0; i < n; i++)
                    for (int q = 0; q < 3; q++)
                        out[3 * i + q] = (float)(tmpl[3 * i + q] + ca[q] - cb[q]);
                bench_err_add(&st[M_BASE1].e, out, truth, n, NULL);
                mim_xfer_frames(topo, tmpl, Ft);
                mim_xfer_report_t rep;
                struct {
                    int m;
                    mim_xfer_solver_t *s;
                    const double *F;
                    mim_xfer_options_t o;
                    double *eacc;
                } runs[] = {
                    {M_BASE2, sq, Fa, {.max_iterations = 1}, NULL},
                    {M_PAPER, sq, Ft, {.max_iterations = 10, .tol = -1, .damping = 1, .no_early_stop = 1, .truth = truth, .error_by_iteration = e_it}, err_sq},
                    {M_LS10, ls, Ft, {.max_iterations = 10, .tol = -1, .damping = 1, .no_early_stop = 1, .truth = truth, .error_by_iteration = e_it}, err_ls},
                    {M_DEFAULT, ls, Ft, {.settle = settle}, NULL},
                    {M_NO_SETTLE, ls, Ft, {.settle = -1}, NULL},
                    {M_LS_D07, ls, Ft, {.damping = 0.7, .stop_ratio = 1}, NULL},
                    {M_LS_D1, ls, Ft, {.damping = 1, .stop_ratio = 1}, NULL},
                    {M_LS_D05R1, ls, Ft, {.damping = 0.5, .stop_ratio = 1}, NULL},
                    {M_LS_D05R07, ls, Ft, {.stop_ratio = 0.7}, NULL},
                    {M_SQ_DEF, sq, Ft, {0}, NULL},
                    {M_LS2, ls, Ft, {.max_iterations = 2, .tol = -1, .damping = 1, .no_early_stop = 1}, NULL},
                    {M_LS3, ls, Ft, {.max_iterations = 3, .tol = -1, .damping = 1, .no_early_stop = 1}, NULL},
                    {M_ANCHOR, an, Ft, {0}, NULL},
                    {M_RETARGET, ls, Ft, {0}, NULL},
                };
                for (size_t r = 0; r < sizeof runs / sizeof runs[0]; r++) {
                    /* mode (a) gets the pelvis (landmark 2) alone */
                    int anchor = runs[r].s == an;
                    const float *u = anchor ? targets + 6 : runs[r].m == M_RETARGET ? retarget : targets;
                    if (mim_xfer_transfer(runs[r].s, W, n, runs[r].F, u, anchor ? 1 : c, &runs[r].o, out, &rep, &err))
                        goto fail;
                    bench_err_add(&st[runs[r].m].e, out, truth, n, NULL);
                    if (runs[r].m == M_DEFAULT || runs[r].m == M_PAPER) {
                        int w = runs[r].m == M_PAPER;
                        for (uint32_t i = 0; i < n; i++) {
                            double dx = out[3 * i] - truth[3 * i], dy = out[3 * i + 1] - truth[3 * i + 1],
                                   dz = out[3 * i + 2] - truth[3 * i + 2];
                            reg_sum[w][region[i]] += 1000.0 * sqrt(dx * dx + dy * dy + dz * dz);
                            if (!w)
                                reg_cnt[region[i]]++;
                        }
                    }
                    st[runs[r].m].iters += rep.iterations;
                    st[runs[r].m].runs++;
                    if (runs[r].eacc)
                        for (int k = 0; k < MAXIT; k++)
                            runs[r].eacc[k] += 1000.0 * e_it[k];
                }
                pairs++;
            }
        }
    }
    printf("\n## %s: %u vertices, %u subjects x %u poses, %llu pairs (A != B, p != 0)\n\n", d->name, n,
           d->subjects, d->poses, (unsigned long long)pairs);
    printf("| method | mean mm | p95 mm | mean iterations |\n|---|---:|---:|---:|\n");
    for (int m = 0; m < M_COUNT; m++)
        printf("| %s | %.2f | %.2f | %s%.2f |\n", st[m].name, bench_err_mean(&st[m].e),
               bench_err_p95(&st[m].e), st[m].runs ? "" : "- ", st[m].runs ? st[m].iters / (double)st[m].runs : 0.0);
    printf("\nmean error (mm) by iteration, no damping, no early stop:\n\n| iteration |");
    for (int k = 0; k < MAXIT; k++)
        printf(" %d |", k + 1);
    printf("\n|---|");
    for (int k = 0; k < MAXIT; k++)
        printf("---:|");
    printf("\n| least squares |");
    for (int k = 0; k < MAXIT; k++)
        printf(" %.2f |", err_ls[k] / (double)pairs);
    printf("\n| square (paper) |");
    for (int k = 0; k < MAXIT; k++)
        printf(" %.2f |", err_sq[k] / (double)pairs);
    printf("\n\nmean error (mm) by body region (vertices nearest each landmark on the rest pose):\n\n");
    printf("| region | share of vertices | mimic default | paper |\n|---|---:|---:|---:|\n");
    uint64_t tot = 0;
    for (uint32_t k = 0; k < c; k++)
        tot += reg_cnt[k];
    for (uint32_t k = 0; k < c; k++)
        if (reg_cnt[k])
            printf("| %s | %.1f%% | %.2f | %.2f |\n", d->map.names[k], 100.0 * (double)reg_cnt[k] / (double)tot,
                   reg_sum[0][k] / (double)reg_cnt[k], reg_sum[1][k] / (double)reg_cnt[k]);
    free(region);
    double md = bench_err_mean(&st[M_DEFAULT].e), mp = bench_err_mean(&st[M_PAPER].e);
    double m1 = bench_err_mean(&st[M_BASE1].e), m2 = bench_err_mean(&st[M_BASE2].e);
    printf("\ntargets: default mean < baselines: %s; default p95 < baselines: %s; default mean / paper mean = %.3f (<= 0.6: %s)\n",
           (md < m1 && md < m2) ? "yes" : "NO",
           (bench_err_p95(&st[M_DEFAULT].e) < bench_err_p95(&st[M_BASE1].e) &&
            bench_err_p95(&st[M_DEFAULT].e) < bench_err_p95(&st[M_BASE2].e)) ? "yes" : "NO",
           md / mp, md / mp <= 0.6 ? "yes" : "NO");
    for (int m = 0; m < M_COUNT; m++)
        bench_err_free(&st[m].e);
    free(W);
    free(Fa);
    free(Ft);
    free(out);
    free(targets);
    mim_xfer_solver_close(&sq);
    mim_xfer_solver_close(&ls);
    mim_xfer_solver_close(&an);
    mim_xfer_topology_close(&topo);
    return 0;
fail:
    fprintf(stderr, "bench: %s\n", mim_error_text(&err));
    mim_xfer_solver_close(&sq);
    mim_xfer_solver_close(&ls);
    mim_xfer_solver_close(&an);
    mim_xfer_topology_close(&topo);
    return -1;
}

static int run_set(const bench_dataset_t *d, void *user)
{
    return run_accuracy(d, *(const uint32_t *)user) ? 1 : 0;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    uint32_t pairs_max = 0;
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i))
            continue;
        if (!strcmp(argv[i], "--pairs-max") && i + 1 < argc) {
            pairs_max = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else if (!strcmp(argv[i], "--settle") && i + 1 < argc) {
            settle = strtod(argv[++i], NULL);
        } else {
            fprintf(stderr, "usage: %s [--vertices N] [--mh DIR | --no-mh] [--pairs-max K] [--settle S]\n", argv[0]);
            return 2;
        }
    }
    printf("settle of the default row: %g\n", settle != 0 ? settle : MIM_XFER_DEFAULT_SETTLE);
    return bench_sets_run(&sets, 4, 12, run_set, &pairs_max);
}
