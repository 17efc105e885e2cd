/* Landmark frames as jansson's tree and the value checks give them: the
 * reference that the streaming reader (core/landmark_frames.c) is held
 * to, in tests/test_landmark_stream.c and the fuzz harness. */
#ifndef MIM_TESTS_FRAMES_REFERENCE_H
#define MIM_TESTS_FRAMES_REFERENCE_H

#include "mim_core.h"

/* text (NUL-terminated) through json_loads (a duplicate member: the last
 * one counts; the reader refuses duplicates of its members), then each
 * frame's "landmarks" through mim_landmark_array_parse and its
 * "orientations" through mim_orientations_parse, gathered as
 * mim_landmark_frames_parse gathers them. 0, or -1 when jansson or a check
 * refuses it (out is then empty). */
int frames_reference(const char *text, uint32_t n, uint32_t max_missing, mim_landmark_frames_t *out);
/* 1 when a and b hold the same frames (NaN equal to NaN), else 0. */
int frames_equal(const mim_landmark_frames_t *a, const mim_landmark_frames_t *b);

#endif
