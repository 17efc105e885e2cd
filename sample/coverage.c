/* Coverage of a set of pose-pairs by samples (seed 002, Section 6, eq.
 * 13): C(G, S) = 1/m sum_i D(g_i, s_i*), s_i* the sample nearest to g_i. */
#include "mim_sample.h"

#include <math.h>

int mim_sample_coverage(const mim_pair_prep_t *truth, uint32_t m, const mim_pair_prep_t *samples, uint32_t k,
                        mim_sample_metric_t metric, mim_progress_t *progress, double *out, mim_error_t *err)
{
    if (!truth || !samples || !out || !m || !k)
        return mim_error_set(err, MIM_EINVAL, "coverage: needs truth pose-pairs and samples (%u and %u given)", m, k);
    if (progress) mim_progress_begin(progress, "coverage", m);
    double sum = 0;
    for (uint32_t i = 0; i < m; i++) {
        double best = INFINITY;
        for (uint32_t j = 0; j < k; j++) {
            double d = mim_sample_distance(&truth[i], &samples[j], metric);
            if (d < best) best = d;
        }
        sum += best;
        if (progress) mim_progress_update(progress, i + 1);
    }
    if (progress) mim_progress_end(progress);
    *out = sum / m;
    return 0;
}
