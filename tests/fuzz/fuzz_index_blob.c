/* libFuzzer harness: the recognition index blob as the store keeps it
 * (index/blob.c). The input is the payload; the harness writes the header
 * with the right length and checksum around it, so the fuzzer reaches the
 * payload decoder instead of stopping at the checksum. The first byte picks
 * the layout, version 1 or 2 (without and with the augmentation fields).
 * Version 3 adds the kd-forests as FLANN's own bytes, which FLANN's loader
 * does not check; the checksum guards them against damage, and this harness
 * does not feed them to it (index/blob.c). A blob that loads must answer a
 * query without crashing. */
#include "mim_core.h"
#include "mim_index.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!size)
        return 0;
    uint32_t version = 1 + data[0] % 2, order = 0x01020304, zero = 0;
    data++, size--;
    unsigned char *blob = malloc(32 + size);
    if (!blob)
        return 0;
    uint64_t plen = size, sum = mim_hash64(data, size, 0x6d6978ULL);
    memcpy(blob, "MIXB", 4);
    memcpy(blob + 4, &version, 4);
    memcpy(blob + 8, &plen, 8);
    memcpy(blob + 16, &sum, 8);
    memcpy(blob + 24, &order, 4);
    memcpy(blob + 28, &zero, 4);
    if (size)
        memcpy(blob + 32, data, size);
    mim_index_t *ix = NULL;
    if (mim_index_load(&ix, blob, 32 + size, NULL) == 0) {
        float lm[3 * MIM_LANDMARKS_MAX];
        for (int i = 0; i < 3 * MIM_LANDMARKS_MAX; i++)
            lm[i] = (float)((i * 7919) % 101) / 50.0f;
        mim_index_answer_t a;
        mim_index_hit_t hits[4];
        mim_index_query_options_t qo = {.k = 4};
        mim_index_query(ix, lm, NULL, &qo, &a, hits, NULL);
        mim_index_close(&ix);
    }
    free(blob);
    return 0;
}
