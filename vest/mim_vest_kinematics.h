/* mimic vest, the body: the 17 segments of the PrioVR full-body kit, the
 * skeleton estimated from an avatar, calibration (rest / T / A pose) into a
 * rig, the live state of the sensors, and forward kinematics from sensor
 * orientations to the avatar's landmarks.
 * Implemented by skeleton.c, calibrate.c and kinematics.c.
 *
 * Frames: metres, +Y up, the body faces +Z, its own left is +X (as synth and
 * mh-bodies). A sensor's tared orientation is the rotation of its body
 * segment, in that world frame, since the moment of the tare.
 *
 * Everything here is computation over caller-owned plain data: nothing is
 * allocated, nothing is kept after a call returns. Functions are safe from
 * any thread as long as no other thread writes the same output. */
#ifndef MIM_VEST_KINEMATICS_H
#define MIM_VEST_KINEMATICS_H

#include "mim_core.h"
#include "mim_vest_protocol.h"

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The PrioVR full-body kit: 17 sensors, one per segment; sensor id = the
 * bit index in the hub's active-sensor bitfield = this enum. */
enum {
    MIM_VEST_PELVIS, MIM_VEST_CHEST, MIM_VEST_HEAD,
    MIM_VEST_L_SHOULDER, MIM_VEST_R_SHOULDER,
    MIM_VEST_L_UPPERARM, MIM_VEST_R_UPPERARM,
    MIM_VEST_L_FOREARM, MIM_VEST_R_FOREARM,
    MIM_VEST_L_HAND, MIM_VEST_R_HAND,
    MIM_VEST_L_THIGH, MIM_VEST_R_THIGH,
    MIM_VEST_L_SHIN, MIM_VEST_R_SHIN,
    MIM_VEST_L_FOOT, MIM_VEST_R_FOOT,
    MIM_VEST_SEGMENTS
};
_Static_assert(MIM_VEST_SEGMENTS == MIM_SEGMENTS, "the vest's segments are core's mim_segment_names");
/* "pelvis", ...: a static string; NULL past the end. */
const char *mim_vest_segment_name(uint32_t s);
/* The parent segment (parents have lower ids); -1 for the pelvis and out of range. */
int mim_vest_segment_parent(uint32_t s);

/* ---- skeleton (skeleton.c) ---- */
/* A skeleton estimated from the avatar in its rest pose. */
typedef struct mim_vest_skeleton {
    mim_vec3 pivot[MIM_VEST_SEGMENTS]; /* the joint centre the segment turns about */
    mim_vec3 end[MIM_VEST_SEGMENTS];   /* its distal end */
    double length[MIM_VEST_SEGMENTS];  /* |end - pivot| */
    uint32_t n_landmarks;
    uint32_t segment[MIM_LANDMARKS_MAX];  /* the segment that carries each landmark */
    mim_vec3 landmark[MIM_LANDMARKS_MAX]; /* rest positions */
    mim_vec3 centre[MIM_LANDMARKS_MAX];   /* joint centre estimated under each landmark */
} mim_vest_skeleton_t;

/* Joint centres under the landmarks (midpoint of the chord along the inward
 * normal, bounded per landmark), then pivots and bone lengths. The map needs
 * the 16 default names; other landmarks go to the nearest bone. Costs one
 * ray cast over all faces per landmark. avatar and map are read only during
 * the call. Returns 0; MIM_EINVAL (a NULL argument); MIM_EEMPTY (no vertices
 * or no faces); mim_landmarks_validate's codes (MIM_EFORMAT, MIM_EINDEX,
 * MIM_ETOPOLOGY); MIM_ENOLANDMARKS (a default name missing); MIM_EFORMAT (no
 * height along +Y). On failure *sk may be partly written. */
int mim_vest_skeleton_estimate(mim_vest_skeleton_t *sk, const mim_mesh_t *avatar, const mim_landmark_map_t *map,
                               mim_error_t *err);

/* The 17 bones of a skeleton as 17 x 6 doubles (pivot x y z, end x y z),
 * segment order: what mim_xfer_skin_from_bones segments an avatar by. */
void mim_vest_skeleton_bones(const mim_vest_skeleton_t *sk, double bones[MIM_VEST_SEGMENTS * 6]);
/* ---- a rig's joint names (segment_names.c) ---- */
/* The segment a rig joint named `name` turns (the bone from it to its
 * child; segment_names.c lists the names recognised), or -1.
 * shoulder_is_upperarm: the rig names its clavicle "collar" (SMPL), so a
 * sided "shoulder" is the upper arm. */
int mim_vest_segment_of_joint(const char *name, int shoulder_is_upperarm);
/* The same for a rig's n joints into segment[n], deciding
 * shoulder_is_upperarm from the names; returns how many distinct segments
 * the rig covers. */
uint32_t mim_vest_segments_of_joints(const char *const *names, uint32_t n, int *segment);
/* ---- calibration (calibrate.c) ---- */
enum {
    MIM_VEST_POSE_REST = 0, /* the wearer stands as the avatar mesh does */
    MIM_VEST_POSE_T,        /* arms straight out sideways */
    MIM_VEST_POSE_A         /* arms straight, 45 degrees from vertical */
};

typedef struct mim_vest_calib_options {
    int pose; /* MIM_VEST_POSE_*; 0 = rest */
} mim_vest_calib_options_t;

/* Everything forward kinematics needs; plain data (copy it freely). */
typedef struct mim_vest_rig {
    mim_vec3 root;                            /* pelvis pivot (IMUs give no translation) */
    mim_vec3 joint[MIM_VEST_SEGMENTS];        /* pivot - parent pivot, rest frame */
    mim_quat calib[MIM_VEST_SEGMENTS];        /* segment rotation rest -> calibration pose */
    mim_quat tare_inv[MIM_VEST_SEGMENTS];     /* inverse of the reading at the tare (software tare) */
    uint32_t n_landmarks;
    uint32_t segment[MIM_LANDMARKS_MAX];
    mim_vec3 offset[MIM_LANDMARKS_MAX];       /* landmark - pivot, in its bone's rest frame */
} mim_vest_rig_t;

/* Builds the rig for a wearer standing in opt->pose (opt NULL = rest) at the
 * tare. tare: the 17 readings at that moment for a software tare, or NULL
 * when the device was tared (command 0x60); read during the call only.
 * Returns 0; MIM_EINVAL (rig or sk NULL, unknown pose, more than
 * MIM_LANDMARKS_MAX landmarks, a landmark on no segment); MIM_ENONFINITE (a
 * tare reading not finite); MIM_EFORMAT (an arm segment of zero length, T or
 * A pose). On failure *rig may be partly written. */
int mim_vest_calibrate(mim_vest_rig_t *rig, const mim_vest_skeleton_t *sk, const mim_vest_calib_options_t *opt,
                       const mim_quat tare[MIM_VEST_SEGMENTS], mim_error_t *err);

/* ---- segment orientations (kinematics.c) ---- */
/* The rotation of each segment from the avatar's rest pose (R_s of
 * kinematics.c: the tared reading after the calibration), for the
 * orientation drive. have may be NULL (all); a missing one is identity. */
void mim_vest_segment_rotations(const mim_vest_rig_t *rig, const mim_quat q[MIM_VEST_SEGMENTS], const uint8_t *have,
                                mim_quat R[MIM_VEST_SEGMENTS]);
/* Lost sensors take a neighbour's rotation (issue 17's first fallback):
 * a segment without have[s] gets its parent's (after the parent's own
 * fill), the pelvis the chest's. from[s] (may be NULL) gets the segment
 * whose reading it holds, or -1 when there was none (the pelvis and chest
 * both lost: the chest's subtree keeps what it has, identity where lost).
 * R and have must not be NULL. Returns the number of segments filled. */
uint32_t mim_vest_rotations_fill(mim_quat R[MIM_VEST_SEGMENTS], const uint8_t have[MIM_VEST_SEGMENTS],
                                 int8_t from[MIM_VEST_SEGMENTS]);
/* ---- live state and forward kinematics (kinematics.c) ---- */
/* The latest orientation of each sensor and when it came; plain data. */
typedef struct mim_vest_state {
    mim_quat q[MIM_VEST_SEGMENTS];
    uint64_t t_us[MIM_VEST_SEGMENTS];
    uint8_t seen[MIM_VEST_SEGMENTS];
} mim_vest_state_t;
/* Identity orientations, nothing seen. NULL is a no-op. */
void mim_vest_state_reset(mim_vest_state_t *st);
/* Records one decoded frame; ignores NULL arguments and sensor ids >= 17. */
void mim_vest_state_update(mim_vest_state_t *st, const mim_vest_frame_t *f);

#define MIM_VEST_TIMEOUT_US_DEFAULT 250000u

/* Which sensors are fresh at now_us (have[s] 1): seen, and not silent for
 * more than timeout_us (0 = default; a reading later than now_us counts as
 * fresh). mim_vest_fk's rule. */
void mim_vest_fresh(const mim_vest_state_t *st, uint64_t now_us, uint64_t timeout_us, uint8_t have[MIM_VEST_SEGMENTS]);
/* Landmarks at now_us from the latest orientations: a sensor never seen, or
 * silent for more than timeout_us (0 = default; a reading later than now_us
 * counts as fresh), makes the landmarks of its segment and of the segments
 * below it missing: NaN and present 0. rig, st and xyz must not be NULL
 * (not checked); xyz: 3 * rig->n_landmarks floats; present: n_landmarks
 * bytes, or NULL. Returns the number present. */
uint32_t mim_vest_fk(const mim_vest_rig_t *rig, const mim_vest_state_t *st, uint64_t now_us, uint64_t timeout_us,
                     float *xyz, uint8_t *present);
/* The same from given orientations (have[s] = 0: sensor missing; have NULL:
 * all present). Used by mim_vest_fk and by the simulator's expected output. */
uint32_t mim_vest_fk_orient(const mim_vest_rig_t *rig, const mim_quat q[MIM_VEST_SEGMENTS], const uint8_t *have,
                            float *xyz, uint8_t *present);

#ifdef __cplusplus
}
#endif
#endif
