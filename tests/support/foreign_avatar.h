/* A foreign avatar for the tests of issue 13 (test_serve_avatar.c, and
 * tests/viewer_test.mjs through tests/make_foreign_avatar.c): a synth body
 * that is in no store made from the other options (another seed, or a
 * subject the store leaves out), re-triangulated so that its connectivity
 * is not the store's: midpoint subdivision (rt_subdivide, which keeps every
 * original vertex where it was) some times, then its vertices and faces
 * shuffled (rt_shuffle). Its landmark positions are those of the body's
 * landmark vertices, in the order of mim_synth_landmarks (the order of the
 * landmarks.json `mimic synth` writes, so of a store made from it).
 * No cmocka, no output: callers check what they need. */
#ifndef MIM_TEST_FOREIGN_AVATAR_H
#define MIM_TEST_FOREIGN_AVATAR_H

#include "mim_core.h"

#include <stddef.h>
#include <stdint.h>

typedef struct fa_options {
    uint32_t vertices;     /* the synth body's (mim_synth_options_t); 0: 2000 */
    uint32_t subjects;     /* of the synth; 0: subject + 1 */
    uint32_t subject, pose; /* which body (pose 0: rest) */
    uint64_t seed;         /* the synth's seed; 0 means 1 (as the CLI) */
    uint32_t subdivisions; /* rt_subdivide this many times */
    uint64_t shuffle_seed; /* rt_shuffle's; 0: no shuffle */
    uint32_t copies;       /* 0 or 1: one body; 2: two copies side by side, 1 m apart in x, not joined */
} fa_options_t;

typedef struct fa_avatar {
    mim_mesh_t mesh;             /* the avatar (mim_mesh_free) */
    uint32_t body_vertices;      /* the synth body's vertex count before re-triangulation */
    uint32_t n_landmarks;        /* 16 */
    float landmarks[3 * MIM_LANDMARKS_MAX]; /* positions, in mim_synth_landmarks' order */
    uint32_t landmark_vertex[MIM_LANDMARKS_MAX]; /* the avatar's vertex at each landmark (exactly there) */
    char names[MIM_LANDMARKS_MAX][MIM_LANDMARK_NAME_MAX];
} fa_avatar_t;

/* 0, or a negative MIM_E* code with why (one line). */
int fa_make(const fa_options_t *opt, fa_avatar_t *out, char *why, size_t why_size);
void fa_free(fa_avatar_t *a);
/* Writes the mesh to path (any mim_io_write_mesh format) and, when
 * sidecar_path is not NULL, its landmark positions there as
 * {"landmarks": [[x, y, z], ...]}; null_at >= 0 writes that landmark as
 * null instead (a lost one). 0, or a negative code with why. */
int fa_write(const fa_avatar_t *a, const char *path, const char *sidecar_path, int null_at, char *why,
             size_t why_size);

#endif
