/* A small RFC 6455 WebSocket client for the tests of mimic serve: the HTTP
 * upgrade (Sec-WebSocket-Key, 101, Sec-WebSocket-Accept checked), masked
 * client frames, server frames of any length (7, 16 and 64-bit lengths,
 * continuations joined), pings answered, and raw bytes for protocol abuse.
 * Blocking sockets with a poll deadline on every read: nothing waits for
 * ever. */
#ifndef MIM_WS_CLIENT_H
#define MIM_WS_CLIENT_H

#include <stddef.h>
#include <stdint.h>

enum { WS_CONT = 0, WS_TEXT = 1, WS_BINARY = 2, WS_CLOSE = 8, WS_PING = 9, WS_PONG = 10 };

typedef struct ws_client {
    int fd;
    unsigned char *buf; /* bytes read but not consumed yet */
    size_t len, cap;
    int http_status;    /* of the handshake's response (0 if none came) */
    char head[4096];    /* the response's status line and headers */
} ws_client_t;

typedef struct ws_msg {
    int opcode;          /* WS_TEXT, WS_BINARY or WS_CLOSE */
    unsigned char *data; /* malloc'd, NUL-terminated (not counted in len) */
    size_t len;
} ws_msg_t;

/* A TCP connection to 127.0.0.1:port (rcvbuf > 0: SO_RCVBUF set before
 * connect); -1 on failure. */
int ws_tcp_connect(int port, int rcvbuf);
/* Connects and upgrades GET path. Returns 0 on 101 with the right
 * Sec-WebSocket-Accept; -1 otherwise (w->http_status says what came, and
 * the socket is closed). */
int ws_connect(ws_client_t *w, int port, const char *path, int rcvbuf);
/* The next whole message within timeout_ms: 1 got one (free with
 * ws_msg_free), 0 timed out, -1 the connection closed or failed (a close
 * frame is returned as a message, opcode WS_CLOSE). Pings are answered. */
int ws_recv(ws_client_t *w, ws_msg_t *m, int timeout_ms);
void ws_msg_free(ws_msg_t *m);
/* One frame: fin and opcode in the first byte as given (first = 0x80 |
 * opcode for a normal one), payload masked when masked is set. 0 or -1. */
int ws_send_frame(ws_client_t *w, unsigned first, int masked, const void *data, size_t len);
/* A whole masked message (FIN set). */
int ws_send(ws_client_t *w, int opcode, const void *data, size_t len);
int ws_send_text(ws_client_t *w, const char *text);
/* Arbitrary bytes on the socket. */
int ws_send_raw(ws_client_t *w, const void *data, size_t len);
/* Up to n raw bytes of the stream (buffered ones first) within timeout_ms:
 * the count read, 0 on timeout, -1 on close. */
long ws_read_raw(ws_client_t *w, void *out, size_t n, int timeout_ms);
/* 1 when the peer has closed the connection (EOF or reset) within
 * timeout_ms, reading and discarding whatever still arrives; 0 if not. */
int ws_wait_closed(ws_client_t *w, int timeout_ms);
/* Closes the socket (no close handshake) and frees the buffer. */
void ws_close(ws_client_t *w);

/* SHA-1 and base64, for Sec-WebSocket-Accept. out is 20 bytes; b64 needs
 * 4 * ceil(n / 3) + 1. */
void ws_sha1(const void *data, size_t n, unsigned char out[20]);
void ws_base64(const unsigned char *in, size_t n, char *out);

/* Sends all n bytes on a socket (no SIGPIPE); 0, or -1 when the peer is gone. */
int ws_send_all(int fd, const void *p, size_t n);

#endif
