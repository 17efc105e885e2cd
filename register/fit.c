/* Similarity fit of two landmark sets (Umeyama 1991, "Least-squares
 * estimation of transformation parameters between two point patterns"):
 * the first step of registration (mim_register.h), bringing the template
 * into the target's place, orientation and size before anything else. */
#include "mim_register.h"

#include <lapacke.h>
#include <math.h>

static double det3(const double m[9])
{
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[3] * (m[1] * m[8] - m[2] * m[7]) + m[6] * (m[1] * m[5] - m[2] * m[4]);
}

int mim_reg_similarity_fit(const float *src, const float *dst, uint32_t n, mim_reg_similarity_t *out,
                           mim_error_t *err)
{
    if (!src || !dst || !out || n < 3)
        return mim_error_set(err, MIM_EINVAL, "similarity fit: needs at least 3 point pairs");
    double ms[3] = {0}, md[3] = {0};
    for (uint32_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            ms[c] += src[3 * i + c], md[c] += dst[3 * i + c];
    for (int c = 0; c < 3; c++)
        ms[c] /= n, md[c] /= n;
    /* Cross-covariance Sigma = 1/n sum (d - md)(s - ms)^T, and the source's variance. */
    double S[9] = {0}, var = 0.0; /* column-major: S[3 * col + row] */
    for (uint32_t i = 0; i < n; i++) {
        double a[3], b[3];
        for (int c = 0; c < 3; c++)
            a[c] = src[3 * i + c] - ms[c], b[c] = dst[3 * i + c] - md[c];
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                S[3 * c + r] += b[r] * a[c];
        var += a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    }
    for (int k = 0; k < 9; k++)
        S[k] /= n;
    var /= n;
    if (!(var > 0.0) || !isfinite(var))
        return mim_error_set(err, MIM_EINVAL, "similarity fit: the points are all at one place");

    double U[9], Vt[9], sv[3], superb[2], A[9];
    for (int k = 0; k < 9; k++)
        A[k] = S[k];
    if (LAPACKE_dgesvd(LAPACK_COL_MAJOR, 'A', 'A', 3, 3, A, 3, sv, U, 3, Vt, 3, superb) != 0)
        return mim_error_set(err, MIM_EUNSUPPORTED, "similarity fit: the SVD did not converge");
    /* Points on a line leave the rotation about that line undetermined.
     * The points are floats: collinear ones read from decimals are off
     * the line by their rounding, which leaves sv[1] / sv[0] at ~1e-7 (up
     * to 1e-5 a body's 1000 m from the origin), where the landmarks of
     * bodies give 0.06 or more (synth, every pair of 4 subjects x 40
     * poses). */
    if (!(sv[1] > 1e-4 * (sv[0] > 0 ? sv[0] : 1.0)))
        return mim_error_set(err, MIM_EINVAL, "similarity fit: the points lie on a line");
    double d3 = det3(U) * det3(Vt) < 0 ? -1.0 : 1.0;
    double D[3] = {1.0, 1.0, d3};
    /* R = U D V^T */
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double v = 0.0;
            for (int k = 0; k < 3; k++)
                v += U[3 * k + r] * D[k] * Vt[3 * c + k];
            out->R[3 * c + r] = v;
        }
    out->scale = (sv[0] + sv[1] + d3 * sv[2]) / var;
    for (int r = 0; r < 3; r++) {
        double v = 0.0;
        for (int c = 0; c < 3; c++)
            v += out->R[3 * c + r] * ms[c];
        out->t[r] = md[r] - out->scale * v;
    }
    if (!(out->scale > 0.0) || !isfinite(out->scale))
        return mim_error_set(err, MIM_EINVAL, "similarity fit: degenerate (scale %g)", out->scale);
    return 0;
}

int mim_reg_likest(const float *target, uint32_t n, const float *cand, uint32_t nc, uint32_t *best, mim_error_t *err)
{
    double least = INFINITY;
    float moved[3 * MIM_LANDMARKS_MAX];
    if (n > MIM_LANDMARKS_MAX) return mim_error_set(err, MIM_EINVAL, "%u landmarks: at most %d", n, MIM_LANDMARKS_MAX);
    for (uint32_t c = 0; c < nc; c++) {
        const float *lm = cand + (size_t)c * 3 * n;
        mim_reg_similarity_t s;
        if (mim_reg_similarity_fit(lm, target, n, &s, NULL)) continue;
        mim_reg_similarity_apply(&s, lm, n, moved);
        double ss = 0;
        for (uint32_t i = 0; i < 3 * n; i++) ss += ((double)moved[i] - target[i]) * ((double)moved[i] - target[i]);
        if (ss < least) least = ss, *best = c;
    }
    return isfinite(least) ? 0 : mim_error_set(err, MIM_EINVAL, "none of %u candidate bodies fits the landmarks", nc);
}

void mim_reg_similarity_apply(const mim_reg_similarity_t *s, const float *in, uint32_t n, float *out)
{
    for (uint32_t i = 0; i < n; i++) {
        double p[3] = {in[3 * i], in[3 * i + 1], in[3 * i + 2]};
        for (int r = 0; r < 3; r++)
            out[3 * i + r] =
                (float)(s->scale * (s->R[r] * p[0] + s->R[3 + r] * p[1] + s->R[6 + r] * p[2]) + s->t[r]);
    }
}
