/* The HTTP side of mimic serve: civetweb start and stop, one handler that
 * routes by path and method, the request body limit, and JSON replies.
 * civetweb (Debian libcivetweb-dev) gives HTTP/1.1 and WebSocket in one C
 * library with its own worker threads, so handlers are plain functions. */
#include "internal.h"
#include "viewer.h"

#include <civetweb.h>
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int mim__reply(struct mg_connection *c, int status, const char *type, const void *body, size_t len,
               const char *extra_headers)
{
    char clen[32];
    snprintf(clen, sizeof clen, "%zu", len);
    mg_response_header_start(c, status);
    mg_response_header_add(c, "Content-Type", type, -1);
    mg_response_header_add(c, "Content-Length", clen, -1);
    mg_response_header_add(c, "Cache-Control", "no-store", -1);
    if (extra_headers)
        mg_response_header_add_lines(c, extra_headers);
    mg_response_header_send(c);
    if (len)
        mg_write(c, body, len);
    return status;
}

int mim__reply_json(struct mg_connection *c, int status, json_t *j)
{
    char *txt = j ? json_dumps(j, JSON_COMPACT | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) : NULL;
    json_decref(j);
    if (!txt) {
        static const char oom[] = "{\"error\":\"out of memory for the reply\"}";
        return mim__reply(c, 500, "application/json", oom, sizeof oom - 1, NULL);
    }
    int rc = mim__reply(c, status, "application/json", txt, strlen(txt), NULL);
    free(txt);
    return rc;
}

int mim__reply_error(struct mg_connection *c, int status, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return mim__reply_json(c, status, json_pack("{s:s, s:i}", "error", msg, "status", status));
}

typedef int (*handler_fn)(mim_serve_t *, struct mg_connection *, const char *, size_t);
static const struct {
    const char *path, *method;
    mim__route_t route;
    handler_fn fn;
} routes[] = {
    {"/api/status", "GET", MIM__R_STATUS, mim__api_status},
    {"/api/avatar", "GET", MIM__R_AVATAR, mim__api_avatar},
    {"/api/query", "POST", MIM__R_QUERY, mim__api_query},
    {"/api/transfer", "POST", MIM__R_TRANSFER, mim__api_transfer},
    {"/metrics", "GET", MIM__R_METRICS, mim__api_metrics},
};

/* Reads the whole body into a NUL-terminated buffer, refusing more than
 * max bytes (a declared length is checked before reading anything). Returns
 * 0, or the HTTP status already sent. */
static int read_body(mim_serve_t *sv, struct mg_connection *c, char **out, size_t *len)
{
    const struct mg_request_info *ri = mg_get_request_info(c);
    *out = NULL, *len = 0;
    if (ri->content_length > (long long)sv->max_body)
        return mim__reply_error(c, 413, "request body: %lld bytes, the limit is %zu", ri->content_length,
                                sv->max_body);
    size_t cap = ri->content_length >= 0 ? (size_t)ri->content_length + 1 : 65536, n = 0;
    char *b = malloc(cap);
    if (!b)
        return mim__reply_error(c, 500, "out of memory for a %zu-byte request body", cap);
    for (;;) {
        if (n + 1 >= cap) {
            if (cap > sv->max_body + 1) {
                free(b);
                return mim__reply_error(c, 413, "request body: over the limit of %zu bytes", sv->max_body);
            }
            char *nb = realloc(b, 2 * cap);
            if (!nb) {
                free(b);
                return mim__reply_error(c, 500, "out of memory for the request body");
            }
            b = nb, cap *= 2;
        }
        int r = mg_read(c, b + n, cap - 1 - n);
        if (r < 0) {
            free(b);
            return mim__reply_error(c, 400, "request body: read error");
        }
        if (r == 0)
            break;
        n += (size_t)r;
    }
    if (n > sv->max_body) {
        free(b);
        return mim__reply_error(c, 413, "request body: over the limit of %zu bytes", sv->max_body);
    }
    b[n] = 0;
    *out = b, *len = n;
    return 0;
}

static int handle(struct mg_connection *c, void *cbdata)
{
    mim_serve_t *sv = cbdata;
    double t0 = mim_now();
    const struct mg_request_info *ri = mg_get_request_info(c);
    const char *path = ri->local_uri ? ri->local_uri : "";
    mim__route_t route = MIM__R_OTHER;
    int status = 0;
    size_t i = 0, n = sizeof routes / sizeof routes[0];
    while (i < n && strcmp(routes[i].path, path))
        i++;
    if (i == n && (status = mim__viewer_serve(c, path)) != 0) { /* it answers GET and HEAD only */
        route = MIM__R_VIEWER;
    } else if (i == n) {
        status = mim__reply_error(c, 404, "%s: no such route (see schemas/ for the API)", path);
    } else if (route = routes[i].route, strcmp(ri->request_method, routes[i].method)) {
        char allow[64];
        snprintf(allow, sizeof allow, "Allow: %s\r\n", routes[i].method);
        char msg[256];
        int m = snprintf(msg, sizeof msg, "{\"error\":\"%s: use %s\",\"status\":405}", routes[i].path,
                         routes[i].method);
        status = mim__reply(c, 405, "application/json", msg, (size_t)m, allow);
    } else if (!strcmp(routes[i].method, "POST")) {
        char *body;
        size_t len;
        if (!(status = read_body(sv, c, &body, &len)))
            status = routes[i].fn(sv, c, body, len);
        free(body);
    } else {
        status = routes[i].fn(sv, c, NULL, 0);
    }
    mim__metrics_request(&sv->m, route, status, mim_now() - t0);
    return status; /* civetweb: a status >= 1 means handled */
}

static int quiet_log(const struct mg_connection *c, const char *message)
{
    (void)c, (void)message;
    return 1; /* mimic reports its own errors; civetweb's go nowhere */
}

int mim_serve_open(mim_serve_t **out, mim_session_t *s, const mim_serve_options_t *opt, mim_error_t *err)
{
    *out = NULL;
    mim_serve_options_t o = opt ? *opt : (mim_serve_options_t){0};
    mim_serve_t *sv = calloc(1, sizeof *sv);
    if (!sv)
        return mim_error_set(err, MIM_ENOMEM, "out of memory");
    mim__metrics_init(&sv->m);
    sv->t_start = mim_now();
    sv->max_body = o.max_body ? o.max_body : MIM_SERVE_DEFAULT_MAX_BODY;
    sv->s = s;
    sv->store = mim_session_store(s);
    sv->mesh = mim_session_mesh(s);
    sv->map = mim_session_map(s);
    sv->q = mim_session_query(s);
    int rc = mim_session_has_avatar(s) ? 0 : mim_error_set(err, MIM_EINVAL, "%s: serve: the session has no avatar",
                                                             sv->store);
    const unsigned max_clients = o.max_clients ? o.max_clients : MIM_SERVE_DEFAULT_MAX_CLIENTS;
    if (!rc)
        rc = mim__ws_open(&sv->ws, sv, max_clients, err);
    if (!rc && o.vest)
        rc = mim__loop_open(&sv->loop, sv, &o, err);
    if (rc) {
        mim_serve_close(&sv);
        return rc;
    }

    /* civetweb gives every WebSocket connection a worker thread for its
     * life: room for max_clients of them plus the HTTP workers. A write
     * to a client that stopped reading gives up after request_timeout_ms;
     * websocket_timeout_ms is how often an idle read loop looks at the
     * stop flag, so shutdown waits at most that long. */
    char threads[16];
    snprintf(threads, sizeof threads, "%u", (o.threads ? o.threads : 4) + max_clients);
    const char *options[] = {"listening_ports", o.listen ? o.listen : MIM_SERVE_DEFAULT_LISTEN,
                             "num_threads", threads,
                             "request_timeout_ms", "10000",
                             "websocket_timeout_ms", "500",
                             "tcp_nodelay", "1", /* a frame's tail must not wait for an ACK (Nagle) */
                             NULL};
    /* civetweb starts its workers with 100 KiB stacks in Debian's build (a
     * compile-time setting, no run-time option), too small once glibc has
     * carved this process's static TLS out of them. Raising them is the
     * host program's business (mim_serve.h; mimic's is cli/stack_size.c):
     * a library must not change thread attributes for the whole process. */
    struct mg_callbacks cb = {.log_message = quiet_log};
    struct mg_init_data init = {.callbacks = &cb, .user_data = sv, .configuration_options = options};
    char why[256] = "";
    unsigned code = 0;
    struct mg_error_data ed = {.code = &code, .text = why, .text_buffer_size = sizeof why};
    mg_init_library(0);
    sv->ctx = mg_start2(&init, &ed);
    if (!sv->ctx) {
        rc = mim_error_set(err, MIM_EIO, "cannot listen on %s: %s", options[1], why[0] ? why : "civetweb failed");
        mim_serve_close(&sv);
        mg_exit_library();
        return rc;
    }
    mg_set_request_handler(sv->ctx, "/", handle, sv);
    mim__ws_attach(sv->ws, sv->ctx);
    struct mg_server_port ports[4];
    int np = mg_get_server_ports(sv->ctx, 4, ports);
    sv->port = np > 0 ? ports[0].port : 0;
    *out = sv;
    return 0;
}

int mim_serve_port(const mim_serve_t *s)
{
    return s ? s->port : 0;
}

const char *mim_serve_vest_state(mim_serve_t *s)
{
    return mim__loop_state(s ? s->loop : NULL);
}

const mim_mesh_t *mim_serve_avatar_mesh(const mim_serve_t *s)
{
    return s ? s->mesh : NULL;
}

uint64_t mim_serve_frames(mim_serve_t *s)
{
    return s ? mim__metrics_get(&s->m, MIM__C_FRAMES) : 0;
}

void mim_serve_close(mim_serve_t **ps)
{
    mim_serve_t *sv = ps ? *ps : NULL;
    if (!sv)
        return;
    if (sv->ctx) {
        mg_stop(sv->ctx); /* joins the workers: no handler runs after this */
        mg_exit_library();
    }
    mim__loop_close(&sv->loop); /* after the workers: /api/status reads the loop */
    mim__ws_close(&sv->ws);     /* after the loop, which publishes to it */
    mim__metrics_destroy(&sv->m);
    free(sv);
    *ps = NULL;
}
