/* The RFC 6455 WebSocket client of the tests of mimic serve and of
 * bench/serve: the HTTP upgrade (Sec-WebSocket-Key, 101,
 * Sec-WebSocket-Accept checked), masked client frames, server frames of any
 * length (7, 16 and 64-bit lengths, continuations joined), pings answered,
 * and raw bytes for protocol abuse. Frames are read by one incremental
 * reader (ws_reader_t): ws_recv drives it over a blocking socket with a
 * poll deadline on every read (nothing waits for ever); bench/serve feeds
 * it from its own epoll loop. Last, the header of mimic's binary /ws frames
 * (schemas/serve-ws-frame.md). Sockets come from http_client.h; no cmocka. */
#ifndef MIM_WS_CLIENT_H
#define MIM_WS_CLIENT_H

#include "http_client.h"

#include <stddef.h>
#include <stdint.h>

enum { WS_CONT = 0, WS_TEXT = 1, WS_BINARY = 2, WS_CLOSE = 8, WS_PING = 9, WS_PONG = 10 };

/* ---- the frame reader ---- */
typedef struct ws_reader {
    unsigned char hb[14];    /* the frame header being read */
    unsigned hlen, hneed;    /* bytes of it read; bytes it has (known from the second) */
    int in_payload;          /* the header is read: the payload follows */
    int opcode, fin, masked; /* of the current frame, from its WS_EV_HEAD on */
    unsigned char key[4];    /* its mask key, when masked */
    uint64_t len, got;       /* its payload length; bytes of it read */
    int msg_opcode;          /* the data message under way: WS_TEXT, WS_BINARY (0: none) */
    int msg_done;            /* its last frame has ended */
    uint64_t msg_len;        /* bytes of it read so far, over all its frames */
    unsigned char ctl[125];  /* a control frame's payload (its first 125 bytes: RFC 6455's limit) */
    size_t ctl_len;
} ws_reader_t; /* all zero: ready for a stream's first frame */

enum {
    WS_EV_NONE = 0, /* every byte given is used; nothing more until more come */
    WS_EV_HEAD,     /* a frame's header is read (r->opcode, fin, masked, len) */
    WS_EV_DATA,     /* payload bytes of a data frame (opcode < 8), unmasked */
    WS_EV_END,      /* the frame is whole (a control frame's payload is in r->ctl) */
};

typedef struct ws_event {
    int type;                  /* WS_EV_... */
    const unsigned char *data; /* WS_EV_DATA: the bytes, in the buffer given */
    size_t len;
    uint64_t offset; /* WS_EV_DATA: where they start in the message (r->msg_opcode) */
} ws_event_t;

/* Reads p[0..n) up to the next event: returns the bytes used and sets *ev
 * (WS_EV_NONE once all are used and no event is pending: call it again,
 * even with n == 0, until then). A masked payload is unmasked in place. */
size_t ws_reader_next(ws_reader_t *r, unsigned char *p, size_t n, ws_event_t *ev);

/* ---- a client connection ---- */
typedef struct ws_client {
    int fd;
    unsigned char *buf; /* bytes read: buf[pos..len) not consumed yet */
    size_t pos, len, cap;
    ws_reader_t rd;     /* reads the frames */
    unsigned char *msg; /* the data message being put together by ws_recv */
    size_t msg_len;
    int http_status;    /* of the handshake's response (0 if none came) */
    int close_status;   /* of the close frame ws_wait_closed saw (-1: none) */
    char head[4096];    /* the response's status line and headers */
} ws_client_t;

typedef struct ws_msg {
    int opcode;          /* WS_TEXT, WS_BINARY or WS_CLOSE */
    unsigned char *data; /* malloc'd, NUL-terminated (not counted in len) */
    size_t len;
} ws_msg_t;

/* Connects to 127.0.0.1:port (rcvbuf as hc_connect) and upgrades GET path.
 * Returns 0 on 101 with the right Sec-WebSocket-Accept; -1 otherwise
 * (w->http_status says what came, and the socket is closed). The bytes
 * after the response stay buffered for ws_recv or ws_read_raw. */
int ws_connect(ws_client_t *w, int port, const char *path, int rcvbuf);
/* The next whole message within timeout_ms: 1 got one (free with
 * ws_msg_free), 0 timed out, -1 the connection closed or failed (a close
 * frame is returned as a message, opcode WS_CLOSE). Pings are answered. */
int ws_recv(ws_client_t *w, ws_msg_t *m, int timeout_ms);
void ws_msg_free(ws_msg_t *m);
/* Answers the ping just read (w->rd at its WS_EV_END) with a pong of its
 * payload. 0 or -1. */
int ws_pong(ws_client_t *w);
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
/* For a caller that reads the socket itself (bench/serve's epoll loop):
 * the bytes buffered and not consumed yet (those that came with the
 * handshake), *n of them in a malloc'd buffer (NULL when none), handed
 * over: the client keeps none. */
unsigned char *ws_take_buffered(ws_client_t *w, size_t *n);
/* Reads (and drops) messages until the server's close frame, within
 * timeout_ms: its status code (0 when it has none), WS_CLOSE_EOF when the
 * connection closed without one, WS_CLOSE_TIMEOUT when neither came. */
#define WS_CLOSE_EOF (-1)
#define WS_CLOSE_TIMEOUT (-2)
int ws_wait_close_frame(ws_client_t *w, int timeout_ms);
/* 1 when the peer has closed the connection (EOF or reset) within
 * timeout_ms, reading and discarding whatever still arrives (a close frame
 * is answered, as a client must: its status goes to w->close_status, -1
 * when none came); 0 if not. */
int ws_wait_closed(ws_client_t *w, int timeout_ms);
/* Closes the socket (no close handshake) and frees the buffers. */
void ws_close(ws_client_t *w);

/* SHA-1 and base64, for Sec-WebSocket-Accept. out is 20 bytes; b64 needs
 * 4 * ceil(n / 3) + 1. */
void ws_sha1(const void *data, size_t n, unsigned char out[20]);
void ws_base64(const unsigned char *in, size_t n, char *out);

/* ---- mimic's binary /ws frames (schemas/serve-ws-frame.md) ---- */
#define MIMF_HEADER 112u /* bytes of the header */

typedef struct mimf {
    uint16_t version, flags;
    uint64_t number, t_vest, tmpl, arrival;
    uint32_t n, L, compute, key_interval;
    char label[33];
    float lo[3], hi[3];
    int i16;                       /* flags bit 1: int16 positions */
    const unsigned char *pos, *lm; /* into the message; NULL when it is shorter than mimf_size */
} mimf_t;

/* Decodes the header at msg (len bytes, at least MIMF_HEADER; the magic is
 * the caller's to check) and places positions and landmarks. */
void mimf_decode(const unsigned char *msg, size_t len, mimf_t *f);
/* The message's length by its header: header, positions, landmarks. */
size_t mimf_size(const mimf_t *f);
/* A little-endian float32. */
float mimf_f32(const unsigned char *p);
/* Coordinate i (x y z of vertex i / 3) of the positions, decoded. */
float mimf_x(const mimf_t *f, size_t i);

#endif
