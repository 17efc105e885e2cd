/* The vest skeleton estimated from the avatar: 17 segments (one per PrioVR
 * sensor), their pivots (joint centres) and bone lengths.
 *
 * Landmarks sit on the skin (seed 000, sec. 3.2 and Fig. 3: the 16 landmarks are
 * surface points tracked on the body), so each joint centre is found under
 * its landmark: the midpoint of the chord through the body along the
 * landmark vertex's inward normal, bounded by a depth typical of that joint
 * as a fraction of stature (a shoulder joint lies about 4 cm below the
 * acromion, a hip joint about 6 cm inside the trochanter). The avatar is in
 * mimic's frame: +Y up, facing +Z, its own left +X. */
#include "mim_vest_kinematics.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

const char *mim_vest_segment_name(uint32_t s) { return s < MIM_VEST_SEGMENTS ? mim_segment_names[s] : NULL; }
int mim_vest_segment_parent(uint32_t s) { return mim_segment_parent(s); }

enum { HEAD, CHEST, PELVIS, LSH, RSH, LEL, REL, LWR, RWR, LHIP, RHIP, LKN, RKN, LAN, RAN, SPINE, NDEF };

/* The segment that carries each default landmark: a landmark at the distal
 * end of a bone (elbow, wrist, knee, ankle) moves with that bone. */
static const int default_segment[NDEF] = {
    MIM_VEST_HEAD,       MIM_VEST_CHEST,      MIM_VEST_PELVIS,     MIM_VEST_L_SHOULDER,
    MIM_VEST_R_SHOULDER, MIM_VEST_L_UPPERARM, MIM_VEST_R_UPPERARM, MIM_VEST_L_FOREARM,
    MIM_VEST_R_FOREARM,  MIM_VEST_L_THIGH,    MIM_VEST_R_THIGH,    MIM_VEST_L_THIGH,
    MIM_VEST_R_THIGH,    MIM_VEST_L_SHIN,     MIM_VEST_R_SHIN,     MIM_VEST_CHEST};

/* Joint depth bound under each landmark, as a fraction of stature. */
static const double depth_cap[NDEF] = {0.05, 0.1, 0.1, 0.025, 0.025, 0.05, 0.05, 0.05,
                                       0.05, 0.035, 0.035, 0.05, 0.05, 0.05, 0.05, 0.1};

static mim_vec3 vtx(const mim_mesh_t *m, uint32_t i)
{
    return mim_v3(m->positions[3 * i], m->positions[3 * i + 1], m->positions[3 * i + 2]);
}

static mim_vec3 vertex_normal(const mim_mesh_t *m, uint32_t v)
{
    mim_vec3 n = mim_v3(0, 0, 0);
    for (uint32_t f = 0; f < m->n_faces; f++) {
        const uint32_t *t = m->faces + 3 * f;
        if (t[0] != v && t[1] != v && t[2] != v) continue;
        mim_vec3 a = vtx(m, t[0]), b = vtx(m, t[1]), c = vtx(m, t[2]);
        n = mim_v3_add(n, mim_v3_cross(mim_v3_sub(b, a), mim_v3_sub(c, a))); /* area-weighted */
    }
    return mim_v3_normalize(n);
}

/* Nearest hit t > 0 of the ray o + t d with the mesh, skipping faces of
 * vertex skip (Moller-Trumbore); DBL_MAX if none. */
static double ray_hit(const mim_mesh_t *m, mim_vec3 o, mim_vec3 d, uint32_t skip)
{
    double best = DBL_MAX;
    for (uint32_t f = 0; f < m->n_faces; f++) {
        const uint32_t *t = m->faces + 3 * f;
        if (t[0] == skip || t[1] == skip || t[2] == skip) continue;
        mim_vec3 a = vtx(m, t[0]), e1 = mim_v3_sub(vtx(m, t[1]), a), e2 = mim_v3_sub(vtx(m, t[2]), a);
        mim_vec3 p = mim_v3_cross(d, e2);
        double det = mim_v3_dot(e1, p);
        if (fabs(det) < 1e-15) continue;
        double inv = 1.0 / det;
        mim_vec3 s = mim_v3_sub(o, a);
        double u = mim_v3_dot(s, p) * inv;
        if (u < 0 || u > 1) continue;
        mim_vec3 q = mim_v3_cross(s, e1);
        double v = mim_v3_dot(d, q) * inv;
        if (v < 0 || u + v > 1) continue;
        double tt = mim_v3_dot(e2, q) * inv;
        if (tt > 1e-7 && tt < best) best = tt;
    }
    return best;
}

static double seg_dist(mim_vec3 p, mim_vec3 a, mim_vec3 b)
{
    mim_vec3 ab = mim_v3_sub(b, a);
    double l2 = mim_v3_dot(ab, ab), t = l2 > 0 ? mim_v3_dot(mim_v3_sub(p, a), ab) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return mim_v3_norm(mim_v3_sub(p, mim_v3_add(a, mim_v3_scale(ab, t))));
}

int mim_vest_skeleton_estimate(mim_vest_skeleton_t *sk, const mim_mesh_t *avatar, const mim_landmark_map_t *map,
                               mim_error_t *err)
{
    if (!sk || !avatar || !map) return mim_error_set(err, MIM_EINVAL, "vest skeleton: missing avatar or map");
    if (!avatar->n_vertices || !avatar->n_faces)
        return mim_error_set(err, MIM_EEMPTY, "vest skeleton: the avatar mesh is empty");
    int rc = mim_landmarks_validate(map, avatar->n_vertices, "avatar landmark map", err);
    if (rc) return rc;
    memset(sk, 0, sizeof *sk);
    int idx[NDEF];
    for (int k = 0; k < NDEF; k++) {
        idx[k] = -1;
        for (uint32_t i = 0; i < map->count; i++)
            if (!strcmp(map->names[i], mim_landmark_default_names[k])) idx[k] = (int)i;
        if (idx[k] < 0)
            return mim_error_set(err, MIM_ENOLANDMARKS,
                                 "vest skeleton: the landmark map has no '%s' (the vest needs the 16 default landmarks)",
                                 mim_landmark_default_names[k]);
    }
    double ylo = DBL_MAX, yhi = -DBL_MAX;
    for (uint32_t i = 0; i < avatar->n_vertices; i++) {
        double y = avatar->positions[3 * i + 1];
        if (y < ylo) ylo = y;
        if (y > yhi) yhi = y;
    }
    double H = yhi - ylo;
    if (!(H > 0)) return mim_error_set(err, MIM_EFORMAT, "vest skeleton: the avatar has no height along +Y");

    sk->n_landmarks = map->count;
    for (uint32_t i = 0; i < map->count; i++) {
        mim_vec3 L = vtx(avatar, map->vertex[i]);
        sk->landmark[i] = L;
        double cap = 0.05;
        for (int k = 0; k < NDEF; k++)
            if (idx[k] == (int)i) cap = depth_cap[k];
        mim_vec3 n = vertex_normal(avatar, map->vertex[i]);
        mim_vec3 in = mim_v3_scale(n, -1);
        double t = ray_hit(avatar, L, in, map->vertex[i]);
        double depth = t < DBL_MAX ? 0.5 * t : cap * H;
        if (depth > cap * H) depth = cap * H;
        sk->centre[i] = mim_v3_add(L, mim_v3_scale(in, depth));
    }
#define C(k) (sk->centre[idx[k]])
    mim_vec3 *pv = sk->pivot, *en = sk->end;
    mim_vec3 neck = mim_v3_lerp(C(LSH), C(RSH), 0.5);
    pv[MIM_VEST_PELVIS] = mim_v3_lerp(C(LHIP), C(RHIP), 0.5);
    en[MIM_VEST_PELVIS] = C(SPINE);
    pv[MIM_VEST_CHEST] = C(SPINE);
    en[MIM_VEST_CHEST] = neck;
    pv[MIM_VEST_HEAD] = neck;
    en[MIM_VEST_HEAD] = C(HEAD);
    static const int side[2][7] = {{LSH, LEL, LWR, LHIP, LKN, LAN, 0}, {RSH, REL, RWR, RHIP, RKN, RAN, 1}};
    for (int s = 0; s < 2; s++) {
        const int *j = side[s];
        pv[MIM_VEST_L_SHOULDER + s] = neck;
        en[MIM_VEST_L_SHOULDER + s] = C(j[0]);
        pv[MIM_VEST_L_UPPERARM + s] = C(j[0]);
        en[MIM_VEST_L_UPPERARM + s] = C(j[1]);
        pv[MIM_VEST_L_FOREARM + s] = C(j[1]);
        en[MIM_VEST_L_FOREARM + s] = C(j[2]);
        pv[MIM_VEST_L_HAND + s] = C(j[2]);
        /* no landmark on the hand: its length is 0.6 forearm (Winter's table) */
        en[MIM_VEST_L_HAND + s] = mim_v3_add(C(j[2]), mim_v3_scale(mim_v3_sub(C(j[2]), C(j[1])), 0.6));
        pv[MIM_VEST_L_THIGH + s] = C(j[3]);
        en[MIM_VEST_L_THIGH + s] = C(j[4]);
        pv[MIM_VEST_L_SHIN + s] = C(j[4]);
        en[MIM_VEST_L_SHIN + s] = C(j[5]);
        pv[MIM_VEST_L_FOOT + s] = C(j[5]);
        en[MIM_VEST_L_FOOT + s] = mim_v3_add(C(j[5]), mim_v3(0, 0, 0.1 * H));
    }
#undef C
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) sk->length[s] = mim_v3_norm(mim_v3_sub(en[s], pv[s]));
    for (uint32_t i = 0; i < map->count; i++) {
        int k = -1;
        for (int j = 0; j < NDEF; j++)
            if (idx[j] == (int)i) k = j;
        if (k >= 0) {
            sk->segment[i] = (uint32_t)default_segment[k];
            continue;
        }
        /* another landmark rides on the bone nearest to it */
        double best = DBL_MAX;
        for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
            double dd = seg_dist(sk->landmark[i], pv[s], en[s]);
            if (dd < best) best = dd, sk->segment[i] = s;
        }
    }
    return 0;
}

void mim_vest_skeleton_bones(const mim_vest_skeleton_t *sk, double bones[MIM_VEST_SEGMENTS * 6])
{
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) {
        const mim_vec3 a = sk->pivot[s], b = sk->end[s];
        double *o = bones + 6 * s;
        o[0] = a.x, o[1] = a.y, o[2] = a.z, o[3] = b.x, o[4] = b.y, o[5] = b.z;
    }
}
