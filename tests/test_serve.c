/* mimic serve end to end: the real binary on 127.0.0.1 (an ephemeral port)
 * over a synth store made here, spoken to with real sockets and plain
 * HTTP/1.1 (support/http_client.c). Status, avatar, query, transfer (GLB),
 * metrics, each error status, and a clean exit on SIGTERM. */
#include "mim_io.h"
#include "test_support.h"

#include "http_client.h"
#include "vest_support.h"

#include <jansson.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

/* synth naming: subject s pose p is template 1 + s * POSES + p (file order) */
#define SUBJECTS 3
#define POSES 12

static char *dir, *bodies, *store;
static mim_landmark_map_t map;
static pid_t server = -1;
static int port;

static int run(const char *const *args)
{
    char *out = NULL, *err = NULL;
    int rc = ts_run_mimic(&out, &err, args);
    if (rc)
        fprintf(stderr, "mimic %s failed (%d): %s\n", args[0], rc, err ? err : "");
    free(out), free(err);
    return rc;
}

/* Starts `mimic serve` on store st (with --vest vest --vest-pose t when
 * vest is given) and reads the URL it prints to learn the port. */
static int start_server_on(const char *st, const char *vest)
{
    if (server > 0) { /* a test that failed before stopping its server */
        kill(server, SIGKILL);
        waitpid(server, NULL, 0);
        server = -1;
    }
    int fd[2];
    if (pipe(fd))
        return -1;
    server = fork();
    if (server < 0)
        return -1;
    if (server == 0) {
        dup2(fd[1], 1);
        close(fd[0]), close(fd[1]);
        if (vest)
            execl(ts_mimic_bin(), ts_mimic_bin(), "serve", "--store", st, "--avatar", "1", "--listen",
                  "127.0.0.1:0", "--vest", vest, "--vest-pose", "t", (char *)NULL);
        else
            execl(ts_mimic_bin(), ts_mimic_bin(), "serve", "--store", st, "--avatar", "1", "--listen",
                  "127.0.0.1:0", (char *)NULL);
        _exit(127);
    }
    close(fd[1]);
    char line[256];
    size_t n = 0;
    struct pollfd p = {fd[0], POLLIN, 0};
    while (n < sizeof line - 1 && !memchr(line, '\n', n) && poll(&p, 1, 120000) == 1) {
        ssize_t r = read(fd[0], line + n, sizeof line - 1 - n);
        if (r <= 0)
            break;
        n += (size_t)r;
    }
    close(fd[0]);
    line[n] = 0;
    const char *colon = strrchr(line, ':');
    port = colon ? atoi(colon + 1) : 0;
    if (strncmp(line, "http://127.0.0.1:", 17) || port <= 0) {
        fprintf(stderr, "mimic serve printed '%s', not its URL\n", line);
        return -1;
    }
    return 0;
}

static int start_server(const char *vest)
{
    return start_server_on(store, vest);
}

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("serve");
    bodies = ts_path(dir, "bodies");
    store = ts_path(dir, "store");
    const char *synth[] = {"synth", "--out", bodies, "--subjects", "3", "--poses", "12", "--vertices", "1500", NULL};
    const char *ingest[] = {"ingest", "--store", store, bodies, NULL};
    const char *index[] = {"index", "--store", store, NULL};
    int rc = run(synth);
    if (!rc)
        rc = run(ingest);
    if (!rc)
        rc = run(index);
    char *lm = ts_path(bodies, "landmarks.json");
    if (!rc)
        rc = mim_landmarks_read(&map, lm, NULL);
    free(lm);
    if (!rc)
        rc = start_server(NULL);
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    if (server > 0) {
        kill(server, SIGKILL);
        waitpid(server, NULL, 0);
    }
    ts_rmtree(dir);
    free(dir), free(bodies), free(store);
    return 0;
}

/* One request on a fresh connection (support/http_client.h), read until
 * the server closes: it must connect, be sent whole, and be answered with
 * an HTTP/1.1 status line and headers. Headers (may be NULL) are extra
 * lines, each ending in \r\n; Content-Length is added for a body unless
 * given. */
static hc_reply_t http(const char *method, const char *path, const char *headers, const void *body, size_t len)
{
    hc_reply_t rep;
    assert_int_equal(hc_request(&rep, port, method, path, headers, body, len, HC_FOREVER), HC_OK);
    assert_non_null(rep.head);
    int status;
    assert_int_equal(sscanf(rep.raw, "HTTP/1.1 %d", &status), 1);
    return rep;
}

static json_t *json_of(const hc_reply_t *r)
{
    json_error_t je;
    json_t *j = json_loadb(r->body, r->len, 0, &je);
    if (!j)
        fail_msg("not JSON (%s): %s", je.text, r->body);
    return j;
}

/* {"landmarks": [...]} of a synth body, optionally with a template id. */
static char *landmarks_body(int s, int p, uint64_t tmpl)
{
    char name[64];
    snprintf(name, sizeof name, "synth_s%02d_p%02d.ply", s, p);
    char *path = ts_path(bodies, name);
    mim_mesh_t m = {0};
    mim_error_t e = {0};
    if (mim_io_read_mesh(path, &m, &e))
        fail_msg("%s", e.msg);
    json_t *arr = json_array();
    for (uint32_t k = 0; k < map.count; k++) {
        const float *x = m.positions + 3 * (size_t)map.vertex[k];
        json_array_append_new(arr, json_pack("[f, f, f]", (double)x[0], (double)x[1], (double)x[2]));
    }
    json_t *j = json_pack("{s:o}", "landmarks", arr);
    if (tmpl)
        json_object_set_new(j, "template", json_integer((json_int_t)tmpl));
    char *txt = json_dumps(j, JSON_COMPACT | JSON_REAL_PRECISION(9));
    json_decref(j);
    mim_mesh_free(&m);
    free(path);
    return txt;
}

static void test_status(void **state)
{
    (void)state;
    hc_reply_t r = http("GET", "/api/status", NULL, NULL, 0);
    assert_int_equal(r.status, 200);
    assert_non_null(strstr(r.head, "Content-Type: application/json"));
    json_t *j = json_of(&r);
    assert_string_equal(json_string_value(json_object_get(j, "store")), store);
    assert_string_equal(json_string_value(json_object_get(j, "avatar")), "template 1");
    assert_int_equal(json_integer_value(json_object_get(j, "templates")), SUBJECTS * POSES);
    assert_int_equal(json_integer_value(json_object_get(j, "landmarks")), map.count);
    json_t *ix = json_object_get(j, "index");
    assert_true(json_is_true(json_object_get(ix, "present")));
    assert_true(json_is_false(json_object_get(ix, "stale")));
    assert_true(json_real_value(json_object_get(j, "uptime_s")) >= 0.0);
    assert_int_equal(json_integer_value(json_object_get(j, "frames")), 0);
    assert_true(json_is_null(json_object_get(j, "vest")));
    json_decref(j);
    hc_reply_free(&r);
}

/* The index is readied on serve's own thread: soon every class is (a test
 * store's index takes milliseconds; the wait is only for a loaded
 * machine), and nothing was found damaged. (After test_metrics, which
 * counts the status requests.) */
static void test_index_ready(void **state)
{
    (void)state;
    int ready = 0;
    for (int i = 0; i < 600 && !ready; i++) {
        hc_reply_t r = http("GET", "/api/status", NULL, NULL, 0);
        json_t *j = json_of(&r), *ix = json_object_get(j, "index");
        ready = json_is_true(json_object_get(ix, "ready"));
        assert_true(json_is_boolean(json_object_get(ix, "ready")));
        assert_null(json_object_get(ix, "error"));
        json_decref(j);
        hc_reply_free(&r);
        if (!ready) usleep(100000);
    }
    assert_true(ready);
}

static void test_avatar(void **state)
{
    (void)state;
    char *path = ts_path(bodies, "synth_s00_p00.ply"); /* template 1, the avatar */
    mim_mesh_t m = {0};
    assert_int_equal(mim_io_read_mesh(path, &m, NULL), 0);
    hc_reply_t r = http("GET", "/api/avatar", NULL, NULL, 0);
    assert_int_equal(r.status, 200);
    json_t *j = json_of(&r);
    assert_int_equal(json_integer_value(json_object_get(j, "vertices")), m.n_vertices);
    assert_int_equal(json_integer_value(json_object_get(j, "faces")), m.n_faces);
    json_t *pos = json_object_get(j, "positions"), *idx = json_object_get(j, "indices");
    assert_int_equal(json_array_size(pos), 3 * (size_t)m.n_vertices);
    assert_int_equal(json_array_size(idx), 3 * (size_t)m.n_faces);
    for (size_t i = 0; i < 3 * (size_t)m.n_vertices; i++)
        assert_true((float)json_number_value(json_array_get(pos, i)) == m.positions[i]);
    json_decref(j);
    hc_reply_free(&r);
    mim_mesh_free(&m);
    free(path);
}

static void test_query_self(void **state)
{
    (void)state;
    const int cases[][2] = {{0, 3}, {1, 7}, {2, 11}};
    for (int c = 0; c < 3; c++) {
        char *body = landmarks_body(cases[c][0], cases[c][1], 0);
        hc_reply_t r = http("POST", "/api/query?k=2", "Content-Type: application/json\r\n", body, strlen(body));
        assert_int_equal(r.status, 200);
        json_t *j = json_of(&r);
        json_t *res = json_object_get(json_array_get(json_object_get(j, "frames"), 0), "results");
        assert_true(json_array_size(res) >= 1);
        assert_int_equal(json_integer_value(json_object_get(json_array_get(res, 0), "id")),
                         1 + cases[c][0] * POSES + cases[c][1]);
        assert_true(json_real_value(json_object_get(json_array_get(res, 0), "distance")) < 1e-6);
        json_decref(j);
        hc_reply_free(&r);
        free(body);
    }
}

static void assert_glb(const hc_reply_t *r)
{
    assert_int_equal(r->status, 200);
    assert_non_null(strstr(r->head, "Content-Type: model/gltf-binary"));
    assert_true(r->len > 12);
    assert_memory_equal(r->body, "glTF", 4);
    uint32_t total;
    memcpy(&total, r->body + 8, 4); /* the GLB header's length: the whole file arrived */
    assert_int_equal(total, r->len);
}

static void test_transfer(void **state)
{
    (void)state;
    const char *by_id = "{\"template\": 5}";
    hc_reply_t r = http("POST", "/api/transfer", NULL, by_id, strlen(by_id));
    assert_glb(&r);
    assert_non_null(strstr(r.head, "X-Mimic-Template: 5\r\n"));
    hc_reply_free(&r);
    /* landmarks alone: the template is their nearest pose */
    char *body = landmarks_body(2, 6, 0);
    r = http("POST", "/api/transfer", NULL, body, strlen(body));
    assert_glb(&r);
    char want[64];
    snprintf(want, sizeof want, "X-Mimic-Template: %d\r\n", 1 + 2 * POSES + 6);
    assert_non_null(strstr(r.head, want));
    hc_reply_free(&r);
    free(body);
    body = landmarks_body(1, 2, 9);
    r = http("POST", "/api/transfer", NULL, body, strlen(body));
    assert_glb(&r);
    assert_non_null(strstr(r.head, "X-Mimic-Template: 9\r\n"));
    /* serve's default: relative transfer (issue 15) */
    assert_non_null(strstr(r.head, "X-Mimic-Relative: 1\r\n"));
    assert_non_null(strstr(r.head, "X-Mimic-Drive: template")); /* the last header: head ends before its \r\n */
    hc_reply_free(&r);
    /* landmarks on the plain path: the skeleton drive, as serve's vests without orientations take it */
    free(body);
    body = landmarks_body(1, 2, 0);
    assert_true(body[0] == '{');
    char *plain = malloc(strlen(body) + 32);
    sprintf(plain, "{\"relative\": false, %s", body + 1);
    r = http("POST", "/api/transfer", NULL, plain, strlen(plain));
    assert_glb(&r);
    assert_non_null(strstr(r.head, "X-Mimic-Relative: 0\r\n"));
    assert_non_null(strstr(r.head, "X-Mimic-Drive: skeleton"));
    hc_reply_free(&r);
    free(plain), free(body);
    /* "relative": false asks for the plain transfer: another pose, said so */
    const char *rel[] = {"{\"template\": 9, \"relative\": true}", "{\"template\": 9, \"relative\": false}"};
    hc_reply_t on = http("POST", "/api/transfer", NULL, rel[0], strlen(rel[0]));
    hc_reply_t off = http("POST", "/api/transfer", NULL, rel[1], strlen(rel[1]));
    assert_glb(&on), assert_glb(&off);
    assert_non_null(strstr(on.head, "X-Mimic-Relative: 1"));
    assert_non_null(strstr(off.head, "X-Mimic-Relative: 0"));
    /* other positions; the lengths may differ too (the accessors' min and max are text in the JSON) */
    assert_true(on.len != off.len || memcmp(on.body, off.body, on.len) != 0);
    hc_reply_free(&on), hc_reply_free(&off);
}

static void test_metrics(void **state)
{
    (void)state;
    hc_reply_t r = http("GET", "/metrics", NULL, NULL, 0);
    assert_int_equal(r.status, 200);
    assert_non_null(strstr(r.head, "Content-Type: text/plain; version=0.0.4"));
    const char *names[] = {"\nmimic_queries_total 3\n", "\nmimic_transfers_total 6\n", "\nmimic_frames_total 0\n",
                           "# TYPE mimic_query_seconds histogram", "mimic_transfer_seconds_bucket{le=\"+Inf\"} 6",
                           "mimic_http_requests_total{route=\"status\",code=\"200\"} 1", "mimic_vest_errors_total"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (!strstr(r.body, names[i]))
            fail_msg("metrics lack '%s':\n%s", names[i], r.body);
    /* every sample line is a mimic_ name */
    for (const char *l = r.body; *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : l + strlen(l))
        if (*l != '#' && *l != '\n')
            assert_int_equal(strncmp(l, "mimic_", 6), 0);
    hc_reply_free(&r);
}

static void assert_error(const hc_reply_t *r, int status, const char *needle)
{
    assert_int_equal(r->status, status);
    json_t *j = json_of(r);
    const char *msg = json_string_value(json_object_get(j, "error"));
    assert_non_null(msg);
    if (needle && !strstr(msg, needle))
        fail_msg("error '%s' lacks '%s'", msg, needle);
    assert_null(strchr(msg, '\n'));
    json_decref(j);
}

static void test_errors(void **state)
{
    (void)state;
    const char *bad = "{\"landmarks\": [[0, 1, 2],";
    hc_reply_t r = http("POST", "/api/query", NULL, bad, strlen(bad));
    assert_error(&r, 400, "request body:1:");
    hc_reply_free(&r);
    const char *bad2 = "{\"template\": 5,\n \"tmpl\": }";
    r = http("POST", "/api/transfer", NULL, bad2, strlen(bad2));
    assert_error(&r, 400, "request body:2:");
    hc_reply_free(&r);
    /* a template that is not in the store is not there: 404 (issue 12, defect 6) */
    const char *unknown = "{\"template\": 999}";
    r = http("POST", "/api/transfer", NULL, unknown, strlen(unknown));
    assert_error(&r, 404, "no template 999");
    hc_reply_free(&r);
    const char *not_bool = "{\"template\": 5, \"relative\": 1}";
    r = http("POST", "/api/transfer", NULL, not_bool, strlen(not_bool));
    assert_error(&r, 400, "\"relative\" must be true or false");
    hc_reply_free(&r);
    const char *few = "{\"landmarks\": [[0, 1, 2]]}";
    r = http("POST", "/api/query", NULL, few, strlen(few));
    assert_error(&r, 400, "landmark map has 16");
    hc_reply_free(&r);
    /* oversized: a declared length over the limit is refused unread... */
    r = http("POST", "/api/query", "Content-Length: 2097152\r\n", "", 0);
    assert_error(&r, 413, "limit");
    hc_reply_free(&r);
    /* ...and so is a body that really is that long */
    size_t big = (size_t)3 << 19;
    char *blob = malloc(big);
    memset(blob, ' ', big);
    r = http("POST", "/api/transfer", NULL, blob, big);
    assert_error(&r, 413, "limit");
    hc_reply_free(&r);
    free(blob);
    r = http("GET", "/api/nothing", NULL, NULL, 0);
    assert_error(&r, 404, "/api/nothing");
    hc_reply_free(&r);
    r = http("GET", "/api/query", NULL, NULL, 0);
    assert_error(&r, 405, "POST");
    assert_non_null(strstr(r.head, "Allow: POST"));
    hc_reply_free(&r);
    /* still serving after all that */
    r = http("GET", "/api/status", NULL, NULL, 0);
    assert_int_equal(r.status, 200);
    hc_reply_free(&r);
}

static void test_sigterm(void **state)
{
    (void)state;
    assert_int_equal(kill(server, SIGTERM), 0);
    int st = 0;
    assert_int_equal(waitpid(server, &st, 0), server);
    server = -1;
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 0);
}

static void test_bad_usage(void **state)
{
    (void)state;
    char *out = NULL, *err = NULL;
    const char *a1[] = {"serve", "--store", store, NULL};
    assert_int_equal(ts_run_mimic(&out, &err, a1), 2);
    assert_non_null(strstr(err, "--avatar"));
    free(out), free(err);
    const char *a2[] = {"serve", "--store", store, "--avatar", "1", "--listen", "nowhere", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, a2), 2);
    assert_non_null(strstr(err, "HOST:PORT"));
    free(out), free(err);
    const char *a3[] = {"serve", "--store", store, "--avatar", "999", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, a3), 1);
    assert_non_null(strstr(err, "no template 999"));
    free(out), free(err);
    /* the options of the stream and the loop, and mimic demo's own: exit 2, one line saying what */
    static const struct {
        const char *args[8], *says;
    } bad[] = {
        {{"serve", "--store", "S", "--avatar", "1", "--key-rate", "fast"}, "--key-rate 'fast' is neither auto nor"},
        {{"serve", "--store", "S", "--avatar", "1", "--key-rate", "0"}, "--key-rate '0' is neither auto nor"},
        {{"serve", "--store", "S", "--avatar", "1", "--warm-start", "maybe"}, "--warm-start 'maybe' is not auto, on or off"},
        {{"serve", "--store", "S", "--avatar", "1", "--max-clients", "0"}, "--max-clients '0' is not a number in 1..1000"},
        {{"serve", "--store", "S", "--avatar", "1", "--blend", "17"}, "--blend '17' is not a number in 1..16"},
        {{"serve", "--store", "S", "--avatar", "1", "--segment-correction", "yes"}, "--segment-correction 'yes': use on or off"},
        {{"demo", "--duration", "-3"}, "--duration '-3' is not a number of seconds"},
        {{"demo", "--listen", "8080"}, "mimic demo: --listen '8080' is not HOST:PORT"},
        {{"demo", "--key-rate", "x"}, "mimic demo: --key-rate 'x' is neither auto nor"},
        {{"demo", "extra"}, "mimic demo: unexpected argument 'extra'"},
        {{"vest", "simulate", "--motion", "demo"}, "--out are required"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const char *a[8];
        for (int k = 0; k < 8; k++)
            a[k] = bad[i].args[k] && !strcmp(bad[i].args[k], "S") ? store : bad[i].args[k];
        assert_int_equal(ts_run_mimic(&out, &err, a), 2);
        if (!strstr(err, bad[i].says))
            fail_msg("mimic %s %s: said '%s', not '%s'", a[0], a[1], err, bad[i].says);
        assert_true(*err && strchr(err, '\n') == err + strlen(err) - 1); /* one line */
        free(out), free(err);
    }
}

/* A store without an index: what needs recognition answers 503 (the
 * query, a transfer of landmarks alone), what names a template works. */
static void test_no_index(void **state)
{
    (void)state;
    char *bare = ts_path(dir, "store-no-index");
    const char *ingest[] = {"ingest", "--store", bare, bodies, NULL};
    assert_int_equal(run(ingest), 0);
    assert_int_equal(start_server_on(bare, NULL), 0);
    char *body = landmarks_body(1, 4, 0);
    hc_reply_t r = http("POST", "/api/query", NULL, body, strlen(body));
    assert_error(&r, 503, "no index");
    hc_reply_free(&r);
    r = http("POST", "/api/transfer", NULL, body, strlen(body));
    assert_error(&r, 503, "no index");
    hc_reply_free(&r);
    free(body);
    body = landmarks_body(1, 4, 7);
    r = http("POST", "/api/transfer", NULL, body, strlen(body));
    assert_glb(&r);
    assert_non_null(strstr(r.head, "X-Mimic-Template: 7\r\n"));
    hc_reply_free(&r);
    free(body);
    r = http("GET", "/api/status", NULL, NULL, 0);
    assert_int_equal(r.status, 200);
    json_t *j = json_of(&r);
    const json_int_t before = json_integer_value(json_object_get(j, "templates"));
    json_decref(j);
    hc_reply_free(&r);
    /* issue 30: another process grows the store; the status follows it */
    char *more = ts_path(dir, "more-bodies");
    const char *synth[] = {"synth", "--out", more, "--subjects", "1", "--poses", "2", "--vertices", "1500", "--seed",
                           "5", NULL};
    const char *grow[] = {"ingest", "--store", bare, more, NULL};
    assert_int_equal(run(synth), 0);
    assert_int_equal(run(grow), 0);
    r = http("GET", "/api/status", NULL, NULL, 0);
    assert_int_equal(r.status, 200);
    j = json_of(&r);
    assert_int_equal(json_integer_value(json_object_get(j, "templates")), before + 2);
    json_decref(j);
    hc_reply_free(&r);
    free(more);
    test_sigterm(NULL);
    free(bare);
}

/* --vest: a recording of a simulated vest (a T-pose BVH) plays in real time;
 * every vest frame has all landmarks, so every vest frame the loop takes
 * becomes one published frame: a key frame or a morph between two (how
 * many are key frames depends on how fast the machine is now, so that is
 * not asserted; bench/serve measures it). */
static void test_vest_loop(void **state)
{
    (void)state;
    char *bvh = vs_write_bvh(dir, 30), *rec = ts_path(dir, "motion.vest");
    const char *sim[] = {"vest", "simulate", "--motion", bvh, "--out", rec, NULL};
    assert_int_equal(run(sim), 0);
    assert_int_equal(start_server(rec), 0);
    json_t *vest = NULL, *j = NULL;
    for (int tries = 0; tries < 600; tries++) { /* the recording lasts about a second */
        hc_reply_t r = http("GET", "/api/status", NULL, NULL, 0);
        assert_int_equal(r.status, 200);
        json_decref(j);
        j = json_of(&r);
        hc_reply_free(&r);
        vest = json_object_get(j, "vest");
        assert_true(json_is_object(vest));
        if (strcmp(json_string_value(json_object_get(vest, "state")), "streaming"))
            break;
        usleep(100000);
    }
    assert_string_equal(json_string_value(json_object_get(vest, "state")), "ended");
    assert_true(json_is_null(json_object_get(vest, "error")));
    json_int_t frames = json_integer_value(json_object_get(j, "frames")),
               vest_frames = json_integer_value(json_object_get(j, "vest_frames")),
               keys = json_integer_value(json_object_get(j, "key_frames"));
    json_int_t last = json_integer_value(json_object_get(vest, "last_template"));
    assert_true(last >= 1 && last <= SUBJECTS * POSES);
    /* the vest gives segment orientations and a synth avatar can be
     * segmented: every key frame is the orientation drive's (auto, issue 17),
     * and still recognised (last_template above) */
    assert_string_equal(json_string_value(json_object_get(vest, "drive")), "auto");
    assert_int_equal(json_integer_value(json_object_get(vest, "oriented_keys")), keys);
    assert_true(json_number_value(json_object_get(vest, "iterations_per_key")) == 1.0);
    json_decref(j);
    hc_reply_t r = http("GET", "/metrics", NULL, NULL, 0);
    const char *p = strstr(r.body, "\nmimic_vest_frames_skipped_total ");
    assert_non_null(p);
    long long skipped = atoll(p + strlen("\nmimic_vest_frames_skipped_total "));
    p = strstr(r.body, "\nmimic_morph_frames_total ");
    assert_non_null(p);
    long long morphs = atoll(p + strlen("\nmimic_morph_frames_total "));
    print_message("vest loop: %lld vest frames taken, %lld skipped (the loop was behind), %lld published: %lld key "
                  "frames, %lld morphs\n",
                  (long long)vest_frames, skipped, (long long)frames, (long long)keys, morphs);
    /* every vest frame of the recording was taken or skipped for a newer one */
    assert_true(vest_frames + skipped >= 30);
    /* each one taken became one frame */
    assert_int_equal(frames, vest_frames);
    /* key frames were made, and every frame was a key frame or a morph
     * (or the latest key pose again, before there are two to morph) */
    assert_true(keys >= 1);
    assert_true(keys + morphs <= frames);
    char want[64];
    snprintf(want, sizeof want, "\nmimic_key_frames_total %lld\n", (long long)keys);
    assert_non_null(strstr(r.body, want));
    assert_non_null(strstr(r.body, "\nmimic_vest_errors_total 0\n"));
    hc_reply_free(&r);
    test_sigterm(NULL);
    /* a vest that is not there: a clear error, exit 1 */
    char *out = NULL, *err = NULL;
    char *nothing = ts_path(dir, "no-such.vest");
    const char *bad[] = {"serve", "--store", store, "--avatar", "1", "--vest", nothing, NULL};
    assert_int_equal(ts_run_mimic(&out, &err, bad), 1);
    assert_non_null(strstr(err, "no-such.vest"));
    free(out), free(err), free(nothing), free(bvh), free(rec);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_status),   cmocka_unit_test(test_avatar),    cmocka_unit_test(test_query_self),
        cmocka_unit_test(test_transfer), cmocka_unit_test(test_metrics), cmocka_unit_test(test_index_ready),   cmocka_unit_test(test_errors),
        cmocka_unit_test(test_sigterm),  cmocka_unit_test(test_bad_usage),   cmocka_unit_test(test_no_index),
        cmocka_unit_test(test_vest_loop),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
