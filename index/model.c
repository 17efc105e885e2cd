/* Building the recognition index (seed 000, Section 3.3): classes from
 * pose labels (or k-means), the d salient angles chosen by the CART tree of
 * Section 3.2, one-vs-rest SVMs, and a FLANN k-NN index inside each class
 * (answer.c queries it). The method and its choices are described in
 * mim_index.h. */
#include "internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- a small string table (labels) ---- */
typedef struct {
    char **s;
    uint32_t n, cap;
    uint32_t *slot; /* open addressing: string index + 1, 0 = empty */
    uint32_t nslot;
} strtab_t;

static int strtab_grow(strtab_t *t)
{
    uint32_t ns = t->nslot ? t->nslot * 2 : 64;
    uint32_t *slot = calloc(ns, sizeof *slot);
    if (!slot) return MIM_ENOMEM;
    for (uint32_t i = 0; i < t->n; i++) {
        uint64_t h = mim_hash64(t->s[i], strlen(t->s[i]), 7);
        uint32_t p = (uint32_t)(h & (ns - 1));
        while (slot[p]) p = (p + 1) & (ns - 1);
        slot[p] = i + 1;
    }
    free(t->slot);
    t->slot = slot, t->nslot = ns;
    return 0;
}

/* Index of s in the table, added if new; -1 when out of memory. */
static int64_t strtab_add(strtab_t *t, const char *s)
{
    if (!s) s = "";
    if (2 * (t->n + 1) > t->nslot && strtab_grow(t)) return -1;
    uint64_t h = mim_hash64(s, strlen(s), 7);
    uint32_t p = (uint32_t)(h & (t->nslot - 1));
    while (t->slot[p]) {
        if (!strcmp(t->s[t->slot[p] - 1], s)) return t->slot[p] - 1;
        p = (p + 1) & (t->nslot - 1);
    }
    if (t->n == t->cap) {
        uint32_t nc = t->cap ? 2 * t->cap : 16;
        char **ns = realloc(t->s, sizeof(char *) * nc);
        if (!ns) return -1;
        t->s = ns, t->cap = nc;
    }
    if (!(t->s[t->n] = strdup(s))) return -1;
    t->slot[p] = t->n + 1;
    return t->n++;
}

/* ---- k-NN ----
 * FLANN's C API reseeds libc's generator (srand) in every call, searches
 * included, when random_seed > 0 (flann.cpp, init_flann_parameters).
 * mimic passes 0 to every call, so FLANN never reseeds it, and needs no
 * lock around searches:
 * - a search draws no random numbers (best-bin-first in the kd-forest, or
 *   the linear scan): the seed only put an srand inside mim_index_query,
 *   which is documented thread-safe and runs concurrently in serve;
 * - the linear index (classes up to exact_max) draws nothing at build;
 * - the kd-forest (larger classes) shuffles with std::random_device in
 *   Debian's FLANN 1.9.2 (kdtree_index.h, buildIndexImpl), so a seed never
 *   made it reproducible (with the old fixed seed, two loads of one blob,
 *   800 templates a class, 128 checks, gave another 5 nearest for 31 % of
 *   jittered frames). Its split choice (rand_int) still draws from libc's
 *   rand() while it is built, without reseeding it.
 * FLANN still sets its logger's level in every call (always the same
 * FLANN_LOG_NONE). */
struct FLANNParameters mim__flann_params(const mim_index_t *ix, int exact)
{
    struct FLANNParameters p = DEFAULT_FLANN_PARAMETERS;
    p.algorithm = exact ? FLANN_INDEX_LINEAR : FLANN_INDEX_KDTREE;
    p.trees = 4;
    p.checks = (int)ix->checks;
    p.cores = 1;
    p.log_level = FLANN_LOG_NONE;
    p.random_seed = 0; /* no srand (see above) */
    return p;
}
#define flann_params mim__flann_params

/* Class c's k-NN index: its saved forest where one is given and loads,
 * else built (an exact class's linear scan costs nothing to build). The
 * points are the class's rows of desc, used where they are (in place: in
 * the blob; FLANN only reads them). */
int mim__class_knn(mim_index_t *ix, uint32_t c, const void *bytes, size_t len, mim_error_t *err)
{
    uint32_t n = ix->class_start[c + 1] - ix->class_start[c]; /* flann_exact[c] is set: read only here */
    if (!n) return 0;
    struct FLANNParameters p = flann_params(ix, ix->flann_exact[c]);
    float speedup = 0, *points = ix->desc + (size_t)ix->class_start[c] * ix->d;
    if (!ix->flann_exact[c] && len && (ix->flann[c] = mim__forest_load(bytes, len, points, n, ix->d))) {
        ix->forests_loaded++;
        return 0;
    }
    ix->flann[c] = flann_build_index_float(points, (int)n, (int)ix->d, &speedup, &p);
    if (!ix->flann_exact[c]) ix->forests_built++;
    if (!ix->flann[c]) return mim_error_set(err, MIM_ENOMEM, "k-NN index of class %u (%u templates) failed", c, n);
    return 0;
}

int mim__index_build_knn(mim_index_t *ix, mim_error_t *err)
{
    ix->flann = calloc(ix->n_classes, sizeof *ix->flann);
    ix->flann_exact = calloc(ix->n_classes, sizeof *ix->flann_exact);
    if (!ix->flann || !ix->flann_exact) return MIM_ENOMEM;
    for (uint32_t c = 0; c < ix->n_classes; c++) {
        ix->flann_exact[c] = ix->class_start[c + 1] - ix->class_start[c] <= ix->exact_max;
        int rc = mim__class_knn(ix, c, NULL, 0, err);
        if (rc) return rc;
    }
    return 0;
}

void mim_index_close(mim_index_t **pix)
{
    if (!pix || !*pix) return;
    mim_index_t *ix = *pix;
    if (ix->flann && ix->flann_exact)
        for (uint32_t c = 0; c < ix->n_classes; c++) {
            struct FLANNParameters p = flann_params(ix, ix->flann_exact[c]);
            if (ix->flann[c]) flann_free_index_float(ix->flann[c], &p);
        }
    mim__lazy_free(ix);
    if (ix->borrowed) { /* the arrays, strings and SVMs' arrays are the blob's */
        mim__shape_free(&ix->shape);
        free(ix->strings), free(ix->svm), free(ix->flann), free(ix->flann_exact), free(ix->own);
        free(ix);
        *pix = NULL;
        return;
    }
    if (ix->svm)
        for (uint32_t c = 0; c < ix->n_classes; c++) mim__svm_free(&ix->svm[c]);
    if (ix->strings)
        for (uint32_t i = 0; i < ix->n_strings; i++) free(ix->strings[i]);
    free(ix->strings), free(ix->selected), free(ix->class_name), free(ix->class_start), free(ix->ids);
    free(ix->subject), free(ix->pose), free(ix->desc), free(ix->extra), free(ix->svm), free(ix->flann), free(ix->flann_exact), free(ix->w);
    mim__lda_free(&ix->lda);
    mim__shape_free(&ix->shape);
    free(ix);
    *pix = NULL;
}

/* ---- build ---- */
static void full_angles(const mim_index_input_t *in, uint32_t t, float *out)
{
    mim_index_angles(in->landmarks + (size_t)t * in->n_landmarks * 3, NULL, in->n_landmarks, out);
}

/* ---- noise augmentation (issue 15) ----
 * The bodies' scale: the median, over at most 1001 evenly spread templates,
 * of the RMS distance of a template's landmarks from their centroid. One
 * number per store, in the store's own unit, so that the training noise
 * means the same for bodies in metres or millimetres. */
static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double body_scale(const mim_index_input_t *in)
{
    uint32_t n = in->n_templates, L = in->n_landmarks, m = n < 1001 ? n : 1001;
    double r[1001];
    for (uint32_t i = 0; i < m; i++) {
        const float *p = in->landmarks + (size_t)((uint64_t)i * n / m) * L * 3;
        double c[3] = {0, 0, 0}, s = 0;
        for (uint32_t l = 0; l < L; l++)
            for (int k = 0; k < 3; k++) c[k] += p[3 * l + k] / (double)L;
        for (uint32_t l = 0; l < L; l++)
            for (int k = 0; k < 3; k++) s += (p[3 * l + k] - c[k]) * (p[3 * l + k] - c[k]);
        r[i] = sqrt(s / L);
    }
    qsort(r, m, sizeof *r, cmp_double);
    return r[m / 2];
}

/* Template t's landmarks (raw: as given) with Gaussian noise of sigma on
 * every coordinate, then seen as the angles see them (on canonical
 * proportions when prop is on), as a noisy query would be. */
static void noisy_landmarks(const mim_index_input_t *raw, const mim__proportions_t *prop, uint32_t t, double sigma,
                            mim_rng_t *rng, float *out)
{
    const uint32_t L = raw->n_landmarks;
    const float *p = raw->landmarks + (size_t)t * L * 3;
    float noisy[3 * MIM_LANDMARKS_MAX];
    for (uint32_t i = 0; i < 3 * L; i++) noisy[i] = (float)(p[i] + sigma * mim_rng_gauss(rng));
    if (prop->on) mim__proportions_apply(prop, L, noisy, NULL, out);
    else memcpy(out, noisy, sizeof *out * 3 * L);
}

/* Nearest of k centres (rows of nf doubles) to the angles a; NaN left out. */
static uint32_t nearest_centre(const float *a, const double *centres, uint32_t k, uint32_t nf)
{
    double best = INFINITY;
    uint32_t arg = 0;
    for (uint32_t j = 0; j < k; j++) {
        double s = 0;
        for (uint32_t f = 0; f < nf; f++) {
            double c = centres[(size_t)j * nf + f];
            if (isnan(a[f]) || isnan(c)) continue;
            s += (a[f] - c) * (a[f] - c);
        }
        if (s < best) best = s, arg = j;
    }
    return arg;
}

/* Class means over all candidate angles of the rows whose class is known
 * (cls[t] < k), from the angles of those rows. */
static int class_means(const mim_index_input_t *in, const uint32_t *cls, const uint32_t *rows, uint32_t nrows,
                       uint32_t k, uint32_t nf, double *centres)
{
    uint32_t *cnt = calloc((size_t)k * nf, sizeof *cnt);
    float *a = malloc(sizeof(float) * nf);
    if (!cnt || !a) {
        free(cnt), free(a);
        return MIM_ENOMEM;
    }
    memset(centres, 0, sizeof(double) * (size_t)k * nf);
    for (uint32_t r = 0; r < nrows; r++) {
        uint32_t t = rows[r];
        if (cls[t] >= k) continue;
        full_angles(in, t, a);
        for (uint32_t f = 0; f < nf; f++)
            if (!isnan(a[f])) centres[(size_t)cls[t] * nf + f] += a[f], cnt[(size_t)cls[t] * nf + f]++;
    }
    for (size_t i = 0; i < (size_t)k * nf; i++) centres[i] = cnt[i] ? centres[i] / cnt[i] : NAN;
    free(cnt), free(a);
    return 0;
}

/* Assigns class ids: pose labels, else k-means. cls gets n entries; names
 * gets the class names as string-table indices. */
static int assign_classes(const mim_index_input_t *in, strtab_t *st, uint32_t *cls, uint32_t **names_out,
                          uint32_t *nc_out, uint32_t *source, mim_error_t *err)
{
    uint32_t n = in->n_templates, nf = mim_index_angle_count(in->n_landmarks);
    uint32_t *str_class = NULL, n_map = 0, nc = 0, *names = NULL, unlabelled = 0;
    int rc = 0;
    /* pose label string index -> class */
    names = malloc(sizeof(uint32_t) * (n + 64));
    uint32_t *rows = malloc(sizeof(uint32_t) * n);
    float *a = malloc(sizeof(float) * nf);
    double *centres = NULL;
    if (!names || !rows || !a) {
        rc = MIM_ENOMEM;
        goto out;
    }
    for (uint32_t t = 0; t < n; t++) {
        const char *p = in->poses ? in->poses[t] : NULL;
        if (!p || !*p) {
            cls[t] = UINT32_MAX;
            unlabelled++;
            continue;
        }
        int64_t s = strtab_add(st, p);
        if (s < 0) {
            rc = MIM_ENOMEM;
            goto out;
        }
        /* class of string s (subject strings share the table: grow the map) */
        if ((uint32_t)s >= n_map) {
            uint32_t nn = st->n + 64;
            uint32_t *m2 = realloc(str_class, sizeof(uint32_t) * nn);
            if (!m2) {
                rc = MIM_ENOMEM;
                goto out;
            }
            for (uint32_t i = n_map; i < nn; i++) m2[i] = UINT32_MAX;
            str_class = m2, n_map = nn;
        }
        if (str_class[s] == UINT32_MAX) {
            if (nc == n + 64) { /* cannot happen: at most one class per template */
                rc = MIM_EINVAL;
                goto out;
            }
            str_class[s] = nc;
            names[nc++] = (uint32_t)s;
        }
        uint32_t c = str_class[s];
        cls[t] = c;
    }
    *source = MIM_CLASSES_LABELS;
    if (nc == 0) { /* no labels at all: k-means on a sample, then nearest centre */
        *source = MIM_CLASSES_KMEANS;
        uint32_t m = n < 4000 ? n : 4000;
        mim_rng_t rng;
        mim_rng_seed(&rng, MIM__INDEX_SEED, 0x6b6dULL);
        for (uint32_t i = 0; i < n; i++) rows[i] = i;
        for (uint32_t i = 0; i < m && n > m; i++) {
            uint32_t j = i + (uint32_t)mim_rng_below(&rng, n - i), tt = rows[i];
            rows[i] = rows[j], rows[j] = tt;
        }
        float *x = malloc(sizeof(float) * (size_t)m * nf);
        uint32_t *as = malloc(sizeof(uint32_t) * m);
        if (!x || !as) {
            free(x), free(as);
            rc = MIM_ENOMEM;
            goto out;
        }
        for (uint32_t i = 0; i < m; i++) full_angles(in, rows[i], x + (size_t)i * nf);
        uint32_t k = mim__kmeans_k(n);
        if (k > m) k = m;
        rc = mim__kmeans(x, m, nf, k, as, err);
        for (uint32_t i = 0; i < m && !rc; i++) cls[rows[i]] = as[i];
        free(x), free(as);
        if (rc) goto out;
        nc = k;
        unlabelled = n - m;
    }
    if (unlabelled) { /* the rest join the nearest class mean */
        centres = malloc(sizeof(double) * (size_t)nc * nf);
        if (!centres) {
            rc = MIM_ENOMEM;
            goto out;
        }
        uint32_t nrows = 0;
        for (uint32_t t = 0; t < n; t++)
            if (cls[t] != UINT32_MAX) rows[nrows++] = t;
        if ((rc = class_means(in, cls, rows, nrows, nc, nf, centres))) goto out;
        for (uint32_t t = 0; t < n; t++)
            if (cls[t] == UINT32_MAX) {
                full_angles(in, t, a);
                cls[t] = nearest_centre(a, centres, nc, nf);
            }
    }
    /* drop empty clusters; k-means names its classes "cluster-N" */
    uint32_t *count = calloc(nc, sizeof *count), *remap = malloc(sizeof(uint32_t) * (nc ? nc : 1));
    if (!count || !remap) {
        free(count), free(remap);
        rc = MIM_ENOMEM;
        goto out;
    }
    for (uint32_t t = 0; t < n; t++) count[cls[t]]++;
    uint32_t used = 0;
    for (uint32_t c = 0; c < nc; c++) {
        remap[c] = count[c] ? used : UINT32_MAX;
        if (!count[c]) continue;
        if (*source == MIM_CLASSES_KMEANS) {
            char nm[32];
            snprintf(nm, sizeof nm, "cluster-%u", used);
            int64_t s = strtab_add(st, nm);
            if (s < 0) {
                rc = MIM_ENOMEM;
                break;
            }
            names[used] = (uint32_t)s;
        } else {
            names[used] = names[c];
        }
        used++;
    }
    for (uint32_t t = 0; t < n && !rc; t++) cls[t] = remap[cls[t]];
    free(count), free(remap);
    nc = used;
out:
    free(str_class), free(rows), free(a), free(centres);
    if (rc) {
        free(names);
        return rc;
    }
    *names_out = names;
    *nc_out = nc;
    return 0;
}

int mim_index_build(mim_index_t **out, const mim_index_input_t *in, const mim_index_options_t *opt_in,
                    mim_index_report_t *report, mim_error_t *err)
{
    *out = NULL;
    mim_index_options_t opt = opt_in ? *opt_in : (mim_index_options_t){0};
    double t0 = mim_now();
    uint32_t n = in->n_templates, L = in->n_landmarks;
    if (!n) return mim_error_set(err, MIM_EINVAL, "no templates to index (ingest some first)");
    if (L < MIM_LANDMARKS_MIN || L > MIM_LANDMARKS_MAX)
        return mim_error_set(err, MIM_EINVAL, "%u landmarks: the index needs %d to %d", L, MIM_LANDMARKS_MIN,
                             MIM_LANDMARKS_MAX);
    for (size_t i = 0; i < (size_t)n * L * 3; i++)
        if (!isfinite(in->landmarks[i]))
            return mim_error_set(err, MIM_ENONFINITE, "template %llu: landmark %u is not finite",
                                 (unsigned long long)in->ids[i / (L * 3)], (uint32_t)(i / 3 % L));
    uint32_t nf = mim_index_angle_count(L), d = opt.features ? opt.features : 60;
    if (d > nf) d = nf;
    uint32_t d2 = opt.missing_features ? opt.missing_features : 3 * d;
    if (d2 < d) d2 = d;
    if (d2 > nf) d2 = nf;
    if (!(opt.noise <= 1) || (opt.augment > 64 && opt.noise >= 0))
        return mim_error_set(err, MIM_EINVAL, "noise augmentation: noise %g (at most 1) and %u copies (at most 64)",
                             opt.noise, opt.augment);
    if (!(opt.weight <= 4)) return mim_error_set(err, MIM_EINVAL, "angle weighting: power %g (at most 4)", opt.weight);
    if (!(opt.discriminant_noise <= 1))
        return mim_error_set(err, MIM_EINVAL, "linear discriminants: noise %g (at most 1)", opt.discriminant_noise);
    if (!(opt.shape_noise <= 1))
        return mim_error_set(err, MIM_EINVAL, "shape discriminants: noise %g (at most 1)", opt.shape_noise);
    const int proportions = opt.proportions ? opt.proportions : MIM_INDEX_PROPORTIONS_DEFAULT;
    if (proportions != MIM_INDEX_PROPORTIONS_BODY && proportions != MIM_INDEX_PROPORTIONS_CANONICAL)
        return mim_error_set(err, MIM_EINVAL, "proportions %d: neither the body's nor canonical", opt.proportions);
    /* canonical proportions: the angles below see the templates redrawn
     * on the mean segment lengths (proportions.c), as queries' will be;
     * the shape discriminants and the training noise see them as given */
    const mim_index_input_t *raw = in;
    mim__proportions_t prop = {0};
    mim_index_input_t canonical_in;
    float *canonical = NULL;
    if (in->parent && proportions == MIM_INDEX_PROPORTIONS_CANONICAL) {
        int prc = mim__proportions_build(&prop, in, err);
        if (prc) return prc;
        if (!(canonical = malloc(sizeof *canonical * 3 * (size_t)n * L))) return MIM_ENOMEM;
        for (uint32_t t = 0; t < n; t++)
            mim__proportions_apply(&prop, L, in->landmarks + (size_t)t * L * 3, NULL, canonical + (size_t)t * L * 3);
        canonical_in = *in;
        canonical_in.landmarks = canonical;
        in = &canonical_in;
    }
    double noise = opt.noise < 0 ? 0 : opt.noise > 0 ? opt.noise : MIM_INDEX_NOISE_DEFAULT;
    uint32_t A = noise > 0 ? (opt.augment ? opt.augment : MIM_INDEX_AUGMENT_DEFAULT) : 0;
    const double scale = body_scale(raw); /* the training noises' unit */
    double sigma = A ? noise * scale : 0;
    if (!A) noise = 0;
    double wpow = opt.weight < 0 ? 0 : opt.weight > 0 ? opt.weight : MIM_INDEX_WEIGHT_DEFAULT;
    if (!(wpow > 0) || !A) wpow = 0;
    double dnoise = opt.discriminant_noise > 0 ? opt.discriminant_noise : 0;
    double snoise = opt.shape_noise < 0 ? -1 : opt.shape_noise > 0 ? opt.shape_noise : MIM_INDEX_SHAPE_NOISE_DEFAULT;
    mim_index_t *ix = calloc(1, sizeof *ix);
    strtab_t st = {0};
    uint32_t *cls = malloc(sizeof(uint32_t) * n), *names = NULL, nc = 0, source = 0;
    uint32_t *order = NULL, *rows = NULL, *mmap = NULL, *y = NULL, *grp = NULL;
    float *x = NULL, *desc = NULL, *noisy = NULL;
    double *sx = NULL;
    int rc = 0;
    mim_progress_t *progress = NULL; /* set once begun */
    if (!ix || !cls || strtab_add(&st, "") != 0) {
        rc = MIM_ENOMEM;
        goto out;
    }
    ix->n_landmarks = L, ix->d = d, ix->d2 = d2, ix->n_templates = n;
    ix->prop = prop;
    ix->augment = A, ix->noise = noise, ix->weight = wpow;
    ix->exact_max = opt.exact_max ? opt.exact_max : 8192;
    ix->checks = opt.checks ? opt.checks : 128;
    if ((rc = assign_classes(in, &st, cls, &names, &nc, &source, err))) goto out;
    ix->n_classes = nc, ix->class_source = source;
    if (dnoise > 0 && (rc = mim__lda_build(&ix->lda, in, cls, nc, dnoise * scale, err))) goto out;
    ix->discriminant_noise = ix->lda.nf ? dnoise : 0;
    if (snoise >= 0 && (rc = mim__shape_build(&ix->shape, raw, cls, nc, snoise, err))) goto out;
    progress = opt.progress;
    if (progress) mim_progress_begin(progress, "index", (nc > 1 && !(opt.C > 0 && opt.gamma > 0) ? 16 : 0) + nc);

    /* the tree chooses the d angles, on a sample of at most select_max rows
     * (templates and their noisy copies) */
    uint32_t smax = opt.select_max_samples ? opt.select_max_samples : 4000;
    uint32_t m = n < smax / (1 + A) ? n : smax / (1 + A);
    if (!m) m = 1;
    /* SVMs: a uniform sample of at most 2 * svm_max rows, copies included */
    uint32_t vmax = 2 * (opt.svm_max_samples ? opt.svm_max_samples : 4000);
    uint32_t sm = n < vmax / (1 + A) ? n : vmax / (1 + A);
    if (!sm) sm = 1;
    size_t ycap = (size_t)(m > sm ? m : sm) * (1 + A);
    rows = malloc(sizeof(uint32_t) * n);
    x = malloc(sizeof(float) * (size_t)m * (1 + A) * nf);
    y = malloc(sizeof(uint32_t) * (ycap > n ? ycap : n));
    noisy = malloc(sizeof(float) * 3 * L);
    ix->selected = malloc(sizeof(uint32_t) * d2);
    ix->w = malloc(sizeof(float) * d2);
    if (in->mirror) mmap = malloc(sizeof(uint32_t) * nf);
    if (!rows || !x || !y || !noisy || !ix->selected || !ix->w || (in->mirror && !mmap)) {
        rc = MIM_ENOMEM;
        goto out;
    }
    for (uint32_t i = 0; i < n; i++) rows[i] = i;
    for (uint32_t f = 0; f < d2; f++) ix->w[f] = 1;
    mim_rng_t rng;
    mim_rng_seed(&rng, MIM__INDEX_SEED, 0x73656cULL);
    for (uint32_t i = 0; i < m && n > m; i++) {
        uint32_t j = i + (uint32_t)mim_rng_below(&rng, n - i), tt = rows[i];
        rows[i] = rows[j], rows[j] = tt;
    }
    for (uint32_t i = 0; i < m; i++) {
        full_angles(in, rows[i], x + (size_t)i * nf);
        y[i] = cls[rows[i]];
    }
    mim_rng_seed(&rng, MIM__INDEX_SEED, 0x6e6f6973ULL);
    for (uint32_t i = 0; i < m; i++) /* the noisy copies after the templates */
        for (uint32_t a = 0; a < A; a++) {
            size_t row = m + (size_t)i * A + a;
            noisy_landmarks(raw, &prop, rows[i], sigma, &rng, noisy);
            mim_index_angles(noisy, NULL, L, x + row * nf);
            y[row] = cls[rows[i]];
        }
    if (mmap) mim_index_angle_mirror(L, in->mirror, mmap);
    mim_select_options_t so = {.features = d2}; /* ranked: the first d are the descriptor */
    mim_select_report_t srep = {0};
    if (nc > 1) {
        if ((rc = mim_index_select(x, y, m * (1 + A), nf, nc, mmap, &so, ix->selected, &srep, err))) goto out;
    } else { /* one class: nothing to separate; keep the first d angles */
        for (uint32_t s = 0; s < d2; s++) ix->selected[s] = s * (nf / d2);
    }
    free(x), x = NULL;

    /* templates grouped by class (counting sort), descriptors, labels */
    ix->class_start = calloc(nc + 1, sizeof(uint32_t));
    ix->class_name = malloc(sizeof(uint32_t) * (nc ? nc : 1));
    order = malloc(sizeof(uint32_t) * n);
    ix->ids = malloc(sizeof(uint64_t) * n);
    ix->subject = malloc(sizeof(uint32_t) * n);
    ix->pose = malloc(sizeof(uint32_t) * n);
    ix->desc = malloc(sizeof(float) * (size_t)n * d);
    ix->extra = malloc(sizeof(float) * ((size_t)n * (d2 - d) + 1));
    desc = malloc(sizeof(float) * d2);
    if (!ix->extra || !desc || !ix->class_start || !ix->class_name || !order || !ix->ids || !ix->subject || !ix->pose || !ix->desc) {
        rc = MIM_ENOMEM;
        goto out;
    }
    memcpy(ix->class_name, names, sizeof(uint32_t) * nc);
    for (uint32_t t = 0; t < n; t++) ix->class_start[cls[t] + 1]++;
    for (uint32_t c = 0; c < nc; c++) ix->class_start[c + 1] += ix->class_start[c];
    {
        uint32_t *fill = malloc(sizeof(uint32_t) * (nc ? nc : 1));
        if (!fill) {
            rc = MIM_ENOMEM;
            goto out;
        }
        memcpy(fill, ix->class_start, sizeof(uint32_t) * nc);
        for (uint32_t t = 0; t < n; t++) order[fill[cls[t]]++] = t;
        free(fill);
    }
    for (uint32_t r = 0; r < n; r++) {
        uint32_t t = order[r];
        int64_t sj = strtab_add(&st, in->subjects ? in->subjects[t] : "");
        int64_t sp = strtab_add(&st, in->poses ? in->poses[t] : "");
        if (sj < 0 || sp < 0) {
            rc = MIM_ENOMEM;
            goto out;
        }
        ix->ids[r] = in->ids[t];
        ix->subject[r] = (uint32_t)sj, ix->pose[r] = (uint32_t)sp;
        mim_index_descriptor(in->landmarks + (size_t)t * L * 3, NULL, L, ix->selected, d2, desc);
        memcpy(ix->desc + (size_t)r * d, desc, sizeof(float) * d);
        memcpy(ix->extra + (size_t)r * (d2 - d), desc + d, sizeof(float) * (d2 - d));
    }
    /* an undefined angle (coincident landmarks) takes its class mean */
    for (uint32_t c = 0; c < nc; c++)
        for (uint32_t f = 0; f < d2; f++) {
            float *col = f < d ? ix->desc + f : ix->extra + (f - d);
            size_t stride = f < d ? d : d2 - d;
            double s = 0;
            uint32_t cnt = 0, nan = 0;
            for (uint32_t r = ix->class_start[c]; r < ix->class_start[c + 1]; r++) {
                float v = col[r * stride];
                if (isnan(v)) nan++;
                else s += v, cnt++;
            }
            if (!nan) continue;
            for (uint32_t r = ix->class_start[c]; r < ix->class_start[c + 1]; r++)
                if (isnan(col[r * stride])) col[r * stride] = cnt ? (float)(s / cnt) : 0.5f * 3.14159265f;
        }

    /* SVMs on a uniform sample of at most 2 * svm_max rows: sm templates
     * and their noisy copies */
    ix->svm = calloc(nc ? nc : 1, sizeof *ix->svm);
    sx = malloc(sizeof(double) * (size_t)sm * (1 + A) * d);
    grp = malloc(sizeof(uint32_t) * (size_t)sm * (1 + A));
    if (!ix->svm || !sx || !grp) {
        rc = MIM_ENOMEM;
        goto out;
    }
    for (uint32_t i = 0; i < n; i++) rows[i] = i; /* rows of the class-sorted arrays */
    mim_rng_seed(&rng, MIM__INDEX_SEED, 0x73766dULL);
    for (uint32_t i = 0; i < sm && n > sm; i++) {
        uint32_t j = i + (uint32_t)mim_rng_below(&rng, n - i), tt = rows[i];
        rows[i] = rows[j], rows[j] = tt;
    }
    uint32_t n_groups = 0;
    {
        /* subjects renumbered 0.. in order of appearance for the folds */
        uint32_t *gmap = malloc(sizeof(uint32_t) * st.n);
        if (!gmap) {
            rc = MIM_ENOMEM;
            goto out;
        }
        for (uint32_t i = 0; i < st.n; i++) gmap[i] = UINT32_MAX;
        for (uint32_t i = 0; i < sm; i++) {
            uint32_t r = rows[i], c = 0;
            while (ix->class_start[c + 1] <= r) c++;
            y[i] = c;
            uint32_t sj = ix->subject[r];
            if (gmap[sj] == UINT32_MAX) gmap[sj] = n_groups++;
            grp[i] = gmap[sj];
            for (uint32_t f = 0; f < d; f++) sx[(size_t)i * d + f] = ix->desc[(size_t)r * d + f];
        }
        free(gmap);
        mim_rng_seed(&rng, MIM__INDEX_SEED, 0x6e6f6974ULL);
        double *ss = calloc(2 * (size_t)d2, sizeof(double)); /* per angle: sum of squared changes, count */
        if (!ss) {
            rc = MIM_ENOMEM;
            goto out;
        }
        for (uint32_t i = 0; i < sm; i++)
            for (uint32_t a = 0; a < A; a++) {
                size_t row = sm + (size_t)i * A + a;
                uint32_t r = rows[i];
                noisy_landmarks(raw, &prop, order[r], sigma, &rng, noisy);
                mim_index_descriptor(noisy, NULL, L, ix->selected, d2, desc);
                y[row] = y[i], grp[row] = grp[i];
                for (uint32_t f = 0; f < d; f++) /* an undefined angle: the template's own */
                    sx[row * d + f] = isnan(desc[f]) ? ix->desc[(size_t)r * d + f] : desc[f];
                for (uint32_t f = 0; f < d2 && wpow > 0; f++) { /* each angle's change, for its weight */
                    float c = f < d ? ix->desc[(size_t)r * d + f] : ix->extra[(size_t)r * (d2 - d) + f - d];
                    if (isnan(desc[f])) continue;
                    ss[f] += (double)(desc[f] - c) * (desc[f] - c), ss[d2 + f]++;
                }
            }
        if (wpow > 0) { /* weights s^-wpow, RMS 1 over the descriptor */
            double sq = 0;
            for (uint32_t f = 0; f < d2; f++) {
                double sd = ss[d2 + f] > 0 ? sqrt(ss[f] / ss[d2 + f]) : 0;
                if (sd < 1e-4) sd = 1e-4;
                ix->w[f] = (float)pow(sd, -wpow);
                if (f < d) sq += (double)ix->w[f] * ix->w[f];
            }
            double norm = sqrt(sq / d);
            for (uint32_t f = 0; f < d2; f++) ix->w[f] = (float)(ix->w[f] / norm);
            for (size_t row = 0; row < (size_t)sm * (1 + A); row++)
                for (uint32_t f = 0; f < d; f++) sx[row * d + f] *= ix->w[f];
        }
        free(ss);
    }
    mim__svm_data_t sd = {sx, y, grp, sm * (1 + A), d, nc, n_groups};
    if ((rc = mim__svm_train_all(&sd, &opt, ix->svm, &ix->C, &ix->gamma, &ix->cv_accuracy, err))) goto out;
    if ((rc = mim__index_build_knn(ix, err))) goto out;
    ix->strings = st.s, ix->n_strings = st.n;
    st.s = NULL, st.n = 0;
    if (report) {
        memset(report, 0, sizeof *report);
        report->n_classes = nc, report->d = d, report->class_source = source;
        report->C = ix->C, report->gamma = ix->gamma, report->cv_accuracy = ix->cv_accuracy;
        for (uint32_t c = 0; c < nc; c++) {
            report->support_vectors += ix->svm[c].n_sv;
            report->exact_classes += ix->flann_exact[c] != 0;
        }
        report->select = srep;
        report->augment = A, report->noise = noise, report->weight = wpow;
        report->discriminant_noise = ix->discriminant_noise;
        report->shape_noise = ix->shape.n_classes ? ix->shape.noise_max : -1;
        report->canonical = ix->prop.on;
        report->seconds = mim_now() - t0;
    }
    *out = ix;
    ix = NULL;
out:
    if (progress) mim_progress_end(progress);
    for (uint32_t i = 0; i < st.n; i++) free(st.s[i]);
    free(st.s), free(st.slot);
    mim_index_close(&ix);
    free(cls), free(names), free(order), free(rows), free(mmap), free(y), free(grp), free(x), free(desc), free(sx);
    free(noisy), free(canonical);
    return rc;
}

void mim_index_get_info(const mim_index_t *ix, mim_index_info_t *o)
{
    memset(o, 0, sizeof *o);
    o->n_templates = ix->n_templates, o->n_landmarks = ix->n_landmarks, o->d = ix->d, o->d2 = ix->d2;
    o->n_classes = ix->n_classes, o->class_source = ix->class_source;
    o->C = ix->C, o->gamma = ix->gamma, o->cv_accuracy = ix->cv_accuracy;
    o->augment = ix->augment, o->noise = ix->noise, o->weight = ix->weight;
    o->discriminant_noise = ix->discriminant_noise;
    o->shape_noise = ix->shape.n_classes ? ix->shape.noise_max : -1;
    o->canonical = ix->prop.on;
    o->forests_loaded = ix->forests_loaded, o->forests_built = ix->forests_built;
    o->in_place = ix->borrowed && !ix->own;
    o->classes_ready = ix->n_classes;
    if (ix->lazy) {
        o->classes_ready = 0;
        for (uint32_t c = 0; c < ix->n_classes; c++)
            o->classes_ready += atomic_load_explicit(&ix->lazy->cls[c], memory_order_acquire) == 1;
    }
}

const char *mim_index_class_name(const mim_index_t *ix, uint32_t c)
{
    return c < ix->n_classes ? ix->strings[ix->class_name[c]] : "";
}

const uint32_t *mim_index_selected(const mim_index_t *ix) { return ix->selected; }
