/* Landmark frames: the tracked positions of the landmark map's landmarks,
 * one frame or a batch, as `mimic query` and `mimic transfer` read them
 * (schemas/landmark-frames.schema.json):
 *   {"frames": [{"landmarks": [[x, y, z] | null, ...]}, ...]}  or
 *   {"landmarks": [[x, y, z] | null, ...]}                      (one frame)
 * in the order of the store's landmark map. null marks a landmark the
 * tracker lost. JSON through jansson: malformed text is reported with line
 * and column; a wrong count or a bad coordinate names the frame and the
 * landmark. Each frame must be a plausible skeleton (plausible.c). A file
 * is read through a counting callback so that input past
 * MIM_LANDMARK_FRAMES_MAX_BYTES is refused however it arrives (a pipe has
 * no size): jansson's tree takes several times the text's size. */
#include "mim_core.h"

#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

void mim_landmark_frames_free(mim_landmark_frames_t *f)
{
    if (!f)
        return;
    free(f->positions);
    free(f->present);
    memset(f, 0, sizeof *f);
}

/* "origin" or "origin: frame F": the start of every message below. */
static const char *where(char *buf, size_t size, const char *origin, long frame)
{
    if (frame < 0)
        return origin;
    snprintf(buf, size, "%s: frame %ld", origin, frame);
    return buf;
}

int mim_landmark_array_parse(const json_t *lm, uint32_t n, uint32_t max_missing, const char *origin, long frame,
                             float *pos, uint8_t *present, mim_error_t *err)
{
    char wb[600];
    if (!origin)
        origin = "landmarks";
    if (!json_is_array(lm))
        return mim_error_set(err, MIM_EFORMAT, "%s: \"landmarks\" must be an array",
                             where(wb, sizeof wb, origin, frame));
    if (json_array_size(lm) != n)
        return mim_error_set(err, MIM_EFORMAT, "%s has %zu landmarks, the landmark map has %u",
                             where(wb, sizeof wb, origin, frame), json_array_size(lm), n);
    uint32_t missing = 0;
    for (uint32_t i = 0; i < n; i++) {
        json_t *p = json_array_get(lm, i);
        if (json_is_null(p)) {
            present[i] = 0;
            pos[3 * i] = pos[3 * i + 1] = pos[3 * i + 2] = NAN;
            missing++;
            continue;
        }
        if (!json_is_array(p) || json_array_size(p) != 3)
            return mim_error_set(err, MIM_EFORMAT, "%s, landmark %u: expected [x, y, z] or null",
                                 where(wb, sizeof wb, origin, frame), i);
        for (int c = 0; c < 3; c++) {
            json_t *v = json_array_get(p, (size_t)c);
            if (!json_is_number(v))
                return mim_error_set(err, MIM_EFORMAT, "%s, landmark %u: %c is not a number",
                                     where(wb, sizeof wb, origin, frame), i, "xyz"[c]);
            double x = json_number_value(v);
            if (!isfinite(x) || !isfinite((float)x))
                return mim_error_set(err, MIM_ENONFINITE, "%s, landmark %u: %c = %g is not a finite float",
                                     where(wb, sizeof wb, origin, frame), i, "xyz"[c], x);
            pos[3 * i + (uint32_t)c] = (float)x;
        }
        present[i] = 1;
    }
    if (missing > max_missing)
        return mim_error_set(err, MIM_EFORMAT, "%s has %u missing landmarks, at most %u allowed",
                             where(wb, sizeof wb, origin, frame), missing, max_missing);
    /* finite numbers, but a body? (one place for files, the API and UDP) */
    return mim_landmarks_check(pos, present, n, origin, frame, err);
}

static int parse_root(json_t *root, const char *origin, uint32_t n, uint32_t max_missing,
                      mim_landmark_frames_t *out, mim_error_t *err)
{
    if (!json_is_object(root))
        return mim_error_set(err, MIM_EFORMAT, "%s: expected an object with \"frames\" or \"landmarks\"",
                             origin);
    json_t *frames = json_object_get(root, "frames");
    json_t *single = json_object_get(root, "landmarks");
    if (frames && single)
        return mim_error_set(err, MIM_EFORMAT, "%s: has both \"frames\" and \"landmarks\"; use one", origin);
    size_t nf;
    if (frames) {
        if (!json_is_array(frames) || json_array_size(frames) == 0)
            return mim_error_set(err, MIM_EFORMAT, "%s: \"frames\" must be a non-empty array", origin);
        nf = json_array_size(frames);
    } else if (single) {
        nf = 1;
    } else {
        return mim_error_set(err, MIM_EFORMAT, "%s: no \"frames\" or \"landmarks\" member", origin);
    }
    if (nf > UINT32_MAX / 3 / (n ? n : 1))
        return mim_error_set(err, MIM_EFORMAT, "%s: %zu frames is too many", origin, nf);
    out->positions = malloc(nf * n * 3 * sizeof(float));
    out->present = malloc(nf * n);
    if (!out->positions || !out->present)
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %zu frames", origin, nf);
    out->n_frames = (uint32_t)nf;
    out->n_landmarks = n;
    for (size_t f = 0; f < nf; f++) {
        json_t *lm = single;
        if (frames) {
            json_t *fr = json_array_get(frames, f);
            lm = json_is_object(fr) ? json_object_get(fr, "landmarks") : NULL;
            if (!lm)
                return mim_error_set(err, MIM_EFORMAT, "%s: frame %zu is not an object with \"landmarks\"",
                                     origin, f);
        }
        int rc = mim_landmark_array_parse(lm, n, max_missing, origin, (long)f, out->positions + f * n * 3,
                                          out->present + f * n, err);
        if (rc)
            return rc;
    }
    return 0;
}

static int finish(json_t *root, const char *origin, uint32_t n, uint32_t max_missing,
                  mim_landmark_frames_t *out, mim_error_t *err)
{
    int rc = parse_root(root, origin, n, max_missing, out, err);
    json_decref(root);
    if (rc)
        mim_landmark_frames_free(out);
    return rc;
}

int mim_landmark_frames_parse(const char *text, size_t len, const char *origin, uint32_t n_landmarks,
                              uint32_t max_missing, mim_landmark_frames_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!text || n_landmarks < MIM_LANDMARKS_MIN || n_landmarks > MIM_LANDMARKS_MAX)
        return mim_error_set(err, MIM_EINVAL, "%s: bad arguments (%u landmarks)", origin ? origin : "frames",
                             n_landmarks);
    origin = origin ? origin : "landmark frames";
    json_error_t je;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
    if (!root)
        return mim_error_set(err, MIM_EFORMAT, "%s:%d:%d: %s", origin, je.line, je.column, je.text);
    return finish(root, origin, n_landmarks, max_missing, out, err);
}

/* jansson pulls the file through this, so the cap holds for pipes too and
 * the text is never held whole. */
typedef struct {
    FILE *f;
    size_t total, limit;
    int over;
} capped_t;

static size_t capped_read(void *buf, size_t size, void *data)
{
    capped_t *c = data;
    if (c->total >= c->limit) {
        /* one byte more tells whether there is more than the limit */
        int ch = fgetc(c->f);
        if (ch == EOF)
            return 0;
        c->over = 1;
        return (size_t)-1;
    }
    size_t want = c->limit - c->total < size ? c->limit - c->total : size;
    size_t got = fread(buf, 1, want, c->f);
    c->total += got;
    return got;
}

static int too_big(const char *path, unsigned long long bytes, int stopped, mim_error_t *err)
{
    if (stopped) /* a pipe: how much more there was is not known */
        return mim_error_set(err, MIM_EUNSUPPORTED,
                             "%s: more than the %zu MiB a landmark batch may have (stopped reading at %llu bytes): split it into smaller files",
                             path, MIM_LANDMARK_FRAMES_MAX_BYTES >> 20, bytes);
    return mim_error_set(err, MIM_EUNSUPPORTED,
                         "%s: %llu bytes (%.1f MiB), more than the %zu MiB a landmark batch may have: split it into smaller files",
                         path, bytes, (double)bytes / (1 << 20), MIM_LANDMARK_FRAMES_MAX_BYTES >> 20);
}

int mim_landmark_frames_read(const char *path, uint32_t n_landmarks, uint32_t max_missing,
                             mim_landmark_frames_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!path || n_landmarks < MIM_LANDMARKS_MIN || n_landmarks > MIM_LANDMARKS_MAX)
        return mim_error_set(err, MIM_EINVAL, "landmark frames: bad arguments (%u landmarks)", n_landmarks);
    FILE *f = fopen(path, "rb");
    if (!f)
        return mim_error_set(err, errno == ENOENT ? MIM_ENOTFOUND : MIM_EIO, "%s: cannot open: %s", path,
                             strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && S_ISREG(st.st_mode) && (uint64_t)st.st_size > MIM_LANDMARK_FRAMES_MAX_BYTES) {
        fclose(f);
        return too_big(path, (unsigned long long)st.st_size, 0, err);
    }
    capped_t c = {f, 0, MIM_LANDMARK_FRAMES_MAX_BYTES, 0};
    json_error_t je;
    json_t *root = json_load_callback(capped_read, &c, JSON_REJECT_DUPLICATES, &je);
    int rerr = ferror(f);
    fclose(f);
    if (c.over) {
        json_decref(root);
        return too_big(path, (unsigned long long)c.total, 1, err);
    }
    if (!root)
        return mim_error_set(err, rerr ? MIM_EIO : MIM_EFORMAT, "%s:%d:%d: %s", path, je.line, je.column,
                             je.text);
    return finish(root, path, n_landmarks, max_missing, out, err);
}
