/* The likelihood of seed 002 (eqs. 6 and 9): a 3D pose-pair seen along
 * the chain's views, each projection compared with the annotations of
 * similar views (mim_sample_mcmc.h's choices), the best match per view
 * through eq. 9's kernel, averaged over the views (the Monte Carlo sum of
 * eq. 6), in logs. */
#include "internal.h"
#include "mim_sample_mcmc.h"

#include <math.h>

#define SHORTLIST 8 /* annotations measured with the density's distance per view */

typedef struct near {
    double mse;
    uint32_t i;
    double c, s;
} near_t;

/* Keeps the k smallest by mse in list (sorted, insertion). */
static void keep(near_t *list, int *len, int k, near_t x)
{
    if (*len == k && x.mse >= list[k - 1].mse) return;
    int j = *len < k ? (*len)++ : k - 1;
    while (j > 0 && list[j - 1].mse > x.mse) list[j] = list[j - 1], j--;
    list[j] = x;
}

/* The best match of one view's projection q (normalised, its
 * triangulation tq) among the annotations near the local view ldir:
 * distance in the density's measure, *which the annotation. */
static double best_match(const mim_pairs_evidence_t *e, mim_pairs_density_t density, const double *q, const mim_ic_t *tq,
                         const double ldir[3], double cone_angle, uint32_t *which)
{
    const double cone = cone_angle >= M_PI ? -2.0 : cos(cone_angle);
    uint32_t n = mim_pairs_evidence_count(e);
    near_t list[SHORTLIST], views[SHORTLIST];
    int len = 0, vlen = 0, in_cone = 0, k = density == MIM_DENSITY_CARTESIAN ? 1 : SHORTLIST;
    for (uint32_t i = 0; i < n; i++) {
        const double *d = mim__evidence_dir(e, i);
        double dot = d[0] * ldir[0] + d[1] * ldir[1] + d[2] * ldir[2];
        near_t x = {0, i, 1, 0};
        if (dot < cone) {
            /* the nearest views outside, in case the cone holds too few */
            x.mse = -dot;
            keep(views, &vlen, SHORTLIST, x);
            continue;
        }
        in_cone++;
        x.mse = mim_pairs2d_align(mim__evidence_points(e, i), q, &x.c, &x.s);
        keep(list, &len, k, x);
    }
    for (int v = 0; in_cone + v < SHORTLIST && v < vlen; v++) {
        near_t x = views[v];
        x.mse = mim_pairs2d_align(mim__evidence_points(e, x.i), q, &x.c, &x.s);
        keep(list, &len, k, x);
    }
    double best = INFINITY;
    for (int c = 0; c < len; c++) {
        double d;
        if (density == MIM_DENSITY_CARTESIAN) {
            d = sqrt(list[c].mse);
        } else {
            double r[2 * MIM_PAIR_JOINTS];
            mim_pairs2d_rotate(q, list[c].c, list[c].s, r);
            if (density == MIM_DENSITY_SHAPE) {
                float sc[MIM_PAIR_JOINTS][MIM__SC2_BINS];
                mim__pairs2d_shape_contexts(r, sc);
                d = mim__shape_cost(mim__evidence_sc(e, list[c].i), &sc[0][0], MIM_PAIR_JOINTS, MIM__SC2_BINS);
            } else {
                /* eq. 8 between the annotation and M theta_v, each with its own
                 * triangulation (a rotation keeps the projection's) */
                d = mim_ic_distance(mim__evidence_points(e, list[c].i), mim__evidence_ic(e, list[c].i), r, tq,
                                    MIM_IC_DEFAULT_BETA);
            }
        }
        if (d < best) best = d, *which = list[c].i;
    }
    return best;
}

double mim_pairs_log_likelihood(const mim_pairs_evidence_t *e, mim_pairs_density_t density, double sigma_l,
                                double cone, const double *joints, const double *views, uint32_t m, uint32_t *nearest)
{
    double R[9];
    if (density == MIM_DENSITY_PRIOR || !m) return 0.0;
    if (mim_pairs_local_frame(joints, R)) return -INFINITY;
    double terms[MIM_PAIRS_MAX_VIEWS], top = -INFINITY;
    if (m > MIM_PAIRS_MAX_VIEWS) m = MIM_PAIRS_MAX_VIEWS;
    for (uint32_t v = 0; v < m; v++) {
        double dir[3], uv[2 * MIM_PAIR_JOINTS], q[2 * MIM_PAIR_JOINTS];
        double psi = views[2 * v], phi = views[2 * v + 1];
        double ldir[3] = {sin(phi) * cos(psi), cos(phi), sin(phi) * sin(psi)};
        uint32_t which = UINT32_MAX;
        mim_ic_t tq;
        mim_error_t err = {0};
        mim_pairs_view_direction(R, psi, phi, dir);
        mim_pairs2d_project(joints, dir, uv);
        terms[v] = -INFINITY;
        if (mim_pairs2d_normalise(uv, q) && (density != MIM_DENSITY_IC || !mim_ic_build(q, 2, &tq, &err))) {
            double d = best_match(e, density, q, &tq, ldir, cone, &which);
            terms[v] = -d / (2 * sigma_l * sigma_l); /* eq. 9 */
        }
        if (nearest) nearest[v] = which;
        if (terms[v] > top) top = terms[v];
    }
    if (top == -INFINITY) return -INFINITY;
    /* eq. 6: log of the mean of the views' likelihoods */
    double s = 0;
    for (uint32_t v = 0; v < m; v++) s += exp(terms[v] - top);
    return top + log(s / m);
}
