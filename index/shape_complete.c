/* Completion of lost landmarks from the pose classes' Gaussians (issue 29,
 * item 4): the shape discriminants (shape.c) model each class as a
 * Gaussian over the 3L landmark coordinates, after a similarity onto its
 * mean shape, with one shared covariance S (+ v^2 I at each noise level).
 * A Gaussian's conditional mean of the missing coordinates m given the
 * present ones s is
 *     mu_m + S_ms S_ss^-1 (y_s - mu_s),
 * y the frame brought onto the class's mean by the similarity fitted on
 * its present landmarks. The classes are scored as mim__shape_class
 * scores them (each at its most likely noise level); each answers at
 * v = 0, S itself (measured: the noisier levels pull the answer towards
 * the class's mean, 46.0 against 46.5 to 48.8 mm on the imitation set,
 * bench/complete.c); the answers, mapped back into the frame by the
 * inverse similarity, are mixed by the classes' posteriors (equal priors),
 * so a frame between two poses gets an answer between theirs.
 *
 * Why beside retrieval (session/complete.c): the store's templates of a
 * pose are a handful of bodies, and the nearest one carries its own way of
 * taking the pose into the lost landmarks; the class's covariance knows
 * how each landmark moves with the others over every subject (a lowered
 * elbow, a lower wrist), which is what a person imitating a pose changes. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NMAX (3 * MIM_LANDMARKS_MAX)

/* classes whose posterior is below this share of the best one's are left
 * out of the mixture (exp(-20): nothing they add shows in a float) */
#define NEGLIGIBLE_LOG (-20.0)

int mim__shape_complete(const mim__shape_t *m, const float *positions, const uint8_t *present, float *out,
                        uint32_t *cls, double *scores)
{
    if (!m->n_classes) return -1;
    const uint32_t L = m->L, n = 3 * L, nc = m->n_classes;
    uint32_t idx[NMAX];
    uint8_t here[MIM_LANDMARKS_MAX];
    double x[NMAX];
    const uint32_t k = mim__shape_present(L, positions, present, here, idx, x);
    if (k < 9) return -1; /* fewer than three landmarks: no shape */
    for (uint32_t i = 0; i < n; i++) out[i] = (float)x[i];
    if (k == n) { /* nothing to complete: the class only */
        double st[256], *score = scores ? scores : nc <= 256 ? st : malloc(sizeof *score * nc);
        if (!score) return -1;
        int64_t c = mim__shape_class(m, positions, present, score);
        if (score != st && score != scores) free(score);
        if (c < 0) return -1;
        *cls = (uint32_t)c;
        return 0;
    }
    /* each level's factor of the present block, S_ss + v^2 I, and its log determinant */
    double *F = malloc(sizeof *F * MIM__SHAPE_LEVELS * k * k), *score = scores ? scores : malloc(sizeof *score * nc);
    if (!F || !score) {
        free(F), free(score == scores ? NULL : score);
        return -1;
    }
    double v2[MIM__SHAPE_LEVELS], logdet[MIM__SHAPE_LEVELS];
    for (int lv = 0; lv < MIM__SHAPE_LEVELS; lv++) {
        double v = m->noise_max * lv / (MIM__SHAPE_LEVELS - 1), *A = F + (size_t)lv * k * k;
        v2[lv] = v * v;
        for (uint32_t a = 0; a < k; a++)
            for (uint32_t b = 0; b < k; b++) A[a * k + b] = m->S[(size_t)idx[a] * n + idx[b]] + (a == b ? v2[lv] : 0);
        if (mim__cholesky(A, k)) {
            free(F), free(score == scores ? NULL : score);
            return -1;
        }
        logdet[lv] = 0;
        for (uint32_t a = 0; a < k; a++) logdet[lv] += 2 * log(A[a * k + a]);
    }
    /* every class's log-likelihood at its best level */
    double y[NMAX], z[NMAX];
    int64_t arg = -1;
    for (uint32_t c = 0; c < nc; c++) {
        const double *mu = m->mu + (size_t)c * n;
        mim__similarity_t sim;
        mim__similarity_fit(mu, x, here, L, &sim);
        mim__similarity_apply(&sim, x, here, L, y);
        score[c] = -INFINITY;
        for (int lv = 0; lv < MIM__SHAPE_LEVELS; lv++) {
            for (uint32_t a = 0; a < k; a++) z[a] = y[idx[a]] - mu[idx[a]];
            double e = -0.5 * (mim__chol_forward(F + (size_t)lv * k * k, k, z) + logdet[lv]);
            if (e > score[c]) score[c] = e;
        }
        if (isfinite(score[c]) && (arg < 0 || score[c] > score[arg])) arg = c;
    }
    if (arg < 0) {
        free(F), free(score == scores ? NULL : score);
        return -1;
    }
    /* the conditional means, back in the frame, mixed by the posteriors */
    double acc[NMAX] = {0}, wsum = 0;
    for (uint32_t c = 0; c < nc; c++) {
        double lw = score[c] - score[arg];
        if (!(lw > NEGLIGIBLE_LOG)) continue;
        const double w = exp(lw), *mu = m->mu + (size_t)c * n;
        mim__similarity_t sim;
        mim__similarity_fit(mu, x, here, L, &sim);
        if (!(sim.s > 0)) continue; /* a frame flattened onto a point: no way back */
        mim__similarity_apply(&sim, x, here, L, y);
        for (uint32_t a = 0; a < k; a++) z[a] = y[idx[a]] - mu[idx[a]];
        mim__chol_solve(F, k, z); /* S_ss^-1 (y_s - mu_s), level 0 */
        double cond[NMAX];
        for (uint32_t i = 0; i < n; i++) {
            if (here[i / 3]) continue;
            const double *Si = m->S + (size_t)i * n;
            double s = mu[i];
            for (uint32_t a = 0; a < k; a++) s += Si[idx[a]] * z[a];
            cond[i] = s;
        }
        /* x = R^T (y - ct) / s + cx for each missing landmark */
        for (uint32_t l = 0; l < L; l++) {
            if (here[l]) continue;
            for (int r = 0; r < 3; r++) {
                double v = 0;
                for (int q = 0; q < 3; q++) v += sim.R[q][r] * (cond[3 * l + q] - sim.ct[q]);
                acc[3 * l + r] += w * (v / sim.s + sim.cx[r]);
            }
        }
        wsum += w;
    }
    if (!(wsum > 0)) {
        free(F), free(score == scores ? NULL : score);
        return -1;
    }
    for (uint32_t l = 0; l < L; l++)
        if (!here[l])
            for (int r = 0; r < 3; r++) out[3 * l + r] = (float)(acc[3 * l + r] / wsum);
    *cls = (uint32_t)arg;
    free(F), free(score == scores ? NULL : score);
    return 0;
}

int mim_index_complete(const mim_index_t *ix, const float *positions, const uint8_t *present, float *out,
                       uint32_t *cls, mim_error_t *err)
{
    const uint32_t L = ix->n_landmarks;
    if (!ix->shape.n_classes)
        return mim_error_set(err, MIM_ENOTFOUND, "index: no shape discriminants to complete landmarks from "
                                                 "(one class, or built without them)");
    uint32_t seen = 0;
    for (uint32_t l = 0; l < L; l++) {
        if (present && !present[l]) continue;
        for (int c = 0; c < 3; c++)
            if (!isfinite(positions[3 * l + c]))
                return mim_error_set(err, MIM_ENONFINITE, "landmark %u is not a finite position", l);
        seen++;
    }
    if (seen < 3) return mim_error_set(err, MIM_EINVAL, "completion: %u landmarks present, at least 3 needed", seen);
    uint32_t c = 0;
    if (mim__shape_complete(&ix->shape, positions, present, out, &c, NULL))
        return mim_error_set(err, MIM_EINVAL, "completion: the present landmarks span no shape");
    if (cls) *cls = c;
    return 0;
}
