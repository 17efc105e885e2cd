/* mimic serve against hostile clients (issue 12): the real binary on
 * 127.0.0.1 with the real simulated vest, and clients that
 *  - announce WebSocket messages of 64 MB and stream megabytes of them
 *    (defect 1: each is closed with 1009 before it is held; the server's
 *    memory stays flat), and fragment messages up to and past the cap;
 *  - hold 500 connections with half-sent requests (slowloris) and 100
 *    with a POST announcing a gigabyte, trickling, while the API and a new
 *    WebSocket client must still be served within seconds (defect 2);
 *  - send paths and framings meant to confuse (defect 6: statuses;
 *    request smuggling; path traversal), and more clients than
 *    --max-clients.
 * Counts and waits are bounded; the binary comes from $MIMIC_BIN, so the
 * same test runs against an older server. */
#include "serve_support.h"

#include <errno.h>
#include <jansson.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#define SUBJECTS 2

static char *dir, *store;
static int templates_in_store[SUBJECTS * 12 + 1];
static ss_svc_t A; /* the demo motion at 60 Hz */

static int setup(void **state)
{
    (void)state;
    return ss_fixture_open("serve-hostile", SUBJECTS, &dir, &store, templates_in_store, &A);
}

static int teardown(void **state)
{
    (void)state;
    ss_fixture_close(&dir, &store, &A);
    return 0;
}

/* The resident memory of a process, KiB (0 if unknown). */
static long rss_kib(pid_t pid)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    char *t = ts_read_file(path, NULL);
    const char *p = t ? strstr(t, "\nVmRSS:") : NULL;
    long kb = p ? strtol(p + 7, NULL, 10) : 0;
    free(t);
    return kb;
}

/* ---- defect 1: the size of client messages ---- */
#define BIG_CLIENTS 40
#define ANNOUNCED ((uint64_t)64 << 20) /* what each frame header says */
#define STREAMED ((size_t)8 << 20)     /* what each client sends of it at most (320 MB in all), */
#define STREAMED_MIN ((size_t)1 << 20) /* and at least, close frame or not (unless the server hangs up) */
#define PIECE ((size_t)64 << 10)

/* The messages waiting on c (1 ms at most): a close frame's status, -2
 * while none came, -1 when the connection is gone without one. */
static int poll_close(ws_client_t *c)
{
    for (;;) {
        ws_msg_t m;
        int r = ws_recv(c, &m, 1);
        if (r < 0)
            return -1;
        if (r == 0)
            return -2;
        int st = m.opcode == WS_CLOSE ? (m.len >= 2 ? (m.data[0] << 8 | m.data[1]) : 0) : -2;
        ws_msg_free(&m);
        if (st != -2)
            return st;
    }
}

static void test_message_cap(void **state)
{
    (void)state;
    const long rss0 = rss_kib(A.server);
    ws_client_t c[BIG_CLIENTS];
    int status[BIG_CLIENTS];
    size_t sent[BIG_CLIENTS];
    for (int i = 0; i < BIG_CLIENTS; i++) {
        json_decref(ss_ws_open(&c[i], A.port, "/ws", 0));
        unsigned char h[14] = {0x81, 0x80 | 127};
        for (int k = 0; k < 8; k++)
            h[2 + k] = (unsigned char)(ANNOUNCED >> (56 - 8 * k));
        for (int k = 0; k < 4; k++)
            h[10 + k] = (unsigned char)rand();
        assert_int_equal(ws_send_raw(&c[i], h, sizeof h), 0);
        status[i] = -2, sent[i] = 0;
    }
    /* stream the payloads side by side, each until its close frame comes
     * (then 6 s more for the close frames still missing) */
    unsigned char *junk = malloc(PIECE);
    memset(junk, 'x', PIECE);
    long peak = rss0;
    double end = ss_now_s() + 30, end_wait = 0;
    for (;;) {
        int sending = 0, waiting = 0;
        for (int i = 0; i < BIG_CLIENTS; i++) {
            waiting += status[i] == -2;
            if (sent[i] >= (status[i] == -2 ? STREAMED : STREAMED_MIN))
                continue;
            sending++;
            ssize_t w = send(c[i].fd, junk, PIECE, MSG_DONTWAIT | MSG_NOSIGNAL);
            if (w > 0)
                sent[i] += (size_t)w;
            else if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK)
                sent[i] = STREAMED; /* the server has closed it: its close frame is read below */
        }
        if ((!waiting && !sending) || ss_now_s() > end)
            break;
        if (!sending) {
            if (!end_wait)
                end_wait = ss_now_s() + 6;
            else if (ss_now_s() > end_wait)
                break;
        }
        struct pollfd pf[BIG_CLIENTS];
        for (int i = 0; i < BIG_CLIENTS; i++)
            pf[i] = (struct pollfd){status[i] == -2 ? c[i].fd : -1, POLLIN, 0};
        poll(pf, BIG_CLIENTS, sending ? 0 : 50);
        for (int i = 0; i < BIG_CLIENTS; i++)
            if (pf[i].fd >= 0 && (pf[i].revents & (POLLIN | POLLHUP | POLLERR)))
                status[i] = poll_close(&c[i]);
        long r = rss_kib(A.server);
        peak = r > peak ? r : peak;
    }
    free(junk);
    size_t total = 0;
    int closed_1009 = 0;
    for (int i = 0; i < BIG_CLIENTS; i++) {
        total += sent[i];
        closed_1009 += status[i] == 1009;
    }
    const long rss1 = rss_kib(A.server);
    print_message("%d clients announcing %llu MB each: %.1f MB sent in all, %d closed with 1009; server RSS %ld -> "
                  "peak %ld -> %ld KiB\n",
                  BIG_CLIENTS, (unsigned long long)(ANNOUNCED >> 20), total / 1048576.0, closed_1009, rss0, peak, rss1);
    for (int i = 0; i < BIG_CLIENTS; i++) {
        if (status[i] != 1009)
            fail_msg("client %d (%.1f MB sent of a 64 MB frame): %s %d, not a close with 1009 (message too big)", i,
                     sent[i] / 1048576.0, status[i] == -2 ? "no close frame" : status[i] == -1 ? "closed without a close frame" : "close status",
                     status[i]);
        ws_close(&c[i]);
    }
    if (peak - rss0 > 300L * 1024)
        fail_msg("the server's RSS grew by %ld KiB (limit 300 MB)", peak - rss0);
    ss_assert_alive(A.port);
}

/* A message in pieces: fragments of the given sizes (a ping between the
 * first two); the bytes are {"format": "i16"} padded with spaces. */
static void send_fragmented(ws_client_t *w, const size_t *sizes, int n)
{
    size_t total = 0;
    for (int k = 0; k < n; k++)
        total += sizes[k];
    const char fmt[] = "{\"format\": \"i16\"}";
    assert_true(total >= sizeof fmt);
    char *msg = malloc(total + sizeof fmt);
    memset(msg, ' ', total);
    memcpy(msg, fmt, sizeof fmt - 1);
    size_t off = 0;
    for (int k = 0; k < n; k++) {
        unsigned first = (k == n - 1 ? 0x80u : 0u) | (k == 0 ? (unsigned)WS_TEXT : (unsigned)WS_CONT);
        assert_int_equal(ws_send_frame(w, first, 1, msg + off, sizes[k]), 0);
        if (k == 0)
            assert_int_equal(ws_send(w, WS_PING, "p", 1), 0); /* control frames may come between fragments */
        off += sizes[k];
    }
    free(msg);
}

static void test_fragments(void **state)
{
    (void)state;
    /* 3 KiB in three fragments: joined, and taken */
    ws_client_t w;
    json_decref(ss_ws_open(&w, A.port, "/ws", 0));
    const size_t three[] = {1024, 1024, 1024};
    send_fragmented(&w, three, 3);
    json_t *r = ss_next_text(&w, 5000);
    if (!r)
        fail_msg("a 3 KiB message in three fragments: no reply");
    assert_string_equal(json_string_value(json_object_get(r, "type")), "format");
    assert_string_equal(json_string_value(json_object_get(r, "format")), "i16");
    json_decref(r);
    ws_msg_t m;
    assert_int_equal(ss_next_frame(&w, &m, 3000, NULL), 1);
    assert_int_equal(ss_parse_frame(&m).i16, 1);
    ws_msg_free(&m);
    /* exactly 4096 bytes, in one frame: still taken */
    const size_t cap[] = {4096};
    send_fragmented(&w, cap, 1);
    r = ss_next_text(&w, 5000);
    assert_non_null(r);
    assert_string_equal(json_string_value(json_object_get(r, "type")), "format");
    json_decref(r);
    ws_close(&w);

    /* past the cap: one frame of 5000 bytes, and 3 x 2 KiB fragments */
    const size_t one[] = {5000}, frags[] = {2048, 2048, 2048};
    const struct {
        const char *what;
        const size_t *sizes;
        int n;
    } over[] = {{"a 5000-byte frame", one, 1}, {"6 KiB in three fragments", frags, 3}};
    for (int i = 0; i < 2; i++) {
        json_decref(ss_ws_open(&w, A.port, "/ws", 0));
        send_fragmented(&w, over[i].sizes, over[i].n);
        int st = ws_wait_close_frame(&w, 5000);
        if (st != 1009)
            fail_msg("%s: close status %d, not 1009", over[i].what, st);
        ws_close(&w);
    }
    ss_assert_alive(A.port);
}

/* ---- defect 2: slowloris and gigabyte bodies ---- */
#define SLOW 500
#define HUGE 100

static void test_starvation(void **state)
{
    (void)state;
    struct rlimit rl;
    assert_int_equal(getrlimit(RLIMIT_NOFILE, &rl), 0);
    if (rl.rlim_cur < SLOW + HUGE + 100 && rl.rlim_cur < rl.rlim_max) {
        rl.rlim_cur = rl.rlim_max;
        setrlimit(RLIMIT_NOFILE, &rl);
    }
    if (rl.rlim_cur < SLOW + HUGE + 100) {
        print_message("RLIMIT_NOFILE is %llu: too few descriptors for %d hostile sockets\n",
                      (unsigned long long)rl.rlim_cur, SLOW + HUGE);
        skip();
    }
    int *slow = malloc(SLOW * sizeof *slow), *huge = malloc(HUGE * sizeof *huge);
    const double t_open = ss_now_s();
    for (int i = 0; i < SLOW; i++) {
        slow[i] = hc_connect(A.port, 0);
        if (slow[i] < 0)
            fail_msg("slowloris socket %d: cannot connect: %s", i, strerror(errno));
        if (i % 2) /* half send part of a request line; the others nothing */
            hc_send_all(slow[i], "GET /api/sta", 12);
    }
    const char post[] = "POST /api/query HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 1000000000\r\n\r\n[[0.1, ";
    for (int i = 0; i < HUGE; i++) {
        huge[i] = hc_connect(A.port, 0);
        if (huge[i] < 0)
            fail_msg("body socket %d: cannot connect: %s", i, strerror(errno));
        hc_send_all(huge[i], post, sizeof post - 1);
    }
    /* a trickle on every one of them */
    for (int i = 0; i < SLOW; i++)
        if (i % 2)
            send(slow[i], "t", 1, MSG_NOSIGNAL | MSG_DONTWAIT);
    for (int i = 0; i < HUGE; i++)
        send(huge[i], "0.2, ", 5, MSG_NOSIGNAL | MSG_DONTWAIT);

    /* while all of them are open: the API answers, a new client streams */
    double t0 = ss_now_s();
    hc_reply_t r;
    int rc = hc_request(&r, A.port, "GET", "/api/status", NULL, NULL, 0, 5000);
    double t_status = ss_now_s() - t0;
    if (rc != HC_OK || r.status != 200)
        fail_msg("with %d slowloris and %d gigabyte-body sockets open: /api/status gave %d after %.1f s", SLOW, HUGE,
                 r.status, t_status);
    hc_reply_free(&r);
    t0 = ss_now_s();
    ws_client_t w;
    if (ws_connect(&w, A.port, "/ws", 0))
        fail_msg("with %d slowloris and %d gigabyte-body sockets open: no WebSocket upgrade (HTTP %d) after %.1f s",
                 SLOW, HUGE, w.http_status, ss_now_s() - t0);
    json_t *hello = ss_next_text(&w, 5000);
    assert_non_null(hello);
    assert_string_equal(json_string_value(json_object_get(hello, "type")), "hello");
    json_decref(hello);
    for (int k = 0; k < 3; k++) {
        ws_msg_t m;
        if (!ss_next_frame(&w, &m, 5000, NULL))
            fail_msg("the new WebSocket client got %d frames, not 3", k);
        ss_parse_frame(&m);
        ws_msg_free(&m);
    }
    double t_ws = ss_now_s() - t0;
    ws_close(&w);
    print_message("%d slowloris + %d gigabyte-body sockets open: /api/status in %.3f s; a new /ws client had its "
                  "hello and 3 frames in %.3f s\n",
                  SLOW, HUGE, t_status, t_ws);
    assert_true(t_status < 5.0 && t_ws < 5.0);

    /* each gigabyte body had its 413 at once, and its connection closed */
    int answered = 0;
    for (int i = 0; i < HUGE; i++) {
        assert_int_equal(hc_read_reply(&r, huge[i], 10000), HC_OK);
        answered += r.status == 413;
        if (r.status != 413)
            fail_msg("gigabyte body %d: status %d, not 413:\n%.300s", i, r.status, r.raw);
        hc_reply_free(&r);
        close(huge[i]);
    }
    /* the slowloris sockets are closed by the server: headers must be
     * whole within 10 s (a trickle does not extend it) */
    int closed = 0;
    double deadline = t_open + 16;
    for (int i = 0; i < SLOW; i++) {
        char buf[512];
        for (;;) {
            long k = hc_recv(slow[i], buf, sizeof buf, deadline * 1e3); /* both CLOCK_MONOTONIC */
            if (k < 0) {
                closed++;
                break;
            }
            if (k == 0)
                break; /* still open at the deadline */
        }
        close(slow[i]);
    }
    print_message("%d of %d gigabyte bodies answered 413; %d of %d slowloris sockets closed by the server within "
                  "%.1f s of opening\n",
                  answered, HUGE, closed, SLOW, ss_now_s() - t_open);
    assert_int_equal(closed, SLOW);
    free(slow), free(huge);
    ss_assert_alive(A.port);
}

/* ---- defect 6 and friends: statuses, smuggling, traversal ---- */
static void expect_json_error(const hc_reply_t *r, const char *what, int a, int b)
{
    if (r->status != a && r->status != b)
        fail_msg("%s: status %d, not %d or %d:\n%.300s", what, r->status, a, b, r->raw);
    json_error_t je;
    json_t *j = json_loadb(r->body, r->len, 0, &je);
    if (!j)
        fail_msg("%s: the body is not JSON (%s):\n%.300s", what, je.text, r->raw);
    const char *msg = json_string_value(json_object_get(j, "error"));
    if (!msg || strchr(msg, '\n'))
        fail_msg("%s: no one-line error", what);
    json_decref(j);
}

static int count(const char *hay, const char *needle)
{
    int n = 0;
    for (const char *p = hay; (p = strstr(p, needle)); p++)
        n++;
    return n;
}

static void test_statuses(void **state)
{
    (void)state;
    const int p = A.port;
    hc_reply_t r = ss_http_get(p, "/%c0%ae");
    expect_json_error(&r, "GET /%c0%ae (an overlong '.')", 400, 404);
    hc_reply_free(&r);
    r = ss_http_get(p, "/%00zzz");
    expect_json_error(&r, "GET /%00zzz (a NUL in the path)", 400, 404);
    hc_reply_free(&r);
    r = ss_http_get(p, "/index.html%00.js");
    if (r.status) /* (libwebsockets 4.1 closes this one itself, without an answer) */
        expect_json_error(&r, "GET /index.html%00.js", 400, 404);
    hc_reply_free(&r);
    /* traversal: never a file from outside the viewer */
    const char *up[] = {"/../../../../etc/passwd", "/%2e%2e/%2e%2e/%2e%2e/etc/passwd", "/..%2f..%2f..%2fetc%2fpasswd",
                        "/three/../../../etc/passwd"};
    for (size_t i = 0; i < sizeof up / sizeof up[0]; i++) {
        r = ss_http_get(p, up[i]);
        if (r.status == 200 || strstr(r.raw, "root:"))
            fail_msg("GET %s: status %d:\n%.300s", up[i], r.status, r.raw);
        assert_true(r.status >= 400 && r.status < 500);
        hc_reply_free(&r);
    }
    /* smuggling: a body framed two ways, or by an unknown coding, is
     * refused and the connection closed: the request hidden behind it is
     * never answered */
    const char *smuggle[] = {
        "POST /api/query HTTP/1.1\r\nHost: x\r\nContent-Length: 6\r\nTransfer-Encoding: chunked\r\n\r\n"
        "0\r\n\r\nGET /api/status HTTP/1.1\r\nHost: x\r\n\r\n",
        "POST /api/query HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: gzip, chunked\r\n\r\n"
        "0\r\n\r\nGET /api/status HTTP/1.1\r\nHost: x\r\n\r\n",
        "POST /api/query HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\nContent-Length: 45\r\n\r\n"
        "{}GET /api/status HTTP/1.1\r\nHost: x\r\n\r\n",
        "POST /api/query HTTP/1.1\r\nHost: x\r\nContent-Length: +2\r\n\r\n{}GET /api/status HTTP/1.1\r\nHost: x\r\n\r\n",
    };
    for (size_t i = 0; i < sizeof smuggle / sizeof smuggle[0]; i++) {
        r = ss_http_raw(p, smuggle[i], strlen(smuggle[i]));
        if (r.status && r.status != 400)
            fail_msg("smuggling %zu: status %d, not 400:\n%.400s", i, r.status, r.raw);
        if (count(r.raw, "HTTP/1.1 ") > 1)
            fail_msg("smuggling %zu: the hidden request was answered:\n%.600s", i, r.raw);
        hc_reply_free(&r);
    }
    /* an error to a request whose body is not read closes the connection */
    const char get_body[] = "GET /nothing HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\nabc";
    int fd = hc_connect(p, 0);
    assert_true(fd >= 0);
    hc_send_all(fd, get_body, sizeof get_body - 1);
    double t0 = ss_now_s();
    assert_int_equal(hc_read_reply(&r, fd, 10000), HC_OK); /* until the server closes */
    close(fd);
    expect_json_error(&r, "GET with an unread body", 404, 404);
    assert_non_null(strstr(r.head, "Connection: close"));
    print_message("an error to a request with an unread body: answered and closed in %.2f s\n", ss_now_s() - t0);
    assert_true(ss_now_s() - t0 < 5.0);
    hc_reply_free(&r);
    ss_assert_alive(p);
}

/* --max-clients: the handshake past it is refused, and a place that frees
 * up is taken again */
static void test_max_clients(void **state)
{
    (void)state;
    ss_svc_t B;
    const char *extra[] = {"--max-clients", "2", NULL};
    assert_int_equal(ss_svc_start(&B, dir, store, "b", NULL, extra), 0);
    ws_client_t c[3];
    json_decref(ss_ws_open(&c[0], B.port, "/ws", 0));
    json_decref(ss_ws_open(&c[1], B.port, "/ws", 0));
    if (ws_connect(&c[2], B.port, "/ws", 0) == 0)
        fail_msg("a third client was let in with --max-clients 2");
    print_message("the third client: HTTP %d\n", c[2].http_status);
    assert_int_not_equal(c[2].http_status, 101);
    ws_close(&c[0]);
    int in = 0;
    for (int k = 0; k < 50 && !in; k++) { /* the server sees the close */
        in = ws_connect(&c[2], B.port, "/ws", 0) == 0;
        if (!in)
            ss_sleep_ms(50);
    }
    assert_true(in);
    ws_close(&c[1]), ws_close(&c[2]);
    ss_svc_term(&B);
    ss_svc_free(&B);
}

/* after all that, the service still stops cleanly on SIGTERM (under the
 * sanitizers: no leak, no error report) */
static void test_clean_exit(void **state)
{
    (void)state;
    ss_assert_alive(A.port);
    ss_svc_term(&A);
}

/* Clients that never read cannot lock viewers out (issue 30, item 4):
 * with --max-clients 2 held by two clients that stopped reading after
 * their hello, once frames are dropped for them a new viewer still gets
 * in (the client stalled longest gives up its place) and receives the
 * stream without a gap; the other stalled client is closed after
 * MIM_SERVE_STALL_CLOSE_S; the reading viewer is never evicted. */
static void test_stalled_clients_yield(void **state)
{
    (void)state;
    ss_svc_t B;
    const char *extra[] = {"--max-clients", "2", NULL};
    assert_int_equal(ss_svc_start(&B, dir, store, "stall", NULL, extra), 0);
    ws_client_t idle[2], viewer;
    for (int k = 0; k < 2; k++)
        json_decref(ss_ws_open(&idle[k], B.port, "/ws", 4096)); /* small buffers, then never read */
    if (ws_connect(&viewer, B.port, "/ws", 0) == 0)
        fail_msg("a third client was let in with --max-clients 2 before any client stalled");
    assert_int_equal(viewer.http_status, 503);
    double t0 = ss_now_s();
    while (ss_metric(B.port, "mimic_frames_dropped_total") < 2 && ss_now_s() - t0 < 60)
        ss_sleep_ms(100);
    assert_true(ss_metric(B.port, "mimic_frames_dropped_total") >= 2);
    print_message("stalled clients: frames dropped for them %.1f s after they stopped reading\n", ss_now_s() - t0);
    int in = 0;
    double t1 = ss_now_s();
    while (!in && ss_now_s() - t1 < 30) { /* MIM_SERVE_STALL_YIELD_S after their first drop */
        in = ws_connect(&viewer, B.port, "/ws", 0) == 0;
        if (!in)
            ss_sleep_ms(100);
    }
    if (!in)
        fail_msg("a new viewer was kept out by two clients that never read");
    assert_true(ss_metric(B.port, "mimic_ws_evicted_total") >= 1);
    json_decref(ss_next_text(&viewer, 10000)); /* its hello */
    size_t n = 0;
    uint64_t *v = ss_collect_numbers(&viewer, 3000, &n);
    ss_assert_consecutive(v, n, "the viewer that took a stalled client's place");
    print_message("the new viewer: in %.1f s after the drops began, %zu frames in 3 s\n", ss_now_s() - t1 - 3, n);
    assert_true(n > 0);
    free(v);
    /* the other stalled client is closed in time; the viewer that reads stays */
    double t2 = ss_now_s();
    while (ss_metric(B.port, "mimic_ws_evicted_total") < 2 && ss_now_s() - t2 < 60) {
        free(ss_collect_numbers(&viewer, 250, &n));
    }
    assert_true(ss_metric(B.port, "mimic_ws_evicted_total") >= 2);
    v = ss_collect_numbers(&viewer, 500, &n);
    assert_true(n > 0); /* still streaming */
    free(v);
    assert_true(ss_metric(B.port, "mimic_ws_evicted_total") == 2);
    ws_close(&viewer), ws_close(&idle[0]), ws_close(&idle[1]);
    ss_svc_term(&B);
    ss_svc_free(&B);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_message_cap), cmocka_unit_test(test_fragments),   cmocka_unit_test(test_starvation),
        cmocka_unit_test(test_statuses),    cmocka_unit_test(test_max_clients), cmocka_unit_test(test_stalled_clients_yield), cmocka_unit_test(test_clean_exit),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
