/* Selecting the salient angles with a decision tree (seed 000, Section 3.2):
 * a CART tree with Gini impurity is grown on the pose labels, every sample
 * also mirrored left<->right so that neither side dominates; the angles the
 * tree splits on, ranked by their total (sample-weighted) Gini decrease, form
 * the descriptor. A tree needs only about one split per class, so when it uses
 * fewer than d angles the rest are the angles with the best single split of
 * the whole set. Missing values (NaN) are left out of a split's search and
 * follow the larger side. */
#include "mim_index.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    float v;
    uint32_t label;
} vl_t;

typedef struct {
    const float *x; /* rows of n_features: originals, then mirrored copies */
    const uint32_t *y;
    uint32_t n_features, n_classes, min_leaf, max_depth;
    double *importance;
    double *root_gain; /* best single-split decrease per feature at the root */
    vl_t *scratch;
    uint32_t *counts_l, *counts_r;
    uint32_t nodes, correct;
} tree_t;

static int cmp_vl(const void *a, const void *b)
{
    float x = ((const vl_t *)a)->v, y = ((const vl_t *)b)->v;
    return x < y ? -1 : x > y;
}

static double gini(const uint32_t *counts, uint32_t n_classes, uint32_t total)
{
    if (!total) return 0;
    double s = 0;
    for (uint32_t c = 0; c < n_classes; c++) {
        double p = (double)counts[c] / total;
        s += p * p;
    }
    return 1 - s;
}

/* Best split of feature f over rows idx: returns the Gini decrease (weighted
 * by the rows that have a value) and the threshold. */
static double best_split(tree_t *t, const uint32_t *idx, uint32_t n, uint32_t f, float *threshold)
{
    uint32_t m = 0;
    for (uint32_t r = 0; r < n; r++) {
        float v = t->x[(size_t)idx[r] * t->n_features + f];
        if (!isnan(v)) t->scratch[m++] = (vl_t){v, t->y[idx[r]]};
    }
    if (m < 2 * t->min_leaf) return 0;
    qsort(t->scratch, m, sizeof *t->scratch, cmp_vl);
    memset(t->counts_l, 0, sizeof(uint32_t) * t->n_classes);
    memset(t->counts_r, 0, sizeof(uint32_t) * t->n_classes);
    for (uint32_t r = 0; r < m; r++) t->counts_r[t->scratch[r].label]++;
    double parent = gini(t->counts_r, t->n_classes, m), best = 0;
    for (uint32_t r = 0; r + 1 < m; r++) {
        t->counts_l[t->scratch[r].label]++;
        t->counts_r[t->scratch[r].label]--;
        uint32_t nl = r + 1, nr = m - nl;
        if (t->scratch[r].v == t->scratch[r + 1].v || nl < t->min_leaf || nr < t->min_leaf) continue;
        double w = (nl * gini(t->counts_l, t->n_classes, nl) + nr * gini(t->counts_r, t->n_classes, nr)) / m;
        if (parent - w > best) {
            best = parent - w;
            *threshold = 0.5f * (t->scratch[r].v + t->scratch[r + 1].v);
        }
    }
    return best * m / n; /* rows without a value contribute no decrease */
}

static int grow(tree_t *t, uint32_t *idx, uint32_t n, uint32_t depth)
{
    t->nodes++;
    uint32_t *counts = calloc(t->n_classes, sizeof *counts);
    if (!counts) return MIM_ENOMEM;
    for (uint32_t r = 0; r < n; r++) counts[t->y[idx[r]]]++;
    uint32_t major = 0;
    for (uint32_t c = 1; c < t->n_classes; c++)
        if (counts[c] > counts[major]) major = c;
    int pure = counts[major] == n;
    free(counts);
    double best = 0;
    float thr = 0;
    uint32_t bf = 0;
    if (!pure && depth < t->max_depth && n >= 2 * t->min_leaf) {
        for (uint32_t f = 0; f < t->n_features; f++) {
            float th = 0;
            double g = best_split(t, idx, n, f, &th);
            if (depth == 0) t->root_gain[f] = g;
            if (g > best + 1e-12) best = g, thr = th, bf = f;
        }
    }
    if (best <= 0) { /* a leaf: it predicts its majority class */
        for (uint32_t r = 0; r < n; r++) t->correct += t->y[idx[r]] == major;
        return 0;
    }
    t->importance[bf] += best * n;
    /* partition: values below the threshold left; NaN to the larger side */
    uint32_t below = 0, above = 0;
    for (uint32_t r = 0; r < n; r++) {
        float v = t->x[(size_t)idx[r] * t->n_features + bf];
        if (isnan(v)) continue;
        if (v < thr) below++;
        else above++;
    }
    int nan_left = below >= above;
    uint32_t *tmp = malloc(sizeof *tmp * n);
    if (!tmp) return MIM_ENOMEM;
    uint32_t l = 0, rr = n;
    for (uint32_t r = 0; r < n; r++) {
        float v = t->x[(size_t)idx[r] * t->n_features + bf];
        int left = isnan(v) ? nan_left : v < thr;
        if (left) tmp[l++] = idx[r];
        else tmp[--rr] = idx[r];
    }
    memcpy(idx, tmp, sizeof *tmp * n);
    free(tmp);
    int rc = grow(t, idx, l, depth + 1);
    if (!rc) rc = grow(t, idx + l, n - l, depth + 1);
    return rc;
}

typedef struct {
    double key;
    uint32_t f;
} rank_t;

static int cmp_rank(const void *a, const void *b)
{
    double x = ((const rank_t *)a)->key, y = ((const rank_t *)b)->key;
    if (x != y) return x > y ? -1 : 1; /* larger first */
    return ((const rank_t *)a)->f < ((const rank_t *)b)->f ? -1 : 1;
}

int mim_index_select(const float *x, const uint32_t *labels, uint32_t n_samples, uint32_t n_features,
                     uint32_t n_classes, const uint32_t *angle_mirror, const mim_select_options_t *opt,
                     uint32_t *selected, mim_select_report_t *report, mim_error_t *err)
{
    mim_select_options_t o = opt ? *opt : (mim_select_options_t){0};
    uint32_t d = o.features ? o.features : 60;
    if (d > n_features) d = n_features;
    if (!n_samples || !n_features || !n_classes)
        return mim_error_set(err, MIM_EINVAL, "feature selection needs samples, features and classes");
    for (uint32_t s = 0; s < n_samples; s++)
        if (labels[s] >= n_classes)
            return mim_error_set(err, MIM_EINVAL, "sample %u has class %u, but there are %u classes", s, labels[s], n_classes);
    uint32_t rows = angle_mirror ? 2 * n_samples : n_samples;
    float *xx = malloc(sizeof(float) * (size_t)rows * n_features);
    uint32_t *yy = malloc(sizeof(uint32_t) * rows), *idx = malloc(sizeof(uint32_t) * rows);
    tree_t t = {0};
    t.importance = calloc(n_features, sizeof(double));
    t.root_gain = calloc(n_features, sizeof(double));
    t.scratch = malloc(sizeof(vl_t) * rows);
    t.counts_l = malloc(sizeof(uint32_t) * n_classes);
    t.counts_r = malloc(sizeof(uint32_t) * n_classes);
    rank_t *rank = malloc(sizeof(rank_t) * n_features);
    int rc = 0;
    if (!xx || !yy || !idx || !t.importance || !t.root_gain || !t.scratch || !t.counts_l || !t.counts_r || !rank) {
        rc = MIM_ENOMEM;
        goto out;
    }
    memcpy(xx, x, sizeof(float) * (size_t)n_samples * n_features);
    memcpy(yy, labels, sizeof(uint32_t) * n_samples);
    if (angle_mirror) /* the mirrored body: its angle a is the original's angle mirror[a] */
        for (uint32_t s = 0; s < n_samples; s++) {
            for (uint32_t a = 0; a < n_features; a++)
                xx[(size_t)(n_samples + s) * n_features + a] = x[(size_t)s * n_features + angle_mirror[a]];
            yy[n_samples + s] = labels[s];
        }
    for (uint32_t r = 0; r < rows; r++) idx[r] = r;
    t.x = xx;
    t.y = yy;
    t.n_features = n_features;
    t.n_classes = n_classes;
    t.min_leaf = o.min_leaf ? o.min_leaf : 1;
    t.max_depth = o.max_depth ? o.max_depth : 32;
    if ((rc = grow(&t, idx, rows, 0))) goto out;

    /* the tree's angles first, then the best single splits */
    uint32_t used = 0;
    for (uint32_t f = 0; f < n_features; f++) {
        int in_tree = t.importance[f] > 0;
        used += in_tree;
        rank[f].f = f;
        rank[f].key = in_tree ? 1e9 + t.importance[f] : t.root_gain[f];
    }
    qsort(rank, n_features, sizeof *rank, cmp_rank);
    for (uint32_t s = 0; s < d; s++) selected[s] = rank[s].f;
    if (report) {
        report->tree_nodes = t.nodes;
        report->tree_features = used;
        report->training_accuracy = (double)t.correct / rows;
    }
out:
    free(xx), free(yy), free(idx), free(t.importance), free(t.root_gain), free(t.scratch), free(t.counts_l),
        free(t.counts_r), free(rank);
    return rc;
}
