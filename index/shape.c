/* The pose classes as Gaussians in landmark space (issue 15): shape
 * discriminants, the class of every frame, whole or with landmarks missing.
 *
 * Why: the angles' discriminants (lda.c) see 1680 angles learnt from a few
 * thousand rows; the 16 landmarks themselves are 48 numbers, whose
 * within-class covariance the training subjects determine well, and a
 * Gaussian's marginal over the present landmarks is its sub-block, so a
 * frame with landmarks missing needs no completion (bench/RESULTS.md,
 * "Shape discriminants").
 *
 * The model:
 *  - every template brought onto its class's mean shape by the
 *    least-squares similarity (rotation, scale, translation: what the
 *    angles do not see either), the means found by generalised Procrustes
 *    (MIM__SHAPE_GPA rounds), centred and of unit RMS radius;
 *  - one within-class covariance S of the aligned templates, unbiased,
 *    shrunk towards its mean variance by Ledoit and Wolf's intensity (at
 *    least MIM__SHAPE_SHRINK);
 *  - the frame's noise is not known (a vest's landmarks are off by
 *    millimetres or centimetres), so each class has MIM__SHAPE_LEVELS
 *    Gaussians, S + v_k^2 I with v_k = noise_max k / (LEVELS - 1) (shape
 *    units: a fraction of the bodies' RMS radius), and a frame's score for
 *    a class is its largest log-likelihood over the levels (with the log
 *    determinant: a noiseless frame picks a level near 0, a noisy one a
 *    wide level). Measured: one covariance learnt from noisy copies gained
 *    at 3 cm what it lost clean; the levels keep both;
 *  - a frame is aligned onto each class's mean over its present
 *    landmarks, and scored with S + v_k^2 I restricted to them: for a
 *    whole frame through S's eigenvectors (one 3L x 3L product a class,
 *    every level from it), for a frame with landmarks missing by the
 *    Cholesky factor of each level's sub-block (made per frame). */
#include "internal.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NMAX (3 * MIM_LANDMARKS_MAX)

/* Horn's quaternion (mim_quat_best_rotation), never a reflection; the
 * scale then
 * Sum b . R a / Sum |a|^2, a = x - cx, b = target - ct. */
void mim__similarity_fit(const double *target, const double *x, const uint8_t *present, uint32_t L, mim__similarity_t *f)
{
    double ct[3] = {0}, cx[3] = {0};
    uint32_t n = 0;
    for (uint32_t l = 0; l < L; l++)
        if (!present || present[l]) {
            n++;
            for (int c = 0; c < 3; c++) ct[c] += target[3 * l + c], cx[c] += x[3 * l + c];
        }
    for (int c = 0; c < 3; c++) f->ct[c] = n ? ct[c] / n : 0, f->cx[c] = n ? cx[c] / n : 0;
    double M[3][3] = {{0}}, aa = 0; /* M = Sum a b^T */
    for (uint32_t l = 0; l < L; l++)
        if (!present || present[l])
            for (int r = 0; r < 3; r++) {
                double a = x[3 * l + r] - f->cx[r];
                aa += a * a;
                for (int c = 0; c < 3; c++) M[r][c] += a * (target[3 * l + c] - f->ct[c]);
            }
    double Rc[9];
    mim_quat_to_matrix(mim_quat_best_rotation((const double(*)[3])M), Rc);
    double ba = 0; /* Sum b . R a = Sum_rc R[r][c] M[c][r] */
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) f->R[r][c] = Rc[3 * c + r], ba += f->R[r][c] * M[c][r]; /* Rc column-major */
    f->s = aa > 0 ? ba / aa : 1;
}

void mim__similarity_apply(const mim__similarity_t *f, const double *x, const uint8_t *present, uint32_t L, double *y)
{
    for (uint32_t l = 0; l < L; l++)
        if (!present || present[l])
            for (int r = 0; r < 3; r++) {
                double v = 0;
                for (int c = 0; c < 3; c++) v += f->R[r][c] * (x[3 * l + c] - f->cx[c]);
                y[3 * l + r] = f->s * v + f->ct[r];
            }
}

static void align(const double *target, const double *x, const uint8_t *present, uint32_t L, double *y)
{
    mim__similarity_t f;
    mim__similarity_fit(target, x, present, L, &f);
    mim__similarity_apply(&f, x, present, L, y);
}

/* Centred, unit RMS radius; 0, or -1 for a shape of one point. */
static int unit_shape(double *x, uint32_t L)
{
    double c[3] = {0}, r = 0;
    for (uint32_t l = 0; l < L; l++)
        for (int k = 0; k < 3; k++) c[k] += x[3 * l + k] / L;
    for (uint32_t l = 0; l < L; l++)
        for (int k = 0; k < 3; k++) x[3 * l + k] -= c[k], r += x[3 * l + k] * x[3 * l + k];
    if (!(r > 0) || !isfinite(r)) return -1;
    r = sqrt(r / L);
    for (uint32_t i = 0; i < 3 * L; i++) x[i] /= r;
    return 0;
}

void mim__shape_free(mim__shape_t *m)
{
    if (!m->borrowed) free(m->mu), free(m->S);
    free(m->V), free(m->lam), free(m->Vmu), free(m->U);
    memset(m, 0, sizeof *m);
}

int mim__shape_prepare(mim__shape_t *m)
{
    const uint32_t n = 3 * m->L, nc = m->n_classes;
    free(m->V), free(m->lam), free(m->Vmu), free(m->U);
    m->V = malloc(sizeof *m->V * n * n), m->lam = malloc(sizeof *m->lam * n);
    m->Vmu = malloc(sizeof *m->Vmu * (size_t)nc * n), m->U = calloc(3 * (size_t)n, sizeof *m->U);
    if (!m->V || !m->lam || !m->Vmu || !m->U) return MIM_ENOMEM;
    memcpy(m->V, m->S, sizeof *m->V * n * n);
    /* S = V diag(lam) V^T; row-major, so the eigenvectors are V's columns */
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'L', (lapack_int)n, m->V, (lapack_int)n, m->lam)) return MIM_EFORMAT;
    for (uint32_t i = 0; i < n; i++)
        if (!(m->lam[i] > 0) || !isfinite(m->lam[i])) return MIM_EFORMAT; /* shrunk: positive definite */
    for (uint32_t c = 0; c < nc; c++)
        for (uint32_t j = 0; j < n; j++) {
            double s = 0;
            for (uint32_t i = 0; i < n; i++) s += m->V[(size_t)i * n + j] * m->mu[(size_t)c * n + i];
            m->Vmu[(size_t)c * n + j] = s;
        }
    for (uint32_t i = 0; i < n; i++) /* U_r = V^T (a translation by e_r) */
        for (uint32_t j = 0; j < n; j++) m->U[(size_t)(i % 3) * n + j] += m->V[(size_t)i * n + j];
    return 0;
}

int mim__shape_build(mim__shape_t *out, const mim_index_input_t *in, const uint32_t *cls, uint32_t nc,
                     double noise_max, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    const uint32_t L = in->n_landmarks, n = 3 * L;
    if (nc < 2 || L < 3) return 0; /* nothing to tell apart, or no shape */
    out->mu = calloc((size_t)nc * n, sizeof *out->mu), out->S = calloc((size_t)n * n, sizeof *out->S);
    uint32_t *count = calloc(nc, sizeof *count), *pick = malloc(sizeof *pick * in->n_templates), N = 0;
    double *acc = malloc(sizeof *acc * nc * n), x[NMAX], y[NMAX];
    int rc = 0;
    uint32_t per_class = MIM__SHAPE_TEMPLATES / nc > 8 ? MIM__SHAPE_TEMPLATES / nc : 8;
    if (!out->mu || !out->S || !count || !pick || !acc ||
        !(N = mim__class_sample(cls, in->n_templates, nc, per_class, pick))) {
        rc = mim_error_set(err, MIM_ENOMEM, "index: out of memory for the shape discriminants");
        goto out;
    }
    for (uint32_t i = 0; i < N; i++) { /* a class's first template starts its mean */
        uint32_t t = pick[i], c = cls[t];
        if (count[c]++) continue;
        for (uint32_t k = 0; k < n; k++) out->mu[(size_t)c * n + k] = in->landmarks[(size_t)t * n + k];
        if (unit_shape(out->mu + (size_t)c * n, L)) goto flat;
    }
    for (int round = 0; round < MIM__SHAPE_GPA; round++) { /* generalised Procrustes, each class */
        memset(acc, 0, sizeof *acc * nc * n);
        for (uint32_t i = 0; i < N; i++) {
            uint32_t t = pick[i], c = cls[t];
            for (uint32_t k = 0; k < n; k++) x[k] = in->landmarks[(size_t)t * n + k];
            align(out->mu + (size_t)c * n, x, NULL, L, y);
            for (uint32_t k = 0; k < n; k++) acc[(size_t)c * n + k] += y[k] / count[c];
        }
        memcpy(out->mu, acc, sizeof *acc * nc * n);
        for (uint32_t c = 0; c < nc; c++)
            if (unit_shape(out->mu + (size_t)c * n, L)) goto flat;
    }
    /* the within-class scatter of the aligned templates, unbiased (N - nc
     * degrees of freedom), then shrunk by Ledoit and Wolf's estimate of
     * the best intensity (2004) */
    double dof = N > nc ? (double)(N - nc) : 1, b2 = 0;
    for (int pass = 0; pass < 2; pass++)
        for (uint32_t i = 0; i < N; i++) {
            uint32_t t = pick[i];
            const double *mu = out->mu + (size_t)cls[t] * n;
            for (uint32_t k = 0; k < n; k++) x[k] = in->landmarks[(size_t)t * n + k];
            align(mu, x, NULL, L, y);
            for (uint32_t k = 0; k < n; k++) y[k] -= mu[k];
            if (pass == 0) {
                for (uint32_t a = 0; a < n; a++)
                    for (uint32_t b = 0; b < n; b++) out->S[(size_t)a * n + b] += y[a] * y[b] / dof;
            } else { /* |y y^T - S|_F^2 = |y|^4 - 2 y^T S y + |S|_F^2, the last added once below */
                double yy = 0, ySy = 0;
                for (uint32_t a = 0; a < n; a++) {
                    double sa = 0;
                    for (uint32_t b = 0; b < n; b++) sa += out->S[(size_t)a * n + b] * y[b];
                    yy += y[a] * y[a], ySy += y[a] * sa;
                }
                b2 += yy * yy - 2 * ySy;
            }
        }
    double tr = 0, ss = 0;
    for (uint32_t a = 0; a < n; a++) tr += out->S[(size_t)a * n + a];
    for (uint32_t a = 0; a < n * n; a++) ss += out->S[a] * out->S[a];
    if (!(tr > 0) || !isfinite(tr)) goto flat;
    const double mean = tr / n, d2 = ss - n * mean * mean; /* |S - mean I|_F^2 */
    b2 = (b2 + N * ss) / ((double)N * N);
    double delta = d2 > 0 ? (b2 < d2 ? b2 / d2 : 1) : 1;
    if (delta < MIM__SHAPE_SHRINK) delta = MIM__SHAPE_SHRINK;
    for (uint32_t a = 0; a < n; a++)
        for (uint32_t b = 0; b < n; b++)
            out->S[(size_t)a * n + b] = (1 - delta) * out->S[(size_t)a * n + b] + (a == b ? delta * mean : 0);
    out->L = L, out->n_classes = nc, out->noise_max = noise_max;
    if ((rc = mim__shape_prepare(out)))
        rc = mim_error_set(err, rc, "index: the shape discriminants' covariance has no eigen decomposition");
    goto out;
flat: /* every template the same shape, or all landmarks at one place: no discriminant to learn */
    mim__shape_free(out);
out:
    if (rc) mim__shape_free(out);
    free(count), free(pick), free(acc);
    return rc;
}

uint32_t mim__shape_present(uint32_t L, const float *positions, const uint8_t *present, uint8_t *here, uint32_t *idx,
                            double *x)
{
    uint32_t k = 0;
    for (uint32_t l = 0; l < L; l++) {
        here[l] = (!present || present[l]) && isfinite(positions[3 * l]) && isfinite(positions[3 * l + 1]) &&
                  isfinite(positions[3 * l + 2]);
        for (int c = 0; here[l] && c < 3; c++) idx[k++] = 3 * l + (uint32_t)c;
    }
    for (uint32_t i = 0; i < 3 * L; i++) x[i] = here[i / 3] ? positions[i] : 0;
    return k;
}

int64_t mim__shape_class(const mim__shape_t *m, const float *positions, const uint8_t *present, double *score)
{
    if (!m->n_classes) return -1;
    const uint32_t L = m->L, n = 3 * L, nc = m->n_classes;
    uint32_t idx[NMAX];
    uint8_t here[MIM_LANDMARKS_MAX];
    double x[NMAX], y[NMAX], z[NMAX], v2[MIM__SHAPE_LEVELS], logdet[MIM__SHAPE_LEVELS];
    const uint32_t k = mim__shape_present(L, positions, present, here, idx, x);
    if (k < 9) return -1; /* fewer than three landmarks: no shape */
    for (int lv = 0; lv < MIM__SHAPE_LEVELS; lv++) {
        double v = m->noise_max * lv / (MIM__SHAPE_LEVELS - 1);
        v2[lv] = v * v;
    }
    const int whole = k == n;
    double *F = NULL; /* landmarks missing: each level's Cholesky factor of its sub-block */
    /* a whole frame: W_rc = V^T (x's coordinate c, centred, as coordinate r); 14 KiB at 64 landmarks */
    double W[9 * NMAX];
    if (whole) {
        for (int lv = 0; lv < MIM__SHAPE_LEVELS; lv++) {
            logdet[lv] = 0;
            for (uint32_t j = 0; j < n; j++) logdet[lv] += log(m->lam[j] + v2[lv]);
        }
        double c[3] = {0};
        for (uint32_t l = 0; l < L; l++)
            for (int r = 0; r < 3; r++) c[r] += x[3 * l + r] / L;
        memset(W, 0, sizeof *W * 9 * n);
        for (uint32_t l = 0; l < L; l++)
            for (int r = 0; r < 3; r++) {
                const double *vi = m->V + (size_t)(3 * l + r) * n;
                for (int cc = 0; cc < 3; cc++) {
                    double xc = x[3 * l + cc] - c[cc], *w = W + (size_t)(3 * r + cc) * n;
                    for (uint32_t j = 0; j < n; j++) w[j] += vi[j] * xc;
                }
            }
    } else {
        if (!(F = malloc(sizeof *F * MIM__SHAPE_LEVELS * k * k))) return -1;
        for (int lv = 0; lv < MIM__SHAPE_LEVELS; lv++) {
            double *A = F + (size_t)lv * k * k;
            for (uint32_t a = 0; a < k; a++)
                for (uint32_t b = 0; b < k; b++) A[a * k + b] = m->S[(size_t)idx[a] * n + idx[b]] + (a == b ? v2[lv] : 0);
            if (mim__cholesky(A, k)) {
                free(F);
                return -1;
            }
            logdet[lv] = 0;
            for (uint32_t a = 0; a < k; a++) logdet[lv] += 2 * log(A[a * k + a]);
        }
    }
    int64_t arg = -1;
    for (uint32_t c = 0; c < nc; c++) {
        const double *mu = m->mu + (size_t)c * n;
        mim__similarity_t sim;
        mim__similarity_fit(mu, x, here, L, &sim);
        double best = -INFINITY;
        if (whole) { /* z = V^T (y - mu) = s Sum_rc R_rc W_rc + Sum_r ct_r U_r - V^T mu; every level from it */
            const double *Vmu = m->Vmu + (size_t)c * n;
            for (uint32_t j = 0; j < n; j++) z[j] = -Vmu[j];
            for (int r = 0; r < 3; r++) {
                const double *u = m->U + (size_t)r * n;
                for (uint32_t j = 0; j < n; j++) z[j] += sim.ct[r] * u[j];
                for (int cc = 0; cc < 3; cc++) {
                    const double g = sim.s * sim.R[r][cc], *w = W + (size_t)(3 * r + cc) * n;
                    for (uint32_t j = 0; j < n; j++) z[j] += g * w[j];
                }
            }
            for (int lv = 0; lv < MIM__SHAPE_LEVELS; lv++) {
                double q = 0;
                for (uint32_t j = 0; j < n; j++) q += z[j] * z[j] / (m->lam[j] + v2[lv]);
                double e = -0.5 * (q + logdet[lv]);
                if (e > best) best = e;
            }
        } else {
            mim__similarity_apply(&sim, x, here, L, y);
            for (int lv = 0; lv < MIM__SHAPE_LEVELS; lv++) {
                for (uint32_t a = 0; a < k; a++) z[a] = y[idx[a]] - mu[idx[a]];
                double e = -0.5 * (mim__chol_forward(F + (size_t)lv * k * k, k, z) + logdet[lv]);
                if (e > best) best = e;
            }
        }
        score[c] = best;
        if (isfinite(best) && (arg < 0 || best > score[arg])) arg = c;
    }
    free(F);
    return arg;
}
