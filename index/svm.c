/* Per-class SVMs, one-vs-rest, with libsvm (seed 000, Section 3.3): RBF
 * kernel, C and gamma by k-fold cross-validation over a small grid, Platt
 * probabilities (libsvm's -b 1 method, run here: platt_fit). libsvm trains;
 * the trained models are kept in a dense form of our own (support vectors,
 * coefficients, rho, Platt A and B), which is what the blob stores and what
 * queries evaluate, so a libsvm model (which points into its training
 * problem) never outlives its training data. */
#include "internal.h"

#include <libsvm/svm.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static void quiet(const char *s) { (void)s; }

void mim__svm_free(mim__svm_t *m)
{
    if (!m) return;
    free(m->sv), free(m->coef);
    memset(m, 0, sizeof *m);
}

double mim__svm_decision(const mim__svm_t *m, double gamma, const double *x, const uint8_t *mask, uint32_t d)
{
    uint32_t avail = d;
    if (mask) {
        avail = 0;
        for (uint32_t f = 0; f < d; f++) avail += mask[f] != 0;
    }
    double scale = avail ? (double)d / avail : 1;
    double s = 0;
    for (uint32_t i = 0; i < m->n_sv; i++) {
        const double *v = m->sv + (size_t)i * d;
        double d2 = 0;
        if (mask) {
            for (uint32_t f = 0; f < d; f++)
                if (mask[f]) d2 += (x[f] - v[f]) * (x[f] - v[f]);
            d2 *= scale;
        } else {
            for (uint32_t f = 0; f < d; f++) d2 += (x[f] - v[f]) * (x[f] - v[f]);
        }
        s += m->coef[i] * exp(-gamma * d2);
    }
    return s - m->rho;
}

/* libsvm's sigmoid_predict, for the positive class */
double mim__svm_probability(const mim__svm_t *m, double f)
{
    double t = f * m->prob_a + m->prob_b;
    double p = t >= 0 ? exp(-t) / (1 + exp(-t)) : 1 / (1 + exp(t));
    if (p < 1e-7) p = 1e-7;
    if (p > 1 - 1e-7) p = 1 - 1e-7;
    return p;
}

/* Training rows as libsvm nodes: d features 1..d, then index -1. */
typedef struct {
    struct svm_node *nodes; /* n * (d + 1) */
    struct svm_node **rows;
    double *y;
} problem_mem_t;

static int problem_alloc(problem_mem_t *p, uint32_t n, uint32_t d)
{
    p->nodes = malloc(sizeof(struct svm_node) * (size_t)n * (d + 1));
    p->rows = malloc(sizeof(struct svm_node *) * n);
    p->y = malloc(sizeof(double) * n);
    return p->nodes && p->rows && p->y ? 0 : MIM_ENOMEM;
}

static void problem_free(problem_mem_t *p) { free(p->nodes), free(p->rows), free(p->y); }

/* Fills the problem with rows idx[0..n) of data, labelled +1 for class c. */
static void problem_fill(problem_mem_t *p, const mim__svm_data_t *data, const uint32_t *idx, uint32_t n, uint32_t c)
{
    uint32_t d = data->d;
    for (uint32_t r = 0; r < n; r++) {
        struct svm_node *row = p->nodes + (size_t)r * (d + 1);
        const double *x = data->x + (size_t)idx[r] * d;
        for (uint32_t f = 0; f < d; f++) row[f] = (struct svm_node){(int)f + 1, x[f]};
        row[d].index = -1;
        p->rows[r] = row;
        p->y[r] = data->y[idx[r]] == c ? 1 : -1;
    }
}

static void param_init(struct svm_parameter *pa, double C, double gamma)
{
    memset(pa, 0, sizeof *pa);
    pa->svm_type = C_SVC;
    pa->kernel_type = RBF;
    pa->gamma = gamma;
    pa->cache_size = 64;
    pa->eps = 1e-3;
    pa->C = C;
    pa->shrinking = 1;
    pa->probability = 0; /* libsvm's own Platt fit would shuffle with rand(): platt_fit */
}

static uint32_t count_positive(const mim__svm_data_t *data, const uint32_t *idx, uint32_t n, uint32_t c)
{
    uint32_t pos = 0;
    for (uint32_t r = 0; r < n; r++) pos += data->y[idx[r]] == c;
    return pos;
}

/* Trains class c against the rest on rows idx; fills the dense model, with
 * Platt A = -1, B = 0 (platt_fit sets them). When the rows hold no positive
 * (or no negative) example the model is empty and always says "no" (or
 * "yes"): f = -1 (or +1), P = 0 (or 1). */
static int train_one(const mim__svm_data_t *data, const uint32_t *idx, uint32_t n, uint32_t c, double C, double gamma,
                     mim__svm_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    uint32_t pos = count_positive(data, idx, n, c);
    if (pos == 0 || pos == n) { /* constant answer: f = -/+1, P = 0/1 */
        out->rho = pos ? -1 : 1;
        out->prob_a = -40, out->prob_b = 0;
        return 0;
    }
    problem_mem_t pm = {0};
    if (problem_alloc(&pm, n, data->d)) {
        problem_free(&pm);
        return MIM_ENOMEM;
    }
    problem_fill(&pm, data, idx, n, c);
    struct svm_problem prob = {(int)n, pm.y, pm.rows};
    struct svm_parameter pa;
    param_init(&pa, C, gamma);
    const char *why = svm_check_parameter(&prob, &pa);
    if (why) {
        problem_free(&pm);
        return mim_error_set(err, MIM_EINVAL, "SVM of class %u: %s", c, why);
    }
    struct svm_model *m = svm_train(&prob, &pa);
    int rc = 0;
    if (!m) {
        rc = MIM_ENOMEM;
        goto out;
    }
    /* libsvm orders labels by first appearance but puts +1 first for a
     * -1/+1 problem; read it rather than assume it */
    double sign = m->label[0] == 1 ? 1 : -1;
    out->n_sv = (uint32_t)m->l;
    out->sv = calloc((size_t)m->l * data->d + 1, sizeof(double));
    out->coef = malloc(sizeof(double) * ((size_t)m->l + 1));
    if (!out->sv || !out->coef) {
        rc = MIM_ENOMEM;
        mim__svm_free(out);
        goto out;
    }
    for (int i = 0; i < m->l; i++) {
        for (const struct svm_node *nd = m->SV[i]; nd->index != -1; nd++)
            if (nd->index >= 1 && (uint32_t)nd->index <= data->d)
                out->sv[(size_t)i * data->d + nd->index - 1] = nd->value;
        out->coef[i] = sign * m->sv_coef[0][i];
    }
    out->rho = sign * m->rho[0];
    out->prob_a = -1, out->prob_b = 0;
out:
    svm_free_and_destroy_model(&m);
    problem_free(&pm);
    return rc;
}

/* The negative log-likelihood of Platt's sigmoid at (A, B) against targets
 * hi (positives) and lo (negatives), each term written so that exp never
 * overflows. */
static double platt_nll(uint32_t n, const double *dec, const int8_t *lab, double hi, double lo, double A, double B)
{
    double s = 0;
    for (uint32_t i = 0; i < n; i++) {
        double t = lab[i] > 0 ? hi : lo, z = dec[i] * A + B;
        s += z >= 0 ? t * z + log(1 + exp(-z)) : (t - 1) * z + log(1 + exp(z));
    }
    return s;
}

/* Platt's sigmoid P(+1 | f) = 1 / (1 + exp(A f + B)) fitted to decision
 * values dec with labels lab (+1/-1): the regularised targets of Platt
 * (1999) and the Newton iteration with backtracking of Lin, Lin & Weng, "A
 * note on Platt's probabilistic outputs for support vector machines",
 * Machine Learning 68 (2007), Algorithm 1, with libsvm's constants (its
 * sigmoid_train). */
static void sigmoid_fit(uint32_t n, const double *dec, const int8_t *lab, double *A_out, double *B_out)
{
    double n_pos = 0, n_neg = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (lab[i] > 0) n_pos++;
        else n_neg++;
    }
    const double hi = (n_pos + 1) / (n_pos + 2), lo = 1 / (n_neg + 2);
    const double min_step = 1e-10, sigma = 1e-12, eps = 1e-5;
    double A = 0, B = log((n_neg + 1) / (n_pos + 1));
    double f = platt_nll(n, dec, lab, hi, lo, A, B);
    for (int it = 0; it < 100; it++) {
        /* gradient and Hessian (+ sigma I: strictly positive definite) */
        double h11 = sigma, h22 = sigma, h21 = 0, g1 = 0, g2 = 0;
        for (uint32_t i = 0; i < n; i++) {
            double z = dec[i] * A + B, p, q; /* p = P(+1 | dec[i]), q = 1 - p */
            if (z >= 0) p = exp(-z) / (1 + exp(-z)), q = 1 / (1 + exp(-z));
            else p = 1 / (1 + exp(z)), q = exp(z) / (1 + exp(z));
            double w = p * q, r = (lab[i] > 0 ? hi : lo) - p;
            h11 += dec[i] * dec[i] * w, h22 += w, h21 += dec[i] * w;
            g1 += dec[i] * r, g2 += r;
        }
        if (fabs(g1) < eps && fabs(g2) < eps) break;
        /* the Newton direction -H^-1 g, then halve the step until the
         * likelihood decreases enough (Armijo) */
        double det = h11 * h22 - h21 * h21;
        double dA = -(h22 * g1 - h21 * g2) / det, dB = -(-h21 * g1 + h11 * g2) / det, gd = g1 * dA + g2 * dB;
        double step = 1;
        for (; step >= min_step; step /= 2) {
            double nA = A + step * dA, nB = B + step * dB, nf = platt_nll(n, dec, lab, hi, lo, nA, nB);
            if (nf < f + 1e-4 * step * gd) {
                A = nA, B = nB, f = nf;
                break;
            }
        }
        if (step < min_step) break; /* the line search failed: keep the last point */
    }
    *A_out = A, *B_out = B;
}

/* Platt A and B of class c's SVM trained on rows idx, as libsvm's -b 1 gets
 * them (svm_binary_svc_probability): the rows in a random order split into
 * 5 folds; each fold's rows get their decision values from a model (same C
 * and gamma) trained on the other 4; the sigmoid is fitted to those. libsvm
 * draws that order from libc's rand(), which would make a library reseed
 * the process's generator; here it comes from core's generator, seeded
 * per class (stream), so builds stay reproducible. */
static int platt_fit(const mim__svm_data_t *data, const uint32_t *idx, uint32_t n, uint32_t c, double C, double gamma,
                     uint64_t stream, mim__svm_t *out, mim_error_t *err)
{
    enum { FOLDS = 5 };
    uint32_t *perm = malloc(sizeof(uint32_t) * (n + 1)), *tr = malloc(sizeof(uint32_t) * (n + 1));
    double *dec = malloc(sizeof(double) * (n + 1));
    int8_t *lab = malloc(n + 1);
    int rc = 0;
    if (!perm || !tr || !dec || !lab) {
        rc = MIM_ENOMEM;
        goto out;
    }
    memcpy(perm, idx, sizeof(uint32_t) * n);
    mim_rng_t rng;
    mim_rng_seed(&rng, MIM__INDEX_SEED, stream);
    for (uint32_t i = 0; i + 1 < n; i++) {
        uint32_t j = i + (uint32_t)mim_rng_below(&rng, n - i), t = perm[i];
        perm[i] = perm[j], perm[j] = t;
    }
    for (uint32_t i = 0; i < n; i++) lab[i] = data->y[perm[i]] == c ? 1 : -1;
    for (uint32_t f = 0; f < FOLDS && !rc; f++) {
        uint32_t begin = (uint32_t)((uint64_t)f * n / FOLDS), end = (uint32_t)((uint64_t)(f + 1) * n / FOLDS);
        if (begin == end) continue;
        uint32_t ntr = 0;
        for (uint32_t i = 0; i < n; i++)
            if (i < begin || i >= end) tr[ntr++] = perm[i];
        if (!ntr) { /* nothing to learn from: no opinion */
            for (uint32_t i = begin; i < end; i++) dec[i] = 0;
            continue;
        }
        mim__svm_t m; /* a constant model (one label only) answers -1 or +1, as libsvm's fit does */
        if ((rc = train_one(data, tr, ntr, c, C, gamma, &m, err))) break;
        for (uint32_t i = begin; i < end; i++)
            dec[i] = mim__svm_decision(&m, gamma, data->x + (size_t)perm[i] * data->d, NULL, data->d);
        mim__svm_free(&m);
    }
    if (!rc) sigmoid_fit(n, dec, lab, &out->prob_a, &out->prob_b);
out:
    free(perm), free(tr), free(dec), free(lab);
    return rc;
}

/* A stratified subsample of at most max rows (all rows if fewer), seeded. */
static uint32_t subsample(const mim__svm_data_t *data, uint32_t max, uint64_t stream, uint32_t *idx)
{
    uint32_t n = data->n;
    for (uint32_t i = 0; i < n; i++) idx[i] = i;
    if (n <= max) return n;
    mim_rng_t rng;
    mim_rng_seed(&rng, MIM__INDEX_SEED, stream);
    for (uint32_t i = n - 1; i > 0; i--) { /* shuffle, then keep the first max */
        uint32_t j = (uint32_t)mim_rng_below(&rng, i + 1), t = idx[i];
        idx[i] = idx[j], idx[j] = t;
    }
    return max;
}

/* Rows for class c's SVM: every positive (up to max/2), negatives to fill. */
static uint32_t class_rows(const mim__svm_data_t *data, uint32_t c, uint32_t max, uint64_t stream, uint32_t *idx,
                           uint32_t *scratch)
{
    uint32_t n = data->n;
    if (n <= max) {
        for (uint32_t i = 0; i < n; i++) idx[i] = i;
        return n;
    }
    uint32_t m = subsample(data, n, stream, scratch); /* a shuffled order */
    uint32_t out = 0, pos = 0;
    for (uint32_t i = 0; i < m && out < max / 2; i++)
        if (data->y[scratch[i]] == c) idx[out++] = scratch[i], pos++;
    for (uint32_t i = 0; i < m && out < max; i++)
        if (data->y[scratch[i]] != c) idx[out++] = scratch[i];
    return out;
}

int mim__svm_train_all(const mim__svm_data_t *data, const mim_index_options_t *opt, mim__svm_t *out, double *C_out,
                       double *gamma_out, double *cv_out, mim_error_t *err)
{
    svm_set_print_string_function(quiet);
    uint32_t n = data->n, d = data->d, nc = data->n_classes;
    uint32_t folds = opt->cv_folds ? opt->cv_folds : 5;
    uint32_t cv_max = opt->cv_max_samples ? opt->cv_max_samples : 1000;
    uint32_t svm_max = opt->svm_max_samples ? opt->svm_max_samples : 4000;
    uint32_t *idx = malloc(sizeof(uint32_t) * n), *scratch = malloc(sizeof(uint32_t) * n);
    uint32_t *fold = malloc(sizeof(uint32_t) * n), *tr = malloc(sizeof(uint32_t) * n);
    mim__svm_t *tmp = calloc(nc, sizeof *tmp);
    int rc = 0;
    if (!idx || !scratch || !fold || !tr || !tmp) {
        rc = MIM_ENOMEM;
        goto out;
    }
    double C = opt->C, gamma = opt->gamma, cv_acc = -1;
    if (nc < 2) { /* one class: nothing to decide */
        C = C > 0 ? C : 1, gamma = gamma > 0 ? gamma : 1;
        goto train;
    }
    if (!(C > 0 && gamma > 0)) {
        /* gamma's scale: 1 / mean squared distance between descriptors */
        uint32_t m = subsample(data, cv_max, 0x6376ULL, idx);
        double sum = 0;
        uint64_t pairs = 0;
        mim_rng_t rng;
        mim_rng_seed(&rng, MIM__INDEX_SEED, 0x67616d6dULL);
        for (uint32_t t = 0; t < 4000 && m > 1; t++) {
            uint32_t a = idx[mim_rng_below(&rng, m)], b = idx[mim_rng_below(&rng, m)];
            if (a == b) continue;
            double s = 0;
            for (uint32_t f = 0; f < d; f++) {
                double q = data->x[(size_t)a * d + f] - data->x[(size_t)b * d + f];
                s += q * q;
            }
            sum += s, pairs++;
        }
        double g0 = pairs && sum > 0 ? pairs / sum : 1.0 / d;
        /* folds: by subject when there are several (unseen people), else random */
        uint32_t k = folds;
        if (data->group && data->n_groups >= 2) {
            if (k > data->n_groups) k = data->n_groups;
            for (uint32_t i = 0; i < m; i++) fold[i] = data->group[idx[i]] % k;
        } else {
            if (k > m) k = m;
            mim_rng_seed(&rng, MIM__INDEX_SEED, 0x666f6c64ULL);
            for (uint32_t i = 0; i < m; i++) fold[i] = (uint32_t)mim_rng_below(&rng, k);
        }
        static const double Cs[] = {1, 10, 100, 1000}, Gs[] = {0.25, 1, 4, 16};
        double best_acc = -1;
        uint64_t best_sv = UINT64_MAX;
        for (int ci = 0; ci < 4; ci++)
            for (int gi = 0; gi < 4; gi++) {
                double c_try = Cs[ci], g_try = Gs[gi] * g0;
                uint32_t hits = 0, tested = 0;
                uint64_t svs = 0;
                for (uint32_t f = 0; f < k; f++) {
                    uint32_t ntr = 0;
                    for (uint32_t i = 0; i < m; i++)
                        if (fold[i] != f) tr[ntr++] = idx[i];
                    if (ntr == m || !ntr) continue;
                    for (uint32_t c = 0; c < nc && !rc; c++)
                        rc = train_one(data, tr, ntr, c, c_try, g_try, &tmp[c], err);
                    for (uint32_t i = 0; i < m && !rc; i++) {
                        if (fold[i] != f) continue;
                        const double *x = data->x + (size_t)idx[i] * d;
                        double bv = -INFINITY;
                        uint32_t arg = 0;
                        for (uint32_t c = 0; c < nc; c++) {
                            double v = mim__svm_decision(&tmp[c], g_try, x, NULL, d);
                            if (v > bv) bv = v, arg = c;
                        }
                        hits += arg == data->y[idx[i]];
                        tested++;
                    }
                    for (uint32_t c = 0; c < nc; c++) svs += tmp[c].n_sv, mim__svm_free(&tmp[c]);
                    if (rc) goto out;
                }
                double acc = tested ? (double)hits / tested : 0;
                if (acc > best_acc + 1e-12 || (acc > best_acc - 1e-12 && svs < best_sv)) {
                    best_acc = acc, best_sv = svs, C = c_try, gamma = g_try;
                }
                if (opt->progress) mim_progress_update(opt->progress, opt->progress->done + 1);
            }
        cv_acc = best_acc;
    }
train:
    for (uint32_t c = 0; c < nc && !rc; c++) {
        if (nc < 2) break;
        uint32_t m = class_rows(data, c, svm_max, 0x737663ULL + c, idx, scratch);
        uint32_t pos = count_positive(data, idx, m, c);
        rc = train_one(data, idx, m, c, C, gamma, &out[c], err);
        if (!rc && pos && pos < m) rc = platt_fit(data, idx, m, c, C, gamma, 0x706c6174ULL + c, &out[c], err);
        if (opt->progress) mim_progress_update(opt->progress, opt->progress->done + 1);
    }
    *C_out = C, *gamma_out = gamma, *cv_out = cv_acc;
out:
    if (tmp)
        for (uint32_t c = 0; c < nc; c++) mim__svm_free(&tmp[c]);
    free(tmp), free(idx), free(scratch), free(fold), free(tr);
    return rc;
}
