/* Lower bounds of Section 6's D_C, D_I and D_S (distance.c), so that
 * coverage (eq. 13, coverage.c) computes a distance only for the samples
 * that can still be nearest. Each holds for every pair, whatever the
 * alignment turns b by:
 *
 * - D_C. The alignment puts b's centroid on a's (bb_i = ca + R (b_i - cb),
 *   R a rotation), so |bb_i - ca| = |b_i - cb| =: rb_i, and by the triangle
 *   inequality |a_i - bb_i| >= | |a_i - ca| - rb_i |:
 *   D_C >= sqrt(mean_i (ra_i - rb_i)^2), ra and rb the joints' distances
 *   from their own centroid.
 * - LIMBS. The same over the 24 limb joints, whose centroid the fit over
 *   them matches: each |a_i - bb_i| >= | |a_i - ca| - rb_i |, so the mean
 *   distance is at least the mean of | ra_i - rb_i |; for the people
 *   swapped, rb's halves swapped; the smaller of the two bounds both.
 * - D_I (eq. 8). Each edge term |u_e(a) - u_e(bb)| >= | |u_e(a)| - |u_e(b)| |,
 *   as a rigid motion keeps lengths; so each half of eq. 8 is at least its
 *   weighted mean of length differences: D_I >= sum over the 561 joint pairs
 *   p of (wa_p + wb_p) |La_p - Lb_p|, L the pairs' lengths and w_p a
 *   triangulation's weight over its weights' sum (0 off its edges). Once
 *   b is aligned, the distance itself in floats, lowered by its rounding
 *   (ic_aligned).
 * - D_S. f(x, y) = (x - y)^2 / (x + y) is convex and positively homogeneous,
 *   hence subadditive (f(s + t) = 2 f((s + t) / 2) <= f(s) + f(t)): adding
 *   bins together never raises the chi-squared cost. Summed over azimuth and
 *   elevation, a joint's histogram depends on distances alone, which the
 *   alignment keeps: the first bound, with the sample's sums made once.
 *   Once b is aligned, each joint's own term in place of its sum's, a
 *   joint at a time: the aligned bound.
 *
 * Rounding: the bounds hold in exact arithmetic; each computed bound is
 * lowered so that it stays at or below the distance as computed. The
 * first bounds are sums of nonnegative float terms (relative error under
 * 200 float epsilons: REL); a float feature is off by an epsilon of its
 * size (LEN_SLACK times the largest length, metres); the alignment's
 * rounding grows with the coordinates' size (FAR_SLACK times it, over the
 * mean joint distance for D_S's bins: mim__bound_slack). D_S's histograms
 * are floats summed by spread: at most 8 additions per other joint reach
 * a bin, so a joint's histogram is off its exact value by at most
 * 8 (n - 1) + 8 float epsilons in all (its counts sum to 1), and the
 * samples' radial bin coordinates, kept as floats (|fr| < 4 where it
 * counts), move at most 12 more; f is 3-Lipschitz in each argument and D_S
 * is 0.5 f summed over bins over n: SC_SLACK. The aligned bound's
 * histograms (mim__sc_row and mim__sc_row_histogram, in floats) share
 * each count with its radial, elevation and azimuth coordinates off by 4
 * float epsilons, MIM__BOUND_EL_COORD_ERR and MIM__BOUND_AZ_COORD_ERR
 * bins and its cosine of elevation by MIM__BOUND_COS_ERR: each count's
 * shares by twice their sum. Made in floats, its radial and elevation
 * shares' products round by 2.5 epsilons in all, its azimuth profile
 * (hats |fa - a| off by 2 epsilons, 1 - that by half of one more, times
 * the cosine, plus the rest) by 6.5 and their products by half of one:
 * 10 more; both histograms' sums (the row's: one addition per count and
 * bin, and one more) by SC_SLACK's 8 (n - 1) + 8; times 1.5 for 0.5 f:
 * WHOLE_SLACK. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <string.h>

#define N MIM_PAIR_JOINTS
#define PAIRS MIM__JOINT_PAIRS
#define PAD(x) (((x) + 7) / 8 * 8)
#define C_DIM PAD(N)
#define I_HALF PAD(PAIRS)
#define L_N (2 * MIM_LIMB_COUNT)
#define L_HALF PAD(MIM_LIMB_COUNT) /* a person's limb joints, then 0s */
_Static_assert((L_HALF & (L_HALF - 1)) == 0, "x ^ L_HALF swaps the halves");
#define L_DIM (2 * L_HALF)
#define S_DIM MIM__SC_RADIAL

#define REL 1e-4
#define LEN_SLACK 1e-6
#define FAR_SLACK 1e-12
#define SC_SLACK (1.5 * (8.0 * (N - 1) + 8.0 + 12.0) * (FLT_EPSILON / 2) + 1e-9)
#define WHOLE_SLACK                                                                                                    \
    (1.01 * 1.5 *                                                                                                      \
     (2 * (MIM__BOUND_EL_COORD_ERR + MIM__BOUND_AZ_COORD_ERR + MIM__BOUND_COS_ERR + 4 * FLT_EPSILON) +                 \
      (10 + 2 * (8.0 * (N - 1) + 8)) * FLT_EPSILON))
/* added to x + y in the first D_S bound: a term can only get smaller, and
 * 0 / 0 never arises (the loop stays free of branches) */
#define TINY 1e-30f

uint32_t mim__bound_dim(mim_sample_metric_t metric)
{
    return metric == MIM_METRIC_CARTESIAN ? C_DIM : metric == MIM_METRIC_LIMBS ? L_DIM : metric == MIM_METRIC_SHAPE ? S_DIM : 2 * I_HALF;
}

uint32_t mim__bound_stride(mim_sample_metric_t metric)
{
    return mim__bound_dim(metric) + (metric == MIM_METRIC_SHAPE ? PAD(MIM__JOINT_PAIRS) : 0);
}

static void centroid_distances_n(const double *p, int n, float *f)
{
    double c[3] = {0, 0, 0};
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) c[k] += p[3 * i + k] / n;
    for (int i = 0; i < n; i++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (p[3 * i + k] - c[k]) * (p[3 * i + k] - c[k]);
        f[i] = (float)sqrt(d2);
    }
}

static void centroid_distances(const double *p, float *f) { centroid_distances_n(p, N, f); }

/* LIMBS: the 24 limb joints' distances from their own centroid, each
 * person's 12 in a half of L_DIM (so that the people swapped are the
 * halves swapped, whole lanes; the padding 0) */
static void limb_distances(const double *p, float *f)
{
    double l[3 * L_N];
    float r[L_N];
    mim__limb_joints(p, 0, l);
    centroid_distances_n(l, L_N, r);
    memset(f, 0, L_DIM * sizeof *f);
    for (int person = 0; person < 2; person++)
        memcpy(f + person * L_HALF, r + person * MIM_LIMB_COUNT, MIM_LIMB_COUNT * sizeof *f);
}

/* Lengths of the 561 joint pairs, then each pair's share of eq. 8's
 * weights in p's own triangulation. */
static void pair_lengths(const mim_pair_prep_t *p, float *f)
{
    double len[PAIRS], w[MIM_IC_MAX_EDGES], wsum = 0;
    mim__pair_distances(p->joints, len);
    for (int k = 0; k < PAIRS; k++) f[k] = (float)len[k];
    for (uint32_t e = 0; e < p->ic.n_edges; e++) {
        w[e] = mim__ic_weight(len[mim__pair_index(p->ic.edge[e][0], p->ic.edge[e][1])], MIM_IC_DEFAULT_BETA);
        wsum += w[e];
    }
    for (uint32_t e = 0; e < p->ic.n_edges; e++)
        f[I_HALF + mim__pair_index(p->ic.edge[e][0], p->ic.edge[e][1])] = (float)(w[e] / wsum);
}

void mim__bound_features(mim_sample_metric_t metric, const mim_pair_prep_t *p, int truth, float *f)
{
    memset(f, 0, sizeof(float) * (truth ? mim__bound_dim(metric) : mim__bound_stride(metric)));
    if (metric == MIM_METRIC_CARTESIAN) {
        centroid_distances(p->joints, f);
    } else if (metric == MIM_METRIC_LIMBS) {
        limb_distances(p->joints, f);
    } else if (metric == MIM_METRIC_SHAPE) {
        double rad[N * MIM__SC_R];
        if (truth) {
            /* the truth's histogram itself: D_S compares it, not its exact value */
            mim__sc_histogram_marginals(p->sc, rad);
        } else {
            mim__sc_pair_radii(p->joints, f + S_DIM);
            mim__sc_radial(f + S_DIM, rad);
        }
        for (int i = 0; i < N * MIM__SC_R; i++) f[i] = (float)rad[i];
    } else {
        pair_lengths(p, f);
    }
}

double mim__bound_slack(mim_sample_metric_t metric, const mim_pair_prep_t *p)
{
    double far = 0, size = 0, mean = 0, len[PAIRS];
    float r[C_DIM > L_DIM ? C_DIM : L_DIM];
    for (int i = 0; i < 3 * N; i++) far = fmax(far, fabs(p->joints[i]));
    if (metric == MIM_METRIC_LIMBS) limb_distances(p->joints, r);
    else centroid_distances(p->joints, r);
    for (int i = 0; i < (metric == MIM_METRIC_LIMBS ? L_DIM : N); i++) size = fmax(size, r[i]);
    if (metric != MIM_METRIC_SHAPE) return LEN_SLACK * 2 * size + FAR_SLACK * far;
    mim__pair_distances(p->joints, len);
    for (int k = 0; k < PAIRS; k++) mean += len[k] / PAIRS;
    return mean > 0 ? FAR_SLACK * (far + size) / mean : INFINITY;
}

/* The loops below sum in 8 lanes, so that the compiler may vectorise
 * them without reordering a sum. */
#define LANES 8
static float lanes_sum(const float *acc)
{
    return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
}

/* sum (x - y)^2 / (x + y) over n floats (a multiple of LANES), in lanes. */
static inline float chi_lanes(const float *x, const float *y, uint32_t n)
{
    mim__v8f acc = {0}, a, b;
    for (uint32_t i = 0; i < n; i += LANES) {
        memcpy(&a, x + i, sizeof a), memcpy(&b, y + i, sizeof b);
        acc += (a - b) * (a - b) / (a + b + TINY);
    }
    float lane[LANES];
    memcpy(lane, &acc, sizeof lane);
    return lanes_sum(lane);
}

/* D_I's first bound of n samples (stride floats apart, n up to
 * IC_BLOCK) at once, each summed alike: the truth's features are read
 * once for all of them (the loop is bound by its reads). */
#define IC_BLOCK 4
static inline void ic_first_bounds(const float *fa, const float *b, uint32_t stride, int n, float *out)
{
    float acc[IC_BLOCK][LANES] = {{0}};
    for (uint32_t i = 0; i < I_HALF; i += LANES)
        for (int s = 0; s < n; s++) {
            const float *bs = b + (size_t)s * stride;
            for (int l = 0; l < LANES; l++)
                acc[s][l] += (fa[I_HALF + i + l] + bs[I_HALF + i + l]) * fabsf(fa[i + l] - bs[i + l]);
        }
    for (int s = 0; s < n; s++) out[s] = lanes_sum(acc[s]);
}

/* One truth's first bound of one sample, before the rounding's allowance. */
static inline float first_bound(mim_sample_metric_t metric, const float *fa, const float *b)
{
    float acc[LANES] = {0};
    if (metric == MIM_METRIC_CARTESIAN) {
        for (uint32_t i = 0; i < C_DIM; i += LANES)
            for (int l = 0; l < LANES; l++) acc[l] += (fa[i + l] - b[i + l]) * (fa[i + l] - b[i + l]);
        return sqrtf(lanes_sum(acc) / N);
    }
    if (metric == MIM_METRIC_LIMBS) {
        /* the people as they are, then swapped (b's halves exchanged) */
        float swapped[LANES] = {0};
        for (uint32_t i = 0; i < L_DIM; i += LANES)
            for (int l = 0; l < LANES; l++) {
                const uint32_t x = i + (uint32_t)l;
                acc[l] += fabsf(fa[x] - b[x]);
                swapped[l] += fabsf(fa[x] - b[x ^ L_HALF]);
            }
        return fminf(lanes_sum(acc), lanes_sum(swapped)) / L_N;
    }
    if (metric == MIM_METRIC_SHAPE) return 0.5f * chi_lanes(fa, b, S_DIM) / N;
    float one;
    ic_first_bounds(fa, b, 0, 1, &one);
    return one;
}

/* The truths go in the inner loop: a sample's features are read from
 * memory once for all of them, not once a truth (D_I's are 4.5 KB); D_I's
 * samples IC_BLOCK at a time. */
MIM__VECTOR_CLONES static void bound_lower(mim_sample_metric_t metric, const float *fa, uint32_t n, const float *fb, uint32_t k,
                                            const double *slack, float *lb)
{
    const uint32_t stride = mim__bound_stride(metric), dim = mim__bound_dim(metric);
    const float keep = (float)(1 - REL);
    float less[MIM__BOUND_TRUTHS];
    for (uint32_t t = 0; t < n; t++) less[t] = (float)((metric == MIM_METRIC_SHAPE ? SC_SLACK : LEN_SLACK) + slack[t]);
    uint32_t j = 0;
    if (metric == MIM_METRIC_IC)
        for (; j + IC_BLOCK <= k; j += IC_BLOCK)
            for (uint32_t t = 0; t < n; t++) {
                float first[IC_BLOCK];
                ic_first_bounds(fa + (size_t)t * dim, fb + (size_t)j * stride, stride, IC_BLOCK, first);
                for (int s = 0; s < IC_BLOCK; s++) lb[(size_t)t * k + j + s] = first[s] * keep - less[t];
            }
    for (; j < k; j++)
        for (uint32_t t = 0; t < n; t++)
            lb[(size_t)t * k + j] = first_bound(metric, fa + (size_t)t * dim, fb + (size_t)j * stride) * keep - less[t];
}

void mim__bound_lower(mim_sample_metric_t metric, const float *fa, uint32_t n, const float *fb, uint32_t k, const double *slack,
                      float *lb)
{
    bound_lower(metric, fa, n, fb, k, slack, lb);
}

/* D_I once b is aligned. Each edge term of eq. 8 compares
 * u_e(a) - u_e(bb) = d_j - d_i, with d = a - bb: so D_I is the sum over
 * the 561 joint pairs of (wa_p + wb_p) |d_j - d_i|, w the first bound's
 * weights (0 off a triangulation's edges). In floats: each |d_j - d_i| is
 * off by 4 float epsilons of itself and one of |d_i| + |d_j| (d rounded
 * to floats), the weights by half of one, the sum in lanes by 72 of
 * itself: all within REL, and 2 epsilons of the largest |d|. */
MIM__VECTOR_CLONES static float ic_aligned(const double *a, const double *bb, const float *wa, const float *wb, float *dmax)
{
    float x[N], y[N], z[N], len[I_HALF], big = 0;
    for (int k = PAIRS; k < I_HALF; k++) len[k] = 0; /* the padding (the pairs all set below) */
    for (int i = 0; i < N; i++) {
        x[i] = (float)(a[3 * i] - bb[3 * i]), y[i] = (float)(a[3 * i + 1] - bb[3 * i + 1]);
        z[i] = (float)(a[3 * i + 2] - bb[3 * i + 2]);
        const float ax = fabsf(x[i]), ay = fabsf(y[i]), az = fabsf(z[i]), m = ax > ay ? (ax > az ? ax : az) : (ay > az ? ay : az);
        big = m > big ? m : big;
    }
    for (int i = 0, k = 0; i < N; k += N - 1 - i, i++) {
        float *out = len + k - i - 1; /* pair (i, j) at k + j - i - 1 */
        for (int j = i + 1; j < N; j++) {
            const float dx = x[j] - x[i], dy = y[j] - y[i], dz = z[j] - z[i];
            out[j] = sqrtf(dx * dx + dy * dy + dz * dz);
        }
    }
    float acc[LANES] = {0};
    for (uint32_t i = 0; i < I_HALF; i += LANES)
        for (int l = 0; l < LANES; l++) acc[l] += (wa[i + l] + wb[i + l]) * len[i + l];
    *dmax = 2 * big; /* |d| <= sqrt(3) of its largest coordinate */
    return lanes_sum(acc);
}

double mim__ic_distance_aligned(const mim_pair_prep_t *a, const float *fa, const mim_pair_prep_t *b, const double *bb,
                                const float *fb, double slack, double best, int *exact)
{
    float dmax;
    const double sum = ic_aligned(a->joints, bb, fa + I_HALF, fb + I_HALF, &dmax);
    const double lower = sum * (1 - REL) - 2 * FLT_EPSILON * dmax - LEN_SLACK - slack;
    if (lower > best) {
        *exact = 0;
        return lower;
    }
    *exact = 1; /* the scan's: mim_sample_distance's alignment and eq. 8 */
    return mim_ic_distance(a->joints, &a->ic, bb, &b->ic, MIM_IC_DEFAULT_BETA);
}

/* 0.5 (x - y)^2 / (x + y) for each of n floats (a multiple of LANES). */
MIM__VECTOR_CLONES static void chi_each(const float *x, const float *y, uint32_t n, float *out)
{
    for (uint32_t i = 0; i < n; i++) out[i] = 0.5f * (x[i] - y[i]) * (x[i] - y[i]) / (x[i] + y[i] + TINY);
}

/* One joint's chi-squared cost over its histogram's bins, in float lanes. */
MIM__VECTOR_CLONES static double joint_cost(const float *a, const float *h) { return 0.5f * chi_lanes(a, h, MIM_SC_BINS); }

/* The aligned bound, a joint at a time. Each joint's term is at least its
 * term summed over azimuth and elevation (subadditivity, above), which
 * needs no alignment: the bound starts at those radial terms, and the
 * joints go one by one, each replacing its radial term with its own (its
 * row's histogram, made from the aligned joints alone); it stops as soon
 * as it passes best: most samples end before most joints are made. The
 * joints that added most to this truth's earlier samples go first (gain:
 * a running mean of what a joint adds, each joint's starting above any,
 * so that each is tried). Returns a bound above best, or else -INFINITY
 * (every joint made). */
static double shape_aligned_bound(mim__shape_truth_t *ta, const mim__sc_coords_t *c, const float *fb, double slack, double best)
{
    /* b's radial sums: its first bound's features (float, SC_SLACK's rounding) */
    float term[S_DIM];
    double radial[N], rest = 0;
    chi_each(ta->rad, fb, S_DIM, term);
    for (int i = 0; i < N; i++) {
        radial[i] = 0;
        for (int r = 0; r < MIM__SC_R; r++) radial[i] += term[i * MIM__SC_R + r];
        rest += radial[i];
    }
    /* the order of the samples before, sorted again: gains move a little a sample */
    int *const order = ta->order;
    for (int t = 1; t < N; t++) {
        const int i = order[t];
        int u = t;
        for (; u > 0 && ta->gain[order[u - 1]] < ta->gain[i]; u--) order[u] = order[u - 1];
        order[u] = i;
    }
    /* the bound may pass best once the sum passes this (no division a joint) */
    const double pass = (best + SC_SLACK + WHOLE_SLACK + slack) / (1 - REL) * N;
    double made = 0;
    for (int t = 0; t < N; t++) {
        const int i = order[t];
        mim__sc_row_t row;
        float h[MIM_SC_BINS];
        mim__sc_row(c, fb + S_DIM, i, &row);
        mim__sc_row_histogram(&row, h);
        const double own = joint_cost(ta->sc[i], h);
        ta->gain[i] += (own - radial[i] - ta->gain[i]) / 8;
        made += own, rest -= radial[i];
        const double sum = made + (t + 1 < N ? fmax(rest, 0.0) : 0.0);
        if (sum > pass) {
            const double lower = sum / N * (1 - REL) - SC_SLACK - WHOLE_SLACK - slack;
            if (lower > best) return lower;
        }
    }
    return -INFINITY;
}

void mim__shape_truth(const mim_pair_prep_t *a, mim__shape_truth_t *ta)
{
    double rad[N * MIM__SC_R];
    memset(ta, 0, sizeof *ta);
    mim__sc_histogram_marginals(a->sc, rad);
    for (int i = 0; i < N; i++)
        for (int r = 0; r < MIM__SC_R; r++)
            for (int az = 0; az < MIM__SC_AZ; az++)
                for (int e = 0; e < MIM__SC_EL; e++)
                    ta->sc[i][MIM__SC_WORK(r, e, az)] = a->sc[i][(r * MIM__SC_AZ + az) * MIM__SC_EL + e];
    for (int b = 0; b < N * MIM__SC_R; b++) ta->rad[b] = (float)rad[b];
    for (int i = 0; i < N; i++) ta->gain[i] = 1.0, ta->order[i] = i; /* above any gain: each joint tried */
}

double mim__shape_distance_aligned(const mim_pair_prep_t *a, mim__shape_truth_t *ta, const double *bb, const float *fb,
                                   double slack, double best, int *exact)
{
    double terms[N][MIM_SC_BINS];
    mim__sc_coords_t c;
    mim__sc_coords(bb, &c);
    const double lower = shape_aligned_bound(ta, &c, fb, slack, best);
    if (lower > best) {
        *exact = 0;
        return lower;
    }
    /* no bound above best: the histograms as the scan makes them */
    mim__sc_pairs_t w;
    mim__sc_pairs_begin_lazy(bb, &w);
    mim__sc_pairs_finish_lazy(&w);
    for (int i = 0; i < N; i++) {
        float h[MIM_SC_BINS];
        mim__sc_pairs_joint_ready(&w, i);
        mim__sc_joint(&w, i, h);
        for (int k = 0; k < MIM_SC_BINS; k++) terms[i][k] = mim__chi_term(a->sc[i][k], h[k]);
    }
    /* every joint made: the sum in mim__shape_cost's order, as the scan's */
    double total = 0;
    for (int i = 0; i < N; i++)
        for (int k = 0; k < MIM_SC_BINS; k++) total += terms[i][k];
    *exact = 1;
    return total / N;
}
