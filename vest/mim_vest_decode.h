/* mimic vest, reading the stream: the incremental decoder of hub (and wired
 * sensor) stream packets, and the assembler that groups decoded packets
 * into whole vest frames. The decoder is what fuzz_vest_decode exercises.
 * Implemented by protocol_decode.c (decoder) and kinematics.c (assembler).
 * Wire layout: schemas/vest-protocol.md.
 *
 * Threads: a decoder or an assembler is used by one thread at a time (no
 * internal locking); distinct ones are independent. */
#ifndef MIM_VEST_DECODE_H
#define MIM_VEST_DECODE_H

#include "mim_core.h"
#include "mim_vest_protocol.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* One accepted packet, as the callback sees it. */
typedef struct mim_vest_packet_info {
    uint64_t t_us;       /* as mim_vest_frame_t.t_us */
    uint64_t active;     /* active-sensor bitfield (1 << sensor for a wired one) */
    uint32_t serial;     /* 0 without a serial field */
    uint8_t logical_id, battery, status, buttons; /* logical_id 0 without an id field */
    uint8_t joystick[2][4];
    uint32_t length;     /* bytes of the packet, sync included */
    const uint8_t *raw;  /* those bytes, valid during the callback only */
    uint32_t timestamp;  /* the header's raw u32 timestamp (0 without one) */
} mim_vest_packet_info_t;

/* Why bytes or packets were thrown away. */
enum {
    MIM_VEST_REJ_LENGTH,        /* longer than 128 bytes, or data length field disagrees */
    MIM_VEST_REJ_HEADER,        /* success byte not 0, echo not 0xFF, or a wired id >= 64 */
    MIM_VEST_REJ_HUB_CHECKSUM,  /* hub block checksum */
    MIM_VEST_REJ_DATA_CHECKSUM, /* response header's data checksum */
    MIM_VEST_REJ_QUATERNION,    /* not finite, or norm off 1 by more than 1 % */
    MIM_VEST_REJ_COUNT
};
/* "length", "header", ...: a static string; "unknown" out of range. */
const char *mim_vest_reject_name(int reason);

typedef struct mim_vest_decoder_stats {
    uint64_t bytes;         /* fed */
    uint64_t skipped_bytes; /* not part of any accepted packet */
    uint64_t packets;       /* accepted */
    uint64_t frames;        /* sensor frames emitted */
    uint64_t rejected[MIM_VEST_REJ_COUNT];
} mim_vest_decoder_stats_t;

typedef struct mim_vest_decoder_options {
    uint32_t header_flags; /* 0 means MIM_VEST_HDR_DEFAULT; bits above 0x7F ignored */
    /* A wired sensor streaming by itself (0xDD header + slot data, no sync
     * bytes, no hub block): packets are the response header and one
     * quaternion. The frame's sensor id is the header's logical id when
     * present, else wired_sensor. Needs the checksum and echo fields to
     * resynchronise reliably; the timestamp is not covered by a checksum. */
    int wired;
    uint32_t wired_sensor;
} mim_vest_decoder_options_t;

/* Called once per accepted packet with its sensor frames (n <= 6, in
 * increasing sensor id), on the thread that called mim_vest_decoder_feed,
 * from inside that call. info, info->raw and frames are valid during the
 * call only. It must not feed, reset or close the same decoder. */
typedef void (*mim_vest_packet_fn)(void *user, const mim_vest_packet_info_t *info,
                                   const mim_vest_frame_t *frames, uint32_t n);

typedef struct mim_vest_decoder mim_vest_decoder_t;
/* Creates a decoder (malloc'd; free it with mim_vest_decoder_close). opt NULL
 * = hub stream with the default header; opt is copied. fn may be NULL (then
 * only the counters move); user is handed back to fn. Returns 0, MIM_EINVAL
 * (out NULL) or MIM_ENOMEM; *out is NULL on failure. */
int mim_vest_decoder_open(mim_vest_decoder_t **out, const mim_vest_decoder_options_t *opt, mim_vest_packet_fn fn,
                          void *user);
/* Frees it; accepts NULL and *d NULL; sets *d to NULL. */
void mim_vest_decoder_close(mim_vest_decoder_t **d);
/* Consumes n bytes in any chunking; now_us stands for the timestamp when the
 * header has none. A possible packet start cut off at the end is copied and
 * kept for the next call; bytes is not referenced after the call. Returns
 * the number of packets accepted by this call (0 if d is NULL, or bytes is
 * NULL with n > 0). Never fails on bad bytes: they are counted in the stats.
 * A timestamp that wraps (every 71.6 min) is unwrapped to 64 bits. */
uint32_t mim_vest_decoder_feed(mim_vest_decoder_t *d, const void *bytes, size_t n, uint64_t now_us);
/* Drops a held-back partial packet (after a reconnect), counting it as
 * skipped. Keeps the counters and the timestamp unwrap. NULL is a no-op. */
void mim_vest_decoder_reset(mim_vest_decoder_t *d);
/* Copies the counters into *s; does nothing if d or s is NULL. */
void mim_vest_decoder_get_stats(const mim_vest_decoder_t *d, mim_vest_decoder_stats_t *s);

/* Groups decoded packets into whole vest frames: the frame at time t is
 * done when every sensor of the previous frame has reported t, or when a
 * later timestamp arrives. Plain data: zero-initialise, nothing to free. */
typedef struct mim_vest_assembler {
    uint64_t t_us, expect, got;
    int open;      /* a frame at t_us is being filled */
    int done;      /* ... and was already reported */
} mim_vest_assembler_t;
/* Feeds one packet (a and info non-NULL, not checked); returns how many
 * frames it completed (0..2): their times and sensor masks in t_done[] /
 * mask[], oldest first. A packet older than the open frame is ignored (0).
 * The first frame of a stream can only complete when a later one starts. */
int mim_vest_assembler_push(mim_vest_assembler_t *a, const mim_vest_packet_info_t *info, uint64_t t_done[2],
                            uint64_t mask[2]);
/* At the end of a stream: 1 with the last unfinished frame (then marked
 * done), or 0. Pointers non-NULL, not checked. */
int mim_vest_assembler_flush(mim_vest_assembler_t *a, uint64_t *t_done, uint64_t *mask);

#ifdef __cplusplus
}
#endif
#endif
