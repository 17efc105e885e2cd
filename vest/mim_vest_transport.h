/* mimic vest, the links: serial, HID, UDP and replay transports behind one
 * interface, recording files, the UDP landmark frame format, and the list
 * of plugged-in vests.
 * Implemented by transport.c (spec, timeouts, reconnects), transport_serial.c,
 * transport_hid.c, transport_udp.c (also the frame format), transport_replay.c
 * (also the recorder) and list.c. Formats: schemas/vest-recording.md,
 * schemas/vest-udp.schema.json; HID reports: schemas/vest-protocol.md.
 *
 * Threads: a transport or a recorder is used by one thread at a time (no
 * internal locking); distinct ones are independent, except that the hidapi
 * layer's error() shares one static buffer. */
#ifndef MIM_VEST_TRANSPORT_H
#define MIM_VEST_TRANSPORT_H

#include "mim_core.h"
#include "mim_vest_protocol.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum {
    MIM_VEST_CHUNK_STREAM = 1,   /* protocol bytes (serial, HID, replay of those) */
    MIM_VEST_CHUNK_LANDMARKS = 2 /* one UDP landmark frame, JSON text */
};

typedef struct mim_vest_chunk {
    int kind;
    uint64_t t_us;       /* host time (monotonic, us) or the recording's time */
    const uint8_t *data; /* owned by the transport: valid until the next read or close */
    size_t len;
    int restart;         /* first chunk after a reconnect: reset the decoder */
} mim_vest_chunk_t;

/* A substitutable HID device layer: the real one is hidapi's (hidraw). The
 * functions return what hidapi's do: bytes, 0 on timeout, -1 on error. */
typedef struct mim_vest_hid_layer {
    void *ctx;
    void *(*open)(void *ctx, uint16_t vid, uint16_t pid, const char *serial);
    int (*read_timeout)(void *ctx, void *dev, uint8_t *buf, size_t len, int ms);
    int (*write)(void *ctx, void *dev, const uint8_t *buf, size_t len);
    void (*close)(void *ctx, void *dev);
    const char *(*error)(void *ctx, void *dev); /* dev may be NULL; may return NULL */
} mim_vest_hid_layer_t;
/* hidapi's layer: a static table, valid for the whole process. Its open
 * calls hid_init, its close hid_exit; its error() returns a static buffer,
 * valid until the next call from any thread. */
const mim_vest_hid_layer_t *mim_vest_hid_layer_hidapi(void);
/* HID report: byte 0 = count of stream bytes that follow (0..63). */
#define MIM_VEST_HID_REPORT 64u

/* Zero-initialise: every 0 means the default. Copied by open. */
typedef struct mim_vest_transport_options {
    int timeout_ms;          /* a read waits this long for data; 0 = 1000 */
    int realtime;            /* replay: keep the recorded timing */
    int no_reconnect;        /* live transports: fail at the first disconnect */
    int reconnect_limit_ms;  /* give up after this long unplugged; 0 = 10000 */
    int backoff_min_ms;      /* 0 = 20 */
    int backoff_max_ms;      /* 0 = 1000 */
    const mim_vest_hid_layer_t *hid; /* NULL = hidapi; kept: must outlive the transport */
    uint32_t header_flags;   /* response header of live streams; 0 = default */
    mim_log_fn log;          /* a lost and a regained link, one line each; NULL = quiet */
    void *log_ctx;           /* handed to log */
} mim_vest_transport_options_t;

typedef struct mim_vest_transport mim_vest_transport_t;
/* spec: serial:PATH | hid:VID:PID[:SERIAL] (hex) | udp:HOST:PORT (listen) |
 * replay:FILE (or a plain path to a recording); copied, not kept. opt NULL =
 * defaults. The device must be there now: open does not wait or retry.
 * Creates the transport (malloc'd; free it with mim_vest_transport_close).
 * Returns 0, or: MIM_EINVAL (out or spec NULL, serial: without a path, a bad
 * hid: spec, udp: not HOST:PORT or not resolvable); MIM_ENOMEM; serial: the
 * open, tcgetattr or tcsetattr -errno (-ENOENT, -ENODEV, -ENXIO, -EIO: not
 * plugged in; -EACCES); hid: -ENODEV; udp: socket or bind -errno; replay:
 * fopen -errno, MIM_EFORMAT (no MIMVEST1 header), MIM_EUNSUPPORTED (another
 * version). *out is NULL on failure. */
int mim_vest_transport_open(mim_vest_transport_t **out, const char *spec, const mim_vest_transport_options_t *opt,
                            mim_error_t *err);
/* Closes the link and frees it; accepts NULL and *t NULL; sets *t to NULL. */
void mim_vest_transport_close(mim_vest_transport_t **t);
/* Waits for the next chunk (lent: see mim_vest_chunk_t). Returns 1 with a
 * chunk; MIM_EINVAL if t or chunk is NULL; otherwise, by kind:
 *  - serial, HID: -ETIMEDOUT after timeout_ms without data (also while
 *    reconnecting: the next read carries on); -ENODEV once the device stayed
 *    unplugged past reconnect_limit_ms; with no_reconnect, the failed read's
 *    code (-ENODEV, or a poll/read -errno) and -ENODEV from then on. A lost
 *    link is closed and reopened with doubling waits inside the read; the
 *    loss and the reconnection are reported through opt->log.
 *  - udp: one datagram per chunk; -ETIMEDOUT after timeout_ms; poll/recv
 *    -errno. Never 0.
 *  - replay: 0 at the end of the file; MIM_EIO, MIM_ETRUNCATED (a record cut
 *    short), MIM_EFORMAT (a bad record); never times out; with realtime it
 *    sleeps until each record is due.
 * err says what and where. */
int mim_vest_transport_read(mim_vest_transport_t *t, mim_vest_chunk_t *chunk, mim_error_t *err);
/* Sends command bytes to the device (serial, HID, in 63-byte reports);
 * replay and UDP ignore them and return 0. Returns 0 when all bytes went;
 * MIM_EINVAL (t NULL); -ENODEV (unplugged, not yet reconnected); serial:
 * -ETIMEDOUT (the port took nothing for timeout_ms), write -errno; HID: -EIO. */
int mim_vest_transport_write(mim_vest_transport_t *t, const void *data, size_t len, mim_error_t *err);
/* The response header flags to decode with: opt->header_flags (0 = default)
 * for serial, HID and UDP, the recording's own for replay; 0 for NULL. */
uint32_t mim_vest_transport_header_flags(const mim_vest_transport_t *t);
/* Successful reconnections so far (0 for NULL). */
uint32_t mim_vest_transport_reconnects(const mim_vest_transport_t *t);
/* 0 while a serial or HID vest is unplugged (between a failed read and its
 * reconnection), and for NULL; 1 otherwise. */
int mim_vest_transport_connected(const mim_vest_transport_t *t);
/* 1 for serial and HID (they take commands); 0 otherwise and for NULL. */
int mim_vest_transport_is_device(const mim_vest_transport_t *t);

/* ---- recording files (schemas/vest-recording.md), transport_replay.c ---- */
typedef struct mim_vest_recorder mim_vest_recorder_t;
/* Creates or truncates path (written in place, not atomically) with the file
 * header (header_flags 0 = default); the recorder is malloc'd, free it with
 * mim_vest_recorder_close. out and path must not be NULL (not checked).
 * Returns 0, MIM_ENOMEM, or -errno (cannot create, header write); *out is
 * NULL on failure. */
int mim_vest_recorder_open(mim_vest_recorder_t **out, const char *path, uint32_t header_flags, mim_error_t *err);
/* Appends one chunk (copied; stdio-buffered, so a failure may only show at
 * close). Returns 0; MIM_EINVAL (r or chunk NULL, data NULL with len > 0,
 * len over 65536); -errno (or -EIO) on a write error, which close reports
 * again. */
int mim_vest_recorder_write(mim_vest_recorder_t *r, const mim_vest_chunk_t *chunk, mim_error_t *err);
/* Flushes, fsyncs and closes; returns 0, the flush/fsync/fclose -errno, or
 * the first write error. Always frees the recorder and sets *r to NULL;
 * accepts NULL and *r NULL (0). */
int mim_vest_recorder_close(mim_vest_recorder_t **r, mim_error_t *err);

/* ---- UDP landmark frames (schemas/vest-udp.schema.json), transport_udp.c ----
 * {"t": us, "landmarks": [[x, y, z] | null, ...]}, optionally with
 * "orientations": {"pelvis": [x, y, z, w] | null, ...} (the 17 segments'
 * rotations from the avatar's rest pose). All are thread-safe. */
/* Parses one frame of at most max landmarks into t_us, xyz (3 * max floats)
 * and present (max bytes), all non-NULL (not checked); a null landmark is NaN
 * with present 0. text need not be NUL-terminated. Returns 0 with *count set, or MIM_EFORMAT (not
 * JSON, a duplicate key, "t" not an integer >= 0, no "landmarks" array, more
 * than max, a landmark not [x, y, z] of numbers), or MIM_ENONFINITE (a
 * coordinate that is not a finite float), as mim_landmark_array_parse, or
 * bad "orientations" (mim_orientations_parse's codes: checked even here,
 * where they are dropped); the outputs may then be partly written. */
int mim_vest_udp_parse(const char *text, size_t len, uint64_t *t_us, float *xyz, uint8_t *present, uint32_t max,
                       uint32_t *count, mim_error_t *err);
/* The same, keeping the orientations: *has_orient 1 when the frame has the
 * object, and R / have then hold the 17 segments (normalised; identity and
 * 0 where null or absent; all identity and 0 without the object). R, have
 * and has_orient may each be NULL. */
int mim_vest_udp_parse_orient(const char *text, size_t len, uint64_t *t_us, float *xyz, uint8_t *present,
                              uint32_t max, uint32_t *count, mim_quat R[MIM_SEGMENTS], uint8_t have[MIM_SEGMENTS],
                              int *has_orient, mim_error_t *err);
/* Formats one frame: a malloc'd NUL-terminated string the caller frees with
 * free(); NULL on allocation failure. Coordinates of present landmarks must
 * be finite (not checked). Numbers keep 9 significant digits. */
char *mim_vest_udp_format(uint64_t t_us, const float *xyz, const uint8_t *present, uint32_t count);
/* The same with "orientations" beside the landmarks when R is not NULL:
 * every segment in mim_segment_names order, null where have[s] is 0 (have
 * NULL: all given). R's quaternions should be unit (not checked; a reader
 * refuses a norm off 1 by more than MIM_ORIENT_UNIT_TOL). */
char *mim_vest_udp_format_orient(uint64_t t_us, const float *xyz, const uint8_t *present, uint32_t count,
                                 const mim_quat R[MIM_SEGMENTS], const uint8_t have[MIM_SEGMENTS]);

/* ---- devices that look like vests (list.c) ---- */
typedef struct mim_vest_device {
    char spec[300];  /* serial:/dev/ttyACM0 or hid:2476:1040[:SERIAL] */
    char what[200];  /* product string or sysfs description */
} mim_vest_device_t;
/* Serial ports /dev/ttyACM* and /dev/ttyUSB* whose USB vendor id is 0x2476,
 * read from sysfs under sysfs_root (NULL = "/sys"), then, when list_hid is
 * non-zero, HID devices of that vendor enumerated through hidapi itself
 * (hid_init ... hid_exit; the substitutable HID layer is not used). Fills
 * out[0 .. n-1] and returns n, the number found (0..max). It does not fail
 * today: an unreadable sysfs or hidapi finds nothing, and err is unused. */
int mim_vest_list(mim_vest_device_t *out, int max, const char *sysfs_root, int list_hid, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
