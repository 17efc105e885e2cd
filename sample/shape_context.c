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

/* The log-radius range of a pair's bins: 1/8 to 2 of its mean joint distance. */
static void log_range(const double *p, double *r0, double *r1)
{
    double mean = 0;
    for (int i = 0; i < N; i++)
        for (int j = i + 1; j < N; j++) {
            double d2 = 0;
            for (int c = 0; c < 3; c++) d2 += (p[3 * i + c] - p[3 * j + c]) * (p[3 * i + c] - p[3 * j + c]);
            mean += sqrt(d2);
        }
    mean /= N * (N - 1) / 2.0;
    if (!(mean > 0)) mean = 1.0;
    *r0 = log(mean / 8.0), *r1 = log(mean * 2.0);
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

#define PAIRS (N * (N - 1) / 2)
/* The pair (i, j), i < j, in row-by-row order. */
static int pair_index(int i, int j) { return i * (2 * N - i - 1) / 2 + (j - i - 1); }

void mim__shape_contexts(const double *p, float sc[MIM_PAIR_JOINTS][MIM_SC_BINS])
{
    double r0, r1;
    log_range(p, &r0, &r1);
    /* j seen from i and i from j: one distance (v negated exactly), and
     * opposite elevations of one cosine (asin odd, cos even) */
    double fr[PAIRS], el[PAIRS], cos_el[PAIRS];
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) {
            double v[3], r = pair_vector(p, i, j, v);
            fr[k] = radial_coordinate(r, r0, r1), el[k] = elevation(v, r), cos_el[k] = cos(el[k]);
        }
    /* each bin gets the same additions in the same order in either layout */
    float h[MIM_SC_BINS];
    for (int i = 0; i < N; i++) {
        memset(h, 0, sizeof h);
        for (int j = 0; j < N; j++) {
            if (j == i) continue;
            const int k = i < j ? pair_index(i, j) : pair_index(j, i);
            const double e = i < j ? el[k] : -el[k];
            const double fa = (atan2(p[3 * j + 2] - p[3 * i + 2], p[3 * j] - p[3 * i]) + M_PI) / (2 * M_PI) * SC_AZ - 0.5;
            spread(h, fr[k], fa, elevation_coordinate(e), cos_el[k], weight);
        }
        for (int r = 0; r < SC_R; r++)
            for (int a = 0; a < SC_AZ; a++)
                for (int e = 0; e < SC_EL; e++) sc[i][(r * SC_AZ + a) * SC_EL + e] = h[WORK(r, e, a)];
    }
}

double mim__shape_cost(const float *a, const float *b, int n, int bins)
{
    double total = 0;
    for (int i = 0; i < n * bins; i++) {
        double x = a[i], y = b[i];
        if (x + y > 0) total += 0.5 * (x - y) * (x - y) / (x + y);
    }
    return total / n;
}

/* ---- marginals ----
 * spread hands each count w to the bins as a product of shares, radial
 * (1 - tr, tr) times elevation (1 - te, te) times azimuth, the three
 * summing to 1 each (the azimuth's: cos el (1 - ta, ta) plus (1 - cos el)
 * over all). Summed over azimuth a count is w (1 - tr, tr) x (1 - te, te)
 * in (r, el); summed over elevation too, w (1 - tr, tr) in r. */

/* The two bins a coordinate f is shared between and f's share t of the
 * upper; f is first kept within [-1, nbins] (beyond, both bins are the
 * end one) and floored without a call. */
static void split(double f, int nbins, int b[2], double *t)
{
    f = !(f > -1) ? -1 : f > nbins ? nbins : f;
    int f0 = (int)f;
    f0 -= f < f0;
    *t = f - f0;
    b[0] = f0 < 0 ? 0 : f0 >= nbins ? nbins - 1 : f0;
    b[1] = f0 + 1 >= nbins ? nbins - 1 : f0 + 1;
}

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

void mim__sc_pair_radii(const double *p, float *fr)
{
    double r0, r1, v[3];
    log_range(p, &r0, &r1);
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) fr[k] = (float)radial_coordinate(pair_vector(p, i, j, v), r0, r1);
}

void mim__sc_radial(const float *fr, double *rad)
{
    memset(rad, 0, sizeof(double) * N * SC_R);
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) {
            int rb[2];
            double tr;
            split(fr[k], SC_R, rb, &tr);
            for (int d = 0; d < 2; d++) {
                const double m = weight * (d ? tr : 1 - tr);
                rad[i * SC_R + rb[d]] += m, rad[j * SC_R + rb[d]] += m;
            }
        }
}

void mim__sc_radial_elevation(const double *p, const float *fr, double *rel)
{
    memset(rel, 0, sizeof(double) * N * SC_R * SC_EL);
    for (int i = 0, k = 0; i < N; i++)
        for (int j = i + 1; j < N; j++, k++) {
            double v[3], r = pair_vector(p, i, j, v), el = elevation(v, r), tr, te[2];
            int rb[2], eb[2][2];
            split(fr[k], SC_R, rb, &tr);
            split(elevation_coordinate(el), SC_EL, eb[0], &te[0]);
            split(elevation_coordinate(-el), SC_EL, eb[1], &te[1]);
            for (int dr = 0; dr < 2; dr++)
                for (int de = 0; de < 2; de++) {
                    const double m = weight * (dr ? tr : 1 - tr);
                    rel[(i * SC_R + rb[dr]) * SC_EL + eb[0][de]] += m * (de ? te[0] : 1 - te[0]);
                    rel[(j * SC_R + rb[dr]) * SC_EL + eb[1][de]] += m * (de ? te[1] : 1 - te[1]);
                }
        }
}
