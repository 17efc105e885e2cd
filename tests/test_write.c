/* transfer/ writers: PLY/OBJ/OFF (OpenMesh) and GLB (tinygltf) round trips
 * through mimic's readers, the morph-target sequence GLB checked field by
 * field against its binary chunk, the Khronos glTF validator on every GLB
 * (node tests/gltf_validate.mjs; skipped when node or the npm package is
 * missing), and bad input leaving no file behind. */
#include "mim_io.h"
#include "mim_synth.h"
#include "mim_transfer.h"
#include "test_support.h"

#include <dirent.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define N_FRAMES 4u

static mim_synth_t *synth;
static mim_mesh_t body;        /* subject 0, pose 0 */
static float *frames;          /* N_FRAMES poses of subject 0 */
static char *dir;

static int setup(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_synth_options_t o = {.subjects = 1, .poses = N_FRAMES, .vertices = 1500, .seed = 3};
    if (mim_synth_create(&synth, &o, &err))
        return -1;
    uint32_t n = mim_synth_n_vertices(synth), nf = mim_synth_n_faces(synth);
    if (mim_mesh_alloc(&body, n, nf))
        return -1;
    memcpy(body.faces, mim_synth_faces(synth), 3 * (size_t)nf * sizeof *body.faces);
    frames = malloc(N_FRAMES * 3 * (size_t)n * sizeof *frames);
    if (!frames)
        return -1;
    for (uint32_t p = 0; p < N_FRAMES; p++)
        if (mim_synth_body(synth, 0, p, frames + 3 * (size_t)n * p))
            return -1;
    memcpy(body.positions, frames, 3 * (size_t)n * sizeof *frames);
    dir = ts_tempdir("write");
    return dir ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    mim_mesh_free(&body);
    free(frames);
    mim_synth_destroy(&synth);
    ts_rmtree(dir);
    free(dir);
    return 0;
}

static int exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* Entries of a folder other than . and .. */
static int count_entries(const char *d)
{
    DIR *h = opendir(d);
    assert_non_null(h);
    int n = 0;
    for (struct dirent *e; (e = readdir(h));)
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
            n++;
    closedir(h);
    return n;
}

/* Writes m as name, reads it back with mimic's reader, expects the same
 * faces and bit-identical positions (text formats print 9 significant
 * digits, which read back to the same float32). */
static void round_trip(const mim_mesh_t *m, const char *name)
{
    char *p = ts_path(dir, name);
    mim_error_t err = {0};
    int rc = mim_io_write_mesh(p, m, &err);
    if (rc)
        fprintf(stderr, "%s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
    char *tmp = ts_path(dir, name);
    tmp = realloc(tmp, strlen(tmp) + 5);
    strcat(tmp, ".tmp");
    assert_false(exists(tmp));
    mim_mesh_t back;
    rc = mim_io_read_mesh(p, &back, &err);
    if (rc)
        fprintf(stderr, "%s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
    assert_int_equal(back.n_vertices, m->n_vertices);
    assert_int_equal(back.n_faces, m->n_faces);
    assert_memory_equal(back.faces, m->faces, 3 * (size_t)m->n_faces * sizeof *m->faces);
    size_t differ = 0;
    for (size_t i = 0; i < 3 * (size_t)m->n_vertices; i++)
        differ += back.positions[i] != m->positions[i];
    if (differ)
        fprintf(stderr, "%s: %zu coordinates differ\n", name, differ);
    assert_int_equal(differ, 0);
    mim_mesh_free(&back);
    free(tmp);
    free(p);
}

static void test_round_trip_ply(void **s) { (void)s; round_trip(&body, "body.ply"); }
static void test_round_trip_obj(void **s) { (void)s; round_trip(&body, "body.obj"); }
static void test_round_trip_off(void **s) { (void)s; round_trip(&body, "body.off"); }
static void test_round_trip_glb(void **s) { (void)s; round_trip(&body, "body.glb"); }

static void test_ply_is_binary_le(void **state)
{
    (void)state;
    char *p = ts_path(dir, "hdr.PLY"); /* the extension in any case */
    mim_error_t err = {0};
    assert_int_equal(mim_io_write_mesh(p, &body, &err), 0);
    size_t len;
    char *text = ts_read_file(p, &len);
    assert_non_null(text);
    assert_non_null(strstr(text, "format binary_little_endian 1.0"));
    free(text);
    free(p);
}

/* Faces kept exactly as given, also when a half-edge mesh could not hold
 * them: three triangles on one edge, a vertex on no face. */
static void test_non_manifold(void **state)
{
    (void)state;
    static const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 5, 5, 5};
    static const uint32_t tri[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    mim_mesh_t m = {.n_vertices = 6, .n_faces = 3, .positions = (float *)pos, .faces = (uint32_t *)tri};
    round_trip(&m, "nm.ply");
    round_trip(&m, "nm.obj");
    round_trip(&m, "nm.off");
    round_trip(&m, "nm.glb");
}

/* A grid of more than 65535 vertices: 32-bit indices in the GLB. */
static void grid(mim_mesh_t *m, uint32_t side)
{
    assert_int_equal(mim_mesh_alloc(m, side * side, 2 * (side - 1) * (side - 1)), 0);
    for (uint32_t j = 0; j < side; j++)
        for (uint32_t i = 0; i < side; i++) {
            float *p = m->positions + 3 * ((size_t)j * side + i);
            p[0] = (float)i * 0.01f;
            p[1] = (float)j * 0.01f;
            p[2] = 0.05f * sinf((float)i * 0.1f) * cosf((float)j * 0.07f);
        }
    uint32_t *f = m->faces;
    for (uint32_t j = 0; j + 1 < side; j++)
        for (uint32_t i = 0; i + 1 < side; i++) {
            uint32_t a = j * side + i, b = a + 1, c = a + side, d = c + 1;
            *f++ = a, *f++ = b, *f++ = d;
            *f++ = a, *f++ = d, *f++ = c;
        }
}

/* ---- the GLB container, read in C: header, JSON chunk, BIN chunk ---- */
typedef struct glb {
    unsigned char *file;
    size_t size;
    json_t *json;
    const unsigned char *bin;
    uint32_t bin_size;
} glb_t;

static uint32_t u32le(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void glb_open(glb_t *g, const char *path)
{
    memset(g, 0, sizeof *g);
    g->file = (unsigned char *)ts_read_file(path, &g->size);
    assert_non_null(g->file);
    assert_true(g->size >= 28);
    assert_memory_equal(g->file, "glTF", 4);
    assert_int_equal(u32le(g->file + 4), 2);
    assert_int_equal(u32le(g->file + 8), g->size);
    uint32_t jlen = u32le(g->file + 12);
    assert_int_equal(u32le(g->file + 16), 0x4E4F534Au); /* JSON */
    assert_int_equal(jlen % 4, 0);
    assert_true(20 + (size_t)jlen + 8 <= g->size);
    json_error_t je;
    g->json = json_loadb((const char *)g->file + 20, jlen, 0, &je);
    if (!g->json)
        fprintf(stderr, "GLB JSON: %d:%d: %s\n", je.line, je.column, je.text);
    assert_non_null(g->json);
    const unsigned char *c = g->file + 20 + jlen;
    g->bin_size = u32le(c);
    assert_int_equal(u32le(c + 4), 0x004E4942u); /* BIN */
    assert_int_equal((size_t)(c + 8 - g->file) + g->bin_size, g->size);
    g->bin = c + 8;
}

static void glb_close(glb_t *g)
{
    json_decref(g->json);
    free(g->file);
}

static json_t *at(json_t *o, const char *key)
{
    json_t *v = json_object_get(o, key);
    if (!v)
        fprintf(stderr, "missing \"%s\"\n", key);
    assert_non_null(v);
    return v;
}

static json_t *accessor(const glb_t *g, json_int_t i)
{
    json_t *v = json_array_get(at(g->json, "accessors"), (size_t)i);
    assert_non_null(v);
    return v;
}

/* Float data of an accessor (count * comps), checked to lie in its view,
 * the view in the buffer, tightly packed and 4-byte aligned. */
static const float *accessor_floats(const glb_t *g, json_t *a, size_t comps, json_int_t want_target)
{
    assert_int_equal(json_integer_value(at(a, "componentType")), 5126);
    json_t *bv = json_array_get(at(g->json, "bufferViews"), (size_t)json_integer_value(at(a, "bufferView")));
    assert_non_null(bv);
    size_t off = (size_t)json_integer_value(json_object_get(bv, "byteOffset")) +
                 (size_t)json_integer_value(json_object_get(a, "byteOffset"));
    size_t count = (size_t)json_integer_value(at(a, "count"));
    assert_int_equal(off % 4, 0);
    assert_true(count * comps * 4 <= (size_t)json_integer_value(at(bv, "byteLength")));
    assert_true(off + count * comps * 4 <= g->bin_size);
    assert_null(json_object_get(bv, "byteStride"));
    assert_int_equal(json_integer_value(json_object_get(bv, "target")), want_target);
    return (const float *)(g->bin + off);
}

/* Declared min/max equal the data's, component by component. */
static void expect_minmax(json_t *a, const float *data, size_t count, size_t comps)
{
    json_t *mn = at(a, "min"), *mx = at(a, "max");
    assert_int_equal(json_array_size(mn), comps);
    assert_int_equal(json_array_size(mx), comps);
    for (size_t c = 0; c < comps; c++) {
        float lo = INFINITY, hi = -INFINITY;
        for (size_t i = 0; i < count; i++) {
            lo = fminf(lo, data[i * comps + c]);
            hi = fmaxf(hi, data[i * comps + c]);
        }
        assert_true((float)json_number_value(json_array_get(mn, c)) == lo);
        assert_true((float)json_number_value(json_array_get(mx, c)) == hi);
    }
}

static const char *const names[N_FRAMES] = {"rest", "key 1", "key 2", "key 3"};

/* Checks a sequence GLB against the frames and times it was written from. */
static void expect_sequence(const char *path, const double *times)
{
    uint32_t n = body.n_vertices, nt = N_FRAMES - 1;
    size_t per = 3 * (size_t)n;
    glb_t g;
    glb_open(&g, path);
    assert_string_equal(json_string_value(at(at(g.json, "asset"), "generator")), "mimic " MIM_VERSION);
    json_t *mesh = json_array_get(at(g.json, "meshes"), 0);
    json_t *prim = json_array_get(at(mesh, "primitives"), 0);
    json_t *attrs = at(prim, "attributes");

    /* indices: 16-bit below 65535 vertices, in an element array view */
    json_t *ia = accessor(&g, json_integer_value(at(prim, "indices")));
    assert_int_equal(json_integer_value(at(ia, "componentType")), 5123);
    assert_int_equal(json_integer_value(at(ia, "count")), 3 * (json_int_t)body.n_faces);
    json_t *ibv = json_array_get(at(g.json, "bufferViews"), (size_t)json_integer_value(at(ia, "bufferView")));
    assert_int_equal(json_integer_value(at(ibv, "target")), 34963);

    /* base POSITION = frame 0, with min/max; NORMALs of unit length */
    json_t *pa = accessor(&g, json_integer_value(at(attrs, "POSITION")));
    const float *base = accessor_floats(&g, pa, 3, 34962);
    assert_int_equal(json_integer_value(at(pa, "count")), n);
    assert_memory_equal(base, frames, per * sizeof(float));
    expect_minmax(pa, base, n, 3);
    json_t *na = accessor(&g, json_integer_value(at(attrs, "NORMAL")));
    const float *nrm = accessor_floats(&g, na, 3, 34962);
    for (uint32_t v = 0; v < n; v++) {
        const float *q = nrm + 3 * (size_t)v;
        assert_true(fabs(sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]) - 1) < 1e-5);
    }

    /* one target per later frame: its displacement, with min/max */
    json_t *targets = at(prim, "targets");
    assert_int_equal(json_array_size(targets), nt);
    for (uint32_t t = 0; t < nt; t++) {
        json_t *ta = accessor(&g, json_integer_value(at(json_array_get(targets, t), "POSITION")));
        assert_int_equal(json_integer_value(at(ta, "count")), n);
        const float *d = accessor_floats(&g, ta, 3, 34962);
        const float *want = frames + per * (t + 1);
        for (size_t i = 0; i < per; i++)
            assert_true(d[i] == want[i] - frames[i]);
        expect_minmax(ta, d, n, 3);
        assert_non_null(json_object_get(json_array_get(targets, t), "NORMAL"));
    }
    json_t *tn = at(at(mesh, "extras"), "targetNames");
    assert_int_equal(json_array_size(tn), nt);
    for (uint32_t t = 0; t < nt; t++)
        assert_string_equal(json_string_value(json_array_get(tn, t)), names[t + 1]);
    assert_string_equal(json_string_value(at(mesh, "name")), names[0]);
    assert_int_equal(json_array_size(at(mesh, "weights")), nt);

    /* the animation: one LINEAR weights channel on the mesh's node */
    json_t *anim = json_array_get(at(g.json, "animations"), 0);
    assert_non_null(anim);
    assert_string_equal(json_string_value(at(anim, "name")), "mimic");
    json_t *ch = json_array_get(at(anim, "channels"), 0);
    assert_string_equal(json_string_value(at(at(ch, "target"), "path")), "weights");
    json_int_t node = json_integer_value(at(at(ch, "target"), "node"));
    assert_int_equal(json_integer_value(at(json_array_get(at(g.json, "nodes"), (size_t)node), "mesh")), 0);
    json_t *smp = json_array_get(at(anim, "samplers"), (size_t)json_integer_value(at(ch, "sampler")));
    assert_string_equal(json_string_value(at(smp, "interpolation")), "LINEAR");
    json_t *in = accessor(&g, json_integer_value(at(smp, "input")));
    assert_int_equal(json_integer_value(at(in, "count")), N_FRAMES);
    const float *tt = accessor_floats(&g, in, 1, 0);
    for (uint32_t f = 0; f < N_FRAMES; f++)
        assert_true(tt[f] == (float)times[f]);
    expect_minmax(in, tt, N_FRAMES, 1);
    json_t *out = accessor(&g, json_integer_value(at(smp, "output")));
    assert_int_equal(json_integer_value(at(out, "count")), N_FRAMES * nt);
    const float *w = accessor_floats(&g, out, 1, 0);
    for (uint32_t f = 0; f < N_FRAMES; f++)
        for (uint32_t t = 0; t < nt; t++)
            assert_true(w[f * nt + t] == (f >= 1 && t == f - 1 ? 1.0f : 0.0f));
    glb_close(&g);
}

static void test_sequence(void **state)
{
    (void)state;
    mim_error_t err = {0};
    char *p = ts_path(dir, "seq.glb");
    mim_io_sequence_t seq = {.mesh = &body, .n_frames = N_FRAMES, .positions = frames, .names = names};
    int rc = mim_io_write_sequence_glb(p, &seq, &err); /* times NULL, fps 0: i / 30 */
    if (rc)
        fprintf(stderr, "%s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
    double t30[N_FRAMES];
    for (uint32_t f = 0; f < N_FRAMES; f++)
        t30[f] = f / 30.0;
    expect_sequence(p, t30);
    /* The base mesh reads back as frame 0. */
    mim_mesh_t back;
    assert_int_equal(mim_io_read_mesh(p, &back, &err), 0);
    assert_memory_equal(back.positions, frames, 3 * (size_t)body.n_vertices * sizeof(float));
    mim_mesh_free(&back);

    static const double times[N_FRAMES] = {0.0, 0.5, 1.25, 2.0};
    seq.times = times;
    mim_mesh_t no_pos = body;
    no_pos.positions = NULL; /* ignored by the sequence writer */
    seq.mesh = &no_pos;
    assert_int_equal(mim_io_write_sequence_glb(p, &seq, &err), 0);
    expect_sequence(p, times);
    free(p);
}

static void test_validator(void **state)
{
    (void)state;
    if (!ts_gltf_validator_available())
        skip();
    mim_error_t err = {0};
    char *one = ts_path(dir, "v_one.glb"), *seq_path = ts_path(dir, "v_seq.glb"), *big = ts_path(dir, "v_big.glb");
    assert_int_equal(mim_io_write_mesh(one, &body, &err), 0);
    ts_gltf_validate(one);
    mim_io_sequence_t seq = {.mesh = &body, .n_frames = N_FRAMES, .positions = frames, .names = names};
    assert_int_equal(mim_io_write_sequence_glb(seq_path, &seq, &err), 0);
    ts_gltf_validate(seq_path);
    mim_mesh_t g;
    grid(&g, 260); /* 67600 vertices: 32-bit indices */
    assert_int_equal(mim_io_write_mesh(big, &g, &err), 0);
    ts_gltf_validate(big);
    /* and the validator does catch a broken file: a POSITION min/max that lies */
    size_t len;
    char *bytes = ts_read_file(one, &len);
    assert_non_null(bytes);
    char *mn = strstr(bytes + 20, "\"min\":[");
    assert_non_null(mn);
    mn[7] = mn[7] == '9' ? '8' : '9'; /* first digit of the first minimum */
    char *bad = ts_path(dir, "v_bad.glb");
    assert_int_equal(ts_write_file(bad, bytes, len), 0);
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "node '%s/tests/gltf_validate.mjs' '%s' 2>&1", MIMIC_SOURCE_DIR, bad);
    int st;
    char *out = ts_run_capture(cmd, &st);
    assert_int_equal(st, 1);
    assert_non_null(strstr(out, "ACCESSOR_MIN_MISMATCH"));
    free(out);
    free(bytes);
    mim_mesh_free(&g);
    free(bad);
    free(one);
    free(seq_path);
    free(big);
}

static void test_big_round_trip(void **state)
{
    (void)state;
    mim_mesh_t g;
    grid(&g, 260);
    round_trip(&g, "big.glb");
    round_trip(&g, "big.ply");
    mim_mesh_free(&g);
}

/* ---- bad input: a clear error, and nothing (not even PATH.tmp) left ---- */
static void expect_error(int rc, int code, const mim_error_t *err, const char *needle, const char *bad_dir)
{
    if (rc != code || !strstr(err->msg, needle))
        fprintf(stderr, "rc %d, message \"%s\" (want %d with \"%s\")\n", rc, err->msg, code, needle);
    assert_int_equal(rc, code);
    assert_non_null(strstr(err->msg, needle));
    assert_int_equal(count_entries(bad_dir), 0);
}

static void test_bad_input(void **state)
{
    (void)state;
    char *bd = ts_path(dir, "bad");
    assert_int_equal(mkdir(bd, 0755), 0);
    char *p = ts_path(bd, "x.glb");
    mim_error_t err = {0};

    char *stl = ts_path(bd, "x.stl");
    expect_error(mim_io_write_mesh(stl, &body, &err), MIM_EINVAL, &err, ".ply, .obj, .off, .glb", bd);
    free(stl);
    mim_error_clear(&err);
    char *noext = ts_path(bd, "x");
    expect_error(mim_io_write_mesh(noext, &body, &err), MIM_EINVAL, &err, "unknown extension", bd);
    free(noext);

    mim_error_clear(&err);
    char *missing = ts_path(bd, "no/such/dir/x.ply");
    expect_error(mim_io_write_mesh(missing, &body, &err), MIM_EIO, &err, "No such file or directory", bd);
    assert_non_null(strstr(err.msg, missing));
    free(missing);

    /* the rename fails (a folder holds the name): the .tmp goes too */
    char *isdir = ts_path(bd, "d.off");
    assert_int_equal(mkdir(isdir, 0755), 0);
    mim_error_clear(&err);
    int rc = mim_io_write_mesh(isdir, &body, &err);
    assert_int_equal(rc, MIM_EIO);
    assert_int_equal(count_entries(bd), 1);
    rmdir(isdir);
    free(isdir);

    mim_mesh_t m;
    assert_int_equal(mim_mesh_alloc(&m, body.n_vertices, body.n_faces), 0);
    memcpy(m.positions, body.positions, 3 * (size_t)body.n_vertices * sizeof(float));
    memcpy(m.faces, body.faces, 3 * (size_t)body.n_faces * sizeof(uint32_t));
    m.positions[3 * 17 + 1] = NAN;
    const char *exts[] = {"x.ply", "x.obj", "x.off", "x.glb"};
    for (int i = 0; i < 4; i++) {
        char *q = ts_path(bd, exts[i]);
        mim_error_clear(&err);
        expect_error(mim_io_write_mesh(q, &m, &err), MIM_ENONFINITE, &err, "vertex 17", bd);
        free(q);
    }
    m.positions[3 * 17 + 1] = 0;
    m.faces[3 * 5 + 2] = body.n_vertices;
    mim_error_clear(&err);
    expect_error(mim_io_write_mesh(p, &m, &err), MIM_EINVAL, &err, "face 5", bd);
    m.faces[3 * 5 + 2] = 0;

    mim_mesh_t empty = {0};
    mim_error_clear(&err);
    expect_error(mim_io_write_mesh(p, &empty, &err), MIM_EINVAL, &err, "empty mesh", bd);
    mim_error_clear(&err);
    expect_error(mim_io_write_mesh(p, NULL, &err), MIM_EINVAL, &err, "no mesh", bd);

    mim_io_sequence_t seq = {.mesh = &body, .n_frames = 0, .positions = frames};
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_EINVAL, &err, "without frames", bd);
    seq.n_frames = N_FRAMES;
    double times[N_FRAMES] = {0, 0.1, 0.1, 0.3};
    seq.times = times;
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_EINVAL, &err, "frame 2", bd);
    times[2] = 0.05;
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_EINVAL, &err, "does not increase", bd);
    times[2] = 0.2;
    times[0] = -1;
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_EINVAL, &err, "frame 0", bd);
    seq.times = NULL;
    seq.fps = -5;
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_EINVAL, &err, "fps", bd);
    seq.fps = 0;
    char *ply = ts_path(bd, "x.ply");
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(ply, &seq, &err), MIM_EINVAL, &err, ".glb", bd);
    free(ply);
    /* NaN in a later frame names the frame and vertex */
    float *bad = malloc(N_FRAMES * 3 * (size_t)body.n_vertices * sizeof *bad);
    assert_non_null(bad);
    memcpy(bad, frames, N_FRAMES * 3 * (size_t)body.n_vertices * sizeof *bad);
    bad[3 * (size_t)body.n_vertices * 2 + 3 * 9] = INFINITY;
    seq.positions = bad;
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_ENONFINITE, &err, "frame 2, vertex 9", bd);
    seq.positions = frames;
    seq.mesh = &m;
    m.faces[7] = body.n_vertices + 4;
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_EINVAL, &err, "face 2", bd);

    /* frame names that are not UTF-8 cannot go into the JSON */
    m.faces[7] = body.faces[7];
    static const char *const bad_names[N_FRAMES] = {"rest", "a\xff", "b", "c"};
    seq.names = bad_names;
    mim_error_clear(&err);
    expect_error(mim_io_write_sequence_glb(p, &seq, &err), MIM_EINVAL, &err, "frame 1: name is not valid UTF-8", bd);
    seq.names = NULL;

    /* an existing file is replaced whole */
    m.faces[7] = body.faces[7];
    assert_int_equal(mim_io_write_sequence_glb(p, &seq, &err), 0);
    assert_int_equal(count_entries(bd), 1);

    free(bad);
    mim_mesh_free(&m);
    free(p);
    free(bd);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_ply), cmocka_unit_test(test_round_trip_obj),
        cmocka_unit_test(test_round_trip_off), cmocka_unit_test(test_round_trip_glb),
        cmocka_unit_test(test_ply_is_binary_le), cmocka_unit_test(test_non_manifold),
        cmocka_unit_test(test_sequence),       cmocka_unit_test(test_validator),
        cmocka_unit_test(test_big_round_trip), cmocka_unit_test(test_bad_input),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
