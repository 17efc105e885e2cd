/* Pose transfer speed (issue 3, point 8; seed 000 Section 3.4). Prints
 * figures; never passes or fails.
 *
 * For each body set (synth at about 7000 vertices, mh-bodies at 13380 when
 * present) and each solver (the paper's square L^c; least squares through
 * L^c plus a rank-16 update, mimic's default; least squares on its own
 * normal-matrix factor, the reference): analysis, factorization, factor
 * size, one plain CHOLMOD solve (3 columns) with the cached factor, the
 * frames of one iteration, one whole iteration (frames + right-hand side +
 * solve; measured as 2 iterations minus 1), and a whole transfer with the
 * default options. Every figure is the median of --runs runs on one core;
 * the ratios compare figures measured in the same run.
 *
 * usage: bench_transfer [--vertices N] [--runs R] [--mh DIR | --no-mh] */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_transfer.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RUNS_MAX 1001

typedef struct timing {
    double open, analyze, factorize, nnz, solve, iteration, whole, iterations;
} timing_t;

static int measure(mim_xfer_topology_t *topo, const bench_dataset_t *d, const mim_xfer_solver_options_t *so,
                   const double *W, const double *Ft, const float *targets, int runs, timing_t *r)
{
    mim_error_t err = {0};
    const uint32_t n = d->n, c = d->map.count;
    static double v[RUNS_MAX], v2[RUNS_MAX];
    mim_xfer_solver_t *s = NULL;
    double t0 = mim_now();
    if (mim_xfer_solver_open(&s, topo, d->map.vertex, c, so, &err)) {
        fprintf(stderr, "bench_transfer: %s\n", mim_error_text(&err));
        return -1;
    }
    r->open = mim_now() - t0;
    mim_xfer_solver_stats_t ss;
    mim_xfer_solver_stats(s, &ss);
    r->analyze = ss.t_analyze;
    r->factorize = ss.t_factorize;
    r->nnz = ss.factor_nnz;
    double *rhs = malloc(3 * (size_t)ss.n_free * sizeof(double));
    double *x = malloc(3 * (size_t)ss.n_free * sizeof(double));
    float *out = malloc(3 * (size_t)n * sizeof(float));
    for (size_t i = 0; i < 3 * (size_t)ss.n_free; i++)
        rhs[i] = (double)(i % 7) - 3.0;
    for (int k = 0; k < runs; k++) {
        t0 = mim_now();
        mim_xfer_solver_solve(s, rhs, x, &err);
        v[k] = mim_now() - t0;
    }
    r->solve = bench_median(v, runs);
    mim_xfer_options_t o1 = {.max_iterations = 1, .tol = -1, .no_early_stop = 1};
    mim_xfer_options_t o2 = {.max_iterations = 2, .tol = -1, .damping = 1, .no_early_stop = 1};
    for (int k = 0; k < runs; k++) {
        t0 = mim_now();
        mim_xfer_transfer(s, W, n, Ft, targets, c, &o1, out, NULL, &err);
        v[k] = mim_now() - t0;
        t0 = mim_now();
        mim_xfer_transfer(s, W, n, Ft, targets, c, &o2, out, NULL, &err);
        v2[k] = mim_now() - t0;
    }
    r->iteration = bench_median(v2, runs) - bench_median(v, runs);
    mim_xfer_report_t rep = {0};
    for (int k = 0; k < runs; k++) {
        t0 = mim_now();
        mim_xfer_transfer(s, W, n, Ft, targets, c, NULL, out, &rep, &err);
        v[k] = mim_now() - t0;
    }
    r->whole = bench_median(v, runs);
    r->iterations = rep.iterations;
    mim_xfer_solver_close(&s);
    free(rhs);
    free(x);
    free(out);
    return 0;
}

static int run(const bench_dataset_t *d, int runs)
{
    mim_error_t err = {0};
    const uint32_t n = d->n, c = d->map.count;
    static double v[RUNS_MAX];
    mim_xfer_topology_t *topo = NULL;
    double t0 = mim_now();
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err)) {
        fprintf(stderr, "bench_transfer: %s\n", mim_error_text(&err));
        return -1;
    }
    double t_topo = mim_now() - t0;
    double *W = malloc(3 * (size_t)n * sizeof(double));
    double *Fa = malloc(9 * (size_t)n * sizeof(double));
    double *Ft = malloc(9 * (size_t)n * sizeof(double));
    double *pd = malloc(3 * (size_t)n * sizeof(double));
    float *targets = malloc(3 * (size_t)c * sizeof(float));
    /* avatar: subject 0 at rest; template: subject 1 in pose 3; landmarks:
     * subject 0 in pose 3 */
    const float *rest = d->pos[0], *tmpl = d->pos[1 * d->poses + 3], *truth = d->pos[3];
    for (uint32_t k = 0; k < c; k++)
        for (int q = 0; q < 3; q++)
            targets[3 * k + q] = truth[3 * (size_t)d->map.vertex[k] + q];
    for (size_t i = 0; i < 3 * (size_t)n; i++)
        pd[i] = tmpl[i];
    for (int k = 0; k < runs; k++) {
        t0 = mim_now();
        mim_xfer_frames_d(topo, pd, Ft);
        v[k] = mim_now() - t0;
    }
    double t_frames = bench_median(v, runs);
    mim_xfer_frames(topo, tmpl, Ft);
    mim_xfer_frames(topo, rest, Fa);
    mim_xfer_encode(topo, rest, Fa, W);

    static const struct {
        const char *name;
        mim_xfer_solver_options_t so;
    } cfg[] = {
        {"paper: square L^c", {.formulation = MIM_XFER_SQUARE}},
        {"least squares, L^c + rank-c update (default)", {.formulation = MIM_XFER_LEAST_SQUARES}},
        {"least squares, normal-matrix factor", {.formulation = MIM_XFER_LEAST_SQUARES, .normal_factor = 1}},
    };
    enum { NCFG = sizeof cfg / sizeof cfg[0] };
    timing_t t[NCFG];
    for (int k = 0; k < NCFG; k++)
        if (measure(topo, d, &cfg[k].so, W, Ft, targets, runs, &t[k]))
            return -1;
    printf("\n## %s, %u vertices, %u landmarks (median of %d runs, one core)\n\n", d->name, n, c, runs);
    printf("adjacency build %.3f ms; frames of one iteration %.3f ms\n\n", 1e3 * t_topo, 1e3 * t_frames);
    printf("| solver | open ms (analysis, factorization) | factor nnz | plain solve ms | iteration ms | "
           "iteration / plain solve | whole transfer ms (iterations) |\n|---|---:|---:|---:|---:|---:|---:|\n");
    for (int k = 0; k < NCFG; k++)
        printf("| %s | %.2f (%.2f, %.2f) | %.0f | %.3f | %.3f | %.2f | %.3f (%.0f) |\n", cfg[k].name,
               1e3 * t[k].open, 1e3 * t[k].analyze, 1e3 * t[k].factorize, t[k].nnz, 1e3 * t[k].solve,
               1e3 * t[k].iteration, t[k].iteration / t[k].solve, 1e3 * t[k].whole, t[k].iterations);
    printf("\nleast squares: default iteration / plain solve of the normal-matrix factor = %.2f; "
           "default whole transfer / normal-factor whole transfer = %.2f\n",
           t[1].iteration / t[2].solve, t[1].whole / t[2].whole);
    free(W);
    free(Fa);
    free(Ft);
    free(pd);
    free(targets);
    mim_xfer_topology_close(&topo);
    return 0;
}

static int run_set(const bench_dataset_t *d, void *user) { return run(d, *(const int *)user); }

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    int runs = 201;
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i))
            continue;
        if (!strcmp(argv[i], "--runs") && i + 1 < argc) {
            runs = atoi(argv[++i]);
        } else {
            fprintf(stderr, "usage: %s [--vertices N] [--runs R (1..%d)] [--mh DIR | --no-mh]\n", argv[0],
                    RUNS_MAX);
            return 2;
        }
    }
    if (runs < 1 || runs > RUNS_MAX) {
        fprintf(stderr, "bench_transfer: --runs %d outside 1..%d\n", runs, RUNS_MAX);
        return 2;
    }
    return bench_sets_run(&sets, 2, 4, run_set, &runs);
}
