/* Local frame per vertex (seed 000, Section 3.1, last paragraph):
 *   f1 = vertex normal: the sum of the incident faces' cross products, so
 *        each face weighs by its area;
 *   f2 = the edge to a fixed neighbour projected onto the tangent plane
 *        and normalised. The fixed neighbour is the LOWEST-INDEX one-ring
 *        neighbour: it depends only on the connectivity, so it is the same
 *        vertex on every mesh of it. When that projection is degenerate
 *        (edge nearly along the normal), the next neighbours in index order
 *        are tried, still a rule of the connectivity plus geometry that is
 *        the same on every mesh; if all fail, any unit vector orthogonal to
 *        f1 is used;
 *   f3 = f1 x f2.
 * A vertex whose normal vanishes (no faces, or faces cancelling) gets the
 * normal of its neighbours' centroid direction, or +Z as a last resort, so
 * frames are always orthonormal and finite.
 *
 * Speed: this runs once per iteration of every transfer. Normals are
 * gathered per vertex over its incident faces (no scatter, so no
 * store-to-load stalls between faces sharing a vertex); the transfer
 * passes a face-normal workspace so each face's cross product is computed
 * once, the public functions recompute it per corner. The iteration takes
 * the offsets F(v_i) W_i straight away (mim__xfer_offsets_ws): the frames
 * never reach memory, a third of the bytes the right-hand side reads. */
#include "internal.h"

#include <math.h>
#include <string.h>

/* a tangent is accepted when |projection| > this fraction of |edge| */
#define MIM__XFER_TANGENT_MIN 1e-3

#define POS(i, c) (pf ? (double)pf[3 * (size_t)(i) + (c)] : pd[3 * (size_t)(i) + (c)])

/* f2 from edge e: its projection onto the tangent plane of the normal f1
 * (fr[0..2]), normalised into fr[3..5]; 0 (nothing written) when the
 * projection is degenerate. */
static inline int tangent_of(const double e[3], double *fr)
{
    const double nx = fr[0], ny = fr[1], nz = fr[2];
    double dn = e[0] * nx + e[1] * ny + e[2] * nz;
    double p0 = e[0] - dn * nx, p1 = e[1] - dn * ny, p2 = e[2] - dn * nz;
    double pl2 = p0 * p0 + p1 * p1 + p2 * p2, el2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
    if (!(el2 > 0.0 && pl2 > MIM__XFER_TANGENT_MIN * MIM__XFER_TANGENT_MIN * el2))
        return 0;
    double inv = 1.0 / sqrt(pl2);
    fr[3] = p0 * inv, fr[4] = p1 * inv, fr[5] = p2 * inv;
    return 1;
}

/* f2 where the fixed neighbour's edge lies along the normal f1 (fr[0..2]):
 * the next neighbours in index order, else any axis not along the
 * normal, projected. Rare, so out of the frames' loop. */
static __attribute__((noinline)) void tangent_fallback(const mim_xfer_topology_t *t, const float *pf, const double *pd,
                                                       uint32_t i, double *fr)
{
    const double nx = fr[0], ny = fr[1], nz = fr[2];
    for (uint32_t k = t->adj_start[i] + 1; k < t->adj_start[i + 1]; k++) {
        uint32_t j = t->adj[k];
        const double e[3] = {POS(j, 0) - POS(i, 0), POS(j, 1) - POS(i, 1), POS(j, 2) - POS(i, 2)};
        if (tangent_of(e, fr))
            return;
    }
    double ax[3] = {1.0, 0.0, 0.0};
    if (fabs(nx) > 0.9)
        ax[0] = 0.0, ax[1] = 1.0;
    double dn = ax[0] * nx + ax[1] * ny + ax[2] * nz;
    double p[3] = {ax[0] - dn * nx, ax[1] - dn * ny, ax[2] - dn * nz};
    double inv = 1.0 / sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    fr[3] = p[0] * inv, fr[4] = p[1] * inv, fr[5] = p[2] * inv;
}

/* One body for float and double positions: POS reads either, and each
 * caller passes a constant NULL for the other, so after inlining the loops
 * carry no branch on the element type. fn (3 * n_faces) may be NULL.
 * W NULL: out gets the frames (9 a vertex); else the Laplacian offsets
 * F(v_i) W_i (3 a vertex), all the iteration needs of them. */
static inline __attribute__((always_inline)) void frames_impl(const mim_xfer_topology_t *t, const float *pf,
                                                              const double *pd, const double *W, double *out,
                                                              double *fn)
{
    const uint32_t n = t->n;
#define CROSS(f, out)                                                                                  \
    do {                                                                                               \
        const uint32_t *c_ = t->faces + 3 * (size_t)(f);                                               \
        double ax = POS(c_[1], 0) - POS(c_[0], 0), ay = POS(c_[1], 1) - POS(c_[0], 1),                 \
               az = POS(c_[1], 2) - POS(c_[0], 2);                                                     \
        double bx = POS(c_[2], 0) - POS(c_[0], 0), by = POS(c_[2], 1) - POS(c_[0], 1),                 \
               bz = POS(c_[2], 2) - POS(c_[0], 2);                                                     \
        (out)[0] = ay * bz - az * by;                                                                  \
        (out)[1] = az * bx - ax * bz;                                                                  \
        (out)[2] = ax * by - ay * bx;                                                                  \
    } while (0)
    if (fn)
        for (uint32_t f = 0; f < t->n_faces; f++)
            CROSS(f, fn + 3 * (size_t)f);
    /* Two passes a block of vertices: the gathers (loops as long as each
     * vertex's degree, whose ends the branch predictor misses) first,
     * keeping the normal's sum and the edge to the fixed neighbour; then
     * the arithmetic with its square roots and divisions, with no such loop
     * between vertices, so that those of consecutive vertices overlap.
     * (One pass took about twice the time.) */
    enum { BLOCK = 128 };
    double raw[BLOCK][6];
    for (uint32_t b0 = 0; b0 < n; b0 += BLOCK) {
        const uint32_t b1 = n - b0 < BLOCK ? n : b0 + BLOCK;
        for (uint32_t i = b0; i < b1; i++) {
            double *r = raw[i - b0];
            /* f1: area-weighted normal, gathered over the incident faces */
            double nx = 0.0, ny = 0.0, nz = 0.0;
            for (uint32_t k = t->vf_start[i]; k < t->vf_start[i + 1]; k++) {
                double c[3];
                if (fn) {
                    const double *q = fn + 3 * (size_t)t->vf[k];
                    c[0] = q[0], c[1] = q[1], c[2] = q[2];
                } else {
                    CROSS(t->vf[k], c);
                }
                nx += c[0], ny += c[1], nz += c[2];
            }
            r[0] = nx, r[1] = ny, r[2] = nz;
            r[3] = r[4] = r[5] = 0.0; /* no neighbour: a zero edge, which the tangent rule refuses */
            if (t->adj_start[i] < t->adj_start[i + 1]) {
                const uint32_t j = t->adj[t->adj_start[i]];
                r[3] = POS(j, 0) - POS(i, 0), r[4] = POS(j, 1) - POS(i, 1), r[5] = POS(j, 2) - POS(i, 2);
            }
        }
        for (uint32_t i = b0; i < b1; i++) {
            const double *r = raw[i - b0];
            double fr[9], nx = r[0], ny = r[1], nz = r[2];
            double len2 = nx * nx + ny * ny + nz * nz;
            if (!(len2 > 1e-300) || !isfinite(len2)) {
                nx = 0.0, ny = 0.0, nz = 1.0;
            } else {
                double inv = 1.0 / sqrt(len2);
                nx *= inv, ny *= inv, nz *= inv;
            }
            fr[0] = nx, fr[1] = ny, fr[2] = nz;
            /* f2: the edge to the fixed (lowest-index) neighbour, projected */
            if (!tangent_of(r + 3, fr))
                tangent_fallback(t, pf, pd, i, fr);
            /* f3 = f1 x f2 */
            fr[6] = ny * fr[5] - nz * fr[4];
            fr[7] = nz * fr[3] - nx * fr[5];
            fr[8] = nx * fr[4] - ny * fr[3];
            if (W) { /* as mim_xfer_decode */
                const double *w = W + 3 * (size_t)i;
                double *o = out + 3 * (size_t)i;
                for (int c = 0; c < 3; c++)
                    o[c] = fr[c] * w[0] + fr[3 + c] * w[1] + fr[6 + c] * w[2];
            } else {
                memcpy(out + 9 * (size_t)i, fr, sizeof fr);
            }
        }
    }
#undef CROSS
}
#undef POS

void mim_xfer_frames(const mim_xfer_topology_t *t, const float *positions, double *frames)
{
    frames_impl(t, positions, NULL, NULL, frames, NULL);
}

void mim_xfer_frames_d(const mim_xfer_topology_t *t, const double *positions, double *frames)
{
    frames_impl(t, NULL, positions, NULL, frames, NULL);
}

void mim__xfer_offsets_ws(const mim_xfer_topology_t *t, const double *positions, const double *W, double *offsets,
                          double *face_normals)
{
    frames_impl(t, NULL, positions, W, offsets, face_normals);
}
