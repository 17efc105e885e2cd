/* libFuzzer harness: the vest stream decoder. Byte 0 picks the response
 * header layout (bits 0..6) and the hub or wired-sensor form (bit 7), byte 1
 * the chunk size; the rest is fed in those chunks.
 * Every accepted packet must be exactly what the encoder makes of the frames
 * the decoder reported (so no corrupt packet gets through), with unit
 * quaternions; the counters must add up. */
#include "mim_vest.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static uint32_t g_flags;
static int g_wired;
static uint64_t g_frames;

static void on_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    (void)user;
    float q[MIM_VEST_MAX_IDS][4];
    uint64_t active = 0;
    if (n > 6 || info->length > MIM_VEST_MAX_PACKET) abort();
    for (uint32_t i = 0; i < n; i++) {
        double n2 = 0;
        for (int c = 0; c < 4; c++) {
            if (!isfinite(f[i].q[c])) abort();
            n2 += (double)f[i].q[c] * f[i].q[c];
            q[i][c] = f[i].q[c];
        }
        if (fabs(n2 - 1) > 0.02 || f[i].sensor >= 64 || (active >> f[i].sensor & 1)) abort();
        if (i && f[i].sensor <= f[i - 1].sensor) abort();
        active |= 1ull << f[i].sensor;
        if (f[i].t_us != info->t_us || f[i].status != info->status) abort();
    }
    if (active != info->active) abort();
    if (g_wired) {
        uint8_t w[64];
        size_t wl = mim_vest_encode_wired_packet(w, sizeof w, g_flags, info->timestamp, info->logical_id, q[0]);
        if (n != 1 || wl != info->length) abort();
        /* the encoder writes serial 0; everything else must be identical */
        if (!(g_flags & MIM_VEST_HDR_SERIAL) && memcmp(w, info->raw, wl)) abort();
        g_frames += n;
        return;
    }
    mim_vest_hub_packet_t p = {0};
    p.header_flags = g_flags;
    p.timestamp_us = info->timestamp;
    p.serial = info->serial;
    p.logical_id = info->logical_id;
    p.battery = info->battery, p.status = info->status, p.buttons = info->buttons;
    memcpy(p.joystick, info->joystick, 8);
    p.active = active;
    p.q = (const float(*)[4])q;
    uint8_t buf[MIM_VEST_MAX_PACKET];
    size_t len = mim_vest_encode_hub_packet(buf, sizeof buf, &p);
    if (len != info->length) abort();
    if (memcmp(buf, info->raw, len)) abort();
    g_frames += n;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2) return 0;
    g_flags = data[0] & MIM_VEST_HDR_ALL;
    g_wired = data[0] >> 7; /* the top bit picks a wired sensor's own stream */
    if (!g_flags) g_flags = MIM_VEST_HDR_DEFAULT;
    size_t chunk = 1 + data[1];
    data += 2, size -= 2;
    mim_vest_decoder_t *d = NULL;
    mim_vest_decoder_options_t o = {.header_flags = g_flags, .wired = g_wired, .wired_sensor = 3};
    if (mim_vest_decoder_open(&d, &o, on_packet, NULL)) return 0;
    g_frames = 0;
    for (size_t i = 0; i < size; i += chunk) mim_vest_decoder_feed(d, data + i, size - i < chunk ? size - i : chunk, 1);
    mim_vest_decoder_stats_t st;
    mim_vest_decoder_get_stats(d, &st);
    if (st.bytes != size || st.skipped_bytes > size) abort();
    mim_vest_decoder_close(&d);
    return 0;
}
