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

/* The signed unit axis nearest to v. */
static int snap(mim_vec3 v, mim_vec3 *out)
{
    double a[3] = {v.x, v.y, v.z};
    int k = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(a[i]) > fabs(a[k])) k = i;
    if (!(fabs(a[k]) > 0)) {
        *out = mim_v3(0, 0, 0); /* written on every path: no caller reads an unset axis */
        return -1;
    }
    double s = a[k] > 0 ? 1 : -1;
    *out = mim_v3(k == 0 ? s : 0, k == 1 ? s : 0, k == 2 ? s : 0);
    return k;
}

/* Quaternion of the rotation whose matrix has rows r0, r1, r2. */
static mim_quat from_rows(mim_vec3 r0, mim_vec3 r1, mim_vec3 r2)
{
    const double m[9] = {r0.x, r1.x, r2.x, r0.y, r1.y, r2.y, r0.z, r1.z, r2.z}; /* column-major */
    return mim_quat_from_matrix(m);
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
    mim_vec3 up, left;
    int ku = snap(mim_v3_sub(src->joint[jo[MIM_VEST_HEAD]].rest, src->joint[jo[MIM_VEST_PELVIS]].rest), &up);
    int kl = snap(mim_v3_sub(src->joint[l].rest, src->joint[r].rest), &left);
    if (ku < 0 || kl < 0 || ku == kl)
        return mim_error_set(err, MIM_EFORMAT, "%s: cannot tell up from left in the rest pose", origin);
    /* avatar = B motion: rows are the motion's left, up and front axes */
    mim_quat B = from_rows(left, up, mim_v3_cross(left, up));
    mim_quat Bi = {-B.x, -B.y, -B.z, B.w};

    /* how the rest pose holds the arms: the pose the wearer tared in */
    m->rest_arm_deg = -1;
    int sh = jo[MIM_VEST_L_UPPERARM], el = jo[MIM_VEST_L_FOREARM];
    if (sh >= 0 && el >= 0) {
        mim_vec3 d = mim_quat_rotate(B, mim_v3_sub(src->joint[el].rest, src->joint[sh].rest));
        double n = mim_v3_norm(d);
        if (n > 0) m->rest_arm_deg = acos(fmax(-1, fmin(1, -d.y / n))) * 180 / M_PI;
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
        for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
            mim_quat q = jo[s] >= 0 ? mim_quat_mul(mim_quat_mul(B, W[jo[s]]), Bi) : mim_quat_identity();
            q = mim_quat_normalize(q);
            if (q.w < 0) q.x = -q.x, q.y = -q.y, q.z = -q.z, q.w = -q.w; /* one sign per rotation */
            m->q[(size_t)f * MIM_VEST_SEGMENTS + s] = q;
        }
    }
    free(W);
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
    mim_quat *W = malloc(sizeof *W * n);
    mim_vec3 *P = malloc(sizeof *P * n);
    if (!m->name || !m->parent || !m->positions || !W || !P) {
        free(W), free(P), mim_vest_joint_motion_free(m);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %u frames", origin, src->n_frames);
    }
    m->n_joints = n, m->n_frames = src->n_frames;
    m->frame_time = src->frame_time > 0 ? src->frame_time : 1.0 / 30;
    for (uint32_t j = 0; j < n; j++) {
        snprintf(m->name[j], sizeof m->name[j], "%s", src->joint[j].name);
        m->parent[j] = src->joint[j].parent;
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
    free(m->name), free(m->parent), free(m->positions);
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
