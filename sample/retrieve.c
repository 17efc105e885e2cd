/* Retrieval (seed 002's Fig. 2: a 3D pose-pair for each 2D annotation):
 * the sample whose projection matches the annotation best over views.
 * A view is a direction the camera looks along, in the samples' frame (y
 * up); the match is eq. 9's in 2D (pairs2d.c): both point sets centred and
 * scaled to unit RMS radius, the annotation turned onto the projection by
 * the in-plane rotation of least squares, the mean squared distance per
 * joint left. The projection is orthographic, as the likelihood's.
 *
 * The search, per annotation: every sample through a coarse ring of views
 * (every 30 degrees of azimuth at 15 degrees below, 10 and 35 above the
 * horizon: where pairs annotate's cameras and most photographers stand),
 * then the SHORTLIST best samples refined by a pattern search over azimuth
 * and elevation (15 degrees halved to under 1, elevation within -60..80).
 * A sample whose best view falls between the coarse ones can be missed
 * when its coarse residual is not among the shortlist's. */
#include "internal.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define N MIM_PAIR_JOINTS
#define AZ_STEPS 12
#define SHORTLIST 32
#define DEG (M_PI / 180.0)
static const double coarse_el[] = {-15 * DEG, 10 * DEG, 35 * DEG};
#define EL_STEPS ((int)(sizeof coarse_el / sizeof *coarse_el))

/* The direction a camera at azimuth az and elevation el (seen from the
 * pair) looks along: towards the pair. */
static void view_dir(double az, double el, double d[3])
{
    d[0] = -cos(el) * sin(az), d[1] = -sin(el), d[2] = -cos(el) * cos(az);
}

/* Residual of joints seen along (az, el) against the normalised annotation a. */
static double match(const double *joints, double az, double el, const double *a)
{
    double d[3], uv[2 * N], q[2 * N], c, s;
    view_dir(az, el, d);
    mim_pairs2d_project(joints, d, uv);
    if (!mim_pairs2d_normalise(uv, q)) return INFINITY;
    return mim_pairs2d_align(q, a, &c, &s);
}

typedef struct cand {
    double res, az, el;
    uint32_t i;
} cand_t;

/* Keeps the k lowest residuals in list (sorted), len of them so far. */
static void keep(cand_t *list, int *len, int k, cand_t x)
{
    if (*len == k && !(x.res < list[k - 1].res)) return;
    int at = *len < k ? (*len)++ : k - 1;
    while (at > 0 && x.res < list[at - 1].res) list[at] = list[at - 1], at--;
    list[at] = x;
}

/* A pattern search from c: the best of (az +- h, el +- h) while it improves,
 * then h halved. */
static void refine(const double *joints, const double *a, cand_t *c)
{
    for (double h = 15 * DEG; h > 0.9 * DEG; h /= 2)
        for (int moved = 1; moved;) {
            moved = 0;
            static const int step[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
            for (int k = 0; k < 4; k++) {
                double az = c->az + step[k][0] * h, el = c->el + step[k][1] * h;
                if (el < -60 * DEG || el > 80 * DEG) continue;
                double r = match(joints, az, el, a);
                if (r < c->res) c->res = r, c->az = az, c->el = el, moved = 1;
            }
        }
}

int mim_pairs_retrieve(const double *samples, uint32_t n, const double *uv, mim_pairs_match_t *out)
{
    out->sample = UINT32_MAX, out->residual = INFINITY;
    memset(out->dir, 0, sizeof out->dir);
    double a[2 * N];
    if (!samples || !n || !uv || !mim_pairs2d_normalise(uv, a)) return MIM_EINVAL;
    cand_t list[SHORTLIST];
    int len = 0;
    for (uint32_t i = 0; i < n; i++) {
        const double *p = samples + (size_t)i * 3 * N;
        cand_t best = {INFINITY, 0, 0, i};
        for (int e = 0; e < EL_STEPS; e++)
            for (int k = 0; k < AZ_STEPS; k++) {
                double az = 2 * M_PI * k / AZ_STEPS, r = match(p, az, coarse_el[e], a);
                if (r < best.res) best.res = r, best.az = az, best.el = coarse_el[e];
            }
        if (isfinite(best.res)) keep(list, &len, SHORTLIST, best);
    }
    if (!len) return MIM_ENOTFOUND;
    for (int c = 0; c < len; c++) refine(samples + (size_t)list[c].i * 3 * N, a, &list[c]);
    int b = 0; /* the lowest residual, the lowest index among equals */
    for (int c = 1; c < len; c++)
        if (list[c].res < list[b].res || (list[c].res == list[b].res && list[c].i < list[b].i)) b = c;
    out->sample = list[b].i, out->residual = list[b].res;
    view_dir(list[b].az, list[b].el, out->dir);
    return 0;
}

typedef struct job {
    const double *samples;
    uint32_t n;
    const mim_pairs_annotations_t *ann;
    mim_pairs_match_t *out;
    mim_progress_t *progress;
    _Atomic uint32_t next, done;
} job_t;

static void work(void *ctx, uint32_t worker)
{
    job_t *j = ctx;
    for (uint32_t i; (i = atomic_fetch_add(&j->next, 1)) < j->ann->n;) {
        mim_pairs_retrieve(j->samples, j->n, j->ann->points + (size_t)i * 2 * N, &j->out[i]);
        uint32_t done = atomic_fetch_add(&j->done, 1) + 1;
        if (worker == 0 && j->progress) mim_progress_update(j->progress, done);
    }
}

void mim_pairs_retrieve_many(const double *samples, uint32_t n, const mim_pairs_annotations_t *ann, uint32_t threads,
                             mim_progress_t *progress, mim_pairs_match_t *out)
{
    job_t j = {.samples = samples, .n = n, .ann = ann, .out = out, .progress = progress};
    if (progress) mim_progress_begin(progress, "retrieve", ann->n);
    mim__parallel(threads, work, &j);
    if (progress) mim_progress_end(progress);
}
