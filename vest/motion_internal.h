/* What the BVH and ASF/AMC readers hand to the shared motion builder. */
#ifndef MIM_VEST_MOTION_INTERNAL_H
#define MIM_VEST_MOTION_INTERNAL_H

#include "mim_vest_motion.h"

#define MIM__MOTION_MAX_JOINTS 1024u
#define MIM__MOTION_MAX_VALUES 200000000ull /* frames x joints */

typedef struct mim__mjoint {
    char name[64];
    int parent;    /* -1 for the root; parents come first */
    mim_vec3 rest; /* rest position of the joint, motion frame */
} mim__mjoint_t;

typedef struct mim__motion_src {
    uint32_t n_joints, n_frames;
    double frame_time;
    mim__mjoint_t *joint;
    mim_quat *local; /* n_frames x n_joints: rotation relative to rest, parent frame */
} mim__motion_src_t;

/* World rotations, sensor mapping by joint name, change of axes to the
 * avatar frame. Does not take ownership of src. */
int mim__motion_build(mim_vest_motion_t *m, const mim__motion_src_t *src, const char *origin, mim_error_t *err);
/* Rotation of `deg` degrees about axis 0 (X), 1 (Y) or 2 (Z). */
mim_quat mim__axis_rot(int axis, double deg);
/* Reads a whole file (malloc'd, NUL-terminated); over 1 GiB is MIM_EFORMAT. */
int mim__read_text(const char *path, char **text, size_t *len, mim_error_t *err);

#endif
