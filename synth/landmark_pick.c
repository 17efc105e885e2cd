/* The 16 landmarks as vertices of the rest body of the reference subject.
 *
 * Each landmark is where a vest's tracker would sit, following the
 * definitions of data/mh-bodies (README "Landmarks"): the head top-front (35
 * deg forward of vertical), the mid-sternum, the sacrum, the acromion above
 * the shoulder joint, the outer elbow, the back of the wrist, the outer hip
 * (trochanter), the kneecap, the outer ankle, and the back midline halfway
 * between the chest and pelvis landmarks. The left ones (+X) are found by
 * scoring vertices near the joint; each right landmark is the vertex nearest
 * to the mirror image of its left one, so the pairs match. */
#include "synth_internal.h"

#include <float.h>
#include <math.h>

enum { HEAD, CHEST, PELVIS, LSH, RSH, LEL, REL, LWR, RWR, LHIP, RHIP, LKN, RKN, LAN, RAN, SPINE };

static mim_vec3 vat(const double *p, uint32_t i) { return mim_v3(p[3 * i], p[3 * i + 1], p[3 * i + 2]); }

/* Front (dir > 0) or back midline vertex whose height is nearest y. */
static uint32_t midline_at(const double *p, uint32_t nv, double y, int dir)
{
    uint32_t best = 0;
    double bd = DBL_MAX;
    for (uint32_t i = 0; i < nv; i++) {
        mim_vec3 v = vat(p, i);
        if (fabs(v.x) > 1e-9 || v.z * dir <= 0) continue;
        /* the outermost point at that height: prefer larger |z| on ties */
        double d = fabs(v.y - y) - 1e-3 * fabs(v.z);
        if (d < bd) bd = d, best = i;
    }
    return best;
}

/* Vertex within `radius` of joint J scoring best in direction D, kept close
 * to the plane through J across the bone (axis A) and to the plane of D and
 * A (normal N). */
static uint32_t near_joint(const double *p, uint32_t nv, mim_vec3 J, double radius, mim_vec3 D, mim_vec3 A,
                           mim_vec3 N)
{
    uint32_t best = 0;
    double bs = -DBL_MAX;
    for (uint32_t i = 0; i < nv; i++) {
        mim_vec3 r = mim_v3_sub(vat(p, i), J);
        if (mim_v3_norm(r) > radius || vat(p, i).x <= 0) continue;
        double s = mim_v3_dot(r, D) - 2 * fabs(mim_v3_dot(r, A)) - 2 * fabs(mim_v3_dot(r, N));
        if (s > bs) bs = s, best = i;
    }
    return best;
}

static uint32_t nearest(const double *p, uint32_t nv, mim_vec3 t)
{
    uint32_t best = 0;
    double bd = DBL_MAX;
    for (uint32_t i = 0; i < nv; i++) {
        mim_vec3 r = mim_v3_sub(vat(p, i), t);
        double d = mim_v3_dot(r, r);
        if (d < bd) bd = d, best = i;
    }
    return best;
}

void mim__landmarks_pick(const mim__body_t *b, uint32_t nv, uint32_t out[MIM_LANDMARKS_DEFAULT_COUNT])
{
    const double *p = b->rest;
    const mim__skeleton_t *sk = &b->sk;
    const mim_vec3 *j = sk->j;
    double H = sk->H;
    mim_vec3 X = mim_v3(1, 0, 0), Y = mim_v3(0, 1, 0), Z = mim_v3(0, 0, 1);

    /* head: furthest along 35 deg forward of vertical from the skull centre */
    {
        mim_vec3 c = mim_v3_add(j[MIM__J_HEAD], mim_v3(0, 0.045 * H, 0.005 * H));
        double a = 35 * M_PI / 180;
        mim_vec3 D = mim_v3(0, cos(a), sin(a));
        double bs = -DBL_MAX;
        out[HEAD] = 0;
        for (uint32_t i = 0; i < nv; i++) {
            mim_vec3 v = vat(p, i);
            if (fabs(v.x) > 1e-9 || v.y < j[MIM__J_HEAD].y) continue;
            double s = mim_v3_dot(mim_v3_sub(v, c), D);
            if (s > bs) bs = s, out[HEAD] = i;
        }
    }
    double ychest = j[MIM__J_CHEST].y + 0.25 * (j[MIM__J_LCLAV].y - j[MIM__J_CHEST].y);
    out[CHEST] = midline_at(p, nv, ychest, 1);
    double ypel = j[MIM__J_PELVIS].y + 0.35 * (j[MIM__J_SPINE].y - j[MIM__J_PELVIS].y);
    out[PELVIS] = midline_at(p, nv, ypel, -1);
    out[SPINE] = midline_at(p, nv, 0.5 * (vat(p, out[CHEST]).y + vat(p, out[PELVIS]).y), -1);

    mim_vec3 d = mim__arm_dir(), lat = mim__arm_lat();
    /* acromion: the top of the shoulder over the joint */
    out[LSH] = near_joint(p, nv, j[MIM__J_LUARM], 0.07 * H, Y, X, Z);
    out[LEL] = near_joint(p, nv, j[MIM__J_LFARM], 0.06 * H, lat, d, Z);
    out[LWR] = near_joint(p, nv, j[MIM__J_LHAND], 0.05 * H, lat, d, Z);
    out[LHIP] = near_joint(p, nv, mim_v3_sub(j[MIM__J_LTHIGH], mim_v3(0, 0.006 * H, 0)), 0.14 * H, X, Y, Z);
    out[LKN] = near_joint(p, nv, j[MIM__J_LSHIN], 0.07 * H, Z, Y, X);
    out[LAN] = near_joint(p, nv, j[MIM__J_LFOOT], 0.05 * H, X, Y, Z);

    static const int pairs[][2] = {{LSH, RSH}, {LEL, REL}, {LWR, RWR}, {LHIP, RHIP}, {LKN, RKN}, {LAN, RAN}};
    for (size_t k = 0; k < sizeof pairs / sizeof pairs[0]; k++) {
        mim_vec3 v = vat(p, out[pairs[k][0]]);
        out[pairs[k][1]] = nearest(p, nv, mim_v3(-v.x, v.y, v.z));
    }
}
