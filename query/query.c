/* Building the stored index from a store, opening it, and querying frames. */
#include "mim_query.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* The index is used in place, in the store's memory map (issue 16: at
 * 1 000 000 templates, copying the 739 MiB blob out took most of a 1.8 s
 * open). Pointers into the map stay valid while the read transaction that
 * lent them is open, so the query holds that one read-only transaction for
 * its whole life. That is acceptable: the store's environment is opened
 * with MDB_NOTLS, so the transaction belongs to no thread (serve's threads
 * query through it, and a thread that holds it may still begin others,
 * writes included), and an LMDB reader never blocks a writer: a long one
 * only keeps the pages of its snapshot from being reused, so a store that
 * is written while a query is open (ingest with registration, mimic index
 * while serve runs) grows by what those writes free (at most the old blob,
 * for a new index) until the query closes. An older blob (version 1 to 4)
 * is copied out and the transaction ended at once, as before. */
struct mim_query {
    mim_index_t *ix;
    mim_db_txn_t *txn; /* the snapshot the index lives in (NULL: the index is a copy) */
    mim_query_status_t status;
};

typedef struct {
    const mim_landmark_map_t *map;
    uint32_t n, cap;
    float *lm;
    uint64_t *ids;
    char **subjects, **poses, **datasets;
    mim_progress_t *progress;
    mim_error_t *err;
} gather_t;

static int gather(const mim_template_view_t *t, void *user)
{
    gather_t *g = user;
    const mim_landmark_map_t *map = g->map;
    for (uint32_t l = 0; l < map->count; l++)
        if (map->vertex[l] >= t->n_vertices)
            return mim_error_set(g->err, MIM_ESTORE, "template %llu: %u vertices, landmark %s is vertex %u",
                                 (unsigned long long)t->id, t->n_vertices, map->names[l], map->vertex[l]);
    if (g->n == g->cap) {
        uint32_t nc = g->cap ? 2 * g->cap : 256;
        float *lm = realloc(g->lm, sizeof(float) * 3 * map->count * nc);
        if (lm) g->lm = lm;
        uint64_t *ids = realloc(g->ids, sizeof(uint64_t) * nc);
        if (ids) g->ids = ids;
        char **s = realloc(g->subjects, sizeof(char *) * nc);
        if (s) g->subjects = s;
        char **p = realloc(g->poses, sizeof(char *) * nc);
        if (p) g->poses = p;
        char **d = realloc(g->datasets, sizeof(char *) * nc);
        if (d) g->datasets = d;
        if (!lm || !ids || !s || !p || !d) return MIM_ENOMEM;
        g->cap = nc;
    }
    for (uint32_t l = 0; l < map->count; l++)
        memcpy(g->lm + ((size_t)g->n * map->count + l) * 3, t->positions + 3 * (size_t)map->vertex[l], 12);
    g->ids[g->n] = t->id;
    g->subjects[g->n] = strdup(t->subject);
    g->poses[g->n] = strdup(t->pose);
    g->datasets[g->n] = strdup(t->dataset);
    if (!g->subjects[g->n] || !g->poses[g->n] || !g->datasets[g->n]) {
        free(g->subjects[g->n]), free(g->poses[g->n]), free(g->datasets[g->n]);
        return MIM_ENOMEM;
    }
    g->n++;
    if (g->progress) mim_progress_update(g->progress, g->n);
    return 0;
}

static int cmp_cstr(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* The labels of the gathered templates across datasets: mapped poses take
 * their class, the rest are qualified by dataset where there are several;
 * then the classes and those of one template counted. */
static int label_across_datasets(gather_t *g, mim_query_pose_class_fn pose_class, void *ctx,
                                 mim_query_labels_report_t *r)
{
    memset(r, 0, sizeof *r);
    unsigned char *keep = calloc(g->n ? g->n : 1, 1);
    char **sorted = malloc(sizeof(char *) * (g->n ? g->n : 1));
    if (!keep || !sorted) {
        free(keep), free(sorted);
        return MIM_ENOMEM;
    }
    for (uint32_t i = 0; i < g->n && pose_class; i++) {
        const char *cls = g->poses[i][0] ? pose_class(ctx, g->datasets[i], g->poses[i]) : NULL;
        if (!cls) continue;
        char *c = strdup(cls);
        if (!c) break;
        free(g->poses[i]);
        g->poses[i] = c, keep[i] = 1, r->mapped++;
    }
    const char *const *ds = (const char *const *)g->datasets;
    int rc = mim_db_labels_qualify(g->n, ds, g->subjects, NULL);
    if (!rc) rc = mim_db_labels_qualify(g->n, ds, g->poses, keep);
    /* datasets and classes by sorting copies of the pointers */
    for (int pass = 0; pass < 2 && !rc; pass++) {
        char **src = pass ? g->poses : g->datasets;
        uint32_t m = 0;
        for (uint32_t i = 0; i < g->n; i++)
            if (!pass || src[i][0]) sorted[m++] = src[i];
        qsort(sorted, m, sizeof *sorted, cmp_cstr);
        uint32_t distinct = 0;
        for (uint32_t i = 0; i < m; i++) {
            if (i && !strcmp(sorted[i], sorted[i - 1])) continue;
            distinct++;
            if (pass && (i + 1 == m || strcmp(sorted[i], sorted[i + 1])) && r->single++ < MIM_QUERY_EXAMPLES)
                snprintf(r->single_example[r->single - 1], sizeof r->single_example[0], "%s", sorted[i]);
        }
        if (pass) r->classes = distinct;
        else r->datasets = distinct;
    }
    free(keep), free(sorted);
    return rc;
}

int mim_query_build_index(mim_db_t *db, const mim_index_options_t *opt, mim_index_report_t *report, mim_error_t *err)
{
    return mim_query_build_index_labelled(db, opt, NULL, NULL, report, NULL, err);
}

int mim_query_build_index_labelled(mim_db_t *db, const mim_index_options_t *opt, mim_query_pose_class_fn pose_class,
                                   void *pose_ctx, mim_index_report_t *report, mim_query_labels_report_t *labels,
                                   mim_error_t *err)
{
    mim_query_labels_report_t lrep;
    mim_db_txn_t *t = NULL;
    mim_landmark_map_t map;
    mim_db_meta_t meta;
    gather_t g = {0};
    mim_index_t *ix = NULL;
    void *blob = NULL;
    size_t len = 0;
    mim_progress_t pr;
    int rc = mim_db_begin(db, 0, &t, err);
    if (rc) return rc;
    if ((rc = mim_db_meta_get(t, &meta, err))) goto out;
    rc = mim_db_landmarks_get(t, &map, err);
    if (rc == MIM_ENOTFOUND) {
        rc = mim_error_set(err, MIM_ENOLANDMARKS, "%s: store has no landmark map (it is empty: mimic ingest meshes into it first)",
                           mim_db_path(db));
        goto out;
    }
    if (rc) goto out;
    g.map = &map, g.err = err;
    if (opt && opt->progress) { /* the index options' callback, for the reading first */
        pr = (mim_progress_t){.fn = opt->progress->fn, .ctx = opt->progress->ctx};
        g.progress = &pr;
        mim_progress_begin(&pr, "reading templates", meta.templates);
    }
    rc = mim_db_template_each(t, gather, &g, err);
    if (g.progress) mim_progress_end(&pr);
    mim_db_abort(&t);
    if (rc) goto out;
    if (!g.n) {
        rc = mim_error_set(err, MIM_EEMPTY, "%s: store has no templates to index", mim_db_path(db));
        goto out;
    }
    if ((rc = label_across_datasets(&g, pose_class, pose_ctx, &lrep))) {
        rc = mim_error_set(err, rc, "out of memory labelling %u templates", g.n);
        goto out;
    }
    if (labels) *labels = lrep;
    /* the landmark skeleton, for canonical proportions: the 16 default
     * landmarks' (another map has none) */
    int32_t parent[MIM_LANDMARKS_MAX];
    const int skeleton = !mim_index_skeleton(&map, parent);
    mim_index_input_t in = {g.n, map.count, g.lm, g.ids, (const char *const *)g.subjects,
                            (const char *const *)g.poses, map.mirror, skeleton ? parent : NULL};
    if ((rc = mim_index_build(&ix, &in, opt, report, err))) goto out;
    if ((rc = mim_index_save(ix, &blob, &len, err))) goto out;
    mim_index_info_t info;
    mim_index_get_info(ix, &info);
    mim_db_index_meta_t bm = {meta.next_id, meta.templates, info.class_source, info.n_classes, info.d,
                              (double)time(NULL)};
    if ((rc = mim_db_begin(db, 1, &t, err))) goto out;
    if ((rc = mim_db_index_put(t, blob, len, &bm, err))) goto out;
    rc = mim_db_commit(&t, err);
out:
    mim_db_abort(&t);
    for (uint32_t i = 0; i < g.n; i++) free(g.subjects[i]), free(g.poses[i]), free(g.datasets[i]);
    free(g.lm), free(g.ids), free(g.subjects), free(g.poses), free(g.datasets), free(blob);
    mim_index_close(&ix);
    return rc;
}

static int status_in(mim_db_txn_t *t, mim_query_status_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    mim_db_meta_t meta;
    int rc = mim_db_meta_get(t, &meta, err);
    if (rc) return rc;
    out->templates = meta.templates;
    rc = mim_db_index_get(t, NULL, NULL, &out->built, NULL);
    if (rc == MIM_ENOTFOUND) return 0;
    if (rc) return mim_db_index_get(t, NULL, NULL, &out->built, err);
    out->has_index = 1;
    out->stale = out->built.next_id != meta.next_id || out->built.templates != meta.templates;
    return 0;
}

int mim_query_status(mim_db_t *db, mim_query_status_t *out, mim_error_t *err)
{
    mim_db_txn_t *t = NULL;
    int rc = mim_db_begin(db, 0, &t, err);
    if (!rc) rc = status_in(t, out, err);
    mim_db_abort(&t);
    return rc;
}

int mim_query_open(mim_query_t **out, mim_db_t *db, mim_error_t *err)
{
    *out = NULL;
    mim_query_t *q = calloc(1, sizeof *q);
    if (!q) return MIM_ENOMEM;
    const void *blob;
    size_t len;
    mim_db_index_meta_t bm;
    mim_index_info_t info;
    /* lent without the whole blob's checksum: the blob checks itself, its
     * head now and the rest by section on first use (in place), or all of
     * it as it is copied (unaligned) */
    int rc = mim_db_begin(db, 0, &q->txn, err);
    if (!rc) rc = status_in(q->txn, &q->status, err);
    if (!rc) rc = mim_db_index_lend(q->txn, &blob, &len, &bm, err);
    if (!rc) rc = mim_index_open_in_place(&q->ix, blob, len, err);
    if (!rc) {
        mim_index_get_info(q->ix, &info);
        if (!info.in_place) mim_db_abort(&q->txn);
    }
    if (rc) {
        mim_query_close(&q);
        return rc;
    }
    *out = q;
    return 0;
}

void mim_query_close(mim_query_t **pq)
{
    if (!pq || !*pq) return;
    mim_index_close(&(*pq)->ix);
    mim_db_abort(&(*pq)->txn); /* after the index that points into it */
    free(*pq);
    *pq = NULL;
}

const mim_query_status_t *mim_query_get_status(const mim_query_t *q) { return &q->status; }
const mim_index_t *mim_query_index(const mim_query_t *q) { return q->ix; }

uint32_t mim_query_landmark_count(const mim_query_t *q)
{
    mim_index_info_t info;
    mim_index_get_info(q->ix, &info);
    return info.n_landmarks;
}

int mim_query_frame(const mim_query_t *q, const float *positions, const uint8_t *present,
                    const mim_index_query_options_t *opt, mim_index_answer_t *ans, mim_index_hit_t *hits,
                    mim_error_t *err)
{
    return mim_index_query(q->ix, positions, present, opt, ans, hits, err);
}

int mim_query_nearest(void *ctx, const float *positions, uint32_t k, uint64_t *ids, uint32_t *n, mim_error_t *err)
{
    const mim_query_t *q = ctx;
    mim_index_answer_t ans;
    mim_index_hit_t hits[64];
    mim_index_query_options_t qo = {.k = k < 64 ? k : 64};
    *n = 0;
    int rc = mim_index_query(q->ix, positions, NULL, &qo, &ans, hits, err);
    if (rc) return rc;
    if (!ans.n_hits) return mim_error_set(err, MIM_ENOTFOUND, "the index found no template");
    for (uint32_t i = 0; i < ans.n_hits; i++) ids[i] = hits[i].id;
    *n = ans.n_hits;
    return 0;
}

int mim_query_batch(const mim_query_t *q, const mim_landmark_frames_t *f, const mim_index_query_options_t *opt,
                    mim_index_answer_t *answers, mim_index_hit_t *hits, mim_error_t *err)
{
    uint32_t L = mim_query_landmark_count(q), k = opt && opt->k ? opt->k : 1;
    if (f->n_landmarks != L)
        return mim_error_set(err, MIM_EINVAL, "frames have %u landmarks, the index has %u", f->n_landmarks, L);
    for (uint32_t i = 0; i < f->n_frames; i++) {
        int rc = mim_index_query(q->ix, f->positions + (size_t)i * L * 3, f->present ? f->present + (size_t)i * L : NULL, opt,
                                 &answers[i], hits + (size_t)i * k, err);
        if (rc) {
            if (err && err->code == rc) { /* name the frame */
                char msg[sizeof err->msg + 32];
                snprintf(msg, sizeof msg, "frame %u: %s", i, err->msg);
                memcpy(err->msg, msg, sizeof err->msg - 1);
                err->msg[sizeof err->msg - 1] = 0;
            }
            return rc;
        }
    }
    return 0;
}
