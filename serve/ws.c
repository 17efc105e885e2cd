/* The WebSocket avatar stream of mimic serve at /ws
 * (schemas/serve-ws-frame.md), on the lws service thread (server.c).
 *
 * The real-time loop publishes each frame once (mim__ws_publish, on the
 * vest thread): it is encoded once per format some client wants into an
 * immutable, reference-counted message and put on every client's queue,
 * then the service thread is woken (lws_cancel_service). There, on
 * LWS_CALLBACK_EVENT_WAIT_CANCELLED, every client with something queued
 * asks for a writable callback, and each LWS_CALLBACK_SERVER_WRITEABLE
 * writes one message: every write to a client happens on that one thread.
 * So the loop never waits for a client: a client that is slow to read
 * only fills its own socket, and once QUEUE frames wait for it the oldest
 * is dropped (counted), so it stays near the newest. The queue is there
 * for a client that keeps up: a writable callback that comes a little
 * late on a busy machine must not cost it frames.
 *
 * The text messages (hello, format, error) go on the same queue, in order
 * with the frames, and are never dropped. A format switch takes effect
 * under the queue's lock together with queuing its reply, and publish
 * picks each client's encoding under that lock: every frame queued before
 * the {"type": "format"} reply is in the old format, every one after it in
 * the new (issue 12, defect 7). A client that sends messages without
 * reading the replies is stopped reading (lws rx flow control) while
 * TEXT_PAUSE replies wait, and closed at TEXT_MAX.
 *
 * A client that does not read (issue 30, item 4) is stalled from the
 * first frame dropped for it until a frame is written to it again: a
 * client stalled for MIM_SERVE_STALL_CLOSE_S is closed, and a viewer that
 * finds its session's places all taken takes the place of the client
 * stalled longest, if one is for MIM_SERVE_STALL_YIELD_S, so clients that
 * never read cannot lock viewers out. Neither waits for the client: lws kills the connection
 * (a client that does not read would never take a close frame).
 *
 * Client messages are capped at MIM__WS_MESSAGE_MAX bytes, fragments
 * joined (defect 1): lws hands a frame over in pieces of the protocol's
 * rx_buffer_size as they arrive, with the frame's remaining length, so a
 * frame (or a fragmented message) that would pass the cap is refused at
 * its first piece, before it is held, with close status 1009; the rest of
 * it is read and dropped by lws while the close handshake runs.
 *
 * lws writes a frame's header into the LWS_PRE bytes before the payload,
 * which every client's copy of a message shares: harmless, because all
 * writes happen on the one service thread, one after the other, and the
 * header of a given message is the same for every client (server frames
 * are not masked, and no extension is negotiated). */
#include "internal.h"

#include <libwebsockets.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { FMT_F32 = 0, FMT_I16 = 1, N_FMT = 2 };
static const char *const fmt_names[N_FMT] = {"f32", "i16"};

#define HEADER_BYTES 112u
#define LABEL_BYTES 32u
#define QUEUE 4u       /* frames a client may lag behind before its oldest is dropped (67 ms at 60 Hz) */
#define TEXT_PAUSE 8u  /* text replies waiting: stop reading the client's messages */
#define TEXT_MAX 16u   /* and close it (1008) if it still sends */
#define RING (QUEUE + TEXT_MAX)

typedef struct msg {
    atomic_int refs;
    size_t len;
    unsigned char *bytes; /* room + LWS_PRE */
    unsigned char room[];
} msg_t;

typedef struct item {
    msg_t *m;
    int text;
} item_t;

typedef struct mim__ws_client {
    mim__ws_t *ws;
    mim__vs_t *vs;          /* the session it streams (a reference, released when it closes) */
    int closing;            /* under ws->lock: its session was removed; close it (1001) */
    struct lws *wsi;
    int format;             /* FMT_*, under ws->lock */
    item_t q[RING];         /* under ws->lock: to send, oldest at head */
    unsigned head, count, frames, texts;
    uint64_t drops;
    double stalled_since;   /* under ws->lock: mim_now() of the first drop since its last frame written; 0: not stalled */
    int evicted;            /* under ws->lock: killed for not reading; no longer counted among its session's clients */
    int paused;             /* rx flow control off (service thread) */
    int in_msg, msg_binary; /* a client message is being read (service thread) */
    size_t msg_len;
    char msg[MIM__WS_MESSAGE_MAX + 1];
    struct mim__ws_client *next;
} client_t;

struct mim__ws {
    mim_serve_t *sv;
    pthread_mutex_t lock; /* clients, their queues and formats, ctx */
    struct lws_context *ctx; /* woken by publish; NULL before listening and once closing */
    client_t *clients;    /* every session's */
    unsigned n_clients, max_clients; /* max_clients: of one session */
    struct lws **wake;    /* wake_cap: scratch of the service thread */
    unsigned wake_cap;
};

/* A message of len bytes after LWS_PRE bytes of room for lws's frame
 * header, one reference held. */
static msg_t *msg_new(size_t len)
{
    msg_t *m = malloc(sizeof *m + LWS_PRE + len);
    if (!m)
        return NULL;
    atomic_init(&m->refs, 1);
    m->len = len;
    m->bytes = m->room + LWS_PRE;
    return m;
}

/* A text message of JSON object j (taken); NULL when out of memory. */
static msg_t *msg_json(json_t *j)
{
    char *txt = j ? json_dumps(j, JSON_COMPACT | JSON_PRESERVE_ORDER) : NULL;
    json_decref(j);
    msg_t *m = txt ? msg_new(strlen(txt)) : NULL;
    if (m)
        memcpy(m->bytes, txt, m->len);
    free(txt);
    return m;
}

static void msg_unref(msg_t *m)
{
    if (m && atomic_fetch_sub(&m->refs, 1) == 1)
        free(m);
}

static void put_u16(unsigned char *p, uint16_t v)
{
    p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8);
}
static void put_u32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}
static void put_u64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}
static void put_f32(unsigned char *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    put_u32(p, u);
}

static size_t frame_bytes(uint32_t n_vertices, uint32_t n_landmarks, int int16)
{
    size_t pos = int16 ? 6 * (size_t)n_vertices + 2 * (n_vertices & 1u) : 12 * (size_t)n_vertices;
    return HEADER_BYTES + pos + 12 * (size_t)n_landmarks;
}

/* Encodes a frame in one format (the layout of schemas/serve-ws-frame.md). */
static msg_t *encode(const mim_serve_frame_t *f, int format)
{
    const uint32_t n = f->n_vertices, L = f->n_landmarks;
    size_t len = frame_bytes(n, L, format == FMT_I16);
    msg_t *m = msg_new(len);
    if (!m)
        return NULL;
    unsigned char *b = m->bytes;
    memset(b, 0, HEADER_BYTES);
    memcpy(b, "MIMF", 4);
    put_u16(b + 4, 1);
    put_u16(b + 6, (uint16_t)((f->key ? 1u : 0u) | (format == FMT_I16 ? 2u : 0u)));
    put_u64(b + 8, f->number);
    put_u64(b + 16, f->t_vest_us);
    put_u64(b + 24, f->template_id);
    put_u32(b + 32, n);
    put_u32(b + 36, L);
    put_u32(b + 40, f->compute_us);
    put_u32(b + 44, f->key_interval);
    put_u64(b + 48, f->arrival_us);
    memcpy(b + 56, f->label, strnlen(f->label, LABEL_BYTES)); /* NUL-padded, not terminated at 32 */
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float x = f->positions[3 * i + a];
            lo[a] = x < lo[a] ? x : lo[a];
            hi[a] = x > hi[a] ? x : hi[a];
        }
    for (int a = 0; a < 3; a++) {
        put_f32(b + 88 + 4 * a, n ? lo[a] : 0.0f);
        put_f32(b + 100 + 4 * a, n ? hi[a] : 0.0f);
    }
    unsigned char *p = b + HEADER_BYTES;
    if (format == FMT_F32) {
        for (size_t i = 0; i < 3 * (size_t)n; i++, p += 4)
            put_f32(p, f->positions[i]);
    } else {
        float scale[3];
        for (int a = 0; a < 3; a++)
            scale[a] = hi[a] > lo[a] ? 65535.0f / (hi[a] - lo[a]) : 0.0f;
        for (size_t i = 0; i < 3 * (size_t)n; i++, p += 2) {
            int a = (int)(i % 3);
            long q = lroundf((f->positions[i] - lo[a]) * scale[a]) - 32768;
            put_u16(p, (uint16_t)(int16_t)(q < -32768 ? -32768 : q > 32767 ? 32767 : q));
        }
        if (n & 1u)
            p += 2;
    }
    for (size_t i = 0; i < 3 * (size_t)L; i++, p += 4)
        put_f32(p, f->landmarks[i]);
    return m;
}


/* ---- a client's queue (under ws->lock) ---- */
static item_t *at(client_t *c, unsigned i)
{
    return &c->q[(c->head + i) % RING];
}

/* Appends; a frame past QUEUE drops the oldest frame queued (not a text
 * message: those are never dropped, and the order of the rest is kept).
 * 1 if a frame was dropped. */
static int push(client_t *c, msg_t *m, int text)
{
    int dropped = 0;
    if (!text && c->frames == QUEUE) {
        if (!c->stalled_since)
            c->stalled_since = mim_now();
        unsigned i = 0;
        while (at(c, i)->text)
            i++;
        msg_unref(at(c, i)->m);
        for (; i + 1 < c->count; i++)
            *at(c, i) = *at(c, i + 1);
        c->count--, c->frames--, c->drops++;
        dropped = 1;
    }
    atomic_fetch_add(&m->refs, 1);
    *at(c, c->count) = (item_t){m, text};
    c->count++;
    if (text)
        c->texts++;
    else
        c->frames++;
    return dropped;
}

static item_t pop(client_t *c)
{
    item_t it = *at(c, 0);
    c->head = (c->head + 1) % RING, c->count--;
    if (it.text)
        c->texts--;
    else
        c->frames--;
    return it;
}

void mim__ws_publish(mim__ws_t *ws, mim__vs_t *vs, const mim_serve_frame_t *f)
{
    if (!ws)
        return;
    msg_t *m[N_FMT] = {NULL, NULL};
    uint64_t dropped = 0;
    /* Each client's format is read under the lock, where it changes: an
     * encoding missing for it is made outside the lock and the check
     * repeated (a switch in between is rare), so no client ever gets a
     * frame in a format it has left. */
    pthread_mutex_lock(&ws->lock);
    for (;;) {
        int need[N_FMT] = {0, 0}, missing = 0;
        for (client_t *c = ws->clients; c; c = c->next)
            if (c->vs == vs)
                need[c->format] = 1;
        for (int k = 0; k < N_FMT; k++)
            missing |= need[k] && !m[k];
        if (!missing)
            break;
        pthread_mutex_unlock(&ws->lock);
        for (int k = 0; k < N_FMT; k++)
            if (need[k] && !m[k] && !(m[k] = encode(f, k)))
                break;
        pthread_mutex_lock(&ws->lock);
        int failed = 0;
        for (int k = 0; k < N_FMT; k++)
            failed |= need[k] && !m[k];
        if (failed)
            break; /* out of memory: clients of that format miss this frame */
    }
    int woken = 0;
    for (client_t *c = ws->clients; c; c = c->next) {
        if (c->vs != vs || c->closing || c->evicted || !m[c->format])
            continue;
        dropped += (uint64_t)push(c, m[c->format], 0);
        woken = 1;
    }
    if (woken && ws->ctx)
        lws_cancel_service(ws->ctx); /* under the lock: close detaches ctx before destroying it */
    pthread_mutex_unlock(&ws->lock);
    if (dropped)
        mim__metrics_add(&vs->m, MIM__C_DROPS, dropped);
    for (int k = 0; k < N_FMT; k++)
        msg_unref(m[k]); /* the queues hold their own references */
}

/* ---- the service thread ---- */
/* Kills c's connection for not reading (under ws->lock, on the service
 * thread): it is closed on lws's next pass, and no longer counted. */
static void evict(client_t *c)
{
    c->evicted = 1;
    lws_set_timeout(c->wsi, PENDING_TIMEOUT_USER_OK, LWS_TO_KILL_ASYNC);
    mim__metrics_add(&c->vs->m, MIM__C_WS_EVICTED, 1);
}

void mim__ws_service(mim__ws_t *ws)
{
    unsigned n = 0;
    const double now = mim_now();
    pthread_mutex_lock(&ws->lock);
    if (ws->n_clients > ws->wake_cap) { /* sessions come and go: the scratch grows with the clients */
        struct lws **w = realloc(ws->wake, ws->n_clients * sizeof *w);
        if (w)
            ws->wake = w, ws->wake_cap = ws->n_clients;
    }
    for (client_t *c = ws->clients; c; c = c->next)
        if (!c->evicted && c->stalled_since && now - c->stalled_since >= MIM_SERVE_STALL_CLOSE_S)
            evict(c);
    for (client_t *c = ws->clients; c && n < ws->wake_cap; c = c->next)
        if (!c->evicted && (c->count || c->closing))
            ws->wake[n++] = c->wsi;
    pthread_mutex_unlock(&ws->lock);
    for (unsigned i = 0; i < n; i++)
        lws_callback_on_writable(ws->wake[i]);
}

/* Queues a text message (a JSON object) for c, the format switch first
 * when fmt >= 0 (both under the lock: see the top of the file). */
static int queue_text(client_t *c, json_t *j, int fmt)
{
    mim__ws_t *ws = c->ws;
    msg_t *m = msg_json(j);
    if (!m)
        return -1;
    pthread_mutex_lock(&ws->lock);
    int full = c->texts >= TEXT_MAX;
    if (!full) {
        if (fmt >= 0)
            c->format = fmt;
        push(c, m, 1);
    }
    unsigned texts = c->texts;
    pthread_mutex_unlock(&ws->lock);
    msg_unref(m);
    if (full)
        return -1;
    if (texts >= TEXT_PAUSE && !c->paused) { /* it sends faster than it reads: wait for it */
        lws_rx_flow_control(c->wsi, 0);
        c->paused = 1;
    }
    lws_callback_on_writable(c->wsi);
    return 0;
}

static int send_error(client_t *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int send_error(client_t *c, const char *fmt, ...)
{
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return queue_text(c, json_pack("{s:s, s:s}", "type", "error", "error", msg), -1);
}

/* ?format=f32|i16 on the URL: the format, or -1 if malformed */
static int url_format(struct lws *wsi)
{
    char v[16];
    int r = mim__url_arg(wsi, "format", v, sizeof v);
    if (r == 0)
        return FMT_F32;
    for (int k = 0; r > 0 && k < N_FMT; k++)
        if (!strcmp(v, fmt_names[k]))
            return k;
    return -1;
}

/* ?session=NAME on the URL (absent: the first session): 0 with a
 * reference in *vs, else the HTTP status with why. */
static int url_session(mim__ws_t *ws, struct lws *wsi, char *name, size_t n, mim__vs_t **vs, char *why,
                       size_t why_size)
{
    int r = mim__url_arg(wsi, "session", name, n);
    if (r < 0 || (r > 0 && !mim__session_name_ok(name))) {
        snprintf(why, why_size, "/ws: ?session= must be " MIM_SERVE_SESSION_NAME_RULE);
        return 400;
    }
    if (r == 0)
        name[0] = 0;
    if (!(*vs = mim__sessions_get(ws->sv, name))) {
        if (name[0])
            snprintf(why, why_size, "/ws?session=%s: no such session (GET /api/sessions lists them)", name);
        else
            snprintf(why, why_size, "/ws: the service has no session yet (POST /api/sessions adds one)");
        return 404;
    }
    snprintf(name, n, "%s", (*vs)->name);
    return 0;
}

int mim__ws_confirm(mim__ws_t *ws, struct lws *wsi, char *why, size_t why_size)
{
    char path[64] = "";
    if (lws_hdr_copy(wsi, path, sizeof path, WSI_TOKEN_GET_URI) < 0 || strcmp(path, "/ws")) {
        char shown[80];
        mim__printable(path, strlen(path), shown, sizeof shown);
        snprintf(why, why_size, "%s: no WebSocket here (the stream is /ws)", shown);
        return 404;
    }
    if (url_format(wsi) < 0) {
        snprintf(why, why_size, "/ws: ?format= must be f32 or i16");
        return 400;
    }
    char name[MIM_SERVE_SESSION_NAME_MAX + 1];
    mim__vs_t *vs = NULL;
    int status = url_session(ws, wsi, name, sizeof name, &vs, why, why_size);
    if (status)
        return status;
    unsigned have = mim__ws_clients(ws, vs);
    if (have >= ws->max_clients) { /* every place taken: the client stalled longest makes room */
        client_t *worst = NULL;
        const double now = mim_now();
        pthread_mutex_lock(&ws->lock);
        for (client_t *c = ws->clients; c; c = c->next)
            if (c->vs == vs && !c->evicted && c->stalled_since && now - c->stalled_since >= MIM_SERVE_STALL_YIELD_S &&
                (!worst || c->stalled_since < worst->stalled_since))
                worst = c;
        if (worst)
            evict(worst), have--;
        pthread_mutex_unlock(&ws->lock);
    }
    mim__vs_release(vs);
    if (have >= ws->max_clients) {
        snprintf(why, why_size, "/ws: session %s has its %u clients (--max-clients); try again later", name,
                 ws->max_clients);
        return 503;
    }
    return 0;
}

static int on_established(mim__ws_t *ws, struct lws *wsi, mim__conn_t *conn)
{
    int fmt = url_format(wsi);
    char name[MIM_SERVE_SESSION_NAME_MAX + 1], why[160];
    mim__vs_t *vs = NULL;
    if (url_session(ws, wsi, name, sizeof name, &vs, why, sizeof why)) /* removed since the upgrade was confirmed */
        return -1;
    client_t *c = calloc(1, sizeof *c);
    json_t *names = json_array();
    for (uint32_t i = 0; i < vs->map->count; i++)
        json_array_append_new(names, json_string(vs->map->names[i]));
    json_t *j = json_pack("{s:s, s:i, s:s, s:i, s:i, s:i, s:o, s:s}", "type", "hello", "version", 1, "session",
                          vs->name, "vertices", (int)vs->out_mesh->n_vertices, "faces", (int)vs->out_mesh->n_faces,
                          "landmarks", (int)vs->map->count, "landmark_names", names, "format",
                          fmt_names[fmt < 0 ? 0 : fmt]);
    msg_t *hello = msg_json(j);
    if (!c || fmt < 0 || !hello) {
        free(c);
        msg_unref(hello);
        mim__vs_release(vs);
        return -1;
    }
    c->ws = ws;
    c->vs = vs;
    c->wsi = wsi;
    c->format = fmt;
    /* the hello is queued before the client is on the list that publish
     * walks: it goes first, every frame after it */
    push(c, hello, 1);
    msg_unref(hello);
    pthread_mutex_lock(&ws->lock);
    c->next = ws->clients, ws->clients = c;
    ws->n_clients++;
    pthread_mutex_unlock(&ws->lock);
    /* removed since the lookup: mim_serve_session_remove marks it removed
     * before it closes the clients it finds, so a client it missed sees
     * the mark here */
    if (mim__vs_removed(vs)) {
        pthread_mutex_lock(&ws->lock);
        c->closing = 1;
        pthread_mutex_unlock(&ws->lock);
    }
    conn->client = c;
    mim__metrics_add(&vs->m, MIM__C_WS_JOINED, 1);
    lws_callback_on_writable(wsi);
    return 0;
}

static int refuse_close(struct lws *wsi, enum lws_close_status status, const char *why);

static int on_writable(mim__ws_t *ws, client_t *c)
{
    pthread_mutex_lock(&ws->lock);
    int closing = c->closing;
    pthread_mutex_unlock(&ws->lock);
    if (closing)
        return refuse_close(c->wsi, LWS_CLOSE_STATUS_GOINGAWAY, "session removed");
    pthread_mutex_lock(&ws->lock);
    if (!c->count) {
        pthread_mutex_unlock(&ws->lock);
        return 0;
    }
    item_t it = pop(c);
    int more = c->count > 0;
    unsigned texts = c->texts;
    pthread_mutex_unlock(&ws->lock);
    int w = lws_write(c->wsi, it.m->bytes, it.m->len, it.text ? LWS_WRITE_TEXT : LWS_WRITE_BINARY);
    msg_unref(it.m);
    if (w < 0)
        return -1; /* the peer is gone */
    if (!it.text) {
        mim__metrics_add(&c->vs->m, MIM__C_WS_SENT, 1);
        pthread_mutex_lock(&ws->lock);
        c->stalled_since = 0; /* it reads again */
        pthread_mutex_unlock(&ws->lock);
    }
    if (c->paused && texts < TEXT_PAUSE / 2) {
        lws_rx_flow_control(c->wsi, 1);
        c->paused = 0;
    }
    if (more)
        lws_callback_on_writable(c->wsi);
    return 0;
}

/* A whole client message: {"format": "f32"|"i16"}; anything else gets an
 * error reply and changes nothing. */
static int on_message(client_t *c)
{
    mim__metrics_add(&c->vs->m, MIM__C_WS_MESSAGES, 1);
    if (c->msg_binary) {
        mim__metrics_add(&c->vs->m, MIM__C_WS_BAD, 1);
        return send_error(c, "binary message of %zu bytes: the stream takes JSON text ({\"format\": \"f32\"|\"i16\"})",
                          c->msg_len);
    }
    char why[256];
    int fmt = mim__ws_parse_message(c->msg, c->msg_len, why, sizeof why);
    if (fmt < 0) {
        mim__metrics_add(&c->vs->m, MIM__C_WS_BAD, 1);
        return send_error(c, "%s", why);
    }
    return queue_text(c, json_pack("{s:s, s:s}", "type", "format", "format", fmt_names[fmt]), fmt);
}

static int refuse_close(struct lws *wsi, enum lws_close_status status, const char *why)
{
    lws_close_reason(wsi, status, (unsigned char *)why, strlen(why));
    return -1;
}

/* A piece of a client message: joined with the others of its message,
 * which must stay within MIM__WS_MESSAGE_MAX. */
static int on_receive(struct lws *wsi, client_t *c, const void *in, size_t len)
{
    if (lws_get_reserved_bits(wsi)) { /* no extension was agreed: RFC 6455 5.2 fails the connection */
        mim__metrics_add(&c->vs->m, MIM__C_WS_BAD, 1);
        return refuse_close(wsi, LWS_CLOSE_STATUS_PROTOCOL_ERR, "reserved bits set");
    }
    if (!c->in_msg) {
        c->in_msg = 1;
        c->msg_len = 0;
        c->msg_binary = lws_frame_is_binary(wsi);
    }
    size_t rest = lws_remaining_packet_payload(wsi);
    if (len > MIM__WS_MESSAGE_MAX - c->msg_len || rest > MIM__WS_MESSAGE_MAX - c->msg_len - len) {
        mim__metrics_add(&c->vs->m, MIM__C_WS_BAD, 1);
        return refuse_close(wsi, LWS_CLOSE_STATUS_MESSAGE_TOO_LARGE, "message over 4096 bytes");
    }
    memcpy(c->msg + c->msg_len, in, len);
    c->msg_len += len;
    if (!lws_is_final_fragment(wsi) || rest)
        return 0;
    c->in_msg = 0;
    c->msg[c->msg_len] = 0;
    if (on_message(c))
        return refuse_close(wsi, LWS_CLOSE_STATUS_POLICY_VIOLATION, "too many replies unread");
    return 0;
}

static void on_closed(mim__ws_t *ws, client_t *c)
{
    pthread_mutex_lock(&ws->lock);
    for (client_t **p = &ws->clients; *p; p = &(*p)->next)
        if (*p == c) {
            *p = c->next;
            break;
        }
    ws->n_clients--;
    while (c->count)
        msg_unref(pop(c).m);
    pthread_mutex_unlock(&ws->lock);
    mim__metrics_add(&c->vs->m, MIM__C_WS_LEFT, 1);
    mim__vs_release(c->vs);
    free(c);
}

int mim__ws_callback(mim__ws_t *ws, struct lws *wsi, int reason, void *user, void *in, size_t len)
{
    mim__conn_t *conn = user;
    client_t *c = conn ? conn->client : NULL;
    switch (reason) {
    case LWS_CALLBACK_ESTABLISHED:
        return conn ? on_established(ws, wsi, conn) : -1;
    case LWS_CALLBACK_SERVER_WRITEABLE:
        return c ? on_writable(ws, c) : 0;
    case LWS_CALLBACK_RECEIVE:
        return c ? on_receive(wsi, c, in, len) : -1;
    case LWS_CALLBACK_CLOSED:
        if (c) {
            on_closed(ws, c);
            conn->client = NULL;
        }
        return 0;
    default:
        return 0;
    }
}

int mim__ws_parse_message(const char *data, size_t len, char *why, size_t why_size)
{
    json_error_t je;
    json_t *j = json_loadb(data, len, JSON_REJECT_DUPLICATES, &je), *v, *f = NULL;
    const char *key;
    int fmt = -1;
    why[0] = 0;
    if (!j) {
        /* jansson quotes the bad bytes: keep printable ASCII only */
        for (char *p = je.text; *p; p++)
            if ((unsigned char)*p < 0x20 || (unsigned char)*p >= 0x7f)
                *p = '?';
        snprintf(why, why_size, "message:%d:%d: %s", je.line, je.column, je.text);
    } else if (!json_is_object(j)) {
        snprintf(why, why_size, "message: expected an object such as {\"format\": \"i16\"}");
    } else {
        json_object_foreach(j, key, v) if (!why[0] && strcmp(key, "format"))
        {
            /* the key goes back in a one-line JSON reply: cut at a UTF-8
             * boundary, control characters shown as '?' */
            char shown[65];
            size_t n = strlen(key);
            if (n > 64)
                for (n = 64; n > 0 && ((unsigned char)key[n] & 0xC0) == 0x80; n--)
                    ;
            for (size_t i = 0; i < n; i++)
                shown[i] = (unsigned char)key[i] < 0x20 || key[i] == 0x7f ? '?' : key[i];
            shown[n] = 0;
            snprintf(why, why_size, "message: unknown member \"%s\" (the stream takes \"format\")", shown);
        }
        f = json_object_get(j, "format");
        if (!why[0] && !f)
            snprintf(why, why_size, "message: give \"format\": \"f32\" or \"i16\"");
    }
    for (int k = 0; !why[0] && k < N_FMT; k++)
        if (json_is_string(f) && !strcmp(json_string_value(f), fmt_names[k]))
            fmt = k;
    if (!why[0] && fmt < 0)
        snprintf(why, why_size, "message: \"format\" must be \"f32\" or \"i16\"");
    json_decref(j);
    return why[0] ? -1 : fmt;
}


int mim__ws_open(mim__ws_t **out, mim_serve_t *sv, unsigned max_clients, mim_error_t *err)
{
    mim__ws_t *ws = calloc(1, sizeof *ws);
    if (ws && !(ws->wake = calloc(max_clients ? max_clients : 1, sizeof *ws->wake))) {
        free(ws);
        ws = NULL;
    }
    if (ws)
        ws->wake_cap = max_clients ? max_clients : 1;
    if (!ws)
        return mim_error_set(err, MIM_ENOMEM, "out of memory for the WebSocket stream");
    ws->sv = sv;
    ws->max_clients = max_clients;
    pthread_mutex_init(&ws->lock, NULL);
    *out = ws;
    return 0;
}

void mim__ws_attach(mim__ws_t *ws, struct lws_context *ctx)
{
    pthread_mutex_lock(&ws->lock);
    ws->ctx = ctx;
    pthread_mutex_unlock(&ws->lock);
}

void mim__ws_close(mim__ws_t **pws)
{
    mim__ws_t *ws = pws ? *pws : NULL;
    if (!ws)
        return;
    /* the context is destroyed: every connection has closed and freed its
     * client and queue (on_closed) */
    pthread_mutex_destroy(&ws->lock);
    free(ws->wake);
    free(ws);
    *pws = NULL;
}

void mim__ws_drop_session(mim__ws_t *ws, mim__vs_t *vs)
{
    pthread_mutex_lock(&ws->lock);
    int any = 0;
    for (client_t *c = ws->clients; c; c = c->next)
        if (c->vs == vs)
            c->closing = any = 1;
    if (any && ws->ctx)
        lws_cancel_service(ws->ctx); /* mim__ws_service asks for their writable callbacks, which close them */
    pthread_mutex_unlock(&ws->lock);
}

json_t *mim__ws_status(mim__ws_t *ws, const mim__vs_t *vs)
{
    /* joined and left are the session's counters (the process's: summed) */
    uint64_t joined = 0, left = 0;
    size_t n = 0;
    mim__vs_t **all = vs ? NULL : mim__sessions_all(ws->sv, &n);
    for (size_t i = 0; i < (vs ? 1 : n); i++) {
        mim__vs_t *v = vs ? (mim__vs_t *)vs : all[i];
        joined += mim__metrics_get(&v->m, MIM__C_WS_JOINED);
        left += mim__metrics_get(&v->m, MIM__C_WS_LEFT);
    }
    mim__sessions_release_all(all, n);
    pthread_mutex_lock(&ws->lock);
    uint64_t drops = 0, worst = 0;
    unsigned clients = 0;
    for (client_t *c = ws->clients; c; c = c->next) {
        if (vs && c->vs != vs)
            continue;
        clients++;
        drops += c->drops;
        worst = c->drops > worst ? c->drops : worst;
    }
    json_t *j = json_pack("{s:i, s:i, s:I, s:I, s:I, s:I}", "clients", (int)clients, "max_clients",
                          (int)ws->max_clients, "joined", (json_int_t)joined, "left", (json_int_t)left,
                          "dropped_now", (json_int_t)drops, "dropped_worst_client", (json_int_t)worst);
    pthread_mutex_unlock(&ws->lock);
    return j;
}

unsigned mim__ws_clients(mim__ws_t *ws, const mim__vs_t *vs)
{
    pthread_mutex_lock(&ws->lock);
    unsigned n = 0;
    for (client_t *c = ws->clients; c; c = c->next)
        n += !c->evicted && (!vs || c->vs == vs);
    pthread_mutex_unlock(&ws->lock);
    return n;
}
