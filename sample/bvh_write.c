/* Pose-pairs as BVH (Biovision hierarchy), one file per person, one frame
 * per pose-pair: what `mimic pairs sample --bvh DIR` writes for Blender.
 *
 * The skeleton is the 17 joints as a tree rooted at the pelvis, with CMU
 * names so that mim_pair_joint_map (and vest/'s readers) find them again.
 * Its rest pose is frame 0: the OFFSETs are frame 0's bone vectors, so zero
 * rotations reproduce it. A frame's rotation at a joint comes from where
 * its children are:
 * - one child: the smallest rotation, in the parent's current frame, that
 *   turns the rest bone onto the current one (no twist about the bone, so
 *   the joint's frame is fixed by its parent's);
 * - the pelvis and chest (three children): the rotation that best maps the
 *   rest child directions onto the current ones (Kabsch, solved as Horn's
 *   quaternion eigenproblem, J. Opt. Soc. Am. A 4(4), 1987).
 * Each child then lies along its current bone at frame 0's distance: exact
 * for forward kinematics (the sampler's fixed bone lengths); motion capture
 * whose bones stretch keeps frame 0's lengths.
 * Channels as CMU files and Blender: the root Xposition Yposition Zposition,
 * every joint Zrotation Xrotation Yrotation in degrees, R = Rz Rx Ry (as
 * vest/motion_bvh.c reads them). Units are metres: Blender imports at
 * scale 1. The layout (one keyword per line) is what Blender's line-based
 * importer expects. */
#include "mim_sample.h"

#include <lapacke.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#define NJ MIM_PAIR_PERSON_JOINTS
#define BONE_EPS 1e-9 /* metres: a shorter bone has no direction */

/* The tree in file order, parents first; joint: mim_sample_joint_names index. */
static const struct {
    const char *name;
    int joint, parent;
} skel[NJ] = {
    {"Hips", 2, -1},        {"Spine", 15, 0},        {"Spine1", 1, 1},      {"Neck", 16, 2},
    {"Head", 0, 3},         {"LeftArm", 3, 2},       {"LeftForeArm", 5, 5}, {"LeftHand", 7, 6},
    {"RightArm", 4, 2},     {"RightForeArm", 6, 8},  {"RightHand", 8, 9},   {"LeftUpLeg", 9, 0},
    {"LeftLeg", 11, 11},    {"LeftFoot", 13, 12},    {"RightUpLeg", 10, 0}, {"RightLeg", 12, 14},
    {"RightFoot", 14, 15},
};

typedef struct {
    char *p;
    size_t len, cap;
    int oom;
} buf_t;

static void put(buf_t *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(buf_t *b, const char *fmt, ...)
{
    while (!b->oom) {
        va_list ap;
        va_start(ap, fmt);
        int k = vsnprintf(b->p + b->len, b->cap - b->len, fmt, ap);
        va_end(ap);
        if (k >= 0 && (size_t)k < b->cap - b->len) {
            b->len += (size_t)k;
            return;
        }
        size_t cap = k < 0 ? 0 : 2 * b->cap + (size_t)k;
        char *p = cap ? realloc(b->p, cap) : NULL;
        if (!p) b->oom = 1;
        else b->p = p, b->cap = cap;
    }
}

/* Writes v and returns it as a reader gets it back, so that each joint's
 * rotation makes up for its parent's rounding instead of adding to it. */
static double num(buf_t *b, const char *sep, double v)
{
    char s[40];
    if (!isfinite(v) || fabs(v) < 1e-10) v = 0; /* no "nan", "-0" or 1e-17 */
    snprintf(s, sizeof s, "%.10g", v);
    put(b, "%s%s", sep, s);
    return strtod(s, NULL);
}

static mim_vec3 at(const double *p, int k) { return mim_v3(p[3 * k], p[3 * k + 1], p[3 * k + 2]); }
static mim_quat qconj(mim_quat q) { return (mim_quat){-q.x, -q.y, -q.z, q.w}; }

/* The smallest rotation taking unit a to unit b; opposite vectors turn
 * about an axis across a (any such axis is as small). */
static mim_quat minrot(mim_vec3 a, mim_vec3 b)
{
    double w = 1 + mim_v3_dot(a, b);
    mim_vec3 c = mim_v3_cross(a, b);
    if (w < 1e-12) c = mim_v3_cross(a, fabs(a.x) < 0.6 ? mim_v3(1, 0, 0) : mim_v3(0, 1, 0)), w = 0;
    return mim_quat_normalize((mim_quat){c.x, c.y, c.z, w});
}

/* Horn: the unit quaternion maximising sum d_i . (q o_i) is the eigenvector
 * of N's largest eigenvalue (S = sum o_i d_i^T). */
static mim_quat horn(const mim_vec3 *o, const mim_vec3 *d, int m)
{
    double S[3][3] = {{0}};
    for (int i = 0; i < m; i++) {
        double a[3] = {o[i].x, o[i].y, o[i].z}, c[3] = {d[i].x, d[i].y, d[i].z};
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) S[r][k] += a[r] * c[k];
    }
    double N[16] = {S[0][0] + S[1][1] + S[2][2], S[1][2] - S[2][1], S[2][0] - S[0][2], S[0][1] - S[1][0],
                    0, S[0][0] - S[1][1] - S[2][2], S[0][1] + S[1][0], S[2][0] + S[0][2],
                    0, 0, -S[0][0] + S[1][1] - S[2][2], S[1][2] + S[2][1],
                    0, 0, 0, -S[0][0] - S[1][1] + S[2][2]};
    double ev[4];
    /* row-major upper triangle read as column-major lower: N is symmetric */
    if (LAPACKE_dsyev(LAPACK_COL_MAJOR, 'V', 'L', 4, N, 4, ev)) return mim_quat_identity();
    return mim_quat_normalize((mim_quat){N[13], N[14], N[15], N[12]}); /* ascending: the last column */
}

/* A joint's world rotation from its children's rest (o) and current (d)
 * bone vectors, Gp its parent's. Two directions apart, both at rest and
 * now, fix it (Kabsch); one fixes it up to a twist, taken from the parent;
 * none (a leaf, zero-length bones) leaves the parent's. */
static mim_quat world_rot(mim_quat Gp, const mim_vec3 *o, const mim_vec3 *d, int k)
{
    mim_vec3 ou[3], du[3];
    int m = 0, spread = 0;
    for (int i = 0; i < k; i++)
        if (mim_v3_norm(o[i]) > BONE_EPS && mim_v3_norm(d[i]) > BONE_EPS)
            ou[m] = mim_v3_normalize(o[i]), du[m] = mim_v3_normalize(d[i]), m++;
    for (int a = 0; a < m; a++)
        for (int b = a + 1; b < m; b++)
            if (mim_v3_norm(mim_v3_cross(ou[a], ou[b])) > 1e-6 && mim_v3_norm(mim_v3_cross(du[a], du[b])) > 1e-6)
                spread = 1;
    if (spread) return horn(ou, du, m);
    if (m) return mim_quat_mul(Gp, minrot(ou[0], mim_quat_rotate(qconj(Gp), du[0])));
    return Gp;
}

/* q as Z X Y angles (radians), q = Rz Rx Ry, X in [-90, 90] degrees. Y is
 * what is left after Z and X, so that at gimbal lock (X = +-90, Z and Y
 * about one axis) the three still rebuild q. */
static void euler_zxy(mim_quat q, double out[3])
{
    double R[9];
    mim_quat_to_matrix(q, R); /* column-major: R[3 c + r]; R(2,1) = sin x, R(0,1), R(1,1) = -sin z, cos z times cos x */
    double x = atan2(R[5], hypot(R[3], R[4])), z = atan2(-R[3], R[4]);
    mim_quat zx = mim_quat_mul(mim_quat_axis_angle(mim_v3(0, 0, 1), z), mim_quat_axis_angle(mim_v3(1, 0, 0), x));
    mim_quat r = mim_quat_mul(qconj(zx), q);
    if (r.w < 0) r.y = -r.y, r.w = -r.w;
    out[0] = z, out[1] = x, out[2] = 2 * atan2(r.y, r.w);
}

static void joint(buf_t *b, const double *p0, int k, int depth)
{
    static const char tabs[] = "\t\t\t\t\t\t\t\t";
    int in = depth;
    put(b, "%.*s%s %s\n%.*s{\n%.*s\tOFFSET", in, tabs, k ? "JOINT" : "ROOT", skel[k].name, in, tabs, in, tabs);
    /* the root at the origin: its position channels are then its place in
     * the world both for readers that add OFFSET and for Blender's */
    mim_vec3 off = k ? mim_v3_sub(at(p0, skel[k].joint), at(p0, skel[skel[k].parent].joint)) : mim_v3(0, 0, 0);
    num(b, " ", off.x), num(b, " ", off.y), num(b, " ", off.z);
    put(b, "\n%.*s\tCHANNELS %s\n", in, tabs,
        k ? "3 Zrotation Xrotation Yrotation" : "6 Xposition Yposition Zposition Zrotation Xrotation Yrotation");
    int leaf = 1;
    for (int c = k + 1; c < NJ; c++)
        if (skel[c].parent == k) joint(b, p0, c, depth + 1), leaf = 0;
    if (leaf) { /* a 10 cm tip along the incoming bone (up when it has no length) gives Blender the bone's tail */
        mim_vec3 tip = mim_v3_norm(off) > BONE_EPS ? mim_v3_scale(mim_v3_normalize(off), 0.1) : mim_v3(0, 0.1, 0);
        put(b, "%.*s\tEnd Site\n%.*s\t{\n%.*s\t\tOFFSET", in, tabs, in, tabs, in, tabs);
        num(b, " ", tip.x), num(b, " ", tip.y), num(b, " ", tip.z);
        put(b, "\n%.*s\t}\n", in, tabs);
    }
    put(b, "%.*s}\n", in, tabs);
}

/* One frame's line: p this frame's person, p0 frame 0's. */
static void frame(buf_t *b, const double *p, const double *p0)
{
    static const int axis[3] = {2, 0, 1}; /* Z X Y */
    mim_quat G[NJ];                      /* world rotations as a reader rebuilds them */
    mim_vec3 root = at(p, skel[0].joint);
    num(b, "", root.x), num(b, " ", root.y), num(b, " ", root.z);
    for (int k = 0; k < NJ; k++) {
        mim_quat Gp = skel[k].parent < 0 ? mim_quat_identity() : G[skel[k].parent];
        mim_vec3 o[3], d[3];
        int m = 0;
        for (int c = k + 1; c < NJ; c++)
            if (skel[c].parent == k && m < 3) {
                o[m] = mim_v3_sub(at(p0, skel[c].joint), at(p0, skel[k].joint));
                d[m] = mim_v3_sub(at(p, skel[c].joint), at(p, skel[k].joint));
                m++;
            }
        double zxy[3];
        euler_zxy(mim_quat_mul(qconj(Gp), world_rot(Gp, o, d, m)), zxy);
        mim_quat L = mim_quat_identity();
        for (int a = 0; a < 3; a++) {
            double deg = num(b, " ", zxy[a] * (180.0 / M_PI));
            mim_vec3 ax = mim_v3(axis[a] == 0, axis[a] == 1, axis[a] == 2);
            L = mim_quat_mul(L, mim_quat_axis_angle(ax, deg * (M_PI / 180.0)));
        }
        G[k] = mim_quat_mul(Gp, L);
    }
    put(b, "\n");
}

char *mim_pairs_bvh_text(const double *pairs, uint32_t n, int person, double frame_time)
{
    if (!pairs || !n || (person != 0 && person != 1)) return NULL;
    if (!(frame_time > 0) || !isfinite(frame_time)) frame_time = 1.0 / 30;
    /* a frame is 54 numbers of up to ~17 characters */
    buf_t b = {NULL, 0, 4096 + (n < 1000000 ? (size_t)n * 600 : 0), 0};
    if (!(b.p = malloc(b.cap))) return NULL;
    const double *p0 = pairs + 3 * NJ * person;
    put(&b, "HIERARCHY\n");
    joint(&b, p0, 0, 0);
    put(&b, "MOTION\nFrames: %u\nFrame Time: %.10g\n", (unsigned)n, frame_time);
    for (uint32_t f = 0; f < n && !b.oom; f++) frame(&b, pairs + (size_t)f * 3 * MIM_PAIR_JOINTS + 3 * NJ * person, p0);
    if (b.oom) {
        free(b.p);
        return NULL;
    }
    return b.p;
}
