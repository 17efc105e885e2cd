/* A 3D pose-pair consistent with one 2D annotation (Taylor 2000, per
 * person): the seeds the chains start from, so that they start near the
 * poses the annotations show rather than at the prior's frames (seed 002
 * Section 5 starts from annotations lifted to 3D). Choices:
 * - Taylor's construction in perspective: each joint lies on its pixel's
 *   ray, at its bone's known length from its parent: one of two points
 *   (the sign of the bone's depth), the ray's nearest point when it passes
 *   too far. The camera: f = 0.75 x the image width and the principal
 *   point at the image's centre, as view_estimate.c assumes. A person's
 *   pelvis at depth f / s, s Taylor's scaled-orthographic scale (pixels a
 *   metre: the largest 2D-to-3D length ratio over the bones of at least
 *   MIN_BONE metres, whose 2D length the annotation's noise does not
 *   decide); the two people's depths, each from its own scale, place them.
 * - The lengths: each bone's mean over the prior's frames and people; or,
 *   for the annotations of a take, those the take's annotations show
 *   (mim_pairs_bone_lengths_2d), so that a take of another skeleton lifts
 *   as its own bones go.
 * - The depth signs, one a bone, are what 2D cannot tell: chosen by eq.
 *   2's joint limits (the excess angle; penetration through ODE costs far
 *   more and seldom decides a sign), greedily bone by bone from random
 *   signs, from STARTS random starts, the best kept; the chain's density
 *   (penetration included) then judges the seed.
 * - Camera axes (x right, y down, z forward) become mimic's
 *   (y up) by a half turn about x; the density does not change when the
 *   pair turns (chain.c). */
#include "mim_sample_mcmc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MIN_BONE 0.15 /* metres */
#define STARTS 2
#define PASSES 2
#define PJ MIM_PAIR_PERSON_JOINTS

void mim_pairs_bone_lengths(const double *pairs, uint32_t n, double len[MIM_PAIR_PERSON_JOINTS])
{
    for (int k = 0; k < PJ; k++) {
        double s = 0;
        int parent = mim_pairs_parent[k];
        for (uint32_t i = 0; i < n && parent >= 0; i++)
            for (int p = 0; p < 2; p++) {
                const double *j = pairs + (size_t)i * 3 * MIM_PAIR_JOINTS + 3 * PJ * p;
                double d2 = 0;
                for (int c = 0; c < 3; c++) d2 += (j[3 * k + c] - j[3 * parent + c]) * (j[3 * k + c] - j[3 * parent + c]);
                s += sqrt(d2);
            }
        len[k] = n && parent >= 0 ? s / (2.0 * n) : 0.0;
    }
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Taylor's scale of one person's 2D joints q (34 x 2 halves: 17 [u, v])
 * for bones len: the largest 2D length over 3D length among the bones of
 * at least MIN_BONE; 0 when none shows. */
static double taylor_scale(const double *q, const double len[PJ])
{
    double s = 0;
    for (int k = 0; k < PJ; k++) {
        const int parent = mim_pairs_parent[k];
        if (parent < 0 || !(len[k] >= MIN_BONE)) continue;
        const double r = hypot(q[2 * k] - q[2 * parent], q[2 * k + 1] - q[2 * parent + 1]) / len[k];
        if (isfinite(r)) s = fmax(s, r);
    }
    return s;
}

#define LENGTH_ITERATIONS 5

void mim_pairs_bone_lengths_2d(const mim_pairs_annotations_t *a, uint32_t take,
                               const double len_prior[MIM_PAIR_PERSON_JOINTS], double out[MIM_PAIR_PERSON_JOINTS])
{
    memcpy(out, len_prior, PJ * sizeof *out);
    uint32_t m = 0;
    for (uint32_t i = 0; i < a->n; i++) m += a->take[i] == take;
    if (m < MIM_PAIRS_LENGTH_MIN_ANNOTATIONS) return;
    double *scale = malloc(2 * (size_t)m * sizeof *scale), *ratio = malloc(2 * (size_t)m * sizeof *ratio);
    uint32_t *mine = malloc((size_t)m * sizeof *mine); /* the take's annotations */
    if (!scale || !ratio || !mine) goto done;           /* out of memory: the prior's, as before */
    m = 0;
    for (uint32_t i = 0; i < a->n; i++)
        if (a->take[i] == take) mine[m++] = i;
    static const char *const legs[4] = {"l_knee", "r_knee", "l_ankle", "r_ankle"};
    for (int it = 0; it < LENGTH_ITERATIONS; it++) {
        for (uint32_t t = 0; t < 2 * m; t++)
            scale[t] = taylor_scale(a->points + (size_t)2 * MIM_PAIR_JOINTS * mine[t / 2] + 2 * PJ * (t % 2), out);
        double next[PJ];
        for (int k = 0; k < PJ; k++) {
            const int parent = mim_pairs_parent[k];
            uint32_t n = 0;
            for (uint32_t t = 0; t < 2 * m && parent >= 0; t++) {
                const double *q = a->points + (size_t)2 * MIM_PAIR_JOINTS * mine[t / 2] + 2 * PJ * (t % 2);
                const double r = hypot(q[2 * k] - q[2 * parent], q[2 * k + 1] - q[2 * parent + 1]) / scale[t];
                if (scale[t] > 0 && isfinite(r)) ratio[n++] = r;
            }
            if (parent < 0 || !n) {
                next[k] = parent < 0 ? 0 : out[k];
                continue;
            }
            qsort(ratio, n, sizeof *ratio, cmp_double);
            next[k] = ratio[(uint32_t)(MIM_PAIRS_LENGTH_QUANTILE * (n - 1))];
        }
        double have = 0, want = 0; /* the legs keep the prior's length: the metres */
        for (int l = 0; l < 4; l++) {
            const int k = mim_sample_joint_index(legs[l]);
            have += next[k], want += len_prior[k];
        }
        if (!(have > 0) || !(want > 0)) break;
        for (int k = 0; k < PJ; k++) out[k] = next[k] * want / have;
    }
done:
    free(scale), free(ratio), free(mine);
}

/* Each joint on its pixel's ray at its bone's length from its parent
 * (camera frame: x right, y down, z forward; rays from ray[], roots at
 * depth zr), the nearer or the farther of the two such points as sign
 * says (the nearest point of the ray, the bone then stretched to its
 * length, when the ray passes farther than that); then mimic's frame. */
static void place(const double ray[2][PJ][3], const double zr[2], const double len[PJ], const int sign[2][PJ], double *joints)
{
    for (int p = 0; p < 2; p++) {
        double q[PJ][3];
        int done[PJ] = {0};
        for (int left = PJ; left > 0;)
            for (int k = 0; k < PJ; k++) {
                int parent = mim_pairs_parent[k];
                if (done[k] || (parent >= 0 && !done[parent])) continue;
                done[k] = 1, left--;
                const double *r = ray[p][k];
                if (parent < 0) {
                    for (int c = 0; c < 3; c++) q[k][c] = zr[p] * r[c];
                    continue;
                }
                const double *P = q[parent];
                double rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2], rp = r[0] * P[0] + r[1] * P[1] + r[2] * P[2];
                double pp = P[0] * P[0] + P[1] * P[1] + P[2] * P[2], disc = rp * rp - rr * (pp - len[k] * len[k]);
                double t = (rp + (disc > 0 ? sign[p][k] * sqrt(disc) : 0.0)) / rr, d[3], dl = 0;
                for (int c = 0; c < 3; c++) d[c] = t * r[c] - P[c], dl += d[c] * d[c];
                dl = sqrt(dl);
                for (int c = 0; c < 3; c++) q[k][c] = P[c] + (disc > 0 || !(dl > 0) ? d[c] : d[c] * len[k] / dl);
            }
        for (int k = 0; k < PJ; k++) {
            double *o = joints + 3 * (PJ * p + k);
            o[0] = q[k][0], o[1] = -q[k][1], o[2] = -q[k][2];
        }
    }
}

/* eq. 2's joint limits as a score (penetration, through ODE, costs far
 * more and rarely decides a sign): the excess angle, and the invalid
 * checks beyond those allowed first */
static double score(const mim_pairs_validity_t *v, uint32_t max_invalid, const double *joints)
{
    uint32_t invalid;
    double excess = mim_pairs_validity_excess(v, joints, &invalid);
    return -1e9 * (invalid > max_invalid ? invalid - max_invalid : 0) - excess;
}

int mim_pairs_lift(const mim_pairs_target_t *t, const double *uv, uint32_t width, uint32_t height,
                   const double len[MIM_PAIR_PERSON_JOINTS], mim_rng_t *rng, double *out)
{
    const double f = 0.75 * width;
    double ray[2][PJ][3], zr[2], has[2][PJ];
    for (int p = 0; p < 2; p++) {
        const double *q = uv + 2 * PJ * p;
        for (int k = 0; k < PJ; k++)
            ray[p][k][0] = (q[2 * k] - 0.5 * width) / f, ray[p][k][1] = (q[2 * k + 1] - 0.5 * height) / f, ray[p][k][2] = 1;
        const double s = taylor_scale(q, len);
        if (!(s > 0) || !isfinite(s)) return MIM_EINVAL;
        zr[p] = f / s; /* the pelvis's depth: Taylor's scale, s = f / depth */
        for (int k = 0; k < PJ; k++) has[p][k] = mim_pairs_parent[k] >= 0 && len[k] > 0;
    }
    double best = -INFINITY, joints[3 * MIM_PAIR_JOINTS];
    int sign[2][PJ];
    for (int start = 0; start < STARTS; start++) {
        for (int p = 0; p < 2; p++)
            for (int k = 0; k < PJ; k++) sign[p][k] = mim_rng_unit(rng) < 0.5 ? -1 : 1;
        double cur = -INFINITY;
        /* b = -1: the signs as drawn; then each bone's flipped, kept when the score rises */
        for (int pass = 0; pass < PASSES; pass++)
            for (int b = pass ? 0 : -1; b < 2 * PJ; b++) {
                int p = b < 0 ? 0 : b / PJ, k = b < 0 ? 0 : b % PJ;
                if (b >= 0 && !has[p][k]) continue;
                if (b >= 0) sign[p][k] = -sign[p][k];
                place(ray, zr, len, sign, joints);
                double sc = score(t->validity, t->opt.max_invalid, joints);
                if (sc > cur) {
                    cur = sc;
                    if (sc > best) best = sc, memcpy(out, joints, sizeof joints);
                } else if (b >= 0) {
                    sign[p][k] = -sign[p][k];
                }
            }
    }
    return best > -1e9 ? 0 : MIM_EINVAL; /* no signs within the invalid checks allowed */
}
