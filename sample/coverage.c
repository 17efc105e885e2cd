/* Coverage of a set of pose-pairs by samples (seed 002, Section 6, eq.
 * 13): C(G, S) = 1/m sum_i D(g_i, s_i*), s_i* the sample nearest to g_i.
 *
 * The exhaustive scan computes D for every truth and sample. The default
 * computes it only where lower bounds (coverage_bounds.c) cannot rule the
 * sample out: the truths of a chunk bound every sample at once (a sample's
 * features read from memory once for all of them), then each measures
 * the samples whose bound is not above the nearest distance found: the
 * nearest of the truth before first (the truths of a take come in
 * order), then the few of smallest bound, then the rest in index order
 * (their memory read in order), each against the nearest as it stands
 * then. D_I and D_S go on bounding a sample after aligning it (D_S a
 * joint at a time), and make its distance as the scan does only where no
 * bound passes the nearest. A sample that repeats an earlier one (a chain's refused
 * step) is skipped: it is exactly as far, and the scan keeps the earlier.
 * A sample is passed over only when a bound, hence its distance, is above
 * a distance found, and equal distances go to the lowest index as in the
 * scan: the answers are the scan's, to the bit. Truths are shared among
 * threads in chunks; the sum is made in the truths' order. */
#include "internal.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define N MIM_PAIR_JOINTS
#define SAMPLE_CHUNK 256
#define SEED 32
#define AHEAD 4
/* Consecutive truths taken at once, each trying its predecessor's nearest
 * first: up to 16, fewer for few truths (so that threads share them); never
 * a matter of the threads, so that the work done is the same on any. */
static uint32_t truth_chunk(uint32_t m) { return m >= 16 * MIM__BOUND_TRUTHS ? MIM__BOUND_TRUTHS : m >= 16 ? m / 16 : 1; }
_Static_assert(MIM__BOUND_TRUTHS == 16, "chunks of 16 truths at most");

typedef struct job {
    const mim_pair_prep_t *truth, *samples;
    uint32_t m, k, stride;
    mim_sample_metric_t metric;
    int exhaustive;
    float *feat;     /* k x stride: the samples' bound features */
    double *joints;  /* k x 3 x 34, for D_I and D_S: the samples' joints less their centroid (mim__align_centre), packed */
    uint8_t *repeat; /* k: 1 when an earlier sample is the same pose-pair */
    uint64_t *hash;  /* k: of each sample's joints, to find the repeats */
    double *slack;   /* per worker, then [0]: the samples' largest mim__bound_slack */
    double *nearest; /* m */
    uint32_t *which; /* m */
    mim_progress_t *progress;
    _Atomic uint32_t next, done;
    _Atomic uint64_t distances, aligned, cut;
} job_t;

static uint64_t joints_hash(const mim_pair_prep_t *p)
{
    uint64_t h = 0x9e3779b97f4a7c15u, w;
    for (int i = 0; i < 3 * N; i++) {
        memcpy(&w, &p->joints[i], sizeof w);
        h = (h ^ w) * 0x100000001b3u;
        h ^= h >> 29;
    }
    return h;
}

static void features(void *ctx, uint32_t worker)
{
    job_t *j = ctx;
    double slack = 0;
    for (uint32_t s; (s = atomic_fetch_add(&j->next, SAMPLE_CHUNK)) < j->k;)
        for (uint32_t i = s; i < s + SAMPLE_CHUNK && i < j->k; i++) {
            mim__bound_features(j->metric, &j->samples[i], 0, j->feat + (size_t)i * j->stride);
            if (j->joints) {
                mim__centred_t c;
                mim__align_centre(j->samples[i].joints, &c);
                memcpy(j->joints + (size_t)i * 3 * N, c.p, sizeof c.p);
            }
            slack = fmax(slack, mim__bound_slack(j->metric, &j->samples[i]));
            j->hash[i] = joints_hash(&j->samples[i]);
        }
    j->slack[worker] = slack;
}

/* What D takes from a sample: its joints and its triangulation. */
static int same_pair(const mim_pair_prep_t *a, const mim_pair_prep_t *b)
{
    return !memcmp(a->joints, b->joints, sizeof a->joints) && a->ic.n_edges == b->ic.n_edges &&
           !memcmp(a->ic.edge, b->ic.edge, a->ic.n_edges * sizeof a->ic.edge[0]);
}

typedef struct hashed {
    uint64_t hash;
    uint32_t i;
} hashed_t;

static int by_hash(const void *x, const void *y)
{
    const hashed_t *a = x, *b = y;
    return a->hash != b->hash ? (a->hash < b->hash ? -1 : 1) : (a->i > b->i) - (a->i < b->i);
}

static int find_repeats(job_t *j)
{
    hashed_t *h = malloc((size_t)j->k * sizeof *h);
    if (!h) return -1;
    for (uint32_t i = 0; i < j->k; i++) h[i] = (hashed_t){j->hash[i], i};
    qsort(h, j->k, sizeof *h, by_hash);
    for (uint32_t s = 0, e; s < j->k; s = e) {
        for (e = s + 1; e < j->k && h[e].hash == h[s].hash; e++) {}
        for (uint32_t x = s + 1; x < e; x++)
            for (uint32_t y = s; y < x && !j->repeat[h[x].i]; y++)
                if (!j->repeat[h[y].i] && same_pair(&j->samples[h[x].i], &j->samples[h[y].i])) j->repeat[h[x].i] = 1;
    }
    free(h);
    return 0;
}

/* Heap keys: a bound's bits made to sort as unsigned (a NaN bound is made
 * -inf: it rules nothing out), then the sample's index. */
static uint64_t key(float lb, uint32_t j)
{
    uint32_t u;
    if (isnan(lb)) lb = -INFINITY;
    memcpy(&u, &lb, sizeof u);
    u = (u & 0x80000000u) ? ~u : u | 0x80000000u;
    return (uint64_t)u << 32 | j;
}

/* The seeds: the SEED smallest keys met, in a heap with the largest on
 * top while they are gathered, then sorted in place, increasing. */
static void sift_down_max(uint64_t *h, uint32_t n, uint32_t i)
{
    for (;;) {
        uint32_t c = 2 * i + 1;
        if (c >= n) return;
        if (c + 1 < n && h[c + 1] > h[c]) c++;
        if (h[i] >= h[c]) return;
        uint64_t t = h[i];
        h[i] = h[c], h[c] = t, i = c;
    }
}

static void seeds_keep(uint64_t *h, uint32_t *n, uint64_t k)
{
    if (*n < SEED) {
        uint32_t c = (*n)++;
        for (h[c] = k; c > 0 && h[(c - 1) / 2] < h[c]; c = (c - 1) / 2) {
            const uint64_t up = h[(c - 1) / 2];
            h[(c - 1) / 2] = h[c], h[c] = up;
        }
    } else if (k < h[0]) {
        h[0] = k;
        sift_down_max(h, *n, 0);
    }
}

static void seeds_sort(uint64_t *h, uint32_t n)
{
    for (uint32_t e = n; e > 1; e--) {
        const uint64_t top = h[0];
        h[0] = h[e - 1], h[e - 1] = top;
        sift_down_max(h, e - 1, 0);
    }
}

/* Keeps (d, j) when it is nearer than (best, bj), or as near with a lower
 * index: what the scan's first strict minimum gives. */
static void keep(double d, uint32_t j, double *best, uint32_t *bj)
{
    if (d < *best || (d == *best && d < INFINITY && j < *bj)) *best = d, *bj = j;
}

/* A worker's room: the first bounds of every sample for each truth of a
 * chunk, those a truth may measure, the truths' features and slack. */
typedef struct room {
    float *lb, *fa;
    double slack[MIM__BOUND_TRUTHS];
    uint32_t *cand;       /* the samples a truth may measure */
    uint8_t *seen;        /* k: 1 for the seeds, while a truth is measured */
    uint64_t seed[SEED]; /* the keys of the seeds */
    mim__shape_truth_t shape_a;
    mim__centred_t centred_a;
} room_t;

/* What measuring sample j reads: its joints, and for D_I and D_S (which
 * take them packed) its features (D_I's weights, not its lengths). Asked
 * for with low locality (prefetcht2 on x86): 8 % faster for D_I and D_S
 * than into the first-level cache, where the 49 lines a sample of D_I
 * needs compete with those in use (bench/RESULTS.md). */
static void prefetch(const job_t *jb, uint32_t j)
{
    const int aligned = jb->metric == MIM_METRIC_IC || jb->metric == MIM_METRIC_SHAPE;
    const char *p = (const char *)(aligned ? jb->joints + (size_t)j * 3 * N : jb->samples[j].joints);
    for (size_t o = 0; o < 3 * N * sizeof(double); o += 64) __builtin_prefetch(p + o, 0, 1);
    if (!aligned) return;
    const uint32_t from = jb->metric == MIM_METRIC_IC ? mim__bound_dim(jb->metric) / 2 : 0;
    const char *f = (const char *)(jb->feat + (size_t)j * jb->stride + from);
    for (size_t o = 0; o < (jb->stride - from) * sizeof(float); o += 64) __builtin_prefetch(f + o, 0, 1);
}

/* The nearest sample to truth i, the t-th of its chunk (its first bounds
 * made by the caller). */
static void nearest(job_t *jb, room_t *rm, uint32_t i, uint32_t t, uint32_t hint, double *best, uint32_t *bj, uint64_t *nd,
                    uint64_t *na, uint64_t *nc)
{
    const mim_pair_prep_t *a = &jb->truth[i];
    *best = INFINITY, *bj = UINT32_MAX;
    if (jb->exhaustive) {
        for (uint32_t j = 0; j < jb->k; j++) {
            double d = mim_sample_distance(a, &jb->samples[j], jb->metric);
            if (d < *best) *best = d, *bj = j;
        }
        *nd += jb->k;
        return;
    }
    const int shape = jb->metric == MIM_METRIC_SHAPE, ic = jb->metric == MIM_METRIC_IC;
    const double slack = rm->slack[t];
    const float *lb = rm->lb + (size_t)t * jb->k;
    if (shape) mim__shape_truth(a, &rm->shape_a);
    if (shape || ic) mim__align_centre(a->joints, &rm->centred_a);
    if (hint < jb->k) keep(mim_sample_distance(a, &jb->samples[hint], jb->metric), hint, best, bj), (*nd)++;
    /* the samples that may be nearer than the hint, in index order; the
     * SEED of smallest bound first, in increasing order (a heap of them),
     * so that best falls near its end; then the rest in index order, each
     * against best as it stands then: their memory read in order */
    uint32_t n = 0, seeds = 0;
    for (uint32_t j = 0; j < jb->k; j++)
        if (!jb->repeat[j] && j != hint && !(lb[j] > *best)) rm->cand[n++] = j, seeds_keep(rm->seed, &seeds, key(lb[j], j));
    seeds_sort(rm->seed, seeds);
    for (uint32_t s = 0; s < seeds; s++) rm->seen[(uint32_t)rm->seed[s]] = 1;
    for (uint32_t at = 0; at < seeds + n; at++) {
        const uint32_t j = at < seeds ? (uint32_t)rm->seed[at] : rm->cand[at - seeds];
        if ((at >= seeds && rm->seen[j]) || lb[j] > *best) continue;
        /* a sample's a few ahead, while this one is measured */
        if (at + AHEAD >= seeds && at + AHEAD - seeds < n && !(lb[rm->cand[at + AHEAD - seeds]] > *best))
            prefetch(jb, rm->cand[at + AHEAD - seeds]);
        const mim_pair_prep_t *b = &jb->samples[j];
        if (shape || ic) {
            int exact;
            const float *fb = jb->feat + (size_t)j * jb->stride;
            const double *b_centred = jb->joints + (size_t)j * 3 * N;
            const double d =
                shape ? mim__shape_distance_within(a, &rm->centred_a, &rm->shape_a, b_centred, fb, slack, *best, &exact)
                      : mim__ic_distance_within(a, &rm->centred_a, rm->fa + (size_t)t * mim__bound_dim(jb->metric), b, b_centred, fb,
                                                slack, *best, &exact);
            (*na)++;
            if (exact) keep(d, j, best, bj), (*nd)++;
            else (*nc)++;
            continue;
        }
        keep(mim_sample_distance(a, b, jb->metric), j, best, bj), (*nd)++;
    }
    for (uint32_t s = 0; s < seeds; s++) rm->seen[(uint32_t)rm->seed[s]] = 0;
}

static void truths(void *ctx, uint32_t worker)
{
    job_t *j = ctx;
    room_t rm = {0};
    if (!j->exhaustive) {
        rm.lb = malloc((size_t)MIM__BOUND_TRUTHS * j->k * sizeof *rm.lb);
        rm.fa = malloc((size_t)MIM__BOUND_TRUTHS * j->stride * sizeof *rm.fa);
        rm.cand = malloc((size_t)j->k * sizeof *rm.cand), rm.seen = calloc(j->k, 1);
        if (!rm.lb || !rm.fa || !rm.cand || !rm.seen) goto out; /* the others take this worker's share */
    }
    uint64_t nd = 0, na = 0, nc = 0;
    const uint32_t chunk = truth_chunk(j->m);
    const uint32_t dim = mim__bound_dim(j->metric);
    for (uint32_t s; (s = atomic_fetch_add(&j->next, chunk)) < j->m;) {
        const uint32_t n = s + chunk < j->m ? chunk : j->m - s;
        for (uint32_t t = 0; t < n && !j->exhaustive; t++) {
            rm.slack[t] = mim__bound_slack(j->metric, &j->truth[s + t]) + j->slack[0];
            mim__bound_features(j->metric, &j->truth[s + t], 1, rm.fa + (size_t)t * dim);
        }
        if (!j->exhaustive) mim__bound_lower(j->metric, rm.fa, n, j->feat, j->k, rm.slack, rm.lb);
        uint32_t hint = UINT32_MAX;
        for (uint32_t i = s; i < s + n; i++) {
            nearest(j, &rm, i, i - s, hint, &j->nearest[i], &j->which[i], &nd, &na, &nc);
            hint = j->which[i];
            uint32_t done = atomic_fetch_add(&j->done, 1) + 1;
            if (worker == 0 && j->progress) mim_progress_update(j->progress, done);
        }
    }
    atomic_fetch_add(&j->distances, nd), atomic_fetch_add(&j->aligned, na), atomic_fetch_add(&j->cut, nc);
out:
    free(rm.lb), free(rm.fa), free(rm.cand), free(rm.seen);
}

int mim_sample_coverage(const mim_pair_prep_t *truth, uint32_t m, const mim_pair_prep_t *samples, uint32_t k,
                        mim_sample_metric_t metric, const mim_sample_coverage_options_t *opt, mim_sample_coverage_t *out,
                        mim_error_t *err)
{
    if (!truth || !samples || !out || !m || !k)
        return mim_error_set(err, MIM_EINVAL, "coverage: needs truth pose-pairs and samples (%u and %u given)", m, k);
    const unsigned need_a = mim_sample_metric_parts(metric, 0), need_b = mim_sample_metric_parts(metric, 1);
    for (uint32_t i = 0; i < m + k; i++) {
        const int sample = i >= m;
        const mim_pair_prep_t *p = sample ? &samples[i - m] : &truth[i];
        if ((p->parts & (sample ? need_b : need_a)) != (sample ? need_b : need_a))
            return mim_error_set(err, MIM_EINVAL, "coverage: %s %u was prepared without the %s this distance reads",
                                 sample ? "sample" : "truth", (sample ? i - m : i) + 1,
                                 (sample ? need_b : need_a) & MIM_PREP_TRIANGULATION ? "triangulation" : "shape contexts");
    }
    const mim_sample_coverage_options_t none = {0};
    if (!opt) opt = &none;
    const uint32_t threads = opt->threads ? opt->threads : 1;
    job_t j = {.truth = truth, .samples = samples, .m = m, .k = k, .stride = mim__bound_stride(metric), .metric = metric,
               .exhaustive = opt->exhaustive, .progress = opt->progress};
    double *nearest = out->nearest ? NULL : malloc((size_t)m * sizeof *nearest);
    uint32_t *which = out->which ? NULL : malloc((size_t)m * sizeof *which);
    j.nearest = out->nearest ? out->nearest : nearest, j.which = out->which ? out->which : which;
    j.slack = calloc(threads, sizeof *j.slack);
    if (!j.exhaustive) {
        j.feat = malloc((size_t)k * j.stride * sizeof *j.feat);
        j.repeat = calloc(k, 1), j.hash = malloc((size_t)k * sizeof *j.hash);
        if (metric == MIM_METRIC_IC || metric == MIM_METRIC_SHAPE) j.joints = malloc((size_t)k * 3 * N * sizeof *j.joints);
    }
    int rc = 0;
    if (!j.nearest || !j.which || !j.slack ||
        (!j.exhaustive && (!j.feat || !j.repeat || !j.hash || (!j.joints && (metric == MIM_METRIC_IC || metric == MIM_METRIC_SHAPE))))) {
        rc = mim_error_set(err, MIM_ENOMEM, "coverage: out of memory for %u truths and %u samples", m, k);
        goto done;
    }
    if (!j.exhaustive) {
        atomic_init(&j.next, 0);
        mim__parallel(threads, features, &j);
        for (uint32_t t = 1; t < threads; t++) j.slack[0] = fmax(j.slack[0], j.slack[t]);
        if (find_repeats(&j)) {
            rc = mim_error_set(err, MIM_ENOMEM, "coverage: out of memory for %u samples", k);
            goto done;
        }
    }
    if (j.progress) mim_progress_begin(j.progress, "coverage", m);
    atomic_init(&j.next, 0), atomic_init(&j.done, 0), atomic_init(&j.distances, 0), atomic_init(&j.aligned, 0);
    atomic_init(&j.cut, 0);
    mim__parallel(threads, truths, &j);
    if (j.progress) mim_progress_end(j.progress);
    if (atomic_load(&j.done) < m) {
        rc = mim_error_set(err, MIM_ENOMEM, "coverage: out of memory for %u samples' bounds", k);
        goto done;
    }
    double sum = 0;
    for (uint32_t i = 0; i < m; i++) sum += j.nearest[i];
    out->coverage = sum / m;
    out->distances = atomic_load(&j.distances), out->aligned = atomic_load(&j.aligned), out->cut = atomic_load(&j.cut);
done:
    free(nearest), free(which), free(j.slack), free(j.feat), free(j.repeat), free(j.hash), free(j.joints);
    return rc;
}
