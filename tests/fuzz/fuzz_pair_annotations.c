/* libFuzzer harness: the 2D pose-pair annotations file
 * (sample/annotations_file.c), which the sampler reads from users. A file
 * that parses must hold finite pixel coordinates. */
#include "mim_sample.h"

#include <math.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    mim_pairs_annotations_t a;
    if (mim_pairs_annotations_parse((const char *)data, size, "fuzz", &a, NULL) == 0) {
        for (size_t i = 0; i < (size_t)a.n * 2 * MIM_PAIR_JOINTS; i++)
            if (!isfinite(a.points[i])) abort();
        mim_pairs_annotations_free(&a);
    }
    return 0;
}
