/* mimic query: nearest-pose query against a template store (seed 000,
 * Section 3.3): landmark frame -> descriptor -> class (SVMs) -> k nearest
 * templates (FLANN). Composes db/ (the stored index blob) and index/ (the
 * computation). Building the index from a store lives here too, since it
 * reads every template and writes the blob back. */
#ifndef MIM_QUERY_H
#define MIM_QUERY_H

#include "mim_core.h"
#include "mim_db.h"
#include "mim_index.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Reads every template's landmarks (the store's landmark map), builds the
 * index and stores it with its build record, replacing any older one.
 * MIM_ENOLANDMARKS for a store without a landmark map. Progress, when
 * opt->progress is set: its callback hears "reading templates", then
 * "index". */
int mim_query_build_index(mim_db_t *db, const mim_index_options_t *opt, mim_index_report_t *report,
                          mim_error_t *err);

/* Labels across datasets (issue 30). A pose class a caller's map gives
 * (dataset, pose) (NULL: none, the pose stays its dataset's own). */
typedef const char *(*mim_query_pose_class_fn)(void *ctx, const char *dataset, const char *pose);
#define MIM_QUERY_EXAMPLES 3
typedef struct mim_query_labels_report {
    uint32_t datasets; /* distinct datasets of the templates (templates of none count as one) */
    uint32_t mapped;   /* templates whose pose the map placed in a class */
    uint32_t classes;  /* distinct pose labels (0: an unlabelled store) */
    uint32_t single;   /* of them, classes of one template */
    char single_example[MIM_QUERY_EXAMPLES][128]; /* the first of those, by template order */
} mim_query_labels_report_t;
/* mim_query_build_index where the store may hold several datasets: in a
 * store of more than one, subjects and poses are qualified by their
 * dataset (mim_db_labels_qualify), so that no two datasets share a
 * subject or a pose class, except the poses pose_class maps (may be
 * NULL). labels (may be NULL) says what was made. */
int mim_query_build_index_labelled(mim_db_t *db, const mim_index_options_t *opt, mim_query_pose_class_fn pose_class,
                                   void *pose_ctx, mim_index_report_t *report, mim_query_labels_report_t *labels,
                                   mim_error_t *err);

typedef struct mim_query_status {
    int has_index;           /* the store holds an index */
    int stale;               /* templates were added since it was built */
    mim_db_index_meta_t built; /* the build record (when has_index) */
    uint64_t templates;      /* the store's template count now */
} mim_query_status_t;
int mim_query_status(mim_db_t *db, mim_query_status_t *out, mim_error_t *err);

typedef struct mim_query mim_query_t;
/* Opens the stored index (MIM_ENOTFOUND when there is none: run mimic
 * index; MIM_EFORMAT, with a message that says to rebuild it, when it is
 * of an older version). The index is used in place, in the store's memory
 * map: the query holds one read-only transaction until mim_query_close
 * (close it before the store), and checks the index's sections as queries
 * first need them, so a damaged part makes those queries fail with
 * MIM_EFORMAT (mim_index_open_in_place). An index the map does not hold
 * 8-byte aligned is copied and checked whole, and no transaction is
 * kept. */
int mim_query_open(mim_query_t **out, mim_db_t *db, mim_error_t *err);
void mim_query_close(mim_query_t **q); /* accepts NULL; nulls the pointer */
const mim_query_status_t *mim_query_get_status(const mim_query_t *q);
const mim_index_t *mim_query_index(const mim_query_t *q);
uint32_t mim_query_landmark_count(const mim_query_t *q);

/* One frame (3 * landmark count floats; present NULL = all present), or a
 * batch: answers[n_frames], hits[n_frames * k]. Thread-safe. */
int mim_query_frame(const mim_query_t *q, const float *positions, const uint8_t *present,
                    const mim_index_query_options_t *opt, mim_index_answer_t *ans, mim_index_hit_t *hits,
                    mim_error_t *err);
/* The k nearest templates' ids to one complete frame (its pose class's,
 * nearest first; *n of them); ctx is the mim_query_t (the shape of
 * mim_ingest_nearest_fn, so that registration finds its starting template
 * through the index). MIM_ENOTFOUND when the index gives none.
 * Thread-safe. */
int mim_query_nearest(void *ctx, const float *positions, uint32_t k, uint64_t *ids, uint32_t *n, mim_error_t *err);
int mim_query_batch(const mim_query_t *q, const mim_landmark_frames_t *frames, const mim_index_query_options_t *opt,
                    mim_index_answer_t *answers, mim_index_hit_t *hits, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
