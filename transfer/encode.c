/* Intrinsic encoding (seed 000, Section 3.1): Delta = L X, and
 * Delta_i = F(v_i) W_i, so W_i = F(v_i)^T Delta_i (frames orthonormal).
 * Decoding F(v_i) W_i is the right-hand side of equations (1)-(3). */
#include "internal.h"

#include <math.h>
#include <stdlib.h>

void mim_xfer_encode(const mim_xfer_topology_t *t, const float *positions, const double *frames,
                     double *W)
{
    for (uint32_t i = 0; i < t->n; i++) {
        uint32_t b = t->adj_start[i], e = t->adj_start[i + 1];
        double d = (double)(e - b);
        const float *xi = positions + 3 * (size_t)i;
        double D[3] = {d * xi[0], d * xi[1], d * xi[2]};
        for (uint32_t k = b; k < e; k++) {
            const float *xj = positions + 3 * (size_t)t->adj[k];
            D[0] -= xj[0];
            D[1] -= xj[1];
            D[2] -= xj[2];
        }
        const double *f = frames + 9 * (size_t)i;
        for (int k = 0; k < 3; k++)
            W[3 * (size_t)i + k] = f[3 * k] * D[0] + f[3 * k + 1] * D[1] + f[3 * k + 2] * D[2];
    }
}

void mim_xfer_decode(uint32_t n_vertices, const double *frames, const double *W, double *delta)
{
    for (uint32_t i = 0; i < n_vertices; i++) {
        const double *f = frames + 9 * (size_t)i, *w = W + 3 * (size_t)i;
        double *o = delta + 3 * (size_t)i;
        for (int c = 0; c < 3; c++)
            o[c] = f[c] * w[0] + f[3 + c] * w[1] + f[6 + c] * w[2];
    }
}

/* The stored form: float32, and the frames without f3 (= f1 x f2), which
 * the unpacking recomputes; 36 bytes a vertex instead of 96. */
int mim_xfer_encoding_compute(const mim_xfer_topology_t *t, const float *positions, float *frames6, float *W,
                              double *work, mim_error_t *err)
{
    const size_t n = t->n;
    double *F = work ? work : malloc(12 * n * sizeof *F);
    if (!F)
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory encoding %zu vertices", n);
    double *Wd = F + 9 * n;
    mim_xfer_frames(t, positions, F);
    mim_xfer_encode(t, positions, F, Wd);
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 6; k++)
            frames6[6 * i + (size_t)k] = (float)F[9 * i + (size_t)k];
        for (int k = 0; k < 3; k++)
            W[3 * i + (size_t)k] = (float)Wd[3 * i + (size_t)k];
    }
    if (!work)
        free(F);
    return 0;
}

void mim_xfer_encoding_unpack(uint32_t n_vertices, const float *frames6, const float *W, double *frames,
                              double *W_out)
{
    for (size_t i = 0; frames6 && frames && i < n_vertices; i++) {
        const float *s = frames6 + 6 * i;
        double *f = frames + 9 * i;
        /* re-orthonormalise after the float round trip */
        double n0 = s[0], n1 = s[1], n2 = s[2];
        double inv = 1.0 / sqrt(n0 * n0 + n1 * n1 + n2 * n2);
        n0 *= inv, n1 *= inv, n2 *= inv;
        double dn = s[3] * n0 + s[4] * n1 + s[5] * n2;
        double t0 = s[3] - dn * n0, t1 = s[4] - dn * n1, t2 = s[5] - dn * n2;
        inv = 1.0 / sqrt(t0 * t0 + t1 * t1 + t2 * t2);
        t0 *= inv, t1 *= inv, t2 *= inv;
        f[0] = n0, f[1] = n1, f[2] = n2;
        f[3] = t0, f[4] = t1, f[5] = t2;
        f[6] = n1 * t2 - n2 * t1;
        f[7] = n2 * t0 - n0 * t2;
        f[8] = n0 * t1 - n1 * t0;
    }
    for (size_t i = 0; W && W_out && i < 3 * (size_t)n_vertices; i++)
        W_out[i] = W[i];
}
