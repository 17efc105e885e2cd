/* Helpers of the end-to-end stream tests: serve_support.h. */
#include "serve_support.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

double ss_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

void ss_sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    while (nanosleep(&ts, &ts) && errno == EINTR) {
    }
}

/* ---- child processes: every one is killed in teardown ---- */
#define MAX_CHILDREN 16
static pid_t children[MAX_CHILDREN];

static void child_add(pid_t p)
{
    for (int i = 0; i < MAX_CHILDREN; i++)
        if (children[i] <= 0) {
            children[i] = p;
            return;
        }
}

static void child_forget(pid_t p)
{
    for (int i = 0; i < MAX_CHILDREN; i++)
        if (children[i] == p)
            children[i] = 0;
}

void ss_child_kill(pid_t p)
{
    if (p <= 0)
        return;
    kill(p, SIGKILL);
    waitpid(p, NULL, 0);
    child_forget(p);
}

/* Runs `mimic args...` with stdout and stderr to files; its pid. */
pid_t ss_spawn(const char *const *args, const char *out, const char *err)
{
    return ss_spawn_program(ts_mimic_bin(), args, out, err);
}

pid_t ss_spawn_program(const char *program, const char *const *args, const char *out, const char *err)
{
    /* gone before the child starts: a reader waiting for its first line
     * (ss_wait_line) never sees an earlier process's under the same name */
    unlink(out), unlink(err);
    pid_t p = fork();
    if (p == 0) {
        int fo = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644), fe = open(err, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fo, 1), dup2(fe, 2);
        close(fo), close(fe);
        int n = 0;
        while (args[n])
            n++;
        char **argv = calloc((size_t)n + 2, sizeof *argv);
        argv[0] = (char *)program;
        for (int i = 0; i < n; i++)
            argv[i + 1] = (char *)args[i];
        execvp(argv[0], argv);
        _exit(127);
    }
    if (p > 0)
        child_add(p);
    return p;
}

/* Waits for the child to exit within timeout_s: its wait status, or -1
 * (then it is still running). */
int ss_wait_exit(pid_t p, double timeout_s)
{
    double end = ss_now_s() + timeout_s;
    for (;;) {
        int st;
        pid_t r = waitpid(p, &st, WNOHANG);
        if (r == p) {
            child_forget(p);
            return st;
        }
        if (r < 0 || ss_now_s() > end)
            return -1;
        ss_sleep_ms(20);
    }
}

/* The file's text once it holds a line matching prefix (NULL: any line),
 * within timeout_s; NULL if not, or if the process exited first. */
char *ss_wait_line(const char *path, const char *prefix, pid_t p, double timeout_s)
{
    double end = ss_now_s() + timeout_s;
    for (;;) {
        char *t = ts_read_file(path, NULL);
        if (t) {
            for (char *l = t; *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : l + strlen(l)) {
                char *nl = strchr(l, '\n');
                if (nl && (!prefix || !strncmp(l, prefix, strlen(prefix))))
                    return t;
            }
            free(t);
        }
        if (ss_now_s() > end || (p > 0 && waitpid(p, NULL, WNOHANG) == p))
            return NULL;
        ss_sleep_ms(20);
    }
}

/* No sanitizer report in a server's stderr (the ASan build runs an ASan mimic). */
void ss_assert_clean_stderr(const char *path)
{
    char *t = ts_read_file(path, NULL);
    assert_non_null(t);
    const char *bad[] = {"AddressSanitizer", "LeakSanitizer", "runtime error:", "ThreadSanitizer"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        if (strstr(t, bad[i]))
            fail_msg("%s reports '%s':\n%s", path, bad[i], t);
    free(t);
}


/* extra: more serve arguments (NULL-terminated, may be NULL); faults: the
 * vest's --faults (may be NULL). */
int ss_vest_start(ss_svc_t *s, const char *dir, const char *tag, const char *faults)
{
    char name[64];
    snprintf(name, sizeof name, "%s.vest", tag), s->link = ts_path(dir, name);
    snprintf(name, sizeof name, "%s.vest.out", tag), s->vout = ts_path(dir, name);
    snprintf(name, sizeof name, "%s.vest.err", tag), s->verr = ts_path(dir, name);
    char out[4200];
    snprintf(out, sizeof out, "pty:%s", s->link);
    const char *vargs[] = {"vest", "simulate", "--motion", "demo", "--out", out, "--loop",
                           faults ? "--faults" : NULL, faults, NULL};
    s->vest = ss_spawn(vargs, s->vout, s->verr);
    char *t = ss_wait_line(s->vout, NULL, s->vest, 30);
    if (!t) {
        char *e = ts_read_file(s->verr, NULL);
        fprintf(stderr, "the simulated vest did not start: %s\n", e ? e : "");
        free(e);
        return -1;
    }
    free(t);
    return 0;
}

int ss_serve_start(ss_svc_t *s, const char *dir, const char *tag, const char *const *args)
{
    char name[64];
    snprintf(name, sizeof name, "%s.serve.out", tag), s->sout = ts_path(dir, name);
    snprintf(name, sizeof name, "%s.serve.err", tag), s->serr = ts_path(dir, name);
    s->server = ss_spawn(args, s->sout, s->serr);
    char *t = ss_wait_line(s->sout, "http://127.0.0.1:", s->server, 120);
    if (!t) {
        char *e = ts_read_file(s->serr, NULL);
        fprintf(stderr, "mimic serve did not print its URL: %s\n", e ? e : "");
        free(e);
        return -1;
    }
    s->port = atoi(strrchr(t, ':') + 1);
    free(t);
    return s->port > 0 ? 0 : -1;
}

int ss_svc_start(ss_svc_t *s, const char *dir, const char *store, const char *tag, const char *faults,
                 const char *const *extra)
{
    memset(s, 0, sizeof *s);
    if (ss_vest_start(s, dir, tag, faults))
        return -1;
    char vest[4200];
    snprintf(vest, sizeof vest, "serial:%s", s->link);
    const char *sargs[32] = {"serve", "--store", store, "--avatar", "1", "--vest", vest, "--vest-pose", "t",
                             "--listen", "127.0.0.1:0"};
    int n = 11;
    for (int i = 0; extra && extra[i] && n < 31; i++)
        sargs[n++] = extra[i];
    sargs[n] = NULL;
    return ss_serve_start(s, dir, tag, sargs);
}

void ss_svc_free(ss_svc_t *s)
{
    ss_child_kill(s->server);
    ss_child_kill(s->vest);
    s->server = s->vest = 0;
    free(s->link), free(s->vout), free(s->verr), free(s->sout), free(s->serr);
    memset(s, 0, sizeof *s);
}

/* SIGTERM to the server: it must exit 0 within a few seconds, cleanly. */
void ss_svc_term(ss_svc_t *s)
{
    assert_int_equal(kill(s->server, SIGTERM), 0);
    int st = ss_wait_exit(s->server, 10);
    if (st == -1)
        fail_msg("mimic serve did not exit within 10 s of SIGTERM");
    s->server = 0;
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 0);
    ss_assert_clean_stderr(s->serr);
}


/* The timeout of the checked requests. */
#define HTTP_TIMEOUT_MS 15000

hc_reply_t ss_http_raw(int port, const void *req, size_t n)
{
    hc_reply_t r;
    int rc = hc_raw(&r, port, req, n, HTTP_TIMEOUT_MS);
    assert_true(rc == HC_OK || rc == HC_ESEND); /* the server may close early: what it said is read */
    return r;
}

hc_reply_t ss_http_get(int port, const char *path)
{
    hc_reply_t r;
    int rc = hc_request(&r, port, "GET", path, NULL, NULL, 0, HTTP_TIMEOUT_MS);
    assert_true(rc == HC_OK || rc == HC_ESEND);
    return r;
}

json_t *ss_json_body(const hc_reply_t *r)
{
    json_error_t je;
    json_t *j = json_loadb(r->body, r->len, 0, &je);
    if (!j)
        fail_msg("not JSON (%s): %s", je.text, r->raw);
    return j;
}

json_t *ss_get_status(int port)
{
    hc_reply_t r = ss_http_get(port, "/api/status");
    assert_int_equal(r.status, 200);
    json_t *j = ss_json_body(&r);
    hc_reply_free(&r);
    return j;
}

json_int_t ss_status_int(json_t *j, const char *obj, const char *key)
{
    json_t *o = obj ? json_object_get(j, obj) : j;
    json_t *v = json_object_get(o, key);
    assert_true(json_is_integer(v));
    return json_integer_value(v);
}

const char *ss_vest_state(json_t *j)
{
    const char *s = json_string_value(json_object_get(json_object_get(j, "vest"), "state"));
    assert_non_null(s);
    return s;
}

/* One sample of /metrics (a line "NAME VALUE"). */
double ss_metric(int port, const char *name)
{
    hc_reply_t r = ss_http_get(port, "/metrics");
    assert_int_equal(r.status, 200);
    char want[128];
    snprintf(want, sizeof want, "\n%s ", name);
    const char *p = strstr(r.body, want);
    if (!p)
        fail_msg("/metrics has no %s", name);
    double v = strtod(p + strlen(want), NULL);
    hc_reply_free(&r);
    return v;
}

void ss_assert_alive(int port)
{
    hc_reply_t r = ss_http_get(port, "/api/status");
    if (r.status != 200)
        fail_msg("/api/status answered %d, not 200: %s", r.status, r.raw);
    hc_reply_free(&r);
}

/* ---- stream frames ---- */
/* Parses a binary message and checks what the spec fixes: magic, version,
 * length. */
mimf_t ss_parse_frame(const ws_msg_t *m)
{
    assert_int_equal(m->opcode, WS_BINARY);
    assert_true(m->len >= MIMF_HEADER);
    assert_memory_equal(m->data, "MIMF", 4);
    mimf_t f;
    mimf_decode(m->data, m->len, &f);
    assert_int_equal(f.version, 1);
    assert_int_equal(f.flags & ~3u, 0);
    assert_int_equal(m->len, mimf_size(&f));
    return f;
}

/* The next binary message within timeout_ms (text ones are skipped and
 * counted in *texts when given): 1, or 0 when none came. */
int ss_next_frame(ws_client_t *w, ws_msg_t *m, int timeout_ms, int *texts)
{
    double end = ss_now_s() + timeout_ms / 1000.0;
    for (;;) {
        int left = (int)((end - ss_now_s()) * 1000);
        if (left <= 0)
            return 0;
        int r = ws_recv(w, m, left);
        if (r <= 0)
            return 0;
        if (m->opcode == WS_BINARY)
            return 1;
        if (m->opcode == WS_CLOSE) {
            ws_msg_free(m);
            return 0;
        }
        if (texts)
            ++*texts;
        ws_msg_free(m);
    }
}

/* The next text message as JSON within timeout_ms (binary ones skipped). */
json_t *ss_next_text(ws_client_t *w, int timeout_ms)
{
    double end = ss_now_s() + timeout_ms / 1000.0;
    for (;;) {
        int left = (int)((end - ss_now_s()) * 1000);
        ws_msg_t m;
        if (left <= 0 || ws_recv(w, &m, left) <= 0)
            return NULL;
        if (m.opcode == WS_TEXT) {
            json_error_t je;
            json_t *j = json_loadb((const char *)m.data, m.len, 0, &je);
            if (!j)
                fail_msg("a text message that is not JSON: %s", m.data);
            ws_msg_free(&m);
            return j;
        }
        int close = m.opcode == WS_CLOSE;
        ws_msg_free(&m);
        if (close)
            return NULL;
    }
}

/* Connects to /ws (path may carry a query) and checks the hello. */
json_t *ss_ws_open(ws_client_t *w, int port, const char *path, int rcvbuf)
{
    if (ws_connect(w, port, path, rcvbuf))
        fail_msg("%s: no WebSocket upgrade (HTTP %d): %s", path, w->http_status, w->head);
    ws_msg_t m;
    assert_int_equal(ws_recv(w, &m, 5000), 1);
    if (m.opcode != WS_TEXT)
        fail_msg("the first message is opcode %d, not the text hello", m.opcode);
    json_t *j = json_loadb((const char *)m.data, m.len, 0, NULL);
    assert_non_null(j);
    assert_string_equal(json_string_value(json_object_get(j, "type")), "hello");
    ws_msg_free(&m);
    return j;
}

/* Reads frames for ms milliseconds; the frame numbers (malloc'd, *n of
 * them) and their local arrival times. */
uint64_t *ss_collect_numbers(ws_client_t *w, int ms, size_t *n)
{
    size_t cap = 1024;
    uint64_t *v = malloc(cap * sizeof *v);
    *n = 0;
    double end = ss_now_s() + ms / 1000.0;
    while (ss_now_s() < end) {
        ws_msg_t m;
        int left = (int)((end - ss_now_s()) * 1000);
        if (left <= 0 || !ss_next_frame(w, &m, left, NULL))
            break;
        mimf_t f = ss_parse_frame(&m);
        if (*n == cap)
            v = realloc(v, (cap *= 2) * sizeof *v);
        v[(*n)++] = f.number;
        ws_msg_free(&m);
    }
    return v;
}

void ss_assert_consecutive(const uint64_t *v, size_t n, const char *what)
{
    for (size_t i = 1; i < n; i++)
        if (v[i] != v[i - 1] + 1)
            fail_msg("%s: frame %llu follows %llu (a gap of %llu)", what, (unsigned long long)v[i],
                     (unsigned long long)v[i - 1], (unsigned long long)(v[i] - v[i - 1] - 1));
}

int ss_stream_reaches_newest(ws_client_t *w, int port)
{
    json_t *st = ss_get_status(port);
    const uint64_t newest = (uint64_t)ss_status_int(st, NULL, "frames");
    json_decref(st);
    uint64_t last = 0;
    double end = ss_now_s() + 10;
    while (ss_now_s() < end) {
        ws_msg_t m;
        if (!ss_next_frame(w, &m, (int)((end - ss_now_s()) * 1000) + 1, NULL))
            break;
        mimf_t f = ss_parse_frame(&m);
        ws_msg_free(&m);
        if (last && f.number != last + 1)
            fail_msg("frame %llu follows %llu", (unsigned long long)f.number, (unsigned long long)last);
        last = f.number;
        if (last >= newest)
            return 1;
    }
    print_message("the client reached frame %llu, not %llu, within 10 s\n", (unsigned long long)last,
                  (unsigned long long)newest);
    return 0;
}

void ss_kill_children(void)
{
    for (int i = 0; i < MAX_CHILDREN; i++)
        ss_child_kill(children[i]);
}

static int run_quiet(const char *const *args, char **out)
{
    char *err = NULL;
    int rc = ts_run_mimic(out, &err, args);
    if (rc)
        fprintf(stderr, "mimic %s failed (%d): %s\n", args[0], rc, err ? err : "");
    free(err);
    return rc;
}

int ss_make_store(const char *dir, int subjects, char **store, int *have, int max_id)
{
    char *bodies = ts_path(dir, "bodies"), n[16];
    *store = ts_path(dir, "store");
    snprintf(n, sizeof n, "%d", subjects);
    const char *synth[] = {"synth", "--out", bodies, "--subjects", n, "--poses", "12", "--vertices", "1500", NULL};
    const char *ingest[] = {"ingest", "--store", *store, bodies, NULL};
    const char *index[] = {"index", "--store", *store, NULL};
    const char *list[] = {"list", "--store", *store, "--json", NULL};
    char *out = NULL;
    int rc = run_quiet(synth, NULL);
    if (!rc)
        rc = run_quiet(ingest, NULL);
    if (!rc)
        rc = run_quiet(index, NULL);
    if (!rc)
        rc = run_quiet(list, &out);
    json_t *l = rc ? NULL : json_loads(out, 0, NULL);
    free(out), free(bodies);
    int count = 0;
    size_t i;
    json_t *row;
    json_array_foreach(l, i, row)
    {
        json_int_t id = json_integer_value(json_object_get(row, "id"));
        if (id >= 1 && id <= max_id)
            have[id] = 1, count++;
    }
    json_decref(l);
    return rc ? -1 : count;
}

int ss_fixture_open(const char *tag, int subjects, char **dir, char **store, int *have, ss_svc_t *svc)
{
    signal(SIGPIPE, SIG_IGN);
    srand(12345);
    *dir = ts_tempdir(tag);
    int n = *dir ? ss_make_store(*dir, subjects, store, have, subjects * 12) : -1;
    if (n != subjects * 12) {
        fprintf(stderr, "the store holds %d templates, not %d\n", n, subjects * 12);
        return -1;
    }
    return ss_svc_start(svc, *dir, *store, "a", NULL, NULL);
}

void ss_fixture_close(char **dir, char **store, ss_svc_t *svc)
{
    ss_svc_free(svc);
    ss_kill_children();
    if (*dir)
        ts_rmtree(*dir);
    free(*dir), free(*store);
    *dir = *store = NULL;
}
