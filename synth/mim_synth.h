/* mimic synth: a procedural generator of human-like bodies with exact ground
 * truth (DESIGN.md "Data to work with"). Several subjects x several poses on
 * ONE connectivity: a closed, outward-oriented genus-0 triangle surface.
 *
 * Conventions: metres, +Y up, the body faces +Z, the body's own left is +X,
 * triangles counter-clockwise seen from outside (as data/mh-bodies).
 * Every body stands with its lowest vertex at y = 0; the pelvis joint (the
 * skeleton's root, midway between the hip joints) stays at x = z = 0.
 *
 * Subject s, pose p: the subject's shape (height 1.52..1.93 m, limb lengths
 * and girths, shoulder/hip width, chest and belly depth) comes from the seed
 * and s; pose p means the same joint rotations for every subject: 0 is the
 * rest pose (an A-pose, identity rotations), 1..11 a table of designed poses
 * (see mim_synth_pose_name), 12.. seeded random poses within joint limits.
 * The same options give byte-identical output. */
#ifndef MIM_SYNTH_H
#define MIM_SYNTH_H

#include "mim_core.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mim_synth_options {
    uint32_t subjects; /* 0 means 4 */
    uint32_t poses;    /* 0 means 12 (pose 0 = rest) */
    uint32_t vertices; /* approximate vertex count (500..200000), 0 means 7000 */
    uint64_t seed;     /* any value; the CLI default is 1 */
    /* Imitation (issue 29): each subject takes each pose but the rest its
     * own way: every joint axis with a range turned by a Gaussian angle of
     * this standard deviation (degrees; seeded by subject and pose; kept in
     * the joint's limits). Real people imitating one pose differ by about
     * 11 degrees rms per bone; 0 (the default): every subject takes the
     * designed angles exactly, as one shared rig would. */
    double imitation_deg;
    /* Pose-dependent soft tissue (issue 29): each (subject, pose) its own
     * smooth bulges along the surface, heights of this standard deviation
     * (mm; synth/tissue.c), so that one subject's change of surface from
     * rest to a pose is not another's. 0 (the default): none. */
    double tissue_mm;
    /* Registration's error (issue 29): each (subject, pose)'s vertices slid
     * along the surface by a smooth field of this standard deviation (mm),
     * as a store of registered scans holds them. 0 (the default): none. */
    double slide_mm;
} mim_synth_options_t;

#define MIM_SYNTH_DEFAULT_SUBJECTS 4u
#define MIM_SYNTH_DEFAULT_POSES 12u
#define MIM_SYNTH_DEFAULT_VERTICES 7000u
#define MIM_SYNTH_MIN_VERTICES 500u
#define MIM_SYNTH_MAX_VERTICES 200000u
#define MIM_SYNTH_MAX_SUBJECTS 100000u
#define MIM_SYNTH_MAX_POSES 100000u

typedef struct mim_synth mim_synth_t; /* opaque */

/* Builds the shared connectivity and landmark map. opt may be NULL (defaults).
 * Returns 0, or MIM_EINVAL (options out of range) / MIM_ENOMEM. */
int mim_synth_create(mim_synth_t **out, const mim_synth_options_t *opt, mim_error_t *err);
void mim_synth_destroy(mim_synth_t **s); /* accepts NULL / *s NULL, nulls the pointer */

uint32_t mim_synth_n_vertices(const mim_synth_t *s);
uint32_t mim_synth_n_faces(const mim_synth_t *s);
uint32_t mim_synth_n_subjects(const mim_synth_t *s);
uint32_t mim_synth_n_poses(const mim_synth_t *s);
const uint32_t *mim_synth_faces(const mim_synth_t *s); /* 3 * n_faces, valid until destroy */

/* Positions of subject `subject` in pose `pose`: the caller gives
 * 3 * n_vertices floats. Thread-safe (no shared mutable state).
 * Returns 0, MIM_EINVAL (index out of range, NULL) or MIM_ENOMEM. */
int mim_synth_body(const mim_synth_t *s, uint32_t subject, uint32_t pose, float *positions);

/* The skeleton: mim_synth_n_joints joints (19), parents listed before children. */
uint32_t mim_synth_n_joints(const mim_synth_t *s);
const char *mim_synth_joint_name(const mim_synth_t *s, uint32_t j); /* NULL if out of range */
/* Parent joint index, or -1 for the root (pelvis) and out-of-range j. */
int mim_synth_joint_parent(const mim_synth_t *s, uint32_t j);
/* Joint positions (world, posed, in the same frame as mim_synth_body) of
 * subject/pose: the caller gives 3 * mim_synth_n_joints floats. */
int mim_synth_joints(const mim_synth_t *s, uint32_t subject, uint32_t pose, float *joints);

/* The 16 default landmarks (mim_landmarks_default order), each a vertex. */
void mim_synth_landmarks(const mim_synth_t *s, mim_landmark_map_t *map);

/* "rest", "tpose", "arms_up", ..., then "random12", "random13", ...; NULL if
 * pose >= mim_synth_n_poses. The string lives as long as s. */
const char *mim_synth_pose_name(const mim_synth_t *s, uint32_t pose);

/* File name of a body: "synth_s%02u_p%02u.ply" (3+ digits when > 99). */
void mim_synth_file_name(uint32_t subject, uint32_t pose, char *buf, size_t size);

/* Writes the dataset into dir (created, with its parents, if missing): one
 * binary little-endian PLY per body (header: ply / format
 * binary_little_endian 1.0 / comment mimic synth seed=K / element vertex N /
 * property float x,y,z / element face F / property list uchar int
 * vertex_indices / end_header), manifest.csv (`file,subject,pose,pose_name`)
 * and landmarks.json (mim_landmarks_write). Each file is written atomically
 * (mim_file_write_atomic), so a killed run leaves no half-written file, and
 * the manifest and landmark map last. Progress goes to the callback set by
 * mim_synth_set_progress (label "synth", one step a body). Returns 0 or a
 * negative code with a one-line message in err (-errno when a folder cannot
 * be made, MIM_EIO when a file cannot be written). */
int mim_synth_write_dataset(const mim_synth_t *s, const char *dir, mim_error_t *err);
/* The progress callback of mim_synth_write_dataset; fn NULL (the default)
 * is quiet. */
void mim_synth_set_progress(mim_synth_t *s, mim_progress_fn fn, void *ctx);

#ifdef __cplusplus
}
#endif
#endif
