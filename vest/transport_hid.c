/* HID transport: trackers and dongles that present themselves as HID
 * devices carry the same stream in their reports. Report layout (mimic's,
 * schemas/vest-protocol.md): byte 0 counts the stream bytes that follow
 * (0..63). The device layer is a table of functions so tests can substitute
 * it; the real one is hidapi (hidraw backend). */
#include "transport_internal.h"

#include <errno.h>
#include <hidapi/hidapi.h>
#include <stdlib.h>
#include <string.h>
#include <wchar.h>

static void *hidapi_open(void *ctx, uint16_t vid, uint16_t pid, const char *serial)
{
    (void)ctx;
    if (hid_init()) return NULL;
    wchar_t ws[128];
    if (serial && serial[0]) {
        size_t n = mbstowcs(ws, serial, 127);
        if (n == (size_t)-1) return NULL;
        ws[n] = 0;
    }
    return hid_open(vid, pid, serial && serial[0] ? ws : NULL);
}

static int hidapi_read(void *ctx, void *dev, uint8_t *buf, size_t len, int ms)
{
    (void)ctx;
    return hid_read_timeout(dev, buf, len, ms);
}

static int hidapi_write(void *ctx, void *dev, const uint8_t *buf, size_t len)
{
    (void)ctx;
    return hid_write(dev, buf, len);
}

static void hidapi_close(void *ctx, void *dev)
{
    (void)ctx;
    if (dev) hid_close(dev);
    hid_exit(); /* one vest per process: release hidapi's udev state too */
}

static const char *hidapi_error(void *ctx, void *dev)
{
    (void)ctx;
    static char msg[256];
    const wchar_t *w = hid_error(dev);
    if (!w) return NULL;
    if (wcstombs(msg, w, sizeof msg - 1) == (size_t)-1) return NULL;
    msg[sizeof msg - 1] = 0;
    return msg;
}

static const mim_vest_hid_layer_t hidapi_layer = {NULL, hidapi_open, hidapi_read, hidapi_write, hidapi_close,
                                                  hidapi_error};

const mim_vest_hid_layer_t *mim_vest_hid_layer_hidapi(void) { return &hidapi_layer; }

static const char *why(mim_vest_transport_t *t, void *dev)
{
    const char *w = t->hid->error ? t->hid->error(t->hid->ctx, dev) : NULL;
    return w && w[0] ? w : "no such device";
}

int mim__hid_open(mim_vest_transport_t *t, mim_error_t *err)
{
    t->dev = t->hid->open(t->hid->ctx, t->vid, t->pid, t->serial);
    if (!t->dev)
        return mim_error_set(err, -ENODEV, "%s: cannot open (%s; is the vest plugged in?)", t->desc, why(t, NULL));
    return 0;
}

int mim__hid_read(mim_vest_transport_t *t, uint8_t *buf, size_t cap, int ms, mim_error_t *err)
{
    uint8_t rep[MIM_VEST_HID_REPORT];
    int n = t->hid->read_timeout(t->hid->ctx, t->dev, rep, sizeof rep, ms);
    if (n < 0) return mim_error_set(err, -ENODEV, "%s: read error (%s)", t->desc, why(t, t->dev));
    if (n == 0) return 0;
    size_t k = rep[0];
    if (k > (size_t)n - 1) k = (size_t)n - 1; /* a short report: keep what is there */
    if (k > cap) k = cap;
    memcpy(buf, rep + 1, k);
    return (int)k; /* 0 for an empty report: the caller waits on */
}

int mim__hid_write(mim_vest_transport_t *t, const uint8_t *buf, size_t n, mim_error_t *err)
{
    /* report id 0, then the count and up to 63 bytes */
    while (n) {
        uint8_t rep[1 + MIM_VEST_HID_REPORT] = {0};
        size_t k = n < MIM_VEST_HID_REPORT - 1 ? n : MIM_VEST_HID_REPORT - 1;
        rep[1] = (uint8_t)k;
        memcpy(rep + 2, buf, k);
        if (t->hid->write(t->hid->ctx, t->dev, rep, sizeof rep) < 0)
            return mim_error_set(err, -EIO, "%s: write error (%s)", t->desc, why(t, t->dev));
        buf += k, n -= k;
    }
    return 0;
}

void mim__hid_close(mim_vest_transport_t *t)
{
    if (t->dev) t->hid->close(t->hid->ctx, t->dev);
    t->dev = NULL;
}
