/* mimic index: pose recognition from landmarks (seed 000, Sections 3.2-3.3).
 *
 * The pose descriptor is a set of angles: at landmark j, the angle between the
 * segments j->i and j->k, for every j and every unordered pair {i, k} of the
 * other landmarks (n (n-1) (n-2) / 2 candidates: 1680 for 16 landmarks). The
 * angles do not change when the landmark set is rotated, translated or
 * uniformly scaled. A decision tree trained on pose labels, with every sample
 * also mirrored left<->right (paper §3.2), selects the d most salient angles.
 *
 * Computation over caller-owned arrays; nothing here opens the store or
 * touches process-wide state: every random choice of a build comes from a
 * seeded mim_rng_t (the same input gives the same index, byte for byte),
 * and libc's rand() is neither seeded nor used, except by FLANN's kd-forest
 * build (classes over exact_max templates), which draws from it (model.c). */
#ifndef MIM_INDEX_H
#define MIM_INDEX_H

#include "mim_core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- candidate angles ---- */
/* Number of candidate angles for n landmarks: n (n-1) (n-2) / 2. */
uint32_t mim_index_angle_count(uint32_t n);
/* The triple of candidate a: the angle at *j between *j->*i and *j->*k (i < k). */
void mim_index_angle_triple(uint32_t n, uint32_t a, uint32_t *i, uint32_t *j, uint32_t *k);
/* The candidate index of the angle at j between j->i and j->k (any order of i, k). */
uint32_t mim_index_angle_of(uint32_t n, uint32_t i, uint32_t j, uint32_t k);
/* Fills map[a] = the candidate that a becomes when the body is mirrored
 * through mirror[] (the landmark map's table). map has angle_count entries. */
void mim_index_angle_mirror(uint32_t n, const uint32_t *mirror, uint32_t *map);

/* All candidate angles (radians, 0..pi) of one landmark frame: positions is
 * 3 * n floats; present (n flags, NULL = all present) marks missing
 * landmarks. An angle that involves a missing landmark, or a zero-length
 * segment, is NaN. */
void mim_index_angles(const float *positions, const uint8_t *present, uint32_t n, float *angles);
/* Only the selected candidates: out[s] = angle of candidate selected[s]. */
void mim_index_descriptor(const float *positions, const uint8_t *present, uint32_t n, const uint32_t *selected,
                          uint32_t d, float *out);

/* ---- feature selection (CART, Gini) ---- */
typedef struct mim_select_options {
    uint32_t features;  /* d, the number of angles to keep; 0 means 60 */
    uint32_t max_depth; /* 0 means 32 */
    uint32_t min_leaf;  /* samples a leaf must keep; 0 means 1 */
} mim_select_options_t;

typedef struct mim_select_report {
    uint32_t tree_nodes;    /* nodes of the tree */
    uint32_t tree_features; /* distinct angles the tree splits on */
    double training_accuracy; /* of the tree on its (mirrored) training set */
} mim_select_report_t;

/* Chooses d candidate angles from samples x (n_samples rows of n_features
 * angles, NaN allowed and ignored) labelled with classes 0..n_classes-1.
 * Every sample is also used mirrored through angle_mirror (NULL: no
 * mirroring). The angles the tree splits on come first, by total Gini
 * decrease; the rest are filled by each angle's best single-split Gini
 * decrease over the whole set (a tree on few classes uses few angles).
 * selected gets d indices (d <= n_features). */
int mim_index_select(const float *x, const uint32_t *labels, uint32_t n_samples, uint32_t n_features,
                     uint32_t n_classes, const uint32_t *angle_mirror, const mim_select_options_t *opt,
                     uint32_t *selected, mim_select_report_t *report, mim_error_t *err);

/* ---- the recognition index: classes, per-class SVMs, per-class k-NN ----
 * (seed 000, Section 3.3: "per-class SVMs pick the pose class, k-NN inside
 * the class picks the template").
 *
 * Classes. Pose labels define them. Templates without a pose label, in a
 * store where some have one, join the class whose mean (over all candidate
 * angles) is nearest. A store with no pose label at all is clustered by
 * k-means (k-means++ seeding, fixed seed) on all candidate angles with
 * k = round(sqrt(n / 2)) clamped to 1..64 (the usual rule of thumb: it grows
 * with the store but slowly; silhouette search would cost O(n^2) per k).
 *
 * Features. The d selected angles in radians, unscaled (every feature is an
 * angle in 0..pi, so one scale fits all); a template angle that is undefined
 * (two coincident landmarks) takes its class mean.
 *
 * SVMs. One libsvm C-SVC per class, one-vs-rest, RBF kernel, probability
 * outputs (Platt scaling fitted on 5-fold decision values: libsvm's -b 1
 * method, run by mimic with its own seeded folds, without rand()). C in
 * {1, 10, 100, 1000} and gamma in {1/4, 1, 4, 16} / (mean squared distance
 * between descriptors) are chosen by k-fold cross-validation of the whole
 * one-vs-rest classifier (folds by subject when there are several subjects,
 * so the estimate is for unseen people; ties go to fewer support vectors,
 * i.e. faster queries).
 * The class of a frame is the SVM with the highest probability; its
 * probability is reported normalised over the classes.
 *
 * Noise (issue 15, bench/RESULTS.md "Recognition under landmark noise"):
 * the tree and the SVMs also learn from noisy copies of the templates
 * (mim_index_options_t noise, augment); the SVMs see each angle weighted by
 * its spread under that noise to the power -weight (default 0.5: angles
 * between short segments, which noise moves most, count less); and when
 * the class's probability is below vote_below (default 0.5), a k-NN vote
 * among the most probable classes decides (mim_index_query_options_t).
 *
 * k-NN. FLANN inside each class over the descriptors, squared L2 (reported
 * distances are square-rooted: radians). Classes up to exact_max templates
 * use FLANN's exact linear scan; larger ones a randomised kd-forest (4
 * trees, 128 checks), which is approximate: at 1 000 000 templates its
 * first hit is on average 3 % further than the exact one, for a tenth of
 * the exact scan's time (bench/RESULTS.md). The forest is randomised anew
 * on every build and load (FLANN shuffles with std::random_device), so
 * two loads of one index may answer a frame with different near
 * neighbours in such a class.
 *
 * Missing landmarks (a query frame may lose up to 3): only the angles that
 * do not involve them are used. Beside the d descriptor angles the index
 * keeps the next ranked angles of the tree, d2 in all (default 3 d: with
 * 3 of 16 landmarks lost, about 45 % of any angle set goes, and d angles
 * alone then miss poses). The frame's missing descriptor angles are those
 * of the frame completed by the classes' Gaussians (mim_index_complete;
 * issue 29: no scan of the templates, and the SVMs' accuracy with 2
 * missing 0.963 against 0.775 on test_index_hard's set); an index without
 * shape discriminants completes them from the nearest template over the
 * available angles of the d2 (an exact scan of the whole index; of the
 * first 256 templates of each class in an index over exact_max
 * templates). The SVMs classify the completed descriptor; the k-NN
 * inside a class of up to exact_max templates is an exact scan over the
 * available d2 angles, its squared distance rescaled by d / available (a
 * larger class searches its kd-forest with the completed descriptor). */
typedef struct mim_index mim_index_t;

typedef struct mim_index_input {
    uint32_t n_templates, n_landmarks;
    const float *landmarks;       /* n_templates * n_landmarks * 3, all present */
    const uint64_t *ids;          /* template ids */
    const char *const *subjects;  /* n_templates labels ("" or NULL: none); NULL: none at all */
    const char *const *poses;     /* likewise */
    const uint32_t *mirror;       /* n_landmarks, the landmark map's mirror table; NULL: none */
    /* The landmark skeleton: each landmark's parent (-1: the root; a tree
     * over all n_landmarks, as mim_landmark_skeleton gives for the 16
     * default landmarks); NULL: none, and no canonical proportions. */
    const int32_t *parent;
} mim_index_input_t;

/* The landmark skeleton of map as mim_index_input_t.parent wants it
 * (parent has map->count entries): 0, or MIM_EUNSUPPORTED for a map that
 * is not the 16 default landmarks (mim_landmark_skeleton), which has none. */
int mim_index_skeleton(const mim_landmark_map_t *map, int32_t *parent);

typedef struct mim_index_options {
    uint32_t features;        /* d; 0 means 60 */
    uint32_t missing_features; /* d2 >= d, angles kept for missing landmarks; 0 means 3 d */
    uint32_t cv_folds;        /* 0 means 5 */
    uint32_t cv_max_samples;  /* cross-validation on at most this many templates; 0 means 1000 */
    uint32_t svm_max_samples; /* each SVM trains on at most this many; 0 means 4000 */
    uint32_t select_max_samples; /* the tree sees at most this many; 0 means 4000 */
    uint32_t exact_max;       /* classes up to this size get an exact k-NN; 0 means 8192 */
    uint32_t checks;          /* kd-forest checks for larger classes; 0 means 128 */
    double C, gamma;          /* both > 0: skip cross-validation and use these */
    /* Noise augmentation: the tree and the SVMs also learn from `augment`
     * copies of every template whose landmarks carry Gaussian noise of
     * sigma = noise x the bodies' scale (the median over templates of the
     * RMS distance of the landmarks from their centroid: 0.43-0.61 m over
     * synth's bodies and poses, so the default 0.025 is about 1.3 cm), each
     * copy also mirrored by the tree. Defaults chosen on the hard set of
     * bench/query_accuracy (bench/RESULTS.md, issue 15). Seeded: the same
     * input gives the same index. */
    double noise;             /* 0 means MIM_INDEX_NOISE_DEFAULT; < 0: no augmentation */
    uint32_t augment;         /* copies per template; 0 means MIM_INDEX_AUGMENT_DEFAULT */
    /* Angle weighting by noise sensitivity (issue 15): the SVMs (and the
     * k-NN vote of mim_index_query) see each kept angle a multiplied by
     * s_a^-weight, s_a = the RMS change of a over the augmentation's noisy
     * copies (an angle between short segments moves more), the factors
     * normalised to RMS 1 over the d descriptor angles. Stored in the index.
     * Needs the augmentation (none without it). The k-NN
     * inside a class, and the distances it reports, stay in radians. */
    double weight;            /* 0 means MIM_INDEX_WEIGHT_DEFAULT; < 0: none; at most 4 */
    /* Shape discriminants (issue 15; shape.c says what and why): the
     * classes as Gaussians of one shared covariance over the landmarks,
     * each frame brought onto each class's mean shape by a similarity,
     * at noise levels 0 .. shape_noise (a fraction of the bodies' RMS
     * radius). A frame's class is theirs unless the SVMs are sure
     * (mim_index_query_options_t.svm_above). Stored in the index. */
    double shape_noise;        /* 0 means MIM_INDEX_SHAPE_NOISE_DEFAULT; < 0: none; at most 1 */
    /* Linear discriminants over all angles (issue 15; lda.c), the default
     * before the shape discriminants, which take precedence when both are
     * there: learnt from the templates and noisy copies at sigma =
     * discriminant_noise x the bodies' scale; whole frames only. Stored in
     * the index. */
    double discriminant_noise; /* > 0: build them (MIM_INDEX_DISCRIMINANT_NOISE_MEASURED was their best); else none */
    /* Proportions (proportions.c): with a landmark skeleton in the input,
     * MIM_INDEX_PROPORTIONS_CANONICAL takes the angles of every frame,
     * template or query, on the frame redrawn with the templates' mean
     * segment lengths and its own segment directions, so that the
     * descriptor, the SVMs and the k-NN do not see whose bones they are
     * (bodies of other proportions in one pose answer alike); the shape
     * discriminants and the completion see the frame as it is (noise:
     * proportions.c). MIM_INDEX_PROPORTIONS_BODY takes each frame as it is
     * everywhere. Stored in the index. Without a skeleton: the body's. */
    int proportions; /* 0 means MIM_INDEX_PROPORTIONS_DEFAULT */
    mim_progress_t *progress; /* fn and ctx set by the caller, run by the build; NULL: quiet */
} mim_index_options_t;

enum { MIM_INDEX_PROPORTIONS_BODY = 1, MIM_INDEX_PROPORTIONS_CANONICAL = 2 };
#define MIM_INDEX_PROPORTIONS_DEFAULT MIM_INDEX_PROPORTIONS_CANONICAL

#define MIM_INDEX_NOISE_DEFAULT 0.025
#define MIM_INDEX_AUGMENT_DEFAULT 4u
#define MIM_INDEX_WEIGHT_DEFAULT 0.5
#define MIM_INDEX_DISCRIMINANT_NOISE_MEASURED 0.04
#define MIM_INDEX_SHAPE_NOISE_DEFAULT 0.06

enum { MIM_CLASSES_LABELS = 0, MIM_CLASSES_KMEANS = 1 };

typedef struct mim_index_report {
    uint32_t n_classes, d, class_source; /* MIM_CLASSES_* */
    double C, gamma, cv_accuracy;        /* cv_accuracy < 0: not cross-validated */
    uint32_t support_vectors;            /* all SVMs together */
    uint32_t exact_classes;              /* classes with an exact k-NN */
    uint32_t augment;                    /* noisy copies per template learnt from (0: none) */
    double noise;                        /* their sigma / the bodies' scale (0: none) */
    double weight;                       /* the angle weighting's power (0: none) */
    double discriminant_noise;           /* the angle discriminants' training noise / the bodies' scale (0: none) */
    double shape_noise;                  /* the shape discriminants' top noise level / the RMS radius (-1: none) */
    uint32_t canonical;                  /* frames seen on canonical proportions (1) or their own (0) */
    mim_select_report_t select;
    double seconds;
} mim_index_report_t;

int mim_index_build(mim_index_t **out, const mim_index_input_t *in, const mim_index_options_t *opt,
                    mim_index_report_t *report, mim_error_t *err);
void mim_index_close(mim_index_t **ix); /* accepts NULL; nulls the pointer */

/* Serialised form: one versioned blob with checksums (malloc'd; caller
 * frees), version 6 (layout: blob.c). Saving an index opened in place
 * first verifies what it had not yet (mim_index_verify), so that a damaged
 * section is never written out under fresh checksums.
 *
 * mim_index_load copies: the index owns everything and the caller may free
 * blob at once. It checks magic, version, sizes and every checksum, and
 * loads every saved kd-forest, before it returns: a damaged blob is
 * MIM_EFORMAT, never a crash. Only the version mim_index_save writes is
 * read: the index is made from the store again (mimic index), so an older
 * blob is MIM_EFORMAT with a message that says to rebuild it.
 *
 * mim_index_open_in_place borrows: a blob at an 8-byte aligned
 * address is used where it is (the store's memory map), and must stay
 * valid and unchanged until mim_index_close. Only the small head is read
 * and verified now (sizes, labels, classes, SVMs, and the checksums of the
 * rest); the templates' rows are verified by chunk, and a class's kd-forest
 * verified and loaded, when a query first needs them, once, by one thread
 * (queries on other threads wait for that class, not for others). A query
 * that meets a damaged section fails with MIM_EFORMAT, as will every later
 * query that needs it; it never reads what did not verify. An unaligned
 * blob is copied (mim_index_load). */
int mim_index_save(const mim_index_t *ix, void **blob, size_t *len, mim_error_t *err);
int mim_index_load(mim_index_t **out, const void *blob, size_t len, mim_error_t *err);
int mim_index_open_in_place(mim_index_t **out, const void *blob, size_t len, mim_error_t *err);
/* Verifies every section not verified yet and makes every class's k-NN
 * index (what an open in place defers to first use): MIM_EFORMAT when some
 * part is damaged. Thread-safe with queries. 0 at once for an index that
 * is not in place. */
int mim_index_verify(const mim_index_t *ix, mim_error_t *err);

typedef struct mim_index_info {
    uint32_t n_templates, n_landmarks, d, d2, n_classes, class_source;
    double C, gamma, cv_accuracy;
    uint32_t augment; /* noisy copies per template the build learnt from (0: none) */
    double noise;     /* their sigma, a fraction of the bodies' scale (0: none) */
    double weight;    /* the angle weighting's power (0: none) */
    double discriminant_noise; /* the linear discriminants' training noise / the bodies' scale (0: none) */
    double shape_noise;        /* the shape discriminants' top noise level / the RMS radius (-1: none) */
    uint32_t canonical;        /* frames seen on canonical proportions (1) or their own (0) */
    /* kd-forests (classes above the exact scan's size) read from the blob
     * and built when it was made or loaded (a forest that would not load
     * is built again) */
    uint32_t forests_loaded, forests_built;
    uint32_t in_place;      /* used in place (mim_index_open_in_place of an aligned blob) */
    uint32_t classes_ready; /* classes verified and with their k-NN index (in place: those used so far) */
} mim_index_info_t;
void mim_index_get_info(const mim_index_t *ix, mim_index_info_t *out);
const char *mim_index_class_name(const mim_index_t *ix, uint32_t cls);
const uint32_t *mim_index_selected(const mim_index_t *ix); /* d2 candidate angles, the descriptor first */

typedef struct mim_index_query_options {
    uint32_t k;                  /* 0 means 1 */
    /* Leave this subject's templates out of the answers and the k-NN vote
     * (NULL: none); the angles, SVMs and discriminants were trained with
     * them, so for a strict held-out test build an index without them. */
    const char *exclude_subject;
    uint32_t checks;             /* kd-forest checks for this query; 0 means the index's */
    /* k-NN vote (issue 15): when the top SVM probability (normalised over
     * the classes) is below vote_below, the vote_k nearest templates (over
     * the weighted descriptor angles; all available kept angles when
     * landmarks are missing) among the vote_classes most probable classes
     * vote, and the class with the largest P(class) x (votes + 1) wins.
     * Defaults chosen on the hard set (bench/RESULTS.md, issue 15). */
    double vote_below;           /* 0 means MIM_INDEX_VOTE_BELOW_DEFAULT; < 0: never */
    uint32_t vote_k;             /* 0 means MIM_INDEX_VOTE_K_DEFAULT; at most 32 */
    uint32_t vote_classes;       /* 0 means MIM_INDEX_VOTE_CLASSES_DEFAULT; at most 8 */
    /* A frame's class (issue 15): the SVMs' when their top probability
     * is at least svm_above, else the discriminants' (the shape
     * discriminants', for any frame with three landmarks or more; else the
     * angle discriminants', for a whole frame; an index without them: the
     * SVMs' and the vote). 0 means MIM_INDEX_SVM_ABOVE_DEFAULT: above 1,
     * always the discriminants', and the SVMs are not evaluated (the
     * answer's probability is then the discriminants' posterior, the
     * softmax of their scores); < 0: never. */
    double svm_above;
} mim_index_query_options_t;

#define MIM_INDEX_VOTE_BELOW_DEFAULT 0.5
#define MIM_INDEX_VOTE_K_DEFAULT 5u
#define MIM_INDEX_VOTE_CLASSES_DEFAULT 3u
#define MIM_INDEX_SVM_ABOVE_DEFAULT 2.0

typedef struct mim_index_hit {
    uint64_t id;
    const char *subject, *pose; /* the template's labels ("" when none); valid while ix lives */
    float distance;             /* L2 over the selected angles, radians */
} mim_index_hit_t;

typedef struct mim_index_answer {
    uint32_t cls;
    double probability; /* the class's: the SVMs' normalised Platt probability, or the discriminants' posterior */
    uint32_t missing;   /* landmarks missing in the frame */
    uint32_t n_hits;    /* <= k */
} mim_index_answer_t;

/* Completion of a frame's missing landmarks (issue 29; shape_complete.c):
 * the pose classes' Gaussians over the landmarks (the shape
 * discriminants), each one's conditional mean of the missing coordinates
 * given the present ones, mixed by the classes' posteriors. positions and
 * present as for mim_index_query; out gets all
 * n_landmarks (present ones unchanged); cls (may be NULL) the most
 * probable class. No scan of the templates. Errors: MIM_ENOTFOUND (an
 * index without shape discriminants: one class, or built with
 * shape_noise < 0), MIM_EINVAL (fewer than 3 landmarks present, or a frame
 * with no shape), MIM_ENONFINITE. Thread-safe on one index. */
int mim_index_complete(const mim_index_t *ix, const float *positions, const uint8_t *present, float *out,
                       uint32_t *cls, mim_error_t *err);

/* One frame: positions 3 * n_landmarks, present n_landmarks flags (NULL: all
 * present). hits has room for k. Thread-safe on one index: it only reads
 * the index, takes no lock, and neither seeds nor draws random numbers. */
int mim_index_query(const mim_index_t *ix, const float *positions, const uint8_t *present,
                    const mim_index_query_options_t *opt, mim_index_answer_t *ans, mim_index_hit_t *hits,
                    mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
