/* libFuzzer harness: the recognition index blob as the store keeps it
 * (index/blob.c). The harness writes the 64-byte header, and the
 * checksums, around the input, so that the fuzzer reaches the decoder
 * instead of stopping at a checksum: bytes 1-2 of the input give the
 * head's size in units of 64 bytes, byte 3 the rows a chunk (1 + value),
 * the rest is the blob after its header; every checksum is then made
 * right (mim__index_seal), and when the first byte is odd one byte past
 * the head is flipped after sealing, so that a lazily verified section
 * fails when a query first needs it. (Older versions are refused by their
 * header's version alone: the index is rebuilt, not read.)
 * A blob holds kd-forests as FLANN's own bytes, which FLANN's loader does
 * not check; their checksum guards them against damage, but a sealed
 * input passes it, so the harness gives FLANN no forest: a blob whose
 * head lists one is only opened and closed. A blob that opens must answer
 * queries (or fail them with an error), be verified, saved and closed
 * without a memory error. */
#include "mim_core.h"
#include "mim_index.h"

#include <stdlib.h>
#include <string.h>

void mim__index_seal(unsigned char *p, size_t len);

static void exercise(mim_index_t *ix)
{
    float lm[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX];
    for (int i = 0; i < 3 * MIM_LANDMARKS_MAX; i++) lm[i] = (float)((i * 7919) % 101) / 50.0f;
    memset(present, 1, sizeof present);
    present[1] = 0;
    mim_index_answer_t a;
    mim_index_hit_t hits[4];
    mim_index_query_options_t qo = {.k = 4}, qv = {.k = 2, .vote_below = 2};
    mim_index_query(ix, lm, NULL, &qo, &a, hits, NULL);
    mim_index_query(ix, lm, present, &qo, &a, hits, NULL);
    mim_index_query(ix, lm, NULL, &qv, &a, hits, NULL);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!size) return 0;
    int flip = data[0] % 2;
    data++, size--;
    if (size < 3) return 0;
    uint64_t hb = 64ull * (data[0] | (uint32_t)data[1] << 8);
    uint32_t rows = 1u + data[2], version = 6, order = 0x01020304, hdr = 64;
    data += 3, size -= 3;
    if (hb > size) hb = size / 64 * 64;
    unsigned char *blob = NULL;
    if (posix_memalign((void **)&blob, 64, 64 + size)) return 0;
    memset(blob, 0, 64);
    uint64_t plen = size;
    memcpy(blob, "MIXB", 4);
    memcpy(blob + 4, &version, 4);
    memcpy(blob + 8, &plen, 8);
    memcpy(blob + 24, &order, 4);
    memcpy(blob + 28, &hdr, 4);
    memcpy(blob + 32, &hb, 8);
    memcpy(blob + 40, &rows, 4);
    if (size) memcpy(blob + 64, data, size);
    mim__index_seal(blob, 64 + size);
    if (flip && size > hb) blob[64 + hb + (data[0] * 131u + data[size - 1]) % (size - hb)] ^= 0x10;
    /* a head that lists forests: FLANN must not see their (sealed, so
     * trusted) bytes; opening and the completion scan do not touch them */
    uint32_t nf = 0;
    if (hb >= 88) memcpy(&nf, blob + 64 + 80, 4);
    mim_index_t *ix = NULL;
    if (mim_index_open_in_place(&ix, blob, 64 + size, NULL) == 0) {
        if (!nf) {
            exercise(ix);
            if (mim_index_verify(ix, NULL) == 0) {
                void *again = NULL;
                size_t len = 0;
                if (mim_index_save(ix, &again, &len, NULL) == 0) free(again);
            }
        }
        mim_index_close(&ix);
    }
    if (!nf && mim_index_load(&ix, blob, 64 + size, NULL) == 0) mim_index_close(&ix);
    free(blob);
    return 0;
}
