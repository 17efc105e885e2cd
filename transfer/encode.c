/* Intrinsic encoding (seed 000, Section 3.1): Delta = L X, and
 * Delta_i = F(v_i) W_i, so W_i = F(v_i)^T Delta_i (frames orthonormal).
 * Decoding F(v_i) W_i is the right-hand side of equations (1)-(3). */
#include "internal.h"

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
