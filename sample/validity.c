/* Joint-angle validity of seed 002's physical prior (eq. 2): isvalid(theta)
 * and |theta - theta-bar|, from a model learned on the prior motions.
 *
 * The paper applies Akhter & Black's pose-conditioned joint-angle limits.
 * mimic learns the limits from the prior motions without a parametric
 * form: 12 checks per person, each a bone direction in a frame made from
 * positions only (so that motion capture of any skeleton gives them), and a
 * check holds within MIM_PAIRS_VALID_TOL of some example seen. Forearms and
 * shins are conditioned on their upper bone, as Akhter & Black condition
 * the lower limb: the example must match both. Distances are chords of the
 * unit sphere (2 sin(angle / 2), cheap and close to the angle), turned
 * back into an angle for the excess. The mirror image of every example is
 * added (the left arm's examples teach the right arm), and examples closer
 * than THIN to one kept are dropped, which bounds the scan per check. */
#include "mim_sample_mcmc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { HEAD, CHEST, PELVIS, LSH, RSH, LEL, REL, LWR, RWR, LHIP, RHIP, LKN, RKN, LAN, RAN, SPINE, NECK };
#define THIN 0.03 /* chord: examples closer than about 1.7 degrees are one */

typedef struct check_set {
    int conditioned; /* examples of 6 floats (upper, lower) instead of 3 */
    uint32_t n, cap;
    float *ex;
} check_set_t;

struct mim_pairs_validity {
    check_set_t set[MIM_PAIRS_CHECKS];
};

typedef struct frame {
    mim_vec3 x, y, z;
} frame_t;

static mim_vec3 joint(const double *j, int k) { return mim_v3(j[3 * k], j[3 * k + 1], j[3 * k + 2]); }

/* A frame from an x direction and an up hint (made orthogonal to x); 0
 * when either is degenerate. */
static int frame_from(mim_vec3 x, mim_vec3 up, frame_t *f)
{
    if (mim_v3_norm(x) < 1e-6) return 0;
    x = mim_v3_normalize(x);
    up = mim_v3_sub(up, mim_v3_scale(x, mim_v3_dot(up, x)));
    if (mim_v3_norm(up) < 1e-6) return 0;
    f->x = x, f->y = mim_v3_normalize(up), f->z = mim_v3_cross(f->x, f->y);
    return 1;
}

/* A bone's unit direction in frame f; 0 for a bone of no length. */
static int local_dir(const frame_t *f, mim_vec3 from, mim_vec3 to, float out[3])
{
    mim_vec3 d = mim_v3_sub(to, from);
    if (mim_v3_norm(d) < 1e-6) return 0;
    d = mim_v3_normalize(d);
    out[0] = (float)mim_v3_dot(d, f->x), out[1] = (float)mim_v3_dot(d, f->y), out[2] = (float)mim_v3_dot(d, f->z);
    return 1;
}

/* The 12 checks of one person (17 joints): each a direction, or upper and
 * lower directions; ok[c] 0 where a bone has no length. 0 when the person
 * has no pelvis or chest frame. */
static int person_checks(const double *j, float dir[MIM_PAIRS_CHECKS][6], int ok[MIM_PAIRS_CHECKS])
{
    frame_t P, C;
    mim_vec3 pel = joint(j, PELVIS), chest = joint(j, CHEST);
    mim_vec3 hips = mim_v3_sub(joint(j, LHIP), joint(j, RHIP)), shoulders = mim_v3_sub(joint(j, LSH), joint(j, RSH));
    /* the hips' line, or the shoulders' where the hips sit at the pelvis */
    if (!frame_from(mim_v3_norm(hips) > 1e-3 ? hips : shoulders, mim_v3_sub(joint(j, SPINE), pel), &P) &&
        !frame_from(mim_v3_norm(hips) > 1e-3 ? hips : shoulders, mim_v3_sub(joint(j, NECK), pel), &P))
        return 0;
    mim_vec3 mid = mim_v3_scale(mim_v3_add(joint(j, LSH), joint(j, RSH)), 0.5);
    if (!frame_from(shoulders, mim_v3_sub(mid, chest), &C) && !frame_from(shoulders, mim_v3_sub(joint(j, NECK), chest), &C) &&
        !frame_from(shoulders, mim_v3_sub(joint(j, HEAD), chest), &C))
        return 0;
    memset(ok, 0, MIM_PAIRS_CHECKS * sizeof *ok);
    ok[0] = local_dir(&P, joint(j, SPINE), chest, dir[0]);
    dir[1][0] = (float)mim_v3_dot(C.y, P.x), dir[1][1] = (float)mim_v3_dot(C.y, P.y), dir[1][2] = (float)mim_v3_dot(C.y, P.z);
    dir[2][0] = (float)mim_v3_dot(C.x, P.x), dir[2][1] = (float)mim_v3_dot(C.x, P.y), dir[2][2] = (float)mim_v3_dot(C.x, P.z);
    ok[1] = ok[2] = 1;
    ok[3] = local_dir(&C, joint(j, NECK), joint(j, HEAD), dir[3]);
    static const int limb[4][4] = {{LSH, LEL, LWR, 0}, {RSH, REL, RWR, 0}, {LHIP, LKN, LAN, 1}, {RHIP, RKN, RAN, 1}};
    for (int s = 0; s < 4; s++) {
        const frame_t *ref = limb[s][3] ? &P : &C;
        int up = 4 + (s & 1) + 4 * (s >> 1), low = up + 2; /* arms 4, 5 / 6, 7; legs 8, 9 / 10, 11 */
        ok[up] = local_dir(ref, joint(j, limb[s][0]), joint(j, limb[s][1]), dir[up]);
        frame_t U;
        mim_vec3 upper = mim_v3_sub(joint(j, limb[s][1]), joint(j, limb[s][0]));
        /* the upper bone's frame: y along it, x the reference's x made orthogonal */
        if (ok[up] && frame_from(mim_v3_sub(ref->x, mim_v3_scale(mim_v3_normalize(upper), mim_v3_dot(ref->x, mim_v3_normalize(upper)))),
                                 upper, &U)) {
            memcpy(dir[low], dir[up], 3 * sizeof(float));
            ok[low] = local_dir(&U, joint(j, limb[s][1]), joint(j, limb[s][2]), dir[low] + 3);
        }
    }
    return 1;
}

/* The mirror image (x -> -x, left <-> right): which check a check becomes,
 * and the signs of its components (derived in the frames above: the x
 * axes are left-minus-right lines, so they turn with the labels). */
static const int mirror_of[MIM_PAIRS_CHECKS] = {0, 1, 2, 3, 5, 4, 7, 6, 9, 8, 11, 10};
static const float mirror_sign[MIM_PAIRS_CHECKS][3] = {
    {-1, 1, 1}, {-1, 1, 1}, {1, -1, -1}, {-1, 1, 1}, {-1, 1, 1}, {-1, 1, 1},
    {-1, 1, 1}, {-1, 1, 1}, {-1, 1, 1},  {-1, 1, 1}, {-1, 1, 1}, {-1, 1, 1},
};

static double chord2(const float *a, const float *b)
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

/* The squared distance from e to the nearest example of s (chords; both
 * directions for a conditioned check). */
static double nearest2(const check_set_t *s, const float *e)
{
    double best = INFINITY;
    int w = s->conditioned ? 6 : 3;
    for (uint32_t i = 0; i < s->n; i++) {
        const float *x = s->ex + (size_t)w * i;
        double d = chord2(x, e);
        if (d >= best) continue;
        if (s->conditioned) d += chord2(x + 3, e + 3);
        if (d < best) best = d;
    }
    return best;
}

static int add_example(check_set_t *s, const float *e)
{
    int w = s->conditioned ? 6 : 3;
    if (s->n && nearest2(s, e) < THIN * THIN) return 0;
    if (s->n == s->cap) {
        uint32_t cap = s->cap ? 2 * s->cap : 256;
        float *grown = realloc(s->ex, (size_t)cap * w * sizeof *grown);
        if (!grown) return MIM_ENOMEM;
        s->ex = grown, s->cap = cap;
    }
    memcpy(s->ex + (size_t)w * s->n++, e, (size_t)w * sizeof *e);
    return 0;
}

int mim_pairs_validity_learn(const double *pairs, uint32_t n, mim_pairs_validity_t **out, mim_error_t *err)
{
    *out = NULL;
    if (!n) return mim_error_set(err, MIM_EINVAL, "joint limits: no prior pose-pairs");
    mim_pairs_validity_t *v = calloc(1, sizeof *v);
    if (!v) return mim_error_set(err, MIM_ENOMEM, "joint limits: out of memory");
    for (int c = 0; c < MIM_PAIRS_CHECKS; c++) v->set[c].conditioned = (c >= 6 && c <= 7) || c >= 10;
    uint32_t people = 0;
    for (uint64_t i = 0; i < 2ull * n; i++) {
        float dir[MIM_PAIRS_CHECKS][6];
        int ok[MIM_PAIRS_CHECKS];
        if (!person_checks(pairs + 3 * MIM_PAIR_PERSON_JOINTS * i, dir, ok)) continue;
        people++;
        for (int c = 0; c < MIM_PAIRS_CHECKS; c++) {
            if (!ok[c]) continue;
            float m[6];
            int mc = mirror_of[c], w = v->set[c].conditioned ? 6 : 3;
            for (int k = 0; k < w; k++) m[k] = dir[c][k] * mirror_sign[c][k % 3];
            if (add_example(&v->set[c], dir[c]) || add_example(&v->set[mc], m)) {
                mim_pairs_validity_free(&v);
                return mim_error_set(err, MIM_ENOMEM, "joint limits: out of memory");
            }
        }
    }
    if (!people) {
        mim_pairs_validity_free(&v);
        return mim_error_set(err, MIM_EINVAL, "joint limits: no prior person has a pelvis and a chest frame");
    }
    *out = v;
    return 0;
}

void mim_pairs_validity_free(mim_pairs_validity_t **v)
{
    if (!v || !*v) return;
    for (int c = 0; c < MIM_PAIRS_CHECKS; c++) free((*v)->set[c].ex);
    free(*v);
    *v = NULL;
}

double mim_pairs_validity_excess(const mim_pairs_validity_t *v, const double *joints, uint32_t *invalid)
{
    const double tol_chord = 2 * sin(MIM_PAIRS_VALID_TOL / 2);
    double excess = 0;
    uint32_t bad = 0;
    for (int p = 0; p < 2; p++) {
        float dir[MIM_PAIRS_CHECKS][6];
        int ok[MIM_PAIRS_CHECKS];
        if (!person_checks(joints + 3 * MIM_PAIR_PERSON_JOINTS * p, dir, ok)) {
            /* no frame: every check fails by the largest angle */
            bad += MIM_PAIRS_CHECKS, excess += MIM_PAIRS_CHECKS * M_PI * M_PI;
            continue;
        }
        for (int c = 0; c < MIM_PAIRS_CHECKS; c++) {
            const check_set_t *s = &v->set[c];
            if (!ok[c] || !s->n) continue; /* a bone of no length, or a check the prior never saw */
            double d = sqrt(nearest2(s, dir[c]));
            if (d <= tol_chord) continue;
            /* back to an angle (a conditioned check's two chords combined) */
            double a = 2 * asin(fmin(1.0, d / 2)) - MIM_PAIRS_VALID_TOL;
            bad++, excess += a * a;
        }
    }
    if (invalid) *invalid = bad;
    return excess;
}
