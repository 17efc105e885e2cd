/* libFuzzer harness: landmark map JSON. A parsed map must validate. */
#include "mim_core.h"

#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    mim_landmark_map_t map;
    mim_error_t err = {0};
    if (mim_landmarks_parse(&map, (const char *)data, size, "fuzz", &err) == 0) {
        if (mim_landmarks_validate(&map, 0, "fuzz", NULL)) abort();
        free(mim_landmarks_to_json(&map));
    }
    return 0;
}
