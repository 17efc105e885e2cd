/* support/rigged_avatar.c: every variant of the rigged glTF test avatars
 * (each property alone, each naming scheme, all at once, flat + cm + VRM 0)
 * is written, then checked against its info and against the file itself,
 * read back here with a small independent evaluator (jansson, node
 * transforms, the skin at its bind pose): counts, what a viewer shows
 * (= info->world), body height and facing, eyes at the head, boots outside
 * the feet, the sword in the right hand, the body's copies bitwise equal
 * (welded back to the synth's vertex count, in one piece), every shell
 * closed and facing out, names and VRM humanoid maps, the texture; and the
 * Khronos glTF validator's verdict when node and the package are there.
 * make_rigged_avatar is run once with good and bad arguments. */
#include "rigged_avatar.h"
#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum { L_HEAD = 0, L_LSHOULDER = 3, L_RWRIST = 8 };
enum { J_LFARM = 9, J_RFARM = 10, J_LHAND = 11, J_RHAND = 12 };

static char *dir;
static int validator;

typedef struct variant {
    const char *name;
    ra_options_t o;
} variant_t;

/* every property but flat and tpose, as make_rigged_avatar --all */
#define ALL .split_seams = 1, .joint_rings_first = 1, .shells = 1, .prop = 1, .centimetres = 1, .fists = 1, \
            .texture = 1, .two_primitives = 1
static const variant_t variants[] = {
    {"plain", {0}},
    {"tpose", {.tpose = 1}},
    {"seams", {.split_seams = 1}},
    {"flat", {.flat = 1}},
    {"rings_first", {.joint_rings_first = 1}},
    {"shells", {.shells = 1}},
    {"prop", {.prop = 1}},
    {"centimetres", {.centimetres = 1}},
    {"fists", {.fists = 1}},
    {"texture", {.texture = 1}},
    {"two_primitives", {.two_primitives = 1}},
    {"names_blender", {.names = RA_NAMES_BLENDER}},
    {"names_vrm0", {.names = RA_NAMES_VRM0}},
    {"names_vrm1", {.names = RA_NAMES_VRM1}},
    {"names_none", {.names = RA_NAMES_NONE}},
    {"all", {ALL}},
    {"flat_cm_vrm0", {.flat = 1, .centimetres = 1, .names = RA_NAMES_VRM0}},
    {"all_vrm0_tpose", {ALL, .tpose = 1, .names = RA_NAMES_VRM0}},
    {"all_flat_none", {ALL, .flat = 1, .names = RA_NAMES_NONE}},
    {"all_vrm1_subject2", {ALL, .names = RA_NAMES_VRM1, .subject = 2, .seed = 3}},
};
#define N_VARIANTS (sizeof variants / sizeof variants[0])

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("rigged-avatar");
    validator = ts_gltf_validator_available();
    return dir ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir);
    return 0;
}

/* ---- a small glTF evaluator, independent of the generator ---- */
typedef struct glb {
    char *file;
    size_t len;
    json_t *root;
    const unsigned char *bin;
    size_t bin_len;
} glb_t;

static json_t *jget(const json_t *o, const char *key) { return json_object_get(o, key); }
static long long jint(const json_t *o, const char *key) { return json_integer_value(json_object_get(o, key)); }
static json_t *jat(const json_t *root, const char *array, long long i)
{
    json_t *v = json_array_get(json_object_get(root, array), (size_t)i);
    assert_non_null(v);
    return v;
}

static void glb_load(glb_t *g, const char *path)
{
    memset(g, 0, sizeof *g);
    g->file = ts_read_file(path, &g->len);
    assert_non_null(g->file);
    assert_true(g->len >= 28);
    uint32_t h[5], bl;
    memcpy(h, g->file, 20);
    assert_memory_equal(g->file, "glTF", 4);
    assert_int_equal(h[1], 2);
    assert_int_equal(h[2], g->len);
    assert_int_equal(h[3] % 4, 0);
    assert_memory_equal(g->file + 16, "JSON", 4);
    json_error_t e;
    g->root = json_loadb(g->file + 20, h[3], 0, &e);
    if (!g->root) fprintf(stderr, "%s: JSON: %s (line %d)\n", path, e.text, e.line);
    assert_non_null(g->root);
    memcpy(&bl, g->file + 20 + h[3], 4);
    assert_memory_equal(g->file + 24 + h[3], "BIN\0", 4);
    assert_int_equal(bl % 4, 0);
    assert_int_equal(28 + (size_t)h[3] + bl, g->len);
    g->bin = (const unsigned char *)g->file + 28 + h[3];
    g->bin_len = bl;
    assert_true(jint(jat(g->root, "buffers", 0), "byteLength") <= (long long)bl);
}

static void glb_free(glb_t *g)
{
    json_decref(g->root);
    free(g->file);
}

/* Accessor a's data, checking its types, alignment and extent. */
static const unsigned char *acc_data(const glb_t *g, long long a, int ctype, const char *type, uint32_t *count)
{
    json_t *acc = jat(g->root, "accessors", a);
    assert_int_equal(jint(acc, "componentType"), ctype);
    assert_string_equal(json_string_value(jget(acc, "type")), type);
    *count = (uint32_t)jint(acc, "count");
    json_t *view = jat(g->root, "bufferViews", jint(acc, "bufferView"));
    assert_null(jget(view, "byteStride"));
    size_t off = (size_t)jint(view, "byteOffset") + (size_t)jint(acc, "byteOffset");
    size_t comps = !strcmp(type, "SCALAR") ? 1
                   : !strcmp(type, "VEC2") ? 2
                   : !strcmp(type, "VEC3") ? 3
                   : !strcmp(type, "VEC4") ? 4
                                           : 16;
    size_t csize = ctype == 5126 || ctype == 5125 ? 4 : ctype == 5123 ? 2 : 1;
    assert_int_equal(off % 4, 0);
    assert_true(*count * comps * csize <= (size_t)jint(view, "byteLength"));
    assert_true(off + *count * comps * csize <= g->bin_len);
    return g->bin + off;
}

static float f32(const unsigned char *p, size_t i)
{
    float f;
    memcpy(&f, p + 4 * i, 4);
    return f;
}

typedef struct mat4 {
    double m[16]; /* column-major, as glTF */
} mat4;

static mat4 mat_mul(mat4 a, mat4 b)
{
    mat4 r;
    for (int c = 0; c < 4; c++)
        for (int w = 0; w < 4; w++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a.m[4 * k + w] * b.m[4 * c + k];
            r.m[4 * c + w] = s;
        }
    return r;
}

static void mat_point(const mat4 *m, const double p[3], double out[3])
{
    for (int w = 0; w < 3; w++) out[w] = m->m[w] * p[0] + m->m[4 + w] * p[1] + m->m[8 + w] * p[2] + m->m[12 + w];
}

static double jnum(const json_t *a, size_t i) { return json_number_value(json_array_get(a, i)); }

/* A node's local matrix: T R S (or its matrix). */
static mat4 node_local(const json_t *node)
{
    mat4 r = {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}};
    json_t *m = jget(node, "matrix"), *t = jget(node, "translation"), *q = jget(node, "rotation"),
           *s = jget(node, "scale");
    if (m) {
        for (int i = 0; i < 16; i++) r.m[i] = jnum(m, (size_t)i);
        return r;
    }
    if (q) {
        double x = jnum(q, 0), y = jnum(q, 1), z = jnum(q, 2), w = jnum(q, 3);
        assert_true(fabs(x * x + y * y + z * z + w * w - 1) < 1e-6);
        double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                       2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                       2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
        for (int c = 0; c < 3; c++)
            for (int w2 = 0; w2 < 3; w2++) r.m[4 * c + w2] = R[3 * c + w2];
    }
    if (s)
        for (int c = 0; c < 3; c++)
            for (int w2 = 0; w2 < 3; w2++) r.m[4 * c + w2] *= jnum(s, (size_t)c);
    if (t)
        for (int w2 = 0; w2 < 3; w2++) r.m[12 + w2] = jnum(t, (size_t)w2);
    return r;
}

static void globals_from(const json_t *root, long long n, mat4 parent, mat4 *G, int *seen, long long *parent_of,
                         long long from)
{
    json_t *node = jat(root, "nodes", n);
    assert_false(seen[n]); /* a tree: every node once */
    seen[n] = 1;
    parent_of[n] = from;
    G[n] = mat_mul(parent, node_local(node));
    json_t *ch = jget(node, "children");
    for (size_t i = 0; i < json_array_size(ch); i++)
        globals_from(root, json_integer_value(json_array_get(ch, i)), G[n], G, seen, parent_of, n);
}

static int float_bits_cmp(const void *pa, const void *pb) { return memcmp(pa, pb, 12); }
static int pos_uv_cmp(const void *pa, const void *pb) { return memcmp(pa, pb, 20); }

/* Welded ids of positions (bitwise equal floats share one): out[v]; the count. */
static uint32_t weld(const float *pos, uint32_t nv, uint32_t *out)
{
    typedef struct {
        float p[3];
        uint32_t v;
    } wv_t;
    wv_t *w = malloc((nv + 1) * sizeof *w);
    for (uint32_t v = 0; v < nv; v++) memcpy(w[v].p, pos + 3 * (size_t)v, 12), w[v].v = v;
    qsort(w, nv, sizeof *w, float_bits_cmp);
    uint32_t n = 0;
    for (uint32_t i = 0; i < nv; i++) {
        if (i && memcmp(w[i].p, w[i - 1].p, 12)) n++;
        out[w[i].v] = n;
    }
    free(w);
    return nv ? n + 1 : 0;
}

static uint32_t uf_find(uint32_t *p, uint32_t a)
{
    while (p[a] != a) a = p[a] = p[p[a]];
    return a;
}

/* Connected components of a triangle set over n vertex ids. */
static uint32_t components(const uint32_t *tri, size_t nt, uint32_t n)
{
    uint32_t *p = malloc((n + 1) * sizeof *p), k = n;
    for (uint32_t i = 0; i < n; i++) p[i] = i;
    for (size_t t = 0; t < nt; t++)
        for (int e = 0; e < 2; e++) {
            uint32_t a = uf_find(p, tri[3 * t + (size_t)e]), b = uf_find(p, tri[3 * t + (size_t)e + 1]);
            if (a != b) p[a] = b, k--;
        }
    free(p);
    return k;
}

static int u64_cmp(const void *pa, const void *pb)
{
    uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
    return a < b ? -1 : a > b;
}

/* Closed and consistently oriented (each directed edge once, its reverse
 * once), facing out (positive volume). tri: welded ids; pos: by welded id. */
static void assert_closed(const char *what, const uint32_t *tri, size_t nt, const float *wpos)
{
    uint64_t *e = malloc((3 * nt + 1) * sizeof *e);
    double vol = 0;
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *f = tri + 3 * t;
        for (int k = 0; k < 3; k++) e[3 * t + (size_t)k] = (uint64_t)f[k] << 32 | f[(k + 1) % 3];
        const float *a = wpos + 3 * (size_t)f[0], *b = wpos + 3 * (size_t)f[1], *c = wpos + 3 * (size_t)f[2];
        vol +=
            (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) - a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
             a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) /
            6;
    }
    qsort(e, 3 * nt, sizeof *e, u64_cmp);
    size_t bad = 0;
    for (size_t i = 0; i < 3 * nt; i++) {
        uint64_t rev = e[i] << 32 | e[i] >> 32;
        if ((i && e[i] == e[i - 1]) || !bsearch(&rev, e, 3 * nt, sizeof *e, u64_cmp)) bad++;
    }
    if (bad || vol <= 0) fprintf(stderr, "%s: %zu bad edges, volume %g\n", what, bad, vol);
    assert_int_equal(bad, 0);
    assert_true(vol > 0);
    free(e);
}

/* What the evaluator sees of one primitive. */
typedef struct seen {
    uint32_t nv, nf;
    float *world;  /* 3 nv, metres */
    float *uv;     /* 2 nv, or NULL */
    uint32_t *idx; /* 3 nf */
    int skinned, has_uv;
} seen_t;

/* Every primitive of the file in meshes[] order, as a viewer shows it. */
static uint32_t evaluate(const glb_t *g, seen_t *out, uint32_t max)
{
    const json_t *root = g->root;
    size_t nn = json_array_size(jget(root, "nodes"));
    mat4 *G = calloc(nn, sizeof *G);
    int *seen = calloc(nn, sizeof *seen);
    long long *parent_of = calloc(nn, sizeof *parent_of);
    mat4 id = {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}};
    json_t *scene = jat(root, "scenes", jint(root, "scene"));
    for (size_t i = 0; i < json_array_size(jget(scene, "nodes")); i++)
        globals_from(root, json_integer_value(json_array_get(jget(scene, "nodes"), i)), id, G, seen, parent_of, -1);
    uint32_t np = 0;
    json_t *meshes = jget(root, "meshes");
    for (size_t m = 0; m < json_array_size(meshes); m++) {
        long long node = -1;
        for (size_t n = 0; n < nn; n++)
            if (jget(jat(root, "nodes", (long long)n), "mesh") &&
                jint(jat(root, "nodes", (long long)n), "mesh") == (long long)m) {
                assert_int_equal(node, -1); /* one node per mesh */
                node = (long long)n;
            }
        assert_true(node >= 0 && seen[node]);
        json_t *nd = jat(root, "nodes", node), *skin = jget(nd, "skin") ? jat(root, "skins", jint(nd, "skin")) : NULL;
        mat4 *jm = NULL;
        if (skin) { /* joint matrices: joint's global times its inverse bind matrix */
            json_t *joints = jget(skin, "joints");
            uint32_t nj;
            const unsigned char *ibm = acc_data(g, jint(skin, "inverseBindMatrices"), 5126, "MAT4", &nj);
            assert_int_equal(nj, json_array_size(joints));
            jm = malloc(nj * sizeof *jm);
            for (uint32_t j = 0; j < nj; j++) {
                mat4 b;
                for (int k = 0; k < 16; k++) b.m[k] = f32(ibm, 16 * (size_t)j + (size_t)k);
                assert_true(b.m[3] == 0 && b.m[7] == 0 && b.m[11] == 0 && b.m[15] == 1);
                jm[j] = mat_mul(G[json_integer_value(json_array_get(joints, j))], b);
            }
            assert_null(jget(nd, "translation")); /* ignored for a skinned mesh: not written */
            assert_int_equal(parent_of[node], -1);
        }
        json_t *prims = jget(jat(root, "meshes", (long long)m), "primitives");
        for (size_t k = 0; k < json_array_size(prims); k++) {
            assert_true(np < max);
            seen_t *s = &out[np++];
            json_t *pr = json_array_get(prims, k), *at = jget(pr, "attributes");
            assert_int_equal(jint(pr, "mode"), 4);
            const unsigned char *pos = acc_data(g, jint(at, "POSITION"), 5126, "VEC3", &s->nv), *nrm, *jd = NULL,
                                *wd = NULL;
            uint32_t c;
            assert_non_null(jget(jat(root, "accessors", jint(at, "POSITION")), "min"));
            nrm = acc_data(g, jint(at, "NORMAL"), 5126, "VEC3", &c);
            assert_int_equal(c, s->nv);
            s->has_uv = jget(at, "TEXCOORD_0") != NULL;
            if (s->has_uv) {
                const unsigned char *uv = acc_data(g, jint(at, "TEXCOORD_0"), 5126, "VEC2", &c);
                assert_int_equal(c, s->nv);
                s->uv = malloc(2 * (size_t)s->nv * sizeof *s->uv);
                for (size_t i = 0; i < 2 * (size_t)s->nv; i++) {
                    s->uv[i] = f32(uv, i);
                    assert_true(s->uv[i] >= 0 && s->uv[i] <= 1);
                }
            }
            s->skinned = jget(at, "JOINTS_0") != NULL;
            assert_int_equal(s->skinned, jget(at, "WEIGHTS_0") != NULL);
            assert_int_equal(s->skinned, skin != NULL);
            if (s->skinned) {
                jd = acc_data(g, jint(at, "JOINTS_0"), 5123, "VEC4", &c);
                assert_int_equal(c, s->nv);
                wd = acc_data(g, jint(at, "WEIGHTS_0"), 5126, "VEC4", &c);
                assert_int_equal(c, s->nv);
            }
            json_t *ia = jat(root, "accessors", jint(pr, "indices"));
            const int it = (int)jint(ia, "componentType");
            assert_true(it == 5123 || it == 5125);
            const unsigned char *ix = acc_data(g, jint(pr, "indices"), it, "SCALAR", &c);
            assert_int_equal(c % 3, 0);
            s->nf = c / 3;
            s->idx = malloc((c + 1) * sizeof *s->idx);
            for (uint32_t i = 0; i < c; i++) {
                uint16_t u16;
                if (it == 5123)
                    memcpy(&u16, ix + 2 * (size_t)i, 2), s->idx[i] = u16;
                else
                    memcpy(&s->idx[i], ix + 4 * (size_t)i, 4);
                assert_true(s->idx[i] < s->nv);
            }
            s->world = malloc((3 * (size_t)s->nv + 1) * sizeof *s->world);
            for (uint32_t v = 0; v < s->nv; v++) {
                double p[3] = {f32(pos, 3 * (size_t)v), f32(pos, 3 * (size_t)v + 1), f32(pos, 3 * (size_t)v + 2)}, w[3];
                double nl = 0;
                for (int a = 0; a < 3; a++) nl += pow(f32(nrm, 3 * (size_t)v + (size_t)a), 2);
                assert_true(fabs(sqrt(nl) - 1) < 1e-5);
                if (!skin) {
                    mat_point(&G[node], p, w);
                } else {
                    double sum = 0;
                    w[0] = w[1] = w[2] = 0;
                    for (int k2 = 0; k2 < 4; k2++) {
                        uint16_t j;
                        memcpy(&j, jd + 8 * (size_t)v + 2 * (size_t)k2, 2);
                        float wt = f32(wd, 4 * (size_t)v + (size_t)k2);
                        assert_true(wt >= 0);
                        assert_true(j < json_array_size(jget(skin, "joints")));
                        if (wt == 0) continue;
                        double q[3];
                        mat_point(&jm[j], p, q);
                        for (int a = 0; a < 3; a++) w[a] += wt * q[a];
                        sum += wt;
                    }
                    assert_true(fabs(sum - 1) < 1e-6);
                }
                for (int a = 0; a < 3; a++) s->world[3 * (size_t)v + (size_t)a] = (float)w[a];
            }
        }
        free(jm);
    }
    free(G), free(seen), free(parent_of);
    return np;
}

static long long node_named(const json_t *root, const char *name)
{
    for (size_t n = 0; n < json_array_size(jget(root, "nodes")); n++) {
        const char *s = json_string_value(jget(jat(root, "nodes", (long long)n), "name"));
        if (s && !strcmp(s, name)) return (long long)n;
    }
    return -1;
}

/* The rig as the naming scheme says: skin joint j is synth joint j. */
static void check_names(const glb_t *g, const ra_options_t *o, const ra_avatar_info_t *info)
{
    const json_t *root = g->root;
    json_t *skin = jget(root, "skins") ? jat(root, "skins", 0) : NULL;
    if (o->names == RA_NAMES_NONE) {
        assert_null(skin);
        assert_int_equal(node_named(root, "mixamorig:Hips"), -1);
        assert_int_equal(node_named(root, "hips"), -1);
        return;
    }
    assert_non_null(skin);
    json_t *joints = jget(skin, "joints");
    assert_int_equal(json_array_size(joints), RA_N_JOINTS);
    assert_int_equal(jint(skin, "skeleton"), json_integer_value(json_array_get(joints, 0)));
    long long hips = json_integer_value(json_array_get(joints, 0)),
              lhand = json_integer_value(json_array_get(joints, 11));
    if (o->names == RA_NAMES_MIXAMO) {
        assert_int_equal(node_named(root, "mixamorig:Hips"), hips);
        assert_int_equal(node_named(root, "mixamorig:LeftHand"), lhand);
        assert_int_equal(node_named(root, "mixamorig:Spine2"), json_integer_value(json_array_get(joints, 2)));
        assert_int_equal(node_named(root, "mixamorig:RightUpLeg"), json_integer_value(json_array_get(joints, 14)));
    } else if (o->names == RA_NAMES_BLENDER) {
        assert_int_equal(node_named(root, "hips"), hips);
        assert_int_equal(node_named(root, "hand.L"), lhand);
        assert_int_equal(node_named(root, "shoulder.R"), json_integer_value(json_array_get(joints, 6)));
    } else {
        assert_int_equal(node_named(root, "bone_00"), hips);
        const char *ext = o->names == RA_NAMES_VRM0 ? "VRM" : "VRMC_vrm";
        assert_string_equal(json_string_value(json_array_get(jget(root, "extensionsUsed"), 0)), ext);
        json_t *hb = jget(jget(jget(jget(root, "extensions"), ext), "humanoid"), "humanBones");
        long long h = -1, lh = -1, n = 0;
        if (o->names == RA_NAMES_VRM0) {
            assert_true(json_is_array(hb));
            for (size_t i = 0; i < json_array_size(hb); i++, n++) {
                const char *bone = json_string_value(jget(json_array_get(hb, i), "bone"));
                if (!strcmp(bone, "hips")) h = jint(json_array_get(hb, i), "node");
                if (!strcmp(bone, "leftHand")) lh = jint(json_array_get(hb, i), "node");
            }
        } else {
            assert_string_equal(json_string_value(jget(jget(jget(root, "extensions"), ext), "specVersion")), "1.0");
            assert_true(json_is_object(hb));
            n = (long long)json_object_size(hb);
            h = jint(jget(hb, "hips"), "node"), lh = jint(jget(hb, "leftHand"), "node");
        }
        assert_int_equal(n, RA_N_JOINTS);
        assert_int_equal(h, hips);
        assert_int_equal(lh, lhand);
    }
    /* the left hand is the avatar's own left: +X, or -X when it faces -Z (VRM 0) */
    const float *lw = info->joints + 3 * J_LHAND;
    assert_true(o->names == RA_NAMES_VRM0 ? lw[0] < -0.2f : lw[0] > 0.2f);
}

static void check_variant(void **state)
{
    const variant_t *var = *state;
    const ra_options_t *o = &var->o;
    char name[128], why[512];
    snprintf(name, sizeof name, "%s.glb", var->name);
    char *path = ts_path(dir, name);
    ra_avatar_info_t info;
    int rc = ra_write(o, path, &info, why, sizeof why);
    if (rc) fprintf(stderr, "%s: %s\n", var->name, why);
    assert_int_equal(rc, 0);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_true(st.st_size > 1000);

    /* counts and order */
    const uint32_t n_body = o->two_primitives ? 2 : 1;
    const uint32_t want = (o->joint_rings_first ? 1 : 0) + n_body + (o->shells ? 2 : 0) + (o->prop ? 1 : 0);
    assert_int_equal(info.n_primitives, want);
    uint32_t sum = 0, body_nv = 0, body_nf = 0, i0 = 0;
    if (o->joint_rings_first) assert_string_equal(info.primitive[i0++].mesh_name, "JointRings");
    for (uint32_t k = 0; k < n_body; k++) assert_string_equal(info.primitive[i0++].mesh_name, "Body");
    if (o->shells) {
        assert_string_equal(info.primitive[i0++].mesh_name, "Eyes");
        assert_string_equal(info.primitive[i0++].mesh_name, "Boots");
    }
    if (o->prop) assert_string_equal(info.primitive[i0++].mesh_name, "Sword");
    for (uint32_t i = 0; i < info.n_primitives; i++) {
        const ra_primitive_info_t *p = &info.primitive[i];
        assert_int_equal(p->is_body, !strcmp(p->mesh_name, "Body"));
        assert_true(p->n_vertices > 0 && p->n_faces > 0);
        if (o->flat) assert_int_equal(p->n_vertices, 3 * p->n_faces);
        sum += p->n_vertices;
        if (p->is_body) body_nv += p->n_vertices, body_nf += p->n_faces;
    }
    assert_int_equal(sum, info.n_vertices);
    assert_non_null(info.world);
    for (size_t k = 0; k < 3 * (size_t)info.n_vertices; k++) assert_true(isfinite(info.world[k]));

    /* the body: height, feet on the ground, its copies welded back */
    float *bw = malloc(3 * (size_t)body_nv * sizeof *bw);
    uint32_t *bid = malloc((body_nv + 1) * sizeof *bid), off = 0, boff = 0;
    float ylo = 1e9f, yhi = -1e9f;
    for (uint32_t i = 0; i < info.n_primitives; i++) {
        const ra_primitive_info_t *p = &info.primitive[i];
        if (p->is_body) {
            memcpy(bw + 3 * (size_t)boff, info.world + 3 * (size_t)off, 12 * (size_t)p->n_vertices);
            boff += p->n_vertices;
        }
        off += p->n_vertices;
    }
    for (uint32_t v = 0; v < body_nv; v++) ylo = fminf(ylo, bw[3 * v + 1]), yhi = fmaxf(yhi, bw[3 * v + 1]);
    assert_true(yhi - ylo > 1.4f && yhi - ylo < 2.1f);
    assert_true(fabsf(ylo) < 0.01f);
    const uint32_t welded = weld(bw, body_nv, bid);
    assert_int_equal(welded, info.n_body_welded);
    if (!o->flat && !o->split_seams && !o->two_primitives) assert_int_equal(body_nv, info.n_body_welded);
    if (o->flat || o->split_seams || o->two_primitives) assert_true(body_nv > info.n_body_welded);

    /* the front: +Z, or -Z for VRM 0 */
    const float front = o->names == RA_NAMES_VRM0 ? -1.0f : 1.0f;
    const float *head = info.landmarks + 3 * L_HEAD;
    assert_true(info.landmarks[3 * L_LSHOULDER] * front > 0.05f); /* own left: +X facing +Z */

    /* the file, evaluated independently, shows exactly info's vertices */
    glb_t g;
    glb_load(&g, path);
    seen_t seen[RA_MAX_PRIMITIVES];
    memset(seen, 0, sizeof seen);
    uint32_t np = evaluate(&g, seen, RA_MAX_PRIMITIVES);
    assert_int_equal(np, info.n_primitives);
    off = 0;
    double worst = 0;
    uint32_t *btri = malloc((3 * (size_t)body_nf + 1) * sizeof *btri), bt = 0, pieces = 0;
    boff = 0;
    for (uint32_t i = 0; i < np; i++) {
        const ra_primitive_info_t *p = &info.primitive[i];
        seen_t *s = &seen[i];
        assert_int_equal(s->nv, p->n_vertices);
        assert_int_equal(s->nf, p->n_faces);
        assert_int_equal(s->has_uv, o->texture || o->split_seams);
        assert_int_equal(s->skinned, o->names != RA_NAMES_NONE && strcmp(p->mesh_name, "Sword"));
        for (size_t k = 0; k < 3 * (size_t)s->nv; k++)
            worst = fmax(worst, fabs((double)s->world[k] - info.world[3 * (size_t)off + k]));
        if (p->is_body) {
            for (size_t k = 0; k < 3 * (size_t)s->nf; k++) btri[3 * (size_t)bt + k] = bid[boff + s->idx[k]];
            bt += s->nf;
            /* split seams: several pieces by index, before welding */
            pieces += components(s->idx, s->nf, s->nv);
            if (o->split_seams && !o->flat) { /* a seam's copies differ in their UVs */
                float *pu = malloc(20 * (size_t)s->nv);
                for (uint32_t v = 0; v < s->nv; v++)
                    memcpy(pu + 5 * (size_t)v, s->world + 3 * (size_t)v, 12),
                        memcpy(pu + 5 * (size_t)v + 3, s->uv + 2 * (size_t)v, 8);
                qsort(pu, s->nv, 20, pos_uv_cmp);
                for (uint32_t v = 1; v < s->nv; v++)
                    assert_true(memcmp(pu + 5 * (size_t)v, pu + 5 * (size_t)v - 5, 20) != 0);
                free(pu);
            }
            boff += s->nv;
        } else {
            uint32_t *id = malloc((s->nv + 1) * sizeof *id), *tri = malloc((3 * (size_t)s->nf + 1) * sizeof *tri);
            uint32_t nw = weld(info.world + 3 * (size_t)off, s->nv, id);
            float *wp = malloc((3 * (size_t)nw + 1) * sizeof *wp);
            for (uint32_t v = 0; v < s->nv; v++) memcpy(wp + 3 * (size_t)id[v], info.world + 3 * ((size_t)off + v), 12);
            for (size_t k = 0; k < 3 * (size_t)s->nf; k++) tri[k] = id[s->idx[k]];
            assert_closed(p->mesh_name, tri, s->nf, wp);
            free(id), free(tri), free(wp);
        }
        /* what each shell is and where */
        const float *w = info.world + 3 * (size_t)off;
        if (!strcmp(p->mesh_name, "Eyes")) {
            double cz = 0;
            for (uint32_t v = 0; v < s->nv; v++) {
                float d = 0;
                for (int a = 0; a < 3; a++) d += (w[3 * v + a] - head[a]) * (w[3 * v + a] - head[a]);
                assert_true(sqrtf(d) < 0.16f);
                cz += (w[3 * v + 2] - info.joints[3 * 4 + 2]) / s->nv;
            }
            assert_true(cz * front > 0.03); /* in front of the head joint */
        } else if (!strcmp(p->mesh_name, "Boots")) {
            uint32_t outside = 0;
            for (uint32_t v = 0; v < s->nv; v++) {
                float best = 1e9f;
                for (uint32_t b = 0; b < body_nv; b++) {
                    float d = 0;
                    for (int a = 0; a < 3; a++) d += (w[3 * v + a] - bw[3 * b + a]) * (w[3 * v + a] - bw[3 * b + a]);
                    best = fminf(best, d);
                }
                outside += sqrtf(best) > 0.0035f && sqrtf(best) < 0.03f;
                assert_true(w[3 * v + 1] < info.joints[3 * 17 + 1] + 0.03f);
            }
            assert_true(outside >= s->nv * 9 / 10); /* all but the caps' centres and a few */
        } else if (!strcmp(p->mesh_name, "Sword")) {
            const float *h = info.joints + 3 * J_RHAND;
            float reach = 0, tip_y = 1e9f;
            double c[3] = {0, 0, 0}, ax[3] = {0, 0, 0}, far = 0, tlo = 1e9, thi = -1e9;
            for (uint32_t v = 0; v < s->nv; v++) {
                float d[3] = {w[3 * v] - h[0], w[3 * v + 1] - h[1], w[3 * v + 2] - h[2]};
                if (d[2] * front > reach) reach = d[2] * front, tip_y = d[1];
                for (int a = 0; a < 3; a++) c[a] += w[3 * v + a] / (double)s->nv;
            }
            /* held in the hand: the blade's axis (centre to the farthest corner) passes by the wrist */
            for (uint32_t v = 0; v < s->nv; v++) {
                double d[3] = {w[3 * v] - c[0], w[3 * v + 1] - c[1], w[3 * v + 2] - c[2]};
                double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                if (l > far) far = l, ax[0] = d[0] / l, ax[1] = d[1] / l, ax[2] = d[2] / l;
            }
            for (uint32_t v = 0; v < s->nv; v++) {
                double t = 0;
                for (int a = 0; a < 3; a++) t += (w[3 * v + a] - c[a]) * ax[a];
                tlo = fmin(tlo, t), thi = fmax(thi, t);
            }
            assert_true(thi - tlo > 0.75 && thi - tlo < 0.85); /* 0.8 m long */
            double th = 0, off2 = 0;
            for (int a = 0; a < 3; a++) th += (h[a] - c[a]) * ax[a];
            th = fmax(tlo, fmin(thi, th));
            for (int a = 0; a < 3; a++) off2 += pow(h[a] - (c[a] + th * ax[a]), 2);
            assert_true(sqrt(off2) < 0.06);
            assert_true(reach > 0.45f); /* pointing forwards */
            assert_true(tip_y < -0.1f); /* and down */
        }
        off += s->nv;
    }
    if (worst > 2e-5) fprintf(stderr, "%s: the file shows info's vertices %g m apart\n", var->name, worst);
    assert_true(worst <= 2e-5);
    /* the body: one closed piece once welded */
    float *bp = malloc((3 * (size_t)welded + 1) * sizeof *bp);
    for (uint32_t v = 0; v < body_nv; v++) memcpy(bp + 3 * (size_t)bid[v], bw + 3 * (size_t)v, 12);
    assert_int_equal(components(btri, bt, welded), 1);
    /* split seams: several pieces by index (an island per body part), one once welded */
    if (o->split_seams)
        assert_true(pieces >= 5);
    else
        assert_int_equal(pieces, o->flat ? body_nf : n_body);
    assert_closed("Body", btri, bt, bp);
    free(bp);

    /* the layout a reader meets */
    const json_t *root = g.root;
    assert_string_equal(json_string_value(jget(jat(root, "meshes", 0), "name")),
                        o->joint_rings_first ? "JointRings" : "Body");
    long long first_node = json_integer_value(json_array_get(jget(jat(root, "scenes", 0), "nodes"), 0));
    if (o->names == RA_NAMES_NONE) /* the mesh nodes under Armature, first */
        first_node = json_integer_value(json_array_get(jget(jat(root, "nodes", first_node), "children"), 0));
    assert_int_equal(jint(jat(root, "nodes", first_node), "mesh"), 0);
    long long arm = node_named(root, "Armature");
    assert_true(arm >= 0);
    json_t *scale = jget(jat(root, "nodes", arm), "scale");
    if (o->centimetres)
        assert_true(scale && jnum(scale, 0) == 0.01 && jnum(scale, 1) == 0.01 && jnum(scale, 2) == 0.01);
    else
        assert_null(scale);
    json_t *body0 = json_array_get(jget(jat(root, "meshes", o->joint_rings_first ? 1 : 0), "primitives"), 0);
    float pmax = (float)jnum(jget(jat(root, "accessors", jint(jget(body0, "attributes"), "POSITION")), "max"), 1);
    assert_true(o->centimetres ? pmax > 100 : pmax < 2.5f);
    if (o->prop) { /* the sword's node hangs on the right hand's joint node */
        long long sw = node_named(root, "Sword");
        json_t *sn = jat(root, "nodes", sw);
        assert_non_null(jget(sn, "rotation"));
        assert_null(jget(sn, "skin"));
        long long rh = -1;
        for (size_t n = 0; n < json_array_size(jget(root, "nodes")); n++) {
            json_t *ch = jget(jat(root, "nodes", (long long)n), "children");
            for (size_t c = 0; c < json_array_size(ch); c++)
                if (json_integer_value(json_array_get(ch, c)) == sw) rh = (long long)n;
        }
        json_t *skin = jget(root, "skins") ? jat(root, "skins", 0) : NULL;
        if (skin)
            assert_int_equal(rh, json_integer_value(json_array_get(jget(skin, "joints"), J_RHAND)));
        else
            assert_true(rh >= 0);
    }
    if (o->texture) {
        json_t *img = jat(root, "images", 0);
        assert_string_equal(json_string_value(jget(img, "mimeType")), "image/png");
        json_t *view = jat(root, "bufferViews", jint(img, "bufferView"));
        assert_memory_equal(g.bin + jint(view, "byteOffset"), "\x89PNG\r\n\x1a\n", 8);
        assert_non_null(
            jget(jget(jget(jat(root, "materials", 0), "pbrMetallicRoughness"), "baseColorTexture"), "index"));
        assert_int_equal(json_array_size(jget(root, "samplers")), 1);
    } else {
        assert_null(jget(root, "images"));
    }
    check_names(&g, o, &info);

    /* the validator: no error, no warning; VRM 0's extension name "VRM"
     * breaks glTF's PREFIX_name rule, a warning every real VRM 0 file gets */
    if (validator) {
        if (o->names != RA_NAMES_VRM0) {
            ts_gltf_validate(path);
        } else {
            char cmd[4096];
            snprintf(cmd, sizeof cmd, "node '%s/tests/gltf_validate.mjs' '%s' 2>&1", MIMIC_SOURCE_DIR, path);
            int vst;
            char *out = ts_run_capture(cmd, &vst);
            int ok = vst == 0 && strstr(out, ": 0 errors, 1 warnings") &&
                     strstr(out, "warning: INVALID_EXTENSION_NAME_FORMAT: Extension name has invalid format. "
                                 "(at /extensionsUsed/0)");
            if (!ok) fprintf(stderr, "%s", out);
            assert_true(ok);
            free(out);
        }
    }

    for (uint32_t i = 0; i < np; i++) free(seen[i].world), free(seen[i].uv), free(seen[i].idx);
    glb_free(&g);
    free(btri), free(bw), free(bid);
    ra_info_free(&info);
    assert_null(info.world);
    free(path);
}

/* How far the body (primitive 0) reaches past the right wrist along the
 * forearm's direction, among its vertices within 0.3 m of the wrist. */
static float hand_reach(const ra_avatar_info_t *info)
{
    const float *f = info->joints + 3 * J_RFARM, *h = info->joints + 3 * J_RHAND;
    float d[3] = {h[0] - f[0], h[1] - f[1], h[2] - f[2]}, r = 0;
    float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (uint32_t v = 0; v < info->primitive[0].n_vertices; v++) {
        const float *p = info->world + 3 * (size_t)v;
        float q[3] = {p[0] - h[0], p[1] - h[1], p[2] - h[2]};
        if (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] < 0.3f * 0.3f)
            r = fmaxf(r, (q[0] * d[0] + q[1] * d[1] + q[2] * d[2]) / l);
    }
    return r;
}

/* Fists: the hand no longer reaches its length past the wrist. */
static void test_fists(void **state)
{
    (void)state;
    char *path = ts_path(dir, "fists_cmp.glb"), why[512];
    ra_avatar_info_t open_hand, fist;
    assert_int_equal(ra_write(&(ra_options_t){0}, path, &open_hand, why, sizeof why), 0);
    assert_int_equal(ra_write(&(ra_options_t){.fists = 1}, path, &fist, why, sizeof why), 0);
    float a = hand_reach(&open_hand), b = hand_reach(&fist);
    assert_true(a > 0.14f);
    assert_true(b < 0.12f && b > 0.06f);
    assert_int_equal(open_hand.n_vertices, fist.n_vertices);
    ra_info_free(&open_hand);
    ra_info_free(&fist);
    free(path);
}

/* Same options, same bytes; another seed, other bytes. */
static void test_deterministic(void **state)
{
    (void)state;
    char *a = ts_path(dir, "det_a.glb"), *b = ts_path(dir, "det_b.glb"), *c = ts_path(dir, "det_c.glb"), why[512];
    ra_options_t o = {ALL, .vertices = 1500};
    assert_int_equal(ra_write(&o, a, NULL, why, sizeof why), 0);
    assert_int_equal(ra_write(&o, b, NULL, why, sizeof why), 0);
    o.seed = 11;
    assert_int_equal(ra_write(&o, c, NULL, why, sizeof why), 0);
    size_t la, lb, lc;
    char *da = ts_read_file(a, &la), *db = ts_read_file(b, &lb), *dc = ts_read_file(c, &lc);
    assert_true(la == lb && memcmp(da, db, la) == 0);
    assert_false(la == lc && memcmp(da, dc, la) == 0);
    free(da), free(db), free(dc), free(a), free(b), free(c);
}

static void test_bad_options(void **state)
{
    (void)state;
    char *path = ts_path(dir, "bad.glb"), why[512];
    ra_avatar_info_t info;
    why[0] = 0;
    assert_int_equal(ra_write(&(ra_options_t){.names = (ra_names_t)7}, path, &info, why, sizeof why), MIM_EINVAL);
    assert_non_null(strstr(why, "naming scheme"));
    assert_null(info.world);
    assert_int_equal(ra_write(&(ra_options_t){.vertices = 10}, path, &info, why, sizeof why), MIM_EINVAL);
    assert_non_null(strstr(why, "synth"));
    char *deep = ts_path(dir, "no/such/folder/x.glb");
    assert_int_equal(ra_write(&(ra_options_t){0}, deep, &info, why, sizeof why), MIM_EIO);
    assert_non_null(strstr(why, deep));
    assert_null(strchr(why, '\n'));
    assert_null(info.world);
    ra_info_free(NULL);
    free(deep), free(path);
}

static void test_cli(void **state)
{
    (void)state;
    char *path = ts_path(dir, "cli.glb"), cmd[8192];
    snprintf(cmd, sizeof cmd, "'%s' '%s' --all --vertices 2000 --names vrm1 2>&1", MAKE_RIGGED_AVATAR, path);
    int st;
    char *out = ts_run_capture(cmd, &st);
    assert_int_equal(st, 0);
    json_error_t e;
    json_t *j = json_loads(out, 0, &e);
    assert_non_null(j);
    assert_int_equal(json_integer_value(json_object_get(j, "primitives")), 6);
    assert_true(json_integer_value(json_object_get(j, "vertices")) > 2000);
    json_decref(j);
    free(out);
    static const char *const bad[] = {"--names vrm2", "--vertices x", "--bogus", "--seed", ""};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(cmd, sizeof cmd, "'%s' %s%s%s %s 2>&1", MAKE_RIGGED_AVATAR, i < 4 ? "'" : "", i < 4 ? path : "",
                 i < 4 ? "'" : "", bad[i]);
        out = ts_run_capture(cmd, &st);
        assert_int_equal(st, 1);
        assert_non_null(strstr(out, "make_rigged_avatar"));
        assert_ptr_equal(strchr(out, '\n'), out + strlen(out) - 1); /* one line */
        free(out);
    }
    free(path);
}

int main(void)
{
    struct CMUnitTest tests[N_VARIANTS + 4];
    for (size_t i = 0; i < N_VARIANTS; i++)
        tests[i] = (struct CMUnitTest){variants[i].name, check_variant, NULL, NULL, (void *)&variants[i]};
    tests[N_VARIANTS] = (struct CMUnitTest)cmocka_unit_test(test_fists);
    tests[N_VARIANTS + 1] = (struct CMUnitTest)cmocka_unit_test(test_deterministic);
    tests[N_VARIANTS + 2] = (struct CMUnitTest)cmocka_unit_test(test_bad_options);
    tests[N_VARIANTS + 3] = (struct CMUnitTest)cmocka_unit_test(test_cli);
    return cmocka_run_group_tests(tests, setup, teardown);
}
