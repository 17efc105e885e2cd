/* Metropolis-Hastings as seed 002 runs it (Section 5): eq. 10's acceptance
 * with the velocity-biased proposal's asymmetry (eq. 12: the variances
 * depend on the state, so Q(x|x') != Q(x'|x)), on the density truncated by
 * eq. 11 around the seed's f0. Generic over the state (mim_mh_ops_t), so
 * that the same code samples pose-pairs and the tests' toy densities. */
#include "mim_sample_mcmc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* eq. 11 in logs: 0 density below f0 / c, flat above c f0. */
static double truncate11(double log_f, double log_f0, double log_c)
{
    if (!(log_c > 0) || isinf(log_c)) return log_f;
    if (log_f < log_f0 - log_c) return -INFINITY;
    return fmin(log_f, log_f0 + log_c);
}

/* log Q of a move eps under variances sig2 (groups of width; a group of
 * variance 0 does not move and adds nothing). */
static double log_q(const double *eps, const double *sig2, uint32_t groups, uint32_t width)
{
    double s = 0;
    for (uint32_t g = 0; g < groups; g++) {
        if (!(sig2[g] > 0)) continue;
        double e2 = 0;
        for (uint32_t k = 0; k < width; k++) e2 += eps[g * width + k] * eps[g * width + k];
        s += -e2 / (2 * sig2[g]) - 0.5 * width * log(sig2[g]);
    }
    return s;
}

int mim_mh_run(const mim_mh_ops_t *ops, void *ctx, const void *seed, double c, mim_rng_t *rng, uint32_t n,
               mim_mh_stats_t *stats, _Atomic uint64_t *done, mim_error_t *err)
{
    memset(stats, 0, sizeof *stats);
    size_t g = ops->groups, w = ops->width;
    unsigned char *cur = malloc(ops->state_size), *next = malloc(ops->state_size);
    double *sig2 = malloc(2 * g * sizeof *sig2), *eps = malloc(g * w * sizeof *eps);
    if (!cur || !next || !sig2 || !eps) {
        free(cur), free(next), free(sig2), free(eps);
        return mim_error_set(err, MIM_ENOMEM, "sampler: out of memory");
    }
    double *sig2_next = sig2 + g;
    const double log_c = c > 1 && isfinite(c) ? log(c) : 0.0;
    memcpy(cur, seed, ops->state_size);
    double log_f = ops->evaluate(ctx, cur, -INFINITY, sig2);
    stats->seed_log_density = log_f;
    if (!isfinite(log_f)) {
        free(cur), free(next), free(sig2), free(eps);
        return mim_error_set(err, MIM_EINVAL, "sampler: the seed has density 0 (an invalid pose, or no match)");
    }
    const double log_f0 = log_f, floor = log_c > 0 ? log_f0 - log_c : -INFINITY;
    double cur_t = truncate11(log_f, log_f0, log_c);
    for (uint32_t i = 0; i < n; i++) {
        for (size_t k = 0; k < g * w; k++) eps[k] = sig2[k / w] > 0 ? sqrt(sig2[k / w]) * mim_rng_gauss(rng) : 0.0;
        ops->move(ctx, cur, eps, next);
        double lf = ops->evaluate(ctx, next, floor, sig2_next), lt = truncate11(lf, log_f0, log_c);
        double u = mim_rng_unit(rng); /* drawn on every step: the stream does not depend on the outcome */
        if (lt == -INFINITY) {
            stats->zero++;
        } else {
            /* eq. 10: the reverse move is -eps, under the variances at next */
            double log_a = lt - cur_t + log_q(eps, sig2_next, ops->groups, ops->width) - log_q(eps, sig2, ops->groups, ops->width);
            if (log(u) < log_a) {
                unsigned char *t = cur;
                cur = next, next = t;
                memcpy(sig2, sig2_next, g * sizeof *sig2);
                log_f = lf, cur_t = lt;
                stats->accepted++;
            }
        }
        stats->steps++;
        ops->emit(ctx, i, cur, log_f);
        if (done) atomic_fetch_add_explicit(done, 1, memory_order_relaxed);
    }
    free(cur), free(next), free(sig2), free(eps);
    return 0;
}
