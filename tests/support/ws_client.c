/* A small RFC 6455 WebSocket client for tests (ws_client.h). */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* memmem */
#endif
#include "ws_client.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

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

/* ---- sockets ---- */
int ws_tcp_connect(int port, int rcvbuf)
{
    int s = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (s < 0)
        return -1;
    if (rcvbuf > 0)
        setsockopt(s, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(s, (struct sockaddr *)&a, sizeof a)) {
        close(s);
        return -1;
    }
    return s;
}

int ws_send_all(int fd, const void *p, size_t n)
{
    const char *c = p;
    while (n) {
        ssize_t w = send(fd, c, n, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        c += w, n -= (size_t)w;
    }
    return 0;
}

/* Reads more bytes into the buffer before the deadline: 1, 0 timeout, -1 closed. */
static int fill(ws_client_t *w, double deadline)
{
    if (w->fd < 0)
        return -1;
    if (w->cap - w->len < 65536) {
        size_t cap = w->cap ? 2 * w->cap : 1 << 17;
        unsigned char *b = realloc(w->buf, cap);
        if (!b)
            return -1;
        w->buf = b, w->cap = cap;
    }
    for (;;) {
        double left = deadline - now_ms();
        if (left <= 0)
            return 0;
        struct pollfd p = {w->fd, POLLIN, 0};
        int r = poll(&p, 1, (int)left + 1);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return -1;
        if (r == 0)
            continue; /* the loop checks the deadline */
        ssize_t n = recv(w->fd, w->buf + w->len, w->cap - w->len, 0);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            return -1;
        w->len += (size_t)n;
        return 1;
    }
}

static void consume(ws_client_t *w, size_t n)
{
    memmove(w->buf, w->buf + n, w->len - n);
    w->len -= n;
}

int ws_connect(ws_client_t *w, int port, const char *path, int rcvbuf)
{
    memset(w, 0, sizeof *w);
    w->fd = ws_tcp_connect(port, rcvbuf);
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
    if (ws_send_all(w->fd, req, (size_t)n))
        goto fail;
    double deadline = now_ms() + 10000;
    unsigned char *end = NULL;
    while (!(end = w->len >= 4 ? memmem(w->buf, w->len, "\r\n\r\n", 4) : NULL))
        if (fill(w, deadline) <= 0)
            break;
    size_t hl = end ? (size_t)(end - w->buf) + 4 : w->len;
    size_t keep = hl < sizeof w->head ? hl : sizeof w->head - 1;
    memcpy(w->head, w->buf, keep);
    w->head[keep] = 0;
    if (sscanf(w->head, "HTTP/1.1 %d", &w->http_status) != 1)
        w->http_status = 0;
    if (!end || w->http_status != 101)
        goto fail;
    consume(w, hl);
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
    close(w->fd);
    w->fd = -1;
    free(w->buf);
    w->buf = NULL, w->len = w->cap = 0;
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
    int rc = ws_send_all(w->fd, f, o + len);
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
    return ws_send_all(w->fd, data, len);
}

void ws_msg_free(ws_msg_t *m)
{
    free(m->data);
    memset(m, 0, sizeof *m);
}

/* One whole frame from the buffer, if there: its header length, or 0. */
static size_t frame_ready(const ws_client_t *w, unsigned *first, uint64_t *plen)
{
    if (w->len < 2)
        return 0;
    const unsigned char *b = w->buf;
    size_t hl = 2 + ((b[1] & 0x80) ? 4 : 0);
    uint64_t n = b[1] & 0x7f;
    if (n == 126) {
        hl += 2;
        if (w->len < hl)
            return 0;
        n = (uint64_t)b[2] << 8 | b[3];
    } else if (n == 127) {
        hl += 8;
        if (w->len < hl)
            return 0;
        n = 0;
        for (int k = 0; k < 8; k++)
            n = n << 8 | b[2 + k];
    }
    if (w->len < hl || w->len - hl < n)
        return 0;
    *first = b[0], *plen = n;
    return hl;
}

int ws_recv(ws_client_t *w, ws_msg_t *m, int timeout_ms)
{
    memset(m, 0, sizeof *m);
    double deadline = now_ms() + timeout_ms;
    unsigned char *acc = NULL;
    size_t alen = 0;
    int aop = -1;
    for (;;) {
        unsigned first;
        uint64_t n;
        size_t hl = frame_ready(w, &first, &n);
        if (!hl) {
            int r = fill(w, deadline);
            if (r <= 0) {
                free(acc);
                return r;
            }
            continue;
        }
        const unsigned char *p = w->buf + hl;
        int op = (int)(first & 0x0f), fin = (first & 0x80) != 0;
        if (w->buf[1] & 0x80) { /* a masked server frame: unmask in place */
            unsigned char key[4];
            memcpy(key, w->buf + hl - 4, 4);
            for (uint64_t i = 0; i < n; i++)
                w->buf[hl + i] ^= key[i & 3];
        }
        if (op == WS_PING) {
            ws_send(w, WS_PONG, p, (size_t)n);
            consume(w, hl + (size_t)n);
            continue;
        }
        if (op == WS_PONG) {
            consume(w, hl + (size_t)n);
            continue;
        }
        if (op != WS_CONT)
            aop = op, alen = 0;
        unsigned char *na = realloc(acc, alen + (size_t)n + 1);
        if (!na) {
            free(acc);
            return -1;
        }
        acc = na;
        memcpy(acc + alen, p, (size_t)n);
        alen += (size_t)n;
        acc[alen] = 0;
        consume(w, hl + (size_t)n);
        if (fin || op == WS_CLOSE) {
            m->opcode = aop < 0 ? op : aop, m->data = acc, m->len = alen;
            return 1;
        }
    }
}

long ws_read_raw(ws_client_t *w, void *out, size_t n, int timeout_ms)
{
    if (!w->len) {
        int r = fill(w, now_ms() + timeout_ms);
        if (r <= 0)
            return r;
    }
    size_t k = n < w->len ? n : w->len;
    memcpy(out, w->buf, k);
    consume(w, k);
    return (long)k;
}

int ws_wait_closed(ws_client_t *w, int timeout_ms)
{
    double deadline = now_ms() + timeout_ms;
    for (;;) {
        w->len = 0; /* what still arrives is of no interest */
        int r = fill(w, deadline);
        if (r < 0)
            return 1;
        if (r == 0)
            return 0;
    }
}

void ws_close(ws_client_t *w)
{
    if (w->fd >= 0)
        close(w->fd);
    w->fd = -1;
    free(w->buf);
    w->buf = NULL, w->len = w->cap = 0;
}
