/* libFuzzer harness: landmark frames (one frame or a batch), as query,
 * transfer, /api/query and /api/transfer parse them. A parsed set must hold
 * finite positions for its present landmarks, in the plausible range. */
#include "mim_core.h"

#include <math.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    mim_landmark_frames_t f = {0};
    mim_error_t err = {0};
    if (mim_landmark_frames_parse((const char *)data, size, "fuzz", 16, 3, &f, &err) == 0) {
        for (uint32_t i = 0; i < f.n_frames; i++) {
            const float *p = f.positions + (size_t)i * 16 * 3;
            const uint8_t *present = f.present + (size_t)i * 16;
            for (uint32_t k = 0; k < 16; k++)
                if (present[k] && !(isfinite(p[3 * k]) && isfinite(p[3 * k + 1]) && isfinite(p[3 * k + 2])))
                    abort();
            if (mim_landmarks_check(p, present, 16, "fuzz", (long)i, NULL)) abort();
        }
    }
    mim_landmark_frames_free(&f);
    return 0;
}
