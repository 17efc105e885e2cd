/* The index blob's versions (issue 30 item 14). The index is rebuilt from
 * the store by mimic index, so mimic reads only the version it writes: an
 * older blob is refused in one line that says to rebuild it, a newer one
 * in one line that names the version this mimic reads. The old blobs are
 * made here with their headers as those versions wrote them. */
#include "mim_index.h"
#include "mim_synth.h"
#include "test_support.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CURRENT 7

/* 3 subjects x 4 poses of synth, their landmarks */
static mim_index_t *small_index(void)
{
    enum { S = 3, P = 4, N = S * P };
    mim_synth_options_t so = {.subjects = S, .poses = P, .vertices = 1500, .seed = 7};
    mim_synth_t *syn = NULL;
    assert_int_equal(mim_synth_create(&syn, &so, NULL), 0);
    mim_landmark_map_t map;
    mim_synth_landmarks(syn, &map);
    float *body = malloc(12 * mim_synth_n_vertices(syn)), lm[N * 48];
    uint64_t ids[N];
    char names[2][N][8];
    const char *subjects[N], *poses[N];
    for (uint32_t t = 0; t < N; t++) {
        assert_int_equal(mim_synth_body(syn, t / P, t % P, body), 0);
        for (uint32_t l = 0; l < 16; l++) memcpy(lm + 48 * t + 3 * l, body + 3 * map.vertex[l], 12);
        ids[t] = 1 + t;
        snprintf(names[0][t], 8, "s%u", t / P), snprintf(names[1][t], 8, "p%u", t % P);
        subjects[t] = names[0][t], poses[t] = names[1][t];
    }
    mim_index_input_t in = {N, 16, lm, ids, subjects, poses, map.mirror, NULL};
    mim_index_options_t o = {.features = 20, .C = 10, .gamma = 1};
    mim_index_t *ix = NULL;
    assert_int_equal(mim_index_build(&ix, &in, &o, NULL, NULL), 0);
    free(body);
    mim_synth_destroy(&syn);
    return ix;
}

/* A blob of version ver with a right header: versions 1 to 4 had 32 bytes
 * ("MIXB", u32 version, u64 payload bytes, u64 mim_hash64 of the payload,
 * u32 byte-order mark, u32 0) and payload bytes after them (here those of
 * the current blob); versions 5 and 6 had the current 64-byte header (its head's
 * checksum does not cover the version field). 64-byte aligned. */
static unsigned char *old_blob(const unsigned char *cur, size_t len, uint32_t ver, size_t *out_len)
{
    unsigned char *p = NULL;
    assert_int_equal(posix_memalign((void **)&p, 64, len), 0);
    memcpy(p, cur, len);
    memcpy(p + 4, &ver, 4);
    *out_len = len;
    if (ver >= 5) return p;
    uint64_t plen = len - 64, sum = mim_hash64(cur + 64, plen, 0x6d6978ULL);
    uint32_t bom = 0x01020304, zero = 0;
    memcpy(p + 8, &plen, 8), memcpy(p + 16, &sum, 8), memcpy(p + 24, &bom, 4), memcpy(p + 28, &zero, 4);
    memmove(p + 32, cur + 64, plen);
    *out_len = 32 + plen;
    return p;
}

/* Every opener refuses p with exactly want, in one line, and opens nothing. */
static void refused(const unsigned char *p, size_t len, const char *want)
{
    unsigned char *unaligned = malloc(len + 1);
    memcpy(unaligned + 1, p, len);
    for (int how = 0; how < 3; how++) {
        mim_index_t *ix = NULL;
        mim_error_t err = {0};
        int rc = how == 0   ? mim_index_load(&ix, p, len, &err)
                 : how == 1 ? mim_index_open_in_place(&ix, p, len, &err)
                            : mim_index_open_in_place(&ix, unaligned + 1, len, &err); /* copied */
        assert_int_equal(rc, MIM_EFORMAT);
        assert_null(ix);
        if (strcmp(err.msg, want)) fail_msg("opener %d: '%s', not '%s'", how, err.msg, want);
        assert_null(strchr(err.msg, '\n'));
    }
    free(unaligned);
}

static void test_versions(void **s)
{
    (void)s;
    mim_index_t *ix = small_index(), *back = NULL;
    void *blob = NULL;
    size_t len = 0;
    assert_int_equal(mim_index_save(ix, &blob, &len, NULL), 0);
    uint32_t ver;
    memcpy(&ver, (unsigned char *)blob + 4, 4);
    assert_int_equal(ver, CURRENT); /* what mimic writes, it reads */
    assert_int_equal(mim_index_load(&back, blob, len, NULL), 0);
    mim_index_close(&back);
    assert_int_equal(mim_index_open_in_place(&back, blob, len, NULL), 0);
    mim_index_close(&back);
    char want[256];
    for (uint32_t old = 1; old < CURRENT; old++) {
        size_t olen = 0;
        unsigned char *p = old_blob(blob, len, old, &olen);
        snprintf(want, sizeof want,
                 "index blob: version %u is older than this mimic's (%d): rebuild it (run mimic index)", old, CURRENT);
        refused(p, olen, want);
        if (old < 5) refused(p, 32, want); /* a header alone: still the version that says what to do */
        free(p);
    }
    for (uint32_t other = 0; other <= CURRENT + 1; other += CURRENT + 1) { /* 0 never was; 8 is to come */
        size_t olen = 0;
        unsigned char *p = old_blob(blob, len, other, &olen);
        snprintf(want, sizeof want, "index blob: version %u, this mimic reads version %d (run mimic index)", other,
                 CURRENT);
        refused(p, olen, want);
        free(p);
    }
    free(blob);
    mim_index_close(&ix);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_versions),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
