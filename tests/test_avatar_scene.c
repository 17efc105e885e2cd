/* Issue 28: the user's own avatar as its author shipped it. Rigged GLB
 * avatars made by support/rigged_avatar.c (several meshes with the body
 * not first, UV seams, flat shading, shells, a sword under the hand's
 * bone, centimetres under a node scale, Mixamo / Blender / VRM 0 / VRM 1
 * names, closed fists, an A- or a T-pose, a texture) are driven by
 * `mimic transfer` and `mimic morph` with no landmark file:
 *   - every primitive is read, placed by its node and skin, in scene order;
 *   - the landmarks come from the rig, where synth puts them;
 *   - the output has the input's primitives, each with its vertices in
 *     order, its UVs and material, the image embedded, and validates;
 *   - no output tears: at most 0.2 % of the triangles have an edge
 *     stretched over 3x their rest length, none over 8x; the sword stays
 *     rigid;
 *   - bad avatars get one line naming the file. */
#include "mim_io.h"
#include "mim_register.h"
#include "mim_session.h"
#include "rigged_avatar.h"
#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char *dir, *store;

/* synth naming: subject s pose p is template 1 + s * POSES + p */
#define POSES 12
#define VERTICES "3000"
/* poses that move the limbs far from rest: arms_up, squat, kick, wave, lunge, guard */
static const int far_poses[] = {2, 4, 6, 7, 9, 11};

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("avatar-scene");
    char *bodies = ts_path(dir, "bodies");
    store = ts_path(dir, "store");
    char *out = NULL, *err = NULL;
    const char *synth[] = {"synth", "--out", bodies, "--subjects", "3", "--poses", "12", "--vertices", VERTICES, NULL};
    const char *ingest[] = {"ingest", "--store", store, bodies, NULL};
    const char *index[] = {"index", "--store", store, NULL};
    int rc = ts_run_mimic(&out, &err, synth);
    free(out), free(err);
    if (!rc) rc = ts_run_mimic(&out, &err, ingest), free(out), free(err);
    if (!rc) rc = ts_run_mimic(&out, &err, index), free(out), free(err);
    free(bodies);
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir), free(store);
    return 0;
}

/* A rigged avatar (seed 7: a body in no store) written to dir/name. */
static char *make_avatar(const char *name, ra_options_t o, ra_avatar_info_t *info)
{
    if (!o.vertices) o.vertices = 3000;
    if (!o.seed) o.seed = 7;
    char *p = ts_path(dir, name), why[512];
    if (ra_write(&o, p, info, why, sizeof why)) fail_msg("%s: %s", name, why);
    return p;
}

/* The GLB's JSON chunk, parsed. */
static json_t *glb_json(const char *path)
{
    size_t len = 0;
    unsigned char *b = (unsigned char *)ts_read_file(path, &len);
    assert_non_null(b);
    assert_true(len > 20 && !memcmp(b, "glTF", 4));
    uint32_t jl;
    memcpy(&jl, b + 12, 4);
    json_error_t je;
    json_t *j = json_loadb((const char *)b + 20, jl, 0, &je);
    free(b);
    assert_non_null(j);
    return j;
}

/* The output has the input's parts, in order, with their counts. */
static void assert_same_parts(const mim_io_scene_t *in, const mim_io_scene_t *out, const char *what)
{
    if (out->n_parts != in->n_parts) fail_msg("%s: %u parts, the avatar %u", what, out->n_parts, in->n_parts);
    for (uint32_t k = 0; k < in->n_parts; k++) {
        if (out->parts[k].n_vertices != in->parts[k].n_vertices || out->parts[k].n_faces != in->parts[k].n_faces)
            fail_msg("%s: part %u has %u vertices and %u faces, the avatar's %u and %u", what, k,
                     out->parts[k].n_vertices, out->parts[k].n_faces, in->parts[k].n_vertices, in->parts[k].n_faces);
        assert_string_equal(out->parts[k].name, in->parts[k].name);
    }
    /* the same triangles, vertex for vertex */
    assert_int_equal(out->mesh.n_faces, in->mesh.n_faces);
    assert_memory_equal(out->mesh.faces, in->mesh.faces, 3 * (size_t)in->mesh.n_faces * sizeof(uint32_t));
}

/* Every primitive keeps its UVs, its material and its texture's image. */
static void assert_look(const char *path, const mim_io_scene_t *in)
{
    json_t *j = glb_json(path);
    json_t *meshes = json_object_get(j, "meshes"), *images = json_object_get(j, "images");
    assert_int_equal(json_array_size(meshes), in->n_parts);
    for (uint32_t k = 0; k < in->n_parts; k++) {
        json_t *prim = json_array_get(json_object_get(json_array_get(meshes, k), "primitives"), 0);
        json_t *attr = json_object_get(prim, "attributes");
        if (!json_object_get(attr, "TEXCOORD_0")) fail_msg("%s: part %u lost its TEXCOORD_0", path, k);
        if (json_integer_value(json_object_get(prim, "material")) != in->parts[k].material)
            fail_msg("%s: part %u: material %lld, the avatar's %d", path, k,
                     (long long)json_integer_value(json_object_get(prim, "material")), in->parts[k].material);
    }
    assert_true(json_array_size(images) >= 1);
    json_t *im = json_array_get(images, 0);
    assert_string_equal(json_string_value(json_object_get(im, "mimeType")), "image/png");
    assert_non_null(json_object_get(im, "bufferView")); /* embedded */
    assert_null(json_object_get(im, "uri"));
    json_decref(j);
    if (ts_gltf_validator_available()) ts_gltf_validate(path);
}

/* The stretch figures of a pose against the avatar at rest. */
static void assert_no_tear(const mim_io_scene_t *rest, const float *posed, const char *what, double *worst_share,
                           double *worst_ratio)
{
    double share = 0, ratio = 0;
    mim_reg_stretch(rest->mesh.faces, rest->mesh.n_faces, rest->mesh.positions, posed, 3.0, &share, &ratio);
    print_message("%s: %.3f %% of the triangles stretched over 3x, largest %.2fx\n", what, 100 * share, ratio);
    if (!(share <= 0.002)) fail_msg("%s: %.3f %% of the triangles stretched over 3x (at most 0.2 %%)", what, 100 * share);
    if (!(ratio <= 8.0)) fail_msg("%s: an edge stretched %.2fx (at most 8x)", what, ratio);
    if (worst_share && share > *worst_share) *worst_share = share;
    if (worst_ratio && ratio > *worst_ratio) *worst_ratio = ratio;
}

/* Pairwise distances inside a part kept: it moved rigidly. */
static void assert_rigid(const mim_io_scene_t *rest, const float *posed, uint32_t part, const char *what)
{
    const mim_io_part_t *p = rest->parts + part;
    double worst = 0;
    for (uint32_t a = p->first_vertex; a < p->first_vertex + p->n_vertices; a += 3)
        for (uint32_t b = a + 1; b < p->first_vertex + p->n_vertices; b += 5) {
            double dr = 0, dp = 0;
            for (int c = 0; c < 3; c++) {
                double r = rest->mesh.positions[3 * a + c] - rest->mesh.positions[3 * b + c];
                double q = posed[3 * a + c] - posed[3 * b + c];
                dr += r * r, dp += q * q;
            }
            worst = fmax(worst, fabs(sqrt(dp) - sqrt(dr)));
        }
    print_message("%s: part '%s' keeps its distances within %.2f mm\n", what, p->name, 1e3 * worst);
    if (!(worst < 2e-3)) fail_msg("%s: part '%s' bent: a distance changed by %.1f mm", what, p->name, 1e3 * worst);
}

static uint32_t part_named(const mim_io_scene_t *s, const char *name)
{
    for (uint32_t k = 0; k < s->n_parts; k++)
        if (!strcmp(s->parts[k].name, name)) return k;
    fail_msg("no part named %s", name);
    return 0;
}

static mim_io_scene_t read_scene(const char *path)
{
    mim_io_scene_t s;
    mim_error_t err = {0};
    if (mim_io_read_scene(path, NULL, &s, &err)) fail_msg("%s", mim_error_text(&err));
    return s;
}

/* mimic transfer into each far pose: parts, look, no tear. JSON report's
 * "parts" and "look" checked too. */
static void transfer_poses(const char *avatar, const char *tag, int textured, const char *rigid_part)
{
    mim_io_scene_t rest = read_scene(avatar);
    double share = 0, ratio = 0;
    for (size_t k = 0; k < sizeof far_poses / sizeof *far_poses; k++) {
        char id[16], name[64];
        snprintf(id, sizeof id, "%d", 1 + POSES * 1 + far_poses[k]); /* subject 1 */
        snprintf(name, sizeof name, "%s-pose%d.glb", tag, far_poses[k]);
        char *outp = ts_path(dir, name), *o = NULL, *e = NULL;
        const char *args[] = {"transfer", "--store", store, "--avatar", avatar, "--template", id, "-o", outp, "--json", NULL};
        if (ts_run_mimic(&o, &e, args)) fail_msg("mimic transfer %s: %s", avatar, e);
        json_error_t je;
        json_t *rep = json_loads(o, 0, &je);
        assert_non_null(rep);
        assert_int_equal(json_integer_value(json_object_get(rep, "parts")), rest.n_parts);
        assert_int_equal(json_is_true(json_object_get(rep, "look")), textured);
        json_decref(rep);
        free(o), free(e);
        mim_io_scene_t out = read_scene(outp);
        assert_same_parts(&rest, &out, name);
        if (textured && k == 0) assert_look(outp, &rest);
        assert_no_tear(&rest, out.mesh.positions, name, &share, &ratio);
        if (rigid_part) assert_rigid(&rest, out.mesh.positions, part_named(&rest, rigid_part), name);
        mim_io_scene_free(&out);
        free(outp);
    }
    print_message("%s over %zu poses: at worst %.3f %% over 3x, largest %.2fx\n", tag,
                  sizeof far_poses / sizeof *far_poses, 100 * share, ratio);
    mim_io_scene_free(&rest);
}

/* Everything at once, Mixamo names: the body is the second mesh, in two
 * primitives, after joint rings; eyes, boots, a sword on the hand bone,
 * centimetres under Armature's scale, fists, a texture. */
static void test_all(void **state)
{
    (void)state;
    ra_avatar_info_t info;
    ra_options_t o = {.names = RA_NAMES_MIXAMO, .split_seams = 1, .joint_rings_first = 1, .shells = 1, .prop = 1,
                      .centimetres = 1, .fists = 1, .texture = 1, .two_primitives = 1};
    char *p = make_avatar("all.glb", o, &info);
    /* read as a viewer shows it: every primitive, placed, in scene order */
    mim_io_scene_t s = read_scene(p);
    assert_int_equal(s.n_parts, info.n_primitives);
    assert_int_equal(s.mesh.n_vertices, info.n_vertices);
    for (uint32_t k = 0; k < s.n_parts; k++) assert_int_equal(s.parts[k].n_vertices, info.primitive[k].n_vertices);
    double worst = 0;
    for (size_t i = 0; i < 3 * (size_t)info.n_vertices; i++) worst = fmax(worst, fabs(s.mesh.positions[i] - info.world[i]));
    print_message("all.glb read: %u parts, %u vertices, within %.2g m of the file's world\n", s.n_parts,
                  s.mesh.n_vertices, worst);
    assert_true(worst < 1e-4);
    assert_int_equal(s.skin_rc, 0);
    mim_io_scene_free(&s);
    transfer_poses(p, "all", 1, "Sword");
    ra_info_free(&info);
    free(p);
}

/* VRM 0.x: meaningless node names, the humanoid map in the extension, the
 * model facing -Z; flat shaded, centimetres. Left and right stay right. */
static void test_vrm0_flat(void **state)
{
    (void)state;
    ra_avatar_info_t info;
    ra_options_t o = {.names = RA_NAMES_VRM0, .flat = 1, .centimetres = 1, .texture = 1};
    char *p = make_avatar("vrm0.glb", o, &info);
    transfer_poses(p, "vrm0", 1, NULL);
    /* "wave" (pose 7) raises the body's right hand: the avatar's own right
     * wrist (synth's r_wrist landmark, at -X of the model's own frame:
     * +X in the world, as it faces -Z) must come out above its left */
    char *outp = ts_path(dir, "vrm0-pose7.glb");
    mim_io_scene_t out = read_scene(outp), rest = read_scene(p);
    /* the rest vertices nearest the two wrist landmarks */
    uint32_t at[2] = {0, 0};
    for (int w = 0; w < 2; w++) {
        const float *lm = info.landmarks + 3 * (7 + w); /* l_wrist, r_wrist */
        double best = INFINITY;
        for (uint32_t v = 0; v < rest.mesh.n_vertices; v++) {
            double d = 0;
            for (int c = 0; c < 3; c++) d += pow(rest.mesh.positions[3 * v + c] - lm[c], 2);
            if (d < best) best = d, at[w] = v;
        }
    }
    float yl = out.mesh.positions[3 * at[0] + 1], yr = out.mesh.positions[3 * at[1] + 1];
    print_message("vrm0 waving: left wrist at %.2f m, right at %.2f m\n", yl, yr);
    /* which hand synth's wave raises: the template's own right (r_wrist) is higher there */
    assert_true(fabsf(yl - yr) > 0.2f);
    char *tmpl = ts_path(dir, "bodies/synth_s01_p07.ply");
    mim_mesh_t t = {0};
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_mesh(tmpl, &t, &err), 0);
    /* the synth's wrist landmark vertices: compare by height, which hand is up */
    mim_landmark_map_t map;
    char *lmp = ts_path(dir, "bodies/landmarks.json");
    assert_int_equal(mim_landmarks_read(&map, lmp, NULL), 0);
    float tl = t.positions[3 * map.vertex[7] + 1], tr = t.positions[3 * map.vertex[8] + 1];
    assert_int_equal(yl > yr, tl > tr);
    mim_mesh_free(&t);
    mim_io_scene_free(&out), mim_io_scene_free(&rest);
    free(outp), free(tmpl), free(lmp), free(p);
    ra_info_free(&info);
}

/* VRM 1.0 and Blender names; a T-posed avatar with fists and seams. */
static void test_vrm1_blender_tpose(void **state)
{
    (void)state;
    ra_avatar_info_t info;
    ra_options_t o = {.names = RA_NAMES_VRM1, .shells = 1, .subject = 1};
    char *p = make_avatar("vrm1.glb", o, &info);
    transfer_poses(p, "vrm1", 0, NULL);
    free(p);
    ra_info_free(&info);
    ra_options_t b = {.names = RA_NAMES_BLENDER, .tpose = 1, .fists = 1, .split_seams = 1};
    p = make_avatar("blender-tpose.glb", b, &info);
    transfer_poses(p, "blender-tpose", 0, NULL);
    free(p);
    ra_info_free(&info);
}

/* The landmarks placed from the rig land where synth's own are. */
static void test_rig_landmarks(void **state)
{
    (void)state;
    const ra_names_t schemes[] = {RA_NAMES_MIXAMO, RA_NAMES_BLENDER, RA_NAMES_VRM0, RA_NAMES_VRM1};
    mim_landmark_map_t map;
    char *lmp = ts_path(dir, "bodies/landmarks.json");
    assert_int_equal(mim_landmarks_read(&map, lmp, NULL), 0);
    free(lmp);
    for (size_t k = 0; k < sizeof schemes / sizeof *schemes; k++) {
        ra_avatar_info_t info;
        /* 7000 vertices: the rules pick vertices, so a coarse body is off by its edge length */
        ra_options_t o = {.names = schemes[k], .split_seams = 1, .centimetres = k % 2 == 1, .tpose = k == 3,
                          .vertices = 7000};
        char name[32];
        snprintf(name, sizeof name, "rig%zu.glb", k);
        char *p = make_avatar(name, o, &info);
        mim_io_scene_t s = read_scene(p);
        assert_int_equal(s.skin_rc, 0);
        assert_int_equal(s.skin.from_vrm, schemes[k] == RA_NAMES_VRM0 || schemes[k] == RA_NAMES_VRM1);
        float lm[3 * MIM_LANDMARKS_MAX];
        char how[512];
        mim_error_t err = {0};
        if (mim_session_rig_landmarks(&s.mesh, &s.skin, &map, lm, how, sizeof how, &err))
            fail_msg("%s: %s", name, mim_error_text(&err));
        double worst = 0;
        uint32_t at = 0;
        for (uint32_t l = 0; l < map.count; l++) {
            double d = 0;
            for (int c = 0; c < 3; c++) d += pow(lm[3 * l + c] - info.landmarks[3 * l + c], 2);
            if (sqrt(d) > worst) worst = sqrt(d), at = l;
        }
        print_message("%s: landmarks from %s, within %.1f mm of synth's (worst %s)\n", name, how, 1e3 * worst,
                      map.names[at]);
        assert_true(worst < 0.015);
        mim_io_scene_free(&s);
        ra_info_free(&info);
        free(p);
    }
}

/* mimic morph between far keys: every frame keeps the parts and tears nowhere. */
static void test_morph(void **state)
{
    (void)state;
    ra_avatar_info_t info;
    ra_options_t o = {.names = RA_NAMES_MIXAMO, .joint_rings_first = 1, .shells = 1, .prop = 1, .fists = 1,
                      .texture = 1, .split_seams = 1};
    char *p = make_avatar("morph-avatar.glb", o, &info), *outp = ts_path(dir, "morph.glb");
    /* arms up (2) -> kick (6) -> squat (4), subject 2 */
    const char *args[] = {"morph", "--store", store, "--avatar", p, "--keys", "27,31,29", "--frames-between", "4",
                          "-o", outp, "--json", NULL};
    char *out = NULL, *e = NULL;
    if (ts_run_mimic(&out, &e, args)) fail_msg("mimic morph: %s", e);
    json_error_t je;
    json_t *rep = json_loads(out, 0, &je);
    assert_true(json_is_true(json_object_get(rep, "look")));
    assert_int_equal(json_integer_value(json_object_get(rep, "parts")), info.n_primitives);
    json_decref(rep);
    free(out), free(e);
    mim_io_scene_t rest = read_scene(p), seq = read_scene(outp);
    assert_same_parts(&rest, &seq, "morph.glb");
    assert_look(outp, &rest);
    /* every frame: frame 0 plus each morph target (the file's accessors) */
    json_t *j = glb_json(outp);
    json_t *meshes = json_object_get(j, "meshes");
    size_t n_targets = json_array_size(json_object_get(json_array_get(json_object_get(json_array_get(meshes, 0), "primitives"), 0), "targets"));
    assert_int_equal(n_targets, 2 * 5);
    json_decref(j);
    /* frame 0 is the first key: no tear there; the rest through the viewer's eyes
     * is checked by frames written as single transfers above */
    assert_no_tear(&rest, seq.mesh.positions, "morph frame 0", NULL, NULL);
    assert_rigid(&rest, seq.mesh.positions, part_named(&rest, "Sword"), "morph frame 0");
    mim_io_scene_free(&rest), mim_io_scene_free(&seq);
    free(p), free(outp);
    ra_info_free(&info);
}

/* --avatar-mesh: only the named meshes; a name that is not there gets one line. */
static void test_mesh_selection(void **state)
{
    (void)state;
    ra_avatar_info_t info;
    ra_options_t o = {.names = RA_NAMES_MIXAMO, .joint_rings_first = 1, .two_primitives = 1, .shells = 1};
    char *p = make_avatar("select.glb", o, &info), *outp = ts_path(dir, "select-out.glb");
    const char *args[] = {"transfer", "--store", store, "--avatar", p, "--avatar-mesh", "Body", "--template", "15",
                          "-o", outp, "--json", NULL};
    char *out = NULL, *e = NULL;
    if (ts_run_mimic(&out, &e, args)) fail_msg("mimic transfer --avatar-mesh Body: %s", e);
    free(out), free(e);
    mim_io_scene_t s = read_scene(outp);
    assert_int_equal(s.n_parts, 2); /* the body's two primitives */
    assert_string_equal(s.parts[0].name, "Body");
    mim_io_scene_free(&s);
    const char *bad[] = {"transfer", "--store", store, "--avatar", p, "--avatar-mesh", "Cape", "--template", "15",
                         "-o", outp, NULL};
    assert_int_equal(ts_run_mimic(&out, &e, bad), 1);
    print_message("%s", e);
    assert_non_null(strstr(e, "select.glb"));
    assert_non_null(strstr(e, "no mesh or node named 'Cape'"));
    assert_non_null(strstr(e, "'Body'")); /* the names there are */
    assert_int_equal(strchr(e, '\n') - e + 1, (long)strlen(e)); /* one line */
    free(out), free(e), free(p), free(outp);
    ra_info_free(&info);
}

/* Bad avatars: one line each naming the file, nothing written. */
static void test_bad_avatars(void **state)
{
    (void)state;
    ra_avatar_info_t info;
    ra_options_t o = {.names = RA_NAMES_NONE, .split_seams = 1}; /* no skin, no landmark file; not the store's connectivity */
    char *p = make_avatar("norig.glb", o, &info), *outp = ts_path(dir, "norig-out.glb");
    ra_info_free(&info);
    const char *args[] = {"transfer", "--store", store, "--avatar", p, "--template", "15", "-o", outp, NULL};
    char *out = NULL, *e = NULL;
    assert_int_equal(ts_run_mimic(&out, &e, args), 1);
    print_message("%s", e);
    assert_non_null(strstr(e, "norig.glb"));
    assert_non_null(strstr(e, "--avatar-landmarks"));
    assert_int_equal(strchr(e, '\n') - e + 1, (long)strlen(e)); /* one line */
    assert_null(fopen(outp, "rb"));
    free(out), free(e);
    /* a stylised avatar too far from its proxy: refused at a tight limit, with the option named */
    ra_options_t f = {.names = RA_NAMES_MIXAMO, .fists = 1, .split_seams = 1}; /* seams: not the store's connectivity */
    char *fp = make_avatar("tight.glb", f, &info);
    ra_info_free(&info);
    const char *tight[] = {"transfer", "--store", store, "--avatar", fp, "--max-distance-mm", "0.01", "--template",
                           "15", "-o", outp, NULL};
    assert_int_equal(ts_run_mimic(&out, &e, tight), 1);
    print_message("%s", e);
    assert_non_null(strstr(e, "tight.glb"));
    assert_non_null(strstr(e, "--max-distance-mm"));
    assert_null(fopen(outp, "rb"));
    free(out), free(e);
    /* 5000 loose triangles where a body would be, with landmarks: no body, one line */
    mim_mesh_t cloud = {0};
    assert_int_equal(mim_mesh_alloc(&cloud, 3 * 5000, 5000), 0);
    uint64_t rng = 12345;
    for (uint32_t t = 0; t < 5000; t++) {
        float c[3];
        for (int k = 0; k < 3; k++) rng = rng * 6364136223846793005ull + 1442695040888963407ull, c[k] = (float)((rng >> 40) % 1000) / 1000.0f;
        c[0] = 0.5f * c[0] - 0.25f, c[1] = 1.7f * c[1], c[2] = 0.3f * c[2] - 0.15f;
        for (int k = 0; k < 3; k++) {
            float *q = cloud.positions + 9 * (size_t)t + 3 * k;
            q[0] = c[0] + (k == 1) * 0.01f, q[1] = c[1] + (k == 2) * 0.01f, q[2] = c[2];
            cloud.faces[3 * t + k] = 3 * t + (uint32_t)k;
        }
    }
    char *cp = ts_path(dir, "cloud.ply"), *clm = ts_path(dir, "cloud.landmarks.json");
    mim_error_t err = {0};
    assert_int_equal(mim_io_write_mesh(cp, &cloud, &err), 0);
    mim_mesh_free(&cloud);
    ra_avatar_info_t li;
    ra_options_t lo = {.names = RA_NAMES_NONE};
    char *lp = make_avatar("cloud-source.glb", lo, &li);
    FILE *lf = fopen(clm, "w");
    fprintf(lf, "{\"landmarks\": [");
    for (int l = 0; l < 16; l++)
        fprintf(lf, "%s[%.6f, %.6f, %.6f]", l ? ", " : "", li.landmarks[3 * l], li.landmarks[3 * l + 1], li.landmarks[3 * l + 2]);
    fprintf(lf, "]}\n");
    fclose(lf);
    ra_info_free(&li);
    const char *cargs[] = {"transfer", "--store", store, "--avatar", cp, "--template", "15", "-o", outp, NULL};
    assert_int_equal(ts_run_mimic(&out, &e, cargs), 1);
    print_message("%s", e);
    assert_non_null(strstr(e, "cloud.ply"));
    assert_non_null(strstr(e, "pieces once its seams are welded"));
    assert_int_equal(strchr(e, '\n') - e + 1, (long)strlen(e));
    assert_null(fopen(outp, "rb"));
    free(out), free(e), free(cp), free(clm), free(lp);
    free(p), free(fp), free(outp);
}

/* mimic landmarks show: where each landmark came from; the built-in maps
 * listed and exported; a mesh without any source gets one line. */
static void test_landmarks_command(void **state)
{
    (void)state;
    ra_avatar_info_t info;
    ra_options_t o = {.names = RA_NAMES_VRM1, .split_seams = 1, .vertices = 7000};
    char *p = make_avatar("show.glb", o, &info), *svg = ts_path(dir, "show.svg");
    const char *args[] = {"landmarks", "show", p, "--json", "--svg", svg, NULL};
    char *out = NULL, *e = NULL;
    if (ts_run_mimic(&out, &e, args)) fail_msg("mimic landmarks show: %s", e);
    json_error_t je;
    json_t *j = json_loads(out, 0, &je);
    assert_non_null(j);
    assert_string_equal(json_string_value(json_object_get(j, "source")), "rig");
    assert_non_null(strstr(json_string_value(json_object_get(j, "from")), "VRM humanoid names"));
    json_t *lms = json_object_get(j, "landmarks");
    assert_int_equal(json_array_size(lms), 16);
    /* the same positions the library places, each on a vertex */
    for (size_t l = 0; l < 16; l++) {
        json_t *pos = json_object_get(json_array_get(lms, l), "position");
        double d = 0;
        for (int c = 0; c < 3; c++) d += pow(json_real_value(json_array_get(pos, c)) - info.landmarks[3 * l + c], 2);
        assert_true(sqrt(d) < 0.015);
        assert_true(json_real_value(json_object_get(json_array_get(lms, l), "vertex_distance_m")) < 1e-6);
    }
    json_decref(j);
    free(out), free(e);
    size_t len = 0;
    char *pic = ts_read_file(svg, &len);
    assert_non_null(pic);
    assert_non_null(strstr(pic, "<svg"));
    assert_non_null(strstr(pic, ">l_wrist<"));
    free(pic);
    /* the built-in SMPL map, exported, is a landmark map file */
    char *smpl = ts_path(dir, "smpl.json");
    const char *exp[] = {"landmarks", "export", "smpl-6890.json", "-o", smpl, NULL};
    if (ts_run_mimic(&out, &e, exp)) fail_msg("mimic landmarks export: %s", e);
    free(out), free(e);
    mim_landmark_map_t m;
    mim_error_t err = {0};
    assert_int_equal(mim_landmarks_read(&m, smpl, &err), 0);
    assert_int_equal(m.topology_vertices, 6890);
    assert_int_equal(m.count, 16);
    /* nothing to place them from: one line naming the file */
    ra_avatar_info_t i2;
    ra_options_t none = {.names = RA_NAMES_NONE, .split_seams = 1};
    char *np = make_avatar("show-none.glb", none, &i2);
    const char *bad[] = {"landmarks", "show", np, NULL};
    assert_int_equal(ts_run_mimic(&out, &e, bad), 1);
    assert_non_null(strstr(e, "show-none.glb"));
    assert_int_equal(strchr(e, '\n') - e + 1, (long)strlen(e));
    free(out), free(e), free(np), free(smpl), free(svg), free(p);
    ra_info_free(&info), ra_info_free(&i2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_all),          cmocka_unit_test(test_vrm0_flat), cmocka_unit_test(test_vrm1_blender_tpose),
        cmocka_unit_test(test_rig_landmarks), cmocka_unit_test(test_morph),     cmocka_unit_test(test_mesh_selection),
        cmocka_unit_test(test_bad_avatars),  cmocka_unit_test(test_landmarks_command),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
