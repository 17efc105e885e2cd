/* The deployment of issue 16 (deploy/haproxy.cfg, used as it is): two
 * `mimic serve` replicas on 127.0.0.1, each on its own copy of one store
 * (`mimic store copy`) with its own simulated vest, behind HAProxy. A
 * vest's session (/ws?session=NAME) is pinned to its replica; other
 * requests go to any live one; an unknown session is a 404. Then one
 * replica is killed: the health check on /api/status marks it down, new
 * requests go to the live replica, its session's stream goes on without a
 * gap, and the dead replica's session answers 503. Skips (with a line
 * saying so) where haproxy is not installed; ./build.sh installs it. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "serve_support.h"

#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static char *dir; /* the test's folder, removed by teardown with every child killed */

static char *haproxy_path(void)
{
    const char *path = getenv("PATH");
    char buf[8192];
    snprintf(buf, sizeof buf, "%s:/usr/sbin:/sbin", path ? path : "/usr/bin:/bin");
    for (char *save = NULL, *d = strtok_r(buf, ":", &save); d; d = strtok_r(NULL, ":", &save)) {
        char *p = ts_path(d, "haproxy");
        if (access(p, X_OK) == 0) return p;
        free(p);
    }
    return NULL;
}

/* A port nobody listens on now (bound, read and released). */
static int free_port(void)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof a;
    int port = -1;
    if (fd >= 0 && bind(fd, (struct sockaddr *)&a, sizeof a) == 0 && getsockname(fd, (struct sockaddr *)&a, &len) == 0)
        port = ntohs(a.sin_port);
    if (fd >= 0) close(fd);
    return port;
}

/* The replica that answered (HAProxy's X-Mimic-Replica header), or "". */
static void replica_of(const char *head, char *out, size_t n)
{
    out[0] = 0;
    const char *h = head ? strcasestr(head, "\nx-mimic-replica:") : NULL;
    if (!h) return;
    h += strlen("\nx-mimic-replica:");
    while (*h == ' ') h++;
    size_t k = 0;
    while (h[k] && h[k] != '\r' && h[k] != '\n' && k + 1 < n) out[k] = h[k], k++;
    out[k] = 0;
}

/* GET /api/status through the balancer: the status (0: no answer, as while
 * haproxy starts) and the replica that gave it. */
static int get_status_via(int port, char *replica, size_t n)
{
    hc_reply_t r = {0};
    int rc = hc_request(&r, port, "GET", "/api/status", NULL, NULL, 0, 5000);
    int status = rc == HC_OK ? r.status : 0;
    replica_of(r.head, replica, n);
    hc_reply_free(&r);
    return status;
}

static void test_two_replicas_behind_haproxy(void **state)
{
    (void)state;
    char *haproxy = haproxy_path();
    if (!haproxy) {
        print_message("haproxy is not installed: skipping (./build.sh test installs it)\n");
        skip();
    }
    signal(SIGPIPE, SIG_IGN);
    dir = ts_tempdir("deploy");
    char *store = NULL;
    int have[13] = {0};
    assert_int_equal(ss_make_store(dir, 1, &store, have, 12), 12);
    /* each replica its own copy of the store */
    char *copy[2] = {ts_path(dir, "store_r1"), ts_path(dir, "store_r2")}, *o, *e;
    for (int r = 0; r < 2; r++) {
        const char *args[] = {"store", "copy", store, copy[r], NULL};
        if (ts_run_mimic(&o, &e, args)) fail_msg("store copy: %s", e);
        free(o), free(e);
    }
    /* each replica serves its vest as a session of that name, the name
     * the balancer's map pins to it */
    ss_svc_t rep[2] = {{0}};
    for (int r = 0; r < 2; r++) {
        char tag[8], session[4300];
        snprintf(tag, sizeof tag, "r%d", r + 1);
        assert_int_equal(ss_vest_start(&rep[r], dir, tag, NULL), 0);
        snprintf(session, sizeof session, "vest%d:vest=serial:%s,avatar=1", r + 1, rep[r].link);
        const char *args[] = {"serve", "--store", copy[r], "--session", session, "--vest-pose", "t",
                              "--listen", "127.0.0.1:0", NULL};
        assert_int_equal(ss_serve_start(&rep[r], dir, tag, args), 0);
    }
    /* the balancer, configured by deploy/haproxy.cfg through its environment */
    char *map = ts_path(dir, "sessions.map"), *hout = ts_path(dir, "haproxy.out"), *herr = ts_path(dir, "haproxy.err");
    const char *map_text = "vest1 be_r1\nvest2 be_r2\n";
    ts_write_file(map, map_text, strlen(map_text));
    char listen[64], r1[64], r2[64], who[64];
    snprintf(r1, sizeof r1, "127.0.0.1:%d", rep[0].port);
    snprintf(r2, sizeof r2, "127.0.0.1:%d", rep[1].port);
    setenv("MIMIC_R1", r1, 1), setenv("MIMIC_R2", r2, 1), setenv("MIMIC_SESSIONS", map, 1);
    char *cfg = ts_path(MIMIC_SOURCE_DIR, "deploy/haproxy.cfg");
    const char *hargs[] = {"-db", "-f", cfg, NULL};
    pid_t hp = 0;
    int up = 0, port = 0;
    /* a free port can be taken between its release and haproxy's bind: then
     * haproxy exits, and another port is tried */
    for (int attempt = 0; attempt < 3 && !up; attempt++) {
        port = free_port();
        assert_true(port > 0);
        snprintf(listen, sizeof listen, "127.0.0.1:%d", port);
        setenv("MIMIC_LISTEN", listen, 1);
        hp = ss_spawn_program(haproxy, hargs, hout, herr);
        assert_true(hp > 0);
        for (double end = ss_now_s() + 20; !up && ss_now_s() < end && ss_wait_exit(hp, 0) == -1;) {
            up = get_status_via(port, who, sizeof who) == 200;
            if (!up) ss_sleep_ms(100);
        }
    }
    if (!up) {
        char *t = ts_read_file(herr, NULL);
        fail_msg("haproxy did not answer on %s: %s", listen, t ? t : "");
    }
    /* requests without a session: any live replica, both in turn */
    int seen[2] = {0, 0};
    for (int i = 0; i < 8; i++) {
        assert_int_equal(get_status_via(port, who, sizeof who), 200);
        seen[0] |= !strcmp(who, "r1"), seen[1] |= !strcmp(who, "r2");
    }
    assert_true(seen[0] && seen[1]);
    /* each vest's session is pinned to its replica */
    ws_client_t w[2];
    const char *paths[2] = {"/ws?session=vest1", "/ws?session=vest2"};
    for (int r = 0; r < 2; r++) {
        json_t *hello = ss_ws_open(&w[r], port, paths[r], 0);
        json_decref(hello);
        replica_of(w[r].head, who, sizeof who);
        assert_string_equal(who, r == 0 ? "r1" : "r2");
        size_t n = 0;
        uint64_t *num = ss_collect_numbers(&w[r], 500, &n);
        assert_true(n > 0);
        ss_assert_consecutive(num, n, "a session's stream through the balancer");
        free(num);
    }
    hc_reply_t nf = ss_http_get(port, "/ws?session=nobody");
    assert_int_equal(nf.status, 404);
    assert_non_null(strstr(nf.body, "no such session"));
    hc_reply_free(&nf);
    /* replica 2 dies: its health check fails, everything without a session
     * goes to replica 1, and vest 1's stream goes on */
    ss_child_kill(rep[1].server);
    rep[1].server = 0;
    int only_r1 = 0;
    for (double end = ss_now_s() + 20; only_r1 < 8 && ss_now_s() < end;) {
        int st = get_status_via(port, who, sizeof who);
        only_r1 = st == 200 && !strcmp(who, "r1") ? only_r1 + 1 : 0;
    }
    assert_int_equal(only_r1, 8);
    assert_int_equal(ss_stream_reaches_newest(&w[0], rep[0].port), 1);
    size_t n = 0;
    uint64_t *num = ss_collect_numbers(&w[0], 500, &n);
    assert_true(n > 0);
    ss_assert_consecutive(num, n, "the live replica's session after the other died");
    free(num);
    hc_reply_t gone = ss_http_get(port, "/ws?session=vest2");
    assert_int_equal(gone.status, 503);
    hc_reply_free(&gone);
    ws_client_t again;
    json_decref(ss_ws_open(&again, port, "/ws?session=vest1", 0));
    replica_of(again.head, who, sizeof who);
    assert_string_equal(who, "r1");
    ws_close(&again);
    ws_close(&w[0]), ws_close(&w[1]);
    ss_assert_clean_stderr(rep[0].serr);
    ss_child_kill(hp);
    ss_svc_free(&rep[0]), ss_svc_free(&rep[1]);
    free(store), free(copy[0]), free(copy[1]), free(map), free(hout), free(herr), free(cfg), free(haproxy);
}

/* Also after a failed check: no replica, vest or balancer outlives the test. */
static int teardown(void **state)
{
    (void)state;
    ss_kill_children();
    if (dir) ts_rmtree(dir);
    free(dir);
    dir = NULL;
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test_teardown(test_two_replicas_behind_haproxy, teardown)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
