/* Encoder of the YOST 3-Space / PrioVR wire protocol: command packets and
 * hub stream packets (schemas/vest-protocol.md). The simulated vest and the
 * tests encode through these functions, so the decoder is checked against
 * the one definition of the layout. */
#include "mim_vest_protocol.h"

#include <string.h>

size_t mim_vest_header_size(uint32_t f)
{
    size_t n = 0;
    if (f & MIM_VEST_HDR_SUCCESS) n += 1;
    if (f & MIM_VEST_HDR_TIMESTAMP) n += 4;
    if (f & MIM_VEST_HDR_ECHO) n += 1;
    if (f & MIM_VEST_HDR_CHECKSUM) n += 1;
    if (f & MIM_VEST_HDR_ID) n += 1;
    if (f & MIM_VEST_HDR_SERIAL) n += 4;
    if (f & MIM_VEST_HDR_LENGTH) n += 1;
    return n;
}

uint32_t mim_vest_hub_capacity(uint32_t f)
{
    size_t fixed = 3 + mim_vest_header_size(f) + MIM_VEST_HUB_BLOCK;
    return (uint32_t)((MIM_VEST_MAX_PACKET - fixed) / MIM_VEST_SLOT_BYTES);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24), p[1] = (uint8_t)(v >> 16), p[2] = (uint8_t)(v >> 8), p[3] = (uint8_t)v;
}

static void put_f32(uint8_t *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    put_u32(p, v);
}

size_t mim_vest_encode_command(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint8_t command,
                               const uint8_t *args, size_t n_args)
{
    mim_vest_link_t wired = {0};
    if (!link) link = &wired;
    size_t n = 1 + (link->wireless ? 1 : 0) + 1 + n_args + 1;
    if (!buf || cap < n || (n_args && !args)) return 0;
    size_t k = 0;
    unsigned sum = 0;
    if (link->wireless) {
        buf[k++] = link->want_header ? 0xFA : 0xF8;
        buf[k++] = link->logical_id;
        sum += link->logical_id; /* the dongle's checksum covers the logical id too */
    } else {
        buf[k++] = link->want_header ? 0xF9 : 0xF7;
    }
    buf[k++] = command;
    sum += command;
    for (size_t i = 0; i < n_args; i++) buf[k++] = args[i], sum += args[i];
    buf[k++] = (uint8_t)(sum % 256);
    return k;
}

size_t mim_vest_cmd_set_slots(uint8_t *buf, size_t cap, const mim_vest_link_t *link, const uint8_t slots[8])
{
    return mim_vest_encode_command(buf, cap, link, MIM_VEST_CMD_SET_SLOTS, slots, 8);
}

size_t mim_vest_cmd_set_timing(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t interval_us,
                               uint32_t duration_us, uint32_t delay_us)
{
    uint8_t a[12];
    put_u32(a, interval_us), put_u32(a + 4, duration_us), put_u32(a + 8, delay_us);
    return mim_vest_encode_command(buf, cap, link, MIM_VEST_CMD_SET_TIMING, a, sizeof a);
}

size_t mim_vest_cmd_start(uint8_t *buf, size_t cap, const mim_vest_link_t *link)
{
    return mim_vest_encode_command(buf, cap, link, MIM_VEST_CMD_START, NULL, 0);
}

size_t mim_vest_cmd_stop(uint8_t *buf, size_t cap, const mim_vest_link_t *link)
{
    return mim_vest_encode_command(buf, cap, link, MIM_VEST_CMD_STOP, NULL, 0);
}

size_t mim_vest_cmd_tare(uint8_t *buf, size_t cap, const mim_vest_link_t *link)
{
    return mim_vest_encode_command(buf, cap, link, MIM_VEST_CMD_TARE, NULL, 0);
}

size_t mim_vest_cmd_set_header(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t header_flags)
{
    uint8_t a[4];
    put_u32(a, header_flags);
    int wireless = link && link->wireless;
    return mim_vest_encode_command(buf, cap, link,
                                   wireless ? MIM_VEST_CMD_HEADER_WIRELESS : MIM_VEST_CMD_HEADER_WIRED, a, 4);
}

size_t mim_vest_cmd_stream_setup(uint8_t *buf, size_t cap, const mim_vest_link_t *link, uint32_t header_flags,
                                 uint32_t interval_us)
{
    static const uint8_t slots[8] = {MIM_VEST_CMD_TARED_QUAT, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
    size_t n = 0, k;
    if (!(k = mim_vest_cmd_set_header(buf, cap, link, header_flags))) return 0;
    n += k;
    if (!(k = mim_vest_cmd_set_slots(buf + n, cap - n, link, slots))) return 0;
    n += k;
    if (!(k = mim_vest_cmd_set_timing(buf + n, cap - n, link, interval_us, 0xFFFFFFFFu, 0))) return 0;
    n += k;
    if (!(k = mim_vest_cmd_start(buf + n, cap - n, link))) return 0;
    return n + k;
}

static int popcount64(uint64_t v)
{
    int n = 0;
    for (; v; v &= v - 1) n++;
    return n;
}

size_t mim_vest_encode_hub_packet(uint8_t *buf, size_t cap, const mim_vest_hub_packet_t *p)
{
    if (!buf || !p) return 0;
    uint32_t f = p->header_flags ? p->header_flags & MIM_VEST_HDR_ALL : MIM_VEST_HDR_DEFAULT;
    size_t hs = mim_vest_header_size(f);
    size_t ns = (size_t)popcount64(p->active);
    size_t data = MIM_VEST_HUB_BLOCK + ns * MIM_VEST_SLOT_BYTES;
    size_t total = 3 + hs + data;
    if (total > MIM_VEST_MAX_PACKET || total > cap || (ns && !p->q)) return 0;

    uint8_t *h = buf + 3, *hub = h + hs, *slot = hub + MIM_VEST_HUB_BLOCK;
    buf[0] = 0x00, buf[1] = 0xFF, buf[2] = 0xFF;

    /* hub block: battery, status, buttons, 2 joysticks, active bitfield (BE) */
    hub[0] = p->battery, hub[1] = p->status, hub[2] = p->buttons;
    memcpy(hub + 3, p->joystick[0], 4);
    memcpy(hub + 7, p->joystick[1], 4);
    for (int i = 0; i < 8; i++) hub[11 + i] = (uint8_t)(p->active >> (56 - 8 * i));
    for (size_t i = 0; i < ns; i++)
        for (int c = 0; c < 4; c++) put_f32(slot + 16 * i + 4 * (size_t)c, p->q[i][c]);

    /* response header; the checksum byte is filled last */
    size_t k = 0, cks_at = (size_t)-1;
    if (f & MIM_VEST_HDR_SUCCESS) h[k++] = 0;
    if (f & MIM_VEST_HDR_TIMESTAMP) put_u32(h + k, p->timestamp_us), k += 4;
    if (f & MIM_VEST_HDR_ECHO) h[k++] = 0xFF;
    if (f & MIM_VEST_HDR_CHECKSUM) cks_at = k, h[k++] = 0;
    if (f & MIM_VEST_HDR_ID) h[k++] = p->logical_id;
    if (f & MIM_VEST_HDR_SERIAL) put_u32(h + k, p->serial), k += 4;
    if (f & MIM_VEST_HDR_LENGTH) h[k++] = (uint8_t)data;

    /* hub checksum: the header (without its checksum byte) and the first 19
     * hub bytes, so the timestamp is protected as well as the data */
    unsigned sum = 0;
    for (size_t i = 0; i < hs; i++)
        if (i != cks_at) sum += h[i];
    for (size_t i = 0; i < MIM_VEST_HUB_BLOCK - 1; i++) sum += hub[i];
    hub[MIM_VEST_HUB_BLOCK - 1] = (uint8_t)sum;
    if (cks_at != (size_t)-1) {
        unsigned d = 0;
        for (size_t i = 0; i < data; i++) d += hub[i];
        h[cks_at] = (uint8_t)d;
    }
    return total;
}

size_t mim_vest_encode_wired_packet(uint8_t *buf, size_t cap, uint32_t header_flags, uint32_t timestamp_us,
                                    uint8_t logical_id, const float q[4])
{
    uint32_t f = header_flags ? header_flags & MIM_VEST_HDR_ALL : MIM_VEST_HDR_DEFAULT;
    size_t hs = mim_vest_header_size(f), total = hs + MIM_VEST_SLOT_BYTES;
    if (!buf || !q || cap < total) return 0;
    uint8_t *d = buf + hs;
    unsigned sum = 0;
    for (int c = 0; c < 4; c++) put_f32(d + 4 * c, q[c]);
    for (size_t i = 0; i < MIM_VEST_SLOT_BYTES; i++) sum += d[i];
    size_t k = 0;
    if (f & MIM_VEST_HDR_SUCCESS) buf[k++] = 0;
    if (f & MIM_VEST_HDR_TIMESTAMP) put_u32(buf + k, timestamp_us), k += 4;
    if (f & MIM_VEST_HDR_ECHO) buf[k++] = 0xFF;
    if (f & MIM_VEST_HDR_CHECKSUM) buf[k++] = (uint8_t)sum;
    if (f & MIM_VEST_HDR_ID) buf[k++] = logical_id;
    if (f & MIM_VEST_HDR_SERIAL) put_u32(buf + k, 0), k += 4;
    if (f & MIM_VEST_HDR_LENGTH) buf[k++] = MIM_VEST_SLOT_BYTES;
    return total;
}

