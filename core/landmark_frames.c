/* Landmark frames: the tracked positions of the landmark map's landmarks,
 * one frame or a batch, as `mimic query` and `mimic transfer` read them
 * (schemas/landmark-frames.schema.json):
 *   {"frames": [{"landmarks": [[x, y, z] | null, ...]}, ...]}  or
 *   {"landmarks": [[x, y, z] | null, ...]}                      (one frame)
 * in the order of the store's landmark map. null marks a landmark the
 * tracker lost. A frame may also carry the vest's segment orientations,
 * "orientations": {"pelvis": [x, y, z, w] | null, ...} (issue 17). JSON
 * through jansson: malformed text is reported with line and column; a
 * wrong count or a bad coordinate names the frame and the landmark (or the
 * segment). Each frame must be a plausible skeleton (plausible.c). A file
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
    free(f->orientations);
    free(f->orient_present);
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

/* identity, not given */
static void orient_clear(double *q, uint8_t *have)
{
    for (int s = 0; s < MIM_SEGMENTS; s++) {
        q[4 * s] = q[4 * s + 1] = q[4 * s + 2] = 0, q[4 * s + 3] = 1;
        have[s] = 0;
    }
}

int mim_orientations_parse(const json_t *obj, const char *origin, long frame, double *q, uint8_t *have,
                           mim_error_t *err)
{
    char wb[600];
    if (!origin)
        origin = "orientations";
    orient_clear(q, have);
    if (!json_is_object(obj))
        return mim_error_set(err, MIM_EFORMAT, "%s: \"orientations\" must be an object",
                             where(wb, sizeof wb, origin, frame));
    const char *key;
    json_t *v;
    json_object_foreach((json_t *)obj, key, v) {
        int s = 0;
        while (s < MIM_SEGMENTS && strcmp(key, mim_segment_names[s]))
            s++;
        if (s == MIM_SEGMENTS) {
            char names[256];
            size_t k = 0;
            for (int i = 0; i < MIM_SEGMENTS; i++)
                k += (size_t)snprintf(names + k, sizeof names - k, "%s%s", i ? ", " : "", mim_segment_names[i]);
            return mim_error_set(err, MIM_EFORMAT, "%s: orientation '%.40s' is not a vest segment (%s)",
                                 where(wb, sizeof wb, origin, frame), key, names);
        }
        if (json_is_null(v))
            continue; /* a lost sensor */
        if (!json_is_array(v) || json_array_size(v) != 4)
            return mim_error_set(err, MIM_EFORMAT, "%s, orientation '%s': expected [x, y, z, w] or null",
                                 where(wb, sizeof wb, origin, frame), key);
        double c[4], big = 0;
        for (int i = 0; i < 4; i++) {
            json_t *x = json_array_get(v, (size_t)i);
            if (!json_is_number(x))
                return mim_error_set(err, MIM_EFORMAT, "%s, orientation '%s': %c is not a number",
                                     where(wb, sizeof wb, origin, frame), key, "xyzw"[i]);
            c[i] = json_number_value(x);
            if (!isfinite(c[i])) /* jansson refuses these today; a future reader may not */
                return mim_error_set(err, MIM_ENONFINITE, "%s, orientation '%s': %c = %g is not finite",
                                     where(wb, sizeof wb, origin, frame), key, "xyzw"[i], c[i]);
            big = fmax(big, fabs(c[i]));
        }
        /* scaled, so that [1e200, 0, 0, 0] reports its norm, not inf */
        double norm = 0;
        for (int i = 0; big > 0 && i < 4; i++)
            norm += (c[i] / big) * (c[i] / big);
        norm = big * sqrt(norm);
        if (!(fabs(norm - 1) <= MIM_ORIENT_UNIT_TOL))
            return mim_error_set(err, MIM_EFORMAT, "%s: orientation '%s' is not a unit quaternion (norm %.3g)",
                                 where(wb, sizeof wb, origin, frame), key, norm);
        for (int i = 0; i < 4; i++)
            q[4 * s + i] = c[i] / norm;
        have[s] = 1;
    }
    return 0;
}

static int parse_root(json_t *root, const char *origin, uint32_t n, uint32_t max_missing,
                      mim_landmark_frames_t *out, mim_error_t *err)
{
    if (!json_is_object(root))
        return mim_error_set(err, MIM_EFORMAT, "%s: expected an object with \"frames\" or \"landmarks\"",
                             origin);
    json_t *frames = json_object_get(root, "frames");
    json_t *single = json_object_get(root, "landmarks");
    json_t *single_or = json_object_get(root, "orientations");
    if (frames && single)
        return mim_error_set(err, MIM_EFORMAT, "%s: has both \"frames\" and \"landmarks\"; use one", origin);
    size_t nf;
    int any_or = 0;
    if (frames) {
        if (!json_is_array(frames) || json_array_size(frames) == 0)
            return mim_error_set(err, MIM_EFORMAT, "%s: \"frames\" must be a non-empty array", origin);
        /* left out, they would be dropped without a word */
        if (single_or)
            return mim_error_set(err, MIM_EFORMAT, "%s: \"orientations\" belong in each frame of \"frames\"",
                                 origin);
        nf = json_array_size(frames);
        for (size_t f = 0; f < nf && !any_or; f++)
            any_or = json_object_get(json_array_get(frames, f), "orientations") != NULL;
    } else if (single) {
        nf = 1;
        any_or = single_or != NULL;
    } else if (single_or) {
        return mim_error_set(err, MIM_EFORMAT, "%s: \"orientations\" need the frame's \"landmarks\"", origin);
    } else {
        return mim_error_set(err, MIM_EFORMAT, "%s: no \"frames\" or \"landmarks\" member", origin);
    }
    if (nf > UINT32_MAX / 3 / (n ? n : 1))
        return mim_error_set(err, MIM_EFORMAT, "%s: %zu frames is too many", origin, nf);
    out->positions = malloc(nf * n * 3 * sizeof(float));
    out->present = malloc(nf * n);
    if (any_or) {
        out->orientations = malloc(nf * MIM_SEGMENTS * 4 * sizeof(double));
        out->orient_present = malloc(nf * MIM_SEGMENTS);
    }
    if (!out->positions || !out->present || (any_or && (!out->orientations || !out->orient_present)))
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %zu frames", origin, nf);
    out->n_frames = (uint32_t)nf;
    out->n_landmarks = n;
    for (size_t f = 0; f < nf; f++) {
        json_t *lm = single, *orient = single_or;
        if (frames) {
            json_t *fr = json_array_get(frames, f);
            lm = json_is_object(fr) ? json_object_get(fr, "landmarks") : NULL;
            orient = json_is_object(fr) ? json_object_get(fr, "orientations") : NULL;
            if (!lm && orient)
                return mim_error_set(err, MIM_EFORMAT, "%s: frame %zu: \"orientations\" need the frame's \"landmarks\"",
                                     origin, f);
            if (!lm)
                return mim_error_set(err, MIM_EFORMAT, "%s: frame %zu is not an object with \"landmarks\"",
                                     origin, f);
        }
        int rc = mim_landmark_array_parse(lm, n, max_missing, origin, (long)f, out->positions + f * n * 3,
                                          out->present + f * n, err);
        if (!rc && any_or) {
            double *q = out->orientations + f * MIM_SEGMENTS * 4;
            uint8_t *have = out->orient_present + f * MIM_SEGMENTS;
            if (orient) {
                rc = mim_orientations_parse(orient, origin, (long)f, q, have, err);
            } else {
                orient_clear(q, have);
            }
        }
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
