/* mimic vest: the PrioVR / YOST 3-Space streaming protocol, transports
 * (serial, HID, replay, UDP), calibration and forward kinematics from sensor
 * orientations to the avatar's landmarks, and a simulated vest.
 *
 * Computation and I/O only: this module never opens the template store.
 * Wire layout: schemas/vest-protocol.md; recording files:
 * schemas/vest-recording.md; UDP landmark frames: schemas/vest-udp.schema.json.
 *
 * Frames: metres, +Y up, the body faces +Z, its own left is +X (as synth and
 * mh-bodies). A sensor's tared orientation is the rotation of its body
 * segment, in that world frame, since the moment of the tare. */
#ifndef MIM_VEST_H
#define MIM_VEST_H

#include "mim_core.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------------
 * Protocol constants (YOST 3-Space user's manual; VRPN's PrioVR driver)
 * ---------------------------------------------------------------------- */
#define MIM_VEST_VENDOR_ID 0x2476u
#define MIM_VEST_BAUD 115200
#define MIM_VEST_MAX_PACKET 128u  /* a hub stream packet never exceeds this */
#define MIM_VEST_HUB_BLOCK 20u    /* battery .. active bitfield, checksum */
#define MIM_VEST_SLOT_BYTES 16u   /* command 0x00: x y z w, big-endian float32 */
#define MIM_VEST_MAX_IDS 64u      /* bits of the active-sensor bitfield */

/* Response header bits (commands 0xDD wired / 0xDB wireless); the fields
 * follow in this bit order. */
enum {
    MIM_VEST_HDR_SUCCESS = 0x01,   /* u8, 0 = success */
    MIM_VEST_HDR_TIMESTAMP = 0x02, /* u32 BE, microseconds */
    MIM_VEST_HDR_ECHO = 0x04,      /* u8 command echo, 0xFF for streamed data */
    MIM_VEST_HDR_CHECKSUM = 0x08,  /* u8 additive checksum of the data */
    MIM_VEST_HDR_ID = 0x10,        /* u8 logical id */
    MIM_VEST_HDR_SERIAL = 0x20,    /* u32 BE serial number */
    MIM_VEST_HDR_LENGTH = 0x40,    /* u8 data length */
    MIM_VEST_HDR_ALL = 0x7F
};
/* timestamp, echo, checksum, logical id, length: 8 header bytes, so a packet
 * holds 6 sensors (3 + 8 + 20 + 6 * 16 = 127 bytes). */
#define MIM_VEST_HDR_DEFAULT 0x5Eu

/* Logical ids of the PrioVR hub. */
enum { MIM_VEST_ID_HUB = 0xF0, MIM_VEST_ID_BROADCAST = 0xF1, MIM_VEST_ID_BASE = 0xFE };

/* Commands. */
enum {
    MIM_VEST_CMD_TARED_QUAT = 0x00,
    MIM_VEST_CMD_SET_SLOTS = 0x50,
    MIM_VEST_CMD_SET_TIMING = 0x52,
    MIM_VEST_CMD_START = 0x55,
    MIM_VEST_CMD_STOP = 0x56,
    MIM_VEST_CMD_TARE = 0x60,
    MIM_VEST_CMD_HEADER_WIRELESS = 0xDB,
    MIM_VEST_CMD_HEADER_WIRED = 0xDD
};

/* Bytes of a response header with these field bits (bits above 0x40 ignored). */
size_t mim_vest_header_size(uint32_t header_flags);
/* Sensors one hub packet can carry with this header (<= 6). */
uint32_t mim_vest_hub_capacity(uint32_t header_flags);

/* ------------------------------------------------------------------------
 * Encoder (protocol_encode.c)
 * ---------------------------------------------------------------------- */
/* How a command reaches a device: wired (0xF7/0xF9) or through the dongle to
 * a logical id (0xF8/0xFA); want_header asks for a response header. */
typedef struct mim_vest_link {
    int wireless;
    uint8_t logical_id;
    int want_header;
} mim_vest_link_t;

/* Writes one command packet into buf. Checksum: (command + argument bytes)
 * % 256 wired; the logical id is added too through the dongle. Returns its
 * length, or 0 if cap is too small (link NULL = wired, no header). */
size_t mim_vest_encode_command(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint8_t command,
                               const uint8_t *args, size_t n_args);
size_t mim_vest_cmd_set_slots(uint8_t *buf, size_t cap, const mim_vest_link_t *link, const uint8_t slots[8]);
/* interval, duration and delay in microseconds (duration 0xFFFFFFFF = forever). */
size_t mim_vest_cmd_set_timing(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t interval_us,
                               uint32_t duration_us, uint32_t delay_us);
size_t mim_vest_cmd_start(uint8_t *buf, size_t cap, const mim_vest_link_t *link);
size_t mim_vest_cmd_stop(uint8_t *buf, size_t cap, const mim_vest_link_t *link);
size_t mim_vest_cmd_tare(uint8_t *buf, size_t cap, const mim_vest_link_t *link);
/* 0xDD (wired link) or 0xDB (wireless link) with the field bits as u32 BE. */
size_t mim_vest_cmd_set_header(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t header_flags);
/* The command sequence that starts a PrioVR stream of tared quaternions:
 * response header, slots (0x00, then empty), timing, start. Returns bytes. */
size_t mim_vest_cmd_stream_setup(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t header_flags,
                                 uint32_t interval_us);

/* One hub stream packet: the sensors whose bits are set in `active`, in
 * increasing id order, with their quaternions (x y z w) in q. */
typedef struct mim_vest_hub_packet {
    uint32_t header_flags; /* 0 means MIM_VEST_HDR_DEFAULT */
    uint32_t timestamp_us;
    uint32_t serial;
    uint8_t logical_id;    /* the hub sends MIM_VEST_ID_HUB */
    uint8_t battery, status, buttons;
    uint8_t joystick[2][4];
    uint64_t active;
    const float (*q)[4];
} mim_vest_hub_packet_t;

/* Encodes one packet: sync 00 FF FF, response header, hub block, slot data.
 * Returns its length, or 0 if it would exceed MIM_VEST_MAX_PACKET or cap. */
size_t mim_vest_encode_hub_packet(uint8_t *buf, size_t cap, const mim_vest_hub_packet_t *p);
/* Encodes one packet of a wired sensor's own stream: the response header
 * (header_flags, 0 = default) and the quaternion. Returns its length or 0. */
size_t mim_vest_encode_wired_packet(uint8_t *buf, size_t cap, uint32_t header_flags, uint32_t timestamp_us,
                                    uint8_t logical_id, const float q[4]);

/* ------------------------------------------------------------------------
 * Decoder (protocol_decode.c): feed bytes in any chunking.
 * ---------------------------------------------------------------------- */
typedef struct mim_vest_frame {
    uint64_t t_us;   /* header timestamp unwrapped to 64 bits, else host time */
    uint32_t sensor; /* bit index in the active-sensor bitfield */
    float q[4];      /* tared orientation x y z w */
    uint8_t status;  /* hub status byte */
} mim_vest_frame_t;

typedef struct mim_vest_packet_info {
    uint64_t t_us;
    uint64_t active;
    uint32_t serial;
    uint8_t logical_id, battery, status, buttons;
    uint8_t joystick[2][4];
    uint32_t length;     /* bytes of the packet, sync included */
    const uint8_t *raw;  /* those bytes, valid during the callback */
    uint32_t timestamp;  /* the header's raw u32 timestamp (0 without one) */
} mim_vest_packet_info_t;

/* Why bytes or packets were thrown away. */
enum {
    MIM_VEST_REJ_LENGTH,        /* longer than 128 bytes, or data length field disagrees */
    MIM_VEST_REJ_HEADER,        /* success byte not 0, or echo not 0xFF */
    MIM_VEST_REJ_HUB_CHECKSUM,  /* hub block checksum */
    MIM_VEST_REJ_DATA_CHECKSUM, /* response header's data checksum */
    MIM_VEST_REJ_QUATERNION,    /* not finite, or norm off 1 by more than 1 % */
    MIM_VEST_REJ_COUNT
};
const char *mim_vest_reject_name(int reason);

typedef struct mim_vest_decoder_stats {
    uint64_t bytes;         /* fed */
    uint64_t skipped_bytes; /* not part of any accepted packet */
    uint64_t packets;       /* accepted */
    uint64_t frames;        /* sensor frames emitted */
    uint64_t rejected[MIM_VEST_REJ_COUNT];
} mim_vest_decoder_stats_t;

typedef struct mim_vest_decoder_options {
    uint32_t header_flags; /* 0 means MIM_VEST_HDR_DEFAULT */
    /* A wired sensor streaming by itself (0xDD header + slot data, no sync
     * bytes, no hub block): packets are the response header and one
     * quaternion. The frame's sensor id is the header's logical id when
     * present, else wired_sensor. Needs the checksum and echo fields to
     * resynchronise reliably; the timestamp is not covered by a checksum. */
    int wired;
    uint32_t wired_sensor;
} mim_vest_decoder_options_t;

/* Called once per accepted packet with its sensor frames (n <= 6); frames
 * are valid during the call. */
typedef void (*mim_vest_packet_fn)(void *user, const mim_vest_packet_info_t *info,
                                   const mim_vest_frame_t *frames, uint32_t n);

typedef struct mim_vest_decoder mim_vest_decoder_t;
int mim_vest_decoder_open(mim_vest_decoder_t **out, const mim_vest_decoder_options_t *opt, mim_vest_packet_fn fn,
                          void *user);
void mim_vest_decoder_close(mim_vest_decoder_t **d);
/* Consumes n bytes; now_us stands for the timestamp when the header has
 * none. Returns the number of packets accepted. Never fails on bad bytes. */
uint32_t mim_vest_decoder_feed(mim_vest_decoder_t *d, const void *bytes, size_t n, uint64_t now_us);
/* Drops a partial packet (after a reconnect). Keeps the counters. */
void mim_vest_decoder_reset(mim_vest_decoder_t *d);
void mim_vest_decoder_get_stats(const mim_vest_decoder_t *d, mim_vest_decoder_stats_t *s);

/* ------------------------------------------------------------------------
 * Segments, sensors and the skeleton (skeleton.c)
 * ---------------------------------------------------------------------- */
/* The PrioVR full-body kit: 17 sensors, one per segment; sensor id = the
 * bit index in the hub's active-sensor bitfield = this enum. */
enum {
    MIM_VEST_PELVIS, MIM_VEST_CHEST, MIM_VEST_HEAD,
    MIM_VEST_L_SHOULDER, MIM_VEST_R_SHOULDER,
    MIM_VEST_L_UPPERARM, MIM_VEST_R_UPPERARM,
    MIM_VEST_L_FOREARM, MIM_VEST_R_FOREARM,
    MIM_VEST_L_HAND, MIM_VEST_R_HAND,
    MIM_VEST_L_THIGH, MIM_VEST_R_THIGH,
    MIM_VEST_L_SHIN, MIM_VEST_R_SHIN,
    MIM_VEST_L_FOOT, MIM_VEST_R_FOOT,
    MIM_VEST_SEGMENTS
};
const char *mim_vest_segment_name(uint32_t s); /* "pelvis", ..., NULL past the end */
int mim_vest_segment_parent(uint32_t s);       /* -1 for the pelvis and out of range */

/* A skeleton estimated from the avatar in its rest pose. */
typedef struct mim_vest_skeleton {
    mim_vec3 pivot[MIM_VEST_SEGMENTS]; /* the joint centre the segment turns about */
    mim_vec3 end[MIM_VEST_SEGMENTS];   /* its distal end */
    double length[MIM_VEST_SEGMENTS];  /* |end - pivot| */
    uint32_t n_landmarks;
    uint32_t segment[MIM_LANDMARKS_MAX];  /* the segment that carries each landmark */
    mim_vec3 landmark[MIM_LANDMARKS_MAX]; /* rest positions */
    mim_vec3 centre[MIM_LANDMARKS_MAX];   /* joint centre estimated under each landmark */
} mim_vest_skeleton_t;

/* Joint centres under the landmarks (midpoint of the chord along the inward
 * normal, bounded per landmark), then pivots and bone lengths. The map needs
 * the 16 default names; other landmarks go to the nearest bone. */
int mim_vest_skeleton_estimate(mim_vest_skeleton_t *sk, const mim_mesh_t *avatar, const mim_landmark_map_t *map,
                               mim_error_t *err);

/* ------------------------------------------------------------------------
 * Calibration (calibrate.c) and forward kinematics (kinematics.c)
 * ---------------------------------------------------------------------- */
enum {
    MIM_VEST_POSE_REST = 0, /* the wearer stands as the avatar mesh does */
    MIM_VEST_POSE_T,        /* arms straight out sideways */
    MIM_VEST_POSE_A         /* arms straight, 45 degrees from vertical */
};

typedef struct mim_vest_calib_options {
    int pose; /* MIM_VEST_POSE_*; 0 = rest */
} mim_vest_calib_options_t;

/* Everything forward kinematics needs; plain data. */
typedef struct mim_vest_rig {
    mim_vec3 root;                            /* pelvis pivot (IMUs give no translation) */
    mim_vec3 joint[MIM_VEST_SEGMENTS];        /* pivot - parent pivot, rest frame */
    mim_quat calib[MIM_VEST_SEGMENTS];        /* segment rotation rest -> calibration pose */
    mim_quat tare_inv[MIM_VEST_SEGMENTS];     /* inverse of the reading at the tare (software tare) */
    uint32_t n_landmarks;
    uint32_t segment[MIM_LANDMARKS_MAX];
    mim_vec3 offset[MIM_LANDMARKS_MAX];       /* landmark - pivot, in its bone's rest frame */
} mim_vest_rig_t;

/* Builds the rig for a wearer standing in opt->pose at the tare. tare: the
 * 17 readings at that moment for a software tare, or NULL when the device
 * was tared (command 0x60). */
int mim_vest_calibrate(mim_vest_rig_t *rig, const mim_vest_skeleton_t *sk, const mim_vest_calib_options_t *opt,
                       const mim_quat tare[MIM_VEST_SEGMENTS], mim_error_t *err);

/* Live state: the latest orientation of each sensor and when it came. */
typedef struct mim_vest_state {
    mim_quat q[MIM_VEST_SEGMENTS];
    uint64_t t_us[MIM_VEST_SEGMENTS];
    uint8_t seen[MIM_VEST_SEGMENTS];
} mim_vest_state_t;
void mim_vest_state_reset(mim_vest_state_t *st);
void mim_vest_state_update(mim_vest_state_t *st, const mim_vest_frame_t *f); /* ignores ids >= 17 */

#define MIM_VEST_TIMEOUT_US_DEFAULT 250000u

/* Landmarks at now_us from the latest orientations: a sensor silent for
 * more than timeout_us (0 = default) makes the landmarks of its segment and
 * of the segments below it missing: NaN and present 0. xyz: 3 * n_landmarks.
 * Returns the number present. */
uint32_t mim_vest_fk(const mim_vest_rig_t *rig, const mim_vest_state_t *st, uint64_t now_us, uint64_t timeout_us,
                     float *xyz, uint8_t *present);
/* The same from given orientations (have[s] = 0: sensor missing; have NULL:
 * all present). Used by mim_vest_fk and by the simulator's expected output. */
uint32_t mim_vest_fk_orient(const mim_vest_rig_t *rig, const mim_quat q[MIM_VEST_SEGMENTS], const uint8_t *have,
                            float *xyz, uint8_t *present);

/* Groups decoded packets into whole vest frames: the frame at time t is
 * done when every sensor of the previous frame has reported t, or when a
 * later timestamp arrives (zero-initialise). */
typedef struct mim_vest_assembler {
    uint64_t t_us, expect, got;
    int open;      /* a frame at t_us is being filled */
    int done;      /* ... and was already reported */
} mim_vest_assembler_t;
/* Feeds one packet; returns how many frames it completed (0..2): their
 * times and sensor masks in t_done[] / mask[], oldest first. */
int mim_vest_assembler_push(mim_vest_assembler_t *a, const mim_vest_packet_info_t *info, uint64_t t_done[2],
                            uint64_t mask[2]);
/* At the end of a stream: 1 with the last unfinished frame, or 0. */
int mim_vest_assembler_flush(mim_vest_assembler_t *a, uint64_t *t_done, uint64_t *mask);

/* ------------------------------------------------------------------------
 * Transports (transport*.c): serial, hid, replay, udp behind one interface.
 * ---------------------------------------------------------------------- */
enum {
    MIM_VEST_CHUNK_STREAM = 1,   /* protocol bytes (serial, HID, replay of those) */
    MIM_VEST_CHUNK_LANDMARKS = 2 /* one UDP landmark frame, JSON text */
};

typedef struct mim_vest_chunk {
    int kind;
    uint64_t t_us;       /* host time (monotonic, us) or the recording's time */
    const uint8_t *data; /* valid until the next read or close */
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
const mim_vest_hid_layer_t *mim_vest_hid_layer_hidapi(void);
/* HID report: byte 0 = count of stream bytes that follow (0..63). */
#define MIM_VEST_HID_REPORT 64u

typedef struct mim_vest_transport_options {
    int timeout_ms;          /* a read waits this long for data; 0 = 1000 */
    int realtime;            /* replay: keep the recorded timing */
    int no_reconnect;        /* live transports: fail at the first disconnect */
    int reconnect_limit_ms;  /* give up after this long unplugged; 0 = 10000 */
    int backoff_min_ms;      /* 0 = 20 */
    int backoff_max_ms;      /* 0 = 1000 */
    const mim_vest_hid_layer_t *hid; /* NULL = hidapi */
    uint32_t header_flags;   /* response header of live streams; 0 = default */
} mim_vest_transport_options_t;

typedef struct mim_vest_transport mim_vest_transport_t;
/* spec: serial:PATH | hid:VID:PID[:SERIAL] (hex) | udp:HOST:PORT (listen) |
 * replay:FILE (or a plain path to a recording). */
int mim_vest_transport_open(mim_vest_transport_t **out, const char *spec, const mim_vest_transport_options_t *opt,
                            mim_error_t *err);
void mim_vest_transport_close(mim_vest_transport_t **t);
/* Returns 1 with a chunk, 0 at the end of a replay, -ETIMEDOUT after
 * timeout_ms without data, -ENODEV when the device stayed unplugged past
 * the reconnect limit, or another negative code; err says what and where. */
int mim_vest_transport_read(mim_vest_transport_t *t, mim_vest_chunk_t *chunk, mim_error_t *err);
/* Sends command bytes to the device (serial, HID); replay and UDP ignore them. */
int mim_vest_transport_write(mim_vest_transport_t *t, const void *data, size_t len, mim_error_t *err);
uint32_t mim_vest_transport_header_flags(const mim_vest_transport_t *t);
uint32_t mim_vest_transport_reconnects(const mim_vest_transport_t *t);
/* 0 while a serial or HID vest is unplugged (between a failed read and its
 * reconnection); 1 otherwise. */
int mim_vest_transport_connected(const mim_vest_transport_t *t);
/* 1 for serial and HID (they take commands). */
int mim_vest_transport_is_device(const mim_vest_transport_t *t);

/* Recording files (schemas/vest-recording.md). */
typedef struct mim_vest_recorder mim_vest_recorder_t;
int mim_vest_recorder_open(mim_vest_recorder_t **out, const char *path, uint32_t header_flags, mim_error_t *err);
int mim_vest_recorder_write(mim_vest_recorder_t *r, const mim_vest_chunk_t *chunk, mim_error_t *err);
/* Flushes and closes; returns the first write error, if any. */
int mim_vest_recorder_close(mim_vest_recorder_t **r, mim_error_t *err);

/* UDP landmark frames (schemas/vest-udp.schema.json):
 * {"t": us, "landmarks": [[x, y, z] | null, ...]}. At most max landmarks. */
int mim_vest_udp_parse(const char *text, size_t len, uint64_t *t_us, float *xyz, uint8_t *present, uint32_t max,
                       uint32_t *count, mim_error_t *err);
/* Formats one frame (malloc'd, NUL-terminated; NULL on allocation failure). */
char *mim_vest_udp_format(uint64_t t_us, const float *xyz, const uint8_t *present, uint32_t count);

/* Devices that look like vests. */
typedef struct mim_vest_device {
    char spec[300];  /* serial:/dev/ttyACM0 or hid:2476:1040[:SERIAL] */
    char what[200];  /* product string or sysfs description */
} mim_vest_device_t;
/* Serial ports /dev/ttyACM* and /dev/ttyUSB* whose USB vendor id is 0x2476
 * (sysfs_root NULL = "/sys"), then HID devices of that vendor (via `hid`,
 * NULL = hidapi; hid enumeration is skipped when list_hid is 0). Returns the
 * number found (<= max), or a negative code. */
int mim_vest_list(mim_vest_device_t *out, int max, const char *sysfs_root, int list_hid, mim_error_t *err);

/* ------------------------------------------------------------------------
 * Motion files and the simulated vest (motion*.c, simulate.c)
 * ---------------------------------------------------------------------- */
typedef struct mim_vest_motion {
    uint32_t n_frames;
    double frame_time;                      /* seconds */
    uint8_t have[MIM_VEST_SEGMENTS];        /* segments the motion drives */
    mim_quat *q;                            /* n_frames x 17 tared orientations, avatar frame */
    char joint[MIM_VEST_SEGMENTS][64];      /* the motion joint behind each segment */
    double rest_arm_deg; /* upper arms from vertical in the rest pose (T ~90, A ~45), -1 unknown */
} mim_vest_motion_t;

/* BVH (HIERARCHY/MOTION), or ASF skeleton + AMC motion. Each segment's
 * orientation is its world rotation relative to the motion's rest pose (all
 * channels zero), turned into the avatar frame (up and left axes found from
 * the rest pose). */
int mim_vest_motion_read_bvh(mim_vest_motion_t *m, const char *path, mim_error_t *err);
int mim_vest_motion_read_amc(mim_vest_motion_t *m, const char *asf_path, const char *amc_path, mim_error_t *err);
/* Parses BVH text (origin names it in messages). */
int mim_vest_motion_parse_bvh(mim_vest_motion_t *m, const char *text, size_t len, const char *origin,
                              mim_error_t *err);
void mim_vest_motion_free(mim_vest_motion_t *m);
/* The built-in demo motion (motion_demo.c): eight poses a synth store also
 * holds (rest, T, arms up, wave, reach, squat, walk, bow), 12 s, T-pose
 * rest. Free with mim_vest_motion_free. MIM_ENOMEM only. */
int mim_vest_motion_demo(mim_vest_motion_t *m, mim_error_t *err);
/* Orientations at time t (slerp between frames; clamped to the ends). */
void mim_vest_motion_sample(const mim_vest_motion_t *m, double t, mim_quat q[MIM_VEST_SEGMENTS]);

typedef struct mim_vest_sim_options {
    double rate_hz;          /* 0 = 60 */
    double drop, corrupt;    /* probability per packet */
    double disconnect_at;    /* seconds into the stream; 0 = never */
    double disconnect_for;   /* seconds; 0 = 0.5 */
    int loop;
    uint64_t seed;           /* fault randomness */
    uint32_t header_flags;   /* 0 = default */
} mim_vest_sim_options_t;

typedef struct mim_vest_sim mim_vest_sim_t;
int mim_vest_sim_open(mim_vest_sim_t **out, const mim_vest_motion_t *m, const mim_vest_sim_options_t *opt,
                      mim_error_t *err);
void mim_vest_sim_close(mim_vest_sim_t **s);
/* Stream frames in the motion (a single-frame motion streams one second);
 * with loop, the stream never ends but frames repeat with this period. */
uint64_t mim_vest_sim_n_frames(const mim_vest_sim_t *s);
double mim_vest_sim_rate(const mim_vest_sim_t *s);
/* The orientations frame k sends (as float32 on the wire, read back), its
 * timestamp, and which sensors it carries. Independent of the faults. */
void mim_vest_sim_orientations(const mim_vest_sim_t *s, uint64_t k, mim_quat q[MIM_VEST_SEGMENTS],
                               uint8_t have[MIM_VEST_SEGMENTS], uint64_t *t_us);
/* The packets of frame k (faults applied: a dropped packet is left out, a
 * corrupted one has one byte changed). Returns bytes written (0 if all were
 * dropped). cap >= 4 * MIM_VEST_MAX_PACKET is always enough. counts (may be
 * NULL): [0] packets made, [1] dropped, [2] corrupted. */
size_t mim_vest_sim_frame(mim_vest_sim_t *s, uint64_t k, uint8_t *buf, size_t cap, uint32_t counts[3]);

typedef struct mim_vest_sim_run {
    const char *out;            /* pty | pty:LINK | udp:HOST:PORT | FILE (a recording) */
    const mim_vest_rig_t *rig;  /* needed by udp: landmarks are sent */
    int realtime;               /* pty and udp always; FILE only when set */
    /* Called with the pty path (or LINK) when it is ready, and again after a
     * simulated reconnect if it changed. */
    void (*ready)(void *user, const char *path);
    void *user;
    volatile int *stop;         /* set non-zero to stop (may be NULL) */
} mim_vest_sim_run_t;
/* Streams the whole motion to run->out. Returns 0 or a negative code. */
int mim_vest_sim_run(mim_vest_sim_t *s, const mim_vest_sim_run_t *run, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
