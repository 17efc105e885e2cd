/* Landmark frames: the tracked positions of the landmark map's landmarks,
 * one frame or a batch, as `mimic query`, `transfer`, `morph`, `complete`
 * and the service's API read them (schemas/landmark-frames.schema.json):
 *   {"frames": [{"landmarks": [[x, y, z] | null, ...]}, ...]}  or
 *   {"landmarks": [[x, y, z] | null, ...]}                      (one frame)
 * in the order of the store's landmark map; a frame may also carry
 * "orientations": {"pelvis": [x, y, z, w] | null, ...}; other members
 * are ignored. Read as a stream (json_pull.c): each frame is checked
 * (landmark_values.c) and handed to the caller as soon as its closing
 * brace is read, so that memory is one frame, not the text or a tree of
 * it; mim_landmark_frames_read/_parse gather the frames into arrays, four
 * bytes a coordinate. Malformed JSON is reported with line and column, a
 * bad frame with its number, each in one line. */
#include "json_pull.h"
#include "landmark_values.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* ---- the grammar ---- */

typedef struct scan {
    mim__jp_t jp;
    const char *origin;
    uint32_t n, max_missing;
    mim_landmark_frame_fn fn;
    void *user;
    mim_error_t *err;
    uint32_t index; /* frames handed out */
    float pos[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX];
    double q[4 * MIM_SEGMENTS];
    uint8_t have[MIM_SEGMENTS];
} scan_t;

/* What one frame object (or the top object of one frame) has had. */
typedef struct frame_state {
    int has_lm, has_or;
    mim_error_t or_error; /* told after the landmarks' errors, as ever */
} frame_state_t;

#define KEY_MAX 64
static int key_is(const char *key, size_t len, const char *name) { return len == strlen(name) && !strcmp(key, name); }

/* The value at hand, an array of up to four numbers or anything else. */
static int see(scan_t *s, mim__seen_t *e)
{
    memset(e, 0, sizeof *e);
    int rc = mim__jp_null(&s->jp);
    if (rc) {
        e->kind = MIM__SEEN_NULL;
        return rc < 0 ? rc : 0;
    }
    int c = mim__jp_peek(&s->jp);
    if (c != '[') {
        e->kind = MIM__SEEN_OTHER;
        return mim__jp_skip(&s->jp);
    }
    e->kind = MIM__SEEN_ARRAY;
    int first = 1;
    if ((rc = mim__jp_open(&s->jp)))
        return rc;
    while ((rc = mim__jp_item(&s->jp, &first)) == 1) {
        size_t i = e->count++;
        c = mim__jp_peek(&s->jp);
        if (i < 4 && (c == '-' || (c >= '0' && c <= '9'))) {
            e->isnum[i] = 1;
            rc = mim__jp_number(&s->jp, &e->v[i]);
        } else {
            rc = mim__jp_skip(&s->jp);
        }
        if (rc)
            return rc;
    }
    return rc;
}

/* "landmarks": into s->pos and s->present, checked. Entry errors wait for
 * the count, which comes first. */
static int landmarks_value(scan_t *s, long frame)
{
    int c = mim__jp_peek(&s->jp), rc;
    if (c != '[') {
        if ((rc = mim__jp_skip(&s->jp)))
            return rc;
        return mim__landmarks_not_array(s->origin, frame, s->err);
    }
    if ((rc = mim__jp_open(&s->jp)))
        return rc;
    mim_error_t pending = {0};
    size_t count = 0;
    int first = 1;
    while ((rc = mim__jp_item(&s->jp, &first)) == 1) {
        uint32_t i = (uint32_t)(count < s->n ? count : s->n);
        count++;
        if (i == s->n) { /* only counted */
            if ((rc = mim__jp_skip(&s->jp)))
                return rc;
            continue;
        }
        mim__seen_t e;
        if ((rc = see(s, &e)))
            return rc;
        if (!pending.code)
            mim__landmark_entry(&e, s->origin, frame, i, s->pos, s->present, &pending);
    }
    if (rc < 0)
        return rc;
    return mim__landmarks_close(count, s->n, s->max_missing, &pending, s->origin, frame, s->pos, s->present, s->err);
}

/* "orientations": into s->q and s->have; their errors wait in fs->or_error. */
static int orientations_value(scan_t *s, long frame, frame_state_t *fs)
{
    mim__orient_clear(s->q, s->have);
    int c = mim__jp_peek(&s->jp), rc;
    if (c != '{') {
        if ((rc = mim__jp_skip(&s->jp)))
            return rc;
        mim__orientations_not_object(s->origin, frame, &fs->or_error);
        return 0;
    }
    if ((rc = mim__jp_open(&s->jp)))
        return rc;
    uint32_t seen = 0;
    char key[KEY_MAX];
    size_t len;
    int first = 1;
    while ((rc = mim__jp_member(&s->jp, &first, key, sizeof key, &len)) == 1) {
        int seg = mim__segment_find(key, len);
        if (seg >= 0 && (seen >> seg & 1))
            return mim__jp_fail_key(&s->jp, "duplicate orientation '%s'", key);
        if (seg >= 0)
            seen |= 1u << seg;
        for (char *k = key; *k; k++) /* quoted in a message: one line, no escapes */
            if ((unsigned char)*k < 0x20 || *k == 0x7f) *k = '?';
        mim__seen_t e;
        if ((rc = see(s, &e)))
            return rc;
        if (!fs->or_error.code)
            mim__orientation_entry(key, seg, &e, s->origin, frame, s->q, s->have, &fs->or_error);
    }
    return rc < 0 ? rc : 0;
}

/* A member of a frame: 1 when it was one of the frame's, 0 when it is
 * another's (skipped by the caller), < 0 on error. */
static int frame_member(scan_t *s, const char *key, size_t len, long frame, frame_state_t *fs)
{
    if (key_is(key, len, "landmarks")) {
        if (fs->has_lm)
            return mim__jp_fail_key(&s->jp, "duplicate member \"landmarks\"");
        fs->has_lm = 1;
        int rc = landmarks_value(s, frame);
        return rc ? rc : 1;
    }
    if (key_is(key, len, "orientations")) {
        if (fs->has_or)
            return mim__jp_fail_key(&s->jp, "duplicate member \"orientations\"");
        fs->has_or = 1;
        int rc = orientations_value(s, frame, fs);
        return rc ? rc : 1;
    }
    return 0;
}

/* The frame is read whole: its last checks, then the caller has it. */
static int frame_done(scan_t *s, frame_state_t *fs, long frame)
{
    char wb[600];
    if (!fs->has_lm && fs->has_or)
        return mim_error_set(s->err, MIM_EFORMAT, "%s: \"orientations\" need the frame's \"landmarks\"",
                             mim__where(wb, sizeof wb, s->origin, frame));
    if (!fs->has_lm)
        return mim_error_set(s->err, MIM_EFORMAT, "%s: frame %ld is not an object with \"landmarks\"", s->origin,
                             frame);
    if (fs->or_error.code)
        return mim_error_set(s->err, fs->or_error.code, "%s", fs->or_error.msg);
    if (s->index >= UINT32_MAX / 3 / s->n)
        return mim_error_set(s->err, MIM_EFORMAT, "%s: more than %u frames is too many", s->origin, s->index);
    mim_landmark_frame_t f = {s->index, s->n, s->pos, s->present, fs->has_or ? s->q : NULL,
                              fs->has_or ? s->have : NULL};
    s->index++;
    return s->fn(s->user, &f, s->err);
}

static int frames_value(scan_t *s)
{
    int c = mim__jp_peek(&s->jp), rc, first = 1;
    if (c != '[') {
        if ((rc = mim__jp_skip(&s->jp)))
            return rc;
        return mim_error_set(s->err, MIM_EFORMAT, "%s: \"frames\" must be a non-empty array", s->origin);
    }
    if ((rc = mim__jp_open(&s->jp)))
        return rc;
    while ((rc = mim__jp_item(&s->jp, &first)) == 1) {
        long frame = s->index;
        if (mim__jp_peek(&s->jp) != '{') {
            if ((rc = mim__jp_skip(&s->jp)))
                return rc;
            return mim_error_set(s->err, MIM_EFORMAT, "%s: frame %ld is not an object with \"landmarks\"",
                                 s->origin, frame);
        }
        frame_state_t fs = {0};
        char key[KEY_MAX];
        size_t len;
        int ffirst = 1;
        if ((rc = mim__jp_open(&s->jp)))
            return rc;
        while ((rc = mim__jp_member(&s->jp, &ffirst, key, sizeof key, &len)) == 1)
            if ((rc = frame_member(s, key, len, frame, &fs)) < 0 || (!rc && (rc = mim__jp_skip(&s->jp))))
                return rc;
        if (rc < 0 || (rc = frame_done(s, &fs, frame)))
            return rc;
    }
    if (rc < 0)
        return rc;
    if (s->index == 0)
        return mim_error_set(s->err, MIM_EFORMAT, "%s: \"frames\" must be a non-empty array", s->origin);
    return 0;
}

/* The top object: "frames", or one frame's members. */
static int scan_top(scan_t *s)
{
    int c = mim__jp_peek(&s->jp), rc, first = 1, has_frames = 0;
    if (c != '{')
        return mim__jp_expected(&s->jp, c, "an object with \"frames\" or \"landmarks\"");
    if ((rc = mim__jp_open(&s->jp)))
        return rc;
    frame_state_t fs = {0};
    char key[KEY_MAX];
    size_t len;
    while ((rc = mim__jp_member(&s->jp, &first, key, sizeof key, &len)) == 1) {
        int is_frames = key_is(key, len, "frames");
        if (is_frames && has_frames)
            return mim__jp_fail_key(&s->jp, "duplicate member \"frames\"");
        if ((is_frames && fs.has_lm) || (has_frames && key_is(key, len, "landmarks")))
            return mim_error_set(s->err, MIM_EFORMAT, "%s: has both \"frames\" and \"landmarks\"; use one", s->origin);
        /* left out, they would be dropped without a word */
        if ((is_frames && fs.has_or) || (has_frames && key_is(key, len, "orientations")))
            return mim_error_set(s->err, MIM_EFORMAT, "%s: \"orientations\" belong in each frame of \"frames\"",
                                 s->origin);
        if (is_frames) {
            has_frames = 1;
            rc = frames_value(s);
        } else if (!(rc = frame_member(s, key, len, 0, &fs))) {
            rc = mim__jp_skip(&s->jp);
        }
        if (rc < 0)
            return rc;
    }
    if (rc < 0)
        return rc;
    if (has_frames)
        rc = 0;
    else if (fs.has_lm)
        rc = frame_done(s, &fs, 0);
    else if (fs.has_or)
        rc = mim_error_set(s->err, MIM_EFORMAT, "%s: \"orientations\" need the frame's \"landmarks\"", s->origin);
    else
        rc = mim_error_set(s->err, MIM_EFORMAT, "%s: no \"frames\" or \"landmarks\" member", s->origin);
    return rc ? rc : mim__jp_end(&s->jp);
}

static int scan_run(scan_t *s, const char *text, size_t len, mim__jp_refill_fn refill, void *src)
{
    mim__jp_init(&s->jp, text, len, refill, src, s->origin, s->err);
    return scan_top(s);
}

static int scan_new(scan_t **out, const char *origin, uint32_t n, uint32_t max_missing, mim_landmark_frame_fn fn,
                    void *user, mim_error_t *err)
{
    *out = NULL;
    if (n < MIM_LANDMARKS_MIN || n > MIM_LANDMARKS_MAX || !fn)
        return mim_error_set(err, MIM_EINVAL, "%s: bad arguments (%u landmarks)", origin, n);
    scan_t *s = calloc(1, sizeof *s);
    if (!s)
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
    *s = (scan_t){.origin = origin, .n = n, .max_missing = max_missing, .fn = fn, .user = user, .err = err};
    *out = s;
    return 0;
}

int mim_landmark_frames_scan(const char *text, size_t len, const char *origin, uint32_t n_landmarks,
                             uint32_t max_missing, mim_landmark_frame_fn fn, void *user, mim_error_t *err)
{
    scan_t *s;
    origin = origin ? origin : "landmark frames";
    if (!text)
        return mim_error_set(err, MIM_EINVAL, "%s: bad arguments (no text)", origin);
    int rc = scan_new(&s, origin, n_landmarks, max_missing, fn, user, err);
    if (!rc)
        rc = scan_run(s, text, len, NULL, NULL);
    free(s);
    return rc;
}

/* ---- a file, a chunk at a time, at most MIM_LANDMARK_FRAMES_MAX_BYTES ---- */

typedef struct file_src {
    FILE *f;
    const char *path;
    size_t total;
    unsigned char buf[1 << 16];
} file_src_t;

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

static int file_refill(mim__jp_t *jp)
{
    file_src_t *fs = jp->src;
    size_t want = MIM_LANDMARK_FRAMES_MAX_BYTES - fs->total;
    if (want == 0) { /* one byte more tells whether there is more than the cap */
        if (fgetc(fs->f) == EOF && !ferror(fs->f))
            return 0;
        if (!ferror(fs->f))
            return too_big(fs->path, (unsigned long long)fs->total, 1, jp->err);
    }
    size_t got = want ? fread(fs->buf, 1, want < sizeof fs->buf ? want : sizeof fs->buf, fs->f) : 0;
    if (got == 0)
        return ferror(fs->f) ? mim_error_set(jp->err, MIM_EIO, "%s: read error: %s", fs->path, strerror(errno)) : 0;
    fs->total += got;
    jp->p = fs->buf;
    jp->end = fs->buf + got;
    return 1;
}

int mim_landmark_frames_scan_file(const char *path, uint32_t n_landmarks, uint32_t max_missing,
                                  mim_landmark_frame_fn fn, void *user, mim_error_t *err)
{
    if (!path)
        return mim_error_set(err, MIM_EINVAL, "landmark frames: bad arguments (no path)");
    scan_t *s;
    int rc = scan_new(&s, path, n_landmarks, max_missing, fn, user, err);
    if (rc)
        return rc;
    file_src_t *src = malloc(sizeof *src);
    FILE *f = src ? fopen(path, "rb") : NULL;
    struct stat st;
    if (!src)
        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    else if (!f)
        rc = mim_error_set(err, errno == ENOENT ? MIM_ENOTFOUND : MIM_EIO, "%s: cannot open: %s", path,
                           strerror(errno));
    else if (fstat(fileno(f), &st) == 0 && S_ISREG(st.st_mode) &&
             (uint64_t)st.st_size > MIM_LANDMARK_FRAMES_MAX_BYTES)
        rc = too_big(path, (unsigned long long)st.st_size, 0, err);
    if (!rc) {
        src->f = f, src->path = path, src->total = 0;
        rc = scan_run(s, NULL, 0, file_refill, src);
    }
    if (f)
        fclose(f);
    free(src);
    free(s);
    return rc;
}

/* ---- frames gathered into arrays ---- */

typedef struct gather {
    mim_landmark_frames_t *out;
    uint32_t cap;
} gather_t;

static int gather_grow(gather_t *g, uint32_t cap)
{
    mim_landmark_frames_t *o = g->out;
    size_t n = o->n_landmarks;
    float *p = realloc(o->positions, cap * n * 3 * sizeof(float));
    if (p)
        o->positions = p;
    uint8_t *pr = p ? realloc(o->present, cap * n) : NULL;
    if (pr)
        o->present = pr;
    if (!pr)
        return -1;
    if (o->orientations) {
        double *q = realloc(o->orientations, (size_t)cap * MIM_SEGMENTS * 4 * sizeof(double));
        if (q)
            o->orientations = q;
        uint8_t *h = q ? realloc(o->orient_present, (size_t)cap * MIM_SEGMENTS) : NULL;
        if (h)
            o->orient_present = h;
        if (!h)
            return -1;
    }
    g->cap = cap;
    return 0;
}

static int gather_frame(void *user, const mim_landmark_frame_t *f, mim_error_t *err)
{
    gather_t *g = user;
    mim_landmark_frames_t *o = g->out;
    size_t n = f->n_landmarks, i = o->n_frames;
    o->n_landmarks = f->n_landmarks;
    if (i == g->cap && gather_grow(g, g->cap ? (g->cap > UINT32_MAX / 2 ? UINT32_MAX : 2 * g->cap) : 1))
        return mim_error_set(err, MIM_ENOMEM, "out of memory for %zu frames", i + 1);
    if (f->orientations && !o->orientations) { /* the first frame that has them: the earlier ones had none */
        o->orientations = malloc((size_t)g->cap * MIM_SEGMENTS * 4 * sizeof(double));
        o->orient_present = malloc((size_t)g->cap * MIM_SEGMENTS);
        if (!o->orientations || !o->orient_present)
            return mim_error_set(err, MIM_ENOMEM, "out of memory for %zu frames", i + 1);
        for (size_t k = 0; k < i; k++)
            mim__orient_clear(o->orientations + k * MIM_SEGMENTS * 4, o->orient_present + k * MIM_SEGMENTS);
    }
    memcpy(o->positions + i * n * 3, f->positions, n * 3 * sizeof(float));
    memcpy(o->present + i * n, f->present, n);
    if (o->orientations && f->orientations) {
        memcpy(o->orientations + i * MIM_SEGMENTS * 4, f->orientations, MIM_SEGMENTS * 4 * sizeof(double));
        memcpy(o->orient_present + i * MIM_SEGMENTS, f->orient_present, MIM_SEGMENTS);
    } else if (o->orientations) {
        mim__orient_clear(o->orientations + i * MIM_SEGMENTS * 4, o->orient_present + i * MIM_SEGMENTS);
    }
    o->n_frames++;
    return 0;
}

/* The scan's result: on error nothing is kept. (The capacity past the
 * last frame is never written, so it takes no memory.) */
static int gathered(int rc, gather_t *g)
{
    if (rc)
        mim_landmark_frames_free(g->out);
    return rc;
}

int mim_landmark_frames_parse(const char *text, size_t len, const char *origin, uint32_t n_landmarks,
                              uint32_t max_missing, mim_landmark_frames_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    gather_t g = {out, 0};
    return gathered(mim_landmark_frames_scan(text, len, origin, n_landmarks, max_missing, gather_frame, &g, err), &g);
}

int mim_landmark_frames_read(const char *path, uint32_t n_landmarks, uint32_t max_missing,
                             mim_landmark_frames_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    gather_t g = {out, 0};
    return gathered(mim_landmark_frames_scan_file(path, n_landmarks, max_missing, gather_frame, &g, err), &g);
}

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
