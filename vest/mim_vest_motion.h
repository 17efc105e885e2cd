/* mimic vest, motion data: BVH and ASF/AMC motion files turned into the
 * tared orientations a vest would report, or into world joint positions
 * (mim_vest_joint_motion_t), and the built-in demo motion.
 * Implemented by motion.c (the shared builder, sampling), motion_bvh.c,
 * motion_amc.c and motion_demo.c.
 *
 * A loaded motion is plain data plus one malloc'd array (q): read-only use
 * from many threads is safe. The readers only read the files they are given. */
#ifndef MIM_VEST_MOTION_H
#define MIM_VEST_MOTION_H

#include "mim_core.h"
#include "mim_vest_kinematics.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mim_vest_motion {
    uint32_t n_frames;
    double frame_time;                      /* seconds */
    uint8_t have[MIM_VEST_SEGMENTS];        /* segments the motion drives */
    mim_quat *q;                            /* n_frames x 17 tared orientations, avatar frame; malloc'd */
    char joint[MIM_VEST_SEGMENTS][64];      /* the motion joint behind each segment */
    double rest_arm_deg; /* upper arms from vertical in the rest pose (T ~90, A ~45), -1 unknown */
    int up, left;        /* the file's axes taken as the avatar's +y and +x (mim_axis_*) */
    double rest_arm[3];  /* the left upper arm's rest direction, the file's axes (0 0 0 unknown) */
} mim_vest_motion_t;

/* BVH (HIERARCHY/MOTION), or ASF skeleton + AMC motion (taken as 120 Hz, as
 * CMU captures). Each segment's orientation is its world rotation relative
 * to the motion's rest pose (all channels zero), turned into the avatar frame
 * (up and left axes found from the rest pose). Segments the motion lacks
 * stay at identity with have[s] = 0; the root stands in for a missing pelvis.
 *
 * On success *m owns m->q: free it with mim_vest_motion_free. On failure
 * nothing is left to free: *m is zeroed or partly filled with m->q NULL, or
 * left untouched when read_bvh cannot read its file or parse_bvh rejects
 * its arguments.
 * Returns 0, or: reading a file: -errno (cannot open), MIM_EIO, MIM_ENOMEM,
 * MIM_EFORMAT (over 1 GiB); parsing: MIM_EFORMAT (syntax, counts, limits, no
 * head joint, no left/right hip or arm pair, up and left not told apart),
 * MIM_ETRUNCATED (BVH text ends early), MIM_EEMPTY (no joints or frames),
 * MIM_ENOMEM. err names the file and line. */
int mim_vest_motion_read_bvh(mim_vest_motion_t *m, const char *path, mim_error_t *err);
int mim_vest_motion_read_amc(mim_vest_motion_t *m, const char *asf_path, const char *amc_path, mim_error_t *err);
/* The motion turned as if its file's up axis were `up` (mim_axis_*; the
 * readers take the rest pose's head-above-pelvis axis), its left kept:
 * for a file whose rest pose does not stand. 0; MIM_EFORMAT when up lies
 * along the motion's left-right axis; MIM_EINVAL for no motion or no
 * axis. */
int mim_vest_motion_set_up(mim_vest_motion_t *m, int up, mim_error_t *err);
/* Parses BVH text (len bytes, need not be NUL-terminated; read during the
 * call only); origin names it in messages (NULL = "bvh"). Returns as above,
 * and MIM_EINVAL if m is NULL or text is NULL with len > 0. */
int mim_vest_motion_parse_bvh(mim_vest_motion_t *m, const char *text, size_t len, const char *origin,
                              mim_error_t *err);
/* Frees m->q and zeroes *m. Accepts NULL and a zeroed motion. */
void mim_vest_motion_free(mim_vest_motion_t *m);
/* Joint positions (issue 14, two-person pose-pairs): every joint's world
 * position in every frame, with the root's translation kept, in the file's
 * own units and axes (no change to the avatar frame, no taring). The two
 * files of a two-person take that share one world frame give positions in
 * that one frame. End Sites are not joints and are left out.
 *
 * A loaded joint motion is plain data in four malloc'd arrays: read-only
 * use from many threads is safe. */
typedef struct mim_vest_joint_motion {
    uint32_t n_joints, n_frames;
    double frame_time;  /* seconds */
    char (*name)[64];   /* n_joints joint names, as in the file (cut to 63 bytes) */
    int32_t *parent;    /* n_joints; -1 for the root; parents come first */
    float *positions;   /* n_frames * n_joints * 3: world positions, the file's units and axes;
                         * joint j of frame f at positions[3 * (f * n_joints + j)] */
    float *rest;        /* n_joints * 3: the rest pose (every channel zero, the root at its offset),
                         * the file's units and axes: how its author stood the skeleton */
} mim_vest_joint_motion_t;

/* Reads every joint's world position in every frame of a BVH: the root at
 * its OFFSET plus its position channels (kept, unlike
 * mim_vest_motion_read_bvh), each child at its parent's position plus the
 * parent's world rotation applied to its OFFSET. Position channels on a
 * non-root joint (BVH allows them) are added to that joint's OFFSET in that
 * frame. A channel Xposition gives x wherever it is listed.
 * The file's text is parsed by the same code as mim_vest_motion_read_bvh,
 * with the same limits and errors (naming the file and line), except that
 * no particular joints are needed (no head, hips or arms). On success *m
 * owns its arrays: free them with mim_vest_joint_motion_free. On error *m is
 * zeroed (when m is not NULL) and nothing is left to free. Returns 0, or as
 * mim_vest_motion_read_bvh / _parse_bvh (MIM_EINVAL for a NULL m or path,
 * or text NULL with len > 0). */
int mim_vest_joint_motion_read_bvh(mim_vest_joint_motion_t *m, const char *path, mim_error_t *err);
int mim_vest_joint_motion_parse_bvh(mim_vest_joint_motion_t *m, const char *text, size_t len, const char *origin,
                                    mim_error_t *err);
/* ASF skeleton + AMC motion the same way: the root at the ASF's root
 * `position` plus the AMC root's TX TY TZ (tx/ty/tz dofs on other bones are
 * added to their offset likewise); a bone starts where its parent ends
 * (parent direction x length, rotated by the parent's world rotation).
 * Joint 0 is the root ("root"); bones outside the :hierarchy are left out.
 * Frame time as mim_vest_motion_read_amc (1/120 s). Errors as
 * mim_vest_motion_read_amc, and MIM_EFORMAT for an unreadable root position
 * (which the orientation reader does not use). */
int mim_vest_joint_motion_read_amc(mim_vest_joint_motion_t *m, const char *asf_path, const char *amc_path,
                                   mim_error_t *err);
/* The up axis of a joint motion (mim_axis_*): the signed axis along which
 * the head stands above the feet (head, foot_l, foot_r: joint indices). From
 * the rest pose when it stands clearly (head minus the feet's midpoint
 * within ~37 degrees of an axis; *from_rest 1), else from the frames (the
 * mean of that direction over every frame, normalised; *from_rest 0), so a
 * take lying down all along (push-ups) still takes its rest pose's up.
 * 0 when neither tells, or an index is out of range. */
int mim_vest_joint_motion_up(const mim_vest_joint_motion_t *m, int32_t head, int32_t foot_l, int32_t foot_r,
                             int *from_rest);
/* Frees the arrays and zeroes *m. Accepts NULL and a zeroed joint motion. */
void mim_vest_joint_motion_free(mim_vest_joint_motion_t *m);

/* The built-in demo motion (motion_demo.c): eight poses a synth store also
 * holds (rest, T, arms up, wave, reach, squat, walk, bow), 1.5 s each at
 * 30 fps (12 s), T-pose rest. Free with mim_vest_motion_free. Returns 0 or
 * MIM_ENOMEM only. */
int mim_vest_motion_demo(mim_vest_motion_t *m, mim_error_t *err);
/* Orientations at time t seconds (slerp between frames; clamped to the ends,
 * NaN = 0). m must hold at least one frame (not checked). */
void mim_vest_motion_sample(const mim_vest_motion_t *m, double t, mim_quat q[MIM_VEST_SEGMENTS]);

#ifdef __cplusplus
}
#endif
#endif
