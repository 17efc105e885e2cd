/* Pose-pair completion (seed 002's Fig. 12): the joints of a pose-pair that
 * were not seen (the far person's arm behind the near one) filled in from
 * samples of the interaction.
 *
 * Matching: each sample is fitted rigidly onto the seen joints (Kabsch over
 * them, the other person's joints at a quarter of the weight of the
 * missing joint's own person's: the other person places the arm, but its
 * own body says most about how the person stands); its residual (weighted
 * RMS over the seen joints) ranks it, and the k best are kept. With match PERSON only the joints seen on the missing joint's
 * own person count (single-person completion, the baseline): the other
 * person then says nothing about where the arm goes.
 *
 * Filling, in interaction coordinates (Section 4.3's idea: a joint is
 * placed by its offsets from the joints around it, not by one global
 * fit): in each kept sample, missing joint j has an offset from every
 * matched joint i, turned by that sample's fit; j is put where those
 * offsets from the seen joints' true places agree, each weighted by eq.
 * 8's 1 / |offset|^2 (so the joints near j, of either person, decide), and
 * the k samples' answers are averaged with weights 1 / (residual + eps). */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define N MIM_PAIR_JOINTS
#define EPS_M 0.01 /* metres: a residual this small counts as this, so one exact match does not stand alone */
#define NEAR_M 0.05 /* metres added to an offset's length before its weight: a joint on top of j is not infinitely sure */
#define OWN_WEIGHT 4 /* in the fit, a joint of the missing joint's own person */
#define OTHER_WEIGHT 1 /* ... and one of the other person (bench/pairs_complete.sh: 1, 2, 4 tried) */

typedef struct kept {
    double res;
    uint32_t i;
    double R[9], t[3];
} kept_t;

static void keep(kept_t *list, uint32_t *len, uint32_t k, const kept_t *x)
{
    if (*len == k && !(x->res < list[k - 1].res)) return;
    uint32_t at = *len < k ? (*len)++ : k - 1;
    while (at > 0 && x->res < list[at - 1].res) list[at] = list[at - 1], at--;
    list[at] = *x;
}

int mim_pairs_complete(const double *samples, uint32_t n, const double *pair, const uint8_t *missing,
                       const mim_pairs_complete_options_t *o, double *out)
{
    const uint32_t k = o && o->k ? o->k : MIM_PAIRS_COMPLETE_DEFAULT_K;
    if (!samples || !n || !pair || !missing || !out || k > MIM_PAIRS_COMPLETE_MAX_K) return MIM_EINVAL;
    memcpy(out, pair, sizeof(double) * 3 * N);
    int persons_missing[2] = {0, 0}, any = 0;
    for (int j = 0; j < N; j++)
        if (missing[j]) persons_missing[j >= MIM_PAIR_PERSON_JOINTS]++, any = 1;
    if (!any) return 0;
    /* each person's missing joints are matched on their own set (the same
     * set for both persons when matching on the pair) */
    for (int p = 0; p < 2; p++) {
        if (!persons_missing[p]) continue;
        uint8_t use[N];
        int used = 0, wsum_fit = 0;
        for (int i = 0; i < N; i++) {
            const int own = (i >= MIM_PAIR_PERSON_JOINTS) == p;
            use[i] = !missing[i] && (!(o && o->person_only) || own) ? (own ? OWN_WEIGHT : OTHER_WEIGHT) : 0;
            for (int c = 0; c < 3 && use[i]; c++)
                if (!isfinite(pair[3 * i + c])) return MIM_ENONFINITE;
            used += use[i] > 0, wsum_fit += use[i];
        }
        if (used < 3) return MIM_EEMPTY;
        kept_t list[MIM_PAIRS_COMPLETE_MAX_K];
        uint32_t len = 0;
        for (uint32_t s = 0; s < n; s++) {
            const double *b = samples + (size_t)s * 3 * N;
            kept_t x = {0, s, {0}, {0}};
            mim_sample_rigid_fit(pair, b, use, x.R, x.t);
            for (int i = 0; i < N; i++)
                if (use[i])
                    for (int r = 0; r < 3; r++) {
                        double v = x.t[r] - pair[3 * i + r];
                        for (int c = 0; c < 3; c++) v += x.R[3 * r + c] * b[3 * i + c];
                        x.res += use[i] * v * v;
                    }
            x.res = sqrt(x.res / wsum_fit);
            if (isfinite(x.res)) keep(list, &len, k, &x);
        }
        if (!len) return MIM_ENOTFOUND;
        for (int j = p * MIM_PAIR_PERSON_JOINTS; j < (p + 1) * MIM_PAIR_PERSON_JOINTS; j++) {
            if (!missing[j]) continue;
            double sum[3] = {0, 0, 0}, wsum = 0;
            for (uint32_t c = 0; c < len; c++) {
                const double *b = samples + (size_t)list[c].i * 3 * N;
                double at[3] = {0, 0, 0}, w_in = 0;
                for (int i = 0; i < N; i++) {
                    if (!use[i]) continue;
                    double off[3], d2 = 0;
                    for (int r = 0; r < 3; r++) {
                        off[r] = 0;
                        for (int q = 0; q < 3; q++) off[r] += list[c].R[3 * r + q] * (b[3 * j + q] - b[3 * i + q]);
                        d2 += off[r] * off[r];
                    }
                    const double w = 1.0 / (d2 + NEAR_M * NEAR_M); /* eq. 8's weight, kept finite */
                    for (int r = 0; r < 3; r++) at[r] += w * (pair[3 * i + r] + off[r]);
                    w_in += w;
                }
                const double w = 1.0 / (list[c].res + EPS_M);
                for (int r = 0; r < 3; r++) sum[r] += w * at[r] / w_in;
                wsum += w;
            }
            for (int r = 0; r < 3; r++) out[3 * j + r] = sum[r] / wsum;
        }
    }
    return 0;
}
