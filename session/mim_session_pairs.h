/* mimic session: sampled pose-pairs become templates of the store (issue
 * 14; seed 002's purpose in mimic: the store grows by the poses it
 * samples). Each person of a sample gives the store's landmarks (its
 * joints matched by name, turned to the avatar's facing, on the avatar's
 * proportions or its own, moved onto the avatar), which pose the avatar
 * through the session's one pipeline (landmarks mode: the nearest
 * template's frames, the landmarks held; seed 000, Section 3.4); the
 * results go into the store as templates with their encodings, in one
 * transaction, and the recognition index is rebuilt.
 *
 * The steps, in order (`mimic pairs templates` is them and its options):
 *   mim_session_pairs_check      the session's store can take pose-pairs
 *   mim_session_pairs_prepare    every selected person's landmarks, checked
 *                                (a bad sample stops the run before any transfer)
 *   mim_session_pairs_transfer   every person through the session
 *   (mim_session_close)          LMDB opens a store once at a time in a process
 *   mim_session_pairs_store      the results into the store, the index rebuilt
 * Errors are one line naming the sample ("FILE:LINE: person a: ...").
 * Nothing is printed: progress goes to the options' callback. */
#ifndef MIM_SESSION_PAIRS_H
#define MIM_SESSION_PAIRS_H

#include "mim_sample.h"
#include "mim_session.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Sampled people on their way into the store: their landmarks, then the
 * transfers' results (kept in a temporary file, 3 * n floats each). */
typedef struct mim_session_pairs mim_session_pairs_t;

#define MIM_SESSION_PAIRS_PERSON_A 1u
#define MIM_SESSION_PAIRS_PERSON_B 2u
/* A pose label prefix: up to this many printable characters, no space or '/'. */
#define MIM_SESSION_PAIRS_PREFIX_MAX 48

typedef struct mim_session_pairs_options {
    uint32_t max;              /* the first max samples; 0: all */
    unsigned persons;          /* MIM_SESSION_PAIRS_PERSON_A | _B; 0: both */
    /* 0 (default): each segment of the landmark skeleton keeps the
     * sample's direction and takes the avatar's length (the joints of a
     * motion capture skeleton are not the avatar's surface landmarks;
     * mim_xfer_retarget_landmarks, which needs the 16 default landmarks);
     * 1: the sample's joints held as they are */
    int sample_proportions;
    const char *origin;        /* the samples' file as errors name it; NULL: "samples" */
    mim_progress_t *progress;  /* "transfer", "store", then the index's phases; NULL: quiet */
} mim_session_pairs_options_t;

/* One selected person. */
typedef struct mim_session_pairs_person {
    uint32_t sample;          /* its sample: an index into the samples */
    long line;                /* that sample's line in its file (mim_pairs_samples_t's line; without
                                 one, 2 + sample: a header, then a sample a line) */
    char person;              /* 'a' or 'b' */
    const float *landmarks;   /* 3 * map count floats, map order: the targets that pose the avatar */
    const char *pose_class;   /* after the transfer: the pose class the index gave the person's own joints
                                 ("" in an index of k-means clusters); before it NULL */
    uint64_t id;              /* after the store: its template (0: equal to one stored already, not
                                 stored again; before the store, 0) */
} mim_session_pairs_person_t;

/* 0 when the session's store can take pose-pairs: it has an index
 * (MIM_ENOINDEX, "store has no index (run mimic index)") and every one of
 * its landmarks is a pose-pair joint (mim_sample_joint_names; else
 * MIM_EUNSUPPORTED naming the landmark). */
int mim_session_pairs_check(const mim_session_t *s, mim_error_t *err);

/* The selected people of the first max samples of smp (a then b within a
 * sample), each one's landmarks for the session's avatar (loaded first:
 * mim_session_load_avatar): its joints by the map's names, checked as every
 * landmark input is (mim_landmarks_check, named "ORIGIN:LINE: person a");
 * turned about +Y through their centre so that the body's own left (from
 * its hips and shoulders) is the avatar's (when the map has both hips and
 * shoulders, and neither body's left is vertical); retargeted unless
 * sample_proportions; moved so that the centres of the landmarks
 * coincide; and checked again. opt may be NULL. Errors: MIM_EINVAL (no
 * avatar, no samples, persons other than A and B), mim_session_pairs_check's,
 * the first bad person's (MIM_ENONFINITE, MIM_EFORMAT; MIM_EUNSUPPORTED
 * when retargeting needs landmarks the map lacks), MIM_ENOMEM. On error
 * *out is NULL. smp is not kept. */
int mim_session_pairs_prepare(mim_session_t *s, const mim_pairs_samples_t *smp,
                              const mim_session_pairs_options_t *opt, mim_session_pairs_t **out, mim_error_t *err);
/* The people (and, samples not NULL, the samples they come from). */
uint32_t mim_session_pairs_count(const mim_session_pairs_t *p, uint32_t *samples);
/* Person i (< count); what it points to lives until free. MIM_EINVAL past the end. */
int mim_session_pairs_person(const mim_session_pairs_t *p, uint32_t i, mim_session_pairs_person_t *out);

/* Every person through mim_session_transfer with its landmarks (s: the
 * session p was prepared on), each result checked as a body and kept, its
 * pose class noted. Once. Errors: MIM_EINVAL (another session, a second
 * call), the transfer's and the body check's (prefixed "ORIGIN:LINE:
 * person a: "), MIM_EIO (the temporary file), MIM_ENOMEM. */
int mim_session_pairs_transfer(mim_session_t *s, mim_session_pairs_t *p, mim_error_t *err);
/* Person i's transferred body: 3 * n floats (n: the session's
 * mim_session_mesh n_vertices). MIM_EINVAL before the transfer or past
 * the end, MIM_EIO. */
int mim_session_pairs_body(mim_session_pairs_t *p, uint32_t i, float *positions, mim_error_t *err);

typedef struct mim_session_pairs_store_options {
    uint64_t avatar_id;         /* the avatar's template id: the new templates take its subject */
    const char *source;         /* sources are "sampled:SOURCE:LINE:PERSON"; NULL: the origin */
    /* NULL: each template's pose label is its person's pose class; else
     * PREFIX LINE-PERSON ("sampled-12-a"), one class per person (which the
     * index's per-class SVMs recognise poorly, and which make a rebuild slow) */
    const char *label_prefix;
    const mim_db_options_t *db; /* how the store opens for writing (not read_only); NULL: defaults */
} mim_session_pairs_store_options_t;

typedef struct mim_session_pairs_report {
    uint32_t added;             /* new templates */
    uint32_t duplicates;        /* results equal to a stored template: not stored twice */
    const uint64_t *ids;        /* the added templates' ids, in people order; valid until free */
    mim_index_report_t index;   /* the rebuilt index (the same number of angles as before) */
    uint32_t relabelled;        /* labels moved to the class the rebuilt index gives the person's own joints */
} mim_session_pairs_report_t;

/* The transferred people into store (the one p's session had open, closed
 * now), one transaction: each body a template with its encoding (subject
 * the avatar's, source and pose label as the options say), then the index
 * rebuilt as mimic index builds it. With class labels (no label_prefix),
 * a person whose own joints the rebuilt index puts in another class than
 * its label takes that class, and the index is built again (up to 6
 * times; report's relabelled). Nothing is stored unless all are.
 * Errors, all the store's or the system's: opening it, MIM_ETOPOLOGY (its
 * connectivity changed since), MIM_ENOTFOUND (no avatar_id), a write or
 * the commit (the message ends "nothing stored"), the rebuild ("N templates
 * stored, but the index was not rebuilt: ... (run mimic index)"),
 * MIM_EINVAL (no options, before the transfer, after a store that
 * committed, a bad prefix), MIM_ENOMEM. A store that failed before its
 * commit may be tried again. */
int mim_session_pairs_store(mim_session_pairs_t *p, const char *store, const mim_session_pairs_store_options_t *opt,
                            mim_session_pairs_report_t *report, mim_error_t *err);
void mim_session_pairs_free(mim_session_pairs_t **p); /* accepts NULL; nulls the pointer */

/* 1 when prefix is a pose label prefix (MIM_SESSION_PAIRS_PREFIX_MAX). */
int mim_session_pairs_prefix_ok(const char *prefix);

#ifdef __cplusplus
}
#endif
#endif
