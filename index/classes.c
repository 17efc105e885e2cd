/* Classes for a store without pose labels: k-means on the candidate angles
 * (the paper's classes are pose labels, Section 3.3; an unlabelled store
 * needs some grouping for the per-class SVMs and k-NN). k-means++ seeding
 * with a fixed seed, then Lloyd iterations; a NaN angle (coincident
 * landmarks) is left out of a distance and of a mean. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

uint32_t mim__class_sample(const uint32_t *cls, uint32_t n, uint32_t nc, uint32_t per_class, uint32_t *pick)
{
    uint32_t *count = calloc(nc, sizeof *count), *seen = calloc(nc, sizeof *seen), np = 0;
    if (!count || !seen) {
        free(count), free(seen);
        return 0;
    }
    for (uint32_t t = 0; t < n; t++) count[cls[t]]++;
    for (uint32_t t = 0; t < n; t++) { /* the i-th of a class is picked when it crosses a step */
        uint32_t c = cls[t], i = seen[c]++;
        uint32_t want = count[c] < per_class ? count[c] : per_class;
        if ((uint64_t)i * want / count[c] != (uint64_t)(i + 1) * want / count[c]) pick[np++] = t;
    }
    free(count), free(seen);
    return np;
}

/* k = round(sqrt(n / 2)), 1..64: Mardia's rule of thumb (see mim_index.h). */
uint32_t mim__kmeans_k(uint32_t n)
{
    uint32_t k = (uint32_t)lround(sqrt(n / 2.0));
    if (k < 1) k = 1;
    if (k > 64) k = 64;
    if (k > n) k = n;
    return k;
}

static double dist2(const float *a, const double *c, uint32_t f)
{
    double s = 0;
    for (uint32_t i = 0; i < f; i++) {
        if (isnan(a[i]) || isnan(c[i])) continue;
        double d = a[i] - c[i];
        s += d * d;
    }
    return s;
}

int mim__kmeans(const float *x, uint32_t n, uint32_t f, uint32_t k, uint32_t *assign, mim_error_t *err)
{
    if (!n || !k || k > n) return mim_error_set(err, MIM_EINVAL, "k-means: %u clusters of %u samples", k, n);
    double *c = malloc(sizeof(double) * (size_t)k * f), *best = malloc(sizeof(double) * n);
    double *sum = malloc(sizeof(double) * (size_t)k * f);
    uint32_t *cnt = malloc(sizeof(uint32_t) * (size_t)k * f);
    if (!c || !best || !sum || !cnt) {
        free(c), free(best), free(sum), free(cnt);
        return MIM_ENOMEM;
    }
    mim_rng_t rng;
    mim_rng_seed(&rng, MIM__INDEX_SEED, 0x6b6d65616e73ULL);
    /* k-means++: the first centre at random, then each with probability
     * proportional to the squared distance to the nearest centre so far */
    uint32_t first = (uint32_t)mim_rng_below(&rng, n);
    for (uint32_t i = 0; i < f; i++) c[i] = x[(size_t)first * f + i];
    for (uint32_t s = 0; s < n; s++) best[s] = dist2(x + (size_t)s * f, c, f);
    for (uint32_t j = 1; j < k; j++) {
        double total = 0;
        for (uint32_t s = 0; s < n; s++) total += best[s];
        double r = mim_rng_unit(&rng) * total;
        uint32_t pick = n - 1;
        for (uint32_t s = 0; s < n; s++) {
            r -= best[s];
            if (r < 0) {
                pick = s;
                break;
            }
        }
        for (uint32_t i = 0; i < f; i++) c[(size_t)j * f + i] = x[(size_t)pick * f + i];
        for (uint32_t s = 0; s < n; s++) {
            double d = dist2(x + (size_t)s * f, c + (size_t)j * f, f);
            if (d < best[s]) best[s] = d;
        }
    }
    for (uint32_t it = 0; it < 50; it++) {
        int changed = it == 0;
        for (uint32_t s = 0; s < n; s++) {
            double bd = INFINITY;
            uint32_t arg = 0;
            for (uint32_t j = 0; j < k; j++) {
                double d = dist2(x + (size_t)s * f, c + (size_t)j * f, f);
                if (d < bd) bd = d, arg = j;
            }
            if (it == 0 || assign[s] != arg) changed = 1;
            assign[s] = arg;
        }
        if (!changed) break;
        memset(sum, 0, sizeof(double) * (size_t)k * f);
        memset(cnt, 0, sizeof(uint32_t) * (size_t)k * f);
        for (uint32_t s = 0; s < n; s++)
            for (uint32_t i = 0; i < f; i++) {
                float v = x[(size_t)s * f + i];
                if (isnan(v)) continue;
                sum[(size_t)assign[s] * f + i] += v;
                cnt[(size_t)assign[s] * f + i]++;
            }
        for (size_t i = 0; i < (size_t)k * f; i++)
            if (cnt[i]) c[i] = sum[i] / cnt[i]; /* an emptied cluster keeps its centre */
    }
    free(c), free(best), free(sum), free(cnt);
    return 0;
}
