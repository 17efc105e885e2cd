/* The interaction coordinates' triangulation (seed 002, Section 4.3):
 * mim_ic_build (sample/delaunay.c's Bowyer-Watson where it proves its
 * answer, qhull elsewhere) against qhull alone, in the same run: the
 * median over --runs passes of microseconds a pose-pair, their ratio, how
 * many pose-pairs delaunay.c declined, and whether every edge list is
 * qhull's. Prints figures; never passes or fails (tests/test_delaunay.c
 * tests the agreement).
 *
 * Data: --samples S.jsonl in the samples format (`mimic pairs sample`);
 * without it, --count K generated pose-pairs (tests/support/
 * synthetic_pairs.c) with a capture's noise (up to 2 mm a coordinate).
 *
 * usage: bench_ic_build [--samples S.jsonl | --count K] [--runs R] */
#include "bench_data.h"
#include "internal.h"
#include "synthetic_pairs.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define J MIM_PAIR_JOINTS

int main(int argc, char **argv)
{
    const char *path = NULL;
    uint32_t count = 20000, n = 0;
    int runs = 5;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--samples") && i + 1 < argc) path = argv[++i];
        else if (!strcmp(argv[i], "--count") && i + 1 < argc) count = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) runs = atoi(argv[++i]);
        else {
            const int help = !strcmp(argv[i], "--help");
            fprintf(help ? stdout : stderr, "usage: bench_ic_build [--samples S.jsonl | --count K] [--runs R]\n");
            return help ? 0 : 2;
        }
    }
    if (runs < 1 || runs > 99 || (!path && !count)) {
        fprintf(stderr, "bench_ic_build: --runs 1 to 99, --count at least 1\n");
        return 2;
    }
    double *p = NULL;
    mim_error_t err = {0};
    if (path) {
        char *text = NULL;
        size_t len;
        mim_pairs_samples_t s = {0};
        if (mim_file_read(path, 0, &text, &len, &err) || mim_pairs_samples_parse(text, len, path, &s, &err)) {
            fprintf(stderr, "bench_ic_build: %s\n", mim_error_text(&err));
            free(text);
            return 1;
        }
        free(text), free(s.log_density), free(s.line);
        p = s.joints, n = s.n;
    } else {
        mim_rng_t r;
        mim_rng_seed(&r, 3, 1);
        p = malloc((size_t)count * 3 * J * sizeof *p);
        for (uint32_t i = 0; p && i < count; i++) {
            sp_random_pair(&r, 0.2 + 1.3 * mim_rng_unit(&r), p + (size_t)i * 3 * J);
            for (int k = 0; k < 3 * J; k++) p[(size_t)i * 3 * J + k] += 0.004 * (mim_rng_unit(&r) - 0.5);
        }
        n = count;
    }
    mim_ic_t *fast = malloc((size_t)n * sizeof *fast), *slow = malloc((size_t)n * sizeof *slow);
    if (!p || !fast || !slow) {
        fprintf(stderr, "bench_ic_build: out of memory\n");
        return 1;
    }
    double t_fast[99], t_slow[99];
    for (int r = 0; r < runs; r++) {
        double t0 = mim_now();
        for (uint32_t i = 0; i < n; i++) mim__ic_build_qhull(p + (size_t)i * 3 * J, 3, &slow[i], &err);
        double t1 = mim_now();
        for (uint32_t i = 0; i < n; i++) mim_ic_build(p + (size_t)i * 3 * J, 3, &fast[i], &err);
        double t2 = mim_now();
        t_slow[r] = (t1 - t0) / n * 1e6, t_fast[r] = (t2 - t1) / n * 1e6;
    }
    uint32_t declined = 0, differ = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint8_t have[J][J];
        memset(have, 0, sizeof have);
        declined += mim__delaunay3_edges(p + (size_t)i * 3 * J, J, have) != 0;
        differ += fast[i].n_edges != slow[i].n_edges || memcmp(fast[i].edge, slow[i].edge, fast[i].n_edges * sizeof fast[i].edge[0]);
    }
    const double qh = bench_median(t_slow, runs), ours = bench_median(t_fast, runs);
    printf("%u pose-pairs (%s), median of %d runs, load %.2f: qhull %.2f us each, mim_ic_build %.2f us (%.2fx faster); "
           "delaunay.c declined %u (%.2f %%, qhull's there); edge lists unlike qhull's: %u\n",
           n, path ? path : "generated, 2 mm noise", runs, bench_load_average(), qh, ours, qh / ours, declined, 100.0 * declined / n, differ);
    free(p), free(fast), free(slow);
    return 0;
}
