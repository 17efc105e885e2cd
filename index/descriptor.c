/* The angle pose descriptor (seed 000, Section 3.2): at landmark j the angle
 * theta = acos(l_i . l_k / |l_i||l_k|) between the segments l_i = v_i - v_j and
 * l_k = v_k - v_j, for every j and every unordered pair {i, k} of the other
 * landmarks. Candidate a = j * C(n-1, 2) + (index of the pair {i, k} among
 * the other n-1 landmarks, i < k, in lexicographic order). */
#include "mim_index.h"

#include <math.h>

static uint32_t pairs(uint32_t m) { return m * (m - 1) / 2; }

uint32_t mim_index_angle_count(uint32_t n) { return n < 3 ? 0 : n * pairs(n - 1); }

/* Index of the pair (p < q) among m items. */
static uint32_t pair_index(uint32_t m, uint32_t p, uint32_t q) { return p * (2 * m - p - 1) / 2 + (q - p - 1); }

uint32_t mim_index_angle_of(uint32_t n, uint32_t i, uint32_t j, uint32_t k)
{
    if (i > k) {
        uint32_t t = i;
        i = k;
        k = t;
    }
    uint32_t p = i < j ? i : i - 1, q = k < j ? k : k - 1; /* positions among the others */
    return j * pairs(n - 1) + pair_index(n - 1, p, q);
}

void mim_index_angle_triple(uint32_t n, uint32_t a, uint32_t *i, uint32_t *j, uint32_t *k)
{
    uint32_t m = n - 1, per = pairs(m);
    *j = a / per;
    uint32_t r = a % per, p = 0;
    while (r >= m - 1 - p) { /* row p holds the pairs (p, p+1 .. m-1) */
        r -= m - 1 - p;
        p++;
    }
    uint32_t q = p + 1 + r;
    *i = p < *j ? p : p + 1;
    *k = q < *j ? q : q + 1;
}

void mim_index_angle_mirror(uint32_t n, const uint32_t *mirror, uint32_t *map)
{
    uint32_t count = mim_index_angle_count(n);
    for (uint32_t a = 0; a < count; a++) {
        uint32_t i, j, k;
        mim_index_angle_triple(n, a, &i, &j, &k);
        map[a] = mim_index_angle_of(n, mirror[i], mirror[j], mirror[k]);
    }
}

static float angle_at(const float *pos, uint32_t i, uint32_t j, uint32_t k)
{
    double a[3], b[3], aa = 0, bb = 0, ab = 0;
    for (int c = 0; c < 3; c++) {
        a[c] = (double)pos[3 * i + c] - pos[3 * j + c];
        b[c] = (double)pos[3 * k + c] - pos[3 * j + c];
        aa += a[c] * a[c];
        bb += b[c] * b[c];
        ab += a[c] * b[c];
    }
    if (!(aa > 0) || !(bb > 0)) return NAN; /* coincident landmarks: no direction */
    double cosv = ab / sqrt(aa * bb);
    if (cosv > 1) cosv = 1;
    if (cosv < -1) cosv = -1;
    return (float)acos(cosv);
}

void mim_index_angles(const float *pos, const uint8_t *present, uint32_t n, float *angles)
{
    uint32_t count = mim_index_angle_count(n);
    for (uint32_t a = 0; a < count; a++) {
        uint32_t i, j, k;
        mim_index_angle_triple(n, a, &i, &j, &k);
        angles[a] = (present && (!present[i] || !present[j] || !present[k])) ? NAN : angle_at(pos, i, j, k);
    }
}

void mim_index_descriptor(const float *pos, const uint8_t *present, uint32_t n, const uint32_t *selected, uint32_t d,
                          float *out)
{
    for (uint32_t s = 0; s < d; s++) {
        uint32_t i, j, k;
        mim_index_angle_triple(n, selected[s], &i, &j, &k);
        out[s] = (present && (!present[i] || !present[j] || !present[k])) ? NAN : angle_at(pos, i, j, k);
    }
}
