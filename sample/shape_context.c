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
#define WORK(r, e, a) (((r) * SC_EL + (e)) * SC_AZ + (a))
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

/* The azimuth coordinate of (x, z), as (atan2(z, x) + pi) / 2pi SC_AZ - 1/2
 * is, in floats (MIM__BOUND_AZ_COORD_ERR bounds how far): the angle from
 * the x or z axis, whichever is nearer, by atan's series to u^15 on
 * |u| <= tan(pi/8) (past it, pi/4 + atan((t - 1) / (t + 1))), then the
 * octant put back. Both branches made and one kept, so that loops over it
 * vectorise. */
static inline float bound_azimuth(float x, float z)
{
    static const float c[] = {1.0f, -1.0f / 3, 1.0f / 5, -1.0f / 7, 1.0f / 9, -1.0f / 11, 1.0f / 13, -1.0f / 15};
    const float ax = x < 0 ? -x : x, az = z < 0 ? -z : z;
    const int steep = az > ax;
    const float hi = steep ? az : ax, lo = steep ? ax : az;
    const float t = hi > 0 ? lo / hi : 0.0f; /* in [0, 1] */
    const int past = t > 0.41421356f;
    const float u = past ? (t - 1) / (t + 1) : t, u2 = u * u, u4 = u2 * u2, u8 = u4 * u4;
    const float poly = ((c[0] + c[1] * u2) + (c[2] + c[3] * u2) * u4) + ((c[4] + c[5] * u2) + (c[6] + c[7] * u2) * u4) * u8;
    float ang = (past ? (float)(M_PI / 4) : 0.0f) + u * poly; /* atan(lo / hi), in [0, pi/4] */
    ang = steep ? (float)(M_PI / 2) - ang : ang;                 /* the angle from +x in the quadrant */
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

/* One lane of a row: j's elevation bin coordinate seen from i, from
 * j - i = (dx, dy, dz), clamped as binning clamps it. |el| = atan(u) for
 * u = |dy| / h (h = |(dx, dz)|) at most 1, else pi/2 - atan(1 / u), atan
 * by a polynomial fitted on [0, 1] (within 1.3e-7 of atan there in
 * floats): one square root and one division, both branches made and one
 * kept, so that the loop vectorises. MIM__BOUND_EL_COORD_ERR bounds how
 * far the coordinate lies from libm's asin (test_bound_elevation). */
static inline float lane_elevation(float dx, float dy, float dz)
{
    static const float c[] = {0.99999934f,  -0.33329859f, 0.19946562f,  -0.13908616f,
                              0.096421652f, -0.055911936f, 0.021862714f, -0.0040545058f};
    const float h = sqrtf(dx * dx + dz * dz), ady = dy < 0 ? -dy : dy;
    const int steep = ady > h;
    const float hi = steep ? ady : h, lo = steep ? h : ady;
    const float u = hi > 0 ? lo / hi : 0.0f, s = u * u; /* 0 / 0 (j at i): el 0 */
    /* Estrin's scheme: the terms' products in parallel, not one long chain */
    const float s2 = s * s, s4 = s2 * s2;
    const float poly = ((c[0] + c[1] * s) + (c[2] + c[3] * s) * s2) + ((c[4] + c[5] * s) + (c[6] + c[7] * s) * s2) * s4;
    float el = steep ? (float)(M_PI / 2) - u * poly : u * poly;
    el = dy < 0 ? -el : el;
    /* elevation_coordinate's, the division by pi made a product */
    return clamp_coordinate(el * (float)(SC_EL / M_PI) + (SC_EL - 1) / 2.0f, SC_EL);
}

/* Outside these a vector's largest coordinate (metres) is scaled in
 * double first: the squares of its floats would lose digits or
 * overflow. */
#define ROW_TINY 1e-12
#define ROW_HUGE 1e15

MIM__VECTOR_CLONES static void make_row(const mim__sc_coords_t *c, const float *fr, int i, mim__sc_row_t *w)
{
    int rescale = 0;
    for (int j = 0; j < ROW; j++) {
        const float dx = (float)(c->x[j] - c->x[i]), dy = (float)(c->y[j] - c->y[i]), dz = (float)(c->z[j] - c->z[i]);
        const float ax = dx < 0 ? -dx : dx, ay = dy < 0 ? -dy : dy, az = dz < 0 ? -dz : dz;
        const float m = ax > ay ? (ax > az ? ax : az) : (ay > az ? ay : az);
        /* a joint on another (m 0) too: the second pass leaves it as it is */
        rescale |= j != i && j < N && !(m >= (float)ROW_TINY && m <= (float)ROW_HUGE);
        w->fe[j] = lane_elevation(dx, dy, dz);
        w->dx[j] = dx, w->dy[j] = dy, w->dz[j] = dz;
    }
    for (int j = 0; rescale && j < ROW; j++) {
        const double x = c->x[j] - c->x[i], y = c->y[j] - c->y[i], z = c->z[j] - c->z[i];
        const double m = fmax(fabs(x), fmax(fabs(y), fabs(z)));
        if (!(m > 0 && !(m >= ROW_TINY && m <= ROW_HUGE))) continue;
        const float dx = (float)(x / m), dy = (float)(y / m), dz = (float)(z / m);
        w->fe[j] = lane_elevation(dx, dy, dz);
        w->dx[j] = dx, w->dy[j] = dy, w->dz[j] = dz;
    }
    /* the radial coordinates: pair (i, j) of the 561 for j > i (in a run),
     * (j, i) for j < i; none for j = i and the padding (-2 is in no bin) */
    for (int j = 0; j < i; j++) w->fr[j] = fr[mim__pair_index(j, i)];
    w->fr[i] = -2.0f;
    if (i + 1 < N) memcpy(w->fr + i + 1, fr + mim__pair_index(i, i + 1), (size_t)(N - 1 - i) * sizeof *fr);
    for (int j = N; j < ROW; j++) w->fr[j] = -2.0f;
}

void mim__sc_row(const mim__sc_coords_t *c, const float *fr, int i, mim__sc_row_t *w) { make_row(c, fr, i, w); }

/* The row's histogram summed over azimuth: each count's radial shares
 * times its elevation shares (spread's, summed over azimuth), made as
 * the hat functions max(0, 1 - |f - bin|) of the clamped coordinates so
 * that the lanes go side by side with no branch. */
MIM__VECTOR_CLONES static void row_radial_elevation(const mim__sc_row_t *w, float rel[MIM__SC_REL])
{
    float acc[SC_R * SC_EL][LANES];
    memset(acc, 0, sizeof acc);
    for (int j = 0; j < ROW; j += LANES) {
        float hr[SC_R][LANES], he[SC_EL][LANES];
        for (int r = 0; r < SC_R; r++)
            for (int l = 0; l < LANES; l++) {
                const float d = w->fr[j + l] - (float)r, ad = d < 0 ? -d : d;
                hr[r][l] = ad < 1 ? 1 - ad : 0.0f;
            }
        for (int e = 0; e < SC_EL; e++)
            for (int l = 0; l < LANES; l++) {
                const float d = w->fe[j + l] - (float)e, ad = d < 0 ? -d : d;
                he[e][l] = ad < 1 ? 1 - ad : 0.0f;
            }
        for (int r = 0; r < SC_R; r++)
            for (int e = 0; e < SC_EL; e++)
                for (int l = 0; l < LANES; l++) acc[r * SC_EL + e][l] += hr[r][l] * he[e][l];
    }
    for (int b = 0; b < SC_R * SC_EL; b++) {
        const float *a = acc[b];
        rel[b] = weight * (((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7])));
    }
    for (int b = SC_R * SC_EL; b < MIM__SC_REL; b++) rel[b] = 0;
}

void mim__sc_row_radial_elevation(const mim__sc_row_t *w, float rel[MIM__SC_REL]) { row_radial_elevation(w, rel); }

MIM__VECTOR_CLONES static void row_histogram(const mim__sc_row_t *w, int i, float sc[MIM_SC_BINS])
{
    float fa[ROW], cosel[ROW];
    for (int j = 0; j < ROW; j++) {
        const float dx = w->dx[j], dy = w->dy[j], dz = w->dz[j], h2 = dx * dx + dz * dz, len = sqrtf(h2 + dy * dy);
        const float c = len > 0 ? sqrtf(h2) / len : 1.0f;
        fa[j] = bound_azimuth(dx, dz), cosel[j] = c < 1 ? c : 1.0f;
    }
    /* spread's, but each count's share for all azimuths alike summed apart
     * and added to the 8 at the end: fewer additions reach a bin */
    float h[MIM_SC_BINS], all[SC_R * SC_EL];
    memset(h, 0, sizeof h), memset(all, 0, sizeof all);
    for (int j = 0; j < N; j++) {
        if (j == i) continue;
        float tr, te;
        const int r0 = bin_below(w->fr[j], SC_R, &tr), e0 = bin_below(w->fe[j], SC_EL, &te);
        const float c = cosel[j], f = fa[j];
        const int a0 = (int)floorf(f);
        const float ta = f - (float)a0;
        const int a1 = (a0 + 1 + SC_AZ) % SC_AZ, a0w = (a0 + SC_AZ) % SC_AZ;
        for (int dr = 0; dr < 2; dr++)
            for (int de = 0; de < 2; de++) {
                const float k2 = weight * (dr ? tr : 1 - tr) * (de ? te : 1 - te);
                float *row = h + WORK(r0 + dr, e0 + de, 0);
                row[a0w] += k2 * c * (1 - ta), row[a1] += k2 * c * ta;
                all[(r0 + dr) * SC_EL + e0 + de] += k2 * (1 - c);
            }
    }
    for (int r = 0; r < SC_R; r++)
        for (int a = 0; a < SC_AZ; a++)
            for (int e = 0; e < SC_EL; e++) sc[(r * SC_AZ + a) * SC_EL + e] = h[WORK(r, e, a)] + all[r * SC_EL + e] / SC_AZ;
}

void mim__sc_row_histogram(const mim__sc_row_t *w, int i, float sc[MIM_SC_BINS]) { row_histogram(w, i, sc); }

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


void mim__sc_histogram_marginals(const float sc[MIM_PAIR_JOINTS][MIM_SC_BINS], double *rad, double *rel)
{
    if (rad) memset(rad, 0, sizeof(double) * N * SC_R);
    if (rel) memset(rel, 0, sizeof(double) * N * SC_R * SC_EL);
    for (int i = 0; i < N; i++)
        for (int r = 0; r < SC_R; r++)
            for (int a = 0; a < SC_AZ; a++)
                for (int e = 0; e < SC_EL; e++) {
                    double x = sc[i][(r * SC_AZ + a) * SC_EL + e];
                    if (rad) rad[i * SC_R + r] += x;
                    if (rel) rel[(i * SC_R + r) * SC_EL + e] += x;
                }
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
