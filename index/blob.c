/* The recognition index as one blob, version 7: laid out to be used in
 * place, where the store's memory map holds it, and verified by section as
 * queries first need each one, so that opening an index of 1 000 000
 * templates (739 MiB) reads a few hundred KiB instead of all of it
 * (bench/RESULTS.md, "Opening in place").
 *
 *    0  "MIXB"  4 u32 version (7)  8 u64 bytes after the header
 *   16  u64 checksum: XXH3-64 of the head (bytes 64 .. 64 + head bytes)
 *   24  u32 0x01020304 (byte order)  28 u32 header bytes (64)
 *   32  u64 head bytes (a multiple of 64)  40 u32 rows a chunk  44 u32 0
 *   48  16 bytes 0
 *   64  the head; every item starts 8-byte aligned (zero padding):
 *       u32 n_landmarks, d, n_templates, n_classes, n_strings, class_source,
 *           exact_max, checks, d2, augment; f64 C, gamma, cv_accuracy,
 *           noise, weight; u32 n_forests, 0
 *       n_forests x (u32 class, u32 0, u64 bytes, u64 checksum)
 *       n_chunks x (u64 base checksum, u64 extra checksum)
 *       u32 selected[d2]; f32 w[d2]; u32 class_name[n_classes];
 *       u32 class_start[n_classes + 1]
 *       n_strings x (u32 length, u32 0, bytes, NUL)   label strings, [0] = ""
 *       n_classes x (u32 n_sv, u32 0, f64 rho, prob_a, prob_b,
 *                    f64 coef[n_sv], f64 sv[n_sv * d])   the SVMs
 *       u32 nf, n_classes (0, 0: none); f64 discriminant_noise;
 *       f32 mean[nf], f32 g[n_classes * nf], f64 b[n_classes]
 *                                          the linear discriminants (lda.c)
 *       u32 m (3 n_landmarks, or 0: none), n_classes (or 0);
 *       f64 noise_max; f64 mu[n_classes * m], f64 S[m * m]
 *                                          the shape discriminants (shape.c)
 *       u32 m (n_landmarks, or 0: none), 0; i32 parent[m]; f32 length[m]
 *                                          the canonical proportions (proportions.c)
 *   then the bulk, each section 64-byte aligned (offsets follow from the
 *   sizes; nothing points): u64 ids[n], u32 subject[n], u32 pose[n],
 *   f32 desc[n * d], f32 extra[n * (d2 - d)], and the forests' bytes in
 *   the order of their table (FLANN's own, as forest.c saves them).
 *
 * Checksums (XXH3-64, as the store's records; each with a seed of its own
 * so that a section cannot pass for another; XXH3 rather than core's
 * mim_hash64 because a class's first query hashes its 21 MB of templates
 * at 1 000 000, and XXH3 reads about 1.7x faster here: 14 against 8 GB/s):
 * the head's covers everything needed to open, including the checksums of
 * the rest. A chunk is `rows` templates (256):
 * its base checksum covers their ids, subject, pose and desc, its extra
 * checksum their extra angles; each forest has its own.
 *
 * What is checked when (blob and index are trusted as far as their
 * checksums go; the rest is checked and fuzzed):
 * - open: header, head checksum, every size and label, class ranges,
 *   selected angles, weights and SVMs (finite), and that the sections fit
 *   the blob exactly; the small part of the blob;
 * - a chunk, when a query first reads one of its rows (the completion
 *   scan over the first rows of each class, the k-NN vote's samples): its
 *   checksum, labels in range (subject and pose index the strings: that
 *   is a memory matter) and finite angles (not a memory matter, a NaN
 *   only gives wrong answers; kept, because the check costs little beside
 *   the checksum, on memory just read);
 * - a class, when a query first searches it: all its chunks' base, then
 *   its forest's checksum before FLANN reads the forest (FLANN's loader
 *   trusts the node and point numbers in it), then the forest is loaded
 *   (or, for a class up to exact_max, FLANN's linear scan made). One
 *   thread readies a class under the class's mutex; a query on another
 *   class does not wait for it.
 * A part that fails stays failed: every query that needs it gets
 * MIM_EFORMAT, and nothing of it is read past the check. The whole blob
 * is still verified by mimic store check (the store's XXH3-64 of the value)
 * and by mim_index_load and mim_index_verify.
 *
 * Versions. The index is made from the store by mimic index, so mimic
 * reads only the version it writes, and answers an older blob (versions 1
 * to 4, a 32-byte header and one checksum, read by copying; version 5,
 * this layout without the shape discriminants; version 6, without the
 * proportions) with one line that says to rebuild it. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <xxhash.h>

#define VERSION 7
#define HDR 64
#define CHUNK_ROWS 256
#define SEED_HEAD 0x6d69785648ULL
#define SEED_BASE 0x6d69785642ULL
#define SEED_EXTRA 0x6d69785645ULL
#define SEED_FOREST 0x6d69785646ULL

/* A checksum that chains: hash(data, seed), seeds the next part with it. */
static uint64_t hash(const void *p, size_t n, uint64_t seed) { return XXH3_64bits_withSeed(p, n, seed); }

static uint64_t up(uint64_t x, uint64_t a) { return (x + a - 1) / a * a; }

/* ---- layout of the bulk, from the sizes (writer and reader alike) ---- */
typedef struct {
    uint64_t ids, subject, pose, desc, extra, forests;
} bulk_t;

static uint64_t bulk_layout(uint64_t start, uint32_t n, uint32_t d, uint32_t d2, bulk_t *b)
{
    b->ids = up(start, 64);
    b->subject = up(b->ids + 8ull * n, 64);
    b->pose = up(b->subject + 4ull * n, 64);
    b->desc = up(b->pose + 4ull * n, 64);
    b->extra = up(b->desc + 4ull * n * d, 64);
    b->forests = up(b->extra + 4ull * n * (d2 - d), 64);
    return b->forests; /* each forest then at the next multiple of 64 */
}

static uint64_t base_checksum(const mim_index_t *ix, uint32_t j, uint32_t rows)
{
    uint32_t a = j * rows, b = ix->n_templates - a < rows ? ix->n_templates : a + rows, m = b - a;
    uint64_t h = hash(ix->ids + a, 8ull * m, SEED_BASE ^ j);
    h = hash(ix->subject + a, 4ull * m, h);
    h = hash(ix->pose + a, 4ull * m, h);
    return hash(ix->desc + (size_t)a * ix->d, 4ull * m * ix->d, h);
}

static uint64_t extra_checksum(const mim_index_t *ix, uint32_t j, uint32_t rows)
{
    uint32_t a = j * rows, b = ix->n_templates - a < rows ? ix->n_templates : a + rows, de = ix->d2 - ix->d;
    return hash(ix->extra + (size_t)a * de, 4ull * (b - a) * de, SEED_EXTRA ^ j);
}

/* ---- writer ---- */
/* A growing byte buffer: oom is set once memory runs out, and every later
 * put is then a no-op. */
typedef struct {
    unsigned char *p;
    size_t len, cap;
    int oom;
} wbuf_t;

/* Appends n bytes of src (src may be NULL when n is 0), then zeros up to a
 * multiple of 8: every head item starts 8-byte aligned. */
static void put(wbuf_t *b, const void *src, size_t n)
{
    size_t padded = (n + 7) / 8 * 8;
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

int mim_index_save(const mim_index_t *ix, void **blob, size_t *len, mim_error_t *err)
{
    *blob = NULL, *len = 0;
    int rc = mim_index_verify(ix, err); /* in place: nothing damaged is written out, every forest made */
    if (rc) return rc;
    uint32_t n = ix->n_templates, d = ix->d, d2 = ix->d2, nc = ix->n_classes, ns = ix->n_strings;
    uint32_t rows = CHUNK_ROWS, n_chunks = (n + rows - 1) / rows;
    /* the forests first: their sizes and checksums go into the head. One
     * that cannot be saved (no in-memory file) is left out and built when
     * the blob is used. */
    void **fb = calloc(nc, sizeof *fb);
    size_t *fl = calloc(nc, sizeof *fl);
    uint32_t n_forests = 0;
    wbuf_t h = {0};
    if (!fb || !fl) h.oom = 1;
    for (uint32_t c = 0; !h.oom && c < nc; c++)
        if (ix->flann[c] && !ix->flann_exact[c] && !mim__forest_save(ix->flann[c], &fb[c], &fl[c], NULL)) n_forests++;
    uint32_t head[10] = {ix->n_landmarks, d, n, nc, ns, ix->class_source, ix->exact_max, ix->checks, d2, ix->augment};
    double f64[5] = {ix->C, ix->gamma, ix->cv_accuracy, ix->noise, ix->weight};
    uint32_t nf[2] = {n_forests, 0};
    put(&h, head, sizeof head);
    put(&h, f64, sizeof f64);
    put(&h, nf, sizeof nf);
    for (uint32_t c = 0; !h.oom && c < nc; c++)
        if (fb[c]) {
            uint32_t cl[2] = {c, 0};
            uint64_t l = fl[c], ck = hash(fb[c], fl[c], SEED_FOREST ^ c);
            put(&h, cl, 8), put(&h, &l, 8), put(&h, &ck, 8);
        }
    for (uint32_t j = 0; j < n_chunks; j++) {
        uint64_t ck[2] = {base_checksum(ix, j, rows), d2 > d ? extra_checksum(ix, j, rows) : 0};
        put(&h, ck, sizeof ck);
    }
    put(&h, ix->selected, 4ull * d2);
    put(&h, ix->w, 4ull * d2);
    put(&h, ix->class_name, 4ull * nc);
    put(&h, ix->class_start, 4ull * (nc + 1));
    for (uint32_t i = 0; i < ns; i++) {
        uint32_t l[2] = {(uint32_t)strlen(ix->strings[i]), 0};
        put(&h, l, 8);
        put(&h, ix->strings[i], l[0] + 1);
    }
    for (uint32_t c = 0; c < nc; c++) {
        const mim__svm_t *m = &ix->svm[c];
        uint32_t nsv[2] = {m->n_sv, 0};
        double par[3] = {m->rho, m->prob_a, m->prob_b};
        put(&h, nsv, 8), put(&h, par, sizeof par);
        if (m->n_sv) put(&h, m->coef, 8ull * m->n_sv), put(&h, m->sv, 8ull * m->n_sv * d);
    }
    /* the linear discriminants (issue 15), none: nf 0 */
    uint32_t lda[2] = {ix->lda.nf, ix->lda.n_classes};
    put(&h, lda, sizeof lda), put(&h, &ix->discriminant_noise, 8);
    if (ix->lda.nf) {
        put(&h, ix->lda.mean, 4ull * ix->lda.nf);
        put(&h, ix->lda.g, 4ull * ix->lda.nf * nc);
        put(&h, ix->lda.b, 8ull * nc);
    }
    const mim__shape_t *sh = &ix->shape; /* the shape discriminants (issue 15), none: m 0 */
    uint32_t m = sh->n_classes ? 3 * sh->L : 0, sm[2] = {m, m ? sh->n_classes : 0};
    double noise_max = m ? sh->noise_max : 0;
    put(&h, sm, sizeof sm), put(&h, &noise_max, 8);
    if (m) put(&h, sh->mu, 8ull * nc * m), put(&h, sh->S, 8ull * m * m);
    uint32_t pr[2] = {ix->prop.on ? ix->n_landmarks : 0, 0}; /* canonical proportions, none: 0 */
    put(&h, pr, sizeof pr);
    if (pr[0]) put(&h, ix->prop.parent, 4ull * pr[0]), put(&h, ix->prop.length, 4ull * pr[0]);
    static const unsigned char zero[64];
    if (h.len % 64) put(&h, zero, 64 - h.len % 64); /* the head ends 64-byte aligned */
    bulk_t b;
    uint64_t end = bulk_layout(HDR + h.len, n, d, d2, &b);
    for (uint32_t c = 0; c < nc; c++)
        if (fb && fb[c]) end = up(end, 64) + fl[c];
    unsigned char *p = NULL;
    if (!h.oom && posix_memalign((void **)&p, 64, (size_t)end)) p = NULL;
    if (h.oom || !p) {
        for (uint32_t c = 0; fb && c < nc; c++) free(fb[c]);
        free(fb), free(fl), free(h.p);
        return mim_error_set(err, MIM_ENOMEM, "index blob: out of memory (%llu bytes)", (unsigned long long)end);
    }
    memset(p, 0, (size_t)end);
    memcpy(p + HDR, h.p, h.len);
    memcpy(p + b.ids, ix->ids, 8ull * n);
    memcpy(p + b.subject, ix->subject, 4ull * n);
    memcpy(p + b.pose, ix->pose, 4ull * n);
    memcpy(p + b.desc, ix->desc, 4ull * n * d);
    if (d2 > d) memcpy(p + b.extra, ix->extra, 4ull * n * (d2 - d));
    uint64_t at = b.forests;
    for (uint32_t c = 0; c < nc; c++)
        if (fb[c]) {
            at = up(at, 64);
            memcpy(p + at, fb[c], fl[c]);
            at += fl[c];
        }
    for (uint32_t c = 0; c < nc; c++) free(fb[c]);
    free(fb), free(fl);
    uint64_t hb = h.len, plen = end - HDR, sum = hash(p + HDR, hb, SEED_HEAD);
    uint32_t ver = VERSION, bom = 0x01020304, hdr = HDR;
    free(h.p);
    memcpy(p, "MIXB", 4);
    memcpy(p + 4, &ver, 4);
    memcpy(p + 8, &plen, 8);
    memcpy(p + 16, &sum, 8);
    memcpy(p + 24, &bom, 4);
    memcpy(p + 28, &hdr, 4);
    memcpy(p + 32, &hb, 8);
    memcpy(p + 40, &rows, 4);
    *blob = p, *len = (size_t)end;
    return 0;
}

/* ---- reader: the head, in place ---- */
typedef struct {
    const unsigned char *p;
    uint64_t off, end;
    int bad;
} cur_t;

/* count items of size bytes at the cursor (then its padding to 8), or NULL */
static const void *take(cur_t *c, uint64_t count, uint64_t size)
{
    if (c->bad || (size && count > (c->end - c->off) / size)) {
        c->bad = 1;
        return NULL;
    }
    const void *r = c->p + c->off;
    uint64_t next = up(c->off + count * size, 8);
    if (next > c->end) {
        c->bad = 1;
        return NULL;
    }
    c->off = next;
    return r;
}

#define BAD(...) do { rc = mim_error_set(err, MIM_EFORMAT, __VA_ARGS__); goto out; } while (0)

int mim__index_parse(mim_index_t **out, const unsigned char *p, size_t len, int check_head, mim_error_t *err)
{
    *out = NULL;
    uint32_t ver, bom, hdr, rows;
    uint64_t plen, sum, hb;
    /* the version first: every older one's header is shorter than this one's */
    if (len < 8 || memcmp(p, "MIXB", 4))
        return mim_error_set(err, MIM_EFORMAT, "index blob: not a mimic index (bad magic or too short)");
    memcpy(&ver, p + 4, 4);
    if (ver >= 1 && ver < VERSION)
        return mim_error_set(err, MIM_EFORMAT,
                             "index blob: version %u is older than this mimic's (%d): rebuild it (run mimic index)", ver,
                             VERSION);
    if (ver != VERSION)
        return mim_error_set(err, MIM_EFORMAT, "index blob: version %u, this mimic reads version %d (run mimic index)",
                             ver, VERSION);
    if (len < HDR) return mim_error_set(err, MIM_EFORMAT, "index blob: not a mimic index (bad magic or too short)");
    memcpy(&plen, p + 8, 8), memcpy(&sum, p + 16, 8), memcpy(&bom, p + 24, 4);
    memcpy(&hdr, p + 28, 4), memcpy(&hb, p + 32, 8), memcpy(&rows, p + 40, 4);
    if (bom != 0x01020304) return mim_error_set(err, MIM_EFORMAT, "index blob: written with another byte order");
    static const unsigned char zero[64];
    if (hdr != HDR || plen != len - HDR || hb > len - HDR || hb % 64 || !rows || rows > (1u << 24) ||
        memcmp(p + 44, zero, HDR - 44))
        return mim_error_set(err, MIM_EFORMAT, "index blob: header sizes are inconsistent (%zu bytes)", len);
    if (check_head && hash(p + HDR, hb, SEED_HEAD) != sum)
        return mim_error_set(err, MIM_EFORMAT, "index blob: checksum mismatch in its head (damaged; run mimic index)");
    int rc = 0;
    mim_index_t *ix = calloc(1, sizeof *ix);
    if (!ix) return MIM_ENOMEM;
    ix->borrowed = 1;
    cur_t c = {p, HDR, HDR + hb, 0};
    const uint32_t *head = take(&c, 10, 4);
    const double *f64 = take(&c, 5, 8);
    const uint32_t *nfp = take(&c, 2, 4);
    if (c.bad) BAD("index blob: truncated head");
    memcpy(&ix->C, f64, 8), memcpy(&ix->gamma, f64 + 1, 8), memcpy(&ix->cv_accuracy, f64 + 2, 8);
    memcpy(&ix->noise, f64 + 3, 8), memcpy(&ix->weight, f64 + 4, 8);
    if (!(ix->weight >= 0 && ix->weight <= 4)) BAD("index blob: angle weighting out of range (%g)", ix->weight);
    ix->augment = head[9];
    if (!(ix->noise >= 0 && ix->noise <= 1) || ix->augment > 64 || (ix->augment == 0) != (ix->noise == 0))
        BAD("index blob: noise augmentation out of range (%u copies, noise %g)", ix->augment, ix->noise);
    ix->n_landmarks = head[0], ix->d = head[1], ix->n_templates = head[2], ix->n_classes = head[3];
    ix->class_source = head[5], ix->exact_max = head[6], ix->checks = head[7], ix->d2 = head[8];
    uint32_t L = ix->n_landmarks, d = ix->d, n = ix->n_templates, nc = ix->n_classes, ns = head[4], d2 = ix->d2;
    if (L < MIM_LANDMARKS_MIN || L > MIM_LANDMARKS_MAX || !d || d2 < d || d2 > mim_index_angle_count(L) || !n || !nc ||
        nc > n || !ns || ix->class_source > MIM_CLASSES_KMEANS || !ix->checks || !(ix->gamma > 0) || !isfinite(ix->gamma))
        BAD("index blob: inconsistent sizes (%u landmarks, d %u, %u templates, %u classes)", L, d, n, nc);
    uint32_t nf = nfp[0], n_chunks = (uint32_t)((n + (uint64_t)rows - 1) / rows);
    if (nf > nc) BAD("index blob: %u forests for %u classes", nf, nc);
    const unsigned char *ftab = take(&c, nf, 24), *ck = take(&c, n_chunks, 16);
    ix->selected = (uint32_t *)take(&c, d2, 4);
    ix->w = (float *)take(&c, d2, 4);
    ix->class_name = (uint32_t *)take(&c, nc, 4);
    ix->class_start = (uint32_t *)take(&c, (uint64_t)nc + 1, 4);
    if (c.bad) BAD("index blob: truncated head");
    for (uint32_t s = 0; s < d2; s++)
        if (ix->selected[s] >= mim_index_angle_count(L)) BAD("index blob: selected angle %u out of range", s);
    for (uint32_t s = 0; s < d2; s++)
        if (!(ix->w[s] > 0) || !isfinite(ix->w[s])) BAD("index blob: weight of angle %u is not a positive number", s);
    if (ix->class_start[0] != 0 || ix->class_start[nc] != n) BAD("index blob: class ranges do not cover the templates");
    for (uint32_t k = 0; k < nc; k++) {
        if (ix->class_start[k + 1] <= ix->class_start[k]) BAD("index blob: class %u is empty or out of order", k);
        if (ix->class_name[k] >= ns) BAD("index blob: class %u names label %u of %u", k, ix->class_name[k], ns);
    }
    if (ns > hb / 8) goto trunc;
    if (!(ix->strings = calloc(ns, sizeof(char *)))) goto oom;
    for (uint32_t i = 0; i < ns; i++) {
        const uint32_t *l = take(&c, 2, 4);
        const char *s = l ? take(&c, (uint64_t)l[0] + 1, 1) : NULL;
        if (!s) goto trunc;
        if (s[l[0]] || strlen(s) != l[0]) BAD("index blob: label %u holds a NUL byte or lacks its end", i);
        ix->strings[i] = (char *)s; /* never written: the blob is read-only to us */
        ix->n_strings = i + 1;
    }
    if (!(ix->svm = calloc(nc, sizeof *ix->svm))) goto oom;
    for (uint32_t k = 0; k < nc; k++) {
        mim__svm_t *m = &ix->svm[k];
        const uint32_t *nsv = take(&c, 2, 4);
        const double *par = take(&c, 3, 8);
        if (!nsv || !par) goto trunc;
        m->rho = par[0], m->prob_a = par[1], m->prob_b = par[2];
        if (nsv[0]) {
            if (!(m->coef = (double *)take(&c, nsv[0], 8)) || !(m->sv = (double *)take(&c, (uint64_t)nsv[0] * d, 8)))
                goto trunc;
            m->n_sv = nsv[0];
        }
        int finite = isfinite(m->rho) && isfinite(m->prob_a) && isfinite(m->prob_b);
        for (uint32_t i = 0; i < m->n_sv && finite; i++) finite = isfinite(m->coef[i]);
        for (size_t i = 0; i < (size_t)m->n_sv * d && finite; i++) finite = isfinite(m->sv[i]);
        if (!finite) BAD("index blob: SVM of class %u holds a non-finite number", k);
    }
    const uint32_t *lda = take(&c, 2, 4);
    const double *dn = take(&c, 1, 8);
    if (!lda || !dn) goto trunc;
    memcpy(&ix->discriminant_noise, dn, 8);
    if (lda[0]) { /* the discriminants: for every angle and class, or none */
        uint32_t nfa = mim_index_angle_count(L);
        if (lda[0] != nfa || lda[1] != nc || !(ix->discriminant_noise > 0 && ix->discriminant_noise <= 1))
            BAD("index blob: discriminants of %u angles and %u classes (noise %g) for %u and %u", lda[0], lda[1],
                ix->discriminant_noise, nfa, nc);
        if (!(ix->lda.mean = (float *)take(&c, nfa, 4)) || !(ix->lda.g = (float *)take(&c, (uint64_t)nfa * nc, 4)) ||
            !(ix->lda.b = (double *)take(&c, nc, 8)))
            goto trunc;
        ix->lda.nf = nfa, ix->lda.n_classes = nc;
        int finite = 1; /* a NaN would only give wrong answers; refused as the SVMs' are */
        for (uint32_t f = 0; f < nfa && finite; f++) finite = isfinite(ix->lda.mean[f]);
        for (size_t i = 0; i < (size_t)nfa * nc && finite; i++) finite = isfinite(ix->lda.g[i]);
        for (uint32_t k = 0; k < nc && finite; k++) finite = isfinite(ix->lda.b[k]);
        if (!finite) BAD("index blob: the discriminants hold a non-finite number");
    } else if (lda[1] || ix->discriminant_noise != 0) {
        BAD("index blob: no discriminants, but %u classes and noise %g for them", lda[1], ix->discriminant_noise);
    }
    const uint32_t *sm = take(&c, 2, 4);
    const double *snoise = take(&c, 1, 8);
    if (!sm || !snoise) goto trunc;
    mim__shape_t *sh = &ix->shape;
    double noise_max;
    memcpy(&noise_max, snoise, 8);
    if (sm[0]) { /* the shape discriminants: for every landmark and class, or none */
        const uint32_t m = 3 * L;
        if (sm[0] != m || sm[1] != nc || !(noise_max >= 0 && noise_max <= 1))
            BAD("index blob: shape discriminants of %u coordinates and %u classes (noise %g) for %u and %u", sm[0],
                sm[1], noise_max, m, nc);
        sh->borrowed = 1; /* before the pointers: closing never frees the blob's bytes */
        if (!(sh->mu = (double *)take(&c, (uint64_t)nc * m, 8)) || !(sh->S = (double *)take(&c, (uint64_t)m * m, 8)))
            goto trunc;
        sh->L = L, sh->noise_max = noise_max;
        int finite = 1;
        for (size_t i = 0; i < (size_t)nc * m && finite; i++) finite = isfinite(sh->mu[i]);
        for (size_t i = 0; i < (size_t)m * m && finite; i++) finite = isfinite(sh->S[i]);
        if (!finite) BAD("index blob: the shape discriminants hold a non-finite number");
        sh->n_classes = nc;
        if ((rc = mim__shape_prepare(sh)) == MIM_ENOMEM) goto oom;
        if (rc) BAD("index blob: the shape discriminants' covariance is not positive definite");
    } else if (sm[1] || noise_max != 0) {
        BAD("index blob: no shape discriminants, but %u classes and noise %g for them", sm[1], noise_max);
    }
    const uint32_t *pr = take(&c, 2, 4);
    if (!pr) goto trunc;
    if (pr[0]) { /* canonical proportions: a tree over the landmarks, positive lengths */
        const int32_t *parent = pr[0] == L ? take(&c, L, 4) : NULL;
        const float *length = parent ? take(&c, L, 4) : NULL;
        if (pr[0] != L || pr[1]) BAD("index blob: proportions for %u landmarks, the index has %u", pr[0], L);
        if (!parent || !length) goto trunc;
        if (mim__proportions_check(parent, L)) BAD("index blob: the proportions' skeleton is not a tree");
        for (uint32_t l = 0; l < L; l++)
            if (parent[l] >= 0 ? !(length[l] > 0 && isfinite(length[l])) : length[l] != 0)
                BAD("index blob: proportions: landmark %u's segment length %g", l, (double)length[l]);
        memcpy(ix->prop.parent, parent, 4ull * L), memcpy(ix->prop.length, length, 4ull * L);
        ix->prop.on = 1;
    } else if (pr[1]) {
        BAD("index blob: no proportions, but %u after them", pr[1]);
    }
    if (up(c.off, 64) != c.end) BAD("index blob: %llu bytes left over in its head", (unsigned long long)(c.end - c.off));
    /* the bulk: sections where the sizes put them, all inside the blob */
    bulk_t b;
    uint64_t end = bulk_layout(c.end, n, d, d2, &b);
    if (end > len) goto trunc;
    /* the padding between sections, which no checksum covers, is zero
     * (a few bytes each: nothing is left that a flipped bit can hide in) */
    const uint64_t sec[6][2] = {{b.ids, 8ull * n},       {b.subject, 4ull * n},        {b.pose, 4ull * n},
                                {b.desc, 4ull * n * d}, {b.extra, 4ull * n * (d2 - d)}, {b.forests, 0}};
    for (int i = 0; i < 5; i++)
        if (memcmp(p + sec[i][0] + sec[i][1], zero, sec[i + 1][0] - sec[i][0] - sec[i][1]))
            BAD("index blob: padding after section %d is not zero", i);
    ix->ids = (uint64_t *)(p + b.ids), ix->subject = (uint32_t *)(p + b.subject), ix->pose = (uint32_t *)(p + b.pose);
    ix->desc = (float *)(p + b.desc), ix->extra = (float *)(p + b.extra);
    mim__lazy_t *lz = ix->lazy = calloc(1, sizeof *lz);
    if (!lz) goto oom;
    lz->rows = rows, lz->n_chunks = n_chunks, lz->ck = ck, lz->ftab = ftab, lz->nf = nf;
    lz->base = calloc(n_chunks, 1), lz->extra = calloc(n_chunks, 1), lz->cls = calloc(nc, 1);
    lz->lock = calloc(nc, sizeof *lz->lock);
    lz->forest = calloc(nc, sizeof *lz->forest);
    lz->forest_len = calloc(nc, sizeof *lz->forest_len), lz->forest_ck = calloc(nc, sizeof *lz->forest_ck);
    ix->flann = calloc(nc, sizeof *ix->flann), ix->flann_exact = calloc(nc, sizeof *ix->flann_exact);
    if (!lz->base || !lz->extra || !lz->cls || !lz->lock || !lz->forest || !lz->forest_len || !lz->forest_ck ||
        !ix->flann || !ix->flann_exact)
        goto oom;
    for (uint32_t k = 0; k < nc; k++) {
        pthread_mutex_init(&lz->lock[k], NULL);
        ix->flann_exact[k] = ix->class_start[k + 1] - ix->class_start[k] <= ix->exact_max;
    }
    lz->n_locks = nc;
    for (uint32_t f = 0; f < nf; f++) {
        uint32_t k;
        uint64_t l, fck;
        memcpy(&k, ftab + 24ull * f, 4), memcpy(&l, ftab + 24ull * f + 8, 8), memcpy(&fck, ftab + 24ull * f + 16, 8);
        uint64_t at = up(end, 64);
        if (at > len || memcmp(p + end, zero, at - end)) BAD("index blob: forest %u truncated, or padding not zero", f);
        end = at;
        if (!l || l > len - end) BAD("index blob: forest %u truncated", f);
        if (k >= nc || lz->forest[k]) BAD("index blob: forest %u is for class %u (of %u), or a second one", f, k, nc);
        lz->forest[k] = p + end, lz->forest_len[k] = l, lz->forest_ck[k] = fck;
        end += l;
    }
    if (end != len) BAD("index blob: %llu bytes left over after its last section", (unsigned long long)(len - end));
    *out = ix;
    return 0;
trunc:
    rc = mim_error_set(err, MIM_EFORMAT, "index blob: truncated or sizes out of range");
    goto out;
oom:
    rc = mim_error_set(err, MIM_ENOMEM, "index blob: out of memory");
out:
    mim_index_close(&ix);
    return rc;
}

void mim__lazy_free(mim_index_t *ix)
{
    mim__lazy_t *lz = ix->lazy;
    if (!lz) return;
    for (uint32_t k = 0; k < lz->n_locks; k++) pthread_mutex_destroy(&lz->lock[k]);
    free((void *)lz->base), free((void *)lz->extra), free((void *)lz->cls), free(lz->lock);
    free((void *)lz->forest), free(lz->forest_len), free(lz->forest_ck);
    free(lz);
    ix->lazy = NULL;
}

/* ---- lazy verification ---- */
static int chunk_verify(const mim_index_t *ix, uint32_t j, int extra)
{
    const mim__lazy_t *lz = ix->lazy;
    uint64_t want;
    memcpy(&want, lz->ck + 16ull * j + (extra ? 8 : 0), 8);
    uint32_t a = j * lz->rows, b = ix->n_templates - a < lz->rows ? ix->n_templates : a + lz->rows;
    int ok = 1;
    if (extra) {
        uint32_t de = ix->d2 - ix->d;
        if (!de) return 1;
        if (extra_checksum(ix, j, lz->rows) != want) return 0;
        const float *v = ix->extra + (size_t)a * de;
        for (size_t i = 0; i < (size_t)(b - a) * de; i++) ok &= v[i] - v[i] == 0; /* NaN and inf fail */
        return ok;
    }
    if (base_checksum(ix, j, lz->rows) != want) return 0;
    for (uint32_t r = a; r < b; r++) ok &= (ix->subject[r] < ix->n_strings) & (ix->pose[r] < ix->n_strings);
    const float *v = ix->desc + (size_t)a * ix->d;
    for (size_t i = 0; i < (size_t)(b - a) * ix->d; i++) ok &= v[i] - v[i] == 0;
    return ok;
}

int mim__rows_ready(const mim_index_t *ix, uint32_t lo, uint32_t hi, int extra, mim_error_t *err)
{
    const mim__lazy_t *lz = ix->lazy;
    if (!lz || lo >= hi) return 0;
    for (uint32_t j = lo / lz->rows; j <= (hi - 1) / lz->rows; j++) {
        for (int e = 0; e <= extra; e++) {
            _Atomic uint8_t *st = e ? lz->extra : lz->base;
            uint8_t s = atomic_load_explicit(&st[j], memory_order_acquire);
            if (!s) { /* two threads may both verify a chunk: the same answer, stored twice */
                s = chunk_verify(ix, j, e) ? 1 : 2;
                atomic_store_explicit(&st[j], s, memory_order_release);
            }
            uint32_t last = ix->n_templates - j * lz->rows < lz->rows ? ix->n_templates - 1 : (j + 1) * lz->rows - 1;
            if (s != 1)
                return mim_error_set(err, MIM_EFORMAT,
                                     "index blob: templates %u to %u are damaged (%s: checksum mismatch or a value out "
                                     "of range; run mimic index)",
                                     j * lz->rows, last, e ? "further angles" : "ids, labels or angles");
        }
    }
    return 0;
}

int mim__class_ready(const mim_index_t *cix, uint32_t k, mim_error_t *err)
{
    mim__lazy_t *lz = cix->lazy;
    if (!lz) return 0;
    uint8_t s = atomic_load_explicit(&lz->cls[k], memory_order_acquire);
    if (!s) {
        /* queries take a const index: what a class's first use makes (its
         * FLANN index, the counters) is written here, once, under the
         * class's mutex, and published by the release store of its state */
        mim_index_t *ix = (mim_index_t *)cix;
        int rc = 0;
        pthread_mutex_lock(&lz->lock[k]);
        s = atomic_load_explicit(&lz->cls[k], memory_order_acquire);
        if (!s) {
            if (mim__rows_ready(ix, ix->class_start[k], ix->class_start[k + 1], 0, NULL)) s = 2;
            else if (lz->forest[k] && !ix->flann_exact[k] &&
                     hash(lz->forest[k], lz->forest_len[k], SEED_FOREST ^ k) != lz->forest_ck[k])
                s = 3;
            else if (!(rc = mim__class_knn(ix, k, lz->forest[k], lz->forest_len[k], err)))
                s = 1;
            if (s) atomic_store_explicit(&lz->cls[k], s, memory_order_release);
        }
        pthread_mutex_unlock(&lz->lock[k]);
        if (rc) return rc; /* out of memory: not sticky, a later query tries again */
    }
    if (s == 2)
        return mim_error_set(err, MIM_EFORMAT, "index blob: the templates of class %u are damaged (checksum mismatch or "
                                               "a value out of range; run mimic index)", k);
    if (s == 3)
        return mim_error_set(err, MIM_EFORMAT, "index blob: the kd-forest of class %u is damaged (checksum mismatch; "
                                               "run mimic index)", k);
    return 0;
}

int mim_index_verify(const mim_index_t *ix, mim_error_t *err)
{
    if (!ix->lazy) return 0;
    for (uint32_t k = 0; k < ix->n_classes; k++) {
        int rc = mim__class_ready(ix, k, err);
        if (rc) return rc;
    }
    return mim__rows_ready(ix, 0, ix->n_templates, 1, err);
}

/* ---- the public loaders ---- */
int mim_index_open_in_place(mim_index_t **out, const void *blob, size_t len, mim_error_t *err)
{
    *out = NULL;
    if (!blob || (uintptr_t)blob % 8) return mim_index_load(out, blob, len, err);
    return mim__index_parse(out, blob, len, 1, err);
}

int mim_index_load(mim_index_t **out, const void *blob, size_t len, mim_error_t *err)
{
    *out = NULL;
    if (!blob) return mim_error_set(err, MIM_EFORMAT, "index blob: not a mimic index (bad magic or too short)");
    /* an aligned copy of our own, used in place and verified whole now */
    void *own = NULL;
    if (posix_memalign(&own, 64, len ? len : 1)) return MIM_ENOMEM;
    memcpy(own, blob, len);
    mim_index_t *ix = NULL;
    int rc = mim__index_parse(&ix, own, len, 1, err);
    if (rc) {
        free(own);
        return rc;
    }
    ix->own = own;
    if ((rc = mim_index_verify(ix, err))) {
        mim_index_close(&ix);
        return rc;
    }
    mim__lazy_free(ix); /* all verified, every class ready */
    *out = ix;
    return 0;
}

/* For tests and the fuzz harness: writes every checksum of a blob from
 * what it holds (as far as its head parses; the head's own always), so
 * that a crafted blob reaches the checks behind them. */
void mim__index_seal(unsigned char *p, size_t len)
{
    uint64_t hb;
    if (len < HDR) return;
    memcpy(&hb, p + 32, 8);
    mim_index_t *ix = NULL;
    if (hb <= len - HDR && !mim__index_parse(&ix, p, len, 0, NULL)) {
        mim__lazy_t *lz = ix->lazy;
        for (uint32_t j = 0; j < lz->n_chunks; j++) {
            uint64_t ck[2] = {base_checksum(ix, j, lz->rows), ix->d2 > ix->d ? extra_checksum(ix, j, lz->rows) : 0};
            memcpy((unsigned char *)lz->ck + 16ull * j, ck, 16);
        }
        for (uint32_t f = 0; f < lz->nf; f++) {
            uint32_t k;
            memcpy(&k, lz->ftab + 24ull * f, 4);
            uint64_t ck = hash(lz->forest[k], lz->forest_len[k], SEED_FOREST ^ k);
            memcpy((unsigned char *)lz->ftab + 24ull * f + 16, &ck, 8);
        }
        mim_index_close(&ix);
    }
    if (hb <= len - HDR) {
        uint64_t sum = hash(p + HDR, hb, SEED_HEAD);
        memcpy(p + 16, &sum, 8);
    }
}
