/* 3D shape contexts (seed 002, Section 6: D_S, after Belongie et al., the
 * paper's [45]) and the chi-squared cost between them; and the histograms'
 * marginals, whose cost bounds D_S from below (coverage_bounds.c). Binning
 * choices: mim_sample.h. */
#include "internal.h"

#include <math.h>
#include <string.h>

#define N MIM_PAIR_JOINTS
#define SC_R MIM__SC_R
#define SC_AZ MIM__SC_AZ
#define SC_EL MIM__SC_EL
_Static_assert(SC_R * SC_AZ * SC_EL == MIM_SC_BINS, "shape context bins");

/* Soft binning (each count shared linearly between the two nearest bins
 * along log r, azimuth (circular) and elevation, and the azimuth's share
 * fading out towards the poles, where it is undefined): plain binning
 * jumps when a joint sits on a bin's edge or straight above another, which
 * skeletons do, so a pair and its own rigid copy would differ. h is laid
 * out azimuth innermost (WORK), so that a share for all azimuths is added
 * to 8 neighbours at once. */
#define WORK MIM__SC_WORK
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
                h[WORK(r, e, a)] += (float)(w * k * cos_el * (da ? ta : 1 - ta));
                if (da) continue;
                const float all = (float)(w * k * (1 - cos_el) / SC_AZ);
                float *row = h + WORK(r, e, 0);
                for (int u = 0; u < SC_AZ; u++) row[u] += all;
            }
}

/* The vector from joint i to joint j and its length. */
static double pair_vector(const double *p, int i, int j, double v[3])
{
    for (int c = 0; c < 3; c++) v[c] = p[3 * j + c] - p[3 * i + c];
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* Bin coordinates, bin centres at integers: log r; elevation, up being y
 * (the data's convention: mimic's bodies and BVH). */
static double radial_coordinate(double r, double r0, double r1)
{
    return r > 0 ? (log(r) - r0) / (r1 - r0) * SC_R - 0.5 : 0.0;
}
static double elevation(const double v[3], double r) { return r > 0 ? asin(v[1] / r) : 0.0; }
static double elevation_coordinate(double el) { return (el + M_PI / 2) / M_PI * SC_EL - 0.5; }

/* Every count weighs the same: 1 / (n - 1) as a float, as spread adds it. */
static const float weight = 1.0f / (N - 1);

#define PAIRS MIM__JOINT_PAIRS

/* j seen from i and i from j: one distance (v negated exactly), and
 * opposite elevations of one cosine (asin odd, cos even) */
void mim__sc_pairs_begin(const double *p, mim__sc_pairs_t *w)
{
    w->p = p;
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) {
            double v[3];
            w->r[k] = pair_vector(p, i, j, v), w->el[k] = elevation(v, w->r[k]);
        }
}

void mim__sc_pairs_begin_lazy(const double *p, mim__sc_pairs_t *w)
{
    /* the coordinates apart, so that the loop over j vectorises; each
     * distance is pair_vector's, to the bit (the same operations in order) */
    double x[N], y[N], z[N];
    for (int i = 0; i < N; i++) x[i] = p[3 * i], y[i] = p[3 * i + 1], z[i] = p[3 * i + 2];
    w->p = p;
    for (int i = 0, k = 0; i < N; k += N - 1 - i, i++) {
        double *r = w->r + k - i - 1, *up = w->up + k - i - 1; /* pair (i, j) at k + j - i - 1 */
        for (int j = i + 1; j < N; j++) {
            const double dx = x[j] - x[i], dy = y[j] - y[i], dz = z[j] - z[i];
            r[j] = sqrt(dx * dx + dy * dy + dz * dz), up[j] = dy;
        }
    }
}

/* atan(u) for u in [0, 1]: a polynomial fitted there (within 1.3e-7 of
 * atan in floats), by Estrin's scheme: the terms' products in parallel,
 * not one long chain. */
static inline float atan01(float u)
{
    static const float c[] = {0.99999934f,  -0.33329859f, 0.19946562f,  -0.13908616f,
                              0.096421652f, -0.055911936f, 0.021862714f, -0.0040545058f};
    const float s = u * u, s2 = s * s, s4 = s2 * s2;
    return u * (((c[0] + c[1] * s) + (c[2] + c[3] * s) * s2) + ((c[4] + c[5] * s) + (c[6] + c[7] * s) * s2) * s4);
}

/* The azimuth coordinate of (x, z), as (atan2(z, x) + pi) / 2pi SC_AZ - 1/2
 * is, in floats (MIM__BOUND_AZ_COORD_ERR bounds how far): the angle from
 * the x or z axis, whichever is nearer, atan01 of the smaller coordinate
 * over the larger, then the octant put back. One division; both branches
 * made and one kept, so that loops over it vectorise. */
static inline float bound_azimuth(float x, float z)
{
    const float ax = x < 0 ? -x : x, az = z < 0 ? -z : z;
    const int steep = az > ax;
    const float hi = steep ? az : ax, lo = steep ? ax : az;
    float ang = atan01(hi > 0 ? lo / hi : 0.0f); /* in [0, pi/4] */
    ang = steep ? (float)(M_PI / 2) - ang : ang; /* the angle from +x in the quadrant */
    ang = x < 0 ? (float)M_PI - ang : ang;
    ang = z < 0 ? -ang : ang;
    return (ang + (float)M_PI) * (float)(SC_AZ / (2 * M_PI)) - 0.5f;
}

float mim__sc_bound_azimuth(float x, float z) { return bound_azimuth(x, z); }

/* ---- a joint's row: its pairs side by side, in floats (the bounds') ---- */
#define ROW MIM__SC_ROW
#define LANES 8
_Static_assert(ROW % LANES == 0 && ROW >= N, "a row holds every joint, in whole lanes");

/* The bin below a coordinate clamped to [0, nbins - 1] and the share of
 * the bin after it (spread's 1 - t and t; f - b is exact). */
static inline int bin_below(float f, int nbins, float *t)
{
    const int b = f >= nbins - 1 ? nbins - 2 : (int)f;
    *t = f - (float)b;
    return b;
}

static inline float clamp_coordinate(float f, int nbins)
{
    f = f > 0 ? f : 0.0f; /* NaN too */
    return f < nbins - 1 ? f : nbins - 1.0f;
}

void mim__sc_coords(const double *p, mim__sc_coords_t *c)
{
    memset(c, 0, sizeof *c);
    for (int j = 0; j < N; j++) c->x[j] = p[3 * j], c->y[j] = p[3 * j + 1], c->z[j] = p[3 * j + 2];
}

/* 1 / sqrt(1 + s) for s in [0, 1]: a polynomial fitted there (within
 * 3.9e-7 in floats), by Estrin's scheme as atan01. */
static inline float inv_hypot01(float s)
{
    static const float c[] = {0.99999976f, -0.49996418f, 0.37416843f, -0.30500212f,
                              0.23893045f, -0.15321627f, 0.065147132f, -0.012956658f};
    const float s2 = s * s, s4 = s2 * s2;
    return ((c[0] + c[1] * s) + (c[2] + c[3] * s) * s2) + ((c[4] + c[5] * s) + (c[6] + c[7] * s) * s2) * s4;
}

/* One lane of a row: j seen from i, j - i = (dx, dy, dz). Its elevation
 * bin coordinate, clamped as binning clamps it: |el| = atan(u) for
 * u = |dy| / h (h = |(dx, dz)|) at most 1, else pi/2 - atan(1 / u), by
 * atan01; the elevation's cosine, 1 / sqrt(1 + u^2) or u / sqrt(1 + u^2)
 * past 1; and its azimuth bin coordinate (bound_azimuth). One square root
 * and two divisions, both branches made and one kept, so that the loop
 * vectorises. MIM__BOUND_EL_COORD_ERR bounds how far the elevation
 * coordinate lies from libm's asin, MIM__BOUND_COS_ERR the cosine from
 * libm's (test_bound_elevation). */
static inline void lane_angles(float dx, float dy, float dz, float *fe, float *fa, float *cosel)
{
    const float h = sqrtf(dx * dx + dz * dz), ady = dy < 0 ? -dy : dy;
    const int steep = ady > h;
    const float hi = steep ? ady : h, lo = steep ? h : ady;
    const float u = hi > 0 ? lo / hi : 0.0f; /* 0 / 0 (j at i): el 0 */
    const float at = atan01(u);
    float el = steep ? (float)(M_PI / 2) - at : at;
    el = dy < 0 ? -el : el;
    /* elevation_coordinate's, the division by pi made a product */
    *fe = clamp_coordinate(el * (float)(SC_EL / M_PI) + (SC_EL - 1) / 2.0f, SC_EL);
    *cosel = (steep ? u : 1.0f) * inv_hypot01(u * u);
    *fa = bound_azimuth(dx, dz);
}

/* Outside these a vector's largest coordinate (metres) is scaled in
 * double first: the squares of its floats would lose digits or
 * overflow. */
#define ROW_TINY 1e-12
#define ROW_HUGE 1e15

MIM__WIDE_CLONES static void make_row(const mim__sc_coords_t *c, const float *fr, int i, mim__sc_row_t *w)
{
    int rescale = 0;
    for (int j = 0; j < ROW; j++) {
        const float dx = (float)(c->x[j] - c->x[i]), dy = (float)(c->y[j] - c->y[i]), dz = (float)(c->z[j] - c->z[i]);
        const float ax = dx < 0 ? -dx : dx, ay = dy < 0 ? -dy : dy, az = dz < 0 ? -dz : dz;
        const float m = ax > ay ? (ax > az ? ax : az) : (ay > az ? ay : az);
        /* a joint on another (m 0) too: the second pass leaves it as it is */
        rescale |= j != i && j < N && !(m >= (float)ROW_TINY && m <= (float)ROW_HUGE);
        lane_angles(dx, dy, dz, &w->fe[j], &w->fa[j], &w->cosel[j]);
    }
    for (int j = 0; rescale && j < ROW; j++) {
        const double x = c->x[j] - c->x[i], y = c->y[j] - c->y[i], z = c->z[j] - c->z[i];
        const double m = fmax(fabs(x), fmax(fabs(y), fabs(z)));
        if (!(m > 0 && !(m >= ROW_TINY && m <= ROW_HUGE))) continue;
        lane_angles((float)(x / m), (float)(y / m), (float)(z / m), &w->fe[j], &w->fa[j], &w->cosel[j]);
    }
    /* the radial coordinates: pair (i, j) of the 561 for j > i (in a run),
     * (j, i) for j < i; none for j = i and the padding (-2 is in no bin) */
    for (int j = 0; j < i; j++) w->fr[j] = fr[mim__pair_index(j, i)];
    w->fr[i] = -2.0f;
    if (i + 1 < N) memcpy(w->fr + i + 1, fr + mim__pair_index(i, i + 1), (size_t)(N - 1 - i) * sizeof *fr);
    for (int j = N; j < ROW; j++) w->fr[j] = -2.0f;
}

void mim__sc_row(const mim__sc_coords_t *c, const float *fr, int i, mim__sc_row_t *w) { make_row(c, fr, i, w); }

typedef mim__v8f v8f;
typedef mim__v8i v8i;

/* spread's histogram, a pair at a time: each adds its azimuth profile (8
 * floats, one vector: cos el (1 - ta, ta) at a0, a0 + 1 as the hats
 * max(0, 1 - |fa - a|) taken circularly, plus (1 - cos el) / 8 at all)
 * times its radial and elevation shares to its 4 (radial, elevation)
 * rows of 8 azimuths (WORK's layout). What a pair adds is made first for
 * the row's lanes side by side (j = i and the padding, in no radial bin,
 * add 0); even and odd pairs add to two histograms summed at the end, so
 * that a row's additions need not wait on each other. */
MIM__VECTOR_CLONES static void row_histogram(const mim__sc_row_t *w, float h[MIM_SC_BINS])
{
    float k[4][ROW];
    int32_t at[ROW];
    for (int j = 0; j < ROW; j++) {
        /* bin_below's bins and shares */
        const int counted = w->fr[j] >= 0;
        const float fr = counted ? w->fr[j] : 0.0f, fe = w->fe[j], wt = counted ? weight : 0.0f;
        const int r0 = fr >= SC_R - 1 ? SC_R - 2 : (int)fr, e0 = fe >= SC_EL - 1 ? SC_EL - 2 : (int)fe;
        const float tr = fr - (float)r0, te = fe - (float)e0;
        k[0][j] = wt * (1 - tr) * (1 - te), k[1][j] = wt * (1 - tr) * te;
        k[2][j] = wt * tr * (1 - te), k[3][j] = wt * tr * te;
        at[j] = r0 * SC_EL + e0;
    }
    v8f acc[2][SC_R * SC_EL];
    /* zeroed a vector at a time (memset's string store costs more here) */
#pragma GCC unroll 20
    for (int b = 0; b < SC_R * SC_EL; b++) acc[0][b] = acc[1][b] = (v8f){0};
    const v8f az = {0, 1, 2, 3, 4, 5, 6, 7};
    for (int j = 0; j < N; j++) {
        const float c = w->cosel[j];
        const v8f d = (v8f)((v8i)(w->fa[j] - az) & 0x7fffffff), wrap = (float)SC_AZ - d;
        const v8i nearer = d < wrap;
        const v8f hat = 1.0f - (v8f)((nearer & (v8i)d) | (~nearer & (v8i)wrap));
        const v8f prof = c * (v8f)((hat > (v8f){0}) & (v8i)hat) + (1 - c) / SC_AZ;
        v8f *row = acc[j & 1] + at[j];
        row[0] += k[0][j] * prof, row[1] += k[1][j] * prof;
        row[SC_EL] += k[2][j] * prof, row[SC_EL + 1] += k[3][j] * prof;
    }
    for (int b = 0; b < SC_R * SC_EL; b++) {
        const v8f sum = acc[0][b] + acc[1][b];
        memcpy(h + b * SC_AZ, &sum, sizeof sum);
    }
}

void mim__sc_row_histogram(const mim__sc_row_t *w, float sc[MIM_SC_BINS]) { row_histogram(w, sc); }

/* The bins' log range: 1/8 to 2 of the mean joint distance. */
static void radial_range(const double *r, double *r0, double *r1)
{
    double mean = 0;
    for (int k = 0; k < PAIRS; k++) mean += r[k];
    mean /= N * (N - 1) / 2.0;
    if (!(mean > 0)) mean = 1.0;
    *r0 = log(mean / 8.0), *r1 = log(mean * 2.0);
}

void mim__sc_pairs_finish(mim__sc_pairs_t *w)
{
    radial_range(w->r, &w->r0, &w->r1);
    for (int k = 0; k < PAIRS; k++) w->fr[k] = radial_coordinate(w->r[k], w->r0, w->r1), w->cos_el[k] = cos(w->el[k]);
}

void mim__sc_pairs_finish_lazy(mim__sc_pairs_t *w)
{
    radial_range(w->r, &w->r0, &w->r1);
    memset(w->made, 0, sizeof w->made);
}

void mim__sc_pairs_joint_ready(mim__sc_pairs_t *w, int i)
{
    for (int j = 0; j < N; j++) {
        const int k = i < j ? mim__pair_index(i, j) : j < i ? mim__pair_index(j, i) : -1;
        if (k < 0 || w->made[k]) continue;
        const double v[3] = {0, w->up[k], 0};
        w->made[k] = 1, w->el[k] = elevation(v, w->r[k]);
        w->fr[k] = radial_coordinate(w->r[k], w->r0, w->r1), w->cos_el[k] = cos(w->el[k]);
    }
}

void mim__sc_joint(const mim__sc_pairs_t *w, int i, float sc[MIM_SC_BINS])
{
    const double *p = w->p;
    float h[MIM_SC_BINS];
    memset(h, 0, sizeof h);
    for (int j = 0; j < N; j++) {
        if (j == i) continue;
        const int k = i < j ? mim__pair_index(i, j) : mim__pair_index(j, i);
        const double e = i < j ? w->el[k] : -w->el[k];
        const double fa = (atan2(p[3 * j + 2] - p[3 * i + 2], p[3 * j] - p[3 * i]) + M_PI) / (2 * M_PI) * SC_AZ - 0.5;
        spread(h, w->fr[k], fa, elevation_coordinate(e), w->cos_el[k], weight);
    }
    /* each bin got the same additions in the same order as in sc's layout */
    for (int r = 0; r < SC_R; r++)
        for (int a = 0; a < SC_AZ; a++)
            for (int e = 0; e < SC_EL; e++) sc[(r * SC_AZ + a) * SC_EL + e] = h[WORK(r, e, a)];
}

void mim__shape_contexts(const double *p, float sc[MIM_PAIR_JOINTS][MIM_SC_BINS])
{
    mim__sc_pairs_t w;
    mim__sc_pairs_begin(p, &w);
    mim__sc_pairs_finish(&w);
    for (int i = 0; i < N; i++) mim__sc_joint(&w, i, sc[i]);
}

double mim__shape_cost(const float *a, const float *b, int n, int bins)
{
    double total = 0;
    for (int i = 0; i < n * bins; i++) total += mim__chi_term(a[i], b[i]);
    return total / n;
}

/* ---- marginals ----
 * spread hands each count w to the bins as a product of shares, radial
 * (1 - tr, tr) times elevation (1 - te, te) times azimuth, the three
 * summing to 1 each (the azimuth's: cos el (1 - ta, ta) plus (1 - cos el)
 * over all). Summed over azimuth a count is w (1 - tr, tr) x (1 - te, te)
 * in (r, el); summed over elevation too, w (1 - tr, tr) in r. */


void mim__sc_histogram_marginals(const float sc[MIM_PAIR_JOINTS][MIM_SC_BINS], double *rad)
{
    memset(rad, 0, sizeof(double) * N * SC_R);
    for (int i = 0; i < N; i++)
        for (int r = 0; r < SC_R; r++)
            for (int a = 0; a < SC_AZ; a++)
                for (int e = 0; e < SC_EL; e++) rad[i * SC_R + r] += sc[i][(r * SC_AZ + a) * SC_EL + e];
}

void mim__pair_distances(const double *p, double *len)
{
    double v[3];
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) len[k] = pair_vector(p, i, j, v);
}

void mim__sc_pair_radii(const double *p, float *fr)
{
    double r[PAIRS], r0, r1;
    mim__pair_distances(p, r);
    radial_range(r, &r0, &r1);
    for (int k = 0; k < PAIRS; k++) fr[k] = clamp_coordinate((float)radial_coordinate(r[k], r0, r1), SC_R);
}

void mim__sc_radial(const float *fr, double *rad)
{
    memset(rad, 0, sizeof(double) * N * SC_R);
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) {
            float t;
            const int r = bin_below(fr[k], SC_R, &t);
            const double tr = t;
            rad[i * SC_R + r] += weight * (1 - tr), rad[i * SC_R + r + 1] += weight * tr;
            rad[j * SC_R + r] += weight * (1 - tr), rad[j * SC_R + r + 1] += weight * tr;
        }
}
