/* A foreign avatar end to end (issue 13): `mimic serve|transfer|morph
 * --avatar MESH` where MESH has another connectivity than the store's.
 *
 * The store: synth bodies (3 subjects x 6 poses, about 2000 vertices),
 * ingested and indexed. The avatar: a synth body of another seed (so in no
 * template of the store), subdivided twice (about 32000 vertices) and its
 * vertices and faces shuffled (support/foreign_avatar.c), written as PLY
 * with its landmark positions beside it (NAME.landmarks.json). The first
 * start registers and binds it and keeps the binding in the store; every
 * output (the stream, /api/avatar, /api/status, /api/transfer, mimic
 * transfer's mesh, mimic morph's GLB) is in the avatar's own connectivity
 * and vertex order. Then: a restart finds the binding; a damaged cached
 * binding is not trusted; bad avatars are refused in one line.
 *
 * The real binary, the real simulated vest, real sockets
 * (support/serve_support.c); every wait has a deadline, every child is
 * killed in teardown. RUN_SERIAL: it runs a real-time service. */
#include "foreign_avatar.h"
#include "mim_db.h"
#include "mim_io.h"
#include "mim_register.h"
#include "serve_support.h"

#include <jansson.h>
#include <lmdb.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#define SUBJECTS 3
#define POSES 6
#define SQUAT_POSE "4" /* synth pose 4, "squat": lower than the rest pose */

static char *dir, *store, *store_noidx, *av_path, *av_sidecar;
static fa_avatar_t av;        /* the avatar as written */
static double rest_height;    /* its y extent */
static double rest_edge_max;  /* its longest edge */
static uint64_t rest_id, squat_id; /* subject 0's rest and squat templates */
static char *avatar_json;     /* GET /api/avatar of the first start, for the later ones */
static size_t avatar_json_len;
static unsigned char *first_glb; /* POST /api/transfer {"template": squat_id} of the first start */
static size_t first_glb_len;

/* ---- helpers ---- */
static int run_quiet(const char *const *args, char **out)
{
    char *err = NULL;
    int rc = ts_run_mimic(out, &err, args);
    if (rc)
        fprintf(stderr, "mimic %s failed (%d): %s\n", args[0], rc, err ? err : "");
    free(err);
    return rc;
}

static double y_extent(const float *p, uint32_t n)
{
    float lo = INFINITY, hi = -INFINITY;
    for (uint32_t i = 0; i < n; i++)
        lo = fminf(lo, p[3 * i + 1]), hi = fmaxf(hi, p[3 * i + 1]);
    return (double)hi - lo;
}

/* The longest edge of the avatar's faces with positions p. */
static double longest_edge(const float *p)
{
    double worst = 0.0;
    for (uint32_t f = 0; f < av.mesh.n_faces; f++)
        for (int k = 0; k < 3; k++) {
            const uint32_t *t = av.mesh.faces + 3 * (size_t)f;
            const float *a = p + 3 * (size_t)t[k], *b = p + 3 * (size_t)t[(k + 1) % 3];
            double d = sqrt(pow(a[0] - b[0], 2) + pow(a[1] - b[1], 2) + pow(a[2] - b[2], 2));
            worst = fmax(worst, d);
        }
    return worst;
}

/* Positions p (3 * the avatar's vertex count) are a pose of the avatar in
 * its own vertex order: finite, and every edge of its own faces about as
 * long as at rest (in another order, its faces would span the body). */
static void assert_avatar_pose(const float *p, const char *what)
{
    for (size_t i = 0; i < 3 * (size_t)av.mesh.n_vertices; i++)
        if (!isfinite(p[i]))
            fail_msg("%s: coordinate %zu is %g", what, i, (double)p[i]);
    double e = longest_edge(p);
    if (!(e < 4.0 * rest_edge_max))
        fail_msg("%s: an edge of the avatar's faces is %.3f m long, at rest at most %.3f m: not the avatar's vertex "
                 "order",
                 what, e, rest_edge_max);
}

/* Whether text (a captured stderr) contains s. */
static int has_line_with(const char *text, const char *s)
{
    return text && strstr(text, s) != NULL;
}

static int count_lines(const char *s)
{
    int n = 0;
    for (; s && *s; s++)
        n += *s == '\n';
    return n;
}

/* ---- a GLB, minimally: its JSON chunk, and a float VEC3 accessor's data ---- */
typedef struct glb {
    json_t *json;
    const unsigned char *bin;
    size_t bin_len;
} glb_t;

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static glb_t glb_parse(const unsigned char *b, size_t n, const char *what)
{
    glb_t g = {0};
    if (n < 20 || memcmp(b, "glTF", 4) || le32(b + 4) != 2 || le32(b + 8) != n)
        fail_msg("%s: not a GLB of %zu bytes", what, n);
    size_t jl = le32(b + 12);
    if (memcmp(b + 16, "JSON", 4) || 20 + jl > n)
        fail_msg("%s: no JSON chunk", what);
    json_error_t je;
    g.json = json_loadb((const char *)b + 20, jl, 0, &je);
    if (!g.json)
        fail_msg("%s: the JSON chunk does not parse: %s", what, je.text);
    size_t o = 20 + jl;
    if (o + 8 <= n && !memcmp(b + o + 4, "BIN\0", 4)) {
        g.bin_len = le32(b + o);
        g.bin = b + o + 8;
        assert_true(o + 8 + g.bin_len <= n);
    }
    return g;
}

static json_t *accessor(const glb_t *g, json_int_t i)
{
    json_t *a = json_array_get(json_object_get(g->json, "accessors"), (size_t)i);
    assert_non_null(a);
    return a;
}

/* Mesh 0's primitive 0. */
static json_t *primitive(const glb_t *g)
{
    json_t *mesh = json_array_get(json_object_get(g->json, "meshes"), 0);
    json_t *prim = json_array_get(json_object_get(mesh, "primitives"), 0);
    assert_non_null(prim);
    return prim;
}

/* The POSITION accessor of mesh 0's primitive 0. */
static json_int_t position_accessor(const glb_t *g)
{
    json_t *prim = primitive(g);
    json_t *pos = json_object_get(json_object_get(prim, "attributes"), "POSITION");
    assert_true(json_is_integer(pos));
    return json_integer_value(pos);
}

static json_int_t accessor_count(const glb_t *g, json_int_t i)
{
    json_t *c = json_object_get(accessor(g, i), "count");
    assert_true(json_is_integer(c));
    return json_integer_value(c);
}

/* A float VEC3 accessor's values (malloc'd, 3 * count). */
static float *accessor_vec3(const glb_t *g, json_int_t i)
{
    json_t *a = accessor(g, i);
    assert_int_equal(json_integer_value(json_object_get(a, "componentType")), 5126);
    assert_string_equal(json_string_value(json_object_get(a, "type")), "VEC3");
    json_t *bv = json_array_get(json_object_get(g->json, "bufferViews"),
                                (size_t)json_integer_value(json_object_get(a, "bufferView")));
    assert_non_null(bv);
    size_t count = (size_t)json_integer_value(json_object_get(a, "count"));
    size_t off = (size_t)json_integer_value(json_object_get(bv, "byteOffset")) +
                 (size_t)json_integer_value(json_object_get(a, "byteOffset"));
    size_t stride = json_is_integer(json_object_get(bv, "byteStride"))
                        ? (size_t)json_integer_value(json_object_get(bv, "byteStride"))
                        : 12;
    assert_non_null(g->bin);
    assert_true(off + (count ? (count - 1) * stride + 12 : 0) <= g->bin_len);
    float *out = malloc(3 * count * sizeof *out);
    for (size_t v = 0; v < count; v++)
        memcpy(out + 3 * v, g->bin + off + v * stride, 12);
    return out;
}

/* ---- the fixture ---- */
static int setup(void **state)
{
    (void)state;
    signal(SIGPIPE, SIG_IGN);
    dir = ts_tempdir("serve-avatar");
    if (!dir)
        return -1;
    char *bodies = ts_path(dir, "bodies"), s[16], p[16];
    store = ts_path(dir, "store");
    store_noidx = ts_path(dir, "store-noindex");
    snprintf(s, sizeof s, "%d", SUBJECTS), snprintf(p, sizeof p, "%d", POSES);
    const char *synth[] = {"synth", "--out", bodies, "--subjects", s, "--poses", p, "--vertices", "2000", NULL};
    const char *ingest[] = {"ingest", "--store", store, bodies, NULL};
    const char *ingest2[] = {"ingest", "--store", store_noidx, bodies, NULL};
    const char *index[] = {"index", "--store", store, NULL};
    const char *list[] = {"list", "--store", store, "--json", NULL};
    char *out = NULL;
    int rc = run_quiet(synth, NULL);
    if (!rc) rc = run_quiet(ingest, NULL);
    if (!rc) rc = run_quiet(ingest2, NULL);
    if (!rc) rc = run_quiet(index, NULL);
    if (!rc) rc = run_quiet(list, &out);
    free(bodies);
    json_t *l = rc ? NULL : json_loads(out, 0, NULL);
    free(out);
    size_t i;
    json_t *row;
    json_array_foreach(l, i, row)
    {
        const char *subj = json_string_value(json_object_get(row, "subject")),
                   *pose = json_string_value(json_object_get(row, "pose"));
        uint64_t id = (uint64_t)json_integer_value(json_object_get(row, "id"));
        if (subj && pose && !strcmp(subj, "0") && !strcmp(pose, "0")) rest_id = id;
        if (subj && pose && !strcmp(subj, "0") && !strcmp(pose, SQUAT_POSE)) squat_id = id;
    }
    if (json_array_size(l) != SUBJECTS * POSES || !rest_id || !squat_id) {
        fprintf(stderr, "the store holds %zu templates, not %d (rest %llu, squat %llu)\n", json_array_size(l),
                SUBJECTS * POSES, (unsigned long long)rest_id, (unsigned long long)squat_id);
        json_decref(l);
        return -1;
    }
    json_decref(l);

    /* another seed than the store's (1): a body in no template */
    fa_options_t o = {.vertices = 2000, .seed = 7, .subdivisions = 2, .shuffle_seed = 11};
    char why[512];
    av_path = ts_path(dir, "avatar.ply");
    av_sidecar = ts_path(dir, "avatar.landmarks.json");
    if (fa_make(&o, &av, why, sizeof why) || fa_write(&av, av_path, av_sidecar, -1, why, sizeof why)) {
        fprintf(stderr, "the foreign avatar: %s\n", why);
        return -1;
    }
    rest_height = y_extent(av.mesh.positions, av.mesh.n_vertices);
    rest_edge_max = longest_edge(av.mesh.positions);
    print_message("store: %d templates of %u vertices; avatar: %u vertices, %u faces (%.2f m tall, edges up to "
                  "%.1f mm)\n",
                  SUBJECTS * POSES, av.body_vertices, av.mesh.n_vertices, av.mesh.n_faces, rest_height,
                  1e3 * rest_edge_max);
    return av.mesh.n_vertices >= 30000 && av.mesh.n_vertices <= 60000 ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    ss_kill_children();
    if (dir)
        ts_rmtree(dir);
    fa_free(&av);
    free(dir), free(store), free(store_noidx), free(av_path), free(av_sidecar);
    free(avatar_json), free(first_glb);
    return 0;
}

/* Starts serve on the avatar with the simulated vest (tag names its files)
 * at a fixed key rate (a vest frame per key frame at "60", which the 60 Hz
 * vest gives; "15": three morph frames between key frames). */
static void start(ss_svc_t *s, const char *tag, const char *key_rate)
{
    if (strcmp(tag, "first") && (!avatar_json || !first_glb))
        fail_msg("test_first_start did not pass: nothing to compare with");
    const char *extra[] = {"--avatar", av_path, "--key-rate", key_rate, NULL}; /* the later --avatar wins */
    if (ss_svc_start(s, dir, store, tag, NULL, extra))
        fail_msg("mimic serve did not start with the foreign avatar");
}

/* GET /api/avatar: checks it is the avatar file's mesh, in its order. */
static hc_reply_t check_api_avatar(int port)
{
    hc_reply_t r = ss_http_get(port, "/api/avatar");
    assert_int_equal(r.status, 200);
    json_t *j = ss_json_body(&r);
    assert_int_equal(ss_status_int(j, NULL, "vertices"), av.mesh.n_vertices);
    assert_int_equal(ss_status_int(j, NULL, "faces"), av.mesh.n_faces);
    json_t *pos = json_object_get(j, "positions"), *idx = json_object_get(j, "indices");
    assert_int_equal(json_array_size(pos), 3 * (size_t)av.mesh.n_vertices);
    assert_int_equal(json_array_size(idx), 3 * (size_t)av.mesh.n_faces);
    /* the file as mimic's reader reads it, and as it was written */
    mim_mesh_t file = {0};
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_mesh(av_path, &file, &err), 0);
    assert_int_equal(file.n_vertices, av.mesh.n_vertices);
    double worst = 0.0;
    for (size_t i = 0; i < 3 * (size_t)av.mesh.n_vertices; i++) {
        double x = json_number_value(json_array_get(pos, i));
        worst = fmax(worst, fmax(fabs(x - file.positions[i]), fabs(x - av.mesh.positions[i])));
    }
    if (!(worst <= 1e-6))
        fail_msg("/api/avatar: positions differ from the avatar file's by up to %g m", worst);
    /* its faces, each as the file has it (a corner rotation is the same face) */
    for (uint32_t f = 0; f < av.mesh.n_faces; f++) {
        uint32_t g[3], *w = av.mesh.faces + 3 * (size_t)f;
        for (int k = 0; k < 3; k++)
            g[k] = (uint32_t)json_integer_value(json_array_get(idx, 3 * (size_t)f + k));
        int same = 0;
        for (int rot = 0; rot < 3 && !same; rot++)
            same = g[0] == w[rot] && g[1] == w[(rot + 1) % 3] && g[2] == w[(rot + 2) % 3];
        if (!same)
            fail_msg("/api/avatar: face %u is %u %u %u, the file's %u %u %u", f, g[0], g[1], g[2], w[0], w[1], w[2]);
    }
    mim_mesh_free(&file);
    json_decref(j);
    return r;
}

static void check_status(int port)
{
    json_t *st = ss_get_status(port);
    assert_int_equal(ss_status_int(st, NULL, "vertices"), av.mesh.n_vertices);
    assert_int_equal(ss_status_int(st, NULL, "faces"), av.mesh.n_faces);
    json_decref(st);
}

/* POST /api/transfer {"template": id}: a GLB of the avatar's vertex and face
 * counts; its bytes (malloc'd) in *glb. */
static void post_transfer(int port, uint64_t id, unsigned char **glb, size_t *len)
{
    char body[64];
    snprintf(body, sizeof body, "{\"template\": %llu}", (unsigned long long)id);
    hc_reply_t r;
    int rc = hc_request(&r, port, "POST", "/api/transfer", "Content-Type: application/json\r\n", body, strlen(body),
                        60000);
    assert_int_equal(rc, HC_OK);
    if (r.status != 200)
        fail_msg("/api/transfer: %d %s", r.status, r.body);
    *len = r.len;
    *glb = malloc(r.len);
    memcpy(*glb, r.body, r.len);
    hc_reply_free(&r);
    glb_t g = glb_parse(*glb, *len, "/api/transfer");
    json_int_t pa = position_accessor(&g);
    assert_int_equal(accessor_count(&g, pa), av.mesh.n_vertices);
    json_t *prim = primitive(&g);
    json_t *ind = json_object_get(prim, "indices");
    assert_true(json_is_integer(ind));
    assert_int_equal(accessor_count(&g, json_integer_value(ind)), 3 * (json_int_t)av.mesh.n_faces);
    json_decref(g.json);
}

static float *glb_positions(const unsigned char *b, size_t n, const char *what)
{
    glb_t g = glb_parse(b, n, what);
    float *p = accessor_vec3(&g, position_accessor(&g));
    json_decref(g.json);
    return p;
}

/* The frames of the stream: the hello's counts, frames of the avatar's
 * vertex count that move, in its vertex order, and on key frames every
 * landmark of the avatar where the frame's landmark block says it is. */
static void check_stream(int port)
{
    ws_client_t w;
    json_t *hello = ss_ws_open(&w, port, "/ws", 0);
    assert_int_equal(ss_status_int(hello, NULL, "vertices"), av.mesh.n_vertices);
    assert_int_equal(ss_status_int(hello, NULL, "faces"), av.mesh.n_faces);
    json_t *names = json_object_get(hello, "landmark_names");
    const uint32_t L = (uint32_t)json_array_size(names);
    assert_int_equal(L, av.n_landmarks);
    int l_wrist = -1;
    for (uint32_t i = 0; i < L; i++) {
        assert_string_equal(json_string_value(json_array_get(names, i)), av.names[i]); /* the sidecar's order */
        if (!strcmp(av.names[i], "l_wrist"))
            l_wrist = (int)i;
    }
    assert_true(l_wrist >= 0);
    json_decref(hello);
    /* the avatar's own vertex nearest its left wrist landmark at rest (and
     * so for each landmark) */
    uint32_t near[MIM_LANDMARKS_MAX];
    for (uint32_t i = 0; i < L; i++) {
        double best = INFINITY;
        for (uint32_t v = 0; v < av.mesh.n_vertices; v++) {
            const float *p = av.mesh.positions + 3 * (size_t)v, *q = av.landmarks + 3 * i;
            double d = pow(p[0] - q[0], 2) + pow(p[1] - q[1], 2) + pow(p[2] - q[2], 2);
            if (d < best)
                best = d, near[i] = v;
        }
    }

    const size_t n3 = 3 * (size_t)av.mesh.n_vertices;
    float *first = malloc(n3 * sizeof *first), *cur = malloc(n3 * sizeof *cur);
    double max_change = 0.0, wrist_worst = 0.0, lm_worst = 0.0;
    int frames = 0, keys = 0, have_first = 0;
    double end = ss_now_s() + 60;
    while ((frames < 60 || keys < 5 || max_change <= 1e-3) && ss_now_s() < end) {
        ws_msg_t m;
        assert_int_equal(ss_next_frame(&w, &m, 10000, NULL), 1);
        mimf_t f = ss_parse_frame(&m);
        assert_int_equal(f.n, av.mesh.n_vertices);
        assert_int_equal(f.L, L);
        for (size_t i = 0; i < n3; i++)
            cur[i] = mimf_x(&f, i);
        if (frames % 10 == 0 || (f.flags & 1))
            assert_avatar_pose(cur, "a frame");
        if (!have_first) {
            memcpy(first, cur, n3 * sizeof *cur);
            have_first = 1;
        } else {
            for (size_t i = 0; i < n3; i++)
                max_change = fmax(max_change, fabs((double)cur[i] - first[i]));
        }
        /* a key frame made from this vest frame (key interval 1: at a longer
         * interval, the frame flagged key shows the key made some vest
         * frames before, with this one's landmarks) */
        if ((f.flags & 1) && f.key_interval == 1) {
            keys++;
            for (uint32_t i = 0; i < L; i++) {
                float u[3];
                for (int a = 0; a < 3; a++)
                    u[a] = mimf_f32(f.lm + 4 * (3 * i + a));
                assert_true(isfinite(u[0]) && isfinite(u[1]) && isfinite(u[2])); /* the vest loses none */
                const float *p = cur + 3 * (size_t)near[i];
                double d = sqrt(pow(p[0] - u[0], 2) + pow(p[1] - u[1], 2) + pow(p[2] - u[2], 2));
                lm_worst = fmax(lm_worst, d);
                if ((int)i == l_wrist)
                    wrist_worst = fmax(wrist_worst, d);
            }
        }
        frames++;
        ws_msg_free(&m);
    }
    ws_close(&w);
    free(first), free(cur);
    print_message("stream: %d frames, %d key frames; max change %.3f m; the avatar's vertex at its left wrist "
                  "within %.1f mm of the frame's l_wrist, every landmark within %.1f mm\n",
                  frames, keys, max_change, 1e3 * wrist_worst, 1e3 * lm_worst);
    if (keys < 5)
        fail_msg("only %d key frames in %d frames", keys, frames);
    if (!(max_change > 1e-3))
        fail_msg("the avatar did not move: max change %g m over %d frames", max_change, frames);
    if (!(wrist_worst < 0.03))
        fail_msg("the avatar's left wrist vertex is %.1f mm from the frame's l_wrist landmark", 1e3 * wrist_worst);
    if (!(lm_worst < 0.03))
        fail_msg("an avatar landmark vertex is %.1f mm from the frame's landmark", 1e3 * lm_worst);
}

/* The squat's transfer: lower than the avatar at rest, in its order. */
static void check_squat(const unsigned char *glb, size_t len, const char *what)
{
    float *p = glb_positions(glb, len, what);
    assert_avatar_pose(p, what);
    double h = y_extent(p, av.mesh.n_vertices);
    print_message("%s: the avatar in the squat is %.2f m tall, %.2f m at rest\n", what, h, rest_height);
    if (!(h < 0.9 * rest_height))
        fail_msg("%s: the avatar in template %llu's squat is %.3f m tall, at rest %.3f m", what,
                 (unsigned long long)squat_id, h, rest_height);
    free(p);
}

/* ---- 1. the first start registers, binds and serves the avatar's own mesh ---- */
static void test_first_start(void **state)
{
    (void)state;
    ss_svc_t S;
    double t0 = ss_now_s();
    start(&S, "first", "60");
    char *err = ts_read_file(S.serr, NULL);
    print_message("first start: %.1f s; stderr:\n%s", ss_now_s() - t0, err);
    if (!has_line_with(err, "avatar.ply: registered onto the store's connectivity (") ||
        !has_line_with(err, ") and bound, "))
        fail_msg("no 'registered onto the store's connectivity ... and bound' line:\n%s", err);
    free(err);

    hc_reply_t r = check_api_avatar(S.port);
    avatar_json = malloc(r.len);
    memcpy(avatar_json, r.body, r.len);
    avatar_json_len = r.len;
    hc_reply_free(&r);
    check_status(S.port);
    check_stream(S.port);
    post_transfer(S.port, squat_id, &first_glb, &first_glb_len);
    check_squat(first_glb, first_glb_len, "/api/transfer");
    ss_svc_term(&S);
    ss_svc_free(&S);
}

/* ---- 2. a restart finds the binding in the store ---- */
static void test_restart(void **state)
{
    (void)state;
    ss_svc_t S;
    double t0 = ss_now_s();
    start(&S, "restart", "15");
    char *err = ts_read_file(S.serr, NULL);
    print_message("restart: %.1f s\n", ss_now_s() - t0);
    if (has_line_with(err, "registered onto"))
        fail_msg("the restart registered the avatar again:\n%s", err);
    if (has_line_with(err, "binding"))
        fail_msg("the restart said something of the binding:\n%s", err);
    free(err);
    hc_reply_t r = ss_http_get(S.port, "/api/avatar");
    assert_int_equal(r.status, 200);
    assert_int_equal(r.len, avatar_json_len);
    assert_memory_equal(r.body, avatar_json, avatar_json_len);
    hc_reply_free(&r);
    check_status(S.port);
    /* the same binding: the same transfer, to the byte */
    unsigned char *glb;
    size_t len;
    post_transfer(S.port, squat_id, &glb, &len);
    assert_int_equal(len, first_glb_len);
    assert_memory_equal(glb, first_glb, len);
    free(glb);
    ws_client_t w;
    json_t *hello = ss_ws_open(&w, S.port, "/ws", 0);
    assert_int_equal(ss_status_int(hello, NULL, "vertices"), av.mesh.n_vertices);
    json_decref(hello);
    /* at key rate 15, morph frames between the key frames: they too are
     * the avatar's own (the morph runs on the proxy, then the binding) */
    int morphs = 0, keys = 0;
    float *p = malloc(3 * (size_t)av.mesh.n_vertices * sizeof *p);
    for (double end = ss_now_s() + 60; (morphs < 3 || keys < 1) && ss_now_s() < end;) {
        ws_msg_t m;
        assert_int_equal(ss_next_frame(&w, &m, 10000, NULL), 1);
        mimf_t f = ss_parse_frame(&m);
        assert_int_equal(f.n, av.mesh.n_vertices);
        assert_int_equal(f.key_interval, 4);
        for (size_t i = 0; i < 3 * (size_t)f.n; i++)
            p[i] = mimf_x(&f, i);
        assert_avatar_pose(p, f.flags & 1 ? "a key frame" : "a morph frame");
        keys += f.flags & 1, morphs += !(f.flags & 1);
        ws_msg_free(&m);
    }
    free(p);
    ws_close(&w);
    print_message("restart, key rate 15: %d morph frames and %d key frames of the avatar's own mesh\n", morphs, keys);
    assert_true(morphs >= 3 && keys >= 1);
    ss_svc_term(&S);
    ss_svc_free(&S);
}

/* ---- 3. a damaged cached binding is not trusted ---- */
/* The keys of the store's bindings table (LMDB directly, read-only). */
static size_t binding_keys(uint64_t *keys, size_t max)
{
    MDB_env *env;
    MDB_txn *txn;
    MDB_dbi dbi;
    MDB_cursor *c;
    assert_int_equal(mdb_env_create(&env), 0);
    mdb_env_set_maxdbs(env, 16);
    assert_int_equal(mdb_env_open(env, store, MDB_RDONLY, 0664), 0);
    assert_int_equal(mdb_txn_begin(env, NULL, MDB_RDONLY, &txn), 0);
    assert_int_equal(mdb_dbi_open(txn, "bindings", MDB_INTEGERKEY, &dbi), 0);
    assert_int_equal(mdb_cursor_open(txn, dbi, &c), 0);
    MDB_val k, v;
    size_t n = 0;
    for (int op = MDB_FIRST; mdb_cursor_get(c, &k, &v, (MDB_cursor_op)op) == 0; op = MDB_NEXT) {
        assert_int_equal(k.mv_size, sizeof(size_t));
        size_t key;
        memcpy(&key, k.mv_data, sizeof key);
        if (n < max)
            keys[n] = key;
        n++;
    }
    mdb_cursor_close(c);
    mdb_txn_abort(txn);
    mdb_env_close(env);
    return n;
}

static void put_binding(uint64_t key, const void *blob, size_t len)
{
    mim_db_t *db = NULL;
    mim_db_txn_t *t = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_binding_put(t, key, blob, len, &err), 0);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    mim_db_close(&db);
}

/* A copy of the binding the store holds under key (malloc'd), and the
 * store's faces (malloc'd, 3 * *n_faces). */
static void *get_binding(uint64_t key, size_t *len, uint32_t **faces, uint32_t *n_faces)
{
    mim_db_t *db = NULL;
    mim_db_txn_t *t = NULL;
    mim_error_t err = {0};
    mim_db_options_t ro = {.read_only = 1};
    const void *blob;
    assert_int_equal(mim_db_open(&db, store, &ro, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    assert_int_equal(mim_db_binding_get(t, key, &blob, len, &err), 0);
    void *copy = malloc(*len);
    memcpy(copy, blob, *len);
    mim_db_topology_t topo;
    assert_int_equal(mim_db_topology_get(t, &topo, &err), 0);
    assert_int_equal(topo.n_vertices, av.body_vertices);
    *n_faces = topo.n_faces;
    *faces = malloc(3 * (size_t)topo.n_faces * sizeof **faces);
    memcpy(*faces, topo.faces, 3 * (size_t)topo.n_faces * sizeof **faces);
    mim_db_abort(&t);
    mim_db_close(&db);
    return copy;
}

/* Flips one bit in the middle of the record under key, below the store's
 * API (LMDB directly): its checksum no longer matches. */
static void flip_binding(uint64_t key)
{
    MDB_env *env;
    MDB_txn *txn;
    MDB_dbi dbi;
    assert_int_equal(mdb_env_create(&env), 0);
    mdb_env_set_maxdbs(env, 16);
    assert_int_equal(mdb_env_open(env, store, 0, 0664), 0);
    assert_int_equal(mdb_txn_begin(env, NULL, 0, &txn), 0);
    assert_int_equal(mdb_dbi_open(txn, "bindings", MDB_INTEGERKEY, &dbi), 0);
    size_t k = (size_t)key;
    MDB_val kv = {sizeof k, &k}, v;
    assert_int_equal(mdb_get(txn, dbi, &kv, &v), 0);
    unsigned char *copy = malloc(v.mv_size);
    memcpy(copy, v.mv_data, v.mv_size);
    copy[v.mv_size / 2] ^= 0x10;
    MDB_val d = {v.mv_size, copy};
    assert_int_equal(mdb_put(txn, dbi, &kv, &d, 0), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);
    free(copy);
}

/* A service on the avatar after its binding was damaged: it warns, binds
 * again, serves the same avatar and the same transfer as the first start,
 * and keeps a good binding for the next (which finds it). */
static void expect_rebound(const char *tag, const char *damage)
{
    ss_svc_t S;
    start(&S, tag, "60");
    char *err = ts_read_file(S.serr, NULL);
    print_message("%s: stderr:\n%s", damage, err);
    if (!has_line_with(err, "avatar.ply: cached binding not usable ("))
        fail_msg("%s: no warning that the cached binding is not usable:\n%s", damage, err);
    if (!has_line_with(err, "avatar.ply: registered onto the store's connectivity ("))
        fail_msg("%s: the avatar was not bound again:\n%s", damage, err);
    free(err);
    hc_reply_t r = check_api_avatar(S.port);
    assert_int_equal(r.len, avatar_json_len);
    assert_memory_equal(r.body, avatar_json, avatar_json_len);
    hc_reply_free(&r);
    check_status(S.port);
    unsigned char *glb;
    size_t len;
    post_transfer(S.port, squat_id, &glb, &len);
    check_squat(glb, len, damage);
    float *a = glb_positions(glb, len, damage), *b = glb_positions(first_glb, first_glb_len, "the first");
    double worst = 0.0;
    for (size_t i = 0; i < 3 * (size_t)av.mesh.n_vertices; i++)
        worst = fmax(worst, fabs((double)a[i] - b[i]));
    print_message("%s: the transfer differs from the first start's by up to %g m\n", damage, worst);
    assert_true(worst < 1e-4);
    free(a), free(b), free(glb);
    ws_client_t w;
    json_decref(ss_ws_open(&w, S.port, "/ws", 0));
    ws_msg_t m;
    assert_int_equal(ss_next_frame(&w, &m, 10000, NULL), 1);
    mimf_t f = ss_parse_frame(&m);
    assert_int_equal(f.n, av.mesh.n_vertices);
    float *p = malloc(3 * (size_t)f.n * sizeof *p);
    for (size_t i = 0; i < 3 * (size_t)f.n; i++)
        p[i] = mimf_x(&f, i);
    assert_avatar_pose(p, damage);
    free(p);
    ws_msg_free(&m);
    ws_close(&w);
    ss_svc_term(&S);
    ss_svc_free(&S);

    /* the good binding is back in the store: the next command finds it */
    char *out = ts_path(dir, "after-damage.ply");
    const char *args[] = {"transfer", "--store", store, "--avatar", av_path, "--template", "1", "-o", out, NULL};
    char *e = NULL;
    assert_int_equal(ts_run_mimic(NULL, &e, args), 0);
    if (has_line_with(e, "registered onto") || has_line_with(e, "binding"))
        fail_msg("%s: the binding kept after it was not found again:\n%s", damage, e);
    free(e), free(out);
}

static void test_damaged_binding(void **state)
{
    (void)state;
    uint64_t keys[4];
    assert_int_equal(binding_keys(keys, 4), 1); /* the avatar's, kept by the first start */
    size_t good_len;
    uint32_t *faces, n_faces;
    void *good = get_binding(keys[0], &good_len, &faces, &n_faces);

    /* what is kept gives the avatar back at rest (register/'s API) */
    mim_reg_binding_t b;
    mim_error_t err = {0};
    assert_int_equal(mim_reg_binding_decode(good, good_len, av.body_vertices, n_faces, &b, &err), 0);
    assert_int_equal(b.n_vertices, av.mesh.n_vertices);
    float *work = malloc(3 * (size_t)av.body_vertices * sizeof *work);
    float *back = malloc(3 * (size_t)av.mesh.n_vertices * sizeof *back);
    mim_reg_binding_apply(&b, faces, b.proxy_rest, work, back);
    double worst = 0.0;
    for (size_t i = 0; i < 3 * (size_t)av.mesh.n_vertices; i++)
        worst = fmax(worst, fabs((double)back[i] - av.mesh.positions[i]));
    print_message("the kept binding gives the avatar back at rest within %.3g mm\n", 1e3 * worst);
    assert_true(worst < 1e-5);
    free(work), free(back);

    /* garbage where the binding was */
    unsigned char junk[4096];
    mim_rng_t rng;
    mim_rng_seed(&rng, 13, 0);
    for (size_t i = 0; i < sizeof junk; i++)
        junk[i] = (unsigned char)mim_rng_u64(&rng);
    put_binding(keys[0], junk, sizeof junk);
    expect_rebound("garbage", "a garbage binding");
    assert_int_equal(binding_keys(keys, 4), 1);

    /* the binding's own bytes, cut short */
    put_binding(keys[0], good, good_len / 2);
    expect_rebound("short", "a binding cut short");

    /* a binding whose every byte after its first 16 is garbage */
    unsigned char *bad = malloc(good_len);
    memcpy(bad, good, good_len);
    for (size_t i = 16; i < good_len; i++)
        bad[i] = (unsigned char)mim_rng_u64(&rng);
    put_binding(keys[0], bad, good_len);
    expect_rebound("fields", "a binding of garbage fields");
    free(bad);

    /* a binding that decodes (every field in range, the checksum right)
     * but is not this avatar's: its proxy half as big again. Trusted, it
     * would pose a proxy too big for the avatar's offsets. */
    for (size_t i = 0; i < 3 * (size_t)b.n_proxy_vertices; i++)
        b.proxy_rest[i] *= 1.5f;
    void *scaled;
    size_t scaled_len;
    assert_int_equal(mim_reg_binding_encode(&b, &scaled, &scaled_len, &err), 0);
    mim_reg_binding_free(&b);
    put_binding(keys[0], scaled, scaled_len);
    free(scaled);
    expect_rebound("scaled", "a binding of another proxy");

    /* the record damaged under the store (its checksum fails) */
    flip_binding(keys[0]);
    expect_rebound("flipped", "a binding whose checksum fails");
    assert_int_equal(binding_keys(keys, 4), 1);
    free(good), free(faces);
}

/* ---- 4. bad avatars: exit 1, one line naming the file ---- */
/* Runs `mimic serve ARGS` that must fail: its exit status, and stderr
 * (malloc'd). A service that starts instead fails the test. */
static int serve_fails(const char *const *args, char **err)
{
    char *o = ts_path(dir, "bad.out"), *e = ts_path(dir, "bad.err");
    pid_t p = ss_spawn(args, o, e);
    int st = ss_wait_exit(p, 120);
    if (st == -1) {
        ss_child_kill(p);
        fail_msg("mimic serve %s %s: still running after 2 minutes", args[3], args[4]);
    }
    *err = ts_read_file(e, NULL);
    free(o), free(e);
    assert_true(WIFEXITED(st));
    return WEXITSTATUS(st);
}

static void expect_refused(const char *what, const char *const *args, int want_status, const char *names,
                           const char *says)
{
    char *err = NULL;
    int st = serve_fails(args, &err);
    print_message("%s: exit %d: %s", what, st, err);
    if (st != want_status)
        fail_msg("%s: exit status %d, not %d: %s", what, st, want_status, err);
    if (count_lines(err) != 1 || strncmp(err, "mimic serve: ", 13))
        fail_msg("%s: not one line 'mimic serve: ...':\n%s", what, err);
    if (!strstr(err, names))
        fail_msg("%s: the message does not name %s: %s", what, names, err);
    if (says && !strstr(err, says))
        fail_msg("%s: the message does not say '%s': %s", what, says, err);
    free(err);
}

static void test_bad_avatars(void **state)
{
    (void)state;
    char why[512];
    /* another shuffle: another mesh, whose binding is in no cache */
    fa_options_t o = {.vertices = 2000, .seed = 7, .subdivisions = 1, .shuffle_seed = 23};
    fa_avatar_t b;
    char *nolm = ts_path(dir, "nolandmarks.ply"), *nulls = ts_path(dir, "nulls.json");
    assert_int_equal(fa_make(&o, &b, why, sizeof why), 0);
    assert_int_equal(fa_write(&b, nolm, NULL, -1, why, sizeof why), 0);
    /* a landmark file with a lost landmark (null): its positions are those of b */
    char *unused = ts_path(dir, "unused.ply");
    assert_int_equal(fa_write(&b, unused, nulls, 7, why, sizeof why), 0);
    fa_free(&b);
    /* two copies of the body, side by side, not joined */
    fa_options_t o2 = {.vertices = 2000, .seed = 7, .copies = 2, .shuffle_seed = 5};
    char *two = ts_path(dir, "two.ply"), *two_lm = ts_path(dir, "two.landmarks.json");
    assert_int_equal(fa_make(&o2, &b, why, sizeof why), 0);
    assert_int_equal(fa_write(&b, two, two_lm, -1, why, sizeof why), 0);
    fa_free(&b);

    const char *a1[] = {"serve", "--store", store, "--avatar", nolm, "--listen", "127.0.0.1:0", NULL};
    expect_refused("no landmarks", a1, 1, "nolandmarks.ply", "--avatar-landmarks");
    const char *a2[] = {"serve", "--store", store, "--avatar", two, "--listen", "127.0.0.1:0", NULL};
    /* several pieces are fine (issue 28: shells, props), but a second body
     * is no prop: most of the avatar lies far from the registered body */
    expect_refused("two bodies side by side", a2, 1, "two.ply", "from the registered body");
    const char *a3[] = {"serve", "--store", store, "--avatar", nolm, "--avatar-landmarks", nulls, "--listen",
                        "127.0.0.1:0", NULL};
    expect_refused("a landmark file with a null", a3, 1, "nulls.json", "l_wrist");
    /* a store without index: the registration starts from the nearest
     * template, which needs it; the command could not run (docs/reference.md: exit
     * status 2, as for every "no index where one is needed") */
    const char *a4[] = {"serve", "--store", store_noidx, "--avatar", av_path, "--listen", "127.0.0.1:0", NULL};
    expect_refused("a store without index", a4, 2, "avatar.ply", "mimic index");
    free(nolm), free(nulls), free(unused), free(two), free(two_lm);
}

/* ---- 5. mimic transfer and mimic morph write the avatar's own mesh ---- */
static void test_transfer_morph(void **state)
{
    (void)state;
    if (!first_glb)
        fail_msg("test_first_start did not pass: nothing to compare with");
    char *out = ts_path(dir, "squat.ply"), *glb = ts_path(dir, "morph.glb"), id[32], keys[64];
    snprintf(id, sizeof id, "%llu", (unsigned long long)squat_id);
    snprintf(keys, sizeof keys, "%llu,%llu", (unsigned long long)rest_id, (unsigned long long)squat_id);
    const char *t[] = {"transfer", "--store", store, "--avatar", av_path, "--template", id, "-o", out, NULL};
    char *e = NULL;
    if (ts_run_mimic(NULL, &e, t))
        fail_msg("mimic transfer: %s", e);
    free(e);
    mim_mesh_t m = {0};
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_mesh(out, &m, &err), 0);
    assert_int_equal(m.n_vertices, av.mesh.n_vertices);
    assert_int_equal(m.n_faces, av.mesh.n_faces);
    assert_avatar_pose(m.positions, "mimic transfer");
    /* the same pipeline as /api/transfer: the same pose */
    float *served = glb_positions(first_glb, first_glb_len, "/api/transfer");
    double worst = 0.0;
    for (size_t i = 0; i < 3 * (size_t)m.n_vertices; i++)
        worst = fmax(worst, fabs((double)m.positions[i] - served[i]));
    print_message("mimic transfer: %u vertices, %.2f m tall; differs from /api/transfer by up to %g m\n", m.n_vertices,
                  y_extent(m.positions, m.n_vertices), worst);
    assert_true(worst < 1e-5);
    free(served);
    mim_mesh_free(&m);

    const char *mo[] = {"morph", "--store", store, "--avatar", av_path, "--keys", keys, "--frames-between", "2",
                        "-o", glb, NULL};
    if (ts_run_mimic(NULL, &e, mo))
        fail_msg("mimic morph: %s", e);
    free(e);
    size_t len;
    unsigned char *b = (unsigned char *)ts_read_file(glb, &len);
    assert_non_null(b);
    glb_t g = glb_parse(b, len, "mimic morph");
    json_int_t pa = position_accessor(&g);
    assert_int_equal(accessor_count(&g, pa), av.mesh.n_vertices);
    float *base = accessor_vec3(&g, pa);
    assert_avatar_pose(base, "mimic morph's base mesh");
    free(base);
    /* every morph target's POSITION too */
    json_t *prim = primitive(&g);
    json_t *targets = json_object_get(prim, "targets");
    size_t i;
    json_t *tg;
    assert_true(json_array_size(targets) >= 1);
    json_array_foreach(targets, i, tg)
    {
        json_t *tp = json_object_get(tg, "POSITION");
        assert_true(json_is_integer(tp));
        assert_int_equal(accessor_count(&g, json_integer_value(tp)), av.mesh.n_vertices);
    }
    print_message("mimic morph: %zu bytes, %zu morph targets of %u vertices\n", len, json_array_size(targets),
                  av.mesh.n_vertices);
    json_decref(g.json);
    free(b);
    if (ts_gltf_validator_available())
        ts_gltf_validate(glb);
    free(out), free(glb);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_first_start),   cmocka_unit_test(test_restart),
        cmocka_unit_test(test_damaged_binding), cmocka_unit_test(test_bad_avatars),
        cmocka_unit_test(test_transfer_morph),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
