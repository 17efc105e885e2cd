/* Issue 28 in mimic serve: a rigged, textured GLB avatar of six primitives
 * (support/rigged_avatar.c: joint rings first, the body in two
 * primitives, eyes, boots, a sword under the hand's bone, centimetres,
 * fists, Mixamo names) served on a simulated vest with no landmark file:
 *   - the start says the avatar stands in an A-pose and what a T-pose tare needs;
 *   - /api/avatar has the file's vertices in scene order and its parts;
 *   - /api/avatar.glb is the avatar at rest in its parts, textured, valid;
 *   - every WebSocket frame has all the vertices, and no served pose tears
 *     (at most 0.2 % of the triangles stretched over 3x, none over 8x) or
 *     bends the sword;
 *   - POST /api/transfer's GLB keeps the parts and the look. */
#include "mim_io.h"
#include "mim_register.h"
#include "rigged_avatar.h"
#include "serve_support.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char *dir, *store, *av_path;
static ss_svc_t svc;
static mim_io_scene_t rest;
static ra_avatar_info_t info;

static int setup(void **state)
{
    (void)state;
    signal(SIGPIPE, SIG_IGN);
    dir = ts_tempdir("serve-rigged");
    int have[64];
    if (ss_make_store(dir, 3, &store, have, 63) < 0) return -1;
    av_path = ts_path(dir, "rigged.glb");
    ra_options_t o = {.names = RA_NAMES_MIXAMO, .seed = 7, .vertices = 1500, .split_seams = 1, .joint_rings_first = 1,
                      .shells = 1, .prop = 1, .centimetres = 1, .fists = 1, .texture = 1, .two_primitives = 1};
    char why[512];
    if (ra_write(&o, av_path, &info, why, sizeof why)) {
        fprintf(stderr, "rigged avatar: %s\n", why);
        return -1;
    }
    mim_error_t err = {0};
    if (mim_io_read_scene(av_path, NULL, &rest, &err)) {
        fprintf(stderr, "%s\n", mim_error_text(&err));
        return -1;
    }
    /* the default tare pose: the avatar's own (the fixture's t is overridden) */
    const char *extra[] = {"--avatar", av_path, "--vest-pose", "rest", NULL};
    return ss_svc_start(&svc, dir, store, "rigged", NULL, extra) ? -1 : 0;
}

static int teardown(void **state)
{
    (void)state;
    ss_svc_term(&svc);
    ss_svc_free(&svc);
    ss_kill_children();
    mim_io_scene_free(&rest);
    ra_info_free(&info);
    ts_rmtree(dir);
    free(dir), free(store), free(av_path);
    return 0;
}

/* A GLB answer (freed here), kept at dir/name (the path, malloc'd): the
 * avatar's parts, each with its vertices and faces as the file has them. */
static char *glb_in_parts(hc_reply_t *r, const char *name)
{
    assert_int_equal(r->status, 200);
    char *path = ts_path(dir, name);
    assert_int_equal(ts_write_file(path, r->body, r->len), 0);
    hc_reply_free(r);
    mim_io_scene_t s;
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_scene(path, NULL, &s, &err), 0);
    assert_int_equal(s.n_parts, rest.n_parts);
    for (uint32_t k = 0; k < s.n_parts; k++) assert_int_equal(s.parts[k].n_vertices, rest.parts[k].n_vertices);
    assert_int_equal(s.mesh.n_faces, rest.mesh.n_faces);
    assert_memory_equal(s.mesh.faces, rest.mesh.faces, 3 * (size_t)rest.mesh.n_faces * sizeof(uint32_t));
    mim_io_scene_free(&s);
    return path;
}

static void test_start_says_rest_pose(void **state)
{
    (void)state;
    char *err = ts_read_file(svc.serr, NULL);
    print_message("%s", err);
    assert_non_null(strstr(err, "rigged.glb stands in an A-pose"));
    assert_non_null(strstr(err, "--vest-pose t"));
    assert_non_null(strstr(err, "landmarks from its rig"));
    free(err);
}

static void test_api_avatar_parts(void **state)
{
    (void)state;
    hc_reply_t r = ss_http_get(svc.port, "/api/avatar");
    assert_int_equal(r.status, 200);
    json_t *j = ss_json_body(&r);
    assert_int_equal(ss_status_int(j, NULL, "vertices"), info.n_vertices);
    json_t *parts = json_object_get(j, "parts"), *pos = json_object_get(j, "positions");
    assert_int_equal(json_array_size(parts), info.n_primitives);
    uint32_t at = 0;
    for (uint32_t k = 0; k < info.n_primitives; k++) {
        json_t *p = json_array_get(parts, k);
        assert_int_equal(json_integer_value(json_object_get(p, "first_vertex")), at);
        assert_int_equal(json_integer_value(json_object_get(p, "vertices")), info.primitive[k].n_vertices);
        assert_string_equal(json_string_value(json_object_get(p, "name")), info.primitive[k].mesh_name);
        at += info.primitive[k].n_vertices;
    }
    double worst = 0;
    for (size_t i = 0; i < 3 * (size_t)info.n_vertices; i++)
        worst = fmax(worst, fabs(json_number_value(json_array_get(pos, i)) - info.world[i]));
    assert_true(worst < 1e-4); /* the file's vertices where a viewer shows them, in its order */
    assert_string_equal(json_string_value(json_object_get(j, "glb")), "/api/avatar.glb");
    json_decref(j);
    hc_reply_free(&r);

    r = ss_http_get(svc.port, "/api/avatar.glb");
    char *path = glb_in_parts(&r, "avatar-rest.glb");
    char *txt = ts_read_file(path, NULL);
    assert_non_null(strstr(txt + 20, "\"TEXCOORD_0\""));
    assert_non_null(strstr(txt + 20, "\"image/png\""));
    free(txt);
    if (ts_gltf_validator_available()) ts_gltf_validate(path);
    free(path);
}

static void test_stream_does_not_tear(void **state)
{
    (void)state;
    ws_client_t w;
    json_t *hello = ss_ws_open(&w, svc.port, "/ws", 0);
    assert_int_equal(ss_status_int(hello, NULL, "vertices"), info.n_vertices);
    json_decref(hello);
    const size_t n3 = 3 * (size_t)info.n_vertices;
    float *p = malloc(n3 * sizeof *p);
    double worst_share = 0, worst_ratio = 0, moved = 0, sword = 0;
    uint32_t sw = 0;
    for (uint32_t k = 0; k < rest.n_parts; k++)
        if (!strcmp(rest.parts[k].name, "Sword")) sw = k;
    const mim_io_part_t *sp = rest.parts + sw;
    for (int frames = 0; frames < 90; frames++) {
        ws_msg_t m;
        assert_int_equal(ss_next_frame(&w, &m, 10000, NULL), 1);
        mimf_t f = ss_parse_frame(&m);
        assert_int_equal(f.n, info.n_vertices);
        for (size_t i = 0; i < n3; i++) p[i] = mimf_x(&f, i), moved = fmax(moved, fabs(p[i] - rest.mesh.positions[i]));
        ws_msg_free(&m);
        double share, ratio;
        mim_reg_stretch(rest.mesh.faces, rest.mesh.n_faces, rest.mesh.positions, p, 3.0, &share, &ratio);
        worst_share = fmax(worst_share, share), worst_ratio = fmax(worst_ratio, ratio);
        /* the sword's length end to end */
        const float *a = rest.mesh.positions + 3 * sp->first_vertex, *b = a + 3 * (sp->n_vertices - 1);
        const float *A = p + 3 * sp->first_vertex, *B = A + 3 * (sp->n_vertices - 1);
        double dr = sqrt(pow(a[0] - b[0], 2) + pow(a[1] - b[1], 2) + pow(a[2] - b[2], 2));
        double dp = sqrt(pow(A[0] - B[0], 2) + pow(A[1] - B[1], 2) + pow(A[2] - B[2], 2));
        sword = fmax(sword, fabs(dp - dr));
    }
    ws_close(&w);
    free(p);
    print_message("90 served frames: the avatar moved up to %.2f m; at worst %.3f %% of the triangles over 3x, "
                  "largest %.2fx; the sword's length within %.2f mm\n",
                  moved, 100 * worst_share, worst_ratio, 1e3 * sword);
    assert_true(moved > 0.05); /* it is driven */
    assert_true(worst_share <= 0.002);
    assert_true(worst_ratio <= 8.0);
    assert_true(sword < 2e-3);
}

static void test_transfer_keeps_look(void **state)
{
    (void)state;
    const char *body = "{\"template\": 4}";
    hc_reply_t r;
    assert_int_equal(hc_request(&r, svc.port, "POST", "/api/transfer", "Content-Type: application/json\r\n", body,
                                strlen(body), 60000),
                     HC_OK);
    char *path = glb_in_parts(&r, "transfer.glb");
    char *txt = ts_read_file(path, NULL);
    assert_non_null(strstr(txt + 20, "\"baseColorTexture\""));
    free(txt);
    if (ts_gltf_validator_available()) ts_gltf_validate(path);
    free(path);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_start_says_rest_pose),
        cmocka_unit_test(test_api_avatar_parts),
        cmocka_unit_test(test_stream_does_not_tear),
        cmocka_unit_test(test_transfer_keeps_look),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
