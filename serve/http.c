/* HTTP/1.1 transactions of mimic serve, on the lws service thread (see
 * server.c for the threads): routing by path and method, the request body
 * (Content-Length or chunked, read as it arrives, never more than the
 * limit), handlers run here (status, metrics, the viewer's files) or on
 * the worker pool (query, transfer, avatar), and the reply written in
 * 64 KiB pieces as the socket takes them.
 *
 * What a hostile client meets (issue 12, defect 2):
 *  - request headers must be whole within 10 s of the connection (lws's
 *    timeout_secs_ah_idle; a slowloris socket then closes); headers
 *    over MIM_SERVE_MAX_HEADER_BYTES get 431 and the connection closes,
 *    and a header block past lws's buffer (MIM_SERVE_HEADER_BUFFER) is
 *    closed by lws without an answer;
 *  - a body must not pause for 10 s (lws's timeout_secs, reset by every
 *    piece) and must be whole 30 s after the request began (REQUEST_S,
 *    checked here: a trickle of one byte a second ends too);
 *  - a body over --max-body is refused with 413 as soon as it is known to
 *    be (a declared length at once, a chunked one when it passes the
 *    limit), without reading it;
 *  - an answer to a request whose body was not read (413, 404, 405, a GET
 *    with a body...) closes the connection: "Connection: close", then the
 *    write side is shut and what the client still sends is read and
 *    dropped for at most LINGER_S (so that the answer is not lost to a
 *    reset), then the socket closes;
 *  - request smuggling: Content-Length with Transfer-Encoding, a
 *    Transfer-Encoding other than "chunked", or a Content-Length that is
 *    not a plain number is a 400 that closes the connection; a chunked
 *    request's connection closes after its answer;
 *  - a path with a NUL in it (%00) is a 400; path bytes that are not UTF-8
 *    show as '?' in the one-line JSON error (which so always encodes);
 *  - request bodies held at once are bounded (BODY_BUDGET), and so is the
 *    worker queue: past them a request gets 503 at once;
 *  - a reply the client does not read for SEND_IDLE_S closes.
 * One thing lws (4.1) decides for us: a client that half-closes its
 * connection after a request body (shutdown(SHUT_WR), which browsers and
 * curl do not do) is taken for gone, and its answer is dropped. An answer
 * written while its own request is being read goes out at once (answer()),
 * so refusals reach such a client; a GET is answered after a half-close. */
#include "internal.h"

#include <libwebsockets.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>

#define REQUEST_S 30.0   /* from a request's start to its whole body */
#define LINGER_S 2       /* reading and dropping after an answer that closes */
#define SEND_IDLE_S 30   /* a reply that the client does not take */
#define PIECE 65536u     /* bytes of a reply per write */
#define HEAD_ROOM (LWS_PRE + 1024u) /* LWS_PRE, then the status line and headers */
#define BODY_BUDGET ((size_t)64 << 20) /* request bodies held at once, all connections (or 2 x --max-body) */

enum { M_GET, M_HEAD, M_POST, M_DELETE, M_OTHER };
enum { T_NEW, T_BODY, T_WORK, T_SEND, T_SENT, T_LINGER };
enum { CK_SIZE, CK_EXT, CK_SIZE_LF, CK_DATA, CK_DATA_CR, CK_DATA_LF, CK_LINE, CK_SKIP, CK_END_LF, CK_DONE };

typedef struct mim__http_tx {
    int state;
    double t0;
    mim__route_t route;
    const struct route *r;
    int method;
    int expect_body;   /* the request declares a body */
    long long declared; /* its Content-Length; -1 when chunked */
    int chunked, ck;   /* chunk decoder state (CK_*) */
    unsigned long long ck_left;
    int ck_digits;
    char *body;
    size_t len, cap;
    int body_done;
    int close;         /* close the connection after the answer */
    mim__request_t rq;
    char path[256];    /* printable, for error messages */
    mim__job_t *job;
    mim__reply_t rp;
    int status;
    size_t sent;
    int head_sent;
    double linger_until;
    unsigned char *buf; /* LWS_PRE, then the headers and a piece of the body */
    size_t buf_size;
} mim__http_tx_t;

static const struct route {
    const char *path, *method;
    int m;
    mim__route_t route;
    mim__handler_t fn;
    int worker; /* milliseconds of work: on the pool (adding a session factors an avatar; removing one joins
                   its loop) */
    int named;  /* the path is a prefix, and the rest of it a name (rq.name) */
} routes[] = {
    {"/api/status", "GET", M_GET, MIM__R_STATUS, mim__api_status, 0, 0},
    {"/api/avatar", "GET", M_GET, MIM__R_AVATAR, mim__api_avatar, 1, 0},
    {"/api/avatar.glb", "GET", M_GET, MIM__R_AVATAR, mim__api_avatar_glb, 1, 0},
    {"/api/query", "POST", M_POST, MIM__R_QUERY, mim__api_query, 1, 0},
    {"/api/transfer", "POST", M_POST, MIM__R_TRANSFER, mim__api_transfer, 1, 0},
    {"/metrics", "GET", M_GET, MIM__R_METRICS, mim__api_metrics, 0, 0},
    {"/api/sessions", "GET", M_GET, MIM__R_SESSIONS, mim__api_sessions, 0, 0},
    {"/api/sessions", "POST", M_POST, MIM__R_SESSIONS, mim__api_session_add, 1, 0},
    {"/api/sessions/", "GET", M_GET, MIM__R_SESSIONS, mim__api_session, 0, 1},
    {"/api/sessions/", "DELETE", M_DELETE, MIM__R_SESSIONS, mim__api_session_remove, 1, 1},
};

/* Whether request path in is route r's. */
static int route_matches(const struct route *r, const char *in)
{
    size_t n = strlen(r->path);
    if (!r->named)
        return !strcmp(r->path, in);
    return !strncmp(r->path, in, n) && in[n] && !strchr(in + n, '/');
}

/* ---- replies ---- */
/* The length of the valid UTF-8 sequence at s (n bytes left), 0 if none:
 * no overlong forms, no surrogates, nothing above U+10FFFF (as jansson). */
static size_t utf8_seq(const unsigned char *s, size_t n)
{
    unsigned c = s[0];
    size_t k = c >= 0xF0 && c <= 0xF4 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 && c <= 0xDF ? 2 : 0;
    if (c >= 0xF5 || !k || k > n)
        return 0;
    for (size_t i = 1; i < k; i++)
        if ((s[i] & 0xC0) != 0x80)
            return 0;
    if ((c == 0xE0 && s[1] < 0xA0) || (c == 0xED && s[1] > 0x9F) || (c == 0xF0 && s[1] < 0x90) ||
        (c == 0xF4 && s[1] > 0x8F))
        return 0;
    return k;
}

void mim__printable(const char *s, size_t len, char *out, size_t n)
{
    size_t o = 0;
    const unsigned char *u = (const unsigned char *)s;
    for (size_t i = 0; i < len && o + 1 < n;) {
        if (u[i] >= 0x20 && u[i] < 0x7f) {
            out[o++] = (char)u[i++];
            continue;
        }
        size_t k = u[i] >= 0x80 ? utf8_seq(u + i, len - i) : 0;
        if (k && o + k < n) {
            memcpy(out + o, u + i, k);
            o += k, i += k;
        } else {
            out[o++] = '?';
            i += k ? k : 1;
        }
    }
    if (n)
        out[o] = 0;
}

static int reply_oom(mim__reply_t *r)
{
    static const char oom[] = "{\"error\":\"out of memory for the reply\",\"status\":500}";
    mim__reply_free(r);
    r->status = 500;
    r->type = "application/json";
    r->fixed = (const unsigned char *)oom;
    r->len = sizeof oom - 1;
    return 500;
}

int mim__reply_take(mim__reply_t *r, int status, const char *type, void *body, size_t len)
{
    mim__reply_free(r);
    if (!body && len)
        return reply_oom(r);
    r->status = status;
    r->type = type;
    r->body = body;
    r->len = len;
    return status;
}

int mim__reply_json(mim__reply_t *r, int status, json_t *j)
{
    char *txt = j ? json_dumps(j, JSON_COMPACT | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) : NULL;
    json_decref(j);
    if (!txt)
        return reply_oom(r);
    return mim__reply_take(r, status, "application/json", txt, strlen(txt));
}

int mim__reply_error(mim__reply_t *r, int status, const char *fmt, ...)
{
    char msg[768], clean[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    mim__printable(msg, strlen(msg), clean, sizeof clean); /* one line of UTF-8, whatever the request held */
    return mim__reply_json(r, status, json_pack("{s:s, s:i}", "error", clean, "status", status));
}

void mim__reply_free(mim__reply_t *r)
{
    free(r->body);
    memset(r, 0, sizeof *r);
}

static int add_header(struct lws *wsi, const char *name, const char *value, size_t vlen, unsigned char **p,
                      unsigned char *end);

/* An answer written at once (the refusal of a WebSocket upgrade: lws
 * closes the connection after it). 0, or -1 if it could not be written. */
int mim__http_answer_now(mim_serve_t *sv, struct lws *wsi, int status, const char *why)
{
    mim__reply_t rp = {0};
    status = mim__reply_error(&rp, status, "%s", why);
    unsigned char buf[LWS_PRE + 2048], *start = buf + LWS_PRE, *p = start, *end = buf + sizeof buf;
    char clen[32];
    snprintf(clen, sizeof clen, "%zu", rp.len);
    const unsigned char *data = rp.body ? rp.body : rp.fixed;
    /* the status line by hand: lws has not read the request's version on
     * this path and would answer HTTP/1.0 to a client that asked 1.1 */
    int sl = snprintf((char *)p, (size_t)(end - p), "HTTP/1.1 %d %s\r\n", status,
                      status == 400 ? "Bad Request" : status == 404 ? "Not Found" :
                      status == 503 ? "Service Unavailable" : "Error");
    p += sl > 0 && sl < end - p ? sl : 0;
    int rc = sl <= 0 || sl >= end - p ||
             add_header(wsi, "Content-Type:", rp.type, strlen(rp.type), &p, end) ||
             add_header(wsi, "Content-Length:", clen, strlen(clen), &p, end) ||
             add_header(wsi, "Cache-Control:", "no-store", 8, &p, end) ||
             add_header(wsi, "Connection:", "close", 5, &p, end) || lws_finalize_http_header(wsi, &p, end) ||
             (size_t)(end - p) < rp.len
             ? -1
             : 0;
    if (!rc) {
        memcpy(p, data, rp.len);
        p += rp.len;
        rc = lws_write(wsi, start, (size_t)(p - start), LWS_WRITE_HTTP_FINAL) < 0 ? -1 : 0;
    }
    mim__reply_free(&rp);
    mim__metrics_request(&sv->m, MIM__R_OTHER, status, 0.0);
    return rc;
}

/* ---- the request ---- */
/* The value of the URL argument name (as lws decoded it): 1 and the value
 * in out, -1 when it is longer than out holds, 0 when absent. */
int mim__url_arg(struct lws *wsi, const char *name, char *out, size_t n)
{
    char frag[4200]; /* lws keeps at most 4096 bytes of headers */
    size_t nl = strlen(name);
    for (int i = 0; lws_hdr_copy_fragment(wsi, frag, (int)sizeof frag, WSI_TOKEN_HTTP_URI_ARGS, i) >= 0; i++) {
        if (strncmp(frag, name, nl) || (frag[nl] != '=' && frag[nl] != 0))
            continue;
        const char *v = frag[nl] ? frag + nl + 1 : frag + nl;
        if (strlen(v) >= n)
            return -1;
        memcpy(out, v, strlen(v) + 1);
        return 1;
    }
    return 0;
}

static int method_of(struct lws *wsi)
{
    if (lws_hdr_total_length(wsi, WSI_TOKEN_GET_URI) > 0)
        return M_GET;
    if (lws_hdr_total_length(wsi, WSI_TOKEN_POST_URI) > 0)
        return M_POST;
    if (lws_hdr_total_length(wsi, WSI_TOKEN_HEAD_URI) > 0)
        return M_HEAD;
    if (lws_hdr_total_length(wsi, WSI_TOKEN_DELETE_URI) > 0)
        return M_DELETE;
    return M_OTHER;
}

static void body_free(mim_serve_t *sv, mim__http_tx_t *tx)
{
    sv->body_bytes -= tx->cap;
    free(tx->body);
    tx->body = NULL, tx->len = tx->cap = 0;
}

static void tx_free(mim_serve_t *sv, mim__http_tx_t *tx)
{
    if (!tx)
        return;
    if (tx->job) { /* the connection goes first: the job is dropped when it comes back */
        if (mim__workers_cancel(sv->workers, tx->job))
            mim__job_free(tx->job);
        else
            tx->job->orphaned = 1;
    }
    body_free(sv, tx);
    mim__reply_free(&tx->rp);
    free(tx->buf);
    free(tx);
}

/* ---- sending ---- */
/* The reply in tx->rp goes out from the next writable callbacks. */
static int send_reply(struct lws *wsi, mim__http_tx_t *tx, int status)
{
    tx->status = status;
    tx->state = T_SEND;
    tx->sent = 0, tx->head_sent = 0;
    lws_set_timeout(wsi, PENDING_TIMEOUT_USER_OK, SEND_IDLE_S);
    lws_callback_on_writable(wsi);
    return 0;
}

static int on_writable(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx);

/* The reply made while serving this connection's own callback: its first
 * piece goes out now (a round of poll() sooner, and before lws reads a
 * half-close that would end the connection), the rest when writable. */
static int answer(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx, int status)
{
    send_reply(wsi, tx, status);
    return on_writable(sv, wsi, tx);
}

/* An answer after which the connection closes (its body, if any, unread).
 * It is written at once, not at the next writable callback: lws (4.1)
 * reads on while a body is coming, and a client that half-closes after
 * sending it would have the connection closed before the answer went out. */
static int refuse(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx, int status, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static int refuse(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx, int status, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    tx->close = 1;
    return answer(sv, wsi, tx, mim__reply_error(&tx->rp, status, "%s", msg));
}

static int add_header(struct lws *wsi, const char *name, const char *value, size_t vlen, unsigned char **p,
                      unsigned char *end)
{
    return lws_add_http_header_by_name(wsi, (const unsigned char *)name, (const unsigned char *)value, (int)vlen, p,
                                       end);
}

/* The status line and headers into tx->buf; their end, or NULL. Names
 * keep their usual capitals (HTTP/1.1 ignores case, people read them). */
static unsigned char *put_headers(struct lws *wsi, mim__http_tx_t *tx)
{
    unsigned char *start = tx->buf + LWS_PRE, *p = start, *end = tx->buf + HEAD_ROOM - 1;
    const mim__reply_t *rp = &tx->rp;
    char clen[32];
    snprintf(clen, sizeof clen, "%zu", rp->len);
    const char *cache = rp->cache ? rp->cache : "no-store";
    if (lws_add_http_header_status(wsi, (unsigned)rp->status, &p, end))
        return NULL;
    /* libwebsockets has no reason phrase for some statuses ("HTTP/1.1 201
     * "): RFC 9112 4 allows an empty one, but people and some clients read it */
    static const struct { int status; const char *line; } phrases[] = {
        {201, "HTTP/1.1 201 Created\r\n"}, {431, "HTTP/1.1 431 Request Header Fields Too Large\r\n"}};
    char bare[32];
    int nb = snprintf(bare, sizeof bare, "HTTP/1.1 %d \r\n", rp->status);
    for (size_t k = 0; k < sizeof phrases / sizeof *phrases; k++) {
        size_t ll = strlen(phrases[k].line);
        if (rp->status == phrases[k].status && p - start == nb && !memcmp(start, bare, (size_t)nb) &&
            end - start > (ptrdiff_t)ll) {
            memcpy(start, phrases[k].line, ll);
            p = start + ll;
        }
    }
    if (add_header(wsi, "Content-Type:", rp->type, strlen(rp->type), &p, end) ||
        add_header(wsi, "Content-Length:", clen, strlen(clen), &p, end) ||
        add_header(wsi, "Cache-Control:", cache, strlen(cache), &p, end) ||
        (tx->close && add_header(wsi, "Connection:", "close", 5, &p, end)))
        return NULL;
    /* the handler's own lines, "Name: value\r\n" each */
    for (const char *h = rp->headers; *h;) {
        const char *eol = strstr(h, "\r\n"), *colon = strchr(h, ':');
        if (!eol || !colon || colon > eol)
            break;
        char name[64];
        size_t nl = (size_t)(colon - h) + 1;
        if (nl >= sizeof name)
            break;
        memcpy(name, h, nl), name[nl] = 0;
        const char *v = colon + 1 + strspn(colon + 1, " ");
        if (add_header(wsi, name, v, (size_t)(eol - v), &p, end))
            return NULL;
        h = eol + 2;
    }
    if (lws_finalize_http_header(wsi, &p, end))
        return NULL;
    return p;
}

static int on_writable(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx)
{
    if (tx->state == T_SENT) {
        /* all of it went out (lws calls back only once its own buffer is
         * empty): the transaction is over */
        mim__metrics_request(&sv->m, tx->route, tx->status, mim_now() - tx->t0);
        lws_set_timeout(wsi, NO_PENDING_TIMEOUT, 0);
        if (tx->close) {
            if (tx->expect_body && !tx->body_done) {
                /* the client may still be sending: a close now could reset
                 * the connection before the answer is read */
                int fd = lws_get_socket_fd(wsi);
                if (fd >= 0)
                    shutdown(fd, SHUT_WR);
                tx->state = T_LINGER;
                tx->linger_until = mim_now() + LINGER_S;
                /* a timer, not an lws timeout: lws renews those at every
                 * piece of body that still comes */
                lws_set_timer_usecs(wsi, (lws_usec_t)LINGER_S * LWS_USEC_PER_SEC);
                return 0;
            }
            return -1;
        }
        mim__conn_t *conn = lws_wsi_user(wsi);
        tx_free(sv, tx);
        if (conn)
            conn->tx = NULL;
        return lws_http_transaction_completed(wsi) ? -1 : 0;
    }
    if (tx->state != T_SEND)
        return 0;
    const mim__reply_t *rp = &tx->rp;
    const unsigned char *data = rp->body ? rp->body : rp->fixed;
    if (!tx->buf) {
        tx->buf_size = HEAD_ROOM + (rp->len < PIECE ? rp->len : PIECE);
        if (!(tx->buf = malloc(tx->buf_size)))
            return -1;
    }
    unsigned char *start = tx->buf + LWS_PRE, *p = start;
    if (!tx->head_sent) {
        if (!(p = put_headers(wsi, tx)))
            return -1;
        tx->head_sent = 1;
    }
    size_t room = (size_t)(tx->buf + tx->buf_size - p), n = tx->rq.head ? 0 : rp->len - tx->sent;
    if (n > room)
        n = room;
    if (n)
        memcpy(p, data + tx->sent, n);
    tx->sent += n, p += n;
    int last = tx->rq.head || tx->sent == rp->len;
    if (lws_write(wsi, start, (size_t)(p - start), last ? LWS_WRITE_HTTP_FINAL : LWS_WRITE_HTTP) < 0)
        return -1;
    lws_set_timeout(wsi, PENDING_TIMEOUT_USER_OK, SEND_IDLE_S);
    if (last)
        tx->state = T_SENT;
    lws_callback_on_writable(wsi);
    return 0;
}

/* ---- dispatch ---- */
static int dispatch(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx)
{
    if (tx->body) {
        tx->body[tx->len] = 0;
        tx->rq.body = tx->body, tx->rq.len = tx->len;
    } else if (tx->method == M_POST) {
        tx->rq.body = "", tx->rq.len = 0;
    }
    if (!tx->r->worker)
        return answer(sv, wsi, tx, tx->r->fn(sv, &tx->rq, &tx->rp));
    mim__job_t *job = calloc(1, sizeof *job);
    if (!job)
        return refuse(sv, wsi, tx, 500, "out of memory for the request");
    job->fn = tx->r->fn;
    job->rq = tx->rq;
    snprintf(job->path, sizeof job->path, "%s", tx->path);
    job->rq.path = job->path;
    job->body = tx->body; /* handed over */
    sv->body_bytes -= tx->cap;
    tx->body = NULL, tx->len = tx->cap = 0;
    job->wsi = wsi;
    if (mim__workers_submit(sv->workers, job)) {
        mim__job_free(job);
        return refuse(sv, wsi, tx, 503, "%s: busy with %u requests; try again", tx->path,
                      mim__workers_pending(sv->workers));
    }
    tx->job = job;
    tx->state = T_WORK;
    return 0;
}

void mim__http_job_done(mim_serve_t *sv, mim__job_t *job)
{
    (void)sv;
    if (job->orphaned) {
        mim__job_free(job);
        return;
    }
    mim__conn_t *conn = lws_wsi_user(job->wsi);
    mim__http_tx_t *tx = conn ? conn->tx : NULL;
    if (!tx || tx->job != job) { /* cannot happen: a closed connection orphans its job */
        mim__job_free(job);
        return;
    }
    tx->job = NULL;
    tx->rp = job->rp;
    memset(&job->rp, 0, sizeof job->rp);
    send_reply(job->wsi, tx, job->status);
    mim__job_free(job);
}

/* ---- the request's body ---- */
static int body_room(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx, size_t more)
{
    if (tx->len + more > sv->max_body)
        return refuse(sv, wsi, tx, 413, "request body: over the limit of %zu bytes", sv->max_body), -1;
    if (tx->len + more + 1 <= tx->cap)
        return 0;
    size_t cap = tx->cap ? tx->cap : 4096;
    while (cap < tx->len + more + 1)
        cap *= 2;
    if (tx->declared >= 0 && cap > (size_t)tx->declared + 1)
        cap = (size_t)tx->declared + 1;
    const size_t budget = 2 * sv->max_body > BODY_BUDGET ? 2 * sv->max_body : BODY_BUDGET;
    if (sv->body_bytes - tx->cap + cap > budget)
        return refuse(sv, wsi, tx, 503, "request body: the server holds too many bodies now; try again"), -1;
    char *b = realloc(tx->body, cap);
    if (!b)
        return refuse(sv, wsi, tx, 500, "out of memory for the request body"), -1;
    sv->body_bytes += cap - tx->cap;
    tx->body = b, tx->cap = cap;
    return 0;
}

static int hexval(unsigned char c)
{
    return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

/* Feeds chunked bytes (RFC 9112 7.1): the data goes to the body. 0, or -1
 * after answering (malformed, or over the limit). Trailers are read and
 * dropped. */
static int unchunk(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx, const unsigned char *p, size_t n)
{
    for (size_t i = 0; i < n && tx->ck != CK_DONE;) {
        unsigned char c = p[i];
        switch (tx->ck) {
        case CK_SIZE:
            if (hexval(c) >= 0) {
                if (++tx->ck_digits > 15)
                    return refuse(sv, wsi, tx, 413, "request body: over the limit of %zu bytes", sv->max_body), -1;
                tx->ck_left = tx->ck_left * 16 + (unsigned)hexval(c);
            } else if (tx->ck_digits && (c == ';' || c == ' ' || c == '\t')) {
                tx->ck = CK_EXT;
            } else if (tx->ck_digits && c == '\r') {
                tx->ck = CK_SIZE_LF;
            } else {
                return refuse(sv, wsi, tx, 400, "request body: malformed chunk size"), -1;
            }
            i++;
            break;
        case CK_EXT:
            if (c == '\r')
                tx->ck = CK_SIZE_LF;
            else if (c < 0x20 && c != '\t')
                return refuse(sv, wsi, tx, 400, "request body: malformed chunk extension"), -1;
            i++;
            break;
        case CK_SIZE_LF:
            if (c != '\n')
                return refuse(sv, wsi, tx, 400, "request body: malformed chunk size line"), -1;
            i++;
            if (tx->ck_left > sv->max_body || tx->len + tx->ck_left > sv->max_body)
                return refuse(sv, wsi, tx, 413, "request body: over the limit of %zu bytes", sv->max_body), -1;
            tx->ck = tx->ck_left ? CK_DATA : CK_LINE;
            break;
        case CK_DATA: {
            size_t k = n - i < tx->ck_left ? n - i : (size_t)tx->ck_left;
            if (body_room(sv, wsi, tx, k))
                return -1;
            memcpy(tx->body + tx->len, p + i, k);
            tx->len += k, i += k, tx->ck_left -= k;
            if (!tx->ck_left)
                tx->ck = CK_DATA_CR;
            break;
        }
        case CK_DATA_CR:
        case CK_DATA_LF:
            if (c != (tx->ck == CK_DATA_CR ? '\r' : '\n'))
                return refuse(sv, wsi, tx, 400, "request body: a chunk does not end in CRLF"), -1;
            tx->ck = tx->ck == CK_DATA_CR ? CK_DATA_LF : CK_SIZE;
            tx->ck_digits = 0;
            i++;
            break;
        case CK_LINE: /* a trailer line, or the empty line that ends the body */
            tx->ck = c == '\r' ? CK_END_LF : CK_SKIP;
            i++;
            break;
        case CK_SKIP:
            if (c == '\n')
                tx->ck = CK_LINE;
            i++;
            break;
        case CK_END_LF:
            if (c != '\n')
                return refuse(sv, wsi, tx, 400, "request body: malformed end of a chunked body"), -1;
            tx->ck = CK_DONE;
            i++;
            break;
        }
    }
    if (tx->ck == CK_DONE && !tx->body_done) {
        tx->body_done = 1;
        lws_set_timer_usecs(wsi, LWS_SET_TIMER_USEC_CANCEL);
        if (!tx->body && body_room(sv, wsi, tx, 0))
            return -1;
        return dispatch(sv, wsi, tx);
    }
    return 0;
}

static int on_body(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx, const unsigned char *p, size_t n)
{
    if (tx->state == T_LINGER)
        return mim_now() > tx->linger_until ? -1 : 0; /* dropped */
    if (tx->state != T_BODY)
        return 0; /* after an answer, or beyond a chunked body's end: dropped */
    if (mim_now() - tx->t0 > REQUEST_S) /* (the timer says so too; this is for a body that never pauses) */
        return refuse(sv, wsi, tx, 408, "request body: not whole within %.0f s", REQUEST_S);
    if (tx->chunked) {
        unchunk(sv, wsi, tx, p, n); /* -1: answered already */
        return 0;
    }
    if (body_room(sv, wsi, tx, n))
        return 0; /* answered */
    memcpy(tx->body + tx->len, p, n);
    tx->len += n;
    return 0;
}

static int on_body_done(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx)
{
    if (tx->state != T_BODY || tx->chunked)
        return 0;
    tx->body_done = 1;
    lws_set_timer_usecs(wsi, LWS_SET_TIMER_USEC_CANCEL);
    if (!tx->body && body_room(sv, wsi, tx, 0))
        return 0;
    return dispatch(sv, wsi, tx);
}

/* ---- a new request ---- */
static int on_request(mim_serve_t *sv, struct lws *wsi, mim__conn_t *conn, const char *in, size_t len)
{
    if (conn->tx) /* a keep-alive connection's last transaction, if anything is left of it */
        tx_free(sv, conn->tx);
    mim__http_tx_t *tx = conn->tx = calloc(1, sizeof *tx);
    if (!tx)
        return -1;
    tx->t0 = mim_now();
    tx->route = MIM__R_OTHER;
    tx->state = T_NEW;
    tx->declared = 0;
    tx->method = method_of(wsi);
    tx->rq.head = tx->method == M_HEAD;
    mim__printable(in, len, tx->path, sizeof tx->path);
    tx->rq.path = tx->path; /* (in lives in lws's header buffer, which may go before the answer) */

    /* headers over the limit: 431, and the connection closes */
    size_t header_bytes = 0;
    for (int t = 0; t < (int)WSI_TOKEN_COUNT; t++) {
        int l = lws_hdr_total_length(wsi, (enum lws_token_indexes)t);
        if (l > 0) header_bytes += (size_t)l;
    }
    if (header_bytes > MIM_SERVE_MAX_HEADER_BYTES)
        return refuse(sv, wsi, tx, 431, "request headers: %zu bytes, more than the %d taken", header_bytes,
                      MIM_SERVE_MAX_HEADER_BYTES);

    /* how the body is framed, before anything else: a request that cannot
     * be framed must not leave bytes behind for the next one */
    char v[64];
    int te = lws_hdr_total_length(wsi, WSI_TOKEN_HTTP_TRANSFER_ENCODING),
        cl = lws_hdr_total_length(wsi, WSI_TOKEN_HTTP_CONTENT_LENGTH);
    if (te > 0 && cl > 0)
        return refuse(sv, wsi, tx, 400, "Content-Length and Transfer-Encoding together: refused (RFC 9112 6.3)");
    if (te > 0) {
        int k = lws_hdr_copy(wsi, v, sizeof v, WSI_TOKEN_HTTP_TRANSFER_ENCODING);
        /* the value without the optional whitespace around it (RFC 9110 5.6.3: SP or HTAB; issue 30) */
        char *tv = v;
        while (k > 0 && (*tv == ' ' || *tv == '\t')) tv++;
        for (size_t e = k > 0 ? strlen(tv) : 0; e > 0 && (tv[e - 1] == ' ' || tv[e - 1] == '\t'); e--) tv[e - 1] = 0;
        if (k < 0 || strcasecmp(tv, "chunked"))
            return refuse(sv, wsi, tx, 400, "Transfer-Encoding: only \"chunked\" is taken");
        tx->chunked = 1, tx->declared = -1, tx->expect_body = 1;
        tx->close = 1; /* a chunked request's connection serves no other */
    } else if (cl > 0) {
        int k = lws_hdr_copy(wsi, v, sizeof v, WSI_TOKEN_HTTP_CONTENT_LENGTH);
        if (k <= 0 || k > 18 || strspn(v, "0123456789") != (size_t)k)
            return refuse(sv, wsi, tx, 400, "Content-Length: '%.20s' is not a number of bytes", k > 0 ? v : "");
        tx->declared = atoll(v);
        tx->expect_body = tx->declared > 0;
    }
    tx->close |= tx->expect_body && tx->method != M_POST; /* a body nobody reads */
    /* a method lws does not know (PUT, PATCH, ...): lws reads neither its
     * Connection header nor, after the answer, times the connection out,
     * so it would stay open for as long as the client likes (measured:
     * the test client waited its 120 s): answer and close */
    tx->close |= tx->method == M_OTHER;

    if (strlen(in) != len)
        return refuse(sv, wsi, tx, 400, "request path: has a NUL byte (%%00)");
    size_t i = 0, n = sizeof routes / sizeof routes[0], any = n;
    for (; i < n; i++)
        if (route_matches(&routes[i], in)) {
            any = any < n ? any : i;
            if (routes[i].m == tx->method)
                break;
        }
    if (i == n && any < n) /* the path is there, not with this method */
        i = any;
    if (i == n) {
        if ((tx->method == M_GET || tx->method == M_HEAD) && mim__viewer_reply(in, &tx->rp)) {
            tx->route = MIM__R_VIEWER;
            return answer(sv, wsi, tx, 200);
        }
        tx->close |= tx->expect_body;
        if (!strcmp(in, "/ws"))
            return answer(sv, wsi, tx, mim__reply_error(&tx->rp, 400, "/ws: the stream needs a WebSocket upgrade"));
        return answer(sv, wsi, tx, mim__reply_error(&tx->rp, 404, "%s: no such route (see schemas/ for the API)", tx->path));
    }
    tx->r = &routes[i];
    tx->route = routes[i].route;
    if (tx->method != routes[i].m) {
        tx->close |= tx->expect_body;
        char allow[64] = "";
        for (size_t r = 0; r < n; r++)
            if (route_matches(&routes[r], in))
                snprintf(allow + strlen(allow), sizeof allow - strlen(allow), "%s%s", allow[0] ? ", " : "",
                         routes[r].method);
        int st = mim__reply_error(&tx->rp, 405, "%s: use %s", tx->path, allow);
        if (st == 405)
            snprintf(tx->rp.headers, sizeof tx->rp.headers, "Allow: %s\r\n", allow);
        return answer(sv, wsi, tx, st);
    }
    if (routes[i].named) /* printable already, and checked as a name by the handler */
        snprintf(tx->rq.name, sizeof tx->rq.name, "%.*s", (int)sizeof tx->rq.name - 1, in + strlen(routes[i].path));
    int k = mim__url_arg(wsi, "k", tx->rq.k, sizeof tx->rq.k);
    tx->rq.k_given = k;
    tx->rq.session_given = mim__url_arg(wsi, "session", tx->rq.session, sizeof tx->rq.session);
    char type[32] = "";
    if (lws_hdr_copy(wsi, type, sizeof type, WSI_TOKEN_HTTP_CONTENT_TYPE) > 0)
        tx->rq.json = !strncasecmp(type, "application/json", 16) && (!type[16] || type[16] == ';' || type[16] == ' ');
    if (tx->method != M_POST)
        return dispatch(sv, wsi, tx);
    if (tx->declared > (long long)sv->max_body)
        return refuse(sv, wsi, tx, 413, "request body: %lld bytes, the limit is %zu", tx->declared, sv->max_body);
    if (!tx->expect_body) {
        tx->body_done = 1;
        return dispatch(sv, wsi, tx);
    }
    tx->state = T_BODY;
    lws_set_timer_usecs(wsi, (lws_usec_t)(REQUEST_S * LWS_USEC_PER_SEC)); /* the whole body, however it trickles */
    return 0;
}

static int on_timer(mim_serve_t *sv, struct lws *wsi, mim__http_tx_t *tx)
{
    if (tx->state == T_LINGER)
        return -1;
    if (tx->state == T_BODY)
        return refuse(sv, wsi, tx, 408, "request body: not whole within %.0f s", REQUEST_S);
    return 0;
}

int mim__http_callback(mim_serve_t *sv, struct lws *wsi, int reason, void *user, void *in, size_t len)
{
    mim__conn_t *conn = user;
    mim__http_tx_t *tx = conn ? conn->tx : NULL;
    switch (reason) {
    case LWS_CALLBACK_HTTP:
        return conn ? on_request(sv, wsi, conn, in ? in : "", in ? len : 0) : -1;
    case LWS_CALLBACK_HTTP_BODY:
        return tx ? on_body(sv, wsi, tx, in, len) : 0;
    case LWS_CALLBACK_HTTP_BODY_COMPLETION:
        return tx ? on_body_done(sv, wsi, tx) : 0;
    case LWS_CALLBACK_HTTP_WRITEABLE:
        return tx ? on_writable(sv, wsi, tx) : 0;
    case LWS_CALLBACK_TIMER:
        return tx ? on_timer(sv, wsi, tx) : 0;
    case LWS_CALLBACK_CLOSED_HTTP:
        if (conn) {
            tx_free(sv, tx);
            conn->tx = NULL;
        }
        return 0;
    default:
        return 0;
    }
}
