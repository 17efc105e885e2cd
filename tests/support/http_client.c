/* The HTTP/1.1 client of the serve tests and bench/serve (http_client.h). */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* strndup */
#endif
#include "http_client.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

double hc_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

int hc_connect(int port, int rcvbuf)
{
    int s = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (s < 0)
        return -1;
    if (rcvbuf > 0)
        setsockopt(s, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(s, (struct sockaddr *)&a, sizeof a)) {
        int e = errno;
        close(s);
        errno = e;
        return -1;
    }
    return s;
}

int hc_send_all(int fd, const void *p, size_t n)
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

long hc_recv(int fd, void *buf, size_t n, double deadline)
{
    for (;;) {
        int wait = -1;
        if (deadline >= 0) {
            double left = deadline - hc_now_ms();
            if (left <= 0)
                return 0;
            wait = (int)left + 1;
        }
        struct pollfd p = {fd, POLLIN, 0};
        int r = poll(&p, 1, wait);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return -1;
        if (r == 0)
            continue; /* the loop checks the deadline */
        ssize_t k = recv(fd, buf, n, 0);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        return (long)k;
    }
}

int hc_read_reply(hc_reply_t *r, int fd, int timeout_ms)
{
    memset(r, 0, sizeof *r);
    double deadline = timeout_ms < 0 ? -1.0 : hc_now_ms() + timeout_ms;
    size_t cap = 65536, got = 0;
    char *buf = malloc(cap);
    if (!buf)
        return HC_ENOMEM;
    for (;;) {
        if (got + 1 == cap) {
            char *nb = realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                return HC_ENOMEM;
            }
            buf = nb, cap *= 2;
        }
        long k = hc_recv(fd, buf + got, cap - 1 - got, deadline);
        if (k <= 0)
            break; /* closed (EOF, or a reset after what arrived), or out of time */
        got += (size_t)k;
    }
    buf[got] = 0;
    r->raw = buf, r->raw_len = got;
    if (sscanf(buf, "HTTP/1.%*d %d", &r->status) != 1)
        r->status = 0;
    char *end = strstr(buf, "\r\n\r\n");
    if (end && !(r->head = strndup(buf, (size_t)(end - buf)))) {
        hc_reply_free(r);
        return HC_ENOMEM;
    }
    r->body = end ? end + 4 : buf + got;
    r->len = got - (size_t)(r->body - buf);
    return HC_OK;
}

/* Sends the parts (n of them; a NULL part is skipped) on a fresh
 * connection, half-closes if asked and reads the reply. */
static int exchange(hc_reply_t *r, int port, const void *const *part, const size_t *size, int n, int half_close,
                    int timeout_ms)
{
    memset(r, 0, sizeof *r);
    int fd = hc_connect(port, 0);
    if (fd < 0)
        return HC_ECONNECT;
    int rc = HC_OK;
    for (int i = 0; i < n && rc == HC_OK; i++)
        if (part[i] && hc_send_all(fd, part[i], size[i]))
            rc = HC_ESEND; /* the server may close early: what it said is read below */
    if (half_close)
        shutdown(fd, SHUT_WR); /* the server sees the end of what we send */
    int rr = hc_read_reply(r, fd, timeout_ms);
    close(fd);
    return rr ? rr : rc;
}

int hc_raw(hc_reply_t *r, int port, const void *req, size_t n, int timeout_ms)
{
    const void *part[1] = {req};
    return exchange(r, port, part, &n, 1, 1, timeout_ms);
}

int hc_request(hc_reply_t *r, int port, const char *method, const char *path, const char *headers,
               const void *body, size_t len, int timeout_ms)
{
    memset(r, 0, sizeof *r);
    char length[48] = "";
    if (body && !(headers && strstr(headers, "Content-Length")))
        snprintf(length, sizeof length, "Content-Length: %zu\r\n", len);
    static const char fmt[] = "%s %s HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n%s%s\r\n";
    int n = snprintf(NULL, 0, fmt, method, path, port, headers ? headers : "", length);
    char *head = n < 0 ? NULL : malloc((size_t)n + 1);
    if (!head)
        return HC_ENOMEM;
    snprintf(head, (size_t)n + 1, fmt, method, path, port, headers ? headers : "", length);
    const void *part[2] = {head, body};
    size_t size[2] = {(size_t)n, len};
    int rc = exchange(r, port, part, size, 2, 0, timeout_ms);
    free(head);
    return rc;
}

void hc_reply_free(hc_reply_t *r)
{
    free(r->raw);
    free(r->head);
    memset(r, 0, sizeof *r);
}
