/* One interface over the vest's links: spec parsing, timeouts, and the
 * reconnect-with-backoff loop that live links (serial, HID) share. A device
 * that vanishes gets one line saying so (through the options' log
 * callback); reads then retry opening it with doubling waits until it is
 * back or the reconnect limit passes. */
#include "transport_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

uint64_t mim__now_us(void) { return (uint64_t)llround(mim_now() * 1e6); }

static void nap_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    while (nanosleep(&ts, &ts) && errno == EINTR) {
    }
}

static int parse_hex16(const char *s, size_t n, uint16_t *out)
{
    if (!n || n > 4) return -1;
    unsigned v = 0;
    for (size_t i = 0; i < n; i++) {
        char c = s[i];
        int d = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
        if (d < 0) return -1;
        v = v * 16 + (unsigned)d;
    }
    *out = (uint16_t)v;
    return 0;
}

int mim_vest_transport_open(mim_vest_transport_t **out, const char *spec, const mim_vest_transport_options_t *opt,
                            mim_error_t *err)
{
    if (!out || !spec) return mim_error_set(err, MIM_EINVAL, "vest: no device given");
    *out = NULL;
    mim_vest_transport_t *t = calloc(1, sizeof *t);
    if (!t) return mim_error_set(err, MIM_ENOMEM, "vest: out of memory");
    if (opt) t->o = *opt;
    if (t->o.timeout_ms <= 0) t->o.timeout_ms = 1000;
    if (t->o.reconnect_limit_ms <= 0) t->o.reconnect_limit_ms = 10000;
    if (t->o.backoff_min_ms <= 0) t->o.backoff_min_ms = 20;
    if (t->o.backoff_max_ms <= 0) t->o.backoff_max_ms = 1000;
    t->header_flags = t->o.header_flags ? t->o.header_flags : MIM_VEST_HDR_DEFAULT;
    t->fd = t->sock = -1;
    int rc;
    if (!strncmp(spec, "serial:", 7)) {
        t->kind = MIM__T_SERIAL;
        snprintf(t->path, sizeof t->path, "%s", spec + 7);
        snprintf(t->desc, sizeof t->desc, "serial %s", t->path);
        rc = t->path[0] ? mim__serial_open(t, err) : mim_error_set(err, MIM_EINVAL, "vest: serial: needs a path");
    } else if (!strncmp(spec, "hid:", 4)) {
        t->kind = MIM__T_HID;
        const char *a = spec + 4, *c1 = strchr(a, ':'), *c2 = c1 ? strchr(c1 + 1, ':') : NULL;
        const char *pend = c2 ? c2 : c1 ? c1 + strlen(c1) : NULL;
        if (!c1 || parse_hex16(a, (size_t)(c1 - a), &t->vid) || parse_hex16(c1 + 1, (size_t)(pend - c1 - 1), &t->pid)) {
            free(t);
            return mim_error_set(err, MIM_EINVAL, "vest: '%s' is not hid:VID:PID[:SERIAL] (hexadecimal ids)", spec);
        }
        if (c2) snprintf(t->serial, sizeof t->serial, "%s", c2 + 1);
        snprintf(t->desc, sizeof t->desc, "hid %04x:%04x%s%s", t->vid, t->pid, t->serial[0] ? ":" : "", t->serial);
        t->hid = t->o.hid ? t->o.hid : mim_vest_hid_layer_hidapi();
        rc = mim__hid_open(t, err);
    } else if (!strncmp(spec, "udp:", 4)) {
        t->kind = MIM__T_UDP;
        snprintf(t->desc, sizeof t->desc, "udp %s", spec + 4);
        rc = mim__udp_open(t, spec + 4, err);
    } else {
        t->kind = MIM__T_REPLAY;
        const char *path = !strncmp(spec, "replay:", 7) ? spec + 7 : spec;
        snprintf(t->desc, sizeof t->desc, "%s", path);
        rc = mim__replay_open(t, path, err);
    }
    if (rc) {
        free(t);
        return rc;
    }
    t->connected = 1;
    t->backoff_ms = t->o.backoff_min_ms;
    *out = t;
    return 0;
}

static void close_link(mim_vest_transport_t *t)
{
    if (t->kind == MIM__T_SERIAL) mim__serial_close(t);
    else if (t->kind == MIM__T_HID) mim__hid_close(t);
}

void mim_vest_transport_close(mim_vest_transport_t **tp)
{
    if (!tp || !*tp) return;
    mim_vest_transport_t *t = *tp;
    if (t->kind == MIM__T_UDP) mim__udp_close(t);
    else if (t->kind == MIM__T_REPLAY) mim__replay_close(t);
    else if (t->connected) close_link(t);
    free(t);
    *tp = NULL;
}

uint32_t mim_vest_transport_header_flags(const mim_vest_transport_t *t) { return t ? t->header_flags : 0; }
uint32_t mim_vest_transport_reconnects(const mim_vest_transport_t *t) { return t ? t->reconnects : 0; }
int mim_vest_transport_connected(const mim_vest_transport_t *t)
{
    if (!t) return 0;
    return (t->kind != MIM__T_SERIAL && t->kind != MIM__T_HID) || t->connected;
}
int mim_vest_transport_is_device(const mim_vest_transport_t *t)
{
    return t && (t->kind == MIM__T_SERIAL || t->kind == MIM__T_HID);
}

int mim_vest_transport_write(mim_vest_transport_t *t, const void *data, size_t len, mim_error_t *err)
{
    if (!t) return mim_error_set(err, MIM_EINVAL, "vest: no transport");
    if (!t->connected) return mim_error_set(err, -ENODEV, "%s: not connected", t->desc);
    if (t->kind == MIM__T_SERIAL) return mim__serial_write(t, data, len, err);
    if (t->kind == MIM__T_HID) return mim__hid_write(t, data, len, err);
    return 0;
}

int mim_vest_transport_read(mim_vest_transport_t *t, mim_vest_chunk_t *chunk, mim_error_t *err)
{
    if (!t || !chunk) return mim_error_set(err, MIM_EINVAL, "vest: no transport");
    if (t->kind == MIM__T_UDP) return mim__udp_read(t, chunk, err);
    if (t->kind == MIM__T_REPLAY) return mim__replay_read(t, chunk, err);
    double deadline = mim_now() + t->o.timeout_ms / 1000.0;
    for (;;) {
        if (!t->connected) {
            double gone = mim_now() - t->t_disconnected;
            if (t->o.no_reconnect || gone * 1000 > t->o.reconnect_limit_ms)
                return mim_error_set(err, -ENODEV, "%s: unplugged for %.1f s, giving up", t->desc, gone);
            mim_error_t e2 = {0};
            int rc = t->kind == MIM__T_SERIAL ? mim__serial_open(t, &e2) : mim__hid_open(t, &e2);
            if (rc) {
                /* the caller hears about the wait at its timeout; the next
                 * read carries on with the backoff */
                if (mim_now() >= deadline)
                    return mim_error_set(err, -ETIMEDOUT, "%s: unplugged for %.1f s, reconnecting", t->desc, gone);
                nap_ms(t->backoff_ms);
                t->backoff_ms = t->backoff_ms * 2 > t->o.backoff_max_ms ? t->o.backoff_max_ms : t->backoff_ms * 2;
                continue;
            }
            t->connected = 1, t->restart_pending = 1, t->reconnects++;
            t->backoff_ms = t->o.backoff_min_ms;
            mim_log_emit(t->o.log, t->o.log_ctx, MIM_LOG_INFO, "%s: reconnected after %.2f s", t->desc,
                         mim_now() - t->t_disconnected);
            deadline = mim_now() + t->o.timeout_ms / 1000.0;
        }
        double left = deadline - mim_now();
        int ms = left > 0 ? (int)ceil(left * 1000) : 0;
        mim_error_t e2 = {0};
        int n = t->kind == MIM__T_SERIAL ? mim__serial_read(t, t->buf, sizeof t->buf, ms, &e2)
                                         : mim__hid_read(t, t->buf, sizeof t->buf, ms, &e2);
        if (n > 0) {
            chunk->kind = MIM_VEST_CHUNK_STREAM;
            chunk->t_us = mim__now_us();
            chunk->data = t->buf, chunk->len = (size_t)n;
            chunk->restart = t->restart_pending;
            t->restart_pending = 0;
            return 1;
        }
        if (n == 0) {
            if (mim_now() >= deadline)
                return mim_error_set(err, -ETIMEDOUT, "%s: no data for %d ms", t->desc, t->o.timeout_ms);
            continue;
        }
        /* the link failed: say so once, then reconnect */
        close_link(t);
        t->connected = 0;
        t->t_disconnected = mim_now();
        if (t->o.no_reconnect) return mim_error_set(err, n, "%s", mim_error_text(&e2));
        mim_log_emit(t->o.log, t->o.log_ctx, MIM_LOG_WARN, "%s; reconnecting", mim_error_text(&e2));
    }
}
