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
 * frames are always orthonormal and finite. */
#include "internal.h"

#include <math.h>
#include <string.h>

/* a tangent is accepted when |projection| > this fraction of |edge| */
#define MIM__XFER_TANGENT_MIN 1e-3

static void frames_impl(const mim_xfer_topology_t *t, const float *pf, const double *pd,
                        double *frames)
{
    const uint32_t n = t->n;
#define POS(i, c) (pf ? (double)pf[3 * (size_t)(i) + (c)] : pd[3 * (size_t)(i) + (c)])
    for (uint32_t i = 0; i < n; i++)
        frames[9 * (size_t)i] = frames[9 * (size_t)i + 1] = frames[9 * (size_t)i + 2] = 0.0;
    for (uint32_t f = 0; f < t->n_faces; f++) {
        const uint32_t *c = t->faces + 3 * (size_t)f;
        double a[3], b[3];
        for (int k = 0; k < 3; k++) {
            a[k] = POS(c[1], k) - POS(c[0], k);
            b[k] = POS(c[2], k) - POS(c[0], k);
        }
        double nx = a[1] * b[2] - a[2] * b[1];
        double ny = a[2] * b[0] - a[0] * b[2];
        double nz = a[0] * b[1] - a[1] * b[0];
        for (int k = 0; k < 3; k++) {
            double *fr = frames + 9 * (size_t)c[k];
            fr[0] += nx;
            fr[1] += ny;
            fr[2] += nz;
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        double *fr = frames + 9 * (size_t)i;
        double xi[3] = {POS(i, 0), POS(i, 1), POS(i, 2)};
        double len = sqrt(fr[0] * fr[0] + fr[1] * fr[1] + fr[2] * fr[2]);
        uint32_t b = t->adj_start[i], e = t->adj_start[i + 1];
        if (!(len > 1e-300) || !isfinite(len)) {
            fr[0] = 0.0, fr[1] = 0.0, fr[2] = 1.0;
        } else {
            fr[0] /= len, fr[1] /= len, fr[2] /= len;
        }
        int found = 0;
        for (uint32_t k = b; k < e && !found; k++) {
            uint32_t j = t->adj[k];
            double ed[3] = {POS(j, 0) - xi[0], POS(j, 1) - xi[1], POS(j, 2) - xi[2]};
            double el = sqrt(ed[0] * ed[0] + ed[1] * ed[1] + ed[2] * ed[2]);
            double dn = ed[0] * fr[0] + ed[1] * fr[1] + ed[2] * fr[2];
            double p[3] = {ed[0] - dn * fr[0], ed[1] - dn * fr[1], ed[2] - dn * fr[2]};
            double pl = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            if (el > 0.0 && pl > MIM__XFER_TANGENT_MIN * el) {
                fr[3] = p[0] / pl, fr[4] = p[1] / pl, fr[5] = p[2] / pl;
                found = 1;
            }
        }
        if (!found) {
            /* any axis not along the normal, projected */
            double ax[3] = {1.0, 0.0, 0.0};
            if (fabs(fr[0]) > 0.9)
                ax[0] = 0.0, ax[1] = 1.0;
            double dn = ax[0] * fr[0] + ax[1] * fr[1] + ax[2] * fr[2];
            double p[3] = {ax[0] - dn * fr[0], ax[1] - dn * fr[1], ax[2] - dn * fr[2]};
            double pl = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            fr[3] = p[0] / pl, fr[4] = p[1] / pl, fr[5] = p[2] / pl;
        }
        fr[6] = fr[1] * fr[5] - fr[2] * fr[4];
        fr[7] = fr[2] * fr[3] - fr[0] * fr[5];
        fr[8] = fr[0] * fr[4] - fr[1] * fr[3];
    }
#undef POS
}

void mim_xfer_frames(const mim_xfer_topology_t *t, const float *positions, double *frames)
{
    frames_impl(t, positions, NULL, frames);
}

void mim_xfer_frames_d(const mim_xfer_topology_t *t, const double *positions, double *frames)
{
    frames_impl(t, NULL, positions, frames);
}
