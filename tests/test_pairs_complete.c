/* Pose-pair completion (mim_pairs_complete, mimic pairs complete): where a
 * hidden joint depends on the other person (B's hand on A's head), the
 * pair's seen joints place it and one person's alone cannot; bad input is
 * refused. */
#include "mim_sample.h"
#include "synthetic_pairs.h"

#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define N MIM_PAIR_JOINTS
#define P MIM_PAIR_PERSON_JOINTS
#define SAMPLES 400
#define QUERIES 40

static char *dir;

static int joint(const char *name)
{
    const int j = mim_sample_joint_index(name);
    if (j < 0) fail_msg("no joint %s", name);
    return j;
}

/* A random pair whose B puts its left hand on A's head, elbow half way
 * from its shoulder; B stands anywhere within 1.5 m of where it would. */
static void touching_pair(mim_rng_t *r, double *p)
{
    sp_random_pair(r, 0.6, p);
    const double dx = 1.5 * (mim_rng_unit(r) - 0.5), dz = 1.5 * (mim_rng_unit(r) - 0.5);
    for (int j = P; j < N; j++) p[3 * j] += dx, p[3 * j + 2] += dz;
    const int head = joint("head"), wrist = P + joint("l_wrist"), elbow = P + joint("l_elbow"),
              shoulder = P + joint("l_shoulder");
    for (int c = 0; c < 3; c++) {
        p[3 * wrist + c] = p[3 * head + c] + (c == 1 ? 0.08 : 0);
        p[3 * elbow + c] = 0.5 * (p[3 * shoulder + c] + p[3 * wrist + c]);
    }
}

static double filled_error(const double *got, const double *want, const uint8_t *missing)
{
    double e = 0;
    int n = 0;
    for (int j = 0; j < N; j++)
        if (missing[j]) {
            double d2 = 0;
            for (int c = 0; c < 3; c++) d2 += (got[3 * j + c] - want[3 * j + c]) * (got[3 * j + c] - want[3 * j + c]);
            e += sqrt(d2), n++;
        }
    return e / n;
}

static void test_pair_beats_person(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 21, 0);
    double *smp = malloc(sizeof(double) * 3 * N * SAMPLES);
    for (int i = 0; i < SAMPLES; i++) touching_pair(&r, smp + (size_t)i * 3 * N);
    uint8_t missing[N] = {0};
    missing[P + joint("l_wrist")] = missing[P + joint("l_elbow")] = 1;
    double e_pair = 0, e_person = 0;
    for (int q = 0; q < QUERIES; q++) {
        double truth[3 * N], in[3 * N], out[3 * N];
        touching_pair(&r, truth);
        memcpy(in, truth, sizeof in);
        for (int j = 0; j < N; j++) /* what a hidden joint holds does not matter */
            if (missing[j]) in[3 * j] = in[3 * j + 1] = in[3 * j + 2] = 50;
        mim_pairs_complete_options_t o = {0, 0};
        assert_int_equal(mim_pairs_complete(smp, SAMPLES, in, missing, &o, out), 0);
        for (int j = 0; j < N; j++)
            if (!missing[j]) assert_memory_equal(out + 3 * j, in + 3 * j, 3 * sizeof(double));
        e_pair += filled_error(out, truth, missing) / QUERIES;
        o.person_only = 1;
        assert_int_equal(mim_pairs_complete(smp, SAMPLES, in, missing, &o, out), 0);
        e_person += filled_error(out, truth, missing) / QUERIES;
    }
    if (!(e_pair < 0.5 * e_person && e_pair < 0.12))
        fail_msg("pair %.3f m, person alone %.3f m", e_pair, e_person);

    /* nothing missing: the pair as it is; too few seen; not finite; no samples */
    double in[3 * N], out[3 * N];
    memcpy(in, smp, sizeof in);
    uint8_t none[N] = {0}, most[N];
    assert_int_equal(mim_pairs_complete(smp, SAMPLES, in, none, NULL, out), 0);
    assert_memory_equal(out, in, sizeof in);
    for (int j = 0; j < N; j++) most[j] = j >= P + 2; /* B: only 2 joints seen */
    mim_pairs_complete_options_t alone = {1, 1};
    assert_int_equal(mim_pairs_complete(smp, SAMPLES, in, most, &alone, out), MIM_EEMPTY);
    in[4] = NAN;
    assert_int_equal(mim_pairs_complete(smp, SAMPLES, in, missing, NULL, out), MIM_ENONFINITE);
    assert_int_equal(mim_pairs_complete(smp, 0, in, missing, NULL, out), MIM_EINVAL);
    mim_pairs_complete_options_t big = {MIM_PAIRS_COMPLETE_MAX_K + 1, 0};
    assert_int_equal(mim_pairs_complete(smp, SAMPLES, smp, missing, &big, out), MIM_EINVAL);
    free(smp);
}

static char *write_set(const char *name, mim_rng_t *r, int n)
{
    char *path = ts_path(dir, name), *h = mim_pairs_jsonl_header();
    FILE *f = fopen(path, "w");
    fprintf(f, "%s\n", h);
    free(h);
    for (int i = 0; i < n; i++) {
        double p[3 * N];
        touching_pair(r, p);
        char *l = mim_pairs_jsonl_line(p, -1.0);
        fprintf(f, "%s\n", l);
        free(l);
    }
    fclose(f);
    return path;
}

static void test_cli(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 8, 0);
    char *smp = write_set("s.jsonl", &r, SAMPLES), *in = write_set("in.jsonl", &r, 20), *out = ts_path(dir, "o.jsonl");
    double moved[2];
    for (int m = 0; m < 2; m++) {
        const char *a[] = {"pairs", "complete", "--pairs", in, "--missing", "B.l_elbow,B.l_wrist", "--samples", smp,
                           "--match", m ? "person" : "pair", "--json", "-o", out, NULL};
        char *o = ts_mimic_expect(0, NULL, a);
        json_t *j = json_loads(o, 0, NULL);
        assert_non_null(j);
        assert_int_equal(json_integer_value(json_object_get(j, "pairs")), 20);
        assert_int_equal(json_integer_value(json_object_get(j, "joints")), 2);
        moved[m] = json_real_value(json_object_get(j, "moved_m"));
        json_decref(j);
        free(o);
    }
    assert_true(moved[0] < 0.5 * moved[1]); /* the input holds the truth: moved is the error */
    size_t len;
    char *text = ts_read_file(out, &len);
    mim_pairs_samples_t got;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_samples_parse(text, len, out, &got, &err), 0);
    assert_int_equal(got.n, 20);
    mim_pairs_samples_free(&got);
    free(text);
    char *e = NULL;
    const char *b1[] = {"pairs", "complete", "--pairs", in, "--missing", "B.l_hand", "--samples", smp, "-o", out, NULL};
    free(ts_mimic_expect(2, &e, b1));
    assert_non_null(strstr(e, "'B.l_hand' is no joint"));
    free(e);
    const char *b2[] = {"pairs", "complete", "--pairs", in, "--missing", "A.head", "--samples", smp, "--match", "both",
                        "-o", out, NULL};
    free(ts_mimic_expect(2, &e, b2));
    assert_non_null(strstr(e, "mimic pairs complete: --match 'both': give pair or person"));
    free(e);
    const char *b3[] = {"pairs", "complete", "--pairs", smp, "--missing", "A.head", "--samples", "/nonexistent.jsonl",
                        "-o", out, NULL};
    free(ts_mimic_expect(1, &e, b3));
    assert_non_null(strstr(e, "/nonexistent.jsonl"));
    free(e);
    /* B's joints all hidden but two, matched on B alone: too few to fit */
    char most[1024] = "";
    for (int j = 2; j < P; j++)
        snprintf(most + strlen(most), sizeof most - strlen(most), "%sB.%s", j > 2 ? "," : "", mim_sample_joint_names[j]);
    const char *b5[] = {"pairs", "complete", "--pairs", in, "--missing", most, "--samples", smp, "--match", "person",
                        "-o", out, NULL};
    free(ts_mimic_expect(1, &e, b5));
    assert_non_null(strstr(e, "in.jsonl:2: fewer than 3 seen joints to match on"));
    free(e);
    free(smp), free(in), free(out);
}

int main(void)
{
    dir = ts_tempdir("pairs_complete");
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_pair_beats_person), cmocka_unit_test(test_cli)};
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    ts_rmtree(dir);
    free(dir);
    return rc;
}
