/* Dissimilarities between pose-pairs (seed 002): d_I of eq. 8 on
 * interaction coordinates, and the three measures of Section 6 (D_I, D_C,
 * D_S) after a least-squares rigid alignment. Choices: mim_sample.h. */
#include "internal.h"

#include <lapacke.h>
#include <math.h>
#include <string.h>

static double edge_term(const double *a, const double *b, int dim, const uint8_t e[2], double beta, double *w)
{
    double ua2 = 0, d2 = 0;
    for (int c = 0; c < dim; c++) {
        double ua = a[dim * e[1] + c] - a[dim * e[0] + c], ub = b[dim * e[1] + c] - b[dim * e[0] + c];
        ua2 += ua * ua, d2 += (ua - ub) * (ua - ub);
    }
    double len = sqrt(ua2);
    *w = 1.0 / (len > beta ? len : beta);
    return *w * sqrt(d2);
}

/* One half of eq. 8: the edges of t, weighted by the lengths in `own`. */
static double half(const double *own, const double *other, int dim, const mim_ic_t *t, double beta)
{
    double sum = 0, wsum = 0, w;
    for (uint32_t k = 0; k < t->n_edges; k++) {
        sum += edge_term(own, other, dim, t->edge[k], beta, &w);
        wsum += w;
    }
    return wsum > 0 ? sum / wsum : 0.0;
}

double mim_ic_distance(const double *a, const mim_ic_t *ta, const double *b, const mim_ic_t *tb, double beta)
{
    if (!(beta > 0)) beta = MIM_IC_DEFAULT_BETA;
    return half(a, b, ta->dim, ta, beta) + half(b, a, tb->dim, tb, beta);
}

static double det3(const double m[9])
{
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[3] * (m[1] * m[8] - m[2] * m[7]) + m[6] * (m[1] * m[5] - m[2] * m[4]);
}

void mim_sample_align(const double *a, const double *b, int dim, double *out)
{
    const int n = MIM_PAIR_JOINTS;
    double ca[3] = {0}, cb[3] = {0};
    for (int i = 0; i < n; i++)
        for (int c = 0; c < dim; c++) ca[c] += a[dim * i + c] / n, cb[c] += b[dim * i + c] / n;
    /* H = sum (b - cb)(a - ca)^T, column-major dim x dim; R = V U^T of H = U S V^T */
    double H[9] = {0}, U[9], Vt[9], s[3], superb[2];
    for (int i = 0; i < n; i++)
        for (int r = 0; r < dim; r++)
            for (int c = 0; c < dim; c++) H[dim * c + r] += (b[dim * i + r] - cb[r]) * (a[dim * i + c] - ca[c]);
    double R[9] = {0};
    if (LAPACKE_dgesvd(LAPACK_COL_MAJOR, 'A', 'A', dim, dim, H, dim, s, U, dim, Vt, dim, superb) == 0) {
        /* d keeps R a rotation (no reflection) */
        double d = 1.0;
        if (dim == 3) d = det3(U) * det3(Vt) < 0 ? -1.0 : 1.0;
        else d = (U[0] * U[3] - U[1] * U[2]) * (Vt[0] * Vt[3] - Vt[1] * Vt[2]) < 0 ? -1.0 : 1.0;
        for (int r = 0; r < dim; r++)
            for (int c = 0; c < dim; c++) {
                double v = 0;
                for (int k = 0; k < dim; k++) v += Vt[dim * r + k] * (k == dim - 1 ? d : 1.0) * U[dim * k + c];
                R[dim * c + r] = v; /* R[r][c] = sum_k V[r][k] D_k U[c][k] */
            }
    } else {
        for (int k = 0; k < dim; k++) R[dim * k + k] = 1.0;
    }
    for (int i = 0; i < n; i++)
        for (int r = 0; r < dim; r++) {
            double v = ca[r];
            for (int c = 0; c < dim; c++) v += R[dim * c + r] * (b[dim * i + c] - cb[c]);
            out[dim * i + r] = v;
        }
}

/* ---- shape contexts ---- */
#define SC_R 5
#define SC_AZ 8
#define SC_EL 4

/* Soft binning (each count shared linearly between the two nearest bins
 * along log r, azimuth (circular) and elevation, and the azimuth's share
 * fading out towards the poles, where it is undefined): plain binning
 * jumps when a joint sits on a bin's edge or straight above another, which
 * skeletons do, so a pair and its own rigid copy would differ. */
static void spread(float *h, double fr, double fa, double fe, double cos_el, float w)
{
    int r0 = (int)floor(fr), a0 = (int)floor(fa), e0 = (int)floor(fe);
    double tr = fr - r0, ta = fa - a0, te = fe - e0;
    for (int dr = 0; dr < 2; dr++)
        for (int da = 0; da < 2; da++)
            for (int de = 0; de < 2; de++) {
                int r = r0 + dr, a = ((a0 + da) % SC_AZ + SC_AZ) % SC_AZ, e = e0 + de;
                r = r < 0 ? 0 : r >= SC_R ? SC_R - 1 : r;
                e = e < 0 ? 0 : e >= SC_EL ? SC_EL - 1 : e;
                /* towards the poles the azimuth means less and less: its
                 * share (cos el) goes to its bin, the rest to all alike */
                double k = (dr ? tr : 1 - tr) * (de ? te : 1 - te);
                h[(r * SC_AZ + a) * SC_EL + e] += (float)(w * k * cos_el * (da ? ta : 1 - ta));
                if (da) continue;
                for (int u = 0; u < SC_AZ; u++) h[(r * SC_AZ + u) * SC_EL + e] += (float)(w * k * (1 - cos_el) / SC_AZ);
            }
}

static void shape_contexts(const double *p, float sc[MIM_PAIR_JOINTS][MIM_SC_BINS])
{
    const int n = MIM_PAIR_JOINTS;
    double mean = 0;
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            double d2 = 0;
            for (int c = 0; c < 3; c++) d2 += (p[3 * i + c] - p[3 * j + c]) * (p[3 * i + c] - p[3 * j + c]);
            mean += sqrt(d2);
        }
    mean /= n * (n - 1) / 2.0;
    if (!(mean > 0)) mean = 1.0;
    const double r0 = log(mean / 8.0), r1 = log(mean * 2.0);
    memset(sc, 0, sizeof(float) * MIM_PAIR_JOINTS * MIM_SC_BINS);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            if (j == i) continue;
            double v[3] = {p[3 * j] - p[3 * i], p[3 * j + 1] - p[3 * i + 1], p[3 * j + 2] - p[3 * i + 2]};
            double r = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            /* bin coordinates, bin centres at integers: log r, and up is y
             * (the data's convention: mimic's bodies and BVH) */
            double fr = r > 0 ? (log(r) - r0) / (r1 - r0) * SC_R - 0.5 : 0.0;
            double az = atan2(v[2], v[0]), el = r > 0 ? asin(v[1] / r) : 0.0;
            double fa = (az + M_PI) / (2 * M_PI) * SC_AZ - 0.5, fe = (el + M_PI / 2) / M_PI * SC_EL - 0.5;
            spread(sc[i], fr, fa, fe, cos(el), 1.0f / (n - 1));
        }
}

int mim_pair_prepare(const double *joints, mim_pair_prep_t *out, mim_error_t *err)
{
    out->dim = 3;
    memcpy(out->joints, joints, sizeof out->joints);
    int rc = mim_ic_build(joints, 3, &out->ic, err);
    if (!rc) shape_contexts(joints, out->sc);
    return rc;
}

double mim__shape_cost(const float *a, const float *b, int n, int bins)
{
    double total = 0;
    for (int i = 0; i < n * bins; i++) {
        double x = a[i], y = b[i];
        if (x + y > 0) total += 0.5 * (x - y) * (x - y) / (x + y);
    }
    return total / n;
}

double mim_sample_distance(const mim_pair_prep_t *a, const mim_pair_prep_t *b, mim_sample_metric_t metric)
{
    double bb[3 * MIM_PAIR_JOINTS];
    mim_sample_align(a->joints, b->joints, 3, bb);
    if (metric == MIM_METRIC_CARTESIAN) {
        double s = 0;
        for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) s += (a->joints[i] - bb[i]) * (a->joints[i] - bb[i]);
        return sqrt(s / MIM_PAIR_JOINTS);
    }
    if (metric == MIM_METRIC_SHAPE) {
        float sb[MIM_PAIR_JOINTS][MIM_SC_BINS];
        shape_contexts(bb, sb);
        return mim__shape_cost(&a->sc[0][0], &sb[0][0], MIM_PAIR_JOINTS, MIM_SC_BINS);
    }
    /* D_I: eq. 8 with each pair's own triangulation (a rigid motion keeps
     * a Delaunay triangulation, so b's still holds for bb) */
    return mim_ic_distance(a->joints, &a->ic, bb, &b->ic, MIM_IC_DEFAULT_BETA);
}
