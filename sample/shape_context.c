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
    w->p = p;
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) {
            double v[3];
            w->r[k] = pair_vector(p, i, j, v), w->up[k] = v[1], w->has_share[k] = 0;
        }
}

/* The bins a coordinate f is shared between (b, b + 1) and the upper's
 * share: spread's (1 - t, t), the end bins taking all beyond. */
static int share(double f, int nbins, double *t)
{
    f = f > 0 ? (f < nbins - 1 ? f : nbins - 1) : 0;
    int b = (int)f;
    b = b < nbins - 2 ? b : nbins - 2;
    *t = f - b;
    return b;
}

/* asin to within MIM__BOUND_ELEVATION_ERR (2.3e-9 measured over [-1, 1]),
 * in a few multiplications where libm's asin takes a fifth of the second
 * bound's time: the Taylor series to x^21 on [0, 1/2], and above it
 * asin x = pi/2 - 2 asin sqrt((1 - x) / 2). */
static double bound_asin(double x)
{
    static const double c[] = {1.0,          1.0 / 6,           3.0 / 40,         5.0 / 112,
                               35.0 / 1152,  63.0 / 2816,       231.0 / 13312,    143.0 / 10240,
                               6435.0 / 557056, 12155.0 / 1245184, 46189.0 / 5505024};
    const double a = fabs(x);
    const int far = a > 0.5;
    const double z = far ? sqrt((1 - a) / 2) : a, z2 = z * z;
    /* Estrin's scheme: the terms' products in parallel, not one long chain */
    const double t2 = z2 * z2, t4 = t2 * t2, t8 = t4 * t4;
    const double q03 = (c[0] + c[1] * z2) + (c[2] + c[3] * z2) * t2, q47 = (c[4] + c[5] * z2) + (c[6] + c[7] * z2) * t2;
    const double q8 = (c[8] + c[9] * z2) + c[10] * t2, poly = (q03 + q47 * t4) + q8 * t8;
    const double r = far ? M_PI / 2 - 2 * z * poly : z * poly;
    return x < 0 ? -r : r;
}

double mim__bound_elevation(double up, double r) { return r > 0 ? bound_asin(up / r) : 0.0; }

/* Pair k's bins' shares for the second bound, made once for both its
 * joints: the radial from fr (the pairs' radial bin coordinates), the
 * elevation's from mim__bound_elevation (the bound allows for its error) */
static void lazy_pair(mim__sc_pairs_t *w, const float *fr, int k)
{
    if (w->has_share[k]) return;
    w->has_share[k] = 1;
    w->rbin[k] = (int8_t)share(fr[k], SC_R, &w->rshare[k]);
    w->ebin[k] = (int8_t)share(elevation_coordinate(mim__bound_elevation(w->up[k], w->r[k])), SC_EL, &w->eshare[k]);
}

void mim__sc_pairs_elevations(mim__sc_pairs_t *w)
{
    for (int k = 0; k < PAIRS; k++) {
        const double v[3] = {0, w->up[k], 0};
        w->el[k] = elevation(v, w->r[k]);
    }
}

/* The pairs' radial bin coordinates from their distances; the bins' log
 * range: 1/8 to 2 of the mean joint distance. */
static void radial_coordinates(const double *r, double *fr)
{
    double mean = 0;
    for (int k = 0; k < PAIRS; k++) mean += r[k];
    mean /= N * (N - 1) / 2.0;
    if (!(mean > 0)) mean = 1.0;
    const double r0 = log(mean / 8.0), r1 = log(mean * 2.0);
    for (int k = 0; k < PAIRS; k++) fr[k] = radial_coordinate(r[k], r0, r1);
}

void mim__sc_pairs_finish(mim__sc_pairs_t *w)
{
    radial_coordinates(w->r, w->fr);
    for (int k = 0; k < PAIRS; k++) w->cos_el[k] = cos(w->el[k]);
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
    double r[PAIRS], f[PAIRS];
    mim__pair_distances(p, r);
    radial_coordinates(r, f);
    for (int k = 0; k < PAIRS; k++) fr[k] = (float)f[k];
}

void mim__sc_radial(const float *fr, double *rad)
{
    memset(rad, 0, sizeof(double) * N * SC_R);
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) {
            double tr;
            const int r = share(fr[k], SC_R, &tr);
            rad[i * SC_R + r] += weight * (1 - tr), rad[i * SC_R + r + 1] += weight * tr;
            rad[j * SC_R + r] += weight * (1 - tr), rad[j * SC_R + r + 1] += weight * tr;
        }
}

void mim__sc_joint_radial_elevation(mim__sc_pairs_t *w, const float *fr, int i, double *rel_i)
{
    memset(rel_i, 0, sizeof(double) * SC_R * SC_EL);
    for (int j = 0; j < N; j++) {
        if (j == i) continue;
        const int k = i < j ? mim__pair_index(i, j) : mim__pair_index(j, i);
        lazy_pair(w, fr, k);
        const double tr = w->rshare[k], te = w->eshare[k];
        const int r = w->rbin[k], e = w->ebin[k];
        const double m0 = weight * (1 - tr), m1 = weight * tr;
        double *h = rel_i + r * SC_EL;
        if (i < j) /* i the pair's first joint */
            h[e] += m0 * (1 - te), h[e + 1] += m0 * te, h[SC_EL + e] += m1 * (1 - te), h[SC_EL + e + 1] += m1 * te;
        else /* i the pair's second joint: it sees the first at the opposite elevation, bins mirrored */
            h[SC_EL - 1 - e] += m0 * (1 - te), h[SC_EL - 2 - e] += m0 * te, h[2 * SC_EL - 1 - e] += m1 * (1 - te),
                h[2 * SC_EL - 2 - e] += m1 * te;
    }
}

