/* The checks of one frame's values (landmark_values.c), whoever parsed
 * them: the streaming reader of landmark frames (landmark_frames.c) and
 * the jansson values of a vest UDP datagram (mim_landmark_array_parse,
 * mim_orientations_parse). Each parser reports what it saw of a value in
 * a mim__seen_t; the checks and their messages are written here once.
 * Internal to core/. */
#ifndef MIM_CORE_LANDMARK_VALUES_H
#define MIM_CORE_LANDMARK_VALUES_H

#include "mim_core.h"

/* One value where [x, y, z] (or [x, y, z, w]) or null belongs: its kind,
 * and for an array its length and its first four items as numbers. */
typedef enum { MIM__SEEN_NULL, MIM__SEEN_ARRAY, MIM__SEEN_OTHER } mim__seen_kind_t;
typedef struct mim__seen {
    mim__seen_kind_t kind;
    size_t count;      /* items of an array */
    double v[4];       /* the first four items ... */
    uint8_t isnum[4];  /* ... where they are numbers */
} mim__seen_t;

/* "origin" or "origin: frame F" (frame >= 0) into buf: the start of every
 * message. */
const char *mim__where(char *buf, size_t size, const char *origin, long frame);

/* "landmarks" is not an array (MIM_EFORMAT). */
int mim__landmarks_not_array(const char *origin, long frame, mim_error_t *err);
/* Landmark i: null (present 0, NaN), or [x, y, z] of finite floats
 * (present 1), else MIM_EFORMAT / MIM_ENONFINITE naming the landmark. */
int mim__landmark_entry(const mim__seen_t *e, const char *origin, long frame, uint32_t i, float *pos,
                        uint8_t *present, mim_error_t *err);
/* After a landmark array of count entries whose first n went through
 * mim__landmark_entry (pending: the first of their errors, or NULL): the
 * count, then the pending error, then at most max_missing nulls, then
 * mim_landmarks_check. */
int mim__landmarks_close(size_t count, uint32_t n, uint32_t max_missing, const mim_error_t *pending,
                         const char *origin, long frame, const float *pos, const uint8_t *present, mim_error_t *err);

/* Orientations: identity, none given. */
void mim__orient_clear(double *q, uint8_t *have);
/* "orientations" is not an object (MIM_EFORMAT). */
int mim__orientations_not_object(const char *origin, long frame, mim_error_t *err);
/* The segment called key (key_len bytes), or -1. */
int mim__segment_find(const char *key, size_t key_len);
/* Member key (segment s, -1: no segment) of an orientations object: null
 * (nothing), or [x, y, z, w] of finite numbers of norm 1 within
 * MIM_ORIENT_UNIT_TOL, normalised into q[4 s..] with have[s] = 1; else
 * MIM_EFORMAT / MIM_ENONFINITE naming the segment. */
int mim__orientation_entry(const char *key, int s, const mim__seen_t *e, const char *origin, long frame, double *q,
                           uint8_t *have, mim_error_t *err);

#endif
