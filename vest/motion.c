/* Motion data to tared sensor orientations. Each segment's orientation is
 * the world rotation of its motion joint relative to the rest pose (all
 * channels zero): what a sensor tared in that pose reports. The motion's
 * up and left axes are read off its rest pose (head above pelvis, left hip
 * beside right hip) and mapped to mimic's +Y and +X.
 * The joint-position builder (mim__joint_motion_build) works on the same
 * reader output and keeps the motion's translation, units and axes. */
#include "motion_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* Joint names per segment: MakeHuman, common BVH (CMU, Biovision), ASF. */
static const char *const seg_joints[MIM_VEST_SEGMENTS][8] = {
    {"Hips", "pelvis", "root", "Root", NULL},
    {"Spine3", "Chest", "Spine2", "thorax", "upperback", "Spine1", "Spine", NULL},
    {"Head", NULL},
    {"Clavicle_L", "LeftShoulder", "lclavicle", "LeftCollar", NULL},
    {"Clavicle_R", "RightShoulder", "rclavicle", "RightCollar", NULL},
    {"UpArm_L", "LeftArm", "LeftUpArm", "lhumerus", NULL},
    {"UpArm_R", "RightArm", "RightUpArm", "rhumerus", NULL},
    {"LoArm_L", "LeftForeArm", "LeftLowArm", "lradius", NULL},
    {"LoArm_R", "RightForeArm", "RightLowArm", "rradius", NULL},
    {"Hand_L", "LeftHand", "lhand", "lwrist", NULL},
    {"Hand_R", "RightHand", "rhand", "rwrist", NULL},
    {"UpLeg_L", "LeftUpLeg", "lfemur", "LeftHip", NULL},
    {"UpLeg_R", "RightUpLeg", "rfemur", "RightHip", NULL},
    {"LoLeg_L", "LeftLeg", "LeftLowLeg", "ltibia", "LeftKnee", NULL},
    {"LoLeg_R", "RightLeg", "RightLowLeg", "rtibia", "RightKnee", NULL},
    {"Foot_L", "LeftFoot", "lfoot", "LeftAnkle", NULL},
    {"Foot_R", "RightFoot", "rfoot", "RightAnkle", NULL},
};

mim_quat mim__axis_rot(int axis, double deg)
{
    mim_vec3 a = mim_v3(axis == 0, axis == 1, axis == 2);
    return mim_quat_axis_angle(a, deg * M_PI / 180.0);
}

int mim__read_text(const char *path, char **text, size_t *len, mim_error_t *err)
{
    const size_t limit = (size_t)1 << 30;
    int rc = mim_file_read(path, limit + 1, text, len, err);
    if (!rc && *len > limit) {
        free(*text);
        *text = NULL;
        rc = mim_error_set(err, MIM_EFORMAT, "%s: motion file over 1 GiB", path);
    }
    return rc;
}

static int find_joint(const mim__motion_src_t *src, uint32_t s)
{
    for (int k = 0; seg_joints[s][k]; k++)
        for (uint32_t j = 0; j < src->n_joints; j++)
            if (!strcasecmp(src->joint[j].name, seg_joints[s][k])) return (int)j;
    return -1;
}

/* The unit vector of a signed axis (mim_axis_*). */
static mim_vec3 axis_vec(int a)
{
    double s = a < 0 ? -1 : 1;
    int k = abs(a);
    return mim_v3(k == 1 ? s : 0, k == 2 ? s : 0, k == 3 ? s : 0);
}

/* Quaternion of the rotation whose matrix has rows r0, r1, r2. */
static mim_quat from_rows(mim_vec3 r0, mim_vec3 r1, mim_vec3 r2)
{
    const double m[9] = {r0.x, r1.x, r2.x, r0.y, r1.y, r2.y, r0.z, r1.z, r2.z}; /* column-major */
    return mim_quat_from_matrix(m);
}

/* The rotation from a motion's axes to the avatar's: rows are the motion's
 * left, up and front axes (avatar = B motion). */
static mim_quat avatar_of(int up, int left)
{
    const mim_vec3 u = axis_vec(up), l = axis_vec(left);
    return from_rows(l, u, mim_v3_cross(l, u));
}

/* m's orientations, now in the frame that `was` turned the file's into (the
 * file's own: identity), turned into the avatar frame of the axes up and
 * left (q -> B q B^-1), and the rest arm's angle from the new vertical. */
static void turn_to_axes(mim_vest_motion_t *m, int up, int left, mim_quat was)
{
    const mim_quat B = avatar_of(up, left), wi = {-was.x, -was.y, -was.z, was.w};
    const mim_quat C = mim_quat_mul(B, wi), Ci = {-C.x, -C.y, -C.z, C.w};
    for (size_t i = 0; i < (size_t)m->n_frames * MIM_VEST_SEGMENTS; i++) {
        mim_quat q = mim_quat_normalize(mim_quat_mul(mim_quat_mul(C, m->q[i]), Ci));
        if (q.w < 0) q.x = -q.x, q.y = -q.y, q.z = -q.z, q.w = -q.w; /* one sign per rotation */
        m->q[i] = q;
    }
    m->up = up, m->left = left;
    m->rest_arm_deg = -1;
    mim_vec3 d = mim_quat_rotate(B, mim_v3(m->rest_arm[0], m->rest_arm[1], m->rest_arm[2]));
    double n = mim_v3_norm(d);
    if (n > 0) m->rest_arm_deg = acos(fmax(-1, fmin(1, -d.y / n))) * 180 / M_PI;
}

int mim__motion_build(mim_vest_motion_t *m, const mim__motion_src_t *src, const char *origin, mim_error_t *err)
{
    memset(m, 0, sizeof *m);
    if (!src->n_joints || !src->n_frames)
        return mim_error_set(err, MIM_EEMPTY, "%s: no joints or no frames", origin);
    int jo[MIM_VEST_SEGMENTS];
    for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
        jo[s] = find_joint(src, s);
        if (jo[s] >= 0) {
            m->have[s] = 1;
            snprintf(m->joint[s], sizeof m->joint[s], "%s", src->joint[jo[s]].name);
        }
    }
    if (jo[MIM_VEST_PELVIS] < 0) { /* the root stands in for the hips */
        jo[MIM_VEST_PELVIS] = 0, m->have[MIM_VEST_PELVIS] = 1;
        snprintf(m->joint[0], sizeof m->joint[0], "%s", src->joint[0].name);
    }
    if (jo[MIM_VEST_HEAD] < 0)
        return mim_error_set(err, MIM_EFORMAT, "%s: no head joint (looked for Head)", origin);
    int l = jo[MIM_VEST_L_THIGH], r = jo[MIM_VEST_R_THIGH];
    if (l < 0 || r < 0) l = jo[MIM_VEST_L_UPPERARM], r = jo[MIM_VEST_R_UPPERARM];
    if (l < 0 || r < 0)
        return mim_error_set(err, MIM_EFORMAT, "%s: no left/right hip or arm joints to find the body's left", origin);
    const int up = mim_axis_snap(mim_v3_sub(src->joint[jo[MIM_VEST_HEAD]].rest, src->joint[jo[MIM_VEST_PELVIS]].rest), 0);
    const int left = mim_axis_snap(mim_v3_sub(src->joint[l].rest, src->joint[r].rest), 0);
    if (!up || !left || abs(up) == abs(left))
        return mim_error_set(err, MIM_EFORMAT, "%s: cannot tell up from left in the rest pose", origin);
    /* how the rest pose holds the arms: the pose the wearer tared in */
    int sh = jo[MIM_VEST_L_UPPERARM], el = jo[MIM_VEST_L_FOREARM];
    if (sh >= 0 && el >= 0) {
        mim_vec3 d = mim_v3_sub(src->joint[el].rest, src->joint[sh].rest);
        m->rest_arm[0] = d.x, m->rest_arm[1] = d.y, m->rest_arm[2] = d.z;
    }
    m->n_frames = src->n_frames;
    m->frame_time = src->frame_time > 0 ? src->frame_time : 1.0 / 30;
    m->q = malloc(sizeof *m->q * MIM_VEST_SEGMENTS * src->n_frames);
    mim_quat *W = malloc(sizeof *W * src->n_joints);
    if (!m->q || !W) {
        free(W), mim_vest_motion_free(m);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
    }
    for (uint32_t f = 0; f < src->n_frames; f++) {
        const mim_quat *L = src->local + (size_t)f * src->n_joints;
        for (uint32_t j = 0; j < src->n_joints; j++) {
            int p = src->joint[j].parent;
            W[j] = p < 0 ? L[j] : mim_quat_mul(W[p], L[j]);
        }
        for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) /* the file's axes here; turned below */
            m->q[(size_t)f * MIM_VEST_SEGMENTS + s] = jo[s] >= 0 ? W[jo[s]] : mim_quat_identity();
    }
    free(W);
    turn_to_axes(m, up, left, mim_quat_identity());
    return 0;
}

int mim_vest_motion_set_up(mim_vest_motion_t *m, int up, mim_error_t *err)
{
    if (!m || !m->q || !m->left || up < -3 || up > 3 || !up)
        return mim_error_set(err, MIM_EINVAL, "no motion, or no up axis");
    if (abs(up) == abs(m->left))
        return mim_error_set(err, MIM_EFORMAT, "up %s is the motion's left-right axis (its hips or shoulders lie along it)",
                             mim_axis_name(up));
    turn_to_axes(m, up, m->left, avatar_of(m->up, m->left));
    return 0;
}

/* Forward kinematics with translation: P_root = offset + t, P_j = P_parent +
 * W_parent (offset_j + t_j), W_j = W_parent L_j; in the motion's own units
 * and axes (no change of axes, unlike mim__motion_build). */
int mim__joint_motion_build(mim_vest_joint_motion_t *m, const mim__motion_src_t *src, const char *origin,
                            mim_error_t *err)
{
    memset(m, 0, sizeof *m);
    if (!src->n_joints || !src->n_frames)
        return mim_error_set(err, MIM_EEMPTY, "%s: no joints or no frames", origin);
    uint32_t n = src->n_joints;
    m->name = malloc(sizeof *m->name * n);
    m->parent = malloc(sizeof *m->parent * n);
    m->positions = malloc(sizeof *m->positions * 3 * n * (size_t)src->n_frames);
    m->rest = malloc(sizeof *m->rest * 3 * n);
    mim_quat *W = malloc(sizeof *W * n);
    mim_vec3 *P = malloc(sizeof *P * n);
    if (!m->name || !m->parent || !m->positions || !m->rest || !W || !P) {
        free(W), free(P), mim_vest_joint_motion_free(m);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %u frames", origin, src->n_frames);
    }
    m->n_joints = n, m->n_frames = src->n_frames;
    m->frame_time = src->frame_time > 0 ? src->frame_time : 1.0 / 30;
    for (uint32_t j = 0; j < n; j++) {
        snprintf(m->name[j], sizeof m->name[j], "%s", src->joint[j].name);
        m->parent[j] = src->joint[j].parent;
        const mim_vec3 r = src->joint[j].rest;
        m->rest[3 * j] = (float)r.x, m->rest[3 * j + 1] = (float)r.y, m->rest[3 * j + 2] = (float)r.z;
    }
    for (uint32_t f = 0; f < src->n_frames; f++) {
        const mim_quat *L = src->local + (size_t)f * n;
        const mim_vec3 *T = src->trans ? src->trans + (size_t)f * n : NULL;
        float *out = m->positions + (size_t)f * n * 3;
        for (uint32_t j = 0; j < n; j++) {
            int p = src->joint[j].parent;
            mim_vec3 d = T ? mim_v3_add(src->joint[j].offset, T[j]) : src->joint[j].offset;
            if (p < 0) {
                W[j] = L[j], P[j] = d;
            } else {
                W[j] = mim_quat_mul(W[p], L[j]);
                P[j] = mim_v3_add(P[p], mim_quat_rotate(W[p], d));
            }
            out[3 * j] = (float)P[j].x, out[3 * j + 1] = (float)P[j].y, out[3 * j + 2] = (float)P[j].z;
        }
    }
    free(W), free(P);
    return 0;
}

void mim__motion_src_free(mim__motion_src_t *src)
{
    free(src->joint), free(src->local), free(src->trans);
    memset(src, 0, sizeof *src);
}

void mim_vest_joint_motion_free(mim_vest_joint_motion_t *m)
{
    if (!m) return;
    free(m->name), free(m->parent), free(m->positions), free(m->rest);
    memset(m, 0, sizeof *m);
}

void mim_vest_motion_free(mim_vest_motion_t *m)
{
    if (!m) return;
    free(m->q);
    memset(m, 0, sizeof *m);
}

void mim_vest_motion_sample(const mim_vest_motion_t *m, double t, mim_quat q[MIM_VEST_SEGMENTS])
{
    double x = m->frame_time > 0 ? t / m->frame_time : 0;
    if (!(x > 0)) x = 0;
    uint32_t last = m->n_frames ? m->n_frames - 1 : 0;
    if (x >= last) x = last;
    uint32_t f0 = (uint32_t)x, f1 = f0 < last ? f0 + 1 : f0;
    double a = x - f0;
    for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
        mim_quat A = m->q[(size_t)f0 * MIM_VEST_SEGMENTS + s], Bq = m->q[(size_t)f1 * MIM_VEST_SEGMENTS + s];
        q[s] = a > 0 ? mim_quat_slerp(A, Bq, a) : A;
    }
}
