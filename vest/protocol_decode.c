/* Incremental decoder of PrioVR hub stream packets (schemas/vest-protocol.md).
 *
 * Bytes arrive in any chunking. A packet starts at the sync bytes 00 FF FF;
 * its length follows from the response header layout and the active-sensor
 * bitfield. A packet is accepted only if it is at most 128 bytes, its header
 * fields are what a stream sends (success 0, echo 0xFF, data length), both
 * checksums hold and every quaternion is finite and of unit norm. Anything
 * else is counted by reason and the scan resumes one byte after the rejected
 * sync, so a corrupted length cannot swallow the packets behind it.
 * A wired sensor streaming by itself sends the response header and its slot
 * data without sync bytes or hub block; that form is decoded the same way
 * with a fixed packet length. */
#include "mim_vest_decode.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BUF_CAP 512

struct mim_vest_decoder {
    uint32_t flags;
    size_t hs;           /* response header bytes */
    size_t off_ts, off_cks, off_id, off_serial, off_len, off_success, off_echo;
    int wired;
    uint32_t wired_sensor;
    mim_vest_packet_fn fn;
    void *user;
    uint8_t buf[BUF_CAP];
    size_t len;
    uint32_t last_ts;    /* unwrap of the u32 timestamp */
    uint64_t epoch;
    int have_ts;
    mim_vest_decoder_stats_t st;
};

static const char *const reject_names[MIM_VEST_REJ_COUNT] = {
    "length", "header", "hub_checksum", "data_checksum", "quaternion"};

const char *mim_vest_reject_name(int r)
{
    return r >= 0 && r < MIM_VEST_REJ_COUNT ? reject_names[r] : "unknown";
}

#define NONE ((size_t)-1)

int mim_vest_decoder_open(mim_vest_decoder_t **out, const mim_vest_decoder_options_t *opt, mim_vest_packet_fn fn,
                          void *user)
{
    if (!out) return MIM_EINVAL;
    *out = NULL;
    mim_vest_decoder_t *d = calloc(1, sizeof *d);
    if (!d) return MIM_ENOMEM;
    uint32_t f = opt && opt->header_flags ? opt->header_flags & MIM_VEST_HDR_ALL : MIM_VEST_HDR_DEFAULT;
    d->flags = f;
    d->fn = fn, d->user = user;
    d->wired = opt && opt->wired;
    d->wired_sensor = opt ? opt->wired_sensor : 0;
    size_t k = 0;
    d->off_success = d->off_ts = d->off_echo = d->off_cks = d->off_id = d->off_serial = d->off_len = NONE;
    if (f & MIM_VEST_HDR_SUCCESS) d->off_success = k, k += 1;
    if (f & MIM_VEST_HDR_TIMESTAMP) d->off_ts = k, k += 4;
    if (f & MIM_VEST_HDR_ECHO) d->off_echo = k, k += 1;
    if (f & MIM_VEST_HDR_CHECKSUM) d->off_cks = k, k += 1;
    if (f & MIM_VEST_HDR_ID) d->off_id = k, k += 1;
    if (f & MIM_VEST_HDR_SERIAL) d->off_serial = k, k += 4;
    if (f & MIM_VEST_HDR_LENGTH) d->off_len = k, k += 1;
    d->hs = k;
    *out = d;
    return 0;
}

void mim_vest_decoder_close(mim_vest_decoder_t **d)
{
    if (!d || !*d) return;
    free(*d);
    *d = NULL;
}

void mim_vest_decoder_reset(mim_vest_decoder_t *d)
{
    if (!d) return;
    d->st.skipped_bytes += d->len;
    d->len = 0;
}

void mim_vest_decoder_get_stats(const mim_vest_decoder_t *d, mim_vest_decoder_stats_t *s)
{
    if (d && s) *s = d->st;
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

static float get_f32(const uint8_t *p)
{
    uint32_t v = get_u32(p);
    float f;
    memcpy(&f, &v, 4);
    return f;
}

/* Offset of the first possible packet start in p[0..n): a full sync, or a
 * sync prefix running into the end. */
static size_t find_sync(const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        const uint8_t *z = memchr(p + i, 0x00, n - i);
        if (!z) return n;
        i = (size_t)(z - p);
        if (i + 1 >= n) return i;
        if (p[i + 1] != 0xFF) continue;
        if (i + 2 >= n || p[i + 2] == 0xFF) return i;
    }
    return n;
}

static uint64_t unwrap(mim_vest_decoder_t *d, uint32_t ts)
{
    /* the u32 microsecond clock wraps every 71.6 minutes */
    if (d->have_ts && ts < d->last_ts && d->last_ts - ts > 0x80000000u) d->epoch += 1ull << 32;
    d->last_ts = ts, d->have_ts = 1;
    return d->epoch + ts;
}

/* Checks the packet at p (sync verified, length known and available).
 * Returns -1 if accepted (and emitted), else the reject reason. */
static int check_and_emit(mim_vest_decoder_t *d, const uint8_t *p, size_t total, uint32_t ns, uint64_t now_us)
{
    const uint8_t *h = p + 3, *hub = h + d->hs, *slot = hub + MIM_VEST_HUB_BLOCK;
    size_t data = MIM_VEST_HUB_BLOCK + (size_t)ns * MIM_VEST_SLOT_BYTES;
    if (d->off_len != NONE && h[d->off_len] != data) return MIM_VEST_REJ_LENGTH;
    if (d->off_success != NONE && h[d->off_success] != 0) return MIM_VEST_REJ_HEADER;
    if (d->off_echo != NONE && h[d->off_echo] != 0xFF) return MIM_VEST_REJ_HEADER;
    unsigned sum = 0;
    for (size_t i = 0; i < d->hs; i++)
        if (i != d->off_cks) sum += h[i];
    for (size_t i = 0; i < MIM_VEST_HUB_BLOCK - 1; i++) sum += hub[i];
    if ((uint8_t)sum != hub[MIM_VEST_HUB_BLOCK - 1]) return MIM_VEST_REJ_HUB_CHECKSUM;
    if (d->off_cks != NONE) {
        unsigned s2 = 0;
        for (size_t i = 0; i < data; i++) s2 += hub[i];
        if ((uint8_t)s2 != h[d->off_cks]) return MIM_VEST_REJ_DATA_CHECKSUM;
    }
    mim_vest_frame_t fr[MIM_VEST_MAX_IDS];
    uint64_t active = 0;
    for (int i = 0; i < 8; i++) active = active << 8 | hub[11 + i];
    uint32_t k = 0;
    for (uint32_t id = 0; id < MIM_VEST_MAX_IDS; id++) {
        if (!(active >> id & 1)) continue;
        double n2 = 0;
        for (int c = 0; c < 4; c++) {
            float v = get_f32(slot + 16 * k + 4 * (size_t)c);
            if (!isfinite(v)) return MIM_VEST_REJ_QUATERNION;
            fr[k].q[c] = v;
            n2 += (double)v * v;
        }
        if (fabs(n2 - 1.0) > 0.02) return MIM_VEST_REJ_QUATERNION;
        fr[k].sensor = id;
        fr[k].status = hub[1];
        k++;
    }
    mim_vest_packet_info_t info = {0};
    if (d->off_ts != NONE) {
        info.timestamp = get_u32(h + d->off_ts);
        info.t_us = unwrap(d, info.timestamp);
    } else {
        info.t_us = now_us;
    }
    for (uint32_t i = 0; i < k; i++) fr[i].t_us = info.t_us;
    info.active = active;
    info.serial = d->off_serial != NONE ? get_u32(h + d->off_serial) : 0;
    info.logical_id = d->off_id != NONE ? h[d->off_id] : 0;
    info.battery = hub[0], info.status = hub[1], info.buttons = hub[2];
    memcpy(info.joystick, hub + 3, 8);
    info.length = (uint32_t)total;
    info.raw = p;
    d->st.packets++;
    d->st.frames += k;
    if (d->fn) d->fn(d->user, &info, fr, k);
    return -1;
}

/* A wired sensor's packet at p (header + 16 bytes): -1 if accepted. */
static int check_wired(mim_vest_decoder_t *d, const uint8_t *p, uint64_t now_us)
{
    const uint8_t *q = p + d->hs;
    if (d->off_len != NONE && p[d->off_len] != MIM_VEST_SLOT_BYTES) return MIM_VEST_REJ_LENGTH;
    if (d->off_success != NONE && p[d->off_success] != 0) return MIM_VEST_REJ_HEADER;
    if (d->off_echo != NONE && p[d->off_echo] != 0xFF) return MIM_VEST_REJ_HEADER;
    if (d->off_cks != NONE) {
        unsigned s = 0;
        for (size_t i = 0; i < MIM_VEST_SLOT_BYTES; i++) s += q[i];
        if ((uint8_t)s != p[d->off_cks]) return MIM_VEST_REJ_DATA_CHECKSUM;
    }
    mim_vest_frame_t fr;
    double n2 = 0;
    for (int c = 0; c < 4; c++) {
        float v = get_f32(q + 4 * c);
        if (!isfinite(v)) return MIM_VEST_REJ_QUATERNION;
        fr.q[c] = v;
        n2 += (double)v * v;
    }
    if (fabs(n2 - 1.0) > 0.02) return MIM_VEST_REJ_QUATERNION;
    mim_vest_packet_info_t info = {0};
    if (d->off_ts != NONE) info.timestamp = get_u32(p + d->off_ts), info.t_us = unwrap(d, info.timestamp);
    else info.t_us = now_us;
    info.logical_id = d->off_id != NONE ? p[d->off_id] : 0;
    info.serial = d->off_serial != NONE ? get_u32(p + d->off_serial) : 0;
    fr.sensor = d->off_id != NONE ? info.logical_id : d->wired_sensor;
    if (fr.sensor >= MIM_VEST_MAX_IDS) return MIM_VEST_REJ_HEADER;
    fr.t_us = info.t_us, fr.status = 0;
    info.active = 1ull << fr.sensor;
    info.length = (uint32_t)(d->hs + MIM_VEST_SLOT_BYTES);
    info.raw = p;
    d->st.packets++;
    d->st.frames++;
    if (d->fn) d->fn(d->user, &info, &fr, 1);
    return -1;
}

/* How far to move on past a candidate packet of `total` bytes that check
 * returned r for: a rejection (r >= 0) is counted and the scan resyncs from
 * the next byte; an accepted packet is skipped whole. */
static size_t advance(mim_vest_decoder_t *d, int r, size_t total, uint32_t *accepted)
{
    if (r >= 0) {
        d->st.rejected[r]++;
        d->st.skipped_bytes++;
        return 1;
    }
    (*accepted)++;
    return total;
}

static size_t scan_wired(mim_vest_decoder_t *d, const uint8_t *p, size_t n, uint64_t now_us, uint32_t *accepted)
{
    size_t i = 0, total = d->hs + MIM_VEST_SLOT_BYTES;
    while (n - i >= total) i += advance(d, check_wired(d, p + i, now_us), total, accepted);
    return i;
}

/* Decodes what it can of p[0..n); returns the bytes consumed. What is left
 * is a possible packet start that needs more bytes (< 128). */
static size_t scan(mim_vest_decoder_t *d, const uint8_t *p, size_t n, uint64_t now_us, uint32_t *accepted)
{
    if (d->wired) return scan_wired(d, p, n, now_us, accepted);
    size_t i = 0, fixed = 3 + d->hs + MIM_VEST_HUB_BLOCK;
    while (i < n) {
        size_t s = find_sync(p + i, n - i);
        d->st.skipped_bytes += s;
        i += s;
        if (n - i < fixed) break;
        const uint8_t *hub = p + i + 3 + d->hs;
        uint32_t ns = 0;
        for (int b = 0; b < 8; b++) ns += (uint32_t)__builtin_popcount(hub[11 + b]);
        size_t total = fixed + (size_t)ns * MIM_VEST_SLOT_BYTES;
        if (total > MIM_VEST_MAX_PACKET) {
            i += advance(d, MIM_VEST_REJ_LENGTH, total, accepted);
            continue;
        }
        if (n - i < total) break;
        i += advance(d, check_and_emit(d, p + i, total, ns, now_us), total, accepted);
    }
    return i;
}

uint32_t mim_vest_decoder_feed(mim_vest_decoder_t *d, const void *bytes, size_t n, uint64_t now_us)
{
    if (!d || (!bytes && n)) return 0;
    const uint8_t *in = bytes;
    uint32_t accepted = 0;
    d->st.bytes += n;
    while (n) {
        if (d->len == 0) {
            /* fast path: decode straight from the caller's bytes */
            size_t used = scan(d, in, n, now_us, &accepted);
            in += used, n -= used;
            if (n >= BUF_CAP) { /* cannot happen: a held-back start is < 128 bytes */
                d->st.skipped_bytes += n;
                return accepted;
            }
            memcpy(d->buf, in, n);
            d->len = n;
            return accepted;
        }
        size_t take = BUF_CAP - d->len < n ? BUF_CAP - d->len : n;
        memcpy(d->buf + d->len, in, take);
        d->len += take, in += take, n -= take;
        size_t used = scan(d, d->buf, d->len, now_us, &accepted);
        memmove(d->buf, d->buf + used, d->len - used);
        d->len -= used;
    }
    return accepted;
}
