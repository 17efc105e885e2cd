/* libFuzzer harness: the pose-pair samples file (sample/samples_file.c),
 * JSON lines a user hands to mimic pairs coverage and templates. A file
 * that parses must give finite joints: they are compared next. */
#include "mim_sample.h"

#include <math.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    mim_pairs_samples_t s;
    if (mim_pairs_samples_parse((const char *)data, size, "fuzz", &s, NULL) == 0) {
        for (size_t i = 0; i < (size_t)s.n * 3 * MIM_PAIR_JOINTS; i++)
            if (!isfinite(s.joints[i])) abort();
        mim_pairs_samples_free(&s);
    }
    return 0;
}
