/* The HTTP/1.1 client of the tests of mimic serve and of bench/serve: one
 * request per connection to 127.0.0.1 (Connection: close), the reply read
 * until the server closes, and raw bytes for the hostile-client tests
 * (malformed requests, short or oversized bodies, half-sent requests). The
 * sockets under ws_client.h too. Blocking sockets with a poll deadline on
 * every read; no cmocka: callers assert what they need. */
#ifndef MIM_HTTP_CLIENT_H
#define MIM_HTTP_CLIENT_H

#include <stddef.h>

#define HC_FOREVER (-1) /* a timeout that never ends */

/* What hc_request, hc_raw and hc_read_reply return. */
enum {
    HC_OK = 0,
    HC_ECONNECT = -1, /* no connection (errno says why); nothing was read */
    HC_ESEND = -2,    /* the server stopped taking the request; what it said is read */
    HC_ENOMEM = -3,
};

typedef struct hc_reply {
    int status;     /* of the status line "HTTP/1.x NNN"; 0 when none came */
    char *raw;      /* all that came (malloc'd, NUL-terminated) */
    size_t raw_len;
    char *head;     /* the status line and headers without the blank line after them
                       (malloc'd, NUL-terminated); NULL when no blank line came */
    char *body;     /* into raw: what follows the blank line (raw's end when none came) */
    size_t len;     /* of body */
} hc_reply_t;

/* CLOCK_MONOTONIC in milliseconds: the clock of every deadline here. */
double hc_now_ms(void);
/* A TCP connection to 127.0.0.1:port (rcvbuf > 0: SO_RCVBUF set before
 * connect); -1 on failure, with errno saying why. */
int hc_connect(int port, int rcvbuf);
/* Sends all n bytes (no SIGPIPE); 0, or -1 when the peer is gone (or a
 * non-blocking socket is full). */
int hc_send_all(int fd, const void *p, size_t n);
/* Up to n bytes from fd before deadline (hc_now_ms() terms; < 0: none):
 * the count, 0 when the deadline passed first, -1 on EOF or an error. */
long hc_recv(int fd, void *buf, size_t n, double deadline);

/* One request on a fresh connection: "METHOD PATH HTTP/1.1", Host,
 * Connection: close, the extra header lines (each ending in \r\n; NULL:
 * none), Content-Length when there is a body (body not NULL) unless the
 * extra lines give one, the blank line, then the body. The client then
 * reads the reply until the server closes (as Connection: close asks) or
 * timeout_ms passes (HC_FOREVER: no limit), without half-closing first as
 * browsers do not either (libwebsockets 4.1 takes a half-close after a
 * request body for the client hanging up). *r is filled (free with
 * hc_reply_free) unless HC_ECONNECT or HC_ENOMEM is returned. */
int hc_request(hc_reply_t *r, int port, const char *method, const char *path, const char *headers,
               const void *body, size_t len, int timeout_ms);
/* The n bytes of req sent as they are, then a half-close (the client has
 * nothing more to say), then the reply read as above. */
int hc_raw(hc_reply_t *r, int port, const void *req, size_t n, int timeout_ms);
/* Reads a reply on an open connection until the server closes it (EOF or
 * a reset after what arrived) or timeout_ms passes: HC_OK or HC_ENOMEM. */
int hc_read_reply(hc_reply_t *r, int fd, int timeout_ms);
void hc_reply_free(hc_reply_t *r);

#endif
