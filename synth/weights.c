/* Skin weights of cage vertices: smooth blends across each joint.
 *
 * Along every chain (pelvis-spine-chest-neck-head, clavicle-upper arm-
 * forearm-hand, pelvis-thigh-shin-foot) a vertex's position along its part
 * is compared with the joints' positions; across a joint the skin moves from
 * the parent bone to the child over a band about as wide as the limb there,
 * so it bends over a band instead of creasing.
 *
 * Plain two-bone blending shrinks the skin in the middle of a band by
 * cos(angle / 2) (the "collapsing elbow" of linear blend skinning), which
 * folds the inside of a deeply bent knee into slivers. So every joint also
 * has MIM__HK - 1 internal helper bones turning about the same pivot by
 * 1/4, 2/4, 3/4 of the joint's rotation (pose.c); across the band the
 * weight moves parent -> helpers -> child as hat functions. It is still
 * linear blend skinning, with a finer set of bones; the shrink drops to
 * cos(angle / 8) between two neighbouring helpers. Regions that two chains
 * share get extra fields: the hips move partly with the thighs, the upper
 * chest sides with the clavicles.
 *
 * Band widths: near the point where a joint's axis leaves the skin, a blend
 * of rotations swirls the skin; it folds at a distance band / (1.5 angle)
 * from that point (smoothstep slope 1.5 / band). Bands are kept wider than
 * 1.5 x the largest angle x the limb radius there (knee 140 deg, radius
 * 0.03 H -> over 0.11 H, used 0.12 H; elbow 145 deg, 0.02 H -> over
 * 0.076 H, used 0.088 H), so the fold stays off the skin. */
#include "synth_internal.h"

#include <math.h>
#include <string.h>

static double ss(double e0, double e1, double x)
{
    double t = (x - e0) / (e1 - e0);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return t * t * (3 - 2 * t);
}

typedef struct {
    double w[MIM__NB];
} wset_t;

/* Bone of step k (0..MIM__HK) across joint j: its parent, helpers, j. */
static int step_bone(int j, int k)
{
    if (k <= 0) return mim__joint_parent[j];
    if (k >= MIM__HK) return j;
    return MIM__HELPER(j, k);
}

/* A chain of n joints j[i] (each the child of the previous bone) with the
 * vertex's fractions t[i] across them (0 before the band, 1 past it); adds
 * `share` in total. Each joint is MIM__HK steps (parent -> helpers ->
 * joint); the weight still travelling down the chain is multiplied by each
 * step's fraction and the rest stays on the bone before the step. Products
 * keep the weights continuous even where two joints' bands overlap. */
static void chain(wset_t *o, double share, const int *j, const double *t, int n)
{
    double run = share;
    int bone = mim__joint_parent[j[0]];
    for (int i = 0; i < n; i++)
        for (int k = 0; k < MIM__HK; k++) {
            double s = t[i] * MIM__HK - k;
            s = s < 0 ? 0 : s > 1 ? 1 : s;
            o->w[bone] += run * (1 - s);
            run *= s;
            bone = step_bone(j[i], k + 1);
        }
    o->w[bone] += run;
}

/* Adds `share` spread across joint j at fraction t (0 parent .. 1 child). */
static void split(wset_t *o, double share, int j, double t) { chain(o, share, &j, &t, 1); }

static void left_weights(const mim__skeleton_t *sk, const mim__shape_t *sh, int part, double s, mim_vec3 p,
                         wset_t *o)
{
    double H = sk->H;
    const mim_vec3 *J = sk->j;
    memset(o, 0, sizeof *o);
    if (part == MIM__PART_TORSO || part == MIM__PART_HEAD) {
        double y = p.y;
        int js[4] = {MIM__J_SPINE, MIM__J_CHEST, MIM__J_NECK, MIM__J_HEAD};
        double t[4];
        t[0] = ss(J[MIM__J_SPINE].y - 0.045 * H, J[MIM__J_SPINE].y + 0.045 * H, y);
        t[1] = ss(J[MIM__J_CHEST].y - 0.05 * H, J[MIM__J_CHEST].y + 0.05 * H, y);
        if (part == MIM__PART_HEAD) {
            t[2] = ss(J[MIM__J_NECK].y - 0.012 * H, J[MIM__J_NECK].y + 0.050 * H, y);
            t[3] = ss(J[MIM__J_HEAD].y - 0.014 * H, J[MIM__J_HEAD].y + 0.016 * H, y);
        } else {
            /* over the trapezius the neck takes over towards the neck ring */
            t[2] = 0.5 * ss(J[MIM__J_NECK].y - 0.02 * H, J[MIM__J_NECK].y + 0.025 * H, y) *
                   (1 - ss(0.035 * H, 0.075 * H, fabs(p.x)));
            t[3] = 0;
        }
        if (part == MIM__PART_HEAD) {
            chain(o, 1, js, t, 4);
            return;
        }
        /* the side of the hips follows the thigh (trochanter), the upper
         * chest sides and shoulder tops the clavicle */
        double th = (1 - ss(J[MIM__J_PELVIS].y - 0.03 * H, J[MIM__J_PELVIS].y + 0.07 * H, y)) *
                    ss(0.0, 0.10 * H, p.x) * 0.6;
        double ya = sh->part[MIM__PART_TORSO].s_mark[0];
        double cl = ss(0.04 * H, 0.085 * H, p.x) * ss(ya - 0.07 * H, ya + 0.005 * H, y) * 0.8;
        wset_t base;
        memset(&base, 0, sizeof base);
        chain(&base, 1, js, t, 3);
        for (int b = 0; b < MIM__NB; b++) {
            double w = base.w[b];
            if (w == 0) continue;
            if (b == MIM__J_PELVIS && th > 0) split(o, w, MIM__J_LTHIGH, th);
            else if (b == MIM__J_CHEST && cl > 0) split(o, w, MIM__J_LCLAV, cl);
            else o->w[b] += w;
        }
        return;
    }
    const double *mk = sh->part[part].s_mark;
    if (part == MIM__PART_ARM) {
        int js[3] = {MIM__J_LUARM, MIM__J_LFARM, MIM__J_LHAND};
        double t[3] = {
            ss(mk[0] - 0.03 * H, mk[0] + 0.10 * H, s),   /* shoulder: long, flexion twists the arm root */
            ss(mk[1] - 0.042 * H, mk[1] + 0.046 * H, s), /* elbow */
            ss(mk[2] - 0.014 * H, mk[2] + 0.018 * H, s), /* wrist */
        };
        chain(o, 1, js, t, 3);
        return;
    }
    /* leg: the thigh takes over below the hip joint, by height (legs are
     * nearly vertical at rest), then knee and ankle along the leg */
    int js[3] = {MIM__J_LTHIGH, MIM__J_LSHIN, MIM__J_LFOOT};
    /* near the crotch the two thighs meet at the midline: there the skin
     * stays mostly with the pelvis, so left and right do not tear it apart
     * over a few centimetres */
    double crotch = ss(sk->y_crotch - 0.12 * H, sk->y_crotch - 0.01 * H, p.y) * (1 - ss(0, 0.05 * H, p.x));
    double t[3] = {
        (1 - ss(J[MIM__J_LTHIGH].y - 0.11 * H, J[MIM__J_LTHIGH].y + 0.01 * H, p.y)) * (1 - 0.75 * crotch),
        ss(mk[1] - 0.060 * H, mk[1] + 0.060 * H, s), /* knee */
        ss(mk[2] - 0.014 * H, mk[2] + 0.024 * H, s), /* ankle */
    };
    chain(o, 1, js, t, 3);
}

/* Keeps the MIM__CW largest of MIM__NB weights (ties to the lower bone),
 * renormalised. */
static void keep_largest(const double *all, uint8_t *wj, float *ww)
{
    int used[MIM__NB] = {0};
    double sum = 0;
    for (int k = 0; k < MIM__CW; k++) {
        int best = -1;
        for (int b = 0; b < MIM__NB; b++)
            if (!used[b] && (best < 0 || all[b] > all[best])) best = b;
        used[best] = 1;
        wj[k] = (uint8_t)best;
        ww[k] = (float)all[best];
        sum += all[best];
    }
    for (int k = 0; k < MIM__CW; k++) ww[k] = sum > 0 ? (float)(ww[k] / sum) : (k == 0 ? 1.0f : 0.0f);
}

void mim__weights(const mim__skeleton_t *sk, const mim__shape_t *sh, int part, int ring, double s, mim_vec3 p,
                  int side, uint8_t *wj, float *ww)
{
    (void)ring;
    wset_t l, r;
    left_weights(sk, sh, part, s, p, &l);
    if (side == 1 || side == 2) {
        /* mirror the bones; a midline vertex takes half of each side */
        memset(&r, 0, sizeof r);
        for (int b = 0; b < MIM__NB; b++) r.w[mim__bone_mirror(b)] += l.w[b];
        if (side == 1) l = r;
        else
            for (int b = 0; b < MIM__NB; b++) l.w[b] = 0.5 * (l.w[b] + r.w[b]);
    }
    keep_largest(l.w, wj, ww);
}
