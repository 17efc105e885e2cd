/* The hard recognition set (issue 15): synth subjects in many nearby poses.
 * Shared by bench_query_accuracy (the full run) and the test suite (a small
 * run, tests/test_index_hard.c). */
#ifndef MIM_BENCH_HARD_SET_H
#define MIM_BENCH_HARD_SET_H

#include "mim_core.h"

/* Pose p is designed pose base[p / VARIANTS] (rest, walk, wave, reach,
 * guard, in that order, cycling) with variant p % VARIANTS: 0 the base
 * itself, 1..7 the base with one or two joints turned by 12-20 degrees
 * (an elbow, a shoulder, the spine, the neck, a hip and knee, both
 * shoulders, a knee and hip). Rest and rest with both arms 12 degrees
 * forward are the "two neutral standing poses" of the issue, a few cm apart
 * at most landmarks. Every (subject, pose) also gets its own uniform
 * +-3 degree jitter on every free joint axis (nobody takes a pose twice
 * the same way), seeded. Landmarks are the synth map's 16 vertices, posed
 * by the synth skinning (metres; not stood on the ground, which the angles
 * do not see). spread scales every variant's turn (1: the 12-20 degrees
 * above; 2: 24-40 degrees), for a set whose neighbouring poses lie
 * further apart than the noise; the jitter stays +-3 degrees. */
#define BENCH_HARD_VARIANTS 8u

typedef struct bench_hard {
    uint32_t subjects, poses, n_landmarks;
    float *landmarks;                   /* [(s * poses + p) * n_landmarks * 3] */
    uint32_t mirror[MIM_LANDMARKS_MAX]; /* the landmark map's mirror table */
    int32_t parent[MIM_LANDMARKS_MAX];  /* its landmark skeleton (mim_index_skeleton) */
    char (*pose_name)[32];              /* poses names, "rest+0" ... */
    uint32_t draws;                     /* bench_hard_make_draws: other jitters of every body */
    float *redrawn;                     /* [((s * poses + p) * draws + d) * n_landmarks * 3], or NULL */
} bench_hard_t;

/* 0, or a negative MIM_E* code (err says why). */
int bench_hard_make(bench_hard_t *h, uint32_t subjects, uint32_t poses, uint32_t vertices, uint64_t seed,
                    double spread, mim_error_t *err);
/* The same, and draws more bodies of every (subject, pose) with jitters of
 * their own (streams other than the set's): samples of what the subject
 * would look like taking the pose again, for the references of
 * bench_query_accuracy. */
int bench_hard_make_draws(bench_hard_t *h, uint32_t subjects, uint32_t poses, uint32_t vertices, uint64_t seed,
                          double spread, uint32_t draws, mim_error_t *err);
void bench_hard_free(bench_hard_t *h);

#endif
