/* Answering a frame with the recognition index (seed 000, Section 3.3;
 * model.c builds it): the class (linear discriminants for a whole frame,
 * lda.c; else the SVMs, and a k-NN vote when they are unsure), then the k
 * nearest templates inside the class (FLANN, or an exact scan over the
 * available angles when landmarks are missing). */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { SCAN_PER_CLASS = 256 };
typedef struct {
    float d2;
    uint32_t row;
} cand_t;

/* Keeps the k smallest in a sorted array (insertion). */
static void keep(cand_t *best, uint32_t *nb, uint32_t k, float d2, uint32_t row)
{
    if (*nb == k && d2 >= best[k - 1].d2) return;
    uint32_t i = *nb < k ? (*nb)++ : k - 1;
    while (i > 0 && best[i - 1].d2 > d2) {
        best[i] = best[i - 1];
        i--;
    }
    best[i] = (cand_t){d2, row};
}

static int query_desc(const mim_index_t *ix, const float *positions, const float *angled, const uint8_t *present,
                      const mim_index_query_options_t *opt, uint32_t k, float *q, double *xd, uint8_t *mask,
                      float *w, mim_index_answer_t *ans, mim_index_hit_t *hits, cand_t *best_st, int *ind_st,
                      float *dist_st, mim_error_t *err);

/* In place, the chunk of rows that holds row r is verified before r is
 * read (blob.c); *last remembers the chunk checked last, so a scan checks
 * each chunk once. */
static inline int row_ready(const mim_index_t *ix, uint32_t r, int extra, uint32_t *last, mim_error_t *err)
{
    if (!ix->lazy) return 0;
    uint32_t j = r / ix->lazy->rows;
    if (j == *last) return 0;
    *last = j;
    return mim__rows_ready(ix, r, r + 1, extra, err);
}

/* Squared distance over the angles with mask[f] set: the first d from desc,
 * the next de from extra. */
static float masked_d2(const float *desc, const float *extra, const float *q, const float *w, uint32_t d,
                       uint32_t de)
{
    float s = 0, t = 0; /* weights 0/1 rather than branches: the loops vectorise */
    for (uint32_t f = 0; f < d; f++) s += w[f] * (q[f] - desc[f]) * (q[f] - desc[f]);
    for (uint32_t f = 0; f < de; f++) t += w[d + f] * (q[d + f] - extra[f]) * (q[d + f] - extra[f]);
    return s + t;
}

/* The k-NN vote (issue 15): among the vote_classes classes of highest SVM
 * probability pr, the vote_k nearest templates (the subject left out
 * excluded), by the squared distance over the descriptor's angles (all
 * available kept angles when landmarks are missing) with the index's angle
 * weights; the class with the largest pr * (votes + 1) wins (a vote counts
 * 1 + 0.001 x its rank from the last, so that ties go to the nearer
 * templates). Each class is scanned, a class of more than SCAN_PER_CLASS
 * templates at an even stride (at most SCAN_PER_CLASS of them), so a vote
 * costs at most vote_classes x SCAN_PER_CLASS distances (measured at
 * 10 000 templates: bench/RESULTS.md). *out gets the class chosen; an
 * error only from rows of an index in place that turn out damaged. */
static int vote(const mim_index_t *ix, const mim_index_query_options_t *opt, const float *q, const float *w,
                int masked, int64_t ex, const double *pr, uint32_t top, uint32_t *out, mim_error_t *err)
{
    *out = top;
    enum { MAXC = 8, MAXK = 32 };
    uint32_t T = opt && opt->vote_classes ? opt->vote_classes : MIM_INDEX_VOTE_CLASSES_DEFAULT;
    uint32_t K = opt && opt->vote_k ? opt->vote_k : MIM_INDEX_VOTE_K_DEFAULT;
    uint32_t d = ix->d, d2 = ix->d2, de = d2 - d, nc = ix->n_classes;
    if (T > MAXC) T = MAXC;
    if (K > MAXK) K = MAXK;
    if (T > nc) T = nc;
    /* the T most probable classes */
    uint32_t cl[MAXC];
    uint32_t nt = 0;
    for (uint32_t c = 0; c < nc; c++) {
        if (nt < T) cl[nt++] = c;
        else if (pr[c] > pr[cl[T - 1]]) cl[T - 1] = c;
        else continue;
        for (uint32_t i = nt - 1; i > 0 && pr[cl[i - 1]] < pr[cl[i]]; i--) {
            uint32_t tt = cl[i];
            cl[i] = cl[i - 1], cl[i - 1] = tt;
        }
    }
    /* squared weights over the available angles: the descriptor's only
     * when no landmark is missing (as the k-NN), else all d2 kept */
    float w2[512];
    int wide = masked;
    uint32_t nw = wide ? d2 : d;
    if (nw > 512) return 0;
    for (uint32_t f = 0; f < nw; f++) w2[f] = w[f] * ix->w[f] * ix->w[f];
    cand_t best[MAXK];
    uint32_t nb = 0;
    for (uint32_t t = 0; t < nt; t++) { /* at most SCAN_PER_CLASS templates a class, evenly spread */
        uint32_t c = cl[t], lo = ix->class_start[c], hi = ix->class_start[c + 1];
        uint32_t step = (hi - lo + SCAN_PER_CLASS - 1) / SCAN_PER_CLASS, last = UINT32_MAX;
        for (uint32_t r = lo; r < hi; r += step) {
            int rc = row_ready(ix, r, wide, &last, err);
            if (rc) return rc;
            if (ex >= 0 && ix->subject[r] == (uint32_t)ex) continue;
            keep(best, &nb, K, masked_d2(ix->desc + (size_t)r * d, ix->extra + (size_t)r * de, q, w2, d, wide ? de : 0), r);
        }
    }
    if (!nb) return 0;
    double score[MAXC] = {0};
    for (uint32_t i = 0; i < nb; i++)
        for (uint32_t t = 0; t < nt; t++)
            if (best[i].row >= ix->class_start[cl[t]] && best[i].row < ix->class_start[cl[t] + 1])
                score[t] += 1 + 1e-3 * (nb - i);
    uint32_t arg = 0;
    for (uint32_t t = 0; t < nt; t++) {
        score[t] = pr[cl[t]] * (score[t] + 1);
        if (score[t] > score[arg]) arg = t;
    }
    *out = cl[arg];
    return 0;
}

/* The discriminants' class of a frame and its posterior (the softmax of
 * the classes' log-likelihoods): the shape discriminants' (shape.c, any
 * frame with three landmarks or more), else for a whole frame the angles'
 * (lda.c: built on request). Not both: adding their log-likelihoods
 * measured worse than the shape discriminants alone (bench/RESULTS.md).
 * -1: neither. */
static int64_t discriminant_class(const mim_index_t *ix, const float *positions, const float *angled,
                                  const uint8_t *present, uint32_t missing, const double *shape_scores,
                                  double *posterior)
{
    const uint32_t nc = ix->n_classes;
    double st[256], *a = nc <= 256 ? st : malloc(sizeof *a * nc);
    if (!a) return -1;
    int64_t c = -1;
    if (shape_scores) { /* the completion scored the classes already (mim__shape_complete) */
        memcpy(a, shape_scores, sizeof *a * nc);
        for (uint32_t k = 0; k < nc; k++)
            if (isfinite(a[k]) && (c < 0 || a[k] > a[c])) c = k;
    } else
        c = mim__shape_class(&ix->shape, positions, present, a);
    if (c < 0 && !missing && ix->lda.nf) c = mim__lda_class(&ix->lda, angled, ix->n_landmarks, a);
    if (c >= 0) {
        double z = 0;
        for (uint32_t k = 0; k < nc; k++)
            if (isfinite(a[k])) z += exp(a[k] - a[c]);
        *posterior = 1 / z;
    }
    if (a != st) free(a);
    return c;
}

int mim_index_query(const mim_index_t *ix, const float *positions, const uint8_t *present,
                    const mim_index_query_options_t *opt, mim_index_answer_t *ans, mim_index_hit_t *hits,
                    mim_error_t *err)
{
    uint32_t k = opt && opt->k ? opt->k : 1, d = ix->d2, L = ix->n_landmarks;
    memset(ans, 0, sizeof *ans);
    if (present)
        for (uint32_t l = 0; l < L; l++) ans->missing += !present[l];
    for (uint32_t l = 0; l < L; l++)
        for (int c = 0; c < 3; c++)
            if ((!present || present[l]) && !isfinite(positions[3 * l + c]))
                return mim_error_set(err, MIM_ENONFINITE, "landmark %u is not a finite position", l);
    float canonical[3 * MIM_LANDMARKS_MAX]; /* the frame as the angles see it (proportions.c) */
    const float *angled = positions;
    if (ix->prop.on) {
        mim__proportions_apply(&ix->prop, L, positions, present, canonical);
        angled = canonical;
    }
    /* scratch on the stack for the usual d, on the heap for a large one */
    float q_st[256];
    double xd_st[256];
    uint8_t mask_st[256];
    float w_st[256];
    cand_t best_st[64];
    int ind_st[64];
    float dist_st[64];
    float *q = q_st;
    double *xd = xd_st;
    uint8_t *mask = mask_st;
    float *w = w_st;
    void *heap = NULL;
    if (d > 256) {
        heap = malloc((2 * sizeof(float) + sizeof(double) + 1) * (size_t)d);
        if (!heap) return MIM_ENOMEM;
        xd = heap, q = (float *)(xd + d), w = q + d, mask = (uint8_t *)(w + d);
    }
    int rc = query_desc(ix, positions, angled, present, opt, k, q, xd, mask, w, ans, hits, best_st, ind_st, dist_st,
                        err);
    free(heap);
    return rc;
}

static int query_desc(const mim_index_t *ix, const float *positions, const float *angled, const uint8_t *present,
                      const mim_index_query_options_t *opt, uint32_t k, float *q, double *xd, uint8_t *mask,
                      float *w, mim_index_answer_t *ans, mim_index_hit_t *hits, cand_t *best_st, int *ind_st,
                      float *dist_st, mim_error_t *err)
{
    uint32_t d = ix->d, d2 = ix->d2, de = d2 - d, L = ix->n_landmarks;
    mim_index_descriptor(angled, present, L, ix->selected, d2, q);
    uint32_t avail = 0, avail2 = 0;
    for (uint32_t f = 0; f < d2; f++) {
        mask[f] = !isnan(q[f]);
        w[f] = mask[f];
        avail2 += mask[f];
        if (f < d) avail += mask[f];
        if (f < d) xd[f] = mask[f] ? q[f] * ix->w[f] : 0;
        if (!mask[f]) q[f] = 0;
    }
    if (!avail2)
        return mim_error_set(err, MIM_EINVAL, "none of the %u kept angles survives the %u missing landmarks", d2,
                             ans->missing);
    int masked = avail < d;
    int64_t ex = -1; /* the subject left out, as a string index */
    if (opt && opt->exclude_subject)
        for (uint32_t s = 0; s < ix->n_strings; s++)
            if (!strcmp(ix->strings[s], opt->exclude_subject)) ex = s;
    float full[3 * MIM_LANDMARKS_MAX];
    uint32_t gauss_cls;
    /* the classes' scores come with the completion (up to 256 classes:
     * more are scored again below, as whole frames are) */
    double scores_st[256], *shape_scores = ix->n_classes <= 256 ? scores_st : NULL;
    const int gauss = masked && ix->shape.n_classes && L <= MIM_LANDMARKS_MAX &&
                      !mim__shape_complete(&ix->shape, positions, present, full, &gauss_cls, shape_scores);
    if (!gauss) shape_scores = NULL;
    if (gauss) {
        /* missing landmarks, and the classes' Gaussians: the missing
         * angles are those of the frame completed by their conditional
         * mean (issue 29, shape_complete.c), with no scan of the templates */
        float qc_st[256], *qc = d <= 256 ? qc_st : malloc(sizeof *qc * d);
        if (!qc) return MIM_ENOMEM;
        if (ix->prop.on) { /* the completed frame as the angles see it */
            float as_given[3 * MIM_LANDMARKS_MAX];
            memcpy(as_given, full, sizeof *full * 3 * L);
            mim__proportions_apply(&ix->prop, L, as_given, NULL, full);
        }
        mim_index_descriptor(full, NULL, L, ix->selected, d, qc);
        for (uint32_t f = 0; f < d; f++)
            if (!mask[f]) q[f] = qc[f], xd[f] = q[f] * ix->w[f];
        if (qc != qc_st) free(qc);
    } else if (masked) {
        /* missing landmarks: the SVMs were trained on all d angles, and a
         * kernel over the remaining ones misjudges the class (measured:
         * bench/RESULTS.md). Complete the descriptor instead with the
         * missing angles of the nearest template over the available ones of
         * the d2 kept, then classify. The scan covers every template of an
         * index up to exact_max templates; a larger index scans the first
         * SCAN_PER_CLASS templates of each class (contiguous in memory), so
         * the cost stays bounded: the completion needs a template of the
         * right pose, not the nearest one. */
        float bd = INFINITY;
        uint32_t br = 0;
        int all = ix->n_templates <= ix->exact_max;
        for (uint32_t c = 0; c < ix->n_classes; c++) {
            uint32_t lo = ix->class_start[c], hi = ix->class_start[c + 1];
            if (!all && hi - lo > SCAN_PER_CLASS) hi = lo + SCAN_PER_CLASS;
            int rc = mim__rows_ready(ix, lo, hi, 1, err);
            if (rc) return rc;
            for (uint32_t r = lo; r < hi; r++) {
                if (ex >= 0 && ix->subject[r] == (uint32_t)ex) continue;
                float s2 = masked_d2(ix->desc + (size_t)r * d, ix->extra + (size_t)r * de, q, w, d, de);
                if (s2 < bd) bd = s2, br = r;
            }
        }
        for (uint32_t f = 0; f < d; f++)
            if (!mask[f]) q[f] = ix->desc[(size_t)br * d + f], xd[f] = q[f] * ix->w[f];
    }
    /* the class: the discriminants' (discriminant_class), unless the SVMs
     * are sure (svm_above); else the SVM with the highest probability, and
     * the k-NN vote when that is low */
    uint32_t cls = 0;
    double prob = 1;
    if (ix->n_classes > 1) {
        double vb = opt && opt->vote_below ? opt->vote_below : MIM_INDEX_VOTE_BELOW_DEFAULT;
        double sa = opt && opt->svm_above ? opt->svm_above : MIM_INDEX_SVM_ABOVE_DEFAULT;
        int64_t lc = -1;
        double lp = 0;
        if (sa > 1) /* the discriminants alone: no SVM is evaluated */
            lc = discriminant_class(ix, positions, angled, present, ans->missing, shape_scores, &lp);
        if (lc >= 0) {
            cls = (uint32_t)lc, prob = lp;
        } else {
            double sum = 0, best = -1;
            double pr_st[256], *pr = ix->n_classes <= 256 ? pr_st : malloc(sizeof(double) * ix->n_classes);
            if (!pr) return MIM_ENOMEM;
            for (uint32_t c = 0; c < ix->n_classes; c++) {
                pr[c] = mim__svm_probability(&ix->svm[c], mim__svm_decision(&ix->svm[c], ix->gamma, xd, NULL, d));
                sum += pr[c];
                if (pr[c] > best) best = pr[c], cls = c;
            }
            prob = sum > 0 ? best / sum : 0;
            if (sa > 0 && sa <= 1 && prob < sa && (lc = discriminant_class(ix, positions, angled, present, ans->missing, shape_scores, &lp)) >= 0)
                cls = (uint32_t)lc, prob = lp;
            int vrc = 0;
            if (!(lc >= 0) && vb > 0 && prob < vb)
                vrc = vote(ix, opt, q, w, masked, ex, pr, cls, &cls, err);
            if (pr != pr_st) free(pr);
            if (vrc) return vrc;
        }
    }
    ans->cls = cls, ans->probability = prob;
    /* k nearest inside the class: in place, its rows are verified and its
     * k-NN index made when a query first needs them */
    uint32_t lo = ix->class_start[cls], hi = ix->class_start[cls + 1], nc = hi - lo;
    int rc = mim__class_ready(ix, cls, err);
    if (!rc && masked && ix->flann_exact[cls]) rc = mim__rows_ready(ix, lo, hi, 1, err);
    if (rc) return rc;
    uint32_t n_ex = 0;
    if (ex >= 0)
        for (uint32_t r = lo; r < hi; r++) n_ex += ix->subject[r] == (uint32_t)ex;
    uint32_t want = k + n_ex < nc ? k + n_ex : nc;
    if (!want) return 0;
    cand_t *best = want <= 64 ? best_st : malloc(sizeof(cand_t) * want);
    if (!best) return MIM_ENOMEM;
    uint32_t nb = 0;
    if (masked && ix->flann_exact[cls]) { /* exact scan over the available kept angles, rescaled */
        double scale = (double)d / avail2;
        for (uint32_t r = lo; r < hi; r++) {
            if (ex >= 0 && ix->subject[r] == (uint32_t)ex) continue;
            float s2 = masked_d2(ix->desc + (size_t)r * d, ix->extra + (size_t)r * de, q, w, d, de);
            keep(best, &nb, want, (float)(s2 * scale), r);
        }
    } else {
        int *ind = want <= 64 ? ind_st : malloc(sizeof(int) * want);
        float *dist = want <= 64 ? dist_st : malloc(sizeof(float) * want);
        struct FLANNParameters p = mim__flann_params(ix, ix->flann_exact[cls]);
        if (opt && opt->checks) p.checks = (int)opt->checks;
        int frc = ind && dist ? flann_find_nearest_neighbors_index_float(ix->flann[cls], q, 1, ind, dist, (int)want, &p) : -1;
        if (frc == 0)
            for (uint32_t i = 0; i < want; i++) {
                if (ind[i] < 0 || (uint32_t)ind[i] >= nc) continue;
                uint32_t r = lo + (uint32_t)ind[i];
                if (ex >= 0 && ix->subject[r] == (uint32_t)ex) continue;
                best[nb++] = (cand_t){dist[i], r};
            }
        if (want > 64) free(ind), free(dist);
        if (frc) {
            if (best != best_st) free(best);
            return mim_error_set(err, MIM_ENOMEM, "k-NN search in class %u failed", cls);
        }
    }
    if (nb > k) nb = k;
    for (uint32_t i = 0; i < nb; i++) {
        uint32_t r = best[i].row;
        hits[i] = (mim_index_hit_t){ix->ids[r], ix->strings[ix->subject[r]], ix->strings[ix->pose[r]],
                                    sqrtf(best[i].d2 > 0 ? best[i].d2 : 0)};
    }
    ans->n_hits = nb;
    if (best != best_st) free(best);
    return 0;
}
