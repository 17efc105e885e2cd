/* libFuzzer harness: landmark frames (one frame or a batch), as query,
 * transfer, /api/query and /api/transfer parse them: the streaming reader
 * (core/landmark_frames.c). A parsed set must hold finite positions for
 * its present landmarks, in the plausible range, and unit quaternions for
 * its orientations (identity where not given), and be the frames that
 * jansson's tree and the value checks give (tests/support/
 * frames_reference.c). An error is one line that begins with the origin.
 * A scan stopped by its caller at a frame has handed out that many. */
#include "frames_reference.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct stop {
    uint32_t at, seen;
} stop_t;

static int stop_at(void *user, const mim_landmark_frame_t *f, mim_error_t *err)
{
    stop_t *s = user;
    if (f->index != s->seen++ || f->index > s->at) abort(); /* out of order, or after the stop */
    return f->index == s->at ? mim_error_set(err, MIM_EINVAL, "stopped") : 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    mim_landmark_frames_t f = {0};
    mim_error_t err = {0};
    int rc = mim_landmark_frames_parse((const char *)data, size, "fuzz", 16, 3, &f, &err);
    if (rc == 0) {
        if (!f.orientations != !f.orient_present) abort();
        for (uint32_t i = 0; i < f.n_frames; i++) {
            const float *p = f.positions + (size_t)i * 16 * 3;
            const uint8_t *present = f.present + (size_t)i * 16;
            for (uint32_t k = 0; k < 16; k++)
                if (present[k] && !(isfinite(p[3 * k]) && isfinite(p[3 * k + 1]) && isfinite(p[3 * k + 2])))
                    abort();
            if (mim_landmarks_check(p, present, 16, "fuzz", (long)i, NULL)) abort();
            for (uint32_t s = 0; f.orientations && s < MIM_SEGMENTS; s++) {
                const double *q = f.orientations + ((size_t)i * MIM_SEGMENTS + s) * 4;
                double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
                if (!(fabs(n - 1) < 1e-9)) abort();
                if (!f.orient_present[(size_t)i * MIM_SEGMENTS + s] && q[3] != 1) abort();
            }
        }
        /* jansson stops at a NUL byte: only text without one is compared */
        char *text = memchr(data, 0, size) ? NULL : malloc(size + 1);
        if (text) {
            memcpy(text, data, size);
            text[size] = 0;
            mim_landmark_frames_t ref;
            if (frames_reference(text, 16, 3, &ref) || !frames_equal(&f, &ref)) abort();
            mim_landmark_frames_free(&ref);
            free(text);
        }
        /* stopped by the caller at its last frame */
        stop_t st = {f.n_frames - 1, 0};
        mim_error_t e = {0};
        if (mim_landmark_frames_scan((const char *)data, size, "fuzz", 16, 3, stop_at, &st, &e) != MIM_EINVAL ||
            st.seen != f.n_frames)
            abort();
    } else if (strncmp(err.msg, "fuzz", 4) || strchr(err.msg, '\n') || rc != err.code) {
        abort();
    }
    mim_landmark_frames_free(&f);
    return 0;
}
