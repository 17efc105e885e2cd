/* The WebSocket client of the serve tests and bench/serve (ws_client.h). */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* memmem */
#endif
#include "ws_client.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <unistd.h>

/* ---- SHA-1 (FIPS 180-4) and base64, for the accept header only ---- */
static uint32_t rol(uint32_t x, int n)
{
    return (x << n) | (x >> (32 - n));
}

static void sha1_block(uint32_t h[5], const unsigned char *p)
{
    uint32_t w[80];
    for (int i = 0; i < 16; i++)
        w[i] = (uint32_t)p[4 * i] << 24 | (uint32_t)p[4 * i + 1] << 16 | (uint32_t)p[4 * i + 2] << 8 | p[4 * i + 3];
    for (int i = 16; i < 80; i++)
        w[i] = rol(w[i - 3] ^ w[i - 8] ^ w[i - 14] ^ w[i - 16], 1);
    uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4];
    for (int i = 0; i < 80; i++) {
        uint32_t f, k;
        if (i < 20)
            f = (b & c) | (~b & d), k = 0x5A827999u;
        else if (i < 40)
            f = b ^ c ^ d, k = 0x6ED9EBA1u;
        else if (i < 60)
            f = (b & c) | (b & d) | (c & d), k = 0x8F1BBCDCu;
        else
            f = b ^ c ^ d, k = 0xCA62C1D6u;
        uint32_t t = rol(a, 5) + f + e + k + w[i];
        e = d, d = c, c = rol(b, 30), b = a, a = t;
    }
    h[0] += a, h[1] += b, h[2] += c, h[3] += d, h[4] += e;
}

void ws_sha1(const void *data, size_t n, unsigned char out[20])
{
    uint32_t h[5] = {0x67452301u, 0xEFCDAB89u, 0x98BADCFEu, 0x10325476u, 0xC3D2E1F0u};
    const unsigned char *p = data;
    size_t i = 0;
    for (; i + 64 <= n; i += 64)
        sha1_block(h, p + i);
    unsigned char last[128] = {0};
    size_t rest = n - i, total = rest + 9 <= 64 ? 64 : 128;
    memcpy(last, p + i, rest);
    last[rest] = 0x80;
    uint64_t bits = (uint64_t)n * 8;
    for (int k = 0; k < 8; k++)
        last[total - 1 - k] = (unsigned char)(bits >> (8 * k));
    for (size_t off = 0; off < total; off += 64)
        sha1_block(h, last + off);
    for (int k = 0; k < 5; k++)
        for (int b = 0; b < 4; b++)
            out[4 * k + b] = (unsigned char)(h[k] >> (24 - 8 * b));
}

void ws_base64(const unsigned char *in, size_t n, char *out)
{
    static const char a[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    size_t o = 0;
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)in[i] << 16 | (i + 1 < n ? (uint32_t)in[i + 1] << 8 : 0) | (i + 2 < n ? in[i + 2] : 0);
        out[o++] = a[v >> 18 & 63];
        out[o++] = a[v >> 12 & 63];
        out[o++] = i + 1 < n ? a[v >> 6 & 63] : '=';
        out[o++] = i + 2 < n ? a[v & 63] : '=';
    }
    out[o] = 0;
}

/* ---- the frame reader ---- */
size_t ws_reader_next(ws_reader_t *r, unsigned char *p, size_t n, ws_event_t *ev)
{
    memset(ev, 0, sizeof *ev);
    size_t used = 0;
    if (!r->in_payload) {
        while (used < n && (r->hlen < 2 || r->hlen < r->hneed)) {
            r->hb[r->hlen++] = p[used++];
            if (r->hlen == 2) {
                unsigned l7 = r->hb[1] & 0x7fu;
                r->hneed = 2 + (l7 == 126 ? 2 : l7 == 127 ? 8 : 0) + ((r->hb[1] & 0x80) ? 4 : 0);
            }
        }
        if (r->hlen < 2 || r->hlen < r->hneed)
            return used;
        const unsigned char *b = r->hb;
        uint64_t len = b[1] & 0x7fu;
        unsigned o = 2;
        if (len == 126) {
            len = (uint64_t)b[2] << 8 | b[3];
            o = 4;
        } else if (len == 127) {
            len = 0;
            for (int k = 0; k < 8; k++)
                len = len << 8 | b[2 + k];
            o = 10;
        }
        r->opcode = b[0] & 0x0f, r->fin = (b[0] & 0x80) != 0, r->masked = (b[1] & 0x80) != 0;
        if (r->masked)
            memcpy(r->key, b + o, 4);
        r->len = len, r->got = 0;
        if (r->opcode < 8) {
            if (r->opcode != WS_CONT)
                r->msg_opcode = r->opcode, r->msg_len = 0;
            else if (r->msg_done)
                r->msg_opcode = 0, r->msg_len = 0; /* a continuation of nothing */
            r->msg_done = 0;
        } else {
            r->ctl_len = 0;
        }
        r->in_payload = 1, r->hlen = 0, r->hneed = 0;
        ev->type = WS_EV_HEAD;
        return used;
    }
    if (r->got == r->len) {
        r->in_payload = 0;
        if (r->opcode < 8 && r->fin)
            r->msg_done = 1;
        ev->type = WS_EV_END;
        return 0;
    }
    if (!n)
        return 0;
    size_t k = r->len - r->got < n ? (size_t)(r->len - r->got) : n;
    if (r->masked)
        for (size_t i = 0; i < k; i++)
            p[i] ^= r->key[(r->got + i) & 3];
    if (r->opcode < 8) {
        ev->type = WS_EV_DATA, ev->data = p, ev->len = k, ev->offset = r->msg_len;
        r->msg_len += k;
    } else if (r->ctl_len < sizeof r->ctl) {
        size_t c = sizeof r->ctl - r->ctl_len < k ? sizeof r->ctl - r->ctl_len : k;
        memcpy(r->ctl + r->ctl_len, p, c);
        r->ctl_len += c;
    }
    r->got += k;
    if (ev->type == WS_EV_NONE) /* a control frame's bytes: on to its end */
        return k + ws_reader_next(r, p + k, n - k, ev);
    return k;
}

/* ---- a client connection ---- */
/* Reads more bytes into the buffer before the deadline: 1, 0 timeout, -1 closed. */
static int fill(ws_client_t *w, double deadline)
{
    if (w->fd < 0)
        return -1;
    if (w->pos) { /* what is consumed goes */
        memmove(w->buf, w->buf + w->pos, w->len - w->pos);
        w->len -= w->pos, w->pos = 0;
    }
    if (w->cap - w->len < 65536) {
        size_t cap = w->cap ? 2 * w->cap : 1 << 17;
        unsigned char *b = realloc(w->buf, cap);
        if (!b)
            return -1;
        w->buf = b, w->cap = cap;
    }
    long n = hc_recv(w->fd, w->buf + w->len, w->cap - w->len, deadline);
    if (n <= 0)
        return n < 0 ? -1 : 0;
    w->len += (size_t)n;
    return 1;
}

void ws_close(ws_client_t *w)
{
    if (w->fd >= 0)
        close(w->fd);
    w->fd = -1;
    free(w->buf), free(w->msg);
    w->buf = w->msg = NULL, w->pos = w->len = w->cap = w->msg_len = 0;
    memset(&w->rd, 0, sizeof w->rd);
}

int ws_connect(ws_client_t *w, int port, const char *path, int rcvbuf)
{
    memset(w, 0, sizeof *w);
    w->fd = hc_connect(port, rcvbuf);
    if (w->fd < 0)
        return -1;
    unsigned char nonce[16];
    for (int i = 0; i < 16; i++)
        nonce[i] = (unsigned char)rand();
    char key[32], req[1024];
    ws_base64(nonce, 16, key);
    int n = snprintf(req, sizeof req,
                     "GET %s HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     "Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\n\r\n",
                     path, port, key);
    if (hc_send_all(w->fd, req, (size_t)n))
        goto fail;
    double deadline = hc_now_ms() + 10000;
    unsigned char *end = NULL;
    while (!(end = w->len >= 4 ? memmem(w->buf, w->len, "\r\n\r\n", 4) : NULL))
        if (fill(w, deadline) <= 0)
            break;
    size_t hl = end ? (size_t)(end - w->buf) + 4 : w->len;
    size_t keep = hl < sizeof w->head ? hl : sizeof w->head - 1;
    if (keep)
        memcpy(w->head, w->buf, keep);
    w->head[keep] = 0;
    if (sscanf(w->head, "HTTP/1.1 %d", &w->http_status) != 1)
        w->http_status = 0;
    if (!end || w->http_status != 101)
        goto fail;
    w->pos = hl;
    /* Sec-WebSocket-Accept = base64(SHA-1(key + GUID)) */
    char cat[128], want[64];
    unsigned char dig[20];
    snprintf(cat, sizeof cat, "%s258EAFA5-E914-47DA-95CA-C5AB0DC85B11", key);
    ws_sha1(cat, strlen(cat), dig);
    ws_base64(dig, 20, want);
    const char *h = w->head;
    int ok = 0;
    while ((h = strchr(h, '\n')) != NULL) {
        h++;
        if (!strncasecmp(h, "Sec-WebSocket-Accept:", 21)) {
            const char *v = h + 21;
            v += strspn(v, " \t");
            ok = !strncmp(v, want, strlen(want)) && (v[strlen(want)] == '\r' || v[strlen(want)] == '\n');
        }
    }
    if (!ok)
        goto fail;
    return 0;
fail:
    ws_close(w);
    return -1;
}

int ws_send_frame(ws_client_t *w, unsigned first, int masked, const void *data, size_t len)
{
    size_t hl = 2 + (len >= 126 ? (len > 65535 ? 8 : 2) : 0) + (masked ? 4 : 0);
    unsigned char *f = malloc(hl + len + 1);
    if (!f)
        return -1;
    size_t o = 0;
    f[o++] = (unsigned char)first;
    unsigned char m = masked ? 0x80 : 0;
    if (len < 126) {
        f[o++] = m | (unsigned char)len;
    } else if (len <= 65535) {
        f[o++] = m | 126;
        f[o++] = (unsigned char)(len >> 8), f[o++] = (unsigned char)len;
    } else {
        f[o++] = m | 127;
        for (int k = 7; k >= 0; k--)
            f[o++] = (unsigned char)((uint64_t)len >> (8 * k));
    }
    unsigned char key[4] = {0};
    if (masked) {
        for (int k = 0; k < 4; k++)
            key[k] = (unsigned char)rand();
        memcpy(f + o, key, 4);
        o += 4;
    }
    const unsigned char *d = data;
    for (size_t i = 0; i < len; i++)
        f[o + i] = d[i] ^ key[i & 3];
    int rc = hc_send_all(w->fd, f, o + len);
    free(f);
    return rc;
}

int ws_send(ws_client_t *w, int opcode, const void *data, size_t len)
{
    return ws_send_frame(w, 0x80u | (unsigned)opcode, 1, data, len);
}

int ws_send_text(ws_client_t *w, const char *text)
{
    return ws_send(w, WS_TEXT, text, strlen(text));
}

int ws_send_raw(ws_client_t *w, const void *data, size_t len)
{
    return hc_send_all(w->fd, data, len);
}

int ws_pong(ws_client_t *w)
{
    return ws_send(w, WS_PONG, w->rd.ctl, w->rd.ctl_len);
}

void ws_msg_free(ws_msg_t *m)
{
    free(m->data);
    memset(m, 0, sizeof *m);
}

/* The message for m: the buffer's n bytes (NULL: an empty one), NUL-terminated. */
static int message(ws_msg_t *m, int opcode, unsigned char *data, size_t n)
{
    if (!data && !(data = calloc(1, 1)))
        return -1;
    m->opcode = opcode, m->data = data, m->len = n;
    return 1;
}

int ws_recv(ws_client_t *w, ws_msg_t *m, int timeout_ms)
{
    memset(m, 0, sizeof *m);
    double deadline = hc_now_ms() + timeout_ms;
    ws_reader_t *r = &w->rd;
    for (;;) {
        ws_event_t ev;
        w->pos += ws_reader_next(r, w->buf ? w->buf + w->pos : NULL, w->len - w->pos, &ev);
        if (ev.type == WS_EV_NONE) {
            int got = fill(w, deadline);
            if (got <= 0)
                return got;
        } else if (ev.type == WS_EV_HEAD) {
            if (r->opcode != WS_CONT && r->opcode < 8)
                w->msg_len = 0; /* a new message */
        } else if (ev.type == WS_EV_DATA) {
            unsigned char *b = realloc(w->msg, w->msg_len + ev.len + 1);
            if (!b)
                return -1;
            w->msg = b;
            memcpy(b + w->msg_len, ev.data, ev.len);
            w->msg_len += ev.len;
            b[w->msg_len] = 0;
        } else if (r->opcode == WS_PING) {
            ws_pong(w);
        } else if (r->opcode == WS_PONG) {
            continue;
        } else if (r->opcode >= 8) { /* close (or a reserved control opcode) */
            unsigned char *b = malloc(r->ctl_len + 1);
            if (!b)
                return -1;
            memcpy(b, r->ctl, r->ctl_len);
            b[r->ctl_len] = 0;
            w->msg_len = 0;
            return message(m, r->opcode, b, r->ctl_len);
        } else if (r->fin) {
            unsigned char *b = w->msg;
            size_t n = w->msg_len;
            if (b)
                b[n] = 0; /* (it holds n + 1 bytes or more) */
            w->msg = NULL, w->msg_len = 0;
            return message(m, r->msg_opcode, b, n);
        }
    }
}

long ws_read_raw(ws_client_t *w, void *out, size_t n, int timeout_ms)
{
    if (w->pos == w->len) {
        int r = fill(w, hc_now_ms() + timeout_ms);
        if (r <= 0)
            return r;
    }
    size_t k = n < w->len - w->pos ? n : w->len - w->pos;
    memcpy(out, w->buf + w->pos, k);
    w->pos += k;
    return (long)k;
}

unsigned char *ws_take_buffered(ws_client_t *w, size_t *n)
{
    *n = w->len - w->pos;
    unsigned char *b = w->buf;
    if (b && *n)
        memmove(b, b + w->pos, *n);
    else
        free(b), b = NULL;
    w->buf = NULL, w->pos = w->len = w->cap = 0;
    return b;
}

int ws_wait_close_frame(ws_client_t *w, int timeout_ms)
{
    double deadline = hc_now_ms() + timeout_ms;
    for (;;) {
        int left = (int)(deadline - hc_now_ms());
        if (left <= 0)
            return WS_CLOSE_TIMEOUT;
        ws_msg_t m;
        int r = ws_recv(w, &m, left);
        if (r < 0)
            return WS_CLOSE_EOF;
        if (r == 0)
            return WS_CLOSE_TIMEOUT;
        int st = -3;
        if (m.opcode == WS_CLOSE)
            st = m.len >= 2 ? (m.data[0] << 8 | m.data[1]) : 0;
        ws_msg_free(&m);
        if (st != -3)
            return st;
    }
}

int ws_wait_closed(ws_client_t *w, int timeout_ms)
{
    double deadline = hc_now_ms() + timeout_ms;
    int answered = 0;
    w->close_status = -1;
    for (;;) {
        int left = (int)(deadline - hc_now_ms());
        if (left <= 0)
            return 0;
        ws_msg_t m;
        int r = ws_recv(w, &m, left);
        if (r < 0)
            return 1; /* EOF or reset */
        if (r == 0)
            return 0;
        if (m.opcode == WS_CLOSE && !answered) {
            /* the server closes: answer as RFC 6455 5.5.1 asks, then it
             * closes the TCP connection */
            w->close_status = m.len >= 2 ? (m.data[0] << 8 | m.data[1]) : 0;
            ws_send(w, WS_CLOSE, m.data, m.len >= 2 ? 2 : 0);
            answered = 1;
        }
        ws_msg_free(&m);
    }
}

/* ---- mimic's binary /ws frames ---- */
static uint16_t le16(const unsigned char *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t le64(const unsigned char *p)
{
    return (uint64_t)le32(p) | (uint64_t)le32(p + 4) << 32;
}

float mimf_f32(const unsigned char *p)
{
    uint32_t u = le32(p);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

void mimf_decode(const unsigned char *b, size_t len, mimf_t *f)
{
    memset(f, 0, sizeof *f);
    f->version = le16(b + 4), f->flags = le16(b + 6);
    f->i16 = (f->flags & 2) != 0;
    f->number = le64(b + 8), f->t_vest = le64(b + 16), f->tmpl = le64(b + 24);
    f->n = le32(b + 32), f->L = le32(b + 36), f->compute = le32(b + 40), f->key_interval = le32(b + 44);
    f->arrival = le64(b + 48);
    memcpy(f->label, b + 56, 32);
    for (int a = 0; a < 3; a++)
        f->lo[a] = mimf_f32(b + 88 + 4 * a), f->hi[a] = mimf_f32(b + 100 + 4 * a);
    if (len >= mimf_size(f)) {
        f->pos = b + MIMF_HEADER;
        f->lm = b + mimf_size(f) - 12 * (size_t)f->L;
    }
}

size_t mimf_size(const mimf_t *f)
{
    size_t pos = f->i16 ? 6 * (size_t)f->n + 2 * (f->n & 1u) : 12 * (size_t)f->n;
    return MIMF_HEADER + pos + 12 * (size_t)f->L;
}

float mimf_x(const mimf_t *f, size_t i)
{
    if (!f->i16)
        return mimf_f32(f->pos + 4 * i);
    int a = (int)(i % 3);
    int q = (int16_t)le16(f->pos + 2 * i);
    if (f->hi[a] == f->lo[a])
        return f->lo[a];
    return (float)((double)f->lo[a] + ((double)q + 32768.0) / 65535.0 * ((double)f->hi[a] - (double)f->lo[a]));
}
