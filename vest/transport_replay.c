/* Recording files and their replay (schemas/vest-recording.md): a 16-byte
 * header ("MIMVEST1", version, response header flags), then one record per
 * chunk as the link delivered it, with its time, so a replay reproduces the
 * stream byte for byte and, when asked, with its original timing. */
#include "transport_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define MAGIC "MIMVEST1"
#define VERSION 1u
#define REC_HDR 16u
#define REC_MAX (MIM__T_BUF)

static void le32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static void le64(uint8_t *p, uint64_t v) { for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static uint32_t rd32(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; }
static uint64_t rd64(const uint8_t *p) { return (uint64_t)rd32(p) | (uint64_t)rd32(p + 4) << 32; }

struct mim_vest_recorder {
    FILE *f;
    char path[4096];
    int failed;
};

int mim_vest_recorder_open(mim_vest_recorder_t **out, const char *path, uint32_t header_flags, mim_error_t *err)
{
    *out = NULL;
    mim_vest_recorder_t *r = calloc(1, sizeof *r);
    if (!r) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    snprintf(r->path, sizeof r->path, "%s", path);
    r->f = fopen(path, "wb");
    if (!r->f) {
        int e = errno;
        free(r);
        return mim_error_set(err, -e, "%s: cannot create (%s)", path, strerror(e));
    }
    uint8_t h[16];
    memcpy(h, MAGIC, 8);
    le32(h + 8, VERSION);
    le32(h + 12, header_flags ? header_flags : MIM_VEST_HDR_DEFAULT);
    if (fwrite(h, 1, 16, r->f) != 16) {
        int e = errno;
        fclose(r->f), free(r);
        return mim_error_set(err, -e, "%s: write error (%s)", path, strerror(e));
    }
    *out = r;
    return 0;
}

int mim_vest_recorder_write(mim_vest_recorder_t *r, const mim_vest_chunk_t *c, mim_error_t *err)
{
    if (!r || !c || (c->len && !c->data)) return mim_error_set(err, MIM_EINVAL, "recorder: bad chunk");
    if (c->len > REC_MAX) return mim_error_set(err, MIM_EINVAL, "%s: chunk of %zu bytes", r->path, c->len);
    uint8_t h[REC_HDR] = {0};
    h[0] = (uint8_t)c->kind;
    h[1] = c->restart ? 1 : 0;
    le32(h + 4, (uint32_t)c->len);
    le64(h + 8, c->t_us);
    if (fwrite(h, 1, REC_HDR, r->f) != REC_HDR || fwrite(c->data, 1, c->len, r->f) != c->len) {
        r->failed = errno ? errno : EIO;
        return mim_error_set(err, -r->failed, "%s: write error (%s)", r->path, strerror(r->failed));
    }
    return 0;
}

int mim_vest_recorder_close(mim_vest_recorder_t **rp, mim_error_t *err)
{
    if (!rp || !*rp) return 0;
    mim_vest_recorder_t *r = *rp;
    int rc = 0;
    if (fflush(r->f) || fsync(fileno(r->f))) rc = mim_error_set(err, -errno, "%s: write error (%s)", r->path, strerror(errno));
    if (fclose(r->f) && !rc) rc = mim_error_set(err, -errno, "%s: close error (%s)", r->path, strerror(errno));
    if (r->failed && !rc) rc = mim_error_set(err, -r->failed, "%s: write error", r->path);
    free(r);
    *rp = NULL;
    return rc;
}

int mim__replay_open(mim_vest_transport_t *t, const char *path, mim_error_t *err)
{
    t->f = fopen(path, "rb");
    if (!t->f) return mim_error_set(err, -errno, "%s: %s", path, strerror(errno));
    uint8_t h[16];
    size_t n = fread(h, 1, 16, t->f);
    if (n != 16 || memcmp(h, MAGIC, 8)) {
        fclose(t->f), t->f = NULL;
        return mim_error_set(err, MIM_EFORMAT, "%s: not a vest recording (no MIMVEST1 header)", path);
    }
    if (rd32(h + 8) != VERSION) {
        fclose(t->f), t->f = NULL;
        return mim_error_set(err, MIM_EUNSUPPORTED, "%s: recording version %u (this mimic reads %u)", path,
                             rd32(h + 8), VERSION);
    }
    t->header_flags = rd32(h + 12) & MIM_VEST_HDR_ALL;
    if (!t->header_flags) t->header_flags = MIM_VEST_HDR_DEFAULT;
    t->offset = 16;
    return 0;
}

int mim__replay_read(mim_vest_transport_t *t, mim_vest_chunk_t *c, mim_error_t *err)
{
    uint8_t h[REC_HDR];
    size_t n = fread(h, 1, REC_HDR, t->f);
    if (n == 0 && feof(t->f)) return 0;
    if (n != REC_HDR)
        return ferror(t->f) ? mim_error_set(err, MIM_EIO, "%s: read error at byte %llu", t->desc, (unsigned long long)t->offset)
                            : mim_error_set(err, MIM_ETRUNCATED, "%s: record at byte %llu is cut short", t->desc,
                                            (unsigned long long)t->offset);
    uint32_t len = rd32(h + 4);
    if ((h[0] != MIM_VEST_CHUNK_STREAM && h[0] != MIM_VEST_CHUNK_LANDMARKS) || len > REC_MAX)
        return mim_error_set(err, MIM_EFORMAT, "%s: bad record at byte %llu (kind %u, %u bytes)", t->desc,
                             (unsigned long long)t->offset, h[0], len);
    if (fread(t->buf, 1, len, t->f) != len)
        return mim_error_set(err, MIM_ETRUNCATED, "%s: record at byte %llu is cut short", t->desc,
                             (unsigned long long)t->offset);
    t->offset += REC_HDR + len;
    c->kind = h[0];
    c->restart = h[1] & 1;
    c->t_us = rd64(h + 8);
    c->data = t->buf, c->len = len;
    if (t->o.realtime) {
        if (!t->started) t->started = 1, t->t0_rec = c->t_us, t->t0_wall = mim_now();
        double due = t->t0_wall + (c->t_us >= t->t0_rec ? (double)(c->t_us - t->t0_rec) / 1e6 : 0);
        double d = due - mim_now();
        if (d > 0) {
            struct timespec ts = {(time_t)d, (long)((d - floor(d)) * 1e9)};
            while (nanosleep(&ts, &ts) && errno == EINTR) {
            }
        }
    }
    return 1;
}

void mim__replay_close(mim_vest_transport_t *t)
{
    if (t->f) fclose(t->f);
    t->f = NULL;
}
