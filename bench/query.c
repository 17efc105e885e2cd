/* Recognition speed (issue 4): latency of one frame (median, p99) for
 * indexes of 100, 10 000 and 1 000 000 templates, the index build time,
 * the time to open a stored index (load the blob and its k-NN forests), and
 * batch throughput, on one core. The paper's recognition took 12 ms
 * (seed 000, Section 4.2): that is the reference ratio. A linear scan over
 * all templates' descriptors is measured in the same run as a second
 * reference, and at the large size the exact k-NN (linear scan inside the
 * class) is compared with the kd-forest, with the recall of its first hit.
 *
 * Opening is timed two ways: the copying load of the blob from memory
 * (mim_index_load), and mim_query_open of the blob stored in a store of
 * its own (a temporary directory; the store's pages are in the page
 * cache, as they are after mimic index or a first open), which is what
 * mimic query and serve do: since issue 16 it uses the blob in place and
 * verifies its sections, and loads a class's forest, when a query first
 * needs them. So the store-opened index is the one queried, and the
 * first query into each class is timed on its own (its cost is that
 * class's verification and forest load), beside the median, p99 and max
 * of all. Memory: the process's private (anonymous) and file-backed
 * resident memory after the open and after the queries (/proc).
 *
 * Templates are descriptor-only, made through the index API: the landmarks
 * of synth bodies (8 subjects x 12 poses) jittered by Gaussian noise of
 * 1.5 cm per coordinate, so every template is distinct; query frames are
 * fresh jitters of the same bodies.
 *
 *   bench_query [--sizes 100,10000,1000000] [--queries N] [--vote-below P]
 *
 * --vote-below P sets the k-NN vote's threshold of mim_index_query
 * (issue 15): 2 makes every frame vote (the vote's worst case), -1 none;
 * by default the index's (0.5).
 * Prints a Markdown table. */
#include "bench_data.h"
#include "mim_index.h"
#include "mim_query.h"

#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static uint64_t rng_state = 777;
static double vote_below; /* --vote-below: the k-NN vote's threshold (0: the index default) */
static int ab;            /* --ab: the index from the store against the copied load, interleaved */
static double uniform(void)
{
    rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return ((rng_state >> 11) + 0.5) / 9007199254740992.0;
}
static double gauss(void) { return sqrt(-2 * log(uniform())) * cos(2 * M_PI * uniform()); }

static void jitter(const float *base, uint32_t L, float *out)
{
    for (uint32_t i = 0; i < 3 * L; i++) out[i] = base[i] + (float)(0.015 * gauss());
}

typedef struct {
    double median_us, p99_us, per_frame_us, max_us;
    double first_max_us, first_mean_us; /* the first query into each class */
    uint32_t first_classes;
    double recall;     /* first hit equal to the exact one (-1: not measured) */
    double dist_ratio; /* mean first-hit distance / exact first-hit distance */
} lat_t;

/* Latency of nq single-frame queries, one at a time; missing: landmarks
 * dropped per frame; checks: kd-forest checks (0: the index's); exact: an
 * index with exact k-NN to compare the first hit with. */
static lat_t measure(const mim_index_t *ix, const float *frames, uint32_t nq, uint32_t L, int missing, uint32_t checks,
                     const mim_index_t *exact)
{
    double *t = malloc(sizeof(double) * nq);
    uint8_t present[64];
    mim_index_query_options_t qo = {.k = 1, .checks = checks, .vote_below = vote_below};
    mim_index_answer_t a;
    mim_index_hit_t h, he;
    uint32_t agree = 0;
    double ratio = 0, mx = 0, fmax = 0, fsum = 0;
    uint32_t nfirst = 0;
    uint8_t seen[4096] = {0};
    double t0 = mim_now();
    for (uint32_t i = 0; i < nq; i++) {
        memset(present, 1, L);
        for (int m = 0; m < missing; m++) present[(i * 7 + (uint32_t)m * 5) % L] = 0;
        double s = mim_now();
        int rc = mim_index_query(ix, frames + (size_t)i * 3 * L, missing ? present : NULL, &qo, &a, &h, NULL);
        t[i] = mim_now() - s;
        if (rc) fprintf(stderr, "query %u failed (%d)\n", i, rc);
        if (t[i] > mx) mx = t[i];
        if (!rc && a.cls < 4096 && !seen[a.cls]) {
            seen[a.cls] = 1, nfirst++, fsum += t[i];
            if (t[i] > fmax) fmax = t[i];
        }
    }
    double total = mim_now() - t0;
    if (exact)
        for (uint32_t i = 0; i < nq; i++) {
            mim_index_answer_t ae;
            mim_index_query(ix, frames + (size_t)i * 3 * L, NULL, &qo, &a, &h, NULL);
            mim_index_query(exact, frames + (size_t)i * 3 * L, NULL, &qo, &ae, &he, NULL);
            agree += he.id == h.id;
            ratio += he.distance > 0 ? h.distance / he.distance : 1;
        }
    lat_t r = {bench_median(t, (int)nq) * 1e6, bench_quantile(t, (int)nq, 0.99) * 1e6, total / nq * 1e6, mx * 1e6,
               fmax * 1e6, nfirst ? fsum / nfirst * 1e6 : 0, nfirst, -1, -1};
    if (exact) r.recall = (double)agree / nq, r.dist_ratio = ratio / nq;
    free(t);
    return r;
}

/* The in-run reference: an exact linear scan over all templates' d angles. */
static double linear_scan_us(const float *desc, uint32_t n, uint32_t d, const float *q)
{
    double s = mim_now();
    float best = INFINITY;
    uint32_t arg = 0;
    for (uint32_t i = 0; i < n; i++) {
        const float *v = desc + (size_t)i * d;
        float s2 = 0;
        for (uint32_t f = 0; f < d; f++) s2 += (q[f] - v[f]) * (q[f] - v[f]);
        if (s2 < best) best = s2, arg = i;
    }
    volatile uint32_t sink = arg;
    (void)sink;
    return (mim_now() - s) * 1e6;
}

/* resident memory of this process, MiB: private (anonymous) and file-backed */
static void rss(double *anon, double *file)
{
    *anon = *file = -1;
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    while (f && fgets(line, sizeof line, f)) {
        long kb;
        if (sscanf(line, "RssAnon: %ld", &kb) == 1) *anon = kb / 1024.0;
        if (sscanf(line, "RssFile: %ld", &kb) == 1) *file = kb / 1024.0;
    }
    if (f) fclose(f);
}

/* The blob in a store of its own (dir), opened as mimic query opens it. */
static int store_open(const char *dir, const void *blob, size_t len, mim_db_t **db, mim_query_t **q, double *ms)
{
    mim_error_t err = {0};
    mim_db_txn_t *t = NULL;
    mim_db_index_meta_t bm = {0};
    int rc = mim_db_open(db, dir, NULL, &err);
    if (!rc) rc = mim_db_begin(*db, 1, &t, &err);
    if (!rc) rc = mim_db_index_put(t, blob, len, &bm, &err);
    if (!rc) rc = mim_db_commit(&t, &err);
    if (!rc) {
        double t0 = mim_now();
        rc = mim_query_open(q, *db, &err);
        *ms = (mim_now() - t0) * 1e3;
    }
    if (rc) fprintf(stderr, "store open failed: %s\n", mim_error_text(&err));
    return rc;
}

int main(int argc, char **argv)
{
    uint32_t sizes[8] = {100, 10000, 1000000}, n_sizes = 3, nq = 2000;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--sizes") && i + 1 < argc) {
            n_sizes = 0;
            for (char *p = strtok(argv[++i], ","); p && n_sizes < 8; p = strtok(NULL, ",")) sizes[n_sizes++] = (uint32_t)atol(p);
        } else if (!strcmp(argv[i], "--queries") && i + 1 < argc) {
            nq = (uint32_t)atol(argv[++i]);
        } else if (!strcmp(argv[i], "--vote-below") && i + 1 < argc) {
            vote_below = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--ab")) {
            ab = 1;
        } else {
            fprintf(stderr, "usage: bench_query [--sizes 100,10000,1000000] [--queries N] [--vote-below P] [--ab]\n");
            return 2;
        }
    }
    /* one core: pin to the CPU we start on */
    cpu_set_t cs;
    CPU_ZERO(&cs);
    CPU_SET(sched_getcpu() < 0 ? 0 : sched_getcpu(), &cs);
    sched_setaffinity(0, sizeof cs, &cs);

    bench_dataset_t ds;
    if (bench_load_synth(&ds, 8, 12, 3000)) return 2;
    uint32_t L = ds.map.count, nb = ds.subjects * ds.poses;
    if (nb > 96) return 2;
    float *base = malloc(sizeof(float) * 3 * L * nb);
    for (uint32_t b = 0; b < nb; b++)
        for (uint32_t l = 0; l < L; l++) memcpy(base + 3 * (L * b + l), ds.pos[b] + 3 * ds.map.vertex[l], 12);
    char names[96][2][16];
    for (uint32_t b = 0; b < nb; b++) {
        snprintf(names[b][0], 16, "s%u", b / ds.poses);
        snprintf(names[b][1], 16, "p%u", b % ds.poses);
    }
    float *frames = malloc(sizeof(float) * 3 * L * nq);
    for (uint32_t i = 0; i < nq; i++) jitter(base + 3 * L * (i % nb), L, frames + (size_t)i * 3 * L);

    printf("| templates | build (s) | blob (MiB) | load, copied (ms) | open from the store (ms) | SVs | median (us) | p99 (us) | "
           "max (us) | first query a class: max, mean (us) | batch (frames/s) | 1 missing: median, max (us) | "
           "linear scan (us) | linear scan / median | RSS after open: private, file (MiB) | after queries |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    fflush(stdout);
    for (uint32_t si = 0; si < n_sizes; si++) {
        uint32_t n = sizes[si];
        float *lm = malloc(sizeof(float) * 3 * L * (size_t)n);
        uint64_t *ids = malloc(sizeof(uint64_t) * n);
        const char **sp = malloc(sizeof(char *) * n), **pp = malloc(sizeof(char *) * n);
        if (!lm || !ids || !sp || !pp) return 2;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t b = i % nb;
            jitter(base + 3 * L * b, L, lm + (size_t)i * 3 * L);
            ids[i] = i + 1, sp[i] = names[b][0], pp[i] = names[b][1];
        }
        int32_t parent[MIM_LANDMARKS_MAX]; /* as mimic index: canonical proportions */
        mim_index_input_t in = {n, L, lm, ids, sp, pp, ds.map.mirror,
                                mim_index_skeleton(&ds.map, parent) ? NULL : parent};
        mim_index_options_t o = {0};
        mim_index_report_t rep;
        mim_index_t *ix = NULL, *ix2 = NULL, *exact = NULL;
        mim_error_t err = {0};
        if (mim_index_build(&ix, &in, &o, &rep, &err)) {
            fprintf(stderr, "build failed: %s\n", mim_error_text(&err));
            return 2;
        }
        void *blob;
        size_t len;
        mim_index_save(ix, &blob, &len, NULL);
        double t0 = mim_now();
        if (mim_index_load(&ix2, blob, len, &err)) {
            fprintf(stderr, "load failed: %s\n", mim_error_text(&err));
            return 2;
        }
        double open_ms = (mim_now() - t0) * 1e3;
        mim_index_t *copied = ix2;
        if (!ab) mim_index_close(&ix2), copied = NULL;
        mim_index_close(&ix);
        char dir[] = "/tmp/bench_query_XXXXXX";
        if (!mkdtemp(dir)) return 2;
        mim_db_t *db = NULL;
        mim_query_t *qy = NULL;
        double store_ms = 0, ra0, rf0, ra1, rf1;
        if (store_open(dir, blob, len, &db, &qy, &store_ms)) return 2;
        free(blob);
        rss(&ra0, &rf0);
        ix2 = (mim_index_t *)mim_query_index(qy);
        lat_t lt = measure(ix2, frames, nq, L, 0, 0, NULL);
        lat_t lm1 = measure(ix2, frames, nq < 500 ? nq : 500, L, 1, 0, NULL);
        rss(&ra1, &rf1);
        /* the in-run reference: linear scan over all n descriptors */
        mim_index_info_t info;
        mim_index_get_info(ix2, &info);
        float *desc = malloc(sizeof(float) * (size_t)n * info.d), q[256];
        const uint32_t *sel = mim_index_selected(ix2);
        for (uint32_t i = 0; i < n; i++)
            mim_index_descriptor(lm + (size_t)i * 3 * L, NULL, L, sel, info.d, desc + (size_t)i * info.d);
        double lin[64];
        for (int r = 0; r < 64; r++) {
            mim_index_descriptor(frames + (size_t)r * 3 * L, NULL, L, sel, info.d, q);
            lin[r] = linear_scan_us(desc, n, info.d, q);
        }
        double lin_med = bench_median(lin, 64);
        free(desc);
        printf("| %u | %.2f | %.1f | %.1f | %.1f | %u | %.1f | %.1f | %.0f | %.0f, %.0f (%u classes) | %.0f | %.1f, %.0f | %.0f | "
               "%.0f | %.0f, %.0f | %.0f, %.0f |\n",
               n, rep.seconds, (double)len / 1048576.0, open_ms, store_ms, rep.support_vectors, lt.median_us, lt.p99_us,
               lt.max_us, lt.first_max_us, lt.first_mean_us, lt.first_classes, 1e6 / lt.per_frame_us, lm1.median_us,
               lm1.max_us, lin_med, lin_med / lt.median_us, ra0, rf0, ra1, rf1);
        if (copied) { /* every class warm in both: the same queries, alternating rounds */
            printf("\n--ab at %u templates, all classes used once before (medians and p99 in us):", n);
            for (int round = 0; round < 6; round++) {
                lat_t r = measure(round % 2 ? copied : ix2, frames, nq, L, 0, 0, NULL);
                printf(" %s %.1f/%.1f;", round % 2 ? "copied" : "from the store", r.median_us, r.p99_us);
            }
            printf("\n\n");
            mim_index_close(&copied);
        }
        if (info.forests_loaded + info.forests_built)
            printf("\nopen at %u templates: %u kd-forests read from the blob, %u built (the blob holds them since "
                   "issue 16; before, every open built them)\n\n",
                   n, info.forests_loaded, info.forests_built);
        fflush(stdout);
        if (rep.exact_classes < rep.n_classes) {
            /* the same index with exact k-NN in every class: latency and the
             * kd-forest's recall of the first hit */
            mim_index_options_t oe = {.exact_max = UINT32_MAX, .C = rep.C, .gamma = rep.gamma};
            if (mim_index_build(&exact, &in, &oe, NULL, &err) == 0) {
                lat_t le = measure(exact, frames, nq, L, 0, 0, NULL);
                printf("\nAt %u templates, %u of %u classes use the kd-forest (4 trees). Exact k-NN (FLANN's linear "
                       "scan of the class) instead: median %.1f us, p99 %.1f us. The kd-forest by checks (the index "
                       "default is 128):\n\n",
                       n, rep.n_classes - rep.exact_classes, rep.n_classes, le.median_us, le.p99_us);
                printf("| checks | median (us) | p99 (us) | first hit = exact | mean distance / exact distance |\n"
                       "|---|---|---|---|---|\n");
                static const uint32_t cks[] = {32, 64, 128, 256, 512};
                for (int c = 0; c < 5; c++) {
                    lat_t rc = measure(ix2, frames, nq, L, 0, cks[c], exact);
                    printf("| %u | %.1f | %.1f | %.1f %% | %.3f |\n", cks[c], rc.median_us, rc.p99_us, 100 * rc.recall,
                           rc.dist_ratio);
                    fflush(stdout);
                }
                mim_index_close(&exact);
            }
        }
        ix2 = NULL; /* the query's */
        mim_query_close(&qy);
        mim_db_close(&db);
        char path[64];
        snprintf(path, sizeof path, "%s/data.mdb", dir), unlink(path);
        snprintf(path, sizeof path, "%s/lock.mdb", dir), unlink(path);
        rmdir(dir);
        free(lm), free(ids), free(sp), free(pp);
    }
    free(base), free(frames);
    bench_dataset_free(&ds);
    return 0;
}
