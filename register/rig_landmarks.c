/* The 16 landmarks of a rigged avatar from its joints (mim_register.h,
 * issue 28): a rig's joints are where the bones turn, so each landmark's
 * definition (data/mh-bodies README "Landmarks", the same as synth's:
 * where a vest's tracker sits) becomes a rule from the joint under it.
 *
 * The body frame comes from the joints alone: up U from the hips' midpoint
 * to the shoulders', left L from the right hip and shoulder to the left
 * ones (made orthogonal to U), forward F = L x U; the stature H from the
 * shoulder-to-ankle height (0.76 H in the anthropometry synth uses:
 * shoulder joint 0.805 H, ankle 0.045 H). A limb landmark is the vertex
 * within a radius of its joint that reaches furthest in a direction while
 * staying near the plane across the bone and the plane of that direction
 * (synth/landmark_pick.c's score):
 *   head      top-front: 35 deg forward of U from the skull centre
 *             (head joint + 0.045 H U + 0.005 H F), on the midline
 *   chest     front midline at RIG_CHEST_T of the way from hip to shoulder height
 *   pelvis    back midline at RIG_PELVIS_T of that way
 *   spine     back midline halfway in height between chest and pelvis
 *   shoulder  from the upper arm's joint, furthest up (acromion)
 *   elbow     from the forearm's joint, outwards across the arm (F x arm,
 *             turned up): the outer elbow
 *   wrist     from the hand's joint, the same across the forearm (back of the wrist)
 *   hip       from the thigh's joint (0.006 H lower), furthest outwards
 *   knee      from the shin's joint, furthest forward (kneecap)
 *   ankle     from the foot's joint, furthest outwards
 * Only the avatar's own vertices near each joint are candidates, so props
 * and shells elsewhere play no part. */
#include "mim_register.h"

#include <float.h>
#include <stdio.h>
#include <math.h>
#include <string.h>

/* Heights of the torso landmarks as fractions of hip joint -> shoulder
 * joint height, measured on synth's rest bodies (bench/RESULTS.md). */
#define RIG_CHEST_T 0.72
#define RIG_PELVIS_T 0.088

enum { HEAD, CHEST, PELVIS, LSH, RSH, LEL, REL, LWR, RWR, LHIP, RHIP, LKN, RKN, LAN, RAN, SPINE, NLM };
const char *const mim_reg_rig_landmark_names[MIM_REG_RIG_LANDMARKS] = {
    "head",   "chest",  "pelvis", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist",
    "r_wrist", "l_hip", "r_hip",  "l_knee",     "r_knee",     "l_ankle", "r_ankle", "spine"};
_Static_assert(NLM == MIM_REG_RIG_LANDMARKS, "16 landmarks");

/* the segments (mim_segment_names order) whose joints the rules need */
enum { S_PELVIS, S_CHEST, S_HEAD, S_LSHO, S_RSHO, S_LUA, S_RUA, S_LFA, S_RFA, S_LHA, S_RHA, S_LTH, S_RTH, S_LSH, S_RSH,
       S_LFO, S_RFO };
static const int needed[] = {S_HEAD, S_LUA, S_RUA, S_LFA, S_RFA, S_LHA, S_RHA, S_LTH, S_RTH, S_LSH, S_RSH, S_LFO, S_RFO};

typedef struct {
    mim_vec3 U, L, F, hip, sh;
    double H;
} frame_t;

static mim_vec3 vat(const float *p, uint32_t i)
{
    return mim_v3(p[3 * (size_t)i], p[3 * (size_t)i + 1], p[3 * (size_t)i + 2]);
}

/* The vertex within radius of J scoring best along D, near the planes
 * across A and N through J; only on the given side of the body (side
 * +1 left, -1 right, 0 either). UINT32_MAX when none is that close. */
static uint32_t near_joint(const mim_mesh_t *m, const frame_t *fr, mim_vec3 J, double radius, mim_vec3 D, mim_vec3 A,
                           mim_vec3 N, int side)
{
    uint32_t best = UINT32_MAX;
    double bs = -DBL_MAX;
    for (uint32_t i = 0; i < m->n_vertices; i++) {
        mim_vec3 v = vat(m->positions, i), r = mim_v3_sub(v, J);
        if (mim_v3_dot(r, r) > radius * radius) continue;
        if (side && side * mim_v3_dot(mim_v3_sub(v, fr->hip), fr->L) <= 0) continue;
        double s = mim_v3_dot(r, D) - 2 * fabs(mim_v3_dot(r, A)) - 2 * fabs(mim_v3_dot(r, N));
        if (s > bs) bs = s, best = i;
    }
    return best;
}

/* The midline vertex furthest front (dir +1) or back (-1) at height h
 * (along U from the hips' joints), within a band that widens until some
 * vertex is in it. */
static uint32_t midline_at(const mim_mesh_t *m, const frame_t *fr, double h, int dir)
{
    mim_vec3 c = mim_v3_add(fr->hip, mim_v3_scale(fr->U, h));
    for (double band = 0.005 * fr->H; band < 0.1 * fr->H; band *= 2) {
        uint32_t best = UINT32_MAX;
        double bs = -DBL_MAX;
        for (uint32_t i = 0; i < m->n_vertices; i++) {
            mim_vec3 r = mim_v3_sub(vat(m->positions, i), c);
            double u = mim_v3_dot(r, fr->U), l = mim_v3_dot(r, fr->L), f = dir * mim_v3_dot(r, fr->F);
            if (fabs(u) > band || fabs(l) > band || f <= 0 || f > 0.2 * fr->H) continue;
            if (f > bs) bs = f, best = i;
        }
        if (best != UINT32_MAX) return best;
    }
    return UINT32_MAX;
}

/* Outwards across a limb whose bone points along d, turned up: F x d, or
 * its opposite when that points down (the outer elbow and the back of the
 * wrist, in an A-pose as in a T-pose). */
static mim_vec3 across(const frame_t *fr, mim_vec3 d)
{
    mim_vec3 a = mim_v3_normalize(mim_v3_cross(fr->F, d));
    return mim_v3_dot(a, fr->U) < 0 ? mim_v3_scale(a, -1) : a;
}

int mim_reg_rig_landmarks(const mim_mesh_t *mesh, const double *pivots, const uint8_t *have, float *out,
                          char *missing, size_t missing_size, mim_error_t *err)
{
    if (missing && missing_size) missing[0] = '\0';
    if (!mesh || !mesh->positions || !pivots || !have || !out)
        return mim_error_set(err, MIM_EINVAL, "rig landmarks: needs a mesh, the joints and an output");
    size_t at = 0;
    int lack = 0;
    for (size_t k = 0; k < sizeof needed / sizeof *needed; k++)
        if (!have[needed[k]]) {
            lack++;
            if (missing && at < missing_size)
                at += (size_t)snprintf(missing + at, missing_size - at, "%s%s", at ? ", " : "",
                                       mim_segment_names[needed[k]]);
        }
    if (lack) return mim_error_set(err, MIM_ENOLANDMARKS, "the rig has no joint for %d of the segments the landmarks need", lack);
    mim_vec3 P[MIM_SEGMENTS];
    for (int g = 0; g < MIM_SEGMENTS; g++) P[g] = mim_v3(pivots[3 * g], pivots[3 * g + 1], pivots[3 * g + 2]);
    frame_t fr;
    fr.hip = mim_v3_scale(mim_v3_add(P[S_LTH], P[S_RTH]), 0.5);
    fr.sh = mim_v3_scale(mim_v3_add(P[S_LUA], P[S_RUA]), 0.5);
    fr.U = mim_v3_normalize(mim_v3_sub(fr.sh, fr.hip));
    mim_vec3 L = mim_v3_add(mim_v3_sub(P[S_LTH], P[S_RTH]), mim_v3_sub(P[S_LUA], P[S_RUA]));
    fr.L = mim_v3_normalize(mim_v3_sub(L, mim_v3_scale(fr.U, mim_v3_dot(L, fr.U))));
    fr.F = mim_v3_cross(fr.L, fr.U);
    const double torso = mim_v3_dot(mim_v3_sub(fr.sh, fr.hip), fr.U);
    mim_vec3 ankles = mim_v3_scale(mim_v3_add(P[S_LFO], P[S_RFO]), 0.5);
    fr.H = mim_v3_dot(mim_v3_sub(fr.sh, ankles), fr.U) / 0.76;
    if (!(torso > 0) || !(mim_v3_norm(fr.L) > 0.5) || !(fr.H > 0) || !isfinite(fr.H))
        return mim_error_set(err, MIM_EFORMAT,
                             "rig landmarks: the joints make no body (shoulders not above the hips, or no left and right)");
    const double H = fr.H;
    uint32_t v[NLM];
    /* head: furthest along 35 deg forward of up from the skull centre, near the midline */
    {
        mim_vec3 c = mim_v3_add(P[S_HEAD], mim_v3_add(mim_v3_scale(fr.U, 0.045 * H), mim_v3_scale(fr.F, 0.005 * H)));
        double a = 35 * M_PI / 180;
        mim_vec3 D = mim_v3_add(mim_v3_scale(fr.U, cos(a)), mim_v3_scale(fr.F, sin(a)));
        v[HEAD] = near_joint(mesh, &fr, c, 0.15 * H, D, fr.L, mim_v3_cross(D, fr.L), 0);
    }
    v[CHEST] = midline_at(mesh, &fr, RIG_CHEST_T * torso, 1);
    v[PELVIS] = midline_at(mesh, &fr, RIG_PELVIS_T * torso, -1);
    v[SPINE] = UINT32_MAX;
    if (v[CHEST] != UINT32_MAX && v[PELVIS] != UINT32_MAX) {
        double hc = mim_v3_dot(mim_v3_sub(vat(mesh->positions, v[CHEST]), fr.hip), fr.U);
        double hp = mim_v3_dot(mim_v3_sub(vat(mesh->positions, v[PELVIS]), fr.hip), fr.U);
        v[SPINE] = midline_at(mesh, &fr, 0.5 * (hc + hp), -1);
    }
    for (int side = 0; side < 2; side++) {
        const int sg = side ? -1 : 1, o = side; /* l_ then r_ */
        const mim_vec3 out_dir = mim_v3_scale(fr.L, sg);
        const mim_vec3 ua = P[S_LUA + o], fa = P[S_LFA + o], ha = P[S_LHA + o];
        mim_vec3 d_up = mim_v3_normalize(mim_v3_sub(fa, ua)), d_fo = mim_v3_normalize(mim_v3_sub(ha, fa));
        v[LSH + o] = near_joint(mesh, &fr, ua, 0.07 * H, fr.U, fr.L, fr.F, sg);
        v[LEL + o] = near_joint(mesh, &fr, fa, 0.06 * H, across(&fr, d_up), d_up, fr.F, sg);
        v[LWR + o] = near_joint(mesh, &fr, ha, 0.05 * H, across(&fr, d_fo), d_fo, fr.F, sg);
        v[LHIP + o] = near_joint(mesh, &fr, mim_v3_sub(P[S_LTH + o], mim_v3_scale(fr.U, 0.006 * H)), 0.14 * H, out_dir,
                                 fr.U, fr.F, sg);
        v[LKN + o] = near_joint(mesh, &fr, P[S_LSH + o], 0.07 * H, fr.F, fr.U, fr.L, sg);
        v[LAN + o] = near_joint(mesh, &fr, P[S_LFO + o], 0.05 * H, out_dir, fr.U, fr.F, sg);
    }
    for (int l = 0; l < NLM; l++) {
        if (v[l] == UINT32_MAX)
            return mim_error_set(err, MIM_ENOLANDMARKS,
                                 "rig landmarks: no surface near the joint for %s (is the mesh the rig's?)",
                                 mim_reg_rig_landmark_names[l]);
        memcpy(out + 3 * l, mesh->positions + 3 * (size_t)v[l], 3 * sizeof(float));
    }
    return 0;
}
