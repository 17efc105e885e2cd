/* The transfer iteration (seed 000, Section 3.4, "Final Algorithm"):
 *   1) F* = F_T (the template's frames);
 *   2) solve equation (3) (or its least-squares form, solver.c) for X*,
 *      three right-hand sides F*(v_i) W_i plus the constraint terms;
 *   3) recompute F* from X* (frames.c);
 *   4) stop when the largest vertex move falls below tol, or at the cap
 *      (the paper's "both X* and F* do not change much"; by default tol
 *      is relative, a fraction of the targets' extent, so that a body in
 *      millimetres or in metres settles alike).
 * mimic adds two things, because the iteration does not converge to a
 * tight tolerance (it improves for 2-3 iterations, then oscillates):
 * damping (each new X moves only a fraction of the way from the last one)
 * and an early stop when the largest move stops shrinking fast (move_k >
 * stop_ratio * move_{k-1}, default 0.5), i.e. the iteration has started to
 * drift or oscillate; it then returns the mean of the last two iterates,
 * the middle of an oscillation. A warm start (opt->start, a previous
 * solution) enters as iterate 0: the first solve still uses F_T, but its
 * step is damped from the warm start and the move tests count it as one
 * more iterate, so it stops about one solve sooner. (Taking the warm
 * start's own frames for the first solve instead was worse: the template
 * then no longer guides the pose and the error grew 35-50 % over a stream;
 * bench/warm_start.c.) Nothing is allocated here: all
 * workspaces live in the solver. */
#include "internal.h"

#include <math.h>
#include <string.h>

/* Vertex i's Laplacian offset F_i W_i, or D_i when the offsets are given
 * (the first solve of mim_xfer_transfer_offsets, and every later solve:
 * mim__xfer_offsets_ws makes them from the last iterate). */
static inline void offset(const double *W, const double *F, const double *D, uint32_t i, double r[3])
{
    if (D) {
        const double *d = D + 3 * (size_t)i;
        r[0] = d[0], r[1] = d[1], r[2] = d[2];
        return;
    }
    const double *f = F + 9 * (size_t)i, *w = W + 3 * (size_t)i;
    r[0] = f[0] * w[0] + f[3] * w[1] + f[6] * w[2];
    r[1] = f[1] * w[0] + f[4] * w[1] + f[7] * w[2];
    r[2] = f[2] * w[0] + f[5] * w[1] + f[8] * w[2];
}

static void build_rhs(mim_xfer_solver_t *s, const double *W, const double *F, const double *D, const float *u)
{
    const mim_xfer_topology_t *t = s->topo;
    const uint32_t nf = s->nf;
    double *B = s->B->x;
    if (s->formulation == MIM_XFER_SQUARE || s->low_rank) {
        /* F*W row by row: free rows into B, constrained rows (least
         * squares) into rc; then the constraint terms -L_:c U */
        double *restrict B0 = B, *restrict B1 = B + nf, *restrict B2 = B + 2 * (size_t)nf;
        for (uint32_t i = 0; i < s->n; i++) {
            double r[3];
            offset(W, F, D, i, r);
            int32_t q = s->slot[i];
            if (q >= 0) {
                B0[q] = r[0], B1[q] = r[1], B2[q] = r[2];
            } else if (s->low_rank) {
                double *rc = s->rc + 3 * (size_t)(-1 - q);
                rc[0] = r[0], rc[1] = r[1], rc[2] = r[2];
            }
        }
        for (uint32_t e = 0; e < s->n_cterm; e++) {
            const struct mim__xfer_cterm *ct = &s->cterm[e];
            const float *uu = u + 3 * (size_t)ct->con;
            if (ct->row >= 0) {
                B0[ct->row] += ct->coef * uu[0];
                B1[ct->row] += ct->coef * uu[1];
                B2[ct->row] += ct->coef * uu[2];
            } else {
                double *rc = s->rc + 3 * (size_t)(-1 - ct->row);
                rc[0] += ct->coef * uu[0], rc[1] += ct->coef * uu[1], rc[2] += ct->coef * uu[2];
            }
        }
        return;
    }
    /* least squares on the normal factor: r as above, then B = (L r)_f */
    double *r = s->r;
    for (uint32_t i = 0; i < s->n; i++) {
        double *ri = r + 3 * (size_t)i;
        offset(W, F, D, i, ri);
        int32_t qi = s->slot[i];
        if (qi < 0) {
            const float *uu = u + 3 * (size_t)(-1 - qi);
            double d = (double)(t->adj_start[i + 1] - t->adj_start[i]);
            ri[0] -= d * uu[0], ri[1] -= d * uu[1], ri[2] -= d * uu[2];
        }
        for (uint32_t k = t->adj_start[i]; k < t->adj_start[i + 1]; k++) {
            int32_t q = s->slot[t->adj[k]];
            if (q < 0) {
                const float *uu = u + 3 * (size_t)(-1 - q);
                ri[0] += uu[0], ri[1] += uu[1], ri[2] += uu[2];
            }
        }
    }
    for (uint32_t j = 0; j < nf; j++) {
        uint32_t v = s->free_v[j];
        double d = (double)(t->adj_start[v + 1] - t->adj_start[v]);
        const double *rv = r + 3 * (size_t)v;
        double b0 = d * rv[0], b1 = d * rv[1], b2 = d * rv[2];
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++) {
            const double *ru = r + 3 * (size_t)t->adj[k];
            b0 -= ru[0], b1 -= ru[1], b2 -= ru[2];
        }
        B[j] = b0;
        B[nf + j] = b1;
        B[2 * (size_t)nf + j] = b2;
    }
}

/* The diagonal of the bounding box of n >= 1 points (3 * n floats). */
static double extent(const float *p, uint32_t n)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, d2 = 0.0;
    for (uint32_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            lo[c] = fmin(lo[c], p[3 * (size_t)i + c]), hi[c] = fmax(hi[c], p[3 * (size_t)i + c]);
    for (int c = 0; c < 3; c++)
        d2 += (hi[c] - lo[c]) * (hi[c] - lo[c]);
    return sqrt(d2);
}

static double mean_error(const double *pos, const float *truth, uint32_t n)
{
    double sum = 0.0;
    for (uint32_t i = 0; i < n; i++) {
        double dx = pos[3 * (size_t)i] - truth[3 * (size_t)i];
        double dy = pos[3 * (size_t)i + 1] - truth[3 * (size_t)i + 1];
        double dz = pos[3 * (size_t)i + 2] - truth[3 * (size_t)i + 2];
        sum += sqrt(dx * dx + dy * dy + dz * dz);
    }
    return sum / n;
}

/* The iteration from frames F0 or, when given, offsets D0. */
static int iterate(mim_xfer_solver_t *s, const double *W, uint32_t n_vertices, const double *F0, const double *D0,
                   const float *targets, uint32_t n_targets, const mim_xfer_options_t *opt, float *out,
                   mim_xfer_report_t *report, mim_error_t *err)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!s || !W || !(F0 || D0) || !targets || !out)
        return mim_error_set(err, MIM_EINVAL, "transfer: NULL solver, encoding, frames (or offsets), targets or output");
    if (n_vertices != s->n)
        return mim_error_set(err, MIM_ETOPOLOGY, "transfer: mesh has %u vertices, the connectivity %u",
                             n_vertices, s->n);
    if (n_targets != s->nc)
        return mim_error_set(err, MIM_EINVAL, "transfer: %u landmark positions given, %u expected",
                             n_targets, s->nc);
    mim_xfer_options_t o = {0};
    if (opt)
        o = *opt;
    uint32_t maxit = o.max_iterations ? o.max_iterations : MIM_XFER_DEFAULT_MAX_ITERATIONS;
    double tol = o.tol != 0.0 ? o.tol : MIM_XFER_DEFAULT_TOL;
    const double settle = o.settle != 0.0 ? o.settle : MIM_XFER_DEFAULT_SETTLE;
    double alpha = o.damping != 0.0 ? o.damping : MIM_XFER_DEFAULT_DAMPING;
    double ratio = o.stop_ratio != 0.0 ? o.stop_ratio : MIM_XFER_DEFAULT_STOP_RATIO;
    if (!(ratio > 0.0))
        return mim_error_set(err, MIM_EINVAL, "transfer: stop ratio %g not positive", ratio);
    if (!(alpha > 0.0 && alpha <= 1.0))
        return mim_error_set(err, MIM_EINVAL, "transfer: damping %g outside (0, 1]", alpha);
    if (isnan(tol) || isnan(settle))
        return mim_error_set(err, MIM_EINVAL, "transfer: tolerance is NaN");
    if (o.error_by_iteration && !o.truth)
        return mim_error_set(err, MIM_EINVAL, "transfer: error_by_iteration needs truth");
    for (uint32_t c = 0; c < s->nc; c++)
        for (int k = 0; k < 3; k++)
            if (!isfinite(targets[3 * (size_t)c + k]))
                return mim_error_set(err, MIM_ENONFINITE,
                                     "transfer: landmark %u (vertex %u) has a non-finite coordinate %c",
                                     c, s->cons[c], "xyz"[k]);
    for (size_t i = 0; i < 3 * (size_t)s->n; i++)
        if (!isfinite(W[i]))
            return mim_error_set(err, MIM_ENONFINITE, "transfer: encoding of vertex %zu is not finite", i / 3);
    if (o.tol == 0.0 && settle > 0.0) /* the default: relative to the body (the targets' extent) */
        tol = fmax(tol, settle * extent(targets, s->nc));

    const uint32_t n = s->n, nf = s->nf;
    double *pos = s->pos, *prev = s->prev;
    const double *F = F0, *D = D0;
    double last_prev_move = INFINITY, move = INFINITY;
    uint32_t it = 0, warm = 0;
    int converged = 0, early = 0;
    if (o.start) {
        for (size_t i = 0; i < 3 * (size_t)n; i++) {
            if (!isfinite(o.start[i]))
                return mim_error_set(err, MIM_ENONFINITE, "transfer: warm start of vertex %zu is not finite", i / 3);
            prev[i] = o.start[i];
        }
        warm = 1;
    }
    while (it < maxit) {
        build_rhs(s, W, F, D, targets);
        int rc = mim__xfer_solve(s, err);
        if (rc)
            return rc;
        it++;
        const uint32_t k = it + warm; /* iterates so far, counting a warm start */
        const double *X = s->X->x;
        double mv = 0.0;
        for (uint32_t j = 0; j < nf; j++) {
            double *p = pos + 3 * (size_t)s->free_v[j];
            const double *q = prev + 3 * (size_t)s->free_v[j];
            double m2 = 0.0;
            for (int c = 0; c < 3; c++) {
                double x = X[(size_t)c * nf + j];
                if (k > 1) {
                    x = q[c] + alpha * (x - q[c]);
                    m2 += (x - q[c]) * (x - q[c]);
                }
                p[c] = x;
            }
            if (m2 > mv)
                mv = m2;
        }
        for (uint32_t c = 0; c < s->nc; c++)
            for (int k = 0; k < 3; k++)
                pos[3 * (size_t)s->cons[c] + k] = targets[3 * (size_t)c + k];
        last_prev_move = move;
        move = k > 1 ? sqrt(mv) : INFINITY;
        if (k > 2 && !o.no_early_stop && move > ratio * last_prev_move) {
            /* oscillation: return the middle of the last two iterates */
            for (size_t i = 0; i < 3 * (size_t)n; i++)
                pos[i] = 0.5 * (pos[i] + prev[i]);
            early = 1;
        }
        if (o.error_by_iteration)
            o.error_by_iteration[it - 1] = mean_error(pos, o.truth, n);
        if (early)
            break;
        if (move < tol) {
            converged = 1;
            break;
        }
        /* swap so prev holds this iterate */
        double *tmp = pos;
        pos = prev;
        prev = tmp;
        if (it < maxit) {
            mim__xfer_offsets_ws(s->topo, prev, W, s->D, s->fn);
            F = NULL, D = s->D;
        }
    }
    /* the result is in pos unless the loop ended by the cap after a swap */
    const double *res = (converged || early) ? pos : prev;
    for (size_t i = 0; i < 3 * (size_t)n; i++)
        out[i] = (float)res[i];
    if (report) {
        report->iterations = it;
        report->last_move = move;
        report->converged = converged;
        report->early_stopped = early;
    }
    return 0;
}

int mim_xfer_transfer(mim_xfer_solver_t *s, const double *W, uint32_t n_vertices, const double *frames0,
                      const float *targets, uint32_t n_targets, const mim_xfer_options_t *opt, float *out,
                      mim_xfer_report_t *report, mim_error_t *err)
{
    return iterate(s, W, n_vertices, frames0, NULL, targets, n_targets, opt, out, report, err);
}

int mim_xfer_transfer_offsets(mim_xfer_solver_t *s, const double *W, uint32_t n_vertices, const double *offsets0,
                              const float *targets, uint32_t n_targets, const mim_xfer_options_t *opt, float *out,
                              mim_xfer_report_t *report, mim_error_t *err)
{
    return iterate(s, W, n_vertices, NULL, offsets0, targets, n_targets, opt, out, report, err);
}
