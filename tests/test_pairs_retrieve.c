/* Retrieval (mim_pairs_retrieve, mimic pairs retrieve): a 2D annotation of
 * one of the samples, seen by a perspective camera from anywhere around,
 * finds that sample and the camera's view; a take annotated by pairs
 * annotate and exported as the samples gives back its own frames with no
 * 3D error; bad input is refused in one line. */
#include "mim_sample.h"
#include "synthetic_pairs.h"

#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define N MIM_PAIR_JOINTS
#define SAMPLES 300

static char *dir;

static double angle_deg(const double a[3], const double b[3])
{
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    return acos(fmax(-1, fmin(1, d))) * 180 / M_PI;
}

/* Each of 40 samples, seen by a random camera (any azimuth, -10..35
 * degrees of elevation, 3-8 m) and 1 px of noise, is found among 300, with
 * the camera's view within 6 degrees (the projection searched is
 * orthographic, the camera's perspective). A sample turned about the
 * vertical and moved is found as well. */
static void test_finds_the_sample(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 11, 0);
    double *p = malloc(sizeof(double) * 3 * N * SAMPLES);
    for (int i = 0; i < SAMPLES; i++) sp_random_pair(&r, 0.9, p + (size_t)i * 3 * N);
    int found = 0;
    double worst_view = 0;
    for (int k = 0; k < 40; k++) {
        const uint32_t want = (uint32_t)(k * 7 % SAMPLES);
        double q[3 * N], uv[2 * N];
        memcpy(q, p + (size_t)want * 3 * N, sizeof q);
        if (k % 2) { /* turned and moved: retrieval does not care where a sample stands */
            const double a = 0.7 * k, c = cos(a), sn = sin(a);
            for (int i = 0; i < N; i++) {
                double x = q[3 * i], z = q[3 * i + 2];
                q[3 * i] = c * x + sn * z + 3, q[3 * i + 2] = -sn * x + c * z - 1;
            }
        }
        mim_pairs_camera_t cam;
        assert_int_equal(mim_pairs_camera_random(&r, q, &cam), 0);
        assert_int_equal(mim_pairs_project(&cam, q, uv), 1);
        for (int i = 0; i < 2 * N; i++) uv[i] += mim_rng_gauss(&r);
        mim_pairs_match_t m;
        assert_int_equal(mim_pairs_retrieve(p, SAMPLES, uv, &m), 0);
        if (m.sample != want) continue;
        found++;
        assert_true(m.residual < 0.03); /* perspective against orthographic, and the noise */
        if (k % 2 == 0) worst_view = fmax(worst_view, angle_deg(m.dir, cam.R + 6));
    }
    if (found < 39) fail_msg("found %d of 40", found);
    if (worst_view > 6) fail_msg("a view %g degrees off the camera's", worst_view);

    /* an annotation whose points are all at one place, or NaN, matches nothing */
    double flat[2 * N], m_uv[2 * N];
    for (int i = 0; i < 2 * N; i++) flat[i] = 100, m_uv[i] = i;
    m_uv[7] = NAN;
    mim_pairs_match_t m;
    assert_int_equal(mim_pairs_retrieve(p, SAMPLES, flat, &m), MIM_EINVAL);
    assert_int_equal(m.sample, UINT32_MAX);
    assert_int_equal(mim_pairs_retrieve(p, SAMPLES, m_uv, &m), MIM_EINVAL);
    assert_int_equal(mim_pairs_retrieve(p, 0, m_uv, &m), MIM_EINVAL);
    free(p);
}

/* A take of 30 random pose-pairs (as BVH, person by person), annotated by
 * pairs annotate and exported as the samples: every annotation gets its
 * own frame back, 3D error ~0 and the view within a few degrees; with the
 * other frames only, the error is a real one. */
static void test_cli(void **s)
{
    (void)s;
    enum { FRAMES = 30 };
    mim_rng_t r;
    mim_rng_seed(&r, 5, 0);
    double pairs[FRAMES][3 * N];
    for (int f = 0; f < FRAMES; f++) sp_random_pair(&r, 0.8, pairs[f]);
    char *path[2];
    for (int who = 0; who < 2; who++) {
        char *text = mim_pairs_bvh_text(&pairs[0][0], FRAMES, who, 1.0 / 30);
        assert_non_null(text);
        path[who] = ts_path(dir, who ? "b.bvh" : "a.bvh");
        assert_int_equal(ts_write_file(path[who], text, strlen(text)), 0);
        free(text);
    }
    char spec[8192];
    snprintf(spec, sizeof spec, "%s,%s", path[0], path[1]);
    char *ann = ts_path(dir, "ann.json"), *cams = ts_path(dir, "cams.json"), *all = ts_path(dir, "all.jsonl"),
         *odd = ts_path(dir, "odd.jsonl"), *out = ts_path(dir, "lifted.jsonl");
    const char *an[] = {"pairs", "annotate", "--pair", spec, "--every", "2", "--views", "2", "--unit", "1",
                        "-o", ann, "--cameras", cams, NULL};
    free(ts_mimic_expect(0, NULL, an));
    const char *ex[] = {"pairs", "export", "--pair", spec, "--unit", "1", "-o", all, NULL};
    free(ts_mimic_expect(0, NULL, ex));
    const char *ex2[] = {"pairs", "export", "--pair", spec, "--unit", "1", "--every", "2", "--offset", "1", "-o", odd, NULL};
    free(ts_mimic_expect(0, NULL, ex2));

    const char *re[] = {"pairs", "retrieve", "--annotations", ann, "--samples", all, "--truth", spec, "--unit", "1",
                        "--cameras", cams, "--json", "-o", out, NULL};
    char *o = ts_mimic_expect(0, NULL, re);
    json_t *j = json_loads(o, 0, NULL);
    assert_non_null(j);
    assert_int_equal(json_integer_value(json_object_get(j, "annotations")), 2 * FRAMES / 2);
    assert_int_equal(json_integer_value(json_object_get(j, "retrieved")), 2 * FRAMES / 2);
    assert_true(json_real_value(json_object_get(json_object_get(j, "error_m"), "p95")) < 1e-6);
    assert_true(json_real_value(json_object_get(json_object_get(j, "view_error_deg"), "p95")) < 8);
    json_decref(j);
    free(o);
    /* the lifted file: samples a reader takes, each the annotation's own frame */
    size_t len;
    char *text = ts_read_file(out, &len);
    mim_pairs_samples_t lifted;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_samples_parse(text, len, out, &lifted, &err), 0);
    assert_int_equal(lifted.n, FRAMES);
    int line = 0;
    for (char *l = strtok(text, "\n"); l; l = strtok(NULL, "\n"), line++) {
        if (!line) continue;
        json_t *x = json_loads(l, 0, NULL), *rt = json_object_get(x, "retrieved");
        assert_int_equal(json_integer_value(json_object_get(rt, "annotation")), line);
        assert_int_equal(json_integer_value(json_object_get(rt, "sample")) - 1,
                         json_integer_value(json_object_get(rt, "frame")));
        json_decref(x);
    }
    mim_pairs_samples_free(&lifted);
    free(text);
    /* from the other frames: a real error, reported */
    const char *re2[] = {"pairs", "retrieve", "--annotations", ann, "--samples", odd, "--truth", spec, "--unit", "1",
                         "--json", "-o", out, NULL};
    o = ts_mimic_expect(0, NULL, re2);
    j = json_loads(o, 0, NULL);
    assert_true(json_real_value(json_object_get(json_object_get(j, "error_m"), "median")) > 0.01);
    assert_true(json_is_null(json_object_get(j, "view_error_deg")));
    json_decref(j);
    free(o);

    /* refused, each in one line */
    char *e = NULL;
    const char *b1[] = {"pairs", "retrieve", "--annotations", ann, "--samples", all, "--cameras", cams, "-o", out, NULL};
    free(ts_mimic_expect(2, &e, b1));
    assert_non_null(strstr(e, "--cameras needs the annotated takes"));
    free(e);
    const char *b2[] = {"pairs", "retrieve", "--annotations", ann, "--samples", all, "--truth", spec, "--unit", "1",
                        "--cameras", ann, "-o", out, NULL};
    free(ts_mimic_expect(1, &e, b2));
    assert_non_null(strstr(e, "not a cameras file"));
    free(e);
    const char *b3[] = {"pairs", "retrieve", "--annotations", ann, "--samples", all, "--samples", ann, "-o", out, NULL};
    free(ts_mimic_expect(1, &e, b3));
    assert_non_null(strstr(e, "ann.json"));
    assert_null(strchr(strchr(e, '\n') + 1, '\n'));
    free(e);
    const char *b4[] = {"pairs", "retrieve", "--annotations", ann, "--samples", all, "-o", NULL};
    free(ts_mimic_expect(2, NULL, b4));
    /* cameras of other annotations (one fewer), and a camera whose rotation is no rotation */
    size_t clen;
    char *ctext = ts_read_file(cams, &clen);
    json_t *cj = json_loads(ctext, 0, NULL), *list = json_object_get(cj, "cameras");
    free(ctext);
    char *bad_cams = ts_path(dir, "bad_cams.json");
    json_array_remove(list, json_array_size(list) - 1);
    assert_int_equal(json_dump_file(cj, bad_cams, 0), 0);
    const char *b5[] = {"pairs", "retrieve", "--annotations", ann, "--samples", all, "--truth", spec, "--unit", "1",
                        "--cameras", bad_cams, "-o", out, NULL};
    free(ts_mimic_expect(1, &e, b5));
    assert_non_null(strstr(e, "bad_cams.json: 29 cameras for 30 annotations"));
    free(e);
    json_array_append_new(list, json_pack("{s:i, s:i, s:i, s:[f,f,f], s:[f,f,f]}", "take", 0, "frame", 28, "view", 1,
                                          "position", 0.0, 0.0, 5.0, "rotation", 1.0, 0.0, 0.0));
    assert_int_equal(json_dump_file(cj, bad_cams, 0), 0);
    free(ts_mimic_expect(1, &e, b5));
    assert_non_null(strstr(e, "bad_cams.json: camera 30: \"rotation\" is not 9 numbers of a rotation"));
    free(e);
    json_decref(cj);
    free(bad_cams);
    /* annotations of frames the --truth take does not have (a take of 10 frames, annotated to 28) */
    char *short_a = ts_path(dir, "short_a.bvh"), *short_b = ts_path(dir, "short_b.bvh"), short_spec[8192];
    for (int who = 0; who < 2; who++) {
        char *text = mim_pairs_bvh_text(&pairs[0][0], 10, who, 1.0 / 30);
        assert_int_equal(ts_write_file(who ? short_b : short_a, text, strlen(text)), 0);
        free(text);
    }
    snprintf(short_spec, sizeof short_spec, "%s,%s", short_a, short_b);
    const char *b7[] = {"pairs", "retrieve", "--annotations", ann, "--samples", all, "--truth", short_spec, "--unit", "1",
                        "-o", out, NULL};
    free(ts_mimic_expect(1, &e, b7));
    assert_non_null(strstr(e, "annotation 11 is of take 0 frame 10, which the 1 --truth take do not have"));
    free(e);
    free(short_a), free(short_b);
    free(path[0]), free(path[1]), free(ann), free(cams), free(all), free(odd), free(out);
}

int main(void)
{
    dir = ts_tempdir("pairs_retrieve");
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_finds_the_sample), cmocka_unit_test(test_cli)};
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    ts_rmtree(dir);
    free(dir);
    return rc;
}
