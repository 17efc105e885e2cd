/* Warm-started key frames (issue 6: "each key frame ... with a warm start
 * from the previous key frame's solution"). Prints figures; never passes
 * or fails.
 *
 * A vest stream moves the landmarks a little from one key frame to the
 * next. This bench makes such streams with ground truth at their ends:
 * avatar = subject A at rest; the landmarks go linearly from A's pose p to
 * A's pose q over F frames; the template is subject B's pose p for the
 * first half and B's pose q for the second (the loop warm-starts only
 * while the template stays the same, so the switch is a cold start). Each
 * frame is transferred twice: cold (from the template's frames, the
 * paper) and warm (from the previous frame's warm solution, as serve does).
 * Reported: solves per frame, time per frame, the mean distance between
 * the warm and the cold result over the stream, and the error against the
 * truth (A's pose q) at the last frame, where both end, so any drift the
 * warm chain accumulates would show.
 *
 * usage: bench_warm_start [--frames F] [--vertices N] [--mh DIR | --no-mh] */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_transfer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double mean_dist(const float *a, const float *b, uint32_t n)
{
    double s = 0.0;
    for (size_t i = 0; i < n; i++) {
        double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
        s += sqrt(dx * dx + dy * dy + dz * dz);
    }
    return s / n;
}

typedef struct totals {
    double cold_solves, warm_solves, cold_time, warm_time, gap, cold_err, warm_err;
    int frames, streams;
} totals_t;

static int stream(mim_xfer_solver_t *s, const bench_dataset_t *d, uint32_t A, uint32_t p, uint32_t q,
                  int F, const double *W, double *Fp, double *Fq, float *cold, float *warm, float *prev,
                  totals_t *t)
{
    mim_error_t err = {0};
    const uint32_t n = d->n, L = d->map.count;
    const float *ap = d->pos[A * d->poses + p], *aq = d->pos[A * d->poses + q];
    float u[3 * MIM_LANDMARKS_MAX];
    int have_prev = 0;
    for (int f = 0; f < F; f++) {
        double a = F > 1 ? (double)f / (F - 1) : 1.0;
        for (uint32_t i = 0; i < L; i++)
            for (int c = 0; c < 3; c++) {
                size_t v = 3 * (size_t)d->map.vertex[i] + c;
                u[3 * i + c] = (float)((1.0 - a) * ap[v] + a * aq[v]);
            }
        int second = 2 * f >= F;
        const double *Ft = second ? Fq : Fp;
        if (2 * f == F || 2 * f == F + 1)
            have_prev = 0; /* the template changed: serve starts cold */
        mim_xfer_options_t oc = {0}, ow = {.start = have_prev ? prev : NULL};
        mim_xfer_report_t rc, rw;
        double t0 = mim_now();
        if (mim_xfer_transfer(s, W, n, Ft, u, L, &oc, cold, &rc, &err))
            goto fail;
        double t1 = mim_now();
        if (mim_xfer_transfer(s, W, n, Ft, u, L, &ow, warm, &rw, &err))
            goto fail;
        double t2 = mim_now();
        t->cold_time += t1 - t0, t->warm_time += t2 - t1;
        t->cold_solves += rc.iterations, t->warm_solves += rw.iterations;
        t->gap += mean_dist(cold, warm, n);
        t->frames++;
        memcpy(prev, warm, 3 * (size_t)n * sizeof *prev);
        have_prev = 1;
    }
    t->cold_err += mean_dist(cold, aq, n);
    t->warm_err += mean_dist(warm, aq, n);
    t->streams++;
    return 0;
fail:
    fprintf(stderr, "bench_warm_start: %s\n", mim_error_text(&err));
    return -1;
}

static int frames_arg = 30;

static int run_set(const bench_dataset_t *d, void *user)
{
    (void)user;
    mim_error_t err = {0};
    const uint32_t n = d->n;
    mim_xfer_topology_t *topo = NULL;
    mim_xfer_solver_t *s = NULL;
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err) ||
        mim_xfer_solver_open(&s, topo, d->map.vertex, d->map.count, NULL, &err)) {
        fprintf(stderr, "bench_warm_start: %s\n", mim_error_text(&err));
        mim_xfer_topology_close(&topo);
        return 1;
    }
    double *W = malloc(3 * (size_t)n * sizeof *W), *Fa = malloc(9 * (size_t)n * sizeof *Fa);
    double *Fp = malloc(9 * (size_t)n * sizeof *Fp), *Fq = malloc(9 * (size_t)n * sizeof *Fq);
    float *cold = malloc(3 * (size_t)n * sizeof *cold), *warm = malloc(3 * (size_t)n * sizeof *warm);
    float *prev = malloc(3 * (size_t)n * sizeof *prev);
    totals_t t = {0};
    int rc = 0;
    for (uint32_t A = 0; A < d->subjects && !rc; A++) {
        uint32_t B = (A + 1) % d->subjects;
        mim_xfer_frames(topo, d->pos[A * d->poses], Fa);
        mim_xfer_encode(topo, d->pos[A * d->poses], Fa, W);
        for (uint32_t p = 0; p < d->poses && !rc; p++) {
            uint32_t q = (p + 1) % d->poses;
            mim_xfer_frames(topo, d->pos[B * d->poses + p], Fp);
            mim_xfer_frames(topo, d->pos[B * d->poses + q], Fq);
            rc = stream(s, d, A, p, q, frames_arg, W, Fp, Fq, cold, warm, prev, &t);
        }
    }
    if (!rc && t.frames) {
        printf("%s (%u vertices): %d streams of %d frames (A's pose p -> q, templates B's p then q)\n", d->name, n,
               t.streams, frames_arg);
        printf("  solves per frame       cold %.2f   warm %.2f   (ratio %.2f)\n", t.cold_solves / t.frames,
               t.warm_solves / t.frames, t.warm_solves / t.cold_solves);
        printf("  time per frame         cold %.3f ms   warm %.3f ms   (ratio %.2f)\n", 1e3 * t.cold_time / t.frames,
               1e3 * t.warm_time / t.frames, t.warm_time / t.cold_time);
        printf("  warm vs cold result    mean %.2f mm over all frames\n", 1e3 * t.gap / t.frames);
        printf("  error at the end       cold %.2f mm   warm %.2f mm (mean vertex distance to A's pose q)\n",
               1e3 * t.cold_err / t.streams, 1e3 * t.warm_err / t.streams);
    }
    free(W), free(Fa), free(Fp), free(Fq), free(cold), free(warm), free(prev);
    mim_xfer_solver_close(&s);
    mim_xfer_topology_close(&topo);
    return rc ? 1 : 0;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i))
            continue;
        if (!strcmp(argv[i], "--frames") && i + 1 < argc) {
            frames_arg = atoi(argv[++i]);
            if (frames_arg >= 2 && frames_arg <= 1000)
                continue;
        }
        fprintf(stderr, "usage: %s [--frames F (2..1000)] [--vertices N] [--mh DIR | --no-mh]\n", argv[0]);
        return 2;
    }
    return bench_sets_run(&sets, 4, 12, run_set, NULL);
}
