/* Morphing between key poses (issue 3, point 4; seed 000 Section 3.5 and
 * Fig. 14): the paper's linear interpolation of positions against mimic's
 * frame interpolation (per-vertex frames slerped, landmarks lerped, one
 * solve with the cached factor). Prints figures; never passes or fails.
 *
 * For every subject and every pair of distinct key poses (synth; mh-bodies
 * when present), the in-between poses at t = 0.25, 0.5, 0.75 are measured
 * for the shrinking the paper shows: the enclosed volume against the key
 * poses' volumes interpolated at t, and the mean relative change of edge
 * lengths against the key poses' lengths interpolated at t (a limb that
 * rotates rigidly between the keys keeps both). Also the time of one
 * in-between pose (median).
 *
 * usage: bench_morph [--vertices N] [--mh DIR | --no-mh] */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_transfer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double volume(const float *x, const uint32_t *faces, uint32_t n_faces)
{
    double v = 0.0;
    for (uint32_t f = 0; f < n_faces; f++) {
        const float *a = x + 3 * (size_t)faces[3 * f], *b = x + 3 * (size_t)faces[3 * f + 1],
                    *c = x + 3 * (size_t)faces[3 * f + 2];
        v += a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) - a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
             a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return fabs(v) / 6.0;
}

static double edge_change(const float *x, const float *ka, const float *kb, double t, const uint32_t *faces,
                          uint32_t n_faces)
{
    double sum = 0.0;
    for (uint32_t f = 0; f < n_faces; f++)
        for (int k = 0; k < 3; k++) {
            uint32_t i = faces[3 * f + k], j = faces[3 * f + (k + 1) % 3];
            double l = 0.0, la = 0.0, lb = 0.0;
            for (int c = 0; c < 3; c++) {
                double d = (double)x[3 * i + c] - x[3 * j + c], da = (double)ka[3 * i + c] - ka[3 * j + c],
                       db = (double)kb[3 * i + c] - kb[3 * j + c];
                l += d * d, la += da * da, lb += db * db;
            }
            sum += fabs(sqrt(l) / ((1.0 - t) * sqrt(la) + t * sqrt(lb)) - 1.0);
        }
    return sum / (3.0 * n_faces);
}

static int run(const bench_dataset_t *d)
{
    mim_error_t err = {0};
    const uint32_t n = d->n, c = d->map.count;
    mim_xfer_topology_t *topo = NULL;
    mim_xfer_solver_t *s = NULL;
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err) ||
        mim_xfer_solver_open(&s, topo, d->map.vertex, c, NULL, &err)) {
        fprintf(stderr, "bench_morph: %s\n", mim_error_text(&err));
        return -1;
    }
    double *F = malloc(9 * (size_t)n * sizeof(double));
    double *qa = malloc(4 * (size_t)n * sizeof(double)), *qb = malloc(4 * (size_t)n * sizeof(double));
    double *Wa = malloc(3 * (size_t)n * sizeof(double)), *Wb = malloc(3 * (size_t)n * sizeof(double));
    float *out = malloc(3 * (size_t)n * sizeof(float));
    float ua[3 * MIM_LANDMARKS_MAX], ub[3 * MIM_LANDMARKS_MAX];
    double vol_dev[2] = {0}, vol_worst[2] = {1, 1}, edge[2] = {0}, times[4096];
    uint64_t count = 0;
    int nt = 0;
    const double ts[3] = {0.25, 0.5, 0.75};
    for (uint32_t sub = 0; sub < d->subjects; sub++) {
        for (uint32_t p = 0; p < d->poses; p++)
            for (uint32_t q = p + 1; q < d->poses; q++) {
                const float *xa = d->pos[sub * d->poses + p], *xb = d->pos[sub * d->poses + q];
                const double va = volume(xa, d->faces, d->n_faces), vb = volume(xb, d->faces, d->n_faces);
                mim_xfer_frames(topo, xa, F);
                mim_xfer_frames_to_quats(n, F, qa);
                mim_xfer_encode(topo, xa, F, Wa);
                mim_xfer_frames(topo, xb, F);
                mim_xfer_frames_to_quats(n, F, qb);
                mim_xfer_encode(topo, xb, F, Wb);
                mim_xfer_key_t ka = {xa, qa, Wa, ua, NULL}, kb = {xb, qb, Wb, ub, NULL};
                for (uint32_t k = 0; k < c; k++)
                    for (int e = 0; e < 3; e++) {
                        ua[3 * k + e] = xa[3 * (size_t)d->map.vertex[k] + e];
                        ub[3 * k + e] = xb[3 * (size_t)d->map.vertex[k] + e];
                    }
                for (int ti = 0; ti < 3; ti++)
                    for (int m = 0; m < 2; m++) {
                        double t0 = mim_now();
                        if (mim_xfer_morph(s, m ? MIM_XFER_MORPH_FRAMES : MIM_XFER_MORPH_LINEAR, &ka, &kb, ts[ti],
                                           out, &err)) {
                            fprintf(stderr, "bench_morph: %s\n", mim_error_text(&err));
                            return -1;
                        }
                        if (m && nt < 4096)
                            times[nt++] = mim_now() - t0;
                        double vr = volume(out, d->faces, d->n_faces) / ((1.0 - ts[ti]) * va + ts[ti] * vb);
                        vol_dev[m] += fabs(vr - 1.0);
                        if (fabs(vr - 1.0) > fabs(vol_worst[m] - 1.0))
                            vol_worst[m] = vr;
                        edge[m] += edge_change(out, xa, xb, ts[ti], d->faces, d->n_faces);
                        count += m;
                    }
            }
    }
    printf("\n## %s, %u vertices: %u subjects x %u key-pose pairs x 3 in-between poses (%llu each)\n\n", d->name, n,
           d->subjects, d->poses * (d->poses - 1) / 2, (unsigned long long)count);
    printf("| method | mean abs volume change vs keys | worst volume ratio | mean abs edge-length change vs keys | "
           "ms per in-between (median) |\n|---|---:|---:|---:|---:|\n");
    printf("| paper: linear positions | %.2f%% | %.3f | %.2f%% | - |\n", 100.0 * vol_dev[0] / count, vol_worst[0],
           100.0 * edge[0] / count);
    printf("| mimic: frames slerp + one solve | %.2f%% | %.3f | %.2f%% | %.3f |\n", 100.0 * vol_dev[1] / count,
           vol_worst[1], 100.0 * edge[1] / count, 1e3 * bench_median(times, nt));
    free(F), free(qa), free(qb), free(Wa), free(Wb), free(out);
    mim_xfer_solver_close(&s);
    mim_xfer_topology_close(&topo);
    return 0;
}

static int run_set(const bench_dataset_t *d, void *user)
{
    (void)user;
    return run(d);
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    for (int i = 1; i < argc; i++)
        if (!bench_sets_arg(&sets, argc, argv, &i)) {
            fprintf(stderr, "usage: %s [--vertices N] [--mh DIR | --no-mh]\n", argv[0]);
            return 2;
        }
    return bench_sets_run(&sets, 4, 12, run_set, NULL);
}
