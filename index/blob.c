/* The recognition index as one blob, versions 1 to 4, read by copying
 * (mimic writes version 5 since issue 16: blob_v5.c; the writer of
 * version 4 stays, internal, for the tests that show an old blob still
 * loads). Version 4:
 *
 *   0  "MIXB"   4 u32 version (4)   8 u64 payload bytes   16 u64 checksum
 *  24  u32 0x01020304 (byte order)  28 u32 0
 *  32  payload, little-endian, unaligned:
 *      u32 n_landmarks, d, n_templates, n_classes, n_strings, class_source,
 *          exact_max, checks, d2, augment; f64 C, gamma, cv_accuracy, noise,
 *          weight
 *      u32 selected[d2]                         ranked angles, the descriptor first
 *      f32 w[d2]                                the angles' weights (issue 15)
 *      n_strings x (u32 length, bytes)          label strings, [0] = ""
 *      u32 class_name[n_classes], u32 class_start[n_classes + 1]
 *      u64 ids[n], u32 subject[n], u32 pose[n]  templates grouped by class
 *      f32 desc[n * d]                          the descriptor angles, radians
 *      f32 extra[n * (d2 - d)]                  the further angles (missing landmarks)
 *      n_classes x (u32 n_sv, f64 rho, prob_a, prob_b, f64 coef[n_sv],
 *                   f64 sv[n_sv * d])           the SVMs
 *      u32 n_forests, n_forests x (u32 class, u64 bytes, bytes)
 *                                               the classes' kd-forests (forest.c)
 * The checksum is mim_hash64 of the payload. An exact class needs no forest;
 * a kd-forest is saved as FLANN writes it (the trees; the points are desc),
 * and one that is missing or will not load is built again from desc.
 * FLANN's loader trusts those bytes (a node's feature or point number is
 * not range-checked): the checksum is what guards them, so a store is
 * trusted as far as its checksums go, as mimic's own files are; everything
 * else in the blob is checked here and fuzzed (tests/fuzz). 
 *
 * Version 1 (before noise augmentation, issue 15) lacks augment and noise;
 * it is still read, as an index built without augmentation. Version 2
 * (before saved forests, issue 16) lacks the forests: they are built at
 * load, as they always were then. Version 3 (before the angle weights,
 * issue 15) lacks weight and w: it is read as an index without weighting
 * (every weight 1). */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BLOB_MAGIC "MIXB"
#define BLOB_VERSION 4 /* the last version read here */
#define BLOB_HEADER 32

void mim__wbuf_put(mim__wbuf_t *b, const void *src, size_t n, size_t align)
{
    size_t padded = (n + align - 1) / align * align;
    if (b->oom) return;
    if (b->len + padded > b->cap) {
        size_t nc = b->cap ? b->cap : 4096;
        while (nc < b->len + padded) nc *= 2;
        unsigned char *np = realloc(b->p, nc);
        if (!np) {
            b->oom = 1;
            return;
        }
        b->p = np, b->cap = nc;
    }
    if (n) memcpy(b->p + b->len, src, n);
    memset(b->p + b->len + n, 0, padded - n);
    b->len += padded;
}

typedef mim__wbuf_t wbuf_t;
static void put(wbuf_t *b, const void *src, size_t n) { mim__wbuf_put(b, src, n, 1); } /* version 4: unaligned */
static void put32(wbuf_t *b, uint32_t v) { put(b, &v, 4); }
static void putf64(wbuf_t *b, double v) { put(b, &v, 8); }

int mim__index_save_v4(const mim_index_t *ix, void **blob, size_t *len, mim_error_t *err)
{
    int rc = mim_index_verify(ix, err); /* an index in place: every forest made */
    if (rc) return rc;
    *blob = NULL, *len = 0;
    wbuf_t b = {0};
    unsigned char hdr[BLOB_HEADER] = {0};
    put(&b, hdr, sizeof hdr);
    uint32_t n = ix->n_templates, d = ix->d, nc = ix->n_classes;
    uint32_t head[10] = {ix->n_landmarks, d, n, nc, ix->n_strings, ix->class_source, ix->exact_max, ix->checks, ix->d2,
                         ix->augment};
    put(&b, head, sizeof head);
    putf64(&b, ix->C), putf64(&b, ix->gamma), putf64(&b, ix->cv_accuracy), putf64(&b, ix->noise), putf64(&b, ix->weight);
    put(&b, ix->selected, sizeof(uint32_t) * ix->d2);
    put(&b, ix->w, sizeof(float) * ix->d2);
    for (uint32_t i = 0; i < ix->n_strings; i++) {
        uint32_t l = (uint32_t)strlen(ix->strings[i]);
        put32(&b, l);
        put(&b, ix->strings[i], l);
    }
    put(&b, ix->class_name, sizeof(uint32_t) * nc);
    put(&b, ix->class_start, sizeof(uint32_t) * (nc + 1));
    put(&b, ix->ids, sizeof(uint64_t) * n);
    put(&b, ix->subject, sizeof(uint32_t) * n);
    put(&b, ix->pose, sizeof(uint32_t) * n);
    put(&b, ix->desc, sizeof(float) * (size_t)n * d);
    put(&b, ix->extra, sizeof(float) * (size_t)n * (ix->d2 - d));
    for (uint32_t c = 0; c < nc; c++) {
        const mim__svm_t *m = &ix->svm[c];
        put32(&b, m->n_sv);
        putf64(&b, m->rho), putf64(&b, m->prob_a), putf64(&b, m->prob_b);
        if (m->n_sv) {
            put(&b, m->coef, sizeof(double) * m->n_sv);
            put(&b, m->sv, sizeof(double) * m->n_sv * d);
        }
    }
    /* the kd-forests; one that cannot be saved here (no in-memory file) is
     * left out and built at load */
    uint32_t n_forests = 0;
    void **fb = calloc(nc, sizeof *fb);
    size_t *fl = calloc(nc, sizeof *fl);
    if (!fb || !fl) b.oom = 1;
    for (uint32_t c = 0; !b.oom && c < nc; c++)
        if (ix->flann[c] && !ix->flann_exact[c] && !mim__forest_save(ix->flann[c], &fb[c], &fl[c], NULL))
            n_forests++;
    put32(&b, n_forests);
    for (uint32_t c = 0; !b.oom && c < nc; c++)
        if (fb[c]) {
            uint64_t l = fl[c];
            put32(&b, c);
            put(&b, &l, 8);
            put(&b, fb[c], fl[c]);
        }
    for (uint32_t c = 0; fb && c < nc; c++) free(fb[c]);
    free(fb), free(fl);
    if (b.oom) {
        free(b.p);
        return mim_error_set(err, MIM_ENOMEM, "index blob: out of memory (%zu bytes)", b.len);
    }
    uint32_t ver = BLOB_VERSION, bom = 0x01020304;
    uint64_t plen = b.len - BLOB_HEADER, sum = mim_hash64(b.p + BLOB_HEADER, plen, 0x6d6978ULL);
    memcpy(b.p, BLOB_MAGIC, 4);
    memcpy(b.p + 4, &ver, 4);
    memcpy(b.p + 8, &plen, 8);
    memcpy(b.p + 16, &sum, 8);
    memcpy(b.p + 24, &bom, 4);
    *blob = b.p, *len = b.len;
    return 0;
}

typedef struct {
    const unsigned char *p;
    size_t len, off;
    int bad;
} rbuf_t;

static int get(rbuf_t *r, void *dst, size_t n)
{
    if (r->bad || n > r->len - r->off) {
        r->bad = 1;
        if (dst && n) memset(dst, 0, n < 64 ? n : 0);
        return -1;
    }
    if (dst) memcpy(dst, r->p + r->off, n);
    r->off += n;
    return 0;
}

/* malloc of count items of size bytes that the blob must still hold */
static void *get_array(rbuf_t *r, uint64_t count, size_t size)
{
    if (r->bad || count > (r->len - r->off) / (size ? size : 1)) {
        r->bad = 1;
        return NULL;
    }
    void *p = malloc(count * size + 1);
    if (!p) return NULL;
    memcpy(p, r->p + r->off, count * size);
    r->off += count * size;
    return p;
}

#define BAD(...) do { rc = mim_error_set(err, MIM_EFORMAT, __VA_ARGS__); goto out; } while (0)

int mim__index_load_legacy(mim_index_t **out, const void *blob, size_t len, mim_error_t *err)
{
    *out = NULL;
    const unsigned char *p = blob;
    if (!blob || len < BLOB_HEADER || memcmp(p, BLOB_MAGIC, 4) != 0)
        return mim_error_set(err, MIM_EFORMAT, "index blob: not a mimic index (bad magic or too short)");
    uint32_t ver, bom;
    uint64_t plen, sum;
    memcpy(&ver, p + 4, 4);
    memcpy(&plen, p + 8, 8);
    memcpy(&sum, p + 16, 8);
    memcpy(&bom, p + 24, 4);
    if (ver < 1 || ver > BLOB_VERSION)
        return mim_error_set(err, MIM_EFORMAT, "index blob: version %u, this mimic reads versions 1 to %d (run mimic index)",
                             ver, BLOB_VERSION);
    if (bom != 0x01020304) return mim_error_set(err, MIM_EFORMAT, "index blob: written with another byte order");
    if (plen != len - BLOB_HEADER)
        return mim_error_set(err, MIM_EFORMAT, "index blob: %zu payload bytes, header says %llu", len - BLOB_HEADER,
                             (unsigned long long)plen);
    if (mim_hash64(p + BLOB_HEADER, plen, 0x6d6978ULL) != sum)
        return mim_error_set(err, MIM_EFORMAT, "index blob: checksum mismatch (damaged; run mimic index)");

    rbuf_t r = {p + BLOB_HEADER, plen, 0, 0};
    int rc = 0;
    mim_index_t *ix = calloc(1, sizeof *ix);
    if (!ix) return MIM_ENOMEM;
    uint32_t head[10] = {0};
    get(&r, head, sizeof(uint32_t) * (ver == 1 ? 9 : 10));
    get(&r, &ix->C, 8), get(&r, &ix->gamma, 8), get(&r, &ix->cv_accuracy, 8);
    if (ver >= 2) get(&r, &ix->noise, 8);
    if (ver >= 4) get(&r, &ix->weight, 8);
    if (r.bad) BAD("index blob: truncated header");
    if (!(ix->weight >= 0 && ix->weight <= 4)) BAD("index blob: angle weighting out of range (%g)", ix->weight);
    ix->augment = head[9];
    if (!(ix->noise >= 0 && ix->noise <= 1) || ix->augment > 64 || (ix->augment == 0) != (ix->noise == 0))
        BAD("index blob: noise augmentation out of range (%u copies, noise %g)", ix->augment, ix->noise);
    ix->n_landmarks = head[0], ix->d = head[1], ix->n_templates = head[2], ix->n_classes = head[3];
    ix->class_source = head[5], ix->exact_max = head[6], ix->checks = head[7], ix->d2 = head[8];
    uint32_t L = ix->n_landmarks, d = ix->d, n = ix->n_templates, nc = ix->n_classes, ns = head[4], d2 = ix->d2;
    if (L < MIM_LANDMARKS_MIN || L > MIM_LANDMARKS_MAX || !d || d2 < d || d2 > mim_index_angle_count(L) || !n || !nc || nc > n ||
        !ns || ix->class_source > MIM_CLASSES_KMEANS || !ix->checks || !(ix->gamma > 0) || !isfinite(ix->gamma))
        BAD("index blob: inconsistent sizes (%u landmarks, d %u, %u templates, %u classes)", L, d, n, nc);
    if (!(ix->selected = get_array(&r, d2, 4))) goto trunc;
    for (uint32_t s = 0; s < d2; s++)
        if (ix->selected[s] >= mim_index_angle_count(L)) BAD("index blob: selected angle %u out of range", s);
    if (ver >= 4) {
        if (!(ix->w = get_array(&r, d2, 4))) goto trunc;
        for (uint32_t s = 0; s < d2; s++)
            if (!(ix->w[s] > 0) || !isfinite(ix->w[s])) BAD("index blob: weight of angle %u is not a positive number", s);
    } else {
        if (!(ix->w = malloc(sizeof(float) * d2))) goto trunc;
        for (uint32_t s = 0; s < d2; s++) ix->w[s] = 1;
    }
    if (ns > r.len / 4 || !(ix->strings = calloc(ns, sizeof(char *)))) goto trunc;
    for (uint32_t i = 0; i < ns; i++) {
        uint32_t l = 0;
        if (get(&r, &l, 4) || !(ix->strings[i] = get_array(&r, l, 1))) goto trunc;
        ix->strings[i][l] = 0;
        ix->n_strings = i + 1;
        if (strlen(ix->strings[i]) != l) BAD("index blob: label %u holds a NUL byte", i);
    }
    if (!(ix->class_name = get_array(&r, nc, 4)) || !(ix->class_start = get_array(&r, (uint64_t)nc + 1, 4)) ||
        !(ix->ids = get_array(&r, n, 8)) || !(ix->subject = get_array(&r, n, 4)) || !(ix->pose = get_array(&r, n, 4)) ||
        !(ix->desc = get_array(&r, (uint64_t)n * d, 4)) || !(ix->extra = get_array(&r, (uint64_t)n * (d2 - d), 4)))
        goto trunc;
    if (ix->class_start[0] != 0 || ix->class_start[nc] != n) BAD("index blob: class ranges do not cover the templates");
    for (uint32_t c = 0; c < nc; c++) {
        if (ix->class_start[c + 1] <= ix->class_start[c]) BAD("index blob: class %u is empty or out of order", c);
        if (ix->class_name[c] >= ns) BAD("index blob: class %u names label %u of %u", c, ix->class_name[c], ns);
    }
    for (uint32_t t = 0; t < n; t++)
        if (ix->subject[t] >= ns || ix->pose[t] >= ns) BAD("index blob: template %u names a missing label", t);
    for (size_t i = 0; i < (size_t)n * d; i++)
        if (!isfinite(ix->desc[i])) BAD("index blob: descriptor value %zu is not finite", i);
    for (size_t i = 0; i < (size_t)n * (d2 - d); i++)
        if (!isfinite(ix->extra[i])) BAD("index blob: extra angle %zu is not finite", i);
    if (!(ix->svm = calloc(nc, sizeof *ix->svm))) goto trunc;
    for (uint32_t c = 0; c < nc; c++) {
        mim__svm_t *m = &ix->svm[c];
        uint32_t nsv = 0;
        get(&r, &nsv, 4), get(&r, &m->rho, 8), get(&r, &m->prob_a, 8), get(&r, &m->prob_b, 8);
        if (r.bad) goto trunc;
        if (nsv) {
            if (!(m->coef = get_array(&r, nsv, 8)) || !(m->sv = get_array(&r, (uint64_t)nsv * d, 8))) goto trunc;
            m->n_sv = nsv;
        }
        int finite = isfinite(m->rho) && isfinite(m->prob_a) && isfinite(m->prob_b);
        for (uint32_t i = 0; i < m->n_sv && finite; i++) finite = isfinite(m->coef[i]);
        for (size_t i = 0; i < (size_t)m->n_sv * d && finite; i++) finite = isfinite(m->sv[i]);
        if (!finite) BAD("index blob: SVM of class %u holds a non-finite number", c);
    }
    mim__forest_bytes_t *saved = NULL;
    if (ver >= 3) {
        uint32_t nf = 0;
        if (get(&r, &nf, 4)) goto trunc;
        if (nf > nc) BAD("index blob: %u forests for %u classes", nf, nc);
        if (!(saved = calloc(nc, sizeof *saved))) goto trunc;
        for (uint32_t f = 0; f < nf; f++) {
            uint32_t c = 0;
            uint64_t l = 0;
            if (get(&r, &c, 4) || get(&r, &l, 8) || l > r.len - r.off || !l) {
                free(saved);
                BAD("index blob: forest %u truncated", f);
            }
            if (c >= nc || saved[c].len) {
                free(saved);
                BAD("index blob: forest %u is for class %u (of %u), or a second one", f, c, nc);
            }
            saved[c].bytes = r.p + r.off, saved[c].len = (size_t)l;
            r.off += (size_t)l;
        }
    }
    if (r.off != r.len) {
        free(saved);
        BAD("index blob: %zu bytes left over after the last %s", r.len - r.off, ver >= 3 ? "forest" : "SVM");
    }
    rc = mim__index_build_knn(ix, saved, err);
    free(saved);
    if (rc) goto out;
    *out = ix;
    return 0;
trunc:
    rc = r.bad ? mim_error_set(err, MIM_EFORMAT, "index blob: truncated or sizes out of range") : MIM_ENOMEM;
out:
    mim_index_close(&ix);
    return rc;
}
