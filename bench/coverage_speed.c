/* Coverage's speed (seed 002, eq. 13; issue 31): truths x samples per
 * second of mim_sample_coverage for D_C, D_I and D_S, the exhaustive scan
 * (every distance) against the bounded search in the same run, and how
 * many distances the bounds leave to compute. Prints figures; never
 * passes or fails (the answers' equality is tested by
 * tests/test_pairs_coverage.c; here a mismatch is printed, never hidden).
 * bench/pairs_coverage.sh is another thing: the paper's Fig. 9 figures.
 *
 * Data: --truth T.jsonl and --samples S.jsonl in the samples format
 * (`mimic pairs export`, `mimic pairs sample`; bench/coverage_speed.sh
 * makes them from the shared data); without them, generated sets
 * (tests/support/synthetic_pairs.c): --truths M random pose-pairs and
 * --count K samples, each a new random pose-pair or, 2 times in 5, the
 * one before again (a chain's refused step).
 *
 * For each distance: the scan on one thread over the first --scan truths
 * (the reference), the bounded search on one thread over the same truths
 * (its answers compared with the scan's, bit for bit), and the bounded
 * search on --threads threads (default: the cores) over every truth: the
 * median of --runs runs each, in truths x samples per second. Also the
 * samples prepared per second (mim_pair_prepare_many, their triangulations), which `mimic
 * pairs coverage` does first.
 *
 * usage: bench_pairs_coverage [--truth T.jsonl --samples S.jsonl | --truths M --count K]
 *                             [--scan N] [--runs R] [--threads T] [--metric ic|cartesian|shape] */
#include "bench_data.h"
#include "mim_sample.h"
#include "synthetic_pairs.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define J MIM_PAIR_JOINTS

static double *read_pairs(const char *path, uint32_t *n)
{
    char *text = NULL;
    size_t len;
    mim_error_t err = {0};
    mim_pairs_samples_t s = {0};
    if (mim_file_read(path, 0, &text, &len, &err) || mim_pairs_samples_parse(text, len, path, &s, &err)) {
        fprintf(stderr, "bench_pairs_coverage: %s\n", mim_error_text(&err));
        free(text);
        return NULL;
    }
    free(text), free(s.log_density), free(s.line);
    *n = s.n;
    return s.joints;
}

static double *generate(uint32_t n, uint64_t stream, int repeats)
{
    double *p = malloc((size_t)n * 3 * J * sizeof *p);
    mim_rng_t r;
    mim_rng_seed(&r, 1, stream);
    for (uint32_t i = 0; p && i < n; i++) {
        if (repeats && i && mim_rng_below(&r, 5) < 2) memcpy(p + (size_t)i * 3 * J, p + (size_t)(i - 1) * 3 * J, 3 * J * sizeof *p);
        else sp_random_pair(&r, 0.8, p + (size_t)i * 3 * J);
    }
    return p;
}

static mim_pair_prep_t *prepare(const double *joints, uint32_t n, uint32_t threads, unsigned parts, double *per_s)
{
    mim_pair_prep_t *p = malloc((size_t)n * sizeof *p);
    mim_error_t err = {0};
    uint32_t bad = 0;
    double t0 = mim_now();
    if (!p || mim_pair_prepare_many(joints, n, threads, parts, p, &bad, &err)) {
        fprintf(stderr, "bench_pairs_coverage: pose-pair %u: %s\n", bad + 1, mim_error_text(&err));
        free(p);
        return NULL;
    }
    *per_s = n / (mim_now() - t0);
    return p;
}

/* The median over runs of truths x samples per second; res gets the last
 * run's counts, near/which its answers. */
static double rate(const mim_pair_prep_t *g, uint32_t m, const mim_pair_prep_t *s, uint32_t k, mim_sample_metric_t metric,
                   const mim_sample_coverage_options_t *o, uint32_t runs, mim_sample_coverage_t *res)
{
    double v[64];
    mim_error_t err = {0};
    runs = runs > 64 ? 64 : runs;
    for (uint32_t r = 0; r < runs; r++) {
        double t0 = mim_now();
        if (mim_sample_coverage(g, m, s, k, metric, o, res, &err)) {
            fprintf(stderr, "bench_pairs_coverage: %s\n", mim_error_text(&err));
            return 0;
        }
        v[r] = (double)m * k / (mim_now() - t0);
    }
    return bench_median(v, (int)runs);
}

int main(int argc, char **argv)
{
    const char *truth_path = NULL, *samples_path = NULL;
    uint32_t m = 200, k = 3000, scan = 10, runs = 3, only = 3;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    uint32_t threads = cores > 0 ? (uint32_t)cores : 1;
    static const char *const names[3] = {"ic", "cartesian", "shape"}, *const labels[3] = {"D_I", "D_C", "D_S"};
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--truth") && i + 1 < argc) truth_path = argv[++i];
        else if (!strcmp(argv[i], "--samples") && i + 1 < argc) samples_path = argv[++i];
        else if (!strcmp(argv[i], "--truths") && i + 1 < argc) m = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--count") && i + 1 < argc) k = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--scan") && i + 1 < argc) scan = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) runs = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc) threads = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--metric") && i + 1 < argc) {
            for (only = 0; only < 3 && strcmp(argv[i + 1], names[only]); only++) {}
            i++;
        } else {
            fprintf(stderr, "usage: bench_pairs_coverage [--truth T.jsonl --samples S.jsonl | --truths M --count K]\n"
                            "                            [--scan N] [--runs R] [--threads T] [--metric ic|cartesian|shape]\n");
            return 2;
        }
    }
    if (!truth_path != !samples_path || !m || !k || !scan || !runs || !threads || only > 3) {
        fprintf(stderr, "bench_pairs_coverage: --truth and --samples together; counts of 1 or more; a known --metric\n");
        return 2;
    }
    double *tj = truth_path ? read_pairs(truth_path, &m) : generate(m, 1, 0);
    double *sj = samples_path ? read_pairs(samples_path, &k) : generate(k, 2, 1);
    if (!tj || !sj) return 1;
    double prep_rate;
    mim_pair_prep_t *g = prepare(tj, m, threads, MIM_PREP_ALL, &prep_rate),
                    *s = g ? prepare(sj, k, threads, MIM_PREP_TRIANGULATION, &prep_rate) : NULL;
    if (!s) return 1;
    scan = scan < m ? scan : m;
    printf("%s: %u truths x %u samples; scan and 1-thread figures over the first %u truths; %u threads; median of %u runs; "
           "load average %.2f\n",
           truth_path ? "files" : "generated", m, k, scan, threads, runs, bench_load_average());
    printf("samples prepared (triangulation, as for every distance): %.0f pose-pairs/s on %u threads\n\n", prep_rate, threads);
    printf("     first %u truths:%32s | all %u truths, bounds on %u threads:\n", scan, "", m, threads);
    printf("%-4s %12s %12s %6s %12s %6s | %12s %10s %10s %10s  %s\n", "", "scan 1 thr", "bounds 1 thr", "x",
           "bounds", "x", "pairs/s", "distances", "aligned", "given up", "answers");
    double *near0 = malloc(scan * sizeof *near0), *near1 = malloc(scan * sizeof *near1);
    uint32_t *which0 = malloc(scan * sizeof *which0), *which1 = malloc(scan * sizeof *which1);
    if (!near0 || !near1 || !which0 || !which1) return 1;
    for (int mt = 0; mt < 3; mt++) {
        if (only < 3 && mt != (int)only) continue;
        const mim_sample_metric_t metric = (mim_sample_metric_t)mt;
        const mim_sample_coverage_options_t full = {.threads = 1, .exhaustive = 1}, one = {.threads = 1},
                                            all = {.threads = threads};
        mim_sample_coverage_t r0 = {.nearest = near0, .which = which0}, r1 = {.nearest = near1, .which = which1}, ra = {0};
        const double v0 = rate(g, scan, s, k, metric, &full, runs, &r0), v1 = rate(g, scan, s, k, metric, &one, runs, &r1);
        uint32_t bad = 0;
        for (uint32_t i = 0; i < scan; i++) bad += memcmp(&near0[i], &near1[i], sizeof near0[i]) || which0[i] != which1[i];
        const double vt = rate(g, scan, s, k, metric, &all, runs, &r1);
        for (uint32_t i = 0; i < scan; i++) bad += memcmp(&near0[i], &near1[i], sizeof near0[i]) || which0[i] != which1[i];
        const double va = rate(g, m, s, k, metric, &all, runs, &ra);
        const double pairs = (double)m * k;
        printf("%-4s %12.0f %12.0f %6.1f %12.0f %6.1f | %12.0f %9.3f%% %9.3f%% %9.3f%%  %s\n", labels[mt], v0, v1, v1 / v0, vt,
               vt / v0, va, 100 * ra.distances / pairs, 100 * ra.aligned / pairs, 100 * ra.cut / pairs,
               bad ? "DIFFER from the scan's" : "the scan's, to the bit");
    }
    printf("\n(truths x samples per second; x: against the scan on one thread; bounds: on %u threads; distances:\n"
           "computed in full, of all truth-sample pairs; aligned: D_I's and D_S's samples aligned and bounded again;\n"
           "given up: of all pairs, those stopped part-way; answers: the first truths' nearest distances and samples)\n",
           threads);
    free(near0), free(near1), free(which0), free(which1), free(g), free(s), free(tj), free(sj);
    return 0;
}
