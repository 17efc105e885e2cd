/* Dissimilarities between pose-pairs (seed 002): d_I of eq. 8 on
 * interaction coordinates, and the three measures of Section 6 (D_I, D_C,
 * D_S) after a least-squares rigid alignment. Choices: mim_sample.h. */
#include "internal.h"

#include <math.h>
#include <stdatomic.h>
#include <string.h>

static double edge_term(const double *a, const double *b, int dim, const uint8_t e[2], double beta, double *w)
{
    double ua2 = 0, d2 = 0;
    for (int c = 0; c < dim; c++) {
        double ua = a[dim * e[1] + c] - a[dim * e[0] + c], ub = b[dim * e[1] + c] - b[dim * e[0] + c];
        ua2 += ua * ua, d2 += (ua - ub) * (ua - ub);
    }
    double len = sqrt(ua2);
    *w = mim__ic_weight(len, beta);
    return *w * sqrt(d2);
}

/* One half of eq. 8: the edges of t, weighted by the lengths in `own`. */
static double half(const double *own, const double *other, int dim, const mim_ic_t *t, double beta)
{
    double sum = 0, wsum = 0, w;
    for (uint32_t k = 0; k < t->n_edges; k++) {
        sum += edge_term(own, other, dim, t->edge[k], beta, &w);
        wsum += w;
    }
    return wsum > 0 ? sum / wsum : 0.0;
}

double mim_ic_distance(const double *a, const mim_ic_t *ta, const double *b, const mim_ic_t *tb, double beta)
{
    if (!(beta > 0)) beta = MIM_IC_DEFAULT_BETA;
    return half(a, b, ta->dim, ta, beta) + half(b, a, tb->dim, tb, beta);
}

/* The rotation (column-major) that best turns the centred points b' onto
 * a', given S[x][y] = sum b'_x a'_y. 3D: Horn's closed form
 * (mim_quat_best_rotation), a rotation by construction (no reflection to
 * undo, as after an SVD). 2D: the angle that maximises sum a' . (R b'). */
static void best_rotation(const double S[3][3], int dim, double R[9])
{
    memset(R, 0, 9 * sizeof *R);
    if (dim == 2) {
        const double ang = atan2(S[0][1] - S[1][0], S[0][0] + S[1][1]), c = cos(ang), s = sin(ang);
        R[0] = c, R[1] = s, R[2] = -s, R[3] = c; /* column-major [c -s; s c] */
        return;
    }
    mim_quat_to_matrix(mim_quat_best_rotation(S), R);
}

/* Kabsch's problem: the rotation R (column-major dim x dim) and the
 * centroids ca, cb of the least-squares fit a ~ ca + R (b - cb) over n
 * points, each weighted by use[i] (NULL: all alike; 0: left out). */
static inline __attribute__((always_inline)) void fit_any(const double *a, const double *b, int n, int dim, const uint8_t *use,
                                                         double R[9], double ca[3], double cb[3])
{
    int used = 0;
    for (int i = 0; i < n; i++) used += use ? use[i] : 1;
    ca[0] = ca[1] = ca[2] = cb[0] = cb[1] = cb[2] = 0;
    for (int i = 0; i < n; i++) {
        const double w = use ? use[i] : 1;
        for (int c = 0; c < dim && w > 0; c++) ca[c] += w * a[dim * i + c], cb[c] += w * b[dim * i + c];
    }
    for (int c = 0; c < dim && used > 0; c++) ca[c] /= used, cb[c] /= used;
    double S[3][3] = {{0}};
    for (int i = 0; i < n; i++) {
        const double w = use ? use[i] : 1;
        if (w > 0)
            for (int r = 0; r < dim; r++)
                for (int c = 0; c < dim; c++) S[r][c] += w * (b[dim * i + r] - cb[r]) * (a[dim * i + c] - ca[c]);
    }
    best_rotation((const double(*)[3])S, dim, R);
}

/* The same, made apart for 3D points all alike (the limbs' fits): the
 * same operations in the same order, so the same bits. */
static void fit(const double *a, const double *b, int n, int dim, const uint8_t *use, double R[9], double ca[3],
                double cb[3])
{
    if (!use && dim == 3) fit_any(a, b, n, 3, NULL, R, ca, cb);
    else fit_any(a, b, n, dim, use, R, ca, cb);
}

void mim__align_points(const double *a, const double *b, int n, int dim, double *out)
{
    double R[9], ca[3], cb[3];
    fit(a, b, n, dim, NULL, R, ca, cb);
    for (int i = 0; i < n; i++)
        for (int r = 0; r < dim; r++) {
            double v = ca[r];
            for (int c = 0; c < dim; c++) v += R[dim * c + r] * (b[dim * i + c] - cb[c]);
            out[dim * i + r] = v;
        }
}

/* 3D through the two steps coverage takes (each pose-pair centred once),
 * so that the scan and coverage's bounds align by one piece of code. */
void mim_sample_align(const double *a, const double *b, int dim, double *out)
{
    if (dim != 3) {
        mim__align_points(a, b, MIM_PAIR_JOINTS, dim, out);
        return;
    }
    mim__centred_t ca, cb;
    mim__align_centre(a, &ca), mim__align_centre(b, &cb);
    mim__align_centred(&ca, cb.p, out);
}

void mim__align_centre(const double *p, mim__centred_t *out)
{
    double *c = out->c;
    c[0] = c[1] = c[2] = 0;
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int k = 0; k < 3; k++) c[k] += p[3 * i + k];
    for (int k = 0; k < 3; k++) c[k] /= MIM_PAIR_JOINTS;
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int k = 0; k < 3; k++) out->p[3 * i + k] = p[3 * i + k] - c[k];
}

void mim__align_centred(const mim__centred_t *a, const double *bc, double *out)
{
    double S[3][3] = {{0}}, R[9];
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) S[r][c] += bc[3 * i + r] * a->p[3 * i + c];
    best_rotation((const double(*)[3])S, 3, R);
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int r = 0; r < 3; r++) {
            double v = a->c[r];
            for (int c = 0; c < 3; c++) v += R[3 * c + r] * bc[3 * i + c];
            out[3 * i + r] = v;
        }
}

void mim_sample_rigid_fit(const double *a, const double *b, const uint8_t *use, double R[9], double t[3])
{
    double Rc[9], ca[3], cb[3];
    fit(a, b, MIM_PAIR_JOINTS, 3, use, Rc, ca, cb);
    for (int r = 0; r < 3; r++) {
        t[r] = ca[r];
        for (int c = 0; c < 3; c++) R[3 * r + c] = Rc[3 * c + r], t[r] -= Rc[3 * c + r] * cb[c];
    }
}

void mim__limb_joints(const double *p, int swap, double *out)
{
    for (int person = 0; person < 2; person++)
        memcpy(out + 3 * MIM_LIMB_COUNT * person,
               p + 3 * (MIM_PAIR_PERSON_JOINTS * (person ^ swap) + MIM_LIMB_FIRST), 3 * MIM_LIMB_COUNT * sizeof *out);
}

/* LIMBS: each order of b's people fitted over the 24 limb joints */
static double limbs_distance(const double *a, const double *b)
{
    enum { L = 2 * MIM_LIMB_COUNT };
    double la[3 * L], lb[3 * L], fitted[3 * L], best = INFINITY;
    mim__limb_joints(a, 0, la);
    for (int swap = 0; swap < 2; swap++) {
        mim__limb_joints(b, swap, lb);
        mim__align_points(la, lb, L, 3, fitted);
        double s = 0;
        for (int i = 0; i < L; i++) {
            double d2 = 0;
            for (int k = 0; k < 3; k++) d2 += (la[3 * i + k] - fitted[3 * i + k]) * (la[3 * i + k] - fitted[3 * i + k]);
            s += sqrt(d2);
        }
        best = fmin(best, s / L);
    }
    return best;
}

static int prepare_parts(const double *joints, unsigned parts, mim_pair_prep_t *out, mim_error_t *err)
{
    out->dim = 3, out->parts = parts;
    memcpy(out->joints, joints, sizeof out->joints);
    out->ic.n_edges = 0;
    const int rc = parts & MIM_PREP_TRIANGULATION ? mim_ic_build(joints, 3, &out->ic, err) : mim__joints_finite(joints, 3, err);
    if (!rc && (parts & MIM_PREP_SHAPE_CONTEXTS)) mim__shape_contexts(joints, out->sc);
    return rc;
}

int mim_pair_prepare(const double *joints, mim_pair_prep_t *out, mim_error_t *err)
{
    return prepare_parts(joints, MIM_PREP_ALL, out, err);
}

unsigned mim_sample_metric_parts(mim_sample_metric_t metric, int sample)
{
    return metric == MIM_METRIC_IC ? MIM_PREP_TRIANGULATION : metric == MIM_METRIC_SHAPE && !sample ? MIM_PREP_SHAPE_CONTEXTS : 0;
}

/* Many pose-pairs on threads: chunks taken in turn; the first failure
 * (the lowest index, whichever thread met it) is prepared again on the
 * calling thread for its message. A pose-pair the same as the one before
 * it in its chunk (a chain's refused step: a third of a sampler's output)
 * takes that one's parts: preparing is deterministic, so they are the
 * ones it would make. */
#define PREP_CHUNK 64
typedef struct prep_job {
    const double *joints;
    uint32_t n;
    unsigned parts;
    mim_pair_prep_t *out;
    _Atomic uint32_t next, first_bad;
} prep_job_t;

static void prep_work(void *ctx, uint32_t worker)
{
    (void)worker;
    prep_job_t *j = ctx;
    const size_t size = 3 * MIM_PAIR_JOINTS * sizeof *j->joints;
    for (uint32_t s; (s = atomic_fetch_add(&j->next, PREP_CHUNK)) < j->n;)
        for (uint32_t i = s; i < s + PREP_CHUNK && i < j->n; i++) {
            const double *p = j->joints + (size_t)i * 3 * MIM_PAIR_JOINTS;
            if (i > s && !memcmp(p, p - 3 * MIM_PAIR_JOINTS, size)) {
                const mim_pair_prep_t *from = &j->out[i - 1];
                mim_pair_prep_t *to = &j->out[i];
                to->dim = from->dim, to->parts = from->parts, to->ic = from->ic;
                memcpy(to->joints, from->joints, sizeof to->joints);
                if (from->parts & MIM_PREP_SHAPE_CONTEXTS) memcpy(to->sc, from->sc, sizeof to->sc);
                continue;
            }
            if (prepare_parts(p, j->parts, &j->out[i], NULL)) {
                uint32_t was = atomic_load(&j->first_bad);
                while (i < was && !atomic_compare_exchange_weak(&j->first_bad, &was, i)) {}
                break;
            }
        }
}

int mim_pair_prepare_many(const double *joints, uint32_t n, uint32_t threads, unsigned parts, mim_pair_prep_t *out,
                          uint32_t *failed, mim_error_t *err)
{
    prep_job_t j = {.joints = joints, .n = n, .parts = parts & MIM_PREP_ALL, .out = out};
    atomic_init(&j.next, 0), atomic_init(&j.first_bad, n);
    mim__parallel(threads, prep_work, &j);
    uint32_t bad = atomic_load(&j.first_bad);
    if (bad == n) return 0;
    if (failed) *failed = bad;
    return prepare_parts(joints + (size_t)bad * 3 * MIM_PAIR_JOINTS, j.parts, &out[bad], err);
}

double mim_sample_distance(const mim_pair_prep_t *a, const mim_pair_prep_t *b, mim_sample_metric_t metric)
{
    /* a part the metric reads was not made: no answer rather than a wrong one */
    const unsigned need_a = mim_sample_metric_parts(metric, 0), need_b = mim_sample_metric_parts(metric, 1);
    if ((a->parts & need_a) != need_a || (b->parts & need_b) != need_b) return NAN;
    if (metric == MIM_METRIC_LIMBS) return limbs_distance(a->joints, b->joints);
    double bb[3 * MIM_PAIR_JOINTS];
    mim_sample_align(a->joints, b->joints, 3, bb);
    if (metric == MIM_METRIC_CARTESIAN) {
        double s = 0;
        for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) s += (a->joints[i] - bb[i]) * (a->joints[i] - bb[i]);
        return sqrt(s / MIM_PAIR_JOINTS);
    }
    if (metric == MIM_METRIC_SHAPE) {
        float sb[MIM_PAIR_JOINTS][MIM_SC_BINS];
        mim__shape_contexts(bb, sb);
        return mim__shape_cost(&a->sc[0][0], &sb[0][0], MIM_PAIR_JOINTS, MIM_SC_BINS);
    }
    /* D_I: eq. 8 with each pair's own triangulation (a rigid motion keeps
     * a Delaunay triangulation, so b's still holds for bb) */
    return mim_ic_distance(a->joints, &a->ic, bb, &b->ic, MIM_IC_DEFAULT_BETA);
}
