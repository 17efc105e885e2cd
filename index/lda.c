/* The pose classes as Gaussians of one shared covariance over all candidate
 * angles (issue 15): linear discriminants.
 *
 * Why: under landmark noise, the frames of one pose spread in angle space
 * along directions that depend on the pose and on who wears it (a noisy
 * short segment swings every angle it is part of; a wider subject turns the
 * shoulder angles together). The SVMs see 60 selected angles, the k-NN
 * weighs every angle alike; a Gaussian per class whose covariance is
 * learned from the training subjects and their noisy copies weighs each
 * direction by how much it varies within a pose. On the hard set with the
 * variants 24-40 degrees apart (bench/RESULTS.md, "Linear discriminants")
 * this lifts 3 cm noise from 0.926 (SVMs) and 0.944 (1-NN over all angles)
 * to 0.969, against a ceiling of 0.999.
 *
 * The model: class means mu_c over a sample of the class's templates;
 * one within-class covariance S over those templates and MIM__LDA_COPIES
 * noisy copies of each (deviations from their class mean), shrunk towards
 * its mean variance, S + MIM__LDA_SHRINK * (trace S / nf) I (Ledoit-Wolf
 * style: 1680 angles from a few thousand rows need it); then the
 * discriminant of class c is g_c . (x - m) - b_c with g_c = S^-1 mu_c,
 * b_c = g_c . (mu_c / 2 - m), m the mean of the means (the class with the
 * largest wins: the nearest mean in S's Mahalanobis distance, equal
 * priors). Only whole frames use it: a missing landmark leaves hundreds of
 * angles undefined, and the marginal of S over the rest would need a
 * factorisation per pattern. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* acos on [-1, 1] (Abramowitz and Stegun 4.4.46: sqrt(1 - x) times a
 * polynomial of degree 7, for x >= 0, within 2e-8 in exact arithmetic;
 * pi minus that of -x below 0), branch-free so that a loop of them
 * vectorises; in float within 5e-7 rad of libm's double acos (measured
 * over [-1, 1] in steps of 1e-6). NaN stays NaN. */
static inline float acos_poly(float x)
{
    float a = x < 0 ? -x : x;
    float p = -0.0012624911f;
    p = p * a + 0.0066700901f;
    p = p * a - 0.0170881256f;
    p = p * a + 0.0308918810f;
    p = p * a - 0.0501743046f;
    p = p * a + 0.0889789874f;
    p = p * a - 0.2145988016f;
    p = p * a + 1.5707963050f;
    float r = sqrtf(1 - a) * p;
    return x < 0 ? 3.14159265f - r : r;
}

/* Every angle of the n landmarks, in the order of mim_index_angles (at j,
 * pairs {i, k} of the others), in float: the discriminants read all 1680
 * at every whole frame, and one difference vector per pair of landmarks
 * and a polynomial acos (no triple decoding, no libm acos) keep that to a
 * few microseconds, so that a whole frame's query costs about what the
 * SVM path did (bench/RESULTS.md). Train and query both use this. NaN
 * for a pair of coincident landmarks. */
static void all_angles(const float *pos, uint32_t n, float *out)
{
    float v[MIM_LANDMARKS_MAX][3], len[MIM_LANDMARKS_MAX];
    size_t a = 0;
    for (uint32_t j = 0; j < n; j++) {
        uint32_t m = 0;
        for (uint32_t i = 0; i < n; i++) {
            if (i == j) continue;
            float s = 0;
            for (int c = 0; c < 3; c++) v[m][c] = pos[3 * i + c] - pos[3 * j + c], s += v[m][c] * v[m][c];
            len[m++] = sqrtf(s);
        }
        for (uint32_t p = 0; p < m; p++)
            for (uint32_t q = p + 1; q < m; q++) {
                float d = len[p] * len[q], c = v[p][0] * v[q][0] + v[p][1] * v[q][1] + v[p][2] * v[q][2];
                out[a++] = d > 0 ? c / d : NAN;
            }
    }
    for (size_t i = 0; i < a; i++) { /* cosines to angles, clamped (a NaN fails both tests and stays) */
        float c = out[i] > 1 ? 1.f : out[i] < -1 ? -1.f : out[i];
        out[i] = acos_poly(c);
    }
}

void mim__lda_free(mim__lda_t *m)
{
    free(m->mean), free(m->g), free(m->b);
    memset(m, 0, sizeof *m);
}

int mim__lda_build(mim__lda_t *out, const mim_index_input_t *in, const uint32_t *cls, uint32_t nc, double sigma,
                   mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    const uint32_t n = in->n_templates, L = in->n_landmarks, nf = mim_index_angle_count(L);
    if (nc < 2) return 0; /* nothing to tell apart */
    /* the sample: at most per_class templates of each class, evenly spread */
    uint32_t per_class = MIM__LDA_TEMPLATES / nc > 4 ? MIM__LDA_TEMPLATES / nc : 4;
    uint32_t *seen = calloc(nc, sizeof *seen), *pick = malloc(sizeof *pick * n);
    double *mu = calloc((size_t)nc * nf, sizeof *mu), *S = calloc((size_t)nf * nf, sizeof *S);
    double *r = malloc(sizeof *r * nf);
    float *a = malloc(sizeof *a * nf), *noisy = malloc(sizeof *noisy * 3 * L);
    out->mean = calloc(nf, sizeof *out->mean);
    out->g = malloc(sizeof *out->g * (size_t)nc * nf);
    out->b = malloc(sizeof *out->b * nc);
    int rc = 0;
    uint32_t np = 0;
    if (!seen || !pick || !mu || !S || !r || !a || !noisy || !out->mean || !out->g || !out->b ||
        !(np = mim__class_sample(cls, n, nc, per_class, pick))) {
        rc = mim_error_set(err, MIM_ENOMEM, "index: out of memory for the linear discriminants (%u angles)", nf);
        goto out;
    }
    for (uint32_t i = 0; i < np; i++) { /* class means */
        uint32_t t = pick[i], c = cls[t];
        all_angles(in->landmarks + (size_t)t * L * 3, L, a);
        for (uint32_t f = 0; f < nf; f++) mu[(size_t)c * nf + f] += isnan(a[f]) ? 0 : a[f];
        seen[c]++;
    }
    for (uint32_t c = 0; c < nc; c++)
        for (uint32_t f = 0; f < nf; f++) mu[(size_t)c * nf + f] /= seen[c] ? seen[c] : 1;
    /* the within-class scatter (lower triangle), templates and their copies */
    mim_rng_t rng;
    mim_rng_seed(&rng, MIM__INDEX_SEED, 0x6c6461ULL);
    size_t rows = 0;
    for (uint32_t i = 0; i < np; i++) {
        uint32_t t = pick[i];
        const double *m = mu + (size_t)cls[t] * nf;
        for (uint32_t copy = 0; copy <= MIM__LDA_COPIES; copy++) {
            const float *p = in->landmarks + (size_t)t * L * 3;
            for (uint32_t k = 0; k < 3 * L; k++) noisy[k] = copy ? (float)(p[k] + sigma * mim_rng_gauss(&rng)) : p[k];
            all_angles(noisy, L, a);
            for (uint32_t f = 0; f < nf; f++) r[f] = isnan(a[f]) ? 0 : a[f] - m[f];
            for (uint32_t f = 0; f < nf; f++) {
                double *Sf = S + (size_t)f * nf, rf = r[f];
                for (uint32_t e = 0; e <= f; e++) Sf[e] += rf * r[e];
            }
            rows++;
        }
    }
    double tr = 0;
    for (uint32_t f = 0; f < nf; f++) tr += S[(size_t)f * nf + f];
    const double shrink = MIM__LDA_SHRINK * tr / rows / nf;
    for (uint32_t f = 0; f < nf; f++)
        for (uint32_t e = 0; e <= f; e++) S[(size_t)f * nf + e] = S[(size_t)f * nf + e] / rows + (e == f ? shrink : 0);
    if (!(shrink > 0) || mim__cholesky(S, nf)) { /* every angle constant: no discriminant to learn */
        mim__lda_free(out);
        goto out;
    }
    for (uint32_t c = 0; c < nc; c++)
        for (uint32_t f = 0; f < nf; f++) out->mean[f] += (float)(mu[(size_t)c * nf + f] / nc);
    for (uint32_t c = 0; c < nc; c++) {
        const double *m = mu + (size_t)c * nf;
        memcpy(r, m, sizeof *r * nf);
        mim__chol_solve(S, nf, r);
        double b = 0;
        for (uint32_t f = 0; f < nf; f++) {
            out->g[(size_t)c * nf + f] = (float)r[f];
            b += r[f] * (0.5 * m[f] - out->mean[f]);
        }
        out->b[c] = b;
    }
    out->nf = nf, out->n_classes = nc;
out:
    if (rc) mim__lda_free(out);
    free(seen), free(pick), free(mu), free(S), free(r), free(a), free(noisy);
    return rc;
}

int64_t mim__lda_class(const mim__lda_t *m, const float *positions, uint32_t n_landmarks, double *score)
{
    if (!m->g || mim_index_angle_count(n_landmarks) != m->nf) return -1;
    const uint32_t nf = m->nf, nc = m->n_classes;
    float x_st[1680], *x = nf <= 1680 ? x_st : malloc(sizeof *x * nf);
    int64_t arg = -1;
    if (!x) return -1;
    all_angles(positions, n_landmarks, x);
    for (uint32_t f = 0; f < nf; f++) {
        if (isnan(x[f])) goto out; /* whole frames only */
        x[f] -= m->mean[f];
    }
    for (uint32_t c = 0; c < nc; c++) {
        const float *g = m->g + (size_t)c * nf;
        float acc[8] = {0}; /* eight lanes: a sum the compiler vectorises without reassociating */
        uint32_t f = 0;
        for (; f + 8 <= nf; f += 8)
            for (int l = 0; l < 8; l++) acc[l] += g[f + l] * x[f + l];
        double s = -m->b[c];
        for (; f < nf; f++) s += (double)g[f] * x[f];
        for (int l = 0; l < 8; l++) s += acc[l];
        score[c] = s;
        if (arg < 0 || s > score[arg]) arg = c;
    }
out:
    if (x != x_st) free(x);
    return arg;
}
