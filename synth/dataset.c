/* Writing a dataset: one binary PLY per body, manifest.csv, landmarks.json.
 *
 * Every file goes through mim_file_write_atomic (a temporary beside it,
 * fsync, rename), so readers (and a run killed half-way) never see a
 * partial file. The manifest and landmark map come last: their presence
 * means the bodies they list are all there. Bytes are packed explicitly
 * little-endian so the files are identical on any host. */
#include "synth_internal.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>

static int mkdirs(const char *dir, mim_error_t *err)
{
    size_t n = strlen(dir);
    char *p = malloc(n + 1);
    if (!p) return mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
    memcpy(p, dir, n + 1);
    for (size_t i = 1; i <= n; i++) {
        if (p[i] != '/' && p[i] != '\0') continue;
        char c = p[i];
        p[i] = '\0';
        if (mkdir(p, 0777) != 0 && errno != EEXIST) {
            int e = errno;
            int rc = mim_error_set(err, -e, "%s: cannot create folder: %s", p, strerror(e));
            free(p);
            return rc;
        }
        p[i] = c;
    }
    free(p);
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return mim_error_set(err, -ENOTDIR, "%s: not a folder", dir);
    return 0;
}

static void put_u32(uint8_t *b, uint32_t v)
{
    b[0] = (uint8_t)v, b[1] = (uint8_t)(v >> 8), b[2] = (uint8_t)(v >> 16), b[3] = (uint8_t)(v >> 24);
}

static void put_f32(uint8_t *b, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    put_u32(b, u);
}

static char *join(const char *dir, const char *name)
{
    size_t n = strlen(dir) + strlen(name) + 2;
    char *p = malloc(n);
    if (p) snprintf(p, n, "%s/%s", dir, name);
    return p;
}

/* manifest.csv grows in memory and is written whole at the end */
typedef struct text {
    char *b;
    size_t n, cap;
} text_t;

static int text_addf(text_t *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int text_addf(text_t *t, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int w = vsnprintf(t->b ? t->b + t->n : NULL, t->b ? t->cap - t->n : 0, fmt, ap);
        va_end(ap);
        if (w < 0)
            return -1;
        if (t->b && (size_t)w < t->cap - t->n) {
            t->n += (size_t)w;
            return 0;
        }
        size_t cap = t->cap ? 2 * t->cap : 4096;
        while (cap < t->n + (size_t)w + 1)
            cap *= 2;
        char *nb = realloc(t->b, cap);
        if (!nb)
            return -1;
        t->b = nb, t->cap = cap;
    }
}

void mim_synth_set_progress(mim_synth_t *s, mim_progress_fn fn, void *ctx)
{
    if (s)
        s->progress = fn, s->progress_ctx = ctx;
}

int mim_synth_write_dataset(const mim_synth_t *s, const char *dir, mim_error_t *err)
{
    if (!s || !dir || !*dir) return mim_error_set(err, MIM_EINVAL, "synth: no output folder");
    int rc = mkdirs(dir, err);
    if (rc) return rc;
    uint32_t nv = s->nv, nf = s->nf, S = s->opt.subjects, P = s->opt.poses;
    char header[256];
    int hl = snprintf(header, sizeof header,
                      "ply\nformat binary_little_endian 1.0\ncomment mimic synth seed=%llu\n"
                      "element vertex %u\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face %u\nproperty list uchar int vertex_indices\nend_header\n",
                      (unsigned long long)s->opt.seed, nv, nf);
    size_t vbytes = (size_t)nv * 12, fbytes = (size_t)nf * 13;
    uint8_t *vbuf = malloc(vbytes), *fbuf = malloc(fbytes);
    float *pos = malloc((size_t)nv * 3 * sizeof *pos);
    double *work = malloc((size_t)nv * 3 * sizeof *work);
    text_t man = {0};
    char *path = NULL;
    if (!vbuf || !fbuf || !pos || !work || text_addf(&man, "file,subject,pose,pose_name\n")) {
        rc = mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
        goto out;
    }
    for (uint32_t f = 0; f < nf; f++) { /* the face block is the same in every file */
        uint8_t *b = fbuf + 13 * (size_t)f;
        b[0] = 3;
        for (int k = 0; k < 3; k++) put_u32(b + 1 + 4 * k, s->faces[3 * f + k]);
    }
    mim_progress_t pr = {.fn = s->progress, .ctx = s->progress_ctx};
    mim_progress_begin(&pr, "synth", (uint64_t)S * P);
    for (uint32_t si = 0; si < S && !rc; si++) {
        mim__subject_t sub;
        mim__subject_make(&sub, s->opt.seed, si);
        mim__body_t b;
        rc = mim__body_eval(s, &sub, &b);
        if (rc) {
            mim_error_set(err, rc, "synth: subject %u: %s", si, mim_strerror(rc));
            break;
        }
        for (uint32_t p = 0; p < P && !rc; p++) {
            mim__body_pose(s, &b, si, p, work, pos, NULL);
            for (uint32_t i = 0; i < 3 * nv; i++) put_f32(vbuf + 4 * (size_t)i, pos[i]);
            char name[64];
            mim_synth_file_name(si, p, name, sizeof name);
            free(path);
            path = join(dir, name);
            const mim_file_part_t parts[3] = {{header, (size_t)hl}, {vbuf, vbytes}, {fbuf, fbytes}};
            if (!path || text_addf(&man, "%s,%u,%u,%s\n", name, si, p, s->pose_name[p]))
                rc = mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
            else
                rc = mim_file_write_atomic(path, parts, 3, err);
            mim_progress_update(&pr, (uint64_t)si * P + p + 1);
        }
        mim__body_free(&b);
    }
    mim_progress_end(&pr);
    if (rc) goto out;
    /* the manifest and the landmark map last: they list bodies that are all there */
    free(path);
    path = join(dir, "manifest.csv");
    const mim_file_part_t mpart = {man.b, man.n};
    if (!path)
        rc = mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
    else
        rc = mim_file_write_atomic(path, &mpart, 1, err);
    if (rc) goto out;
    mim_landmark_map_t map;
    mim_synth_landmarks(s, &map);
    free(path);
    path = join(dir, "landmarks.json");
    rc = path ? mim_landmarks_write(&map, path, err) : mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
out:
    free(vbuf), free(fbuf), free(pos), free(work), free(man.b), free(path);
    return rc;
}
