/* Where a key frame's time goes (issue 16, item 2), at about 7000 vertices,
 * through the session as serve makes its key frames: the query (recognition
 * of the landmarks), the template's frames (read and unpacked, or the
 * cached ones; for the orientation drive the avatar's rest frames turned
 * per segment) and the solve (the iterations of the template drive, one
 * solve for the orientation drive). The solve is split further with two
 * references measured in the same run: one plain CHOLMOD solve of the
 * 3-column system and one computation of a pose's frames; the rest of an
 * iteration is the right-hand side and the rank-16 correction. A third
 * reference splits the plain solve's three columns 2 + 1 over two threads
 * (a second solver on a worker woken per solve): its wall time and its
 * solving time in all, whether threads across the right-hand sides pay
 * (issue 31). Fan-out (sending a frame to clients) is not here:
 * bench/serve.c measures it.
 *
 * The stream: subject 1's landmarks (the avatar is subject 0's rest pose),
 * moving from one pose to the next over 12 key frames, so that consecutive
 * key frames mostly share a template, as a wearer holding poses does. The
 * orientation drive gets each segment's rotation from the avatar's rest
 * landmark skeleton to the frame's (mim_xfer_segment_correction: what a
 * vest's sensors would give, without the twist). The skeleton drive
 * (--drive skeleton: the same rotations, found by the session from the
 * landmarks) is the third stream.
 *
 * --relative off: the template drive without relative transfer (issue 15;
 * the default is on, as mimic's). --settle S: the iteration's
 * mim_xfer_options_t.settle (< 0: none, as before issue 31).
 *
 *   bench_keyframe [--vertices N] [--keys K] [--relative on|off] [--settle S]
 * Prints a Markdown table of medians; never passes or fails. */
#include "bench_data.h"
#include "mim_db.h"
#include "mim_ingest.h"
#include "mim_query.h"
#include "mim_session.h"
#include "mim_synth.h"
#include "mim_transfer.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define STEPS 12 /* key frames from one pose to the next */

typedef struct {
    double *query, *tmpl, *solve, *total;
    double iterations;
    uint32_t n, cache_hits, by_solves[5]; /* key frames of 1, 2, 3, 4, more solves */
} phase_t;

static double med(double *v, uint32_t n) { return bench_median(v, (int)n) * 1e3; }

/* The worker of the split solve: one column a wake-up. */
typedef struct {
    pthread_mutex_t m;
    pthread_cond_t c;
    int go, done, quit;
    mim_xfer_solver_t *s;
    const double *rhs;
    double *x, t;
} worker_t;

static void *work(void *arg)
{
    worker_t *w = arg;
    pthread_mutex_lock(&w->m);
    for (;;) {
        while (!w->go && !w->quit) pthread_cond_wait(&w->c, &w->m);
        if (w->quit) break;
        w->go = 0;
        pthread_mutex_unlock(&w->m);
        double t0 = mim_now();
        mim_xfer_solver_solve_columns(w->s, w->rhs, 1, w->x, NULL);
        double t = mim_now() - t0;
        pthread_mutex_lock(&w->m);
        w->t = t, w->done = 1;
        pthread_cond_broadcast(&w->c);
    }
    pthread_mutex_unlock(&w->m);
    return NULL;
}

/* The plain solve with its columns split 2 + 1 over this thread and a
 * worker, each with its own solver (a CHOLMOD common a thread): wall and
 * solving time (both threads') in seconds, medians of runs. */
static int split_solve(const mim_xfer_topology_t *topo, const mim_landmark_map_t *map, const double *rhs, uint32_t nf,
                       int runs, double *wall, double *cpu, mim_error_t *err)
{
    mim_xfer_solver_t *a = NULL, *b = NULL;
    double *x = malloc(3 * sizeof(double) * nf), *tw = malloc(sizeof(double) * runs), *tc = malloc(sizeof(double) * runs);
    int rc = !x || !tw || !tc ? mim_error_set(err, MIM_ENOMEM, "out of memory")
                              : mim_xfer_solver_open(&a, topo, map->vertex, map->count, NULL, err) ||
                                    mim_xfer_solver_open(&b, topo, map->vertex, map->count, NULL, err);
    worker_t w = {.s = b, .rhs = rhs + 2 * (size_t)nf, .x = x ? x + 2 * (size_t)nf : NULL};
    pthread_t th;
    if (!rc) {
        pthread_mutex_init(&w.m, NULL), pthread_cond_init(&w.c, NULL);
        rc = pthread_create(&th, NULL, work, &w) ? mim_error_set(err, MIM_EUNSUPPORTED, "no thread") : 0;
    }
    for (int r = 0; !rc && r < runs; r++) {
        double t0 = mim_now();
        pthread_mutex_lock(&w.m);
        w.go = 1, w.done = 0;
        pthread_cond_broadcast(&w.c);
        pthread_mutex_unlock(&w.m);
        mim_xfer_solver_solve_columns(a, rhs, 2, x, NULL);
        double t1 = mim_now();
        pthread_mutex_lock(&w.m);
        while (!w.done) pthread_cond_wait(&w.c, &w.m);
        pthread_mutex_unlock(&w.m);
        tw[r] = mim_now() - t0, tc[r] = t1 - t0 + w.t;
    }
    if (!rc) {
        pthread_mutex_lock(&w.m);
        w.quit = 1;
        pthread_cond_broadcast(&w.c);
        pthread_mutex_unlock(&w.m);
        pthread_join(th, NULL);
        pthread_mutex_destroy(&w.m), pthread_cond_destroy(&w.c);
        *wall = bench_median(tw, runs), *cpu = bench_median(tc, runs);
    }
    mim_xfer_solver_close(&a), mim_xfer_solver_close(&b);
    free(x), free(tw), free(tc);
    return rc;
}

int main(int argc, char **argv)
{
    uint32_t vertices = 7000, keys = 600;
    int relative = 0;
    double settle = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--vertices") && i + 1 < argc) vertices = (uint32_t)atol(argv[++i]);
        else if (!strcmp(argv[i], "--keys") && i + 1 < argc) keys = (uint32_t)atol(argv[++i]);
        else if (!strcmp(argv[i], "--relative") && i + 1 < argc && (!strcmp(argv[i + 1], "on") || !strcmp(argv[i + 1], "off")))
            relative = strcmp(argv[++i], "on") ? -1 : 1;
        else if (!strcmp(argv[i], "--settle") && i + 1 < argc)
            settle = strtod(argv[++i], NULL);
        else {
            fprintf(stderr, "usage: bench_keyframe [--vertices N] [--keys K] [--relative on|off] [--settle S]\n");
            return 2;
        }
    }
    char tmp[] = "/tmp/mimic-bench-keyframe-XXXXXX";
    if (!mkdtemp(tmp)) return 1;
    char dir[4200], store[4200];
    snprintf(dir, sizeof dir, "%s/bodies", tmp);
    snprintf(store, sizeof store, "%s/store", tmp);
    mim_error_t err = {0};
    mim_synth_t *sy = NULL;
    mim_synth_options_t so = {.subjects = 4, .poses = 12, .vertices = vertices, .seed = 1};
    mim_db_t *db = NULL;
    mim_db_options_t dbo = {0};
    mim_ingest_report_t irep;
    char *paths[1] = {dir};
    int rc = mim_synth_create(&sy, &so, &err) || mim_synth_write_dataset(sy, dir, &err) ||
             mim_db_open(&db, store, &dbo, &err) || mim_ingest_run(db, paths, 1, NULL, &irep, &err) ||
             mim_query_build_index(db, NULL, NULL, &err);
    mim_db_close(&db);
    mim_session_t *s = NULL;
    if (!rc) rc = mim_session_open(&s, store, NULL, &err) || mim_session_load_avatar(s, "1", &err);
    if (rc) {
        fprintf(stderr, "bench_keyframe: %s\n", mim_error_text(&err));
        return 1;
    }
    const mim_landmark_map_t *map = mim_session_map(s);
    const mim_mesh_t *mesh = mim_session_mesh(s);
    const uint32_t n = mesh->n_vertices, L = map->count, P = so.poses;
    /* subject 1's landmarks in every pose, and the avatar's at rest */
    float *pose_lm = malloc(sizeof(float) * 3 * L * P), *rest_lm = malloc(sizeof(float) * 3 * L);
    float *body = malloc(sizeof(float) * 3 * n), *out = malloc(sizeof(float) * 3 * n);
    for (uint32_t p = 0; p < P; p++) {
        mim_synth_body(sy, 1, p, body);
        for (uint32_t l = 0; l < L; l++) memcpy(pose_lm + 3 * (L * p + l), body + 3 * (size_t)map->vertex[l], 12);
    }
    for (uint32_t l = 0; l < L; l++) memcpy(rest_lm + 3 * l, mesh->positions + 3 * (size_t)map->vertex[l], 12);
    enum { DRIVES = 3 };
    static const mim_session_drive_t drive_of[DRIVES] = {MIM_DRIVE_TEMPLATE, MIM_DRIVE_ORIENTATION, MIM_DRIVE_SKELETON};
    phase_t ph[DRIVES];
    for (int d = 0; d < DRIVES; d++) {
        ph[d] = (phase_t){malloc(sizeof(double) * keys), malloc(sizeof(double) * keys), malloc(sizeof(double) * keys),
                          malloc(sizeof(double) * keys), 0, 0, 0, {0}};
    }
    float u[3 * MIM_LANDMARKS_MAX];
    uint64_t last[DRIVES] = {0, 0, 0};
    for (uint32_t k = 0; k < keys; k++) {
        uint32_t a = (k / STEPS) % P, b = (a + 1) % P;
        float t = (float)(k % STEPS) / STEPS;
        for (uint32_t i = 0; i < 3 * L; i++) u[i] = (1 - t) * pose_lm[3 * L * a + i] + t * pose_lm[3 * L * b + i];
        mim_quat R[MIM_SEGMENTS];
        if (mim_xfer_segment_correction(map, rest_lm, u, R, &err)) {
            fprintf(stderr, "bench_keyframe: %s\n", mim_error_text(&err));
            return 1;
        }
        for (int d = 0; d < DRIVES; d++) {
            mim_session_request_t req = {.landmarks = u,
                                         .drive = drive_of[d],
                                         .orientations = drive_of[d] == MIM_DRIVE_ORIENTATION ? R : NULL,
                                         .relative = relative,
                                         .xfer = {.settle = settle}};
            mim_session_report_t rep;
            double t0 = mim_now();
            if (mim_session_transfer(s, &req, out, &rep, &err)) {
                fprintf(stderr, "bench_keyframe: %s\n", mim_error_text(&err));
                return 1;
            }
            phase_t *q = &ph[d];
            q->total[q->n] = mim_now() - t0;
            q->query[q->n] = rep.seconds_query, q->tmpl[q->n] = rep.seconds_template, q->solve[q->n] = rep.seconds_solve;
            q->iterations += rep.xfer.iterations;
            q->by_solves[rep.xfer.iterations < 5 ? rep.xfer.iterations - 1 : 4]++;
            q->cache_hits += rep.template_id == last[d];
            last[d] = rep.template_id;
            q->n++;
        }
    }
    /* the references: one plain 3-column solve, one pose's frames */
    const mim_xfer_topology_t *topo = mim_session_topology(s);
    mim_xfer_solver_t *solver = NULL;
    mim_xfer_solver_options_t sopt = {0};
    double *rhs = NULL, *x = NULL, *F = malloc(9 * sizeof(double) * n), ts[201], tf[201];
    uint32_t nf = 0;
    if (mim_xfer_solver_open(&solver, topo, map->vertex, L, &sopt, &err) == 0) {
        nf = n - L;
        rhs = malloc(3 * sizeof(double) * nf), x = malloc(3 * sizeof(double) * nf);
        for (uint32_t i = 0; i < 3 * nf; i++) rhs[i] = (double)(i % 7) * 1e-3;
        for (int r = 0; r < 201; r++) {
            double t0 = mim_now();
            mim_xfer_solver_solve(solver, rhs, x, &err);
            ts[r] = mim_now() - t0;
            t0 = mim_now();
            mim_xfer_frames(topo, out, F);
            tf[r] = mim_now() - t0;
        }
    }
    double solve_ms = bench_median(ts, 201) * 1e3, frames_ms = bench_median(tf, 201) * 1e3, split_wall = 0,
           split_cpu = 0;
    if (nf && split_solve(topo, map, rhs, nf, 201, &split_wall, &split_cpu, &err)) {
        fprintf(stderr, "bench_keyframe: %s\n", mim_error_text(&err));
        return 1;
    }
    printf("\n### synth, %u vertices, %u key frames a drive (subject 1's poses, %d key frames from one to the next; "
           "settle %g)\n\n",
           n, keys, STEPS, settle != 0 ? settle : MIM_XFER_DEFAULT_SETTLE);
    printf("| drive | query ms | frames ms | solve ms | key frame ms | solves a key frame | same template as the last |\n"
           "|---|---:|---:|---:|---:|---:|---:|\n");
    static const char *const names[DRIVES] = {"template (iterated)", "orientation (one solve)",
                                              "skeleton (one solve)"};
    for (int d = 0; d < DRIVES; d++)
        printf("| %s | %.3f | %.3f | %.3f | %.3f | %.2f | %.0f %% |\n", names[d], med(ph[d].query, ph[d].n),
               med(ph[d].tmpl, ph[d].n), med(ph[d].solve, ph[d].n), med(ph[d].total, ph[d].n),
               ph[d].iterations / ph[d].n, 100.0 * ph[d].cache_hits / ph[d].n);
    double iters = ph[0].iterations / ph[0].n;
    printf("\nReferences in the same run: one plain CHOLMOD solve of the 3-column system %.3f ms; one pose's frames "
           "through the public mim_xfer_frames %.3f ms (the iteration's own, with a face-normal workspace, costs "
           "less). The template drive's %.2f solves a key frame are %.3f ms of CHOLMOD in its %.3f ms solve phase; the "
           "rest is the frames between solves, the right-hand sides and the rank-16 correction.\n",
           solve_ms, frames_ms, iters, solve_ms * iters, med(ph[0].solve, ph[0].n));
    printf("\nThe plain solve's columns split 2 + 1 over two threads (two solvers, a worker woken per solve): "
           "%.3f ms wall (%.2fx the plain solve), %.3f ms of solving in all (%.2fx).\n",
           split_wall * 1e3, split_wall * 1e3 / solve_ms, split_cpu * 1e3, split_cpu * 1e3 / solve_ms);
    printf("\nThe template drive's key frames by solves: 1: %.0f %%, 2: %.0f %%, 3: %.0f %%, 4: %.0f %%, more: %.0f %%.\n",
           100.0 * ph[0].by_solves[0] / ph[0].n, 100.0 * ph[0].by_solves[1] / ph[0].n,
           100.0 * ph[0].by_solves[2] / ph[0].n, 100.0 * ph[0].by_solves[3] / ph[0].n,
           100.0 * ph[0].by_solves[4] / ph[0].n);
    printf("\nKey frame / plain solve: template drive %.2fx, orientation drive %.2fx, skeleton drive %.2fx.\n",
           med(ph[0].total, ph[0].n) / solve_ms, med(ph[1].total, ph[1].n) / solve_ms,
           med(ph[2].total, ph[2].n) / solve_ms);
    mim_xfer_solver_close(&solver);
    free(rhs), free(x), free(F), free(pose_lm), free(rest_lm), free(body), free(out);
    for (int d = 0; d < DRIVES; d++) free(ph[d].query), free(ph[d].tmpl), free(ph[d].solve), free(ph[d].total);
    mim_session_close(&s);
    mim_synth_destroy(&sy);
    char cmd[4300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd)) fprintf(stderr, "bench_keyframe: could not remove %s\n", tmp);
    return 0;
}
