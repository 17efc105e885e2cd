/* index/ on the hard recognition set of issue 15 (bench/hard_set.c: synth
 * subjects in nearby poses), small enough for the test suite: 5 subjects x
 * 16 poses (rest and walk, each with 7 variants of 12-20 degrees at one or
 * two joints), the index built from 4 subjects and queried with the fifth
 * (leave one subject out, one fold). Seeded throughout: the same figures on
 * every run. The full run is bench/query_accuracy (bench/RESULTS.md). Also:
 * the noise-augmentation options are stored with the index, and an index
 * blob of version 1 (before augmentation) still loads. */
#include "hard_set.h"
#include "mim_index.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { S = 5, P = 16, DRAWS = 5 };

typedef struct {
    bench_hard_t h;
    const char *subj[S * P], *pose[S * P];
    char names[S * P][2][16];
    uint64_t ids[S * P];
} set_t;

static void set_make(set_t *s)
{
    mim_error_t err = {0};
    assert_int_equal(bench_hard_make(&s->h, S, P, 1000, 1, &err), 0);
    for (uint32_t t = 0; t < S * P; t++) {
        snprintf(s->names[t][0], 16, "s%u", t / P);
        snprintf(s->names[t][1], 16, "p%u", t % P);
        s->subj[t] = s->names[t][0], s->pose[t] = s->names[t][1], s->ids[t] = t + 1;
    }
}

/* The index of the first S - 1 subjects with options o. */
static mim_index_t *build(const set_t *s, const mim_index_options_t *o)
{
    mim_index_input_t in = {(S - 1) * P, s->h.n_landmarks, s->h.landmarks, s->ids, s->subj, s->pose, s->h.mirror};
    mim_index_t *ix = NULL;
    mim_error_t err = {0};
    mim_index_report_t rep;
    int rc = mim_index_build(&ix, &in, o, &rep, &err);
    if (rc) fprintf(stderr, "build: %s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
    return ix;
}

/* Accuracy on the held-out subject's frames with Gaussian noise of sigma
 * metres per coordinate (DRAWS draws each when sigma > 0), seeded. */
static double accuracy(const set_t *s, const mim_index_t *ix, double sigma)
{
    uint32_t L = s->h.n_landmarks, hits = 0, tests = 0;
    mim_rng_t rng;
    mim_rng_seed(&rng, 15, 0x68617264ULL);
    float frame[3 * MIM_LANDMARKS_MAX];
    for (uint32_t p = 0; p < P; p++) {
        uint32_t t = (S - 1) * P + p;
        for (int r = 0; r < (sigma > 0 ? DRAWS : 1); r++) {
            for (uint32_t i = 0; i < 3 * L; i++)
                frame[i] = (float)(s->h.landmarks[(size_t)t * L * 3 + i] + sigma * mim_rng_gauss(&rng));
            mim_index_answer_t a;
            mim_index_hit_t hit;
            assert_int_equal(mim_index_query(ix, frame, NULL, NULL, &a, &hit, NULL), 0);
            hits += a.n_hits && !strcmp(hit.pose, s->pose[t]);
            tests++;
        }
    }
    return (double)hits / tests;
}

/* mimic's default recognition on the hard set: clean frames of an unseen
 * subject are recognised well, and the default (noise-augmented) index
 * beats the index without augmentation at 3 cm of noise. */
static void test_hard_set_accuracy(void **state)
{
    (void)state;
    set_t *s = calloc(1, sizeof *s);
    set_make(s);
    mim_index_options_t def = {0}, plain = {.noise = -1};
    mim_index_t *a = build(s, &def), *b = build(s, &plain);
    mim_index_info_t info;
    mim_index_get_info(a, &info);
    assert_int_equal(info.augment, MIM_INDEX_AUGMENT_DEFAULT);
    assert_true(info.noise == MIM_INDEX_NOISE_DEFAULT);
    mim_index_get_info(b, &info);
    assert_int_equal(info.augment, 0);
    double clean = accuracy(s, a, 0), robust = accuracy(s, a, 0.03), plain3 = accuracy(s, b, 0.03);
    fprintf(stderr, "hard set (%d x %d, one fold): default clean %.3f, 3 cm %.3f; without augmentation 3 cm %.3f\n", S,
            P, clean, robust, plain3);
    assert_true(clean >= 0.8);
    assert_true(robust >= plain3 + 0.025);
    mim_index_close(&a), mim_index_close(&b);
    bench_hard_free(&s->h);
    free(s);
}

/* The augmentation is stored with the index (blob version 2 on); a version 1
 * blob (no augmentation fields, no forests) still loads, as an index without
 * augmentation that answers as before; options out of range are refused. */
static void test_blob_versions(void **state)
{
    (void)state;
    set_t *s = calloc(1, sizeof *s);
    set_make(s);
    mim_index_options_t o = {.noise = 0.03, .augment = 2, .C = 100, .gamma = 1};
    mim_index_t *ix = build(s, &o), *back = NULL;
    void *blob = NULL;
    size_t len = 0;
    assert_int_equal(mim_index_save(ix, &blob, &len, NULL), 0);
    uint32_t ver;
    memcpy(&ver, (char *)blob + 4, 4);
    assert_int_equal(ver, 3);
    assert_int_equal(mim_index_load(&back, blob, len, NULL), 0);
    mim_index_info_t info;
    mim_index_get_info(back, &info);
    assert_int_equal(info.augment, 2);
    assert_true(info.noise == 0.03);
    mim_index_close(&back);
    /* version 1: the header's 9 u32 (augment gone) and 3 f64 (noise gone),
     * and no forest count at the end (every class here is scanned exactly,
     * so version 3's count is 0) */
    uint32_t n_forests;
    memcpy(&n_forests, (char *)blob + len - 4, 4);
    assert_int_equal(n_forests, 0);
    unsigned char *v1 = malloc(len);
    const unsigned char *p = blob;
    size_t o1 = 0;
    memcpy(v1, p, 32), o1 = 32;
    memcpy(v1 + o1, p + 32, 36), o1 += 36;            /* n_landmarks .. d2 */
    memcpy(v1 + o1, p + 32 + 40, 24), o1 += 24;       /* C, gamma, cv_accuracy */
    memcpy(v1 + o1, p + 32 + 72, len - 108), o1 += len - 108; /* the rest, without the forest count */
    uint32_t one = 1;
    uint64_t plen = o1 - 32, sum = mim_hash64(v1 + 32, plen, 0x6d6978ULL);
    memcpy(v1 + 4, &one, 4), memcpy(v1 + 8, &plen, 8), memcpy(v1 + 16, &sum, 8);
    mim_error_t err = {0};
    int rc = mim_index_load(&back, v1, o1, &err);
    if (rc) fprintf(stderr, "v1: %s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
    mim_index_get_info(back, &info);
    assert_int_equal(info.augment, 0);
    assert_true(info.noise == 0);
    const float *frame = s->h.landmarks + (size_t)(S - 1) * P * s->h.n_landmarks * 3;
    mim_index_answer_t a1, a2;
    mim_index_hit_t h1, h2;
    assert_int_equal(mim_index_query(ix, frame, NULL, NULL, &a1, &h1, NULL), 0);
    assert_int_equal(mim_index_query(back, frame, NULL, NULL, &a2, &h2, NULL), 0);
    assert_int_equal(a1.cls, a2.cls);
    assert_true(h1.id == h2.id);
    mim_index_close(&back), mim_index_close(&ix);
    free(v1), free(blob);
    /* out of range */
    mim_index_input_t in = {P, s->h.n_landmarks, s->h.landmarks, s->ids, s->subj, s->pose, s->h.mirror};
    mim_index_options_t bad1 = {.noise = 2}, bad2 = {.augment = 65};
    assert_int_equal(mim_index_build(&ix, &in, &bad1, NULL, NULL), MIM_EINVAL);
    assert_int_equal(mim_index_build(&ix, &in, &bad2, NULL, NULL), MIM_EINVAL);
    assert_null(ix);
    bench_hard_free(&s->h);
    free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hard_set_accuracy),
        cmocka_unit_test(test_blob_versions),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
