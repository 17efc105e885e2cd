/* core/: error texts and contexts, hashing, math, landmark maps, file
 * reading and atomic writing, the random generator, the landmark-array
 * parser, and the log and progress callbacks. */
#include "test_support.h"

#include <dirent.h>
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

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

/* Orientations in landmark frames (issue 17): all 17, a subset with nulls,
 * frames without them, and each bad input with its one line. */
static void test_landmark_frames_orientations(void **s)
{
    (void)s;
    static const char *lm4 = "[[0,0,0],[1,0,0],[0,1,0],[0,0,1]]";
    char text[4096];
    mim_error_t e = {0};
    mim_landmark_frames_t f;
    /* one frame, all 17 segments: segment i turned by i * 10 degrees about y
     * (w off 1 by 5e-4 for the pelvis: accepted and normalised) */
    size_t k = (size_t)snprintf(text, sizeof text, "{\"t\": 5, \"landmarks\": %s, \"orientations\": {", lm4);
    for (int i = 0; i < MIM_SEGMENTS; i++) {
        double a = i * 10 * M_PI / 180;
        k += (size_t)snprintf(text + k, sizeof text - k, "%s\"%s\": [0, %.17g, 0, %.17g]", i ? ", " : "",
                              mim_segment_names[i], sin(a / 2), i ? cos(a / 2) : 1.0005);
    }
    snprintf(text + k, sizeof text - k, "}}");
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "all", 4, 0, &f, &e), 0);
    assert_non_null(f.orientations);
    for (int i = 0; i < MIM_SEGMENTS; i++) {
        double a = i * 10 * M_PI / 180;
        const double *q = f.orientations + 4 * i;
        assert_int_equal(f.orient_present[i], 1);
        assert_true(fabs(q[0]) < 1e-12 && fabs(q[2]) < 1e-12);
        assert_true(fabs(q[1] - sin(a / 2)) < 1e-12 && fabs(q[3] - cos(a / 2)) < 1e-12);
    }
    mim_landmark_frames_free(&f);
    assert_null(f.orientations);

    /* a batch: a subset with a null (the rest absent), then a frame without */
    snprintf(text, sizeof text,
             "{\"frames\": [{\"landmarks\": %s, \"orientations\": {\"l_hand\": [1, 0, 0, 0], \"head\": null}},"
             " {\"landmarks\": %s}]}", lm4, lm4);
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "some", 4, 0, &f, &e), 0);
    assert_int_equal(f.n_frames, 2);
    for (int i = 0; i < 2 * MIM_SEGMENTS; i++) {
        const double *q = f.orientations + 4 * i;
        int hand = i == 9; /* l_hand in frame 0 */
        assert_int_equal(f.orient_present[i], hand);
        assert_true(q[0] == hand && q[1] == 0 && q[2] == 0 && q[3] == !hand);
    }
    mim_landmark_frames_free(&f);
    /* none anywhere: nothing allocated */
    snprintf(text, sizeof text, "{\"landmarks\": %s}", lm4);
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "none", 4, 0, &f, &e), 0);
    assert_null(f.orientations);
    assert_null(f.orient_present);
    mim_landmark_frames_free(&f);

    static const struct {
        const char *orient; /* the single frame's "orientations" value */
        int code;
        const char *msg;
    } bad[] = {
        {"[0, 0, 0, 1]", MIM_EFORMAT, "o: frame 0: \"orientations\" must be an object"},
        {"{\"pelvis\": [0, 0, 0, 1], \"l_elbow\": [0, 0, 0, 1]}", MIM_EFORMAT,
         "o: frame 0: orientation 'l_elbow' is not a vest segment (pelvis, chest, head, l_shoulder, r_shoulder, "
         "l_upperarm, r_upperarm, l_forearm, r_forearm, l_hand, r_hand, l_thigh, r_thigh, l_shin, r_shin, l_foot, "
         "r_foot)"},
        {"{\"head\": [0, 0, 1]}", MIM_EFORMAT, "o: frame 0, orientation 'head': expected [x, y, z, w] or null"},
        {"{\"head\": \"identity\"}", MIM_EFORMAT, "o: frame 0, orientation 'head': expected [x, y, z, w] or null"},
        {"{\"head\": [0, 0, 0, 1, 0]}", MIM_EFORMAT, "o: frame 0, orientation 'head': expected [x, y, z, w] or null"},
        {"{\"chest\": [0, 0, \"0\", 1]}", MIM_EFORMAT, "o: frame 0, orientation 'chest': z is not a number"},
        {"{\"r_foot\": [0, 0, 0, 1.7]}", MIM_EFORMAT, "o: frame 0: orientation 'r_foot' is not a unit quaternion (norm 1.7)"},
        {"{\"r_foot\": [0, 0, 0, 0.998]}", MIM_EFORMAT, "o: frame 0: orientation 'r_foot' is not a unit quaternion (norm 0.998)"},
        {"{\"r_foot\": [0, 0, 0, 0]}", MIM_EFORMAT, "o: frame 0: orientation 'r_foot' is not a unit quaternion (norm 0)"},
        /* past double's square: the norm is still told */
        {"{\"pelvis\": [1e200, 0, 0, 0]}", MIM_EFORMAT, "o: frame 0: orientation 'pelvis' is not a unit quaternion (norm 1e+200)"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        snprintf(text, sizeof text, "{\"landmarks\": %s, \"orientations\": %s}", lm4, bad[i].orient);
        e = (mim_error_t){0};
        assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "o", 4, 0, &f, &e), bad[i].code);
        assert_string_equal(e.msg, bad[i].msg);
        assert_null(f.orientations);
        assert_null(f.positions);
    }
    /* a bad frame after a good one names its frame */
    snprintf(text, sizeof text,
             "{\"frames\": [{\"landmarks\": %s}, {\"landmarks\": %s, \"orientations\": {\"hips\": null}}]}", lm4, lm4);
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "b.json", 4, 0, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "b.json: frame 1: orientation 'hips' is not a vest segment (pelvis, chest, "));
    /* orientations need the landmarks, in a batch and alone */
    snprintf(text, sizeof text, "{\"frames\": [{\"landmarks\": %s}, {\"orientations\": {}}]}", lm4);
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "b.json", 4, 0, &f, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "b.json: frame 1: \"orientations\" need the frame's \"landmarks\"");
    const char *alone = "{\"orientations\": {\"pelvis\": [0, 0, 0, 1]}}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(alone, strlen(alone), "a.json", 4, 0, &f, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "a.json: \"orientations\" need the frame's \"landmarks\"");
    /* beside "frames" they would belong to no frame */
    snprintf(text, sizeof text, "{\"frames\": [{\"landmarks\": %s}], \"orientations\": {}}", lm4);
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "c.json", 4, 0, &f, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "c.json: \"orientations\" belong in each frame of \"frames\"");
    /* a duplicate segment is a duplicate key */
    snprintf(text, sizeof text, "{\"landmarks\": %s, \"orientations\": {\"head\": null, \"head\": null}}", lm4);
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "d.json", 4, 0, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "duplicate"));
    /* the object parser alone, as the UDP reader calls it: no frame */
    json_t *j = json_loads("{\"l_foot\": [0, 0.6, 0, 0.8]}", 0, NULL);
    double q[4 * MIM_SEGMENTS];
    uint8_t have[MIM_SEGMENTS];
    e = (mim_error_t){0};
    assert_int_equal(mim_orientations_parse(j, "udp frame", -1, q, have, &e), 0);
    assert_true(have[15] == 1 && q[4 * 15 + 1] == 0.6 && have[14] == 0 && q[4 * 14 + 3] == 1);
    json_decref(j);
    j = json_loads("{\"l_foot\": [0, 0.6, 0, 0.9]}", 0, NULL);
    assert_int_equal(mim_orientations_parse(j, "udp frame", -1, q, have, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "udp frame: orientation 'l_foot' is not a unit quaternion (norm 1.08)");
    json_decref(j);
}

/* Entries of a folder other than . and .., and whether one has ".tmp" in
 * its name (a leftover of a write). */
static int count_entries(const char *dir, int *tmp_left)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    *tmp_left = 0;
    for (struct dirent *de; (de = readdir(d));) {
        if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
            continue;
        n++;
        if (strstr(de->d_name, ".tmp"))
            *tmp_left = 1;
    }
    closedir(d);
    return n;
}

/* Atomic write: the parts in order, the old content replaced whole, and a
 * failure leaves the old file (or nothing) and names the path. */
static void test_file_write_atomic(void **s)
{
    (void)s;
    char *dir = ts_tempdir("core-atomic"), *path = ts_path(dir, "f.txt");
    const char *old = "an old content, longer than the new one\n";
    assert_int_equal(ts_write_file(path, old, strlen(old)), 0);
    mim_file_part_t parts[3] = {{"new ", 4}, {"", 0}, {"bytes", 5}};
    mim_error_t e = {0};
    assert_int_equal(mim_file_write_atomic(path, parts, 3, &e), 0);
    size_t len;
    char *got = ts_read_file(path, &len);
    assert_non_null(got);
    assert_int_equal(len, 9);
    assert_memory_equal(got, "new bytes", 9);
    free(got);
    int tmp_left;
    assert_int_equal(count_entries(dir, &tmp_left), 1);
    assert_false(tmp_left);

    /* a folder that does not exist: an error naming the path, nothing made */
    char *missing = ts_path(dir, "missing/f.txt");
    e = (mim_error_t){0};
    assert_int_equal(mim_file_write_atomic(missing, parts, 3, &e), MIM_EIO);
    assert_non_null(strstr(e.msg, missing));
    assert_int_equal(count_entries(dir, &tmp_left), 1);
    struct stat st;
    assert_int_not_equal(stat(missing, &st), 0);

    /* the rename fails (a folder stands at the path): the temporary is gone */
    char *sub = ts_path(dir, "sub");
    assert_int_equal(mkdir(sub, 0777), 0);
    e = (mim_error_t){0};
    assert_int_equal(mim_file_write_atomic(sub, parts, 3, &e), MIM_EIO);
    assert_non_null(strstr(e.msg, sub));
    assert_int_equal(count_entries(dir, &tmp_left), 2);
    assert_false(tmp_left);
    assert_true(stat(sub, &st) == 0 && S_ISDIR(st.st_mode));

    /* the landmark map goes through it too: JSON and a newline, read back */
    uint32_t v[16];
    for (int i = 0; i < 16; i++) v[i] = (uint32_t)(10 * i);
    mim_landmark_map_t m, back;
    mim_landmarks_default(&m, v, 1000);
    char *lpath = ts_path(dir, "landmarks.json");
    assert_int_equal(mim_landmarks_write(&m, lpath, &e), 0);
    got = ts_read_file(lpath, &len);
    assert_true(got && len > 0 && got[len - 1] == '\n');
    free(got);
    assert_int_equal(mim_landmarks_read(&back, lpath, &e), 0);
    assert_memory_equal(back.vertex, v, sizeof v);
    assert_int_equal(count_entries(dir, &tmp_left), 3);
    assert_false(tmp_left);
    ts_rmtree(dir);
    free(lpath), free(sub), free(missing), free(path), free(dir);
}

/* A random unit quaternion: uniform over rotations (normalised 4D Gaussian). */
static mim_quat random_rotation(mim_rng_t *r)
{
    mim_quat q = {mim_rng_gauss(r), mim_rng_gauss(r), mim_rng_gauss(r), mim_rng_gauss(r)};
    return mim_quat_normalize(q);
}

/* The matrix of q built from mim_quat_rotate: its columns are the images
 * of the axes (mim_core.h's layout), independent of mim_quat_to_matrix. */
static void matrix_by_rotate(mim_quat q, double m[9])
{
    mim_vec3 c[3] = {mim_quat_rotate(q, mim_v3(1, 0, 0)), mim_quat_rotate(q, mim_v3(0, 1, 0)),
                     mim_quat_rotate(q, mim_v3(0, 0, 1))};
    for (int k = 0; k < 3; k++)
        m[3 * k] = c[k].x, m[3 * k + 1] = c[k].y, m[3 * k + 2] = c[k].z;
}

/* Matrix -> quaternion -> matrix, for random rotations and for the
 * half-turns about each axis that take every branch of Shepperd's method. */
static void test_quat_matrix(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 11, 0);
    mim_quat qs[1000 + 6];
    int n = 0;
    for (; n < 1000; n++) qs[n] = random_rotation(&r);
    for (int k = 0; k < 3; k++) { /* a trace of -1: only the diagonal branches work */
        mim_vec3 axis = mim_v3(k == 0, k == 1, k == 2);
        qs[n++] = mim_quat_axis_angle(axis, M_PI);
        qs[n++] = mim_quat_axis_angle(mim_v3_add(axis, mim_v3(0.01, 0.02, 0.03)), M_PI - 1e-3);
    }
    for (int i = 0; i < n; i++) {
        double m[9], m2[9];
        matrix_by_rotate(qs[i], m);
        mim_quat_to_matrix(qs[i], m2);
        for (int k = 0; k < 9; k++) assert_true(fabs(m[k] - m2[k]) < 1e-12);
        mim_quat q = mim_quat_from_matrix(m);
        assert_true(fabs(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w - 1) < 1e-12);
        /* the same rotation: q or -q */
        double d = q.x * qs[i].x + q.y * qs[i].y + q.z * qs[i].z + q.w * qs[i].w;
        assert_true(fabs(fabs(d) - 1) < 1e-12);
        mim_vec3 v = mim_v3(mim_rng_gauss(&r), mim_rng_gauss(&r), mim_rng_gauss(&r));
        mim_vec3 a = mim_quat_rotate(q, v), b = mim_quat_rotate(qs[i], v);
        assert_true(mim_v3_norm(mim_v3_sub(a, b)) < 1e-12 * (1 + mim_v3_norm(v)));
    }
    /* slerp: the ends, the short way round, and constant speed */
    mim_quat a = random_rotation(&r), b = random_rotation(&r);
    mim_quat nb = {-b.x, -b.y, -b.z, -b.w};
    for (int k = 0; k <= 4; k++) {
        double t = k / 4.0;
        mim_quat p = mim_quat_slerp(a, b, t), q = mim_quat_slerp(a, nb, t);
        assert_true(fabs(fabs(p.x * q.x + p.y * q.y + p.z * q.z + p.w * q.w) - 1) < 1e-12);
    }
    mim_quat h = mim_quat_slerp(a, b, 0.5), e0 = mim_quat_slerp(a, b, 0), e1 = mim_quat_slerp(a, b, 1);
    assert_true(fabs(fabs(e0.x * a.x + e0.y * a.y + e0.z * a.z + e0.w * a.w) - 1) < 1e-12);
    assert_true(fabs(fabs(e1.x * b.x + e1.y * b.y + e1.z * b.z + e1.w * b.w) - 1) < 1e-12);
    double da = fabs(h.x * a.x + h.y * a.y + h.z * a.z + h.w * a.w);
    double db = fabs(h.x * b.x + h.y * b.y + h.z * b.z + h.w * b.w);
    assert_true(fabs(da - db) < 1e-12);
}

/* Horn's best rotation: points turned by a random rotation give it back
 * (the fast root and the Jacobi fallback alike); with noise, no small turn
 * of the answer fits better; a line (any turn about it fits as well), a
 * plane, a point, and a matrix that is not finite give a unit quaternion. */
static double turned_residual(const double (*x)[3], const double (*y)[3], int n, mim_quat q)
{
    double s = 0;
    for (int i = 0; i < n; i++) {
        const mim_vec3 turned = mim_quat_rotate(q, mim_v3(x[i][0], x[i][1], x[i][2]));
        const double e = mim_v3_norm(mim_v3_sub(turned, mim_v3(y[i][0], y[i][1], y[i][2])));
        s += e * e;
    }
    return s;
}

static void test_best_rotation(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 12, 0);
    enum { P = 30 };
    for (int trial = 0; trial < 400; trial++) {
        double x[P][3], y[P][3], M[3][3] = {{0}};
        const int shape = trial % 4; /* 0 a cloud, 1 a plane, 2 a line, 3 noisy */
        const mim_quat q = random_rotation(&r);
        for (int i = 0; i < P; i++) {
            for (int c = 0; c < 3; c++) x[i][c] = mim_rng_gauss(&r);
            if (shape == 1) x[i][2] = 0.5 * x[i][0] - x[i][1];
            if (shape == 2) x[i][1] = 2 * x[i][0], x[i][2] = -x[i][0];
            const mim_vec3 t = mim_quat_rotate(q, mim_v3(x[i][0], x[i][1], x[i][2]));
            y[i][0] = t.x, y[i][1] = t.y, y[i][2] = t.z;
            if (shape == 3)
                for (int c = 0; c < 3; c++) y[i][c] += 0.3 * mim_rng_gauss(&r);
        }
        for (int i = 0; i < P; i++)
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) M[a][b] += x[i][a] * y[i][b];
        const mim_quat got = mim_quat_best_rotation((const double(*)[3])M);
        assert_true(fabs(got.x * got.x + got.y * got.y + got.z * got.z + got.w * got.w - 1) < 1e-12);
        const double best = turned_residual((const double(*)[3])x, (const double(*)[3])y, P, got);
        if (shape < 3) { /* an exact turn: found to the rounding (a line: any turn about it) */
            if (best > 1e-20 * P) fail_msg("trial %d (shape %d): residual %g", trial, shape, best);
            if (shape == 0) assert_true(fabs(fabs(got.x * q.x + got.y * q.y + got.z * q.z + got.w * q.w) - 1) < 1e-12);
            continue;
        }
        for (int k = 0; k < 20; k++) {
            const mim_vec3 axis = mim_v3_normalize(mim_v3(mim_rng_gauss(&r), mim_rng_gauss(&r), mim_rng_gauss(&r)));
            const mim_quat d = mim_quat_axis_angle(axis, 1e-4);
            const double other = turned_residual((const double(*)[3])x, (const double(*)[3])y, P, mim_quat_mul(d, got));
            if (other < best * (1 - 1e-12)) fail_msg("trial %d: a turned fit is better: %.17g < %.17g", trial, other, best);
        }
    }
    const double zero[3][3] = {{0}}, bad[3][3] = {{1, 0, 0}, {0, NAN, 0}, {0, 0, 1}};
    const mim_quat z = mim_quat_best_rotation(zero), b = mim_quat_best_rotation(bad);
    assert_true(fabs(z.x * z.x + z.y * z.y + z.z * z.z + z.w * z.w - 1) < 1e-12);
    assert_true(b.x == 0 && b.y == 0 && b.z == 0 && b.w == 1);
}

/* The generator: one stream per (seed, stream), pinned values (synth's
 * datasets are byte-identical for a seed only while these hold), ranges. */
static void test_rng(void **s)
{
    (void)s;
    mim_rng_t a, b, c;
    mim_rng_seed(&a, 1, 0);
    assert_true(mim_rng_u64(&a) == 0x85c61a300ec70fa1ULL);
    assert_true(mim_rng_u64(&a) == 0x4952c2a6e1ef0b78ULL);
    assert_true(mim_rng_u64(&a) == 0xf30f1e318359884bULL);
    mim_rng_seed(&a, 42, 7), mim_rng_seed(&b, 42, 7), mim_rng_seed(&c, 42, 8);
    int differ = 0;
    for (int i = 0; i < 100; i++) {
        uint64_t x = mim_rng_u64(&a);
        assert_true(x == mim_rng_u64(&b));
        differ += x != mim_rng_u64(&c);
    }
    assert_true(differ > 90);
    const uint64_t ns[] = {2, 3, 7, 1000, (1ULL << 63) + 1, UINT64_MAX};
    for (size_t k = 0; k < sizeof ns / sizeof ns[0]; k++) {
        int seen[3] = {0};
        for (int i = 0; i < 3000; i++) {
            uint64_t x = mim_rng_below(&a, ns[k]);
            assert_true(x < ns[k]);
            if (ns[k] == 3) seen[x]++;
        }
        if (ns[k] == 3) assert_true(seen[0] > 900 && seen[1] > 900 && seen[2] > 900);
    }
    assert_true(mim_rng_below(&a, 0) == 0 && mim_rng_below(&a, 1) == 0);
    double sum = 0, sq = 0;
    for (int i = 0; i < 20000; i++) {
        double u = mim_rng_unit(&a);
        assert_true(u >= 0 && u < 1);
        double g = mim_rng_gauss(&a);
        assert_true(isfinite(g));
        sum += g, sq += g * g;
    }
    assert_true(fabs(sum / 20000) < 0.03 && fabs(sq / 20000 - 1) < 0.05);
}

/* The landmark-array parser on its own: values and nulls, then each error
 * with its code and where it names. */
static void test_landmark_array(void **s)
{
    (void)s;
    float pos[3 * 4];
    uint8_t present[4];
    mim_error_t e = {0};
    json_t *ok = json_loads("[[1, 2, 3], null, [4, 5.5, -6], [0, 0, 0]]", 0, NULL);
    assert_int_equal(mim_landmark_array_parse(ok, 4, 1, "mem", 0, pos, present, &e), 0);
    assert_true(present[0] && !present[1] && present[2] && present[3]);
    assert_true(pos[1] == 2.0f && pos[7] == 5.5f && pos[8] == -6.0f && isnan(pos[3]));
    /* too many nulls for max_missing 0 */
    assert_int_equal(mim_landmark_array_parse(ok, 4, 0, "mem", 3, pos, present, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "mem: frame 3 has 1 missing landmarks, at most 0 allowed");
    /* the wrong count */
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_array_parse(ok, 5, 1, "mem", 2, pos, present, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "mem: frame 2 has 4 landmarks, the landmark map has 5");
    json_decref(ok);
    struct {
        const char *text;
        int code;
        const char *msg;
    } bad[] = {
        {"{\"a\": 1}", MIM_EFORMAT, "udp frame: \"landmarks\" must be an array"},
        {"[[1, 2, 3], [1, 2], [0, 0, 0], [0, 0, 0]]", MIM_EFORMAT,
         "udp frame, landmark 1: expected [x, y, z] or null"},
        {"[[1, 2, 3], [0, 0, 0], [0, \"y\", 0], [0, 0, 0]]", MIM_EFORMAT, "udp frame, landmark 2: y is not a number"},
        {"[[1, 2, 3], [0, 0, 0], [0, 0, 0], [0, 0, 1e300]]", MIM_ENONFINITE,
         "udp frame, landmark 3: z = 1e+300 is not a finite float"},
        {"[[1, 2, 3], [0, 0, 0], [0, 0, 0], [true, 0, 0]]", MIM_EFORMAT, "udp frame, landmark 3: x is not a number"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        json_t *j = json_loads(bad[i].text, 0, NULL);
        assert_non_null(j);
        e = (mim_error_t){0};
        assert_int_equal(mim_landmark_array_parse(j, 4, 4, "udp frame", -1, pos, present, &e), bad[i].code);
        assert_string_equal(e.msg, bad[i].msg);
        json_decref(j);
    }
}

/* The plausibility range (plausible.c): a body fits in a 10 m box, lies
 * within 1 km of the origin, is not a point; landmarks likewise, and no two
 * present landmarks at one point. One line each, naming what and where. */
static void test_body_check(void **s)
{
    (void)s;
    enum { N = 40 };
    float pos[3 * N];
    for (int i = 0; i < N; i++) /* a 1.8 m tall column of points */
        pos[3 * i] = 0.2f * (float)(i % 3), pos[3 * i + 1] = 1.8f * (float)i / (N - 1), pos[3 * i + 2] = 0.01f * (float)i;
    mim_error_t e = {0};
    assert_int_equal(mim_body_check(pos, N, "body.ply", &e), 0);
    /* one coordinate of 3e38 among a body's: the vertex and the box */
    pos[3 * 12 + 1] = 3e38f;
    assert_int_equal(mim_body_check(pos, N, "body.ply", &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "body.ply: vertex 12: coordinate y = 3e+38 outside the 10 m box a body fits in"));
    assert_null(strchr(e.msg, '\n'));
    pos[3 * 12 + 1] = 0.5f;
    /* every vertex at one point */
    float point[3 * N];
    for (int i = 0; i < 3 * N; i++) point[i] = 0.25f;
    e = (mim_error_t){0};
    assert_int_equal(mim_body_check(point, N, "point.ply", &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "point.ply: the 40 vertices span 0.0 mm: not a body (at least 10 mm)");
    /* all at 3e38: no spread, but far beyond the origin's reach */
    for (int i = 0; i < 3 * N; i++) point[i] = 3e38f;
    e = (mim_error_t){0};
    assert_int_equal(mim_body_check(point, N, "far.ply", &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "far.ply: vertex 0: coordinate x = 3e+38 is more than 1000 m from the origin"));
    /* a body in millimetres is outside the box too */
    float mm[3 * N];
    for (int i = 0; i < 3 * N; i++) mm[i] = pos[i] * 1000;
    e = (mim_error_t){0};
    assert_int_equal(mim_body_check(mm, N, "mm.ply", &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "span 1800 m along y"));
    /* a body 500 m from the origin is fine */
    for (int i = 0; i < N; i++) mm[3 * i] = pos[3 * i] + 500;
    for (int i = 0; i < N; i++) mm[3 * i + 1] = pos[3 * i + 1], mm[3 * i + 2] = pos[3 * i + 2];
    assert_int_equal(mim_body_check(mm, N, "there.ply", NULL), 0);
    /* not finite, and nothing at all */
    pos[3 * 5 + 2] = NAN;
    e = (mim_error_t){0};
    assert_int_equal(mim_body_check(pos, N, "nan.ply", &e), MIM_ENONFINITE);
    assert_string_equal(e.msg, "nan.ply: vertex 5: coordinate z = nan is not finite");
    e = (mim_error_t){0};
    assert_int_equal(mim_body_check(pos, 0, "none.ply", &e), MIM_EEMPTY);
}

static void test_landmarks_check(void **s)
{
    (void)s;
    /* a standing body's 16 landmarks (metres) */
    const float body[48] = {0, 1.6f, 0,     0, 1.3f, 0,      0, 1, 0,          0.2f, 1.4f, 0,
                            -0.2f, 1.4f, 0, 0.45f, 1.4f, 0, -0.45f, 1.4f, 0,   0.7f, 1.4f, 0,
                            -0.7f, 1.4f, 0, 0.1f, 0.95f, 0, -0.1f, 0.95f, 0,   0.1f, 0.5f, 0.02f,
                            -0.1f, 0.5f, 0.02f, 0.1f, 0.08f, 0, -0.1f, 0.08f, 0, 0, 1.15f, -0.05f};
    float p[48];
    uint8_t present[16];
    memset(present, 1, sizeof present);
    mim_error_t e = {0};
    assert_int_equal(mim_landmarks_check(body, present, 16, "f.json", 3, &e), 0);
    assert_int_equal(mim_landmarks_check(body, NULL, 16, "f.json", 3, &e), 0);
    /* 16 identical landmarks */
    for (int i = 0; i < 48; i++) p[i] = i % 3 == 1 ? 1.0f : 0.0f;
    assert_int_equal(mim_landmarks_check(p, present, 16, "f.json", 3, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "f.json: frame 3: landmarks span 0.0 mm: not a body (at least 10 mm)");
    /* 3e38 for one landmark */
    memcpy(p, body, sizeof p);
    p[3 * 7] = 3e38f;
    e = (mim_error_t){0};
    assert_int_equal(mim_landmarks_check(p, present, 16, "udp frame", -1, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "udp frame, landmark 7: coordinate x = 3e+38 outside the 10 m box a body fits in"));
    /* two landmarks at one point: the descriptor's segment between them has no direction */
    memcpy(p, body, sizeof p);
    memcpy(p + 3 * 4, p + 3 * 3, 12);
    e = (mim_error_t){0};
    assert_int_equal(mim_landmarks_check(p, present, 16, "q", 0, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "q: frame 0: landmarks 3 and 4 are at one point (0.2, 1.4, 0): the pose angles need a segment between them");
    /* ... unless one of them is lost */
    present[4] = 0;
    p[12] = p[13] = p[14] = NAN;
    assert_int_equal(mim_landmarks_check(p, present, 16, "q", 0, NULL), 0);
    /* everything lost passes (a vest frame may be all nulls); two close landmarks too */
    uint8_t none[16] = {0};
    assert_int_equal(mim_landmarks_check(p, none, 16, "q", 0, NULL), 0);
    uint8_t two[16] = {1, 1};
    float close[48] = {0, 1, 0, 0.004f, 1, 0};
    assert_int_equal(mim_landmarks_check(close, two, 16, "q", 0, NULL), 0);
    /* three within 10 mm are no skeleton */
    uint8_t three[16] = {1, 1, 1};
    close[6] = 0.002f, close[7] = 1.003f;
    e = (mim_error_t){0};
    assert_int_equal(mim_landmarks_check(close, three, 16, "q", -1, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "q: landmarks span 4.0 mm: not a body (at least 10 mm)");
}

/* Through the parser, which every landmark input uses: one line each. */
static void test_landmark_frames_implausible(void **s)
{
    (void)s;
    mim_landmark_frames_t f;
    mim_error_t e = {0};
    char text[2048];
    size_t k = (size_t)snprintf(text, sizeof text, "{\"frames\": [{\"landmarks\": [");
    for (int i = 0; i < 16; i++) k += (size_t)snprintf(text + k, sizeof text - k, "%s[0.1, 1.2, 0.3]", i ? ", " : "");
    snprintf(text + k, sizeof text - k, "]}]}");
    assert_int_equal(mim_landmark_frames_parse(text, strlen(text), "same.json", 16, 3, &f, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "same.json: frame 0: landmarks span 0.0 mm: not a body (at least 10 mm)");
    assert_null(f.positions);
    const char *big = "{\"landmarks\": [[0,0,0],[1,0,0],[0,3e38,0],[0,0,1]]}";
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_parse(big, strlen(big), "big.json", 4, 3, &f, &e), MIM_EFORMAT);
    assert_non_null(strstr(e.msg, "big.json: frame 0, landmark 2: coordinate y = 3e+38 outside the 10 m box"));
    json_t *j = json_loads("[[0, 1, 0], [0, 1, 0], null, [0.3, 1, 0]]", 0, NULL);
    float pos[12];
    uint8_t present[4];
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_array_parse(j, 4, 4, "udp frame", -1, pos, present, &e), MIM_EFORMAT);
    assert_string_equal(e.msg, "udp frame: landmarks 0 and 1 are at one point (0, 1, 0): the pose angles need a segment between them");
    json_decref(j);
}

/* mim_landmark_frames_read refuses a batch over 64 MiB, from a file (by its
 * size, before reading) or from a pipe (counting as it reads). */
static void test_landmark_frames_cap(void **s)
{
    (void)s;
    char *dir = ts_tempdir("cap");
    char *path = ts_path(dir, "huge.json");
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    assert_int_equal(ftruncate(fileno(fp), (off_t)MIM_LANDMARK_FRAMES_MAX_BYTES + 1), 0); /* sparse */
    fclose(fp);
    mim_landmark_frames_t f;
    mim_error_t e = {0};
    assert_int_equal(mim_landmark_frames_read(path, 16, 3, &f, &e), MIM_EUNSUPPORTED);
    assert_non_null(strstr(e.msg, "huge.json: 67108865 bytes (64.0 MiB), more than the 64 MiB a landmark batch may have"));
    assert_null(f.positions);
    /* a pipe has no size: the reader counts */
    char *fifo = ts_path(dir, "pipe.json");
    assert_int_equal(mkfifo(fifo, 0600), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        FILE *w = fopen(fifo, "wb");
        static char spaces[1 << 16];
        memset(spaces, ' ', sizeof spaces);
        for (size_t done = 0; w && done <= MIM_LANDMARK_FRAMES_MAX_BYTES; done += sizeof spaces)
            if (fwrite(spaces, 1, sizeof spaces, w) != sizeof spaces) break;
        _exit(0);
    }
    e = (mim_error_t){0};
    assert_int_equal(mim_landmark_frames_read(fifo, 16, 3, &f, &e), MIM_EUNSUPPORTED);
    assert_non_null(strstr(e.msg, "pipe.json: more than the 64 MiB a landmark batch may have (stopped reading at 67108864 bytes)"));
    int status;
    waitpid(pid, &status, 0);
    ts_rmtree(dir);
    free(fifo), free(path), free(dir);
}

typedef struct {
    int calls, phase[8], level;
    uint64_t done[8], total;
    char label[32], msg[64];
} heard_t;

static void hear_log(void *ctx, int level, const char *msg)
{
    heard_t *h = ctx;
    h->calls++, h->level = level;
    snprintf(h->msg, sizeof h->msg, "%s", msg);
}

static void hear_progress(void *ctx, int phase, const char *label, uint64_t done, uint64_t total)
{
    heard_t *h = ctx;
    if (h->calls < 8) h->phase[h->calls] = phase, h->done[h->calls] = done;
    h->calls++, h->total = total;
    snprintf(h->label, sizeof h->label, "%s", label);
}

/* The callbacks hear what the library says, in one line; NULL is quiet. */
static void test_callbacks(void **s)
{
    (void)s;
    heard_t h = {0};
    mim_log_emit(hear_log, &h, MIM_LOG_WARN, "%s: %d\nthings", "file.ply", 3);
    assert_int_equal(h.calls, 1);
    assert_int_equal(h.level, MIM_LOG_WARN);
    assert_string_equal(h.msg, "file.ply: 3 things");
    mim_log_emit(NULL, &h, MIM_LOG_ERROR, "nobody hears %d", 1);
    assert_int_equal(h.calls, 1);

    h = (heard_t){0};
    mim_progress_t p = {.fn = hear_progress, .ctx = &h};
    mim_progress_update(&p, 5); /* before begin: not reported */
    mim_progress_begin(&p, "work", 3);
    mim_progress_update(&p, 1);
    mim_progress_update(&p, 3);
    mim_progress_end(&p);
    mim_progress_end(&p); /* a second end: not reported */
    mim_progress_update(&p, 4);
    assert_int_equal(h.calls, 4);
    assert_string_equal(h.label, "work");
    assert_true(h.total == 3);
    int phases[4] = {MIM_PROGRESS_BEGIN, MIM_PROGRESS_STEP, MIM_PROGRESS_STEP, MIM_PROGRESS_END};
    uint64_t done[4] = {0, 1, 3, 3};
    for (int i = 0; i < 4; i++) {
        assert_int_equal(h.phase[i], phases[i]);
        assert_true(h.done[i] == done[i]);
    }
    /* the fn kept across runs; NULL is quiet and still counts */
    mim_progress_begin(&p, "again", 0);
    assert_int_equal(h.calls, 5);
    mim_progress_t quiet = {0};
    mim_progress_begin(&quiet, "quiet", 10);
    mim_progress_update(&quiet, 7);
    mim_progress_end(&quiet);
    assert_true(quiet.done == 7 && quiet.total == 10);
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
        cmocka_unit_test(test_landmark_frames_orientations),
        cmocka_unit_test(test_file_write_atomic),
        cmocka_unit_test(test_quat_matrix),
        cmocka_unit_test(test_rng),
        cmocka_unit_test(test_landmark_array),
        cmocka_unit_test(test_callbacks),
        cmocka_unit_test(test_body_check),
        cmocka_unit_test(test_landmarks_check),
        cmocka_unit_test(test_landmark_frames_implausible),
        cmocka_unit_test(test_landmark_frames_cap),
        cmocka_unit_test(test_best_rotation),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
