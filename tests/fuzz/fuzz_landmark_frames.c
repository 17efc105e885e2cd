/* libFuzzer harness: landmark frames (one frame or a batch), as query,
 * transfer, /api/query and /api/transfer parse them. A parsed set must hold
 * finite positions for its present landmarks, in the plausible range, and
 * unit quaternions for its orientations (identity where not given). */
#include "mim_core.h"

#include <math.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    mim_landmark_frames_t f = {0};
    mim_error_t err = {0};
    if (mim_landmark_frames_parse((const char *)data, size, "fuzz", 16, 3, &f, &err) == 0) {
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
    }
    mim_landmark_frames_free(&f);
    return 0;
}
