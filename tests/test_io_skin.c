/* io/: a glTF skin (mim_io_read_skin): round trips in every weight type,
 * files without a skin, other formats, and hostile files (bad joint
 * indices, bad weights, wrong types and counts, dangling node and skin
 * indices, truncated data), each with its code and a one-line message. */
#include "mim_io.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NJ 4

static mim_mesh_t mesh;
static char *dir;
static uint16_t *good_joints;
static float *good_weights[3]; /* per weight type: exact in that type */
static const char *const names[NJ] = {"mixamorig:Hips", "mixamorig:Spine", "mixamorig:LeftArm",
                                      "\xc3\x9cml\xc3\xa4ut \"quoted\" \\ name"};

/* Vertex v hangs on 1 to 4 distinct joints with non-zero weights that sum
 * to exactly 1 in quanta of 1/q; unused slots hold joint 0 and weight 0. */
static void make_skin(uint32_t nv, int q, uint16_t *j, float *w)
{
    for (uint32_t v = 0; v < nv; v++) {
        int k = (int)(v % 4) + 1, sum = 0, qi[4] = {0, 0, 0, 0};
        for (int i = 1; i < k; i++) sum += qi[i] = q / (k + i + (int)(v % 3));
        qi[0] = q - sum;
        for (int i = 0; i < 4; i++) {
            j[4 * v + i] = i < k ? (uint16_t)((v + (uint32_t)i) % NJ) : 0;
            w[4 * v + i] = (float)qi[i] / (float)q;
        }
    }
}

static int setup(void **state)
{
    (void)state;
    ts_polymesh_t pm;
    ts_sphere(&pm, 8, 12, 0.5f);
    ts_triangulate(&pm, &mesh);
    ts_polymesh_free(&pm);
    size_t n4 = 4 * (size_t)mesh.n_vertices;
    good_joints = malloc(n4 * sizeof *good_joints);
    static const int quanta[3] = {16, 255, 65535}; /* sixteenths are exact in float */
    for (int t = 0; t < 3; t++) {
        good_weights[t] = malloc(n4 * sizeof(float));
        make_skin(mesh.n_vertices, quanta[t], good_joints, good_weights[t]);
    }
    dir = ts_tempdir("io-skin");
    return dir ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    mim_mesh_free(&mesh);
    free(good_joints);
    for (int t = 0; t < 3; t++) free(good_weights[t]);
    ts_rmtree(dir);
    free(dir);
    return 0;
}

static void assert_zeroed(const mim_io_skin_t *s)
{
    assert_int_equal(s->n_vertices, 0);
    assert_int_equal(s->n_joints, 0);
    assert_null(s->joints);
    assert_null(s->weights);
    assert_null(s->names);
}

/* Expects mim_io_read_skin to fail with `code` and one line naming the file and `phrase`. */
static void expect_error(const char *path, int code, const char *phrase)
{
    mim_io_skin_t s;
    memset(&s, 0xab, sizeof s); /* the reader must zero it */
    mim_error_t err = {0};
    int rc = mim_io_read_skin(path, &s, &err);
    if (rc != code || !strstr(err.msg, path) || !strstr(err.msg, phrase))
        fprintf(stderr, "file %s: rc %d (%s), message: %s\n", path, rc, mim_strerror(rc), err.msg);
    assert_int_equal(rc, code);
    assert_int_equal(err.code, code);
    assert_ptr_equal(strstr(err.msg, path), err.msg); /* begins with the path */
    assert_non_null(strstr(err.msg, phrase));
    assert_null(strchr(err.msg, '\n'));
    assert_zeroed(&s);
}

static char *write_good(const char *name, int type)
{
    char *p = ts_path(dir, name);
    assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, good_joints, good_weights[type & 3], type), 0);
    return p;
}

/* Rewrites a GLB: `from` (found exactly once in the JSON chunk) becomes
 * `to`, and the BIN chunk keeps its first bin_keep bytes (SIZE_MAX: all). */
static void glb_patch(const char *path, const char *from, const char *to, size_t bin_keep)
{
    size_t len;
    unsigned char *b = (unsigned char *)ts_read_file(path, &len);
    assert_non_null(b);
    uint32_t jl, bl;
    memcpy(&jl, b + 12, 4);
    memcpy(&bl, b + 20 + jl, 4);
    char *json = malloc(jl + 1);
    memcpy(json, b + 20, jl);
    json[jl] = 0;
    char *at = strstr(json, from);
    if (!at) fprintf(stderr, "'%s' is not in %s\n", from, json);
    assert_non_null(at);
    assert_null(strstr(at + 1, from));
    size_t nl = jl - strlen(from) + strlen(to), npad = (nl + 3) & ~(size_t)3;
    size_t keep = bin_keep < bl ? bin_keep : bl, kpad = (keep + 3) & ~(size_t)3;
    size_t total = 12 + 8 + npad + 8 + kpad;
    unsigned char *o = calloc(1, total);
    memcpy(o, b, 12);
    uint32_t u = (uint32_t)total;
    memcpy(o + 8, &u, 4);
    u = (uint32_t)npad;
    memcpy(o + 12, &u, 4);
    memcpy(o + 16, "JSON", 4);
    size_t pre = (size_t)(at - json);
    memcpy(o + 20, json, pre);
    memcpy(o + 20 + pre, to, strlen(to));
    memcpy(o + 20 + pre + strlen(to), at + strlen(from), jl - pre - strlen(from));
    memset(o + 20 + nl, ' ', npad - nl);
    u = (uint32_t)kpad;
    memcpy(o + 20 + npad, &u, 4);
    memcpy(o + 24 + npad, "BIN\0", 4);
    memcpy(o + 28 + npad, b + 28 + jl, keep);
    assert_int_equal(ts_write_file(path, o, total), 0);
    free(o);
    free(json);
    free(b);
}

/* Reads the skin back and compares it with what was written. */
static void expect_round_trip(const char *p, const float *w_written, int exact)
{
    mim_io_skin_t s;
    mim_error_t err = {0};
    int rc = mim_io_read_skin(p, &s, &err);
    if (rc) fprintf(stderr, "%s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
    mim_mesh_t m;
    assert_int_equal(mim_io_read_mesh(p, &m, &err), 0);
    assert_int_equal(s.n_vertices, m.n_vertices);
    assert_int_equal(s.n_vertices, mesh.n_vertices);
    mim_mesh_free(&m);
    assert_int_equal(s.n_joints, NJ);
    for (uint32_t j = 0; j < NJ; j++) assert_string_equal(s.names[j], names[j]);
    assert_memory_equal(s.joints, good_joints, 4 * (size_t)s.n_vertices * sizeof *s.joints);
    for (uint32_t v = 0; v < s.n_vertices; v++) {
        double sum = 0;
        for (int k = 0; k < 4; k++) sum += s.weights[4 * v + k];
        assert_true(fabs(sum - 1) < 1e-6);
        for (int k = 0; k < 4; k++) {
            float got = s.weights[4 * v + k], want = w_written[4 * v + k];
            if (exact) assert_true(got == want);
            else assert_true(fabsf(got - want) < 1e-6f);
        }
    }
    mim_io_skin_free(&s);
    assert_zeroed(&s);
    mim_io_skin_free(&s); /* again: a no-op */
    mim_io_skin_free(NULL);
}

static void test_round_trip(void **state)
{
    (void)state;
    static const char *const files[] = {"float.glb", "u8.glb", "u16.glb"};
    int validate = ts_gltf_validator_available();
    for (int t = 0; t < 3; t++) {
        char *p = write_good(files[t], t);
        if (validate) ts_gltf_validate(p);
        /* floats in sixteenths come back exactly; k/255 and k/65535 within a rounding */
        expect_round_trip(p, good_weights[t], t == 0);
        free(p);
    }
    /* JOINTS_0 as unsigned byte */
    char *p = write_good("u8_joints.glb", 2 | TS_SKIN_JOINTS_U8);
    if (validate) ts_gltf_validate(p);
    expect_round_trip(p, good_weights[2], 0);
    free(p);
}

/* Weights that do not sum to 1 come back normalised; all zero stay zero. */
static void test_normalised(void **state)
{
    (void)state;
    size_t n4 = 4 * (size_t)mesh.n_vertices;
    float *w = malloc(n4 * sizeof *w);
    for (size_t i = 0; i < n4; i++) w[i] = good_weights[0][i] * 3.0f;
    for (int k = 0; k < 4; k++) w[4 * 2 + k] = 0; /* vertex 2: all zero */
    char *p = ts_path(dir, "unnormalised.glb");
    assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, good_joints, w, 0), 0);
    mim_io_skin_t s;
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_skin(p, &s, &err), 0);
    for (uint32_t v = 0; v < s.n_vertices; v++)
        for (int k = 0; k < 4; k++)
            assert_true(fabsf(s.weights[4 * v + k] - (v == 2 ? 0.0f : good_weights[0][4 * v + k])) < 1e-6f);
    mim_io_skin_free(&s);
    free(w);
    free(p);
}

/* A node without a name reads as ""; a long one is cut to fit, never
 * inside a UTF-8 character. */
static void test_names(void **state)
{
    (void)state;
    char longname[200] = "x"; /* then "aé"s (3 bytes each): byte 63 is inside an "é" */
    while (strlen(longname) < 150) strcat(longname, "a\xc3\xa9");
    const char *const odd[NJ] = {NULL, longname, "", "x"};
    char *p = ts_path(dir, "names.glb");
    assert_int_equal(ts_write_skinned_glb(p, &mesh, odd, NJ, good_joints, good_weights[0], 0), 0);
    mim_io_skin_t s;
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_skin(p, &s, &err), 0);
    assert_string_equal(s.names[0], "");
    assert_int_equal(strlen(s.names[1]), 62); /* "x", 20 "aé", "a": the "é" across byte 63 goes whole */
    assert_memory_equal(s.names[1], longname, 62);
    assert_string_equal(s.names[2], "");
    assert_string_equal(s.names[3], "x");
    mim_io_skin_free(&s);
    free(p);
}

/* The skin is the one the mesh's node names, not necessarily skins[0]. */
static void test_node_skin(void **state)
{
    (void)state;
    char *p = write_good("second_skin.glb", 0);
    glb_patch(p, "\"skins\":[{\"joints\":[1,2,3,4]}]", "\"skins\":[{\"joints\":[3]},{\"joints\":[1,2,3,4]}]",
              SIZE_MAX);
    glb_patch(p, "\"mesh\":0,\"skin\":0", "\"mesh\":0,\"skin\":1", SIZE_MAX);
    expect_round_trip(p, good_weights[0], 1);
    /* a node without a skin places its primitive unskinned, whatever
     * skins the file holds (glTF 2.0 3.7.3: the node names the skin) */
    glb_patch(p, "\"mesh\":0,\"skin\":1", "\"mesh\":0", SIZE_MAX);
    expect_error(p, MIM_ENOTFOUND, "has JOINTS_0 and WEIGHTS_0, but its node has no skin (2 skins in the file)");
    free(p);
}

static void test_no_skin(void **state)
{
    (void)state;
    ts_polymesh_t pm;
    ts_sphere(&pm, 6, 8, 1.0f);
    char *p = ts_path(dir, "plain.glb");
    assert_int_equal(ts_write_glb(p, &pm), 0);
    expect_error(p, MIM_ENOTFOUND, "no skin: no primitive of the scene is skinned");
    expect_error(p, MIM_ENOTFOUND, "none has JOINTS_0 or WEIGHTS_0");
    free(p);
    /* .gltf goes the same way */
    p = ts_path(dir, "plain.gltf");
    assert_int_equal(ts_write_gltf(p, &pm), 0);
    expect_error(p, MIM_ENOTFOUND, "none has JOINTS_0");
    free(p);
    /* JOINTS_0 and WEIGHTS_0 but no skin */
    p = write_good("no_skins.glb", 0);
    glb_patch(p, ",\"skin\":0}", "}", SIZE_MAX);
    glb_patch(p, "\"skins\":[{\"joints\":[1,2,3,4]}],", "", SIZE_MAX);
    expect_error(p, MIM_ENOTFOUND, "but its node has no skin (0 skins in the file)");
    free(p);
    /* one without the other */
    p = write_good("no_weights.glb", 0);
    glb_patch(p, ",\"WEIGHTS_0\":3", "", SIZE_MAX);
    expect_error(p, MIM_ENOTFOUND, "JOINTS_0 but no WEIGHTS_0");
    free(p);
    /* other formats */
    p = ts_path(dir, "s.ply");
    assert_int_equal(ts_write_ply_binary(p, &pm), 0);
    expect_error(p, MIM_ENOTFOUND, "glTF and GLB files only");
    free(p);
    /* no file: the mesh reader's error */
    p = ts_path(dir, "missing.glb");
    expect_error(p, MIM_ENOTFOUND, "cannot read");
    free(p);
    ts_polymesh_free(&pm);
}

/* Hostile files: each gets its code and a line that names the problem. */
static void test_bad_values(void **state)
{
    (void)state;
    size_t n4 = 4 * (size_t)mesh.n_vertices;
    uint16_t *j = malloc(n4 * sizeof *j);
    float *w = malloc(n4 * sizeof *w);
    char *p = ts_path(dir, "bad.glb");

    memcpy(j, good_joints, n4 * sizeof *j);
    j[4 * 5 + 1] = NJ;
    assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, j, good_weights[0], 0), 0);
    expect_error(p, MIM_EFORMAT, "JOINTS_0: vertex 5 refers to joint 4, but skin 0 has 4 joints");
    /* as unsigned byte too */
    assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, j, good_weights[1], 1 | TS_SKIN_JOINTS_U8), 0);
    expect_error(p, MIM_EFORMAT, "vertex 5 refers to joint 4");

    memcpy(w, good_weights[0], n4 * sizeof *w);
    w[4 * 7] = -0.25f;
    assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, good_joints, w, 0), 0);
    expect_error(p, MIM_EFORMAT, "WEIGHTS_0: vertex 7 has weight -0.25, not a finite number >= 0");

    memcpy(w, good_weights[0], n4 * sizeof *w);
    w[4 * 9 + 2] = NAN;
    assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, good_joints, w, 0), 0);
    expect_error(p, MIM_EFORMAT, "WEIGHTS_0: vertex 9 has weight nan");

    w[4 * 9 + 2] = INFINITY;
    assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, good_joints, w, 0), 0);
    expect_error(p, MIM_EFORMAT, "WEIGHTS_0: vertex 9 has weight inf");

    /* the mesh's own errors come first */
    mim_mesh_t bad;
    mim_mesh_alloc(&bad, mesh.n_vertices, mesh.n_faces);
    memcpy(bad.positions, mesh.positions, 12 * (size_t)mesh.n_vertices);
    memcpy(bad.faces, mesh.faces, 12 * (size_t)mesh.n_faces);
    bad.positions[4] = NAN;
    assert_int_equal(ts_write_skinned_glb(p, &bad, names, NJ, good_joints, good_weights[0], 0), 0);
    expect_error(p, MIM_ENONFINITE, "vertex 1 has a non-finite coordinate");
    mim_mesh_free(&bad);

    free(p);
    free(j);
    free(w);
}

/* fmt with "@N" replaced by the vertex count and "@M" by one less. */
static void subst(char *dst, size_t size, const char *fmt)
{
    size_t o = 0;
    for (const char *f = fmt; *f && o + 16 < size; f++) {
        if (f[0] == '@' && (f[1] == 'N' || f[1] == 'M')) {
            o += (size_t)snprintf(dst + o, size - o, "%u", mesh.n_vertices - (f[1] == 'M'));
            f++;
        } else {
            dst[o++] = *f;
        }
    }
    dst[o] = 0;
}

/* Patched JSON: wrong types, counts, dangling indices. */
static void test_bad_layout(void **state)
{
    (void)state;
    static const struct {
        int type;
        const char *from, *to;
        int code;
        const char *phrase;
    } cases[] = {
        {0, "\"bufferView\":2,\"componentType\":5123", "\"bufferView\":2,\"componentType\":5126", MIM_EFORMAT,
         "JOINTS_0 is VEC4 of float, not VEC4 of unsigned byte or unsigned short"},
        {0, "\"bufferView\":2,\"componentType\":5123", "\"bufferView\":2,\"componentType\":5122", MIM_EFORMAT,
         "JOINTS_0 is VEC4 of short, not VEC4"},
        {0, "\"count\":@N,\"type\":\"VEC4\"}]", "\"count\":@N,\"type\":\"VEC3\"}]", MIM_EFORMAT,
         "WEIGHTS_0 is VEC3 of float, not VEC4 of float or normalised unsigned byte or unsigned short"},
        {1, "\"componentType\":5121,\"normalized\":true,", "\"componentType\":5121,", MIM_EFORMAT,
         "WEIGHTS_0 is VEC4 of unsigned byte, not VEC4 of float or normalised"},
        {0, "\"bufferView\":2,\"componentType\":5123,\"count\":@N", "\"bufferView\":2,\"componentType\":5123,\"count\":@M",
         MIM_EFORMAT, "JOINTS_0 has @M elements, POSITION @N"},
        {0, "\"count\":@N,\"type\":\"VEC4\"}]", "\"count\":@M,\"type\":\"VEC4\"}]", MIM_EFORMAT,
         "WEIGHTS_0 has @M elements, POSITION @N"},
        {0, "\"skins\":[{\"joints\":[1,", "\"skins\":[{\"joints\":[99,", MIM_EFORMAT,
         "skin 0: joint 0 is node 99, not a valid node index (5 nodes)"},
        {0, "\"skins\":[{\"joints\":[1,2,3,4]", "\"skins\":[{\"joints\":[1,2,3,-1]", MIM_EFORMAT,
         "skin 0: joint 3 is node -1, not a valid node index"},
        {0, "\"skins\":[{\"joints\":[1,2,3,4]", "\"skins\":[{\"joints\":[]", MIM_EFORMAT, "skin 0 has no joints"},
        {0, "\"mesh\":0,\"skin\":0", "\"mesh\":0,\"skin\":3", MIM_EFORMAT, "node 0 refers to skin 3, but there are 1 skins"},
        {0, "\"JOINTS_0\":2", "\"JOINTS_0\":7", MIM_EFORMAT, "JOINTS_0: accessor 7 does not exist"},
        {0, "{\"bufferView\":3,", "{\"bufferView\":9,", MIM_EFORMAT, "WEIGHTS_0: accessor without a valid bufferView"},
    };
    char *p = ts_path(dir, "layout.glb");
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char from[256], to[256], phrase[256];
        subst(from, sizeof from, cases[i].from);
        subst(to, sizeof to, cases[i].to);
        subst(phrase, sizeof phrase, cases[i].phrase);
        assert_int_equal(ts_write_skinned_glb(p, &mesh, names, NJ, good_joints, good_weights[cases[i].type],
                                              cases[i].type),
                         0);
        glb_patch(p, from, to, SIZE_MAX);
        expect_error(p, cases[i].code, phrase);
    }
    free(p);
}

/* Skin data past the end of the file or of its buffer. */
static void test_truncated(void **state)
{
    (void)state;
    char *p = write_good("cut.glb", 0);
    size_t len;
    free(ts_read_file(p, &len));
    assert_int_equal(ts_truncate(p, len - 100), 0);
    expect_error(p, MIM_ETRUNCATED, "truncated");
    free(p);

    /* a consistent GLB whose buffer stops inside WEIGHTS_0 */
    p = write_good("short_buffer.glb", 0);
    size_t nv = mesh.n_vertices, full = 12 * nv + 12 * (size_t)mesh.n_faces + 8 * nv + 16 * nv, keep = full - 8 * nv;
    char from[64], to[64];
    snprintf(from, sizeof from, "\"buffers\":[{\"byteLength\":%zu}]", full);
    snprintf(to, sizeof to, "\"buffers\":[{\"byteLength\":%zu}]", keep);
    glb_patch(p, from, to, keep);
    expect_error(p, MIM_ETRUNCATED, "WEIGHTS_0: bufferView runs past the end of its buffer");
    free(p);

    /* a view that is shorter than its accessor */
    p = write_good("short_view.glb", 0);
    snprintf(from, sizeof from, "\"byteLength\":%zu,\"target\":34962}]", 16 * nv);
    snprintf(to, sizeof to, "\"byteLength\":%zu,\"target\":34962}]", 16 * nv - 4);
    glb_patch(p, from, to, SIZE_MAX);
    expect_error(p, MIM_ETRUNCATED, "WEIGHTS_0: accessor runs past the end of its bufferView");
    free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip), cmocka_unit_test(test_normalised), cmocka_unit_test(test_names),
        cmocka_unit_test(test_node_skin),  cmocka_unit_test(test_no_skin),    cmocka_unit_test(test_bad_values),
        cmocka_unit_test(test_bad_layout), cmocka_unit_test(test_truncated),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
