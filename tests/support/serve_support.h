/* What the end-to-end tests of mimic serve's stream share
 * (test_serve_stream.c, test_serve_service.c): child processes that are
 * all killed at the end, a service (a simulated vest on a pty and `mimic
 * serve` reading it), and checked HTTP requests and /ws frames
 * (schemas/serve-ws-frame.md) over the one client (http_client.h,
 * ws_client.h). The checks fail the running cmocka test. */
#ifndef MIM_TEST_SERVE_SUPPORT_H
#define MIM_TEST_SERVE_SUPPORT_H

#include "http_client.h"
#include "test_support.h"
#include "ws_client.h"

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

/* ---- a service: a simulated vest on a pty and mimic serve reading it ---- */
typedef struct ss_svc {
    pid_t vest, server;
    int port;
    char *link, *vout, *verr, *sout, *serr;
} ss_svc_t;


double ss_now_s(void);
void ss_sleep_ms(int ms);
void ss_child_kill(pid_t p);
/* Runs `mimic args...` with stdout and stderr to files; its pid. */
pid_t ss_spawn(const char *const *args, const char *out, const char *err);
/* The same for another program (found on PATH), killed at the end too. */
pid_t ss_spawn_program(const char *program, const char *const *args, const char *out, const char *err);
/* Waits for the child to exit within timeout_s: its wait status, or -1
 * (then it is still running). */
int ss_wait_exit(pid_t p, double timeout_s);
/* The file's text once it holds a line matching prefix (NULL: any line),
 * within timeout_s; NULL if not, or if the process exited first. */
char *ss_wait_line(const char *path, const char *prefix, pid_t p, double timeout_s);
/* No sanitizer report in a server's stderr (the ASan build runs an ASan mimic). */
void ss_assert_clean_stderr(const char *path);
/* The simulated vest alone (the demo motion on a pty at DIR/TAG.vest, looping,
 * with faults if not NULL): s's vest, link, vout and verr. 0 once it has
 * started, or -1 with the reason on stderr. */
int ss_vest_start(ss_svc_t *s, const char *dir, const char *tag, const char *faults);
/* mimic serve with args (NULL-terminated, "serve" first, listening on
 * 127.0.0.1:0), its output in DIR/TAG.serve.out and .err: s's server,
 * sout, serr and port. 0 once it has printed its URL, or -1 with the
 * reason on stderr. */
int ss_serve_start(ss_svc_t *s, const char *dir, const char *tag, const char *const *args);
/* extra: more serve arguments (NULL-terminated, may be NULL); faults: the
 * vest's --faults (may be NULL). */
int ss_svc_start(ss_svc_t *s, const char *dir, const char *store, const char *tag, const char *faults,
                 const char *const *extra);
void ss_svc_free(ss_svc_t *s);
/* SIGTERM to the server: it must exit 0 within a few seconds, cleanly. */
void ss_svc_term(ss_svc_t *s);
/* The reply (free with hc_reply_free) to the bytes sent as they are on a
 * fresh connection (whether or not the server takes them all), read until
 * the server closes or 15 s pass. */
hc_reply_t ss_http_raw(int port, const void *req, size_t n);
hc_reply_t ss_http_get(int port, const char *path);
json_t *ss_json_body(const hc_reply_t *r);
json_t *ss_get_status(int port);
json_int_t ss_status_int(json_t *j, const char *obj, const char *key);
const char *ss_vest_state(json_t *j);
/* One sample of /metrics (a line "NAME VALUE"). */
double ss_metric(int port, const char *name);
void ss_assert_alive(int port);
/* Parses a binary message and checks what the spec fixes: magic, version,
 * length. */
mimf_t ss_parse_frame(const ws_msg_t *m);
/* The next binary message within timeout_ms (text ones are skipped and
 * counted in *texts when given): 1, or 0 when none came. */
int ss_next_frame(ws_client_t *w, ws_msg_t *m, int timeout_ms, int *texts);
/* The next text message as JSON within timeout_ms (binary ones skipped). */
json_t *ss_next_text(ws_client_t *w, int timeout_ms);
/* Connects to /ws (path may carry a query) and checks the hello. */
json_t *ss_ws_open(ws_client_t *w, int port, const char *path, int rcvbuf);
/* Reads frames for ms milliseconds; the frame numbers (malloc'd, *n of
 * them) and their local arrival times. */
uint64_t *ss_collect_numbers(ws_client_t *w, int ms, size_t *n);
void ss_assert_consecutive(const uint64_t *v, size_t n, const char *what);
/* A client that keeps up gets every frame the loop publishes: reads w's
 * frames (consecutive numbers, checked) until it holds the newest one
 * /api/status counted when asked, within 10 s. 1 if it did. Behaviour,
 * not a rate: a slow machine only makes it take longer. */
int ss_stream_reaches_newest(ws_client_t *w, int port);
/* Kills every child still running (teardown). */
void ss_kill_children(void);
/* A store of synth bodies (subjects x 12 poses, 1500 vertices), ingested
 * and indexed, at dir/store (*store, malloc'd); have[id] = 1 for each id
 * `mimic list` gives (have holds max_id + 1). The number of templates, or
 * -1 after printing why. */
int ss_make_store(const char *dir, int subjects, char **store, int *have, int max_id);

/* The serve tests' shared fixture: a temp folder (*dir) named after tag,
 * a store of subjects x 12 poses in it (*store, have as ss_make_store), and
 * the service svc on the demo motion at 60 Hz without faults. SIGPIPE is
 * ignored and rand() seeded, so a run is repeatable. 0, or -1 after
 * printing why. ss_fixture_close stops the service and every child, and
 * removes the folder. */
int ss_fixture_open(const char *tag, int subjects, char **dir, char **store, int *have, ss_svc_t *svc);
void ss_fixture_close(char **dir, char **store, ss_svc_t *svc);

#endif
