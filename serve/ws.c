/* The WebSocket avatar stream of mimic serve at /ws
 * (schemas/serve-ws-frame.md). The real-time loop publishes each frame once:
 * it is encoded into an immutable, reference-counted message and put on
 * every client's short queue (QUEUE frames), which the client's own sender
 * thread empties. So the loop never waits for a client: a client that is
 * slow to read only blocks its own sender, and once its queue is full the
 * oldest queued frame is dropped for it (counted), so it stays near the
 * newest. The queue is there for a client that keeps up: a sender thread
 * that the scheduler keeps waiting past one vest period on a busy machine
 * must not cost it frames (with only the latest frame kept, it did).
 * civetweb runs each connection's read loop on a worker thread and locks
 * the connection inside mg_websocket_write, so the sender thread and the
 * worker (text replies, pongs) may both write. */
#include "internal.h"

#include <civetweb.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { FMT_F32 = 0, FMT_I16 = 1, N_FMT = 2 };
static const char *const fmt_names[N_FMT] = {"f32", "i16"};

#define HEADER_BYTES 112u
#define LABEL_BYTES 32u
#define QUEUE 4u /* frames a client may lag behind before its oldest is dropped (67 ms at 60 Hz) */

typedef struct msg {
    atomic_int refs;
    size_t len;
    unsigned char bytes[];
} msg_t;

typedef struct client {
    mim__ws_t *ws;
    struct mg_connection *conn;
    pthread_t thread;
    int started;       /* under ws->lock: its sender runs and takes frames */
    int stop;          /* under ws->lock */
    atomic_int format; /* FMT_* */
    msg_t *queue[QUEUE]; /* under ws->lock: frames to send, oldest at head */
    unsigned head, count;
    uint64_t drops;
    struct client *next;
} client_t;

struct mim__ws {
    mim_serve_t *sv;
    pthread_mutex_t lock; /* clients, their queues and stop flags */
    pthread_cond_t fresh; /* a new frame or a stop */
    client_t *clients;
    unsigned n_clients, max_clients;
    atomic_uint n_i16;    /* clients that want int16: only then is it encoded */
    uint64_t joined, left;
};

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
    msg_t *m = malloc(sizeof *m + len);
    if (!m)
        return NULL;
    atomic_init(&m->refs, 1);
    m->len = len;
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

void mim__ws_publish(mim__ws_t *ws, const mim_serve_frame_t *f)
{
    if (!ws)
        return;
    msg_t *m[N_FMT] = {encode(f, FMT_F32), atomic_load(&ws->n_i16) ? encode(f, FMT_I16) : NULL};
    uint64_t dropped = 0;
    pthread_mutex_lock(&ws->lock);
    for (client_t *c = ws->clients; c; c = c->next) {
        /* a client that just asked for i16 may get one more f32 frame (its flags say so) */
        msg_t *mc = m[atomic_load(&c->format)] ? m[atomic_load(&c->format)] : m[FMT_F32];
        if (!c->started || c->stop || !mc)
            continue;
        if (c->count == QUEUE) { /* full: the oldest is dropped, so the client stays near the newest */
            msg_unref(c->queue[c->head]);
            c->head = (c->head + 1) % QUEUE, c->count--;
            c->drops++, dropped++;
        }
        atomic_fetch_add(&mc->refs, 1);
        c->queue[(c->head + c->count) % QUEUE] = mc, c->count++;
    }
    pthread_cond_broadcast(&ws->fresh);
    pthread_mutex_unlock(&ws->lock);
    if (dropped)
        mim__metrics_add(&ws->sv->m, MIM__C_DROPS, dropped);
    for (int k = 0; k < N_FMT; k++)
        msg_unref(m[k]); /* the queues hold their own references */
}

static void *sender(void *arg)
{
    client_t *c = arg;
    mim__ws_t *ws = c->ws;
    pthread_mutex_lock(&ws->lock);
    while (!c->stop) {
        if (!c->count) {
            pthread_cond_wait(&ws->fresh, &ws->lock);
            continue;
        }
        msg_t *m = c->queue[c->head];
        c->head = (c->head + 1) % QUEUE, c->count--;
        pthread_mutex_unlock(&ws->lock);
        int w = mg_websocket_write(c->conn, MG_WEBSOCKET_OPCODE_BINARY, (const char *)m->bytes, m->len);
        msg_unref(m);
        if (w > 0)
            mim__metrics_add(&ws->sv->m, MIM__C_WS_SENT, 1);
        pthread_mutex_lock(&ws->lock);
        if (w <= 0) {
            c->stop = 1; /* the peer is gone: civetweb's read loop sees it and closes */
            break;
        }
    }
    pthread_mutex_unlock(&ws->lock);
    return NULL;
}

static int send_text(struct mg_connection *conn, json_t *j)
{
    char *txt = j ? json_dumps(j, JSON_COMPACT | JSON_PRESERVE_ORDER) : NULL;
    json_decref(j);
    int w = txt ? mg_websocket_write(conn, MG_WEBSOCKET_OPCODE_TEXT, txt, strlen(txt)) : -1;
    free(txt);
    return w;
}

static int send_error(struct mg_connection *conn, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int send_error(struct mg_connection *conn, const char *fmt, ...)
{
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return send_text(conn, json_pack("{s:s, s:s}", "type", "error", "error", msg));
}

/* ?format=f32|i16 on the URL; -1 if malformed */
static int url_format(const struct mg_connection *conn)
{
    const struct mg_request_info *ri = mg_get_request_info(conn);
    char v[16];
    int n = ri->query_string ? mg_get_var(ri->query_string, strlen(ri->query_string), "format", v, sizeof v) : -1;
    if (n == -1)
        return FMT_F32; /* absent (-2: too long for any format name) */
    if (n < 0)
        return -1;
    for (int k = 0; k < N_FMT; k++)
        if (!strcmp(v, fmt_names[k]))
            return k;
    return -1;
}

static void set_format(client_t *c, int fmt)
{
    int was = atomic_exchange(&c->format, fmt);
    if (was != FMT_I16 && fmt == FMT_I16)
        atomic_fetch_add(&c->ws->n_i16, 1);
    else if (was == FMT_I16 && fmt != FMT_I16)
        atomic_fetch_sub(&c->ws->n_i16, 1);
}

/* civetweb: 0 accepts the handshake, 1 refuses it */
static int on_connect(const struct mg_connection *conn, void *cbdata)
{
    mim__ws_t *ws = cbdata;
    int fmt = url_format(conn);
    if (fmt < 0)
        return 1;
    client_t *c = calloc(1, sizeof *c);
    if (!c)
        return 1;
    c->ws = ws;
    atomic_init(&c->format, FMT_F32);
    pthread_mutex_lock(&ws->lock);
    int full = ws->n_clients >= ws->max_clients;
    if (!full) {
        c->next = ws->clients, ws->clients = c;
        ws->n_clients++, ws->joined++;
    }
    pthread_mutex_unlock(&ws->lock);
    if (full) {
        free(c);
        return 1;
    }
    set_format(c, fmt);
    mg_set_user_connection_data(conn, c);
    return 0;
}

static void on_ready(struct mg_connection *conn, void *cbdata)
{
    mim__ws_t *ws = cbdata;
    client_t *c = mg_get_user_connection_data(conn);
    if (!c)
        return;
    c->conn = conn;
    const mim_serve_t *sv = ws->sv;
    json_t *names = json_array();
    for (uint32_t i = 0; i < sv->map->count; i++)
        json_array_append_new(names, json_string(sv->map->names[i]));
    send_text(conn, json_pack("{s:s, s:i, s:i, s:i, s:i, s:o, s:s}", "type", "hello", "version", 1, "vertices",
                              (int)sv->mesh->n_vertices, "faces", (int)sv->mesh->n_faces, "landmarks",
                              (int)sv->map->count, "landmark_names", names, "format",
                              fmt_names[atomic_load(&c->format)]));
    pthread_mutex_lock(&ws->lock);
    c->started = pthread_create(&c->thread, NULL, sender, c) == 0; /* frames from now on */
    pthread_mutex_unlock(&ws->lock);
    mim__metrics_add(&ws->sv->m, MIM__C_WS_JOINED, 1);
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

/* A client message: {"format": "f32"|"i16"}; anything else gets an error
 * reply and changes nothing. Returns 1 to keep the connection. */
static int on_data(struct mg_connection *conn, int bits, char *data, size_t len, void *cbdata)
{
    mim__ws_t *ws = cbdata;
    client_t *c = mg_get_user_connection_data(conn);
    int op = bits & 0x0f;
    if (op == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE)
        return 0;
    if ((bits & 0x70) || (op > MG_WEBSOCKET_OPCODE_BINARY && op < MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) ||
        op > MG_WEBSOCKET_OPCODE_PONG) {
        /* RSV bits without an extension, or a reserved opcode: RFC 6455 5.2
         * says fail the connection (civetweb passes them on) */
        mim__metrics_add(&ws->sv->m, MIM__C_WS_BAD, 1);
        return 0;
    }
    if (op == MG_WEBSOCKET_OPCODE_PING || op == MG_WEBSOCKET_OPCODE_PONG || !c)
        return 1; /* civetweb answers pings itself */
    mim__metrics_add(&ws->sv->m, MIM__C_WS_MESSAGES, 1);
    if (op != MG_WEBSOCKET_OPCODE_TEXT) {
        mim__metrics_add(&ws->sv->m, MIM__C_WS_BAD, 1);
        send_error(conn, "binary message of %zu bytes: the stream takes JSON text ({\"format\": \"f32\"|\"i16\"})",
                   len);
        return 1;
    }
    char why[256];
    int fmt = mim__ws_parse_message(data, len, why, sizeof why);
    if (fmt < 0) {
        mim__metrics_add(&ws->sv->m, MIM__C_WS_BAD, 1);
        send_error(conn, "%s", why);
        return 1;
    }
    set_format(c, fmt);
    send_text(conn, json_pack("{s:s, s:s}", "type", "format", "format", fmt_names[fmt]));
    return 1;
}

static void on_close(const struct mg_connection *conn, void *cbdata)
{
    mim__ws_t *ws = cbdata;
    client_t *c = mg_get_user_connection_data(conn);
    if (!c)
        return;
    pthread_mutex_lock(&ws->lock);
    c->stop = 1;
    pthread_cond_broadcast(&ws->fresh);
    pthread_mutex_unlock(&ws->lock);
    if (c->started)
        pthread_join(c->thread, NULL); /* before civetweb frees the connection */
    for (; c->count; c->count--, c->head = (c->head + 1) % QUEUE)
        msg_unref(c->queue[c->head]);
    set_format(c, FMT_F32);
    pthread_mutex_lock(&ws->lock);
    for (client_t **p = &ws->clients; *p; p = &(*p)->next)
        if (*p == c) {
            *p = c->next;
            break;
        }
    ws->n_clients--, ws->left++;
    pthread_mutex_unlock(&ws->lock);
    mim__metrics_add(&ws->sv->m, MIM__C_WS_LEFT, 1);
    free(c);
}

int mim__ws_open(mim__ws_t **out, mim_serve_t *sv, unsigned max_clients, mim_error_t *err)
{
    mim__ws_t *ws = calloc(1, sizeof *ws);
    if (!ws)
        return mim_error_set(err, MIM_ENOMEM, "out of memory for the WebSocket stream");
    ws->sv = sv;
    ws->max_clients = max_clients;
    pthread_mutex_init(&ws->lock, NULL);
    pthread_cond_init(&ws->fresh, NULL);
    *out = ws;
    return 0;
}

void mim__ws_attach(mim__ws_t *ws, struct mg_context *ctx)
{
    mg_set_websocket_handler(ctx, "/ws", on_connect, on_ready, on_data, on_close, ws);
}

void mim__ws_close(mim__ws_t **pws)
{
    mim__ws_t *ws = pws ? *pws : NULL;
    if (!ws)
        return;
    /* civetweb has stopped: every connection is closed, its sender joined
     * and its queue emptied */
    pthread_cond_destroy(&ws->fresh);
    pthread_mutex_destroy(&ws->lock);
    free(ws);
    *pws = NULL;
}

json_t *mim__ws_status(mim__ws_t *ws)
{
    pthread_mutex_lock(&ws->lock);
    uint64_t drops = 0, worst = 0;
    for (client_t *c = ws->clients; c; c = c->next) {
        drops += c->drops;
        worst = c->drops > worst ? c->drops : worst;
    }
    json_t *j = json_pack("{s:i, s:i, s:I, s:I, s:I, s:I}", "clients", (int)ws->n_clients, "max_clients",
                          (int)ws->max_clients, "joined", (json_int_t)ws->joined, "left", (json_int_t)ws->left,
                          "dropped_now", (json_int_t)drops, "dropped_worst_client", (json_int_t)worst);
    pthread_mutex_unlock(&ws->lock);
    return j;
}

unsigned mim__ws_clients(mim__ws_t *ws)
{
    pthread_mutex_lock(&ws->lock);
    unsigned n = ws->n_clients;
    pthread_mutex_unlock(&ws->lock);
    return n;
}
