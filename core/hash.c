/* A 64-bit content hash: word-at-a-time multiply/rotate mixing with a
 * murmur-style finaliser. Stable across runs and little-endian machines;
 * used to recognise identical mesh content and connectivity, not for
 * security. */
#include "mim_core.h"

#include <string.h>

static inline uint64_t rotl64(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

static inline uint64_t fmix64(uint64_t k)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    k ^= k >> 33;
    return k;
}

uint64_t mim_hash64(const void *data, size_t len, uint64_t seed)
{
    const uint64_t k1 = 0x87c37b91114253d5ULL, k2 = 0x4cf5ad432745937fULL;
    const unsigned char *p = data;
    /* two lanes so consecutive words do not wait on each other */
    uint64_t h1 = seed ^ 0x9e3779b97f4a7c15ULL, h2 = seed ^ 0x243f6a8885a308d3ULL;
    size_t i = 0;
    for (; i + 16 <= len; i += 16) {
        uint64_t a, b;
        memcpy(&a, p + i, 8);
        memcpy(&b, p + i + 8, 8);
        h1 = rotl64(h1 ^ (rotl64(a * k1, 31) * k2), 27) * 5 + 0x52dce729;
        h2 = rotl64(h2 ^ (rotl64(b * k2, 33) * k1), 31) * 5 + 0x38495ab5;
    }
    uint64_t tail = 0;
    size_t rest = len - i;
    for (size_t j = 0; j < rest; j++) tail |= (uint64_t)p[i + j] << (8 * (j & 7));
    if (rest > 8) {
        uint64_t a;
        memcpy(&a, p + i, 8);
        h1 ^= rotl64(a * k1, 31) * k2;
        tail = 0;
        for (size_t j = 8; j < rest; j++) tail |= (uint64_t)p[i + j] << (8 * (j - 8));
    }
    h2 ^= rotl64(tail * k2, 33) * k1;
    h1 ^= (uint64_t)len;
    h2 ^= (uint64_t)len;
    h1 += h2;
    h2 += h1;
    h1 = fmix64(h1);
    h2 = fmix64(h2);
    return h1 + h2;
}
