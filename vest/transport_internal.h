/* The transport object shared by transport*.c: one struct, a kind, and the
 * per-kind open/read/write/close functions. */
#ifndef MIM_VEST_TRANSPORT_INTERNAL_H
#define MIM_VEST_TRANSPORT_INTERNAL_H

#include "mim_vest_transport.h"

#include <stdio.h>

enum { MIM__T_SERIAL, MIM__T_HID, MIM__T_UDP, MIM__T_REPLAY };

#define MIM__T_BUF 65536

struct mim_vest_transport {
    int kind;
    char desc[320]; /* "serial /dev/ttyACM0", used in every message */
    mim_vest_transport_options_t o;
    uint32_t header_flags;
    /* live link state */
    int connected, restart_pending;
    uint32_t reconnects;
    double t_disconnected;
    int backoff_ms;
    /* serial */
    char path[256];
    int fd;
    /* hid */
    const mim_vest_hid_layer_t *hid;
    void *dev;
    uint16_t vid, pid;
    char serial[128];
    /* udp */
    int sock;
    /* replay */
    FILE *f;
    uint64_t offset, t0_rec;
    double t0_wall;
    int started;
    uint8_t buf[MIM__T_BUF];
};

/* Per kind: open (first time and on reconnect), read (bytes > 0, 0 when the
 * wait ran out, negative when the link failed, message in err), close. */
int mim__serial_open(mim_vest_transport_t *t, mim_error_t *err);
int mim__serial_read(mim_vest_transport_t *t, uint8_t *buf, size_t cap, int ms, mim_error_t *err);
int mim__serial_write(mim_vest_transport_t *t, const uint8_t *buf, size_t n, mim_error_t *err);
void mim__serial_close(mim_vest_transport_t *t);

int mim__hid_open(mim_vest_transport_t *t, mim_error_t *err);
int mim__hid_read(mim_vest_transport_t *t, uint8_t *buf, size_t cap, int ms, mim_error_t *err);
int mim__hid_write(mim_vest_transport_t *t, const uint8_t *buf, size_t n, mim_error_t *err);
void mim__hid_close(mim_vest_transport_t *t);

int mim__udp_open(mim_vest_transport_t *t, const char *hostport, mim_error_t *err);
int mim__udp_read(mim_vest_transport_t *t, mim_vest_chunk_t *c, mim_error_t *err);
void mim__udp_close(mim_vest_transport_t *t);

int mim__replay_open(mim_vest_transport_t *t, const char *path, mim_error_t *err);
int mim__replay_read(mim_vest_transport_t *t, mim_vest_chunk_t *c, mim_error_t *err);
void mim__replay_close(mim_vest_transport_t *t);

uint64_t mim__now_us(void);

#endif
