/* core/: error texts and contexts, hashing, math, landmark maps, file reading. */
#include "test_support.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void test_errors(void **s)
{
    (void)s;
    for (int c = MIM_EINVAL; c < MIM_ELAST_; c++) {
        assert_non_null(mim_strerror(c));
        assert_string_not_equal(mim_strerror(c), "unknown error");
    }
    assert_string_equal(mim_strerror(-2), "No such file or directory");
    mim_error_t e = {0};
    assert_int_equal(mim_error_set(&e, MIM_EFORMAT, "%s:%d: bad\nthing", "f.ply", 3), MIM_EFORMAT);
    assert_string_equal(e.msg, "f.ply:3: bad thing"); /* one line */
    mim_error_set(&e, MIM_EIO, "second");                /* the first error is kept */
    assert_int_equal(e.code, MIM_EFORMAT);
    assert_string_equal(mim_error_text(&e), "f.ply:3: bad thing");
    mim_error_clear(&e);
    assert_int_equal(e.code, 0);
    assert_int_equal(mim_error_set(NULL, MIM_EIO, "x"), MIM_EIO);
}

static void test_hash(void **s)
{
    (void)s;
    unsigned char buf[1000];
    for (int i = 0; i < 1000; i++) buf[i] = (unsigned char)(i * 31 + 7);
    uint64_t h = mim_hash64(buf, sizeof buf, 0);
    assert_int_equal(h, mim_hash64(buf, sizeof buf, 0));
    assert_int_not_equal(h, mim_hash64(buf, sizeof buf, 1));
    /* every single-bit change of every length changes the hash */
    for (size_t len = 0; len <= 40; len++) {
        uint64_t base = mim_hash64(buf, len, 0);
        for (size_t bit = 0; bit < len * 8; bit++) {
            buf[bit / 8] ^= (unsigned char)(1u << (bit % 8));
            assert_int_not_equal(mim_hash64(buf, len, 0), base);
            buf[bit / 8] ^= (unsigned char)(1u << (bit % 8));
        }
        if (len) assert_int_not_equal(base, mim_hash64(buf, len - 1, 0));
    }
}

static void test_quaternions(void **s)
{
    (void)s;
    mim_quat q = mim_quat_axis_angle(mim_v3(0, 0, 1), M_PI / 2);
    mim_vec3 v = mim_quat_rotate(q, mim_v3(1, 0, 0));
    assert_true(fabs(v.x) < 1e-12 && fabs(v.y - 1) < 1e-12 && fabs(v.z) < 1e-12);
    /* mul applies the right factor first */
    mim_quat r = mim_quat_axis_angle(mim_v3(1, 0, 0), M_PI / 2);
    mim_vec3 a = mim_quat_rotate(mim_quat_mul(q, r), mim_v3(0, 1, 0));
    mim_vec3 b = mim_quat_rotate(q, mim_quat_rotate(r, mim_v3(0, 1, 0)));
    assert_true(mim_v3_norm(mim_v3_sub(a, b)) < 1e-12);
    mim_quat h = mim_quat_slerp(mim_quat_identity(), q, 0.5);
    v = mim_quat_rotate(h, mim_v3(1, 0, 0));
    assert_true(fabs(v.x - cos(M_PI / 4)) < 1e-12 && fabs(v.y - sin(M_PI / 4)) < 1e-12);
}

static void test_landmarks(void **s)
{
    (void)s;
    uint32_t v[16];
    for (int i = 0; i < 16; i++) v[i] = (uint32_t)(100 + i);
    mim_landmark_map_t m, back;
    mim_landmarks_default(&m, v, 5000);
    char *json = mim_landmarks_to_json(&m);
    mim_error_t e = {0};
    assert_int_equal(mim_landmarks_parse(&back, json, strlen(json), "mem", &e), 0);
    assert_int_equal(back.count, 16);
    assert_int_equal(back.topology_vertices, 5000);
    for (int i = 0; i < 16; i++) {
        assert_string_equal(back.names[i], mim_landmark_default_names[i]);
        assert_int_equal(back.vertex[i], v[i]);
        assert_int_equal(back.mirror[back.mirror[i]], (uint32_t)i);
    }
    assert_int_equal(back.mirror[5], 6); /* l_elbow <-> r_elbow */
    free(json);
    assert_int_equal(mim_landmarks_validate(&m, 110, "mem", &e), MIM_EINDEX);
    assert_non_null(strstr(e.msg, "'r_hip' is vertex 110"));

    struct { const char *text; int code; const char *phrase; } bad[] = {
        {"{\"landmarks\": [1, 2", MIM_EFORMAT, "mem:1:"},
        {"{\"landmarks\": []}", MIM_EFORMAT, "needs 4"},
        {"{\"landmarks\": [{\"name\":\"a\",\"vertex\":1},{\"name\":\"b\",\"vertex\":2},{\"name\":\"c\",\"vertex\":3},"
         "{\"name\":\"d\",\"vertex\":-4}]}", MIM_EFORMAT, "'d' needs a non-negative integer"},
        {"{\"landmarks\": [{\"name\":\"a\",\"vertex\":1},{\"name\":\"b\",\"vertex\":2},{\"name\":\"c\",\"vertex\":3},"
         "{\"name\":\"d\",\"vertex\":4}], \"mirror\": [1, 2, 0, 3]}", MIM_EFORMAT, "not a pairing"},
        {"{\"landmarks\": [{\"name\":\"a\",\"vertex\":1},{\"name\":\"a\",\"vertex\":2},{\"name\":\"c\",\"vertex\":3},"
         "{\"name\":\"d\",\"vertex\":4}]}", MIM_EFORMAT, "appears twice"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        mim_error_clear(&e);
        assert_int_equal(mim_landmarks_parse(&back, bad[i].text, strlen(bad[i].text), "mem", &e), bad[i].code);
        if (!strstr(e.msg, bad[i].phrase)) fprintf(stderr, "got: %s\n", e.msg);
        assert_non_null(strstr(e.msg, bad[i].phrase));
    }
    /* any count >= 4 works; without a mirror table l_/r_ pairs are found by name */
    const char *five = "{\"landmarks\": [{\"name\":\"nose\",\"vertex\":1},{\"name\":\"l_eye\",\"vertex\":2},"
                       "{\"name\":\"r_eye\",\"vertex\":3},{\"name\":\"l_ear\",\"vertex\":4},{\"name\":\"r_ear\",\"vertex\":5}]}";
    assert_int_equal(mim_landmarks_parse(&back, five, strlen(five), "mem", &e), 0);
    assert_int_equal(back.count, 5);
    assert_int_equal(back.mirror[0], 0);
    assert_int_equal(back.mirror[1], 2);
    assert_int_equal(back.mirror[4], 3);
    mim_error_clear(&e);
    assert_int_equal(mim_landmarks_read(&back, "/nonexistent/landmarks.json", &e), MIM_ENOTFOUND);
    assert_non_null(strstr(e.msg, "/nonexistent/landmarks.json"));
}

/* Reading a file: whole, its head, past a size hint, and a missing one. */
static void test_file_read(void **s)
{
    (void)s;
    char *dir = ts_tempdir("core-file"), *path = ts_path(dir, "f.bin");
    size_t n = 200000, len;
    char *data = malloc(n), *text;
    for (size_t i = 0; i < n; i++) data[i] = (char)(i * 7 + 1);
    assert_int_equal(ts_write_file(path, data, n), 0);
    assert_int_equal(mim_file_read(path, 0, &text, &len, NULL), 0);
    assert_int_equal(len, n);
    assert_memory_equal(text, data, n);
    assert_int_equal(text[n], 0);
    free(text);
    assert_int_equal(mim_file_read(path, 1000, &text, &len, NULL), 0);
    assert_int_equal(len, 1000);
    assert_memory_equal(text, data, 1000);
    assert_int_equal(text[1000], 0);
    free(text);
    assert_int_equal(mim_file_read(path, n + 1, &text, &len, NULL), 0);
    assert_int_equal(len, n);
    free(text);
    /* a file whose size says 0 is read to its end all the same */
    assert_int_equal(mim_file_read("/proc/self/status", 0, &text, &len, NULL), 0);
    assert_true(len > 0 && strlen(text) == len);
    free(text);
    mim_error_t e = {0};
    assert_int_equal(mim_file_read("/nonexistent/f", 0, &text, &len, &e), -ENOENT);
    assert_null(text);
    assert_non_null(strstr(e.msg, "/nonexistent/f: cannot open: "));
    ts_rmtree(dir);
    free(data), free(path), free(dir);
}

/* Landmark frames: both layouts, nulls, and each bad input with where. */
static void test_landmark_frames(void **s)
{
    (void)s;
    mim_error_t e = {0};
    mim_landmark_frames_t f;
    const char *one = "{\"landmarks\": [[0,0,0],[1,0,0],null,[0,0,1.5]]}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(one, strlen(one), "one", 4, 3, &f, &e), 0);
    assert_int_equal(f.n_frames, 1);
    assert_int_equal(f.present[2], 0);
    assert_int_equal(f.present[3], 1);
    assert_true(isnan(f.positions[6]));
    assert_true(f.positions[11] == 1.5f);
    mim_landmark_frames_free(&f);

    const char *batch = "{\"frames\": [{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,1]]},\n"
                        " {\"landmarks\": [[0,0,0],[2,0,0],[0,2,0],[0,0,2]]}]}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(batch, strlen(batch), "batch", 4, 0, &f, &e), 0);
    assert_int_equal(f.n_frames, 2);
    assert_true(f.positions[12 + 3] == 2.0f);
    mim_landmark_frames_free(&f);

    /* malformed JSON: line and column */
    const char *bad = "{\"frames\": [\n  {\"landmarks\": [[0,0,0],]}]}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(bad, strlen(bad), "bad.json", 4, 3, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "bad.json:2:"));
    assert_null(f.positions);
    /* wrong count names the frame */
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(batch, strlen(batch), "b", 5, 3, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "frame 0 has 4 landmarks"));
    /* too many missing */
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(one, strlen(one), "one", 4, 0, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "1 missing"));
    /* a string coordinate, and a float overflow */
    const char *str = "{\"landmarks\": [[0,0,0],[1,\"x\",0],[0,1,0],[0,0,1]]}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(str, strlen(str), "s", 4, 3, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "landmark 1: y is not a number"));
    const char *big = "{\"landmarks\": [[0,0,0],[1,0,0],[0,1e300,0],[0,0,1]]}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(big, strlen(big), "g", 4, 3, &f, &e), MIM_ENONFINITE);
    /* NaN is not JSON */
    const char *nan = "{\"landmarks\": [[0,0,0],[NaN,0,0],[0,1,0],[0,0,1]]}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(nan, strlen(nan), "n", 4, 3, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "n:1:"));
    /* missing file */
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_read("/nonexistent/x.json", 4, 3, &f, &e), MIM_ENOTFOUND);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_hash),
        cmocka_unit_test(test_quaternions),
        cmocka_unit_test(test_landmarks),
        cmocka_unit_test(test_file_read),
        cmocka_unit_test(test_landmark_frames),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
