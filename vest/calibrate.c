/* Calibration: the wearer stands in a known pose (T, A, or the avatar's own
 * rest pose) and the sensors are tared. From then on a sensor's reading is
 * the rotation of its segment since that moment, so the rig records, per
 * segment, the rotation from the avatar's rest pose to the calibration pose,
 * and per landmark its offset from its segment's pivot in the bone's rest
 * frame. Forward kinematics (kinematics.c) then places the landmarks in the
 * avatar's proportions, as seed 000 (sec. 3.2) maps tracked landmarks into
 * the avatar's mesh space. */
#include "mim_vest_kinematics.h"

#include <math.h>
#include <string.h>

static mim_quat qconj(mim_quat q) { mim_quat r = {-q.x, -q.y, -q.z, q.w}; return r; }

/* The shortest rotation taking unit direction a to unit direction b. */
static mim_quat arc(mim_vec3 a, mim_vec3 b)
{
    a = mim_v3_normalize(a), b = mim_v3_normalize(b);
    double d = mim_v3_dot(a, b);
    if (d < -1 + 1e-12) { /* opposite: turn about any axis across a */
        mim_vec3 ax = mim_v3_cross(a, mim_v3(1, 0, 0));
        if (mim_v3_norm(ax) < 1e-6) ax = mim_v3_cross(a, mim_v3(0, 1, 0));
        return mim_quat_axis_angle(mim_v3_normalize(ax), M_PI);
    }
    mim_vec3 c = mim_v3_cross(a, b);
    mim_quat q = {c.x, c.y, c.z, 1 + d};
    return mim_quat_normalize(q);
}

int mim_vest_calibrate(mim_vest_rig_t *rig, const mim_vest_skeleton_t *sk, const mim_vest_calib_options_t *opt,
                       const mim_quat tare[MIM_VEST_SEGMENTS], mim_error_t *err)
{
    if (!rig || !sk) return mim_error_set(err, MIM_EINVAL, "vest calibrate: missing rig or skeleton");
    int pose = opt ? opt->pose : MIM_VEST_POSE_REST;
    if (pose < MIM_VEST_POSE_REST || pose > MIM_VEST_POSE_A)
        return mim_error_set(err, MIM_EINVAL, "vest calibrate: unknown calibration pose %d", pose);
    if (sk->n_landmarks > MIM_LANDMARKS_MAX)
        return mim_error_set(err, MIM_EINVAL, "vest calibrate: %u landmarks (at most %d)", sk->n_landmarks,
                             MIM_LANDMARKS_MAX);
    memset(rig, 0, sizeof *rig);
    rig->root = sk->pivot[MIM_VEST_PELVIS];
    for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
        int p = mim_vest_segment_parent(s);
        rig->joint[s] = p < 0 ? mim_v3(0, 0, 0) : mim_v3_sub(sk->pivot[s], sk->pivot[p]);
        rig->calib[s] = mim_quat_identity();
        if (tare) {
            mim_quat t = mim_quat_normalize(tare[s]);
            if (!isfinite(t.x) || !isfinite(t.y) || !isfinite(t.z) || !isfinite(t.w))
                return mim_error_set(err, MIM_ENONFINITE, "vest calibrate: tare reading of %s is not finite",
                                     mim_vest_segment_name(s));
            rig->tare_inv[s] = qconj(t);
        } else {
            rig->tare_inv[s] = mim_quat_identity();
        }
    }
    if (pose != MIM_VEST_POSE_REST) {
        /* straight arms: out sideways (T) or 45 degrees down (A); the
         * clavicles, torso and legs stay as the avatar has them */
        double a = pose == MIM_VEST_POSE_T ? M_PI / 2 : M_PI / 4;
        for (int side = 0; side < 2; side++) {
            double sx = side == 0 ? 1 : -1; /* the body's own left is +X */
            mim_vec3 target = mim_v3(sx * sin(a), -cos(a), 0);
            static const int arm[3] = {MIM_VEST_L_UPPERARM, MIM_VEST_L_FOREARM, MIM_VEST_L_HAND};
            for (int k = 0; k < 3; k++) {
                int s = arm[k] + side;
                mim_vec3 dir = mim_v3_sub(sk->end[s], sk->pivot[s]);
                if (mim_v3_norm(dir) < 1e-9)
                    return mim_error_set(err, MIM_EFORMAT, "vest calibrate: segment %s has no length",
                                         mim_vest_segment_name((uint32_t)s));
                rig->calib[s] = arc(dir, target);
            }
        }
    }
    rig->n_landmarks = sk->n_landmarks;
    for (uint32_t i = 0; i < sk->n_landmarks; i++) {
        if (sk->segment[i] >= MIM_VEST_SEGMENTS)
            return mim_error_set(err, MIM_EINVAL, "vest calibrate: landmark %u on segment %u", i, sk->segment[i]);
        rig->segment[i] = sk->segment[i];
        rig->offset[i] = mim_v3_sub(sk->landmark[i], sk->pivot[sk->segment[i]]);
    }
    return 0;
}
