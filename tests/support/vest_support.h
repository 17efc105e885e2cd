/* Helpers shared by the vest tests (test_vest_protocol, test_vest_io): a
 * seeded random source, a synthetic avatar and its rig, a BVH motion, a
 * stream of random hub packets, and a decoder sink that keeps its frames. */
#ifndef MIM_VEST_SUPPORT_H
#define MIM_VEST_SUPPORT_H

#include "mim_synth.h"
#include "mim_vest.h"
#include "test_support.h"

/* Core's seeded generator (mim_rng_u64): the same sequence on every run. */
uint64_t vs_rnd(void);
/* A random unit quaternion (x, y, z, w). */
void vs_rand_quat(float q[4]);

/* A synthetic avatar (subject 0, rest pose) and its rig. */
typedef struct {
    mim_mesh_t mesh;
    mim_landmark_map_t map;
    mim_vest_skeleton_t sk;
    mim_vest_rig_t rig;
    float joints[3 * 32];
    mim_synth_t *s;
} vs_avatar_t;
/* Builds the avatar and calibrates its rig for the tare pose. */
void vs_avatar_make(vs_avatar_t *a, int pose);
void vs_avatar_free(vs_avatar_t *a);

/* A small BVH motion, malloc'd text: Y up, T-pose rest, 30 frames/s; arms
 * swing, legs step, the torso turns. */
char *vs_make_bvh(int frames);
/* The same written to dir/motion.bvh; returns the path (malloc'd). */
char *vs_write_bvh(const char *dir, int frames);
/* The same, parsed. */
void vs_load_motion(mim_vest_motion_t *m, int frames);

/* Collects the frames a decoder emits. */
typedef struct {
    mim_vest_frame_t *f;
    size_t n, cap;
    uint64_t packets;
} vs_sink_t;
/* A decoder callback; user is a zeroed vs_sink_t. */
void vs_sink_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *fr, uint32_t n);

/* An encoded stream and the frames it carries, in order. */
typedef struct {
    uint8_t *bytes;
    size_t n, cap;
    mim_vest_frame_t *sent;
    size_t n_sent, cap_sent;
} vs_stream_t;
void vs_stream_put(vs_stream_t *s, const void *p, size_t n);
/* Random packets with header flags f, garbage between some of them. */
void vs_make_stream(vs_stream_t *s, uint32_t f, int packets, int garbage);

void vs_assert_frames_equal(const mim_vest_frame_t *a, const mim_vest_frame_t *b, int check_t);

/* The angle between two orientations, in degrees. */
double vs_angle_deg(mim_quat a, mim_quat b);
/* One vest landmark line read as a landmark frame (what `mimic transfer
 * --landmarks` does): its 17 orientations into R and have; returns 1 when
 * the line has them (fails the test when the line is no frame). */
int vs_line_orientations(const char *line, mim_quat R[MIM_SEGMENTS], uint8_t have[MIM_SEGMENTS]);
/* The line of want (a file of vest lines) with line's time stamp, malloc'd
 * (fails the test when there is none); *t gets the time stamp. */
char *vs_expected_line(const char *want, const char *line, unsigned long long *t);

#endif
