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
 * bound passes the nearest; asked for together, they go through the
 * samples in one pass, and a sample both still need is aligned once for
 * both. A sample that repeats an earlier one (a chain's refused step) is
 * skipped: it is exactly as far, and the scan keeps the earlier.
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

/* One measure's part of a job. */
typedef struct measure {
    mim_sample_metric_t metric;
    uint32_t stride, dim;
    float *feat;     /* k x stride: the samples' bound features */
    double *slack;   /* per worker, then [0]: the samples' largest mim__bound_slack */
    double *nearest; /* m */
    uint32_t *which; /* m */
    _Atomic uint64_t distances, aligned, cut;
} measure_t;

/* The measures a truth is measured in together: D_I and D_S, when both
 * are asked for, share the samples they align (each aligned once for
 * both); any other measure goes alone. */
#define MEASURES 4
typedef struct group {
    int n, q[2]; /* measures (indices into job_t.ms) */
} group_t;

typedef struct job {
    const mim_pair_prep_t *truth, *samples;
    uint32_t m, k;
    int n, groups; /* measures, groups of them */
    measure_t ms[MEASURES];
    group_t group[MEASURES];
    int exhaustive;
    double *joints;  /* k x 3 x 34, for D_I and D_S: the samples' joints less their centroid (mim__align_centre), packed */
    uint8_t *repeat; /* k: 1 when an earlier sample is the same pose-pair */
    uint64_t *hash;  /* k: of each sample's joints, to find the repeats */
    mim_progress_t *progress;
    _Atomic uint32_t next, done;
} job_t;

static int aligned_metric(mim_sample_metric_t metric) { return metric == MIM_METRIC_IC || metric == MIM_METRIC_SHAPE; }

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
    double slack[MEASURES] = {0};
    for (uint32_t s; (s = atomic_fetch_add(&j->next, SAMPLE_CHUNK)) < j->k;)
        for (uint32_t i = s; i < s + SAMPLE_CHUNK && i < j->k; i++) {
            for (int q = 0; q < j->n; q++) {
                const measure_t *ms = &j->ms[q];
                mim__bound_features(ms->metric, &j->samples[i], 0, ms->feat + (size_t)i * ms->stride);
                slack[q] = fmax(slack[q], mim__bound_slack(ms->metric, &j->samples[i]));
            }
            if (j->joints) {
                mim__centred_t c;
                mim__align_centre(j->samples[i].joints, &c);
                memcpy(j->joints + (size_t)i * 3 * N, c.p, sizeof c.p);
            }
            j->hash[i] = joints_hash(&j->samples[i]);
        }
    for (int q = 0; q < j->n; q++) j->ms[q].slack[worker] = slack[q];
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

/* A worker's room: for each measure, the first bounds of every sample
 * for each truth of a chunk, the truths' features and slack, the seeds;
 * the samples a truth may measure. */
typedef struct room {
    float *lb[MEASURES], *fa[MEASURES];
    double slack[MEASURES][MIM__BOUND_TRUTHS];
    uint32_t *cand;              /* the samples a truth may measure in any measure of its group */
    uint8_t *seen;               /* k: bit g set for the hint and seeds of the group's g-th measure, once measured */
    uint64_t seed[2][SEED];      /* the keys of the seeds, for each measure of a group */
    mim__shape_truth_t shape_a;
    mim__centred_t centred_a;
} room_t;

/* What measuring sample j in group gr reads: its joints, and for D_I and
 * D_S (which take them packed) its features (D_I's weights, not its
 * lengths). Asked for with low locality (prefetcht2 on x86): 8 % faster
 * for D_I and D_S than into the first-level cache, where the 49 lines a
 * sample of D_I needs compete with those in use (bench/RESULTS.md).
 * Always inlined: GCC 12 (-O2, its modref analysis) finds a function of
 * prefetches alone free of effects and drops every call to it. */
static inline __attribute__((always_inline)) void prefetch(const job_t *jb, const group_t *gr, int need, uint32_t j)
{
    const int aligned = aligned_metric(jb->ms[gr->q[0]].metric);
    const char *p = (const char *)(aligned ? jb->joints + (size_t)j * 3 * N : jb->samples[j].joints);
    for (size_t o = 0; o < 3 * N * sizeof(double); o += 64) __builtin_prefetch(p + o, 0, 1);
    for (int g = 0; aligned && g < gr->n; g++) {
        if (!(need >> g & 1)) continue;
        const measure_t *ms = &jb->ms[gr->q[g]];
        const uint32_t from = ms->metric == MIM_METRIC_IC ? ms->dim / 2 : 0;
        const char *f = (const char *)(ms->feat + (size_t)j * ms->stride + from);
        for (size_t o = 0; o < (ms->stride - from) * sizeof(float); o += 64) __builtin_prefetch(f + o, 0, 1);
    }
}

/* A measure's search for one truth: the nearest as it stands and what it
 * counted. */
typedef struct search {
    double best;
    uint32_t bj;
    uint64_t distances, aligned, cut;
} search_t;

/* Measures sample j for truth a (the t-th of its chunk) in measure q; bb:
 * j aligned onto a, or NULL (aligned here when the measure aligns). */
static void measure(const job_t *jb, room_t *rm, const mim_pair_prep_t *a, uint32_t t, int q, uint32_t j, const double *bb,
                    search_t *sr)
{
    const measure_t *ms = &jb->ms[q];
    const mim_pair_prep_t *b = &jb->samples[j];
    if (!aligned_metric(ms->metric)) {
        keep(mim_sample_distance(a, b, ms->metric), j, &sr->best, &sr->bj), sr->distances++;
        return;
    }
    double own[3 * N];
    if (!bb) mim__align_centred(&rm->centred_a, jb->joints + (size_t)j * 3 * N, own), bb = own;
    int exact;
    const float *fb = ms->feat + (size_t)j * ms->stride;
    const double slack = rm->slack[q][t];
    const double d = ms->metric == MIM_METRIC_SHAPE
                         ? mim__shape_distance_aligned(a, &rm->shape_a, bb, fb, slack, sr->best, &exact)
                         : mim__ic_distance_aligned(a, rm->fa[q] + (size_t)t * ms->dim, b, bb, fb, slack, sr->best, &exact);
    sr->aligned++;
    if (exact) keep(d, j, &sr->best, &sr->bj), sr->distances++;
    else sr->cut++;
}

/* The measures of group gr (bit g for its g-th) in which sample j is
 * still to be measured: not measured yet, and its first bound not above
 * the nearest found. */
static int needed(const room_t *rm, const group_t *gr, const float *const *lb, const search_t *sr, uint32_t j)
{
    int need = 0;
    for (int g = 0; g < gr->n; g++) need |= (!(rm->seen[j] >> g & 1) && !(lb[g][j] > sr[g].best)) << g;
    return need;
}

/* The nearest sample to truth i, the t-th of its chunk (its first bounds
 * made by the caller), in each measure of group gr; hint: each measure's
 * nearest for the truth before (UINT32_MAX: none). */
static void nearest(job_t *jb, room_t *rm, const group_t *gr, uint32_t i, uint32_t t, const uint32_t *hint)
{
    const mim_pair_prep_t *a = &jb->truth[i];
    search_t sr[2] = {{INFINITY, UINT32_MAX, 0, 0, 0}, {INFINITY, UINT32_MAX, 0, 0, 0}};
    if (jb->exhaustive) {
        for (int g = 0; g < gr->n; g++) {
            for (uint32_t j = 0; j < jb->k; j++) {
                double d = mim_sample_distance(a, &jb->samples[j], jb->ms[gr->q[g]].metric);
                if (d < sr[g].best) sr[g].best = d, sr[g].bj = j;
            }
            sr[g].distances = jb->k;
        }
        goto out;
    }
    const float *lb[2];
    int shape = 0, aligned = 0;
    for (int g = 0; g < gr->n; g++) {
        const mim_sample_metric_t metric = jb->ms[gr->q[g]].metric;
        lb[g] = rm->lb[gr->q[g]] + (size_t)t * jb->k;
        shape |= metric == MIM_METRIC_SHAPE, aligned |= aligned_metric(metric);
    }
    if (shape) mim__shape_truth(a, &rm->shape_a);
    if (aligned) mim__align_centre(a->joints, &rm->centred_a);
    for (int g = 0; g < gr->n; g++)
        if (hint[g] < jb->k) measure(jb, rm, a, t, gr->q[g], hint[g], NULL, &sr[g]), rm->seen[hint[g]] |= (uint8_t)(1u << g);
    /* the samples that may be nearer than the hints in some measure, in
     * index order; in each measure the SEED of smallest bound first, in
     * increasing order (a heap of them), so that its best falls near its
     * end; then the rest in index order, each against the bests as they
     * stand then, aligned once for the measures that still need it:
     * their memory read in order */
    uint32_t n = 0, seeds[2] = {0, 0};
    for (uint32_t j = 0; j < jb->k; j++) {
        if (jb->repeat[j]) continue;
        int any = 0;
        for (int g = 0; g < gr->n; g++)
            if (j != hint[g] && !(lb[g][j] > sr[g].best)) any = 1, seeds_keep(rm->seed[g], &seeds[g], key(lb[g][j], j));
        if (any) rm->cand[n++] = j;
    }
    for (int g = 0; g < gr->n; g++) {
        seeds_sort(rm->seed[g], seeds[g]);
        for (uint32_t s = 0; s < seeds[g]; s++) {
            const uint32_t j = (uint32_t)rm->seed[g][s];
            rm->seen[j] |= (uint8_t)(1u << g);
            if (!(lb[g][j] > sr[g].best)) measure(jb, rm, a, t, gr->q[g], j, NULL, &sr[g]);
        }
    }
    for (uint32_t at = 0; at < n; at++) {
        const uint32_t j = rm->cand[at];
        const int need = needed(rm, gr, lb, sr, j);
        if (!need) continue;
        /* a sample's a few ahead, while this one is measured */
        const int ahead = at + AHEAD < n ? needed(rm, gr, lb, sr, rm->cand[at + AHEAD]) : 0;
        if (ahead) prefetch(jb, gr, ahead, rm->cand[at + AHEAD]);
        double bb[3 * N];
        const int both = need == 3;
        if (both) mim__align_centred(&rm->centred_a, jb->joints + (size_t)j * 3 * N, bb);
        for (int g = 0; g < gr->n; g++)
            if (need >> g & 1) measure(jb, rm, a, t, gr->q[g], j, both ? bb : NULL, &sr[g]);
    }
    for (int g = 0; g < gr->n; g++) {
        for (uint32_t s = 0; s < seeds[g]; s++) rm->seen[(uint32_t)rm->seed[g][s]] = 0;
        if (hint[g] < jb->k) rm->seen[hint[g]] = 0;
    }
out:
    for (int g = 0; g < gr->n; g++) {
        measure_t *ms = &jb->ms[gr->q[g]];
        ms->nearest[i] = sr[g].best, ms->which[i] = sr[g].bj;
        atomic_fetch_add(&ms->distances, sr[g].distances), atomic_fetch_add(&ms->aligned, sr[g].aligned);
        atomic_fetch_add(&ms->cut, sr[g].cut);
    }
}

static void truths(void *ctx, uint32_t worker)
{
    job_t *j = ctx;
    room_t rm = {0};
    int ok = 1;
    if (!j->exhaustive) {
        for (int q = 0; q < j->n; q++) {
            rm.lb[q] = malloc((size_t)MIM__BOUND_TRUTHS * j->k * sizeof *rm.lb[q]);
            rm.fa[q] = malloc((size_t)MIM__BOUND_TRUTHS * j->ms[q].dim * sizeof *rm.fa[q]);
            ok &= rm.lb[q] && rm.fa[q];
        }
        rm.cand = malloc((size_t)j->k * sizeof *rm.cand), rm.seen = calloc(j->k, 1);
        if (!ok || !rm.cand || !rm.seen) goto out; /* the others take this worker's share */
    }
    const uint32_t chunk = truth_chunk(j->m);
    for (uint32_t s; (s = atomic_fetch_add(&j->next, chunk)) < j->m;) {
        const uint32_t n = s + chunk < j->m ? chunk : j->m - s;
        for (int q = 0; q < j->n && !j->exhaustive; q++) {
            const measure_t *ms = &j->ms[q];
            for (uint32_t t = 0; t < n; t++) {
                rm.slack[q][t] = mim__bound_slack(ms->metric, &j->truth[s + t]) + ms->slack[0];
                mim__bound_features(ms->metric, &j->truth[s + t], 1, rm.fa[q] + (size_t)t * ms->dim);
            }
            mim__bound_lower(ms->metric, rm.fa[q], n, ms->feat, j->k, rm.slack[q], rm.lb[q]);
        }
        for (uint32_t i = s; i < s + n; i++) {
            for (int g = 0; g < j->groups; g++) {
                const group_t *gr = &j->group[g];
                uint32_t hint[2] = {UINT32_MAX, UINT32_MAX};
                for (int h = 0; h < gr->n && i > s; h++) hint[h] = j->ms[gr->q[h]].which[i - 1];
                nearest(j, &rm, gr, i, i - s, hint);
            }
            uint32_t done = atomic_fetch_add(&j->done, 1) + 1;
            if (worker == 0 && j->progress) mim_progress_update(j->progress, done);
        }
    }
out:
    for (int q = 0; q < MEASURES; q++) free(rm.lb[q]), free(rm.fa[q]);
    free(rm.cand), free(rm.seen);
}

int mim_sample_coverage_many(const mim_pair_prep_t *truth, uint32_t m, const mim_pair_prep_t *samples, uint32_t k,
                             const mim_sample_metric_t *metrics, uint32_t n, const mim_sample_coverage_options_t *opt,
                             mim_sample_coverage_t *out, mim_error_t *err)
{
    if (!truth || !samples || !out || !m || !k)
        return mim_error_set(err, MIM_EINVAL, "coverage: needs truth pose-pairs and samples (%u and %u given)", m, k);
    if (!metrics || n < 1 || n > MEASURES)
        return mim_error_set(err, MIM_EINVAL, "coverage: %u measures asked for (1 to 4)", metrics ? n : 0);
    for (uint32_t q = 0; q < n; q++) {
        if ((unsigned)metrics[q] > MIM_METRIC_LIMBS) return mim_error_set(err, MIM_EINVAL, "coverage: measure %d is none of the four", (int)metrics[q]);
        for (uint32_t r = 0; r < q; r++)
            if (metrics[r] == metrics[q]) return mim_error_set(err, MIM_EINVAL, "coverage: measure %d asked for twice", (int)metrics[q]);
    }
    for (uint32_t q = 0; q < n; q++) {
        const unsigned need_a = mim_sample_metric_parts(metrics[q], 0), need_b = mim_sample_metric_parts(metrics[q], 1);
        for (uint32_t i = 0; i < m + k; i++) {
            const int sample = i >= m;
            const mim_pair_prep_t *p = sample ? &samples[i - m] : &truth[i];
            if ((p->parts & (sample ? need_b : need_a)) != (sample ? need_b : need_a))
                return mim_error_set(err, MIM_EINVAL, "coverage: %s %u was prepared without the %s this distance reads",
                                     sample ? "sample" : "truth", (sample ? i - m : i) + 1,
                                     (sample ? need_b : need_a) & MIM_PREP_TRIANGULATION ? "triangulation" : "shape contexts");
        }
    }
    const mim_sample_coverage_options_t none = {0};
    if (!opt) opt = &none;
    const uint32_t threads = opt->threads ? opt->threads : 1;
    job_t j = {.truth = truth, .samples = samples, .m = m, .k = k, .n = (int)n, .exhaustive = opt->exhaustive,
               .progress = opt->progress};
    int rc = 0, aligned = 0, ic = -1, shape = -1;
    void *owned[2 * MEASURES] = {0}; /* the nearest and which arrays the caller did not give */
    for (int q = 0; q < j.n; q++) {
        measure_t *ms = &j.ms[q];
        ms->metric = metrics[q], ms->stride = mim__bound_stride(metrics[q]), ms->dim = mim__bound_dim(metrics[q]);
        ms->nearest = out[q].nearest ? out[q].nearest : (owned[2 * q] = malloc((size_t)m * sizeof *ms->nearest));
        ms->which = out[q].which ? out[q].which : (owned[2 * q + 1] = malloc((size_t)m * sizeof *ms->which));
        ms->slack = calloc(threads, sizeof *ms->slack);
        if (!j.exhaustive) ms->feat = malloc((size_t)k * ms->stride * sizeof *ms->feat);
        if (!ms->nearest || !ms->which || !ms->slack || (!j.exhaustive && !ms->feat)) rc = -1;
        atomic_init(&ms->distances, 0), atomic_init(&ms->aligned, 0), atomic_init(&ms->cut, 0);
        aligned |= aligned_metric(metrics[q]);
        if (metrics[q] == MIM_METRIC_IC) ic = q;
        if (metrics[q] == MIM_METRIC_SHAPE) shape = q;
    }
    /* D_I and D_S together, the others alone */
    if (ic >= 0 && shape >= 0) j.group[j.groups++] = (group_t){2, {ic, shape}};
    for (int q = 0; q < j.n; q++)
        if (!(ic >= 0 && shape >= 0 && (q == ic || q == shape))) j.group[j.groups++] = (group_t){1, {q, -1}};
    if (!j.exhaustive) {
        j.repeat = calloc(k, 1), j.hash = malloc((size_t)k * sizeof *j.hash);
        if (aligned) j.joints = malloc((size_t)k * 3 * N * sizeof *j.joints);
        if (!j.repeat || !j.hash || (aligned && !j.joints)) rc = -1;
    }
    if (rc) {
        rc = mim_error_set(err, MIM_ENOMEM, "coverage: out of memory for %u truths and %u samples", m, k);
        goto done;
    }
    if (!j.exhaustive) {
        atomic_init(&j.next, 0);
        mim__parallel(threads, features, &j);
        for (int q = 0; q < j.n; q++)
            for (uint32_t t = 1; t < threads; t++) j.ms[q].slack[0] = fmax(j.ms[q].slack[0], j.ms[q].slack[t]);
        if (find_repeats(&j)) {
            rc = mim_error_set(err, MIM_ENOMEM, "coverage: out of memory for %u samples", k);
            goto done;
        }
    }
    if (j.progress) mim_progress_begin(j.progress, "coverage", m);
    atomic_init(&j.next, 0), atomic_init(&j.done, 0);
    mim__parallel(threads, truths, &j);
    if (j.progress) mim_progress_end(j.progress);
    if (atomic_load(&j.done) < m) {
        rc = mim_error_set(err, MIM_ENOMEM, "coverage: out of memory for %u samples' bounds", k);
        goto done;
    }
    for (int q = 0; q < j.n; q++) {
        const measure_t *ms = &j.ms[q];
        double sum = 0;
        for (uint32_t i = 0; i < m; i++) sum += ms->nearest[i];
        out[q].coverage = sum / m;
        out[q].distances = atomic_load(&ms->distances), out[q].aligned = atomic_load(&ms->aligned);
        out[q].cut = atomic_load(&ms->cut);
    }
done:
    for (int q = 0; q < j.n; q++) free(j.ms[q].slack), free(j.ms[q].feat);
    for (int o = 0; o < 2 * MEASURES; o++) free(owned[o]);
    free(j.repeat), free(j.hash), free(j.joints);
    return rc;
}

int mim_sample_coverage(const mim_pair_prep_t *truth, uint32_t m, const mim_pair_prep_t *samples, uint32_t k,
                        mim_sample_metric_t metric, const mim_sample_coverage_options_t *opt, mim_sample_coverage_t *out,
                        mim_error_t *err)
{
    return mim_sample_coverage_many(truth, m, samples, k, &metric, 1, opt, out, err);
}
