/* What the BVH and ASF/AMC readers hand to the shared builders: the
 * orientation builder (mim__motion_build, motion.c) and the joint-position
 * builder (mim__joint_motion_build, also motion.c). */
#ifndef MIM_VEST_MOTION_INTERNAL_H
#define MIM_VEST_MOTION_INTERNAL_H

#include "mim_vest_motion.h"

#define MIM__MOTION_MAX_JOINTS 1024u
#define MIM__MOTION_MAX_VALUES 200000000ull /* frames x joints */

typedef struct mim__mjoint {
    char name[64];
    int parent;      /* -1 for the root; parents come first */
    mim_vec3 rest;   /* rest position of the joint, motion frame */
    mim_vec3 offset; /* from the parent's rest position (the root: from the origin), parent's rest frame */
} mim__mjoint_t;

typedef struct mim__motion_src {
    uint32_t n_joints, n_frames;
    double frame_time;
    mim__mjoint_t *joint;
    mim_quat *local; /* n_frames x n_joints: rotation relative to rest, parent frame */
    /* n_frames x n_joints: translation added to each joint's offset (the
     * root's position channels, and those of any other joint that has them;
     * zero for joints without). Filled only when the reader was asked for
     * it (joint positions); NULL otherwise. */
    mim_vec3 *trans;
} mim__motion_src_t;

/* World rotations, sensor mapping by joint name, change of axes to the
 * avatar frame. Does not take ownership of src; ignores src->trans. */
int mim__motion_build(mim_vest_motion_t *m, const mim__motion_src_t *src, const char *origin, mim_error_t *err);
/* World position of every joint in every frame: the root at offset + trans,
 * each child at its parent's position plus the parent's world rotation
 * applied to (offset + trans). src->trans NULL counts as zero. Does not take
 * ownership of src; on failure *m is zeroed. */
int mim__joint_motion_build(mim_vest_joint_motion_t *m, const mim__motion_src_t *src, const char *origin,
                            mim_error_t *err);
/* Parses BVH text into src (joints, and per-frame local rotations; with
 * translations != 0 also src->trans). On success the caller frees src with
 * mim__motion_src_free; on failure nothing is left to free (src zeroed).
 * Errors as mim_vest_motion_parse_bvh, naming origin and line. */
int mim__bvh_parse(mim__motion_src_t *src, const char *text, size_t len, const char *origin, int translations,
                   mim_error_t *err);
/* Reads ASF + AMC into src the same way (translations from the AMC's
 * tx/ty/tz dofs). */
int mim__amc_read(mim__motion_src_t *src, const char *asf_path, const char *amc_path, int translations,
                  mim_error_t *err);
/* Frees src's arrays and zeroes it. Accepts a zeroed src. */
void mim__motion_src_free(mim__motion_src_t *src);
/* Rotation of `deg` degrees about axis 0 (X), 1 (Y) or 2 (Z). */
mim_quat mim__axis_rot(int axis, double deg);
/* Reads a whole file (malloc'd, NUL-terminated); over 1 GiB is MIM_EFORMAT. */
int mim__read_text(const char *path, char **text, size_t *len, mim_error_t *err);

#endif
