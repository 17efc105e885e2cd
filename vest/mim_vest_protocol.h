/* mimic vest, the wire protocol: constants of the PrioVR / YOST 3-Space
 * streaming protocol, the encoder of command packets and of stream packets
 * (hub and wired sensor), and the sensor frame the decoder emits.
 * Implemented by protocol_encode.c. Wire layout: schemas/vest-protocol.md.
 *
 * Every function here is pure: no allocation, no state, safe from any thread.
 * Encoders return the bytes written, or 0 when nothing was written (buf or a
 * required pointer NULL, or cap too small); they never write past cap. */
#ifndef MIM_VEST_PROTOCOL_H
#define MIM_VEST_PROTOCOL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- constants (YOST 3-Space user's manual; VRPN's PrioVR driver) ---- */
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
 * holds 6 sensors (3 + 8 + 20 + 6 * 16 = 127 bytes). Wherever a struct or an
 * argument below says "0 = default", this is the default. */
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

/* Bytes of a response header with these field bits (bits above 0x40
 * ignored). Flags are taken literally here: 0 means no header, not the
 * default. */
size_t mim_vest_header_size(uint32_t header_flags);
/* Sensors one hub packet can carry with this header (<= 6); flags literal
 * as for mim_vest_header_size. */
uint32_t mim_vest_hub_capacity(uint32_t header_flags);

/* ---- command packets ---- */
/* How a command reaches a device: wired (0xF7/0xF9) or through the dongle to
 * a logical id (0xF8/0xFA); want_header asks for a response header. */
typedef struct mim_vest_link {
    int wireless;
    uint8_t logical_id;
    int want_header;
} mim_vest_link_t;

/* Writes one command packet into buf. Checksum: (command + argument bytes)
 * % 256 wired; the logical id is added too through the dongle. link NULL =
 * wired, no header. Returns its length (n_args + 3 wired, + 4 wireless), or
 * 0 if buf is NULL, cap is too small, or args is NULL with n_args > 0. */
size_t mim_vest_encode_command(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint8_t command,
                               const uint8_t *args, size_t n_args);
/* The commands below go through mim_vest_encode_command: same returns. */
size_t mim_vest_cmd_set_slots(uint8_t *buf, size_t cap, const mim_vest_link_t *link, const uint8_t slots[8]);
/* interval, duration and delay in microseconds (duration 0xFFFFFFFF = forever). */
size_t mim_vest_cmd_set_timing(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t interval_us,
                               uint32_t duration_us, uint32_t delay_us);
size_t mim_vest_cmd_start(uint8_t *buf, size_t cap, const mim_vest_link_t *link);
size_t mim_vest_cmd_stop(uint8_t *buf, size_t cap, const mim_vest_link_t *link);
size_t mim_vest_cmd_tare(uint8_t *buf, size_t cap, const mim_vest_link_t *link);
/* 0xDD (wired link) or 0xDB (wireless link) with the field bits as u32 BE
 * (sent as given: 0 asks for no header). */
size_t mim_vest_cmd_set_header(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t header_flags);
/* The command sequence that starts a PrioVR stream of tared quaternions:
 * response header, slots (0x00, then empty), timing (forever, no delay),
 * start. Returns the bytes of all four, or 0 if they do not all fit (buf
 * may then hold some of them). */
size_t mim_vest_cmd_stream_setup(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t header_flags,
                                 uint32_t interval_us);

/* ---- stream packets ---- */
/* One hub stream packet: the sensors whose bits are set in `active`, in
 * increasing id order, with their quaternions (x y z w) in q. */
typedef struct mim_vest_hub_packet {
    uint32_t header_flags; /* 0 means MIM_VEST_HDR_DEFAULT; bits above 0x7F ignored */
    uint32_t timestamp_us;
    uint32_t serial;
    uint8_t logical_id;    /* the hub sends MIM_VEST_ID_HUB */
    uint8_t battery, status, buttons;
    uint8_t joystick[2][4];
    uint64_t active;
    const float (*q)[4];   /* one row per set bit of active; read during the call only */
} mim_vest_hub_packet_t;

/* Encodes one packet: sync 00 FF FF, response header, hub block, slot data.
 * Returns its length, or 0 if buf or p is NULL, q is NULL with sensors
 * active, or the packet would exceed MIM_VEST_MAX_PACKET or cap. */
size_t mim_vest_encode_hub_packet(uint8_t *buf, size_t cap, const mim_vest_hub_packet_t *p);
/* Encodes one packet of a wired sensor's own stream: the response header
 * (header_flags, 0 = default; serial field 0) and the quaternion. Returns its
 * length, or 0 if buf or q is NULL or cap is too small. */
size_t mim_vest_encode_wired_packet(uint8_t *buf, size_t cap, uint32_t header_flags, uint32_t timestamp_us,
                                    uint8_t logical_id, const float q[4]);

/* ---- what the decoder (mim_vest_decode.h) emits per sensor ---- */
typedef struct mim_vest_frame {
    uint64_t t_us;   /* header timestamp unwrapped to 64 bits, else host time */
    uint32_t sensor; /* bit index in the active-sensor bitfield */
    float q[4];      /* tared orientation x y z w */
    uint8_t status;  /* hub status byte (0 for a wired sensor) */
} mim_vest_frame_t;

#ifdef __cplusplus
}
#endif
#endif
