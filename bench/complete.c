/* Completion of lost landmarks by retrieval (issue 14, seed 002 Section
 * 6): error on 3 lost landmarks, strict leave-one-subject-out. Prints
 * figures; never passes or fails.
 *
 * Each body of the set (every subject, every pose) loses 3 of its 16
 * landmarks (every one of 40 fixed triples drawn once from seed 1), and
 * mim_session_complete fills them from the other subjects' templates
 * (--exclude-subject). Rows: the nearest template alone (k 1, no blend),
 * and the median of k templates with and without the Gaussian blend.
 * Error: distance from each filled landmark to the truth, pooled.
 *
 * usage: bench_complete [--mh DIR | --no-mh] [--synth-vertices N]
 * Stores are built in a temporary folder from the data set's files. */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_db.h"
#include "mim_ingest.h"
#include "mim_session.h"
#include "mim_synth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define TRIPLES 40

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static int run(const char *name, const char *folder, const char *tmp)
{
    char store[4096];
    snprintf(store, sizeof store, "%s/%s-store", tmp, name);
    mim_db_t *db = NULL;
    mim_error_t err = {0};
    mim_db_options_t o = {0};
    mim_ingest_report_t rep;
    char *paths[1] = {(char *)folder};
    if (mim_db_open(&db, store, &o, &err) || mim_ingest_run(db, paths, 1, NULL, &rep, &err)) {
        fprintf(stderr, "%s: %s\n", name, mim_error_text(&err));
        return 1;
    }
    mim_db_close(&db);
    mim_session_t *s = NULL;
    if (mim_session_open(&s, store, NULL, &err)) {
        fprintf(stderr, "%s: %s\n", name, mim_error_text(&err));
        return 1;
    }
    const mim_landmark_map_t *map = mim_session_map(s);
    const uint32_t L = map->count;
    /* every template's landmarks and subject, from the store */
    mim_db_t *rd = NULL;
    mim_db_options_t ro = {.read_only = 1};
    mim_db_open(&rd, store, &ro, &err);
    mim_db_txn_t *t = NULL;
    mim_db_begin(rd, 0, &t, &err);
    mim_db_meta_t meta;
    mim_db_meta_get(t, &meta, &err);
    uint32_t n = (uint32_t)meta.templates;
    float *truth = malloc((size_t)n * L * 3 * sizeof *truth);
    char (*subject)[64] = malloc((size_t)n * sizeof *subject);
    uint32_t k = 0;
    for (uint64_t id = 1; id < meta.next_id && k < n; id++) {
        mim_template_view_t v;
        if (mim_db_template_get(t, id, &v, NULL)) continue;
        for (uint32_t l = 0; l < L; l++) memcpy(truth + ((size_t)k * L + l) * 3, v.positions + 3 * (size_t)map->vertex[l], 12);
        snprintf(subject[k], 64, "%s", v.subject);
        k++;
    }
    mim_db_abort(&t);
    mim_db_close(&rd);
    n = k;
    /* the triples of lost landmarks */
    uint32_t tri[TRIPLES][3];
    mim_rng_t r;
    mim_rng_seed(&r, 1, 0);
    for (int q = 0; q < TRIPLES; q++) {
        do {
            for (int c = 0; c < 3; c++) tri[q][c] = (uint32_t)mim_rng_below(&r, L);
        } while (tri[q][0] == tri[q][1] || tri[q][0] == tri[q][2] || tri[q][1] == tri[q][2]);
    }
    struct { const char *name; mim_session_complete_options_t o; } rows[] = {
        {"nearest template alone (k 1, no blend)", {.k = 1, .no_blend = 1}},
        {"median of k 3, no blend", {.k = 3, .no_blend = 1}},
        {"median of k 3, Gaussian blend (default)", {.k = 3}},
        {"median of k 8, Gaussian blend", {.k = 8}},
        {"median of k 16, Gaussian blend", {.k = 16}},
    };
    const int R = (int)(sizeof rows / sizeof *rows);
    size_t total = (size_t)n * TRIPLES * 3;
    double *e = malloc(total * sizeof *e);
    printf("\n### %s: %u bodies, %d triples of lost landmarks each, leave one subject out\n\n", name, n, TRIPLES);
    printf("| method | mean (mm) | median (mm) | p95 (mm) |\n|---|---|---|---|\n");
    for (int row = 0; row < R; row++) {
        size_t m = 0;
        for (uint32_t b = 0; b < n; b++) {
            mim_session_complete_options_t co = rows[row].o;
            co.exclude_subject = subject[b];
            for (int q = 0; q < TRIPLES; q++) {
                uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
                float in[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX];
                memcpy(in, truth + (size_t)b * L * 3, (size_t)L * 12);
                memset(present, 1, L);
                for (int c = 0; c < 3; c++) present[tri[q][c]] = 0, in[3 * tri[q][c]] = NAN;
                if (mim_session_complete(s, in, present, &co, out, done, &err)) {
                    fprintf(stderr, "%s: %s\n", name, mim_error_text(&err));
                    return 1;
                }
                for (int c = 0; c < 3; c++) {
                    const float *a = out + 3 * tri[q][c], *g = truth + ((size_t)b * L + tri[q][c]) * 3;
                    e[m++] = 1000 * sqrt((a[0] - g[0]) * (a[0] - g[0]) + (a[1] - g[1]) * (a[1] - g[1]) + (a[2] - g[2]) * (a[2] - g[2]));
                }
            }
        }
        double sum = 0;
        for (size_t i = 0; i < m; i++) sum += e[i];
        qsort(e, m, sizeof *e, cmp_d);
        printf("| %s | %.1f | %.1f | %.1f |\n", rows[row].name, sum / m, e[m / 2], e[(size_t)(0.95 * (m - 1))]);
    }
    free(e), free(truth), free(subject);
    mim_session_close(&s);
    return 0;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i)) continue;
        fprintf(stderr, "usage: %s [--vertices N] [--mh DIR | --no-mh]\n", argv[0]);
        return 2;
    }
    char tmp[] = "/tmp/mimic-bench-complete-XXXXXX";
    if (!mkdtemp(tmp)) return 1;
    /* synth: 6 subjects x 12 poses, written as files and ingested */
    char synth_dir[4096];
    snprintf(synth_dir, sizeof synth_dir, "%s/synth", tmp);
    mim_synth_t *sy = NULL;
    mim_error_t err = {0};
    mim_synth_options_t so = {.subjects = 6, .poses = 12, .vertices = sets.vertices, .seed = 1};
    int rc = mim_synth_create(&sy, &so, &err) || mim_synth_write_dataset(sy, synth_dir, &err);
    mim_synth_destroy(&sy);
    if (rc || run("synth", synth_dir, tmp)) rc = 1;
    if (!rc && !sets.no_mh) {
        const char *mh = sets.mh ? sets.mh : bench_mh_dir(sets.mh_buf, sizeof sets.mh_buf);
        if (mh && access(mh, R_OK) == 0) rc = run("mh-bodies", mh, tmp);
        else printf("\n(mh-bodies not found: skipped)\n");
    }
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd)) fprintf(stderr, "bench_complete: could not remove %s\n", tmp);
    return rc;
}
