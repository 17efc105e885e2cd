/* The network side of mimic serve on libwebsockets (Debian
 * libwebsockets-dev 4.1.6): the context, its one service thread, and the
 * protocol callback that hands HTTP to http.c and the stream to ws.c.
 *
 * Threads, and why (issue 12):
 *  - one lws service thread, started here and stopped in close. It alone
 *    reads and writes every socket: lws is event-driven, so a connection
 *    costs a few KiB and no thread, and a slow or silent client costs
 *    nothing but its socket (civetweb held a thread per connection, and
 *    300 slowloris sockets took the service down). lws reads a WebSocket
 *    frame in pieces as it arrives (civetweb buffered whole frames: 2.5 GB
 *    for 40 hostile clients), which lets ws.c cap client messages.
 *  - the vest loop's thread (loop.c) publishes frames into the clients'
 *    queues and wakes the service thread with lws_cancel_service; on
 *    LWS_CALLBACK_EVENT_WAIT_CANCELLED the service thread asks for
 *    writable callbacks (ws.c).
 *  - a pool of two worker threads (workers.c) runs the handlers that take
 *    milliseconds (query, transfer, the avatar's JSON), so that they never
 *    hold the stream up; a finished one wakes the service thread the same
 *    way and its reply goes out from there (http.c).
 * All threads are serve's own, with default attributes: nothing needs big
 * stacks from the host program any more.
 *
 * lws's logging is global to the library in a process: serve turns it off
 * (mimic reports its own errors, and a library must not print); a host
 * that wants lws's log can set it after mim_serve_open. lws also ignores
 * SIGPIPE for the process when a context is created (Debian's build). */
#include "internal.h"

#include <arpa/inet.h>
#include <errno.h>
#include <libwebsockets.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define HEADERS_S 10 /* a connection's request headers must be whole within this */
#define IDLE_S 10    /* a request body may pause this long (lws's timeout_secs) */
#define WORKERS 2u

static int callback(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in, size_t len)
{
    struct lws_context *ctx = wsi ? lws_get_context(wsi) : NULL;
    mim_serve_t *sv = ctx ? lws_context_user(ctx) : NULL;
    if (!sv)
        return 0;
    switch (reason) {
    case LWS_CALLBACK_EVENT_WAIT_CANCELLED: /* a worker or the vest loop woke us */
        for (mim__job_t *j = mim__workers_done(sv->workers), *next; j; j = next) {
            next = j->next;
            j->next = NULL;
            mim__http_job_done(sv, j);
        }
        mim__ws_service(sv->ws);
        return 0;
    case LWS_CALLBACK_SERVER_NEW_CLIENT_INSTANTIATED: {
        /* a frame's last bytes must not wait for the client's ACK (Nagle) */
        int fd = lws_get_socket_fd(wsi), one = 1;
        if (fd >= 0)
            setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        return 0;
    }
    case LWS_CALLBACK_HTTP_CONFIRM_UPGRADE: {
        char why[256];
        int status = 400;
        if (!in || strcmp(in, "websocket")) /* h2c and the like: the service speaks HTTP/1.1 */
            snprintf(why, sizeof why, "only WebSocket upgrades are taken (at /ws)");
        else
            status = mim__ws_confirm(sv->ws, wsi, why, sizeof why);
        if (!status)
            return 0;
        return mim__http_answer_now(sv, wsi, status, why) ? -1 : 1;
    }
    case LWS_CALLBACK_HTTP:
    case LWS_CALLBACK_HTTP_BODY:
    case LWS_CALLBACK_HTTP_BODY_COMPLETION:
    case LWS_CALLBACK_HTTP_WRITEABLE:
    case LWS_CALLBACK_TIMER:
    case LWS_CALLBACK_CLOSED_HTTP:
        return mim__http_callback(sv, wsi, (int)reason, user, in, len);
    case LWS_CALLBACK_ESTABLISHED:
    case LWS_CALLBACK_RECEIVE:
    case LWS_CALLBACK_SERVER_WRITEABLE:
    case LWS_CALLBACK_CLOSED:
        return mim__ws_callback(sv->ws, wsi, (int)reason, user, in, len);
    default:
        return 0;
    }
}

static const struct lws_protocols protocols[] = {
    /* HTTP and the stream on one protocol: a client that names none gets
     * protocols[0]. Client messages arrive in pieces of at most
     * rx_buffer_size; a frame goes out in one send() (tx_packet_size). */
    {"mimic", callback, sizeof(mim__conn_t), MIM__WS_MESSAGE_MAX, 0, NULL, (size_t)1 << 20},
    {NULL, NULL, 0, 0, 0, NULL, 0},
};

static void *service(void *arg)
{
    mim_serve_t *sv = arg;
    while (!atomic_load(&sv->stop))
        if (lws_service(sv->ctx, 0) < 0)
            break;
    return NULL;
}

/* HOST:PORT (HOST may be [v6], empty, * or 0.0.0.0 for every interface, a
 * name or a number) into a numeric host for lws (empty: all) and a port.
 * 0, or -1 with why. */
static int parse_listen(const char *listen, char *host, size_t host_size, int *port, int *v6, char *why,
                        size_t why_size)
{
    const char *colon = strrchr(listen, ':');
    char *end = NULL;
    long p = colon ? strtol(colon + 1, &end, 10) : -1;
    if (!colon || !colon[1] || *end || p < 0 || p > 65535) {
        snprintf(why, why_size, "not HOST:PORT");
        return -1;
    }
    *port = (int)p;
    size_t hl = (size_t)(colon - listen);
    const char *h = listen;
    if (hl >= 2 && h[0] == '[' && h[hl - 1] == ']')
        h++, hl -= 2;
    char name[256];
    if (hl >= sizeof name) {
        snprintf(why, why_size, "host name too long");
        return -1;
    }
    memcpy(name, h, hl), name[hl] = 0;
    *v6 = 0;
    host[0] = 0;
    if (!hl || !strcmp(name, "*") || !strcmp(name, "0.0.0.0"))
        return 0;
    struct addrinfo hints = {.ai_socktype = SOCK_STREAM, .ai_flags = AI_PASSIVE}, *ai = NULL;
    int g = getaddrinfo(name, NULL, &hints, &ai);
    if (g) {
        snprintf(why, why_size, "%s", gai_strerror(g));
        return -1;
    }
    struct addrinfo *pick = ai;
    for (struct addrinfo *a = ai; a; a = a->ai_next)
        if (a->ai_family == AF_INET) { /* v4 first: "localhost" means 127.0.0.1 */
            pick = a;
            break;
        }
    *v6 = pick->ai_family == AF_INET6;
    int r = getnameinfo(pick->ai_addr, pick->ai_addrlen, host, (socklen_t)host_size, NULL, 0, NI_NUMERICHOST);
    freeaddrinfo(ai);
    if (r) {
        snprintf(why, why_size, "%s", gai_strerror(r));
        return -1;
    }
    if (*v6 && !strcmp(host, "::"))
        host[0] = 0;
    return 0;
}

/* Why binding host:port fails, for the one-line error (lws does not say). */
static void bind_error(const char *host, int port, int v6, char *why, size_t why_size)
{
    struct sockaddr_storage ss = {0};
    socklen_t sl;
    if (v6) {
        struct sockaddr_in6 *a = (struct sockaddr_in6 *)&ss;
        a->sin6_family = AF_INET6, a->sin6_port = htons((uint16_t)port);
        inet_pton(AF_INET6, host[0] ? host : "::", &a->sin6_addr);
        sl = sizeof *a;
    } else {
        struct sockaddr_in *a = (struct sockaddr_in *)&ss;
        a->sin_family = AF_INET, a->sin_port = htons((uint16_t)port);
        inet_pton(AF_INET, host[0] ? host : "0.0.0.0", &a->sin_addr);
        sl = sizeof *a;
    }
    int s = socket(v6 ? AF_INET6 : AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0), one = 1;
    snprintf(why, why_size, "libwebsockets could not listen");
    if (s < 0)
        return;
    setsockopt(s, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(s, (struct sockaddr *)&ss, sl))
        snprintf(why, why_size, "%s", strerror(errno));
    close(s);
}

/* The warm-up thread (internal.h says why): every class of the index
 * checked and its k-NN index made, while queries may already run (they
 * ready what they need first themselves). */
static void *warm_index(void *arg)
{
    mim_serve_t *sv = arg;
    mim_error_t e = {0};
    int rc = mim_index_verify(mim_query_index(sv->q), &e);
    if (rc)
        snprintf(sv->index_error, sizeof sv->index_error, "%s", mim_error_text(&e));
    atomic_store(&sv->index_ready, rc ? -1 : 1);
    return NULL;
}

int mim_serve_open(mim_serve_t **out, mim_session_t *s, const mim_serve_options_t *opt, mim_error_t *err)
{
    *out = NULL;
    mim_serve_options_t o = opt ? *opt : (mim_serve_options_t){0};
    const char *listen = o.listen ? o.listen : MIM_SERVE_DEFAULT_LISTEN;
    char host[256], why[256] = "";
    int port = 0, v6 = 0;
    if (parse_listen(listen, host, sizeof host, &port, &v6, why, sizeof why))
        return mim_error_set(err, MIM_EINVAL, "cannot listen on %s: %s", listen, why);
    mim_serve_t *sv = calloc(1, sizeof *sv);
    if (!sv)
        return mim_error_set(err, MIM_ENOMEM, "out of memory");
    mim__metrics_init(&sv->m);
    pthread_mutex_init(&sv->sessions_lock, NULL);
    mim__cpu_init(&sv->cpu);
    const unsigned slots = o.compute_slots ? o.compute_slots : sv->cpu.cores;
    mim__gate_init(&sv->gate, slots);
    mim__fair_init(&sv->fair, sv->cpu.cores, slots, o.compute_cores, mim__cpu_sample, &sv->cpu);
    sv->t_start = mim_now();
    sv->max_body = o.max_body ? o.max_body : MIM_SERVE_DEFAULT_MAX_BODY;
    sv->opt = o;
    sv->opt.vest = NULL; /* each session's own */
    sv->s = s;
    sv->store = mim_session_store(s);
    sv->map = mim_session_map(s);
    sv->q = mim_session_query(s);
    int rc = 0;
    if (o.drive < MIM_DRIVE_AUTO || o.drive > MIM_DRIVE_SKELETON)
        rc = mim_error_set(err, MIM_EINVAL, "serve: unknown drive %d", o.drive);
    else if (o.blend > MIM_XFER_BLEND_MAX)
        rc = mim_error_set(err, MIM_EINVAL, "serve: --blend %u: at most %d templates", o.blend, MIM_XFER_BLEND_MAX);
    else if (o.vest && !mim_session_has_avatar(s))
        rc = mim_error_set(err, MIM_EINVAL, "%s: serve: a vest needs an avatar (the session has none)", sv->store);
    const unsigned max_clients = o.max_clients ? o.max_clients : MIM_SERVE_DEFAULT_MAX_CLIENTS;
    if (!rc && sv->q) {
        int e = pthread_create(&sv->warm, NULL, warm_index, sv);
        if (e) /* not fatal: queries ready what they need themselves */
            snprintf(sv->index_error, sizeof sv->index_error, "not readied ahead: %s", strerror(e));
        sv->warm_started = !e;
    }
    if (!rc)
        rc = mim__ws_open(&sv->ws, sv, max_clients, err);
    if (!rc)
        rc = mim__workers_open(&sv->workers, sv, o.threads ? o.threads : WORKERS, err);
    if (!rc && mim_session_has_avatar(s))
        rc = mim__sessions_open_default(sv, &o, err);
    if (rc) {
        mim_serve_close(&sv);
        return rc;
    }

    lws_set_log_level(0, NULL); /* see the top of the file */
    struct lws_context_creation_info ci;
    memset(&ci, 0, sizeof ci);
    ci.options = LWS_SERVER_OPTION_EXPLICIT_VHOSTS | LWS_SERVER_OPTION_NO_LWS_SYSTEM_STATES;
    ci.user = sv;
    ci.timeout_secs = IDLE_S;
    ci.timeout_secs_ah_idle = HEADERS_S;
    /* lws reads 32 KiB at a time (bodies, and the rest of a refused frame) */
    ci.pt_serv_buf_size = 32768;
    /* every fd the process may open can be a connection, each with its
     * header buffer while it sends headers: no slowloris can make others
     * wait for one (lws's default; said here because it matters) */
    ci.max_http_header_pool = 0;
    /* room past the headers' limit, so that a request over it gets 431
     * (http.c) rather than a closed connection */
    ci.max_http_header_data = MIM_SERVE_HEADER_BUFFER;
    ci.fd_limit_per_thread = 0;
    sv->ctx = lws_create_context(&ci);
    if (!sv->ctx) {
        rc = mim_error_set(err, MIM_EIO, "cannot listen on %s: libwebsockets: cannot create its context", listen);
        mim_serve_close(&sv);
        return rc;
    }
    struct lws_context_creation_info vi;
    memset(&vi, 0, sizeof vi);
    vi.vhost_name = "mimic";
    vi.port = port; /* 0: the kernel picks a free one (mim_serve_port) */
    vi.iface = host[0] ? host : NULL;
    vi.protocols = protocols;
    vi.options = LWS_SERVER_OPTION_FAIL_UPON_UNABLE_TO_BIND | (v6 ? 0 : LWS_SERVER_OPTION_DISABLE_IPV6);
    vi.timeout_secs = IDLE_S;
    vi.timeout_secs_ah_idle = HEADERS_S;
    vi.keepalive_timeout = 5;
    sv->vhost = lws_create_vhost(sv->ctx, &vi);
    if (!sv->vhost) {
        bind_error(host, port, v6, why, sizeof why);
        rc = mim_error_set(err, MIM_EIO, "cannot listen on %s: %s", listen, why);
        mim_serve_close(&sv);
        return rc;
    }
    sv->port = lws_get_vhost_listen_port(sv->vhost);
    mim__ws_attach(sv->ws, sv->ctx);
    mim__workers_attach(sv->workers, sv->ctx);
    if ((rc = pthread_create(&sv->service, NULL, service, sv)) != 0) {
        rc = mim_error_set(err, -rc, "cannot start the service thread: %s", strerror(rc));
        mim_serve_close(&sv);
        return rc;
    }
    sv->service_started = 1;
    *out = sv;
    return 0;
}

int mim_serve_port(const mim_serve_t *s)
{
    return s ? s->port : 0;
}

const char *mim_serve_vest_state(mim_serve_t *s)
{
    mim__vs_t *vs = s ? mim__sessions_get(s, NULL) : NULL;
    if (!vs)
        return "none";
    pthread_mutex_lock(&vs->lock);
    const char *state = mim__loop_state(vs->loop);
    pthread_mutex_unlock(&vs->lock);
    mim__vs_release(vs);
    return state;
}

const mim_mesh_t *mim_serve_avatar_mesh(const mim_serve_t *s)
{
    /* the first session lives until close or its removal */
    mim__vs_t *vs = s ? mim__sessions_get((mim_serve_t *)s, NULL) : NULL;
    const mim_mesh_t *m = vs ? vs->out_mesh : NULL;
    mim__vs_release(vs);
    return m;
}

uint64_t mim_serve_frames(mim_serve_t *s)
{
    size_t n = 0;
    mim__vs_t **all = s ? mim__sessions_all(s, &n) : NULL;
    uint64_t frames = 0;
    for (size_t i = 0; i < n; i++)
        frames += mim__metrics_get(&all[i]->m, MIM__C_FRAMES);
    mim__sessions_release_all(all, n);
    return frames;
}

void mim_serve_close(mim_serve_t **ps)
{
    mim_serve_t *sv = ps ? *ps : NULL;
    if (!sv)
        return;
    if (sv->warm_started) /* it cannot be cut short: at 1 000 000 templates, a second or two */
        pthread_join(sv->warm, NULL);
    if (sv->service_started) { /* no callback runs after this but those of the destroy below */
        atomic_store(&sv->stop, 1);
        lws_cancel_service(sv->ctx);
        pthread_join(sv->service, NULL);
    }
    /* nobody may wake a context being destroyed */
    if (sv->ws)
        mim__ws_attach(sv->ws, NULL);
    if (sv->workers)
        mim__workers_attach(sv->workers, NULL);
    mim__sessions_stop_all(sv); /* their loops publish to the stream */
    if (sv->ctx)
        lws_context_destroy(sv->ctx); /* closes every connection: their jobs are orphaned, clients freed */
    sv->ctx = NULL;
    mim__workers_close(&sv->workers); /* waits for a running handler, frees what is left */
    mim__sessions_free_all(sv);
    mim__ws_close(&sv->ws);
    mim__gate_destroy(&sv->gate);
    mim__fair_destroy(&sv->fair);
    pthread_mutex_destroy(&sv->sessions_lock);
    mim__metrics_destroy(&sv->m);
    free(sv);
    *ps = NULL;
}
