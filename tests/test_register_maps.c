/* The built-in landmark maps of known connectivities (register/known_maps.c),
 * the landmark file beside a mesh (core/landmark_file.c) and its name
 * (io/sidecar.c). The SHA-256 digests below were computed with Python's
 * hashlib over struct.pack('<...I', ...), independently of OpenSSL. */
#include "test_support.h"

#include "known_maps.h"
#include "mim_io.h"
#include "mim_register.h"
#include "mim_synth.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static void test_faces_sha256(void **state)
{
    (void)state;
    char hex[65];
    /* hashlib.sha256(struct.pack('<3I', 0, 1, 2)) */
    const uint32_t f012[3] = {0, 1, 2};
    mim_reg_faces_sha256(f012, 1, hex);
    assert_string_equal(hex, "ad5dc1478de06a4c2728ea528bd9361a4b945e92a414bf4d180cedaaeaa5f4cc");
    /* byte order: each index little-endian whatever the host's */
    const uint32_t wide[3] = {0x01020304u, 5, 0xfffffffeu};
    mim_reg_faces_sha256(wide, 1, hex);
    assert_string_equal(hex, "e726ddf16160bccf04490a432e18c41f6e597c2b874d4eec6f010824fc3f550b");
    /* no faces: the digest of nothing */
    mim_reg_faces_sha256(NULL, 0, hex);
    assert_string_equal(hex, "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    /* 1000 faces = 12000 bytes, across the 4096-byte chunks of the conversion:
     * v[i] = i * 2654435761 mod 2^32 */
    uint32_t *many = malloc(3000 * sizeof *many);
    assert_non_null(many);
    for (uint32_t i = 0; i < 3000; i++)
        many[i] = i * 2654435761u;
    mim_reg_faces_sha256(many, 1000, hex);
    assert_string_equal(hex, "db2644f1ee64a7330a5cdbbd3a36528f84bcf1aae953f507a4f0b0cffe4f5936");
    /* one index changed changes the digest */
    many[2999] ^= 1;
    mim_reg_faces_sha256(many, 1000, hex);
    assert_string_not_equal(hex, "db2644f1ee64a7330a5cdbbd3a36528f84bcf1aae953f507a4f0b0cffe4f5936");
    free(many);
}

static const char *builtin(const char *name)
{
    for (unsigned i = 0; i < mim__known_map_count; i++)
        if (strcmp(mim__known_map_names[i], name) == 0)
            return mim__known_map_texts[i];
    return NULL;
}

/* The "faces_sha256" member of a map's text (malloc'd). */
static char *sha_of(const char *text)
{
    json_t *root = json_loads(text, 0, NULL);
    assert_non_null(root);
    const char *s = json_string_value(json_object_get(root, "faces_sha256"));
    assert_non_null(s);
    char *copy = strdup(s);
    json_decref(root);
    return copy;
}

static void test_builtin_maps(void **state)
{
    (void)state;
    assert_true(mim__known_map_count >= 1);
    /* every built-in map parses and carries a fingerprint */
    for (unsigned i = 0; i < mim__known_map_count; i++) {
        mim_landmark_map_t m;
        mim_error_t err = {0};
        assert_int_equal(mim_landmarks_parse(&m, mim__known_map_texts[i], strlen(mim__known_map_texts[i]),
                                             mim__known_map_names[i], &err), 0);
        char *sha = sha_of(mim__known_map_texts[i]);
        assert_int_equal(strlen(sha), 64);
        free(sha);
    }
    const char *smpl = builtin("smpl-6890.json");
    assert_non_null(smpl);
    mim_landmark_map_t m;
    mim_error_t err = {0};
    assert_int_equal(mim_landmarks_parse(&m, smpl, strlen(smpl), "smpl", &err), 0);
    assert_int_equal(m.count, 16);
    assert_int_equal(m.topology_vertices, 6890);
    for (uint32_t i = 0; i < 16; i++) {
        assert_string_equal(m.names[i], mim_landmark_default_names[i]);
        assert_true(m.vertex[i] < 6890);
    }
    assert_int_equal(m.vertex[0], 412); /* head */
    assert_int_equal(m.mirror[3], 4);   /* l_shoulder <-> r_shoulder, paired by name */
    assert_int_equal(m.mirror[15], 15);
    /* the embedded text is the shared data file, byte for byte, when it is here */
    char *path = ts_path(ts_shared_data(), "landmark-maps/smpl-6890.json");
    size_t len;
    char *file = ts_read_file(path, &len);
    if (file) {
        assert_int_equal(len, strlen(smpl));
        assert_memory_equal(file, smpl, len);
    }
    free(file);
    free(path);
    /* matched through the internal function with its own fingerprint */
    char *sha = sha_of(smpl);
    mim_landmark_map_t got;
    assert_int_equal(mim__known_map_match(smpl, "smpl-6890.json", sha, 6890, &got, &err), 1);
    assert_int_equal(got.count, 16);
    assert_int_equal(got.vertex[15], m.vertex[15]);
    assert_int_equal(mim__known_map_match(smpl, "smpl-6890.json", sha, 6891, &got, &err), 0);
    free(sha);
}

static void test_unknown_meshes(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_synth_t *s = NULL;
    mim_synth_options_t o = {.subjects = 1, .poses = 1, .vertices = 800, .seed = 3};
    assert_int_equal(mim_synth_create(&s, &o, &err), 0);
    mim_landmark_map_t map;
    memset(&map, 0xab, sizeof map);
    const char *name = "untouched";
    const uint32_t *faces = mim_synth_faces(s);
    uint32_t nf = mim_synth_n_faces(s);
    assert_int_equal(mim_reg_known_map(faces, nf, mim_synth_n_vertices(s), &map, &name), 0);
    /* SMPL's vertex count with other faces is not SMPL */
    assert_int_equal(mim_reg_known_map(faces, nf, 6890, &map, &name), 0);
    uint32_t *f13776 = calloc(3 * 13776, sizeof *f13776);
    assert_non_null(f13776);
    for (uint32_t i = 0; i < 3 * 13776; i++)
        f13776[i] = (i * 7919u) % 6890u;
    assert_int_equal(mim_reg_known_map(f13776, 13776, 6890, &map, &name), 0);
    free(f13776);
    assert_string_equal(name, "untouched");
    assert_int_equal(map.count, 0xabababab); /* nothing written when unknown */
    mim_synth_destroy(&s);
}

/* A map of a 5-vertex connectivity, identified by hex. */
static char *test_map(const char *hex, uint32_t topology, uint32_t last_vertex)
{
    char *t = malloc(1024);
    assert_non_null(t);
    snprintf(t, 1024,
             "{\"topology_vertices\": %u, \"faces_sha256\": \"%s\", \"landmarks\": ["
             "{\"name\": \"head\", \"vertex\": 0}, {\"name\": \"l_hand\", \"vertex\": 1},"
             "{\"name\": \"r_hand\", \"vertex\": 2}, {\"name\": \"foot\", \"vertex\": %u}]}",
             topology, hex, last_vertex);
    return t;
}

static void test_known_map_match(void **state)
{
    (void)state;
    const uint32_t faces[9] = {0, 1, 2, 0, 2, 3, 1, 4, 2};
    char hex[65], other[65];
    mim_reg_faces_sha256(faces, 3, hex);
    mim_reg_faces_sha256(faces, 2, other);
    mim_landmark_map_t map;
    mim_error_t err = {0};
    char *t = test_map(hex, 5, 4);
    assert_int_equal(mim__known_map_match(t, "t.json", hex, 5, &map, &err), 1);
    assert_int_equal(map.count, 4);
    assert_int_equal(map.topology_vertices, 5);
    assert_int_equal(map.vertex[3], 4);
    assert_int_equal(map.mirror[1], 2); /* l_hand <-> r_hand */
    assert_int_equal(mim__known_map_match(t, "t.json", other, 5, &map, &err), 0); /* other faces */
    assert_int_equal(mim__known_map_match(t, "t.json", hex, 6, &map, &err), 0);   /* other vertex count */
    assert_int_equal(mim__known_map_match(t, "t.json", "", 5, &map, &err), 0);    /* a failed hash */
    assert_int_equal(err.code, 0);
    free(t);
    /* the digest in the file may be upper case */
    char upper[65];
    for (int i = 0; i < 65; i++)
        upper[i] = (char)(hex[i] >= 'a' && hex[i] <= 'f' ? hex[i] - 32 : hex[i]);
    t = test_map(upper, 5, 4);
    assert_int_equal(mim__known_map_match(t, "t.json", hex, 5, &map, &err), 1);
    free(t);
    /* a landmark past the vertex count is refused, naming the map */
    t = test_map(hex, 5, 5);
    assert_int_equal(mim__known_map_match(t, "t.json", hex, 5, &map, &err), MIM_EINDEX);
    assert_non_null(strstr(err.msg, "built-in map t.json"));
    free(t);
    /* a map without a fingerprint */
    mim_error_clear(&err);
    assert_int_equal(mim__known_map_match("{\"topology_vertices\": 5, \"landmarks\": []}", "bare.json", hex, 5, &map,
                                          &err),
                     MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "built-in map bare.json"));
    assert_non_null(strstr(err.msg, "faces_sha256"));
}

/* ---- mim_landmark_file_read ---- */

typedef struct files {
    char *dir;
    char path[4096];
} files_t;

static const char *put(files_t *f, const char *name, const char *text)
{
    snprintf(f->path, sizeof f->path, "%s/%s", f->dir, name);
    assert_int_equal(ts_write_file(f->path, text, strlen(text)), 0);
    return f->path;
}

/* One frame of 16 distinct positions, exact in binary (x = i/16, y = 1 + i/8,
 * z = (i % 3)/4), with landmark `null_at` written as null (-1: none). */
static char *frame_json(uint32_t n, int null_at)
{
    char *t = malloc(4096);
    assert_non_null(t);
    size_t k = (size_t)snprintf(t, 4096, "[");
    for (uint32_t i = 0; i < n; i++)
        k += (i == (uint32_t)null_at)
                 ? (size_t)snprintf(t + k, 4096 - k, "%snull", i ? ", " : "")
                 : (size_t)snprintf(t + k, 4096 - k, "%s[%g, %g, %g]", i ? ", " : "", i / 16.0, 1 + i / 8.0,
                                    (i % 3) / 4.0);
    snprintf(t + k, 4096 - k, "]");
    return t;
}

static int read_file(const char *path, uint32_t n, mim_landmark_file_kind_t *kind, mim_landmark_map_t *map,
                     float *pos, mim_error_t *err)
{
    mim_error_clear(err);
    *kind = 0;
    for (int i = 0; i < 3 * MIM_LANDMARKS_MAX; i++)
        pos[i] = -7.0f;
    memset(map, 0, sizeof *map);
    return mim_landmark_file_read(path, n, kind, map, pos, err);
}

static void test_landmark_file_forms(void **state)
{
    (void)state;
    files_t f = {ts_tempdir("lmfile"), ""};
    mim_landmark_file_kind_t kind;
    mim_landmark_map_t map;
    float pos[3 * MIM_LANDMARKS_MAX];
    mim_error_t err = {0};
    char text[8192];

    /* a map (mim_landmarks_to_json writes "topology_vertices") */
    uint32_t verts[16];
    for (uint32_t i = 0; i < 16; i++)
        verts[i] = 100 + 3 * i;
    mim_landmark_map_t def;
    mim_landmarks_default(&def, verts, 500);
    char *js = mim_landmarks_to_json(&def);
    assert_int_equal(read_file(put(&f, "map.json", js), 16, &kind, &map, pos, &err), 0);
    free(js);
    assert_int_equal(kind, MIM_LANDMARK_FILE_MAP);
    assert_int_equal(map.count, 16);
    assert_int_equal(map.topology_vertices, 500);
    assert_int_equal(map.vertex[7], 121);
    assert_true(pos[0] == -7.0f); /* positions untouched */
    /* a map without "topology_vertices" is still a map */
    assert_int_equal(read_file(put(&f, "bare.json",
                                   "{\"landmarks\": [{\"name\": \"a\", \"vertex\": 1}, {\"name\": \"b\", \"vertex\": 2},"
                                   "{\"name\": \"c\", \"vertex\": 3}, {\"name\": \"d\", \"vertex\": 4}]}"),
                         4, &kind, &map, pos, &err),
                     0);
    assert_int_equal(kind, MIM_LANDMARK_FILE_MAP);
    assert_int_equal(map.vertex[3], 4);
    /* ... of another count than asked */
    assert_int_equal(read_file(f.path, 16, &kind, &map, pos, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "landmark map has 4 landmarks, 16 expected"));

    /* positions, as one top-level frame */
    char *fr = frame_json(16, -1);
    snprintf(text, sizeof text, "{\"landmarks\": %s}", fr);
    assert_int_equal(read_file(put(&f, "one.json", text), 16, &kind, &map, pos, &err), 0);
    assert_int_equal(kind, MIM_LANDMARK_FILE_POSITIONS);
    for (uint32_t i = 0; i < 16; i++) {
        assert_true(pos[3 * i] == (float)(i / 16.0));
        assert_true(pos[3 * i + 1] == (float)(1 + i / 8.0));
        assert_true(pos[3 * i + 2] == (float)((i % 3) / 4.0));
    }
    assert_true(pos[48] == -7.0f); /* nothing past 16 */
    assert_int_equal(map.count, 0);  /* map untouched */
    /* ... and as a batch of one */
    snprintf(text, sizeof text, "{\"frames\": [{\"landmarks\": %s}]}", fr);
    assert_int_equal(read_file(put(&f, "frames1.json", text), 16, &kind, &map, pos, &err), 0);
    assert_int_equal(kind, MIM_LANDMARK_FILE_POSITIONS);
    assert_true(pos[3 * 15 + 1] == (float)(1 + 15 / 8.0));
    /* two frames: one mesh has one */
    snprintf(text, sizeof text, "{\"frames\": [{\"landmarks\": %s}, {\"landmarks\": %s}]}", fr, fr);
    assert_int_equal(read_file(put(&f, "frames2.json", text), 16, &kind, &map, pos, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "frames2.json: 2 frames: a landmark file for one mesh holds one"));
    free(fr);
    ts_rmtree(f.dir);
    free(f.dir);
}

static void test_landmark_file_errors(void **state)
{
    (void)state;
    files_t f = {ts_tempdir("lmfile-err"), ""};
    mim_landmark_file_kind_t kind;
    mim_landmark_map_t map;
    float pos[3 * MIM_LANDMARKS_MAX];
    mim_error_t err = {0};
    char text[8192], want[4200];

    /* a null landmark, named with the default names when there are 16 */
    char *fr = frame_json(16, 3);
    snprintf(text, sizeof text, "{\"landmarks\": %s}", fr);
    free(fr);
    const char *p = put(&f, "null.json", text);
    assert_int_equal(read_file(p, 16, &kind, &map, pos, &err), MIM_EFORMAT);
    snprintf(want, sizeof want, "%s: landmark 3 (l_shoulder) is missing: registration needs all of them", p);
    assert_string_equal(err.msg, want);
    /* ... by index otherwise */
    fr = frame_json(5, 4);
    snprintf(text, sizeof text, "{\"landmarks\": %s}", fr);
    free(fr);
    p = put(&f, "null5.json", text);
    assert_int_equal(read_file(p, 5, &kind, &map, pos, &err), MIM_EFORMAT);
    snprintf(want, sizeof want, "%s: landmark 4 is missing: registration needs all of them", p);
    assert_string_equal(err.msg, want);
    /* a wrong count (the frames parser's message) */
    fr = frame_json(15, -1);
    snprintf(text, sizeof text, "{\"landmarks\": %s}", fr);
    free(fr);
    assert_int_equal(read_file(put(&f, "count.json", text), 16, &kind, &map, pos, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "has 15 landmarks, the landmark map has 16"));
    /* malformed JSON: path:line:column */
    p = put(&f, "bad.json", "{\n  \"landmarks\": [[0, 1, 2],\n  oops\n");
    assert_int_equal(read_file(p, 16, &kind, &map, pos, &err), MIM_EFORMAT);
    size_t pl = strlen(p);
    int line = 0, col = 0;
    assert_memory_equal(err.msg, p, pl);
    assert_int_equal(sscanf(err.msg + pl, ":%d:%d:", &line, &col), 2);
    assert_int_equal(line, 3);
    assert_true(col > 0);
    /* missing file */
    snprintf(text, sizeof text, "%s/none.json", f.dir);
    assert_int_equal(read_file(text, 16, &kind, &map, pos, &err), MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "none.json"));
    /* over the frames reader's cap: refused from its size (a sparse file) */
    p = put(&f, "huge.json", "{}");
    assert_int_equal(truncate(p, (off_t)MIM_LANDMARK_FRAMES_MAX_BYTES + 1), 0);
    assert_int_equal(read_file(p, 16, &kind, &map, pos, &err), MIM_EUNSUPPORTED);
    assert_non_null(strstr(err.msg, "64 MiB"));
    /* bad arguments */
    assert_int_equal(read_file(p, 3, &kind, &map, pos, &err), MIM_EINVAL);
    assert_int_equal(mim_landmark_file_read(p, 16, NULL, &map, pos, &err), MIM_EINVAL);
    ts_rmtree(f.dir);
    free(f.dir);
}

/* ---- mim_io_landmarks_sidecar ---- */

static void test_sidecar(void **state)
{
    (void)state;
    char *dir = ts_tempdir("sidecar");
    char mesh[4096], want[4096], out[4096];
    snprintf(mesh, sizeof mesh, "%s/a.b.ply", dir);
    snprintf(want, sizeof want, "%s/a.b.landmarks.json", dir);
    assert_int_equal(mim_io_landmarks_sidecar(mesh, out, sizeof out), 0); /* not there yet */
    assert_string_equal(out, want);
    assert_int_equal(ts_write_file(want, "{}", 2), 0);
    assert_int_equal(mim_io_landmarks_sidecar(mesh, out, sizeof out), 1);
    assert_string_equal(out, want);
    /* a folder of that name is no landmark file */
    snprintf(mesh, sizeof mesh, "%s/c.obj", dir);
    snprintf(want, sizeof want, "%s/c.landmarks.json", dir);
    assert_int_equal(mkdir(want, 0755), 0);
    assert_int_equal(mim_io_landmarks_sidecar(mesh, out, sizeof out), 0);
    assert_string_equal(out, want);

    /* names */
    struct {
        const char *in, *out;
    } cases[] = {
        {"scan.ply", "scan.landmarks.json"},
        {"noext", "noext.landmarks.json"},
        {"d.x/noext", "d.x/noext.landmarks.json"}, /* a dot in a folder is no extension */
        {"d/.ply", "d/.ply.landmarks.json"},       /* nor a leading one */
        {"d/a.", "d/a.landmarks.json"},
        {"/abs/x.y.glb", "/abs/x.y.landmarks.json"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        assert_true(mim_io_landmarks_sidecar(cases[i].in, out, sizeof out) >= 0);
        assert_string_equal(out, cases[i].out);
    }
    /* size: exactly enough, then one byte short */
    size_t need = strlen("scan.landmarks.json") + 1;
    assert_true(mim_io_landmarks_sidecar("scan.ply", out, need) >= 0);
    assert_string_equal(out, "scan.landmarks.json");
    assert_int_equal(mim_io_landmarks_sidecar("scan.ply", out, need - 1), MIM_EINVAL);
    assert_int_equal(mim_io_landmarks_sidecar("scan.ply", out, 3), MIM_EINVAL);
    assert_int_equal(mim_io_landmarks_sidecar(NULL, out, sizeof out), MIM_EINVAL);
    ts_rmtree(dir);
    free(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_faces_sha256),
        cmocka_unit_test(test_builtin_maps),
        cmocka_unit_test(test_unknown_meshes),
        cmocka_unit_test(test_known_map_match),
        cmocka_unit_test(test_landmark_file_forms),
        cmocka_unit_test(test_landmark_file_errors),
        cmocka_unit_test(test_sidecar),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
