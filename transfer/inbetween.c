/* In-between landmarks along the skeleton (issue 29). Seed 000 (Section
 * 3.5) morphs between key poses; the landmarks that pin each in-between
 * used to be lerped, so an arm swinging from over the head to the hip
 * passed its wrist through the shoulder and collapsed (a 0.288 m upper
 * arm 0.165 m long half-way). Here the landmark skeleton (retarget.c's
 * tree) is interpolated as bones: the torso's frame (pelvis to chest up,
 * hips and shoulders left) turns by the slerp of its two keys'; each
 * bone's direction in that frame turns on a great circle from one key's to
 * the other's, through the side when they point opposite ways (an arm from
 * up to down swings out through a T, not through the body); its length
 * goes linearly from one key's to the other's; the pelvis moves on a
 * straight line. Every bone's length so stays within its keys' range. */
#include "internal.h"

#include <math.h>
#include <string.h>

/* The torso's frame of a landmark set: columns left, up, forward. */
static mim_quat torso_frame(const float *lm, int pelvis, int chest, int lh, int rh, int ls, int rs)
{
    const float *p = lm + 3 * pelvis, *c = lm + 3 * chest;
    mim_vec3 U = mim_v3_normalize(mim_v3(c[0] - p[0], c[1] - p[1], c[2] - p[2]));
    mim_vec3 L = mim_v3(lm[3 * lh] - lm[3 * rh] + lm[3 * ls] - lm[3 * rs],
                        lm[3 * lh + 1] - lm[3 * rh + 1] + lm[3 * ls + 1] - lm[3 * rs + 1],
                        lm[3 * lh + 2] - lm[3 * rh + 2] + lm[3 * ls + 2] - lm[3 * rs + 2]);
    L = mim_v3_normalize(mim_v3_sub(L, mim_v3_scale(U, mim_v3_dot(L, U))));
    mim_vec3 F = mim_v3_cross(L, U);
    const double m[9] = {L.x, U.x, F.x, L.y, U.y, F.y, L.z, U.z, F.z}; /* column-major: columns L, U, F */
    return mim_quat_normalize(mim_quat_from_matrix(m));
}

/* From unit a towards unit b by the share t of the angle between them, on
 * a great circle; nearly opposite directions turn towards `side` first
 * (about a x side). */
static mim_vec3 turn_towards(mim_vec3 a, mim_vec3 b, double t, mim_vec3 side)
{
    double c = fmax(-1.0, fmin(1.0, mim_v3_dot(a, b))), angle = acos(c);
    if (angle < 1e-9) return a;
    mim_vec3 axis = mim_v3_cross(a, b);
    if (mim_v3_norm(axis) < 1e-3 * sin(angle) + 1e-6) { /* nearly opposite: through the side */
        axis = mim_v3_cross(a, side);
        if (mim_v3_norm(axis) < 1e-6) axis = mim_v3_cross(a, mim_v3(0, 0, 1));
        if (mim_v3_norm(axis) < 1e-6) axis = mim_v3_cross(a, mim_v3(1, 0, 0));
    }
    return mim_quat_rotate(mim_quat_axis_angle(mim_v3_normalize(axis), t * angle), a);
}

int mim_xfer_landmarks_between(const mim_landmark_map_t *map, const float *a, const float *b, double t, float *out,
                               mim_error_t *err)
{
    if (!map || !a || !b || !out) return mim_error_set(err, MIM_EINVAL, "in-between: NULL landmarks");
    if (!(t >= 0 && t <= 1)) return mim_error_set(err, MIM_EINVAL, "in-between: t = %g outside [0, 1]", t);
    int root, child[MIM__XFER_BONES], parent[MIM__XFER_BONES];
    int rc = mim__xfer_landmark_tree(map, &root, child, parent, "skeletal in-betweens", err);
    if (rc) return rc;
    for (size_t i = 0; i < 3 * (size_t)map->count; i++)
        if (!isfinite(a[i]) || !isfinite(b[i]))
            return mim_error_set(err, MIM_ENONFINITE, "in-between: landmark %zu is not finite", i / 3);
    if (t == 0 || t == 1) { /* the keys themselves, to the bit */
        memcpy(out, t == 0 ? a : b, 3 * (size_t)map->count * sizeof *out);
        return 0;
    }
    const int chest = mim_landmarks_find(map, "chest"), lh = mim_landmarks_find(map, "l_hip"),
              rh = mim_landmarks_find(map, "r_hip"), ls = mim_landmarks_find(map, "l_shoulder"),
              rs = mim_landmarks_find(map, "r_shoulder");
    mim_quat qa = torso_frame(a, root, chest, lh, rh, ls, rs), qb = torso_frame(b, root, chest, lh, rh, ls, rs);
    mim_quat qt = mim_quat_slerp(qa, qb, t); /* mim_quat_slerp takes the shorter way round */
    mim_quat ia = {-qa.x, -qa.y, -qa.z, qa.w}, ib = {-qb.x, -qb.y, -qb.z, qb.w};
    for (int c = 0; c < 3; c++) out[3 * root + c] = (float)((1 - t) * a[3 * root + c] + t * b[3 * root + c]);
    for (int k = 0; k < MIM__XFER_BONES; k++) {
        const int ch = child[k], pa = parent[k];
        mim_vec3 da = mim_v3(a[3 * ch] - a[3 * pa], a[3 * ch + 1] - a[3 * pa + 1], a[3 * ch + 2] - a[3 * pa + 2]);
        mim_vec3 db = mim_v3(b[3 * ch] - b[3 * pa], b[3 * ch + 1] - b[3 * pa + 1], b[3 * ch + 2] - b[3 * pa + 2]);
        const double la = mim_v3_norm(da), lb = mim_v3_norm(db), len = (1 - t) * la + t * lb;
        /* in each key's torso frame; a bone of no length takes the other key's direction */
        mim_vec3 ua = la > 0 ? mim_quat_rotate(ia, mim_v3_scale(da, 1 / la)) : mim_v3(0, 0, 0);
        mim_vec3 ub = lb > 0 ? mim_quat_rotate(ib, mim_v3_scale(db, 1 / lb)) : mim_v3(0, 0, 0);
        if (!(la > 0)) ua = ub;
        if (!(lb > 0)) ub = ua;
        /* opposite ways turn through the body's side: the left limbs out to +L, the right to -L (the
         * side of the bone's end in the torso's frame) */
        mim_vec3 rel = mim_quat_rotate(ia, mim_v3(a[3 * ch] - a[3 * root], a[3 * ch + 1] - a[3 * root + 1],
                                                  a[3 * ch + 2] - a[3 * root + 2]));
        mim_vec3 u = turn_towards(ua, ub, t, mim_v3(rel.x >= 0 ? 1 : -1, 0, 0));
        mim_vec3 d = mim_quat_rotate(qt, mim_v3_scale(u, len));
        out[3 * ch] = (float)(out[3 * pa] + d.x);
        out[3 * ch + 1] = (float)(out[3 * pa + 1] + d.y);
        out[3 * ch + 2] = (float)(out[3 * pa + 2] + d.z);
    }
    return 0;
}

int mim_xfer_landmarks_torso(const mim_landmark_map_t *map, const float *u, double q[4], mim_error_t *err)
{
    int root, child[MIM__XFER_BONES], parent[MIM__XFER_BONES];
    int rc = mim__xfer_landmark_tree(map, &root, child, parent, "a torso frame", err);
    if (rc) return rc;
    mim_quat t = torso_frame(u, root, mim_landmarks_find(map, "chest"), mim_landmarks_find(map, "l_hip"),
                             mim_landmarks_find(map, "r_hip"), mim_landmarks_find(map, "l_shoulder"),
                             mim_landmarks_find(map, "r_shoulder"));
    if (!isfinite(t.x) || !isfinite(t.y) || !isfinite(t.z) || !isfinite(t.w))
        return mim_error_set(err, MIM_ENONFINITE, "a torso frame: the landmarks make none");
    q[0] = t.x, q[1] = t.y, q[2] = t.z, q[3] = t.w;
    return 0;
}
