/* Internal to index/: the recognition index object shared by build, query
 * and the blob reader/writer. */
#ifndef MIM_INDEX_INTERNAL_H
#define MIM_INDEX_INTERNAL_H

#include "mim_index.h"

#include <flann/flann.h>
#include <pthread.h>
#include <stdatomic.h>

/* A trained one-vs-rest SVM in dense form: decision value
 * f(x) = sum_i coef[i] exp(-gamma |x - sv_i|^2) - rho, positive for the
 * class; P(class | x) = 1 / (1 + exp(prob_a f + prob_b)) (Platt). */
typedef struct {
    uint32_t n_sv;
    double *sv;   /* n_sv * d */
    double *coef; /* n_sv */
    double rho, prob_a, prob_b;
} mim__svm_t;

struct mim_index {
    uint32_t n_landmarks, d, n_templates, n_classes, n_strings, class_source;
    double C, gamma, cv_accuracy;
    uint32_t exact_max, checks;
    uint32_t augment;      /* noisy copies per template in the build (0: none) */
    double noise;          /* their sigma / the bodies' scale (0: none) */
    double weight;         /* the weighting's power (0: none) */
    float *w;              /* d2 angle weights (all 1 without weighting) */
    uint32_t d2;           /* d plus the extra angles kept for frames with missing landmarks */
    uint32_t *selected;    /* d2 candidate angles, ranked: the descriptor is the first d */
    char **strings;        /* label strings; strings[0] = "" */
    uint32_t *class_name;  /* n_classes: string index */
    uint32_t *class_start; /* n_classes + 1: templates are stored grouped by class */
    uint64_t *ids;         /* n_templates */
    uint32_t *subject;     /* n_templates: string index */
    uint32_t *pose;        /* n_templates: string index */
    float *desc;           /* n_templates * d, radians */
    float *extra;          /* n_templates * (d2 - d): the further ranked angles */
    mim__svm_t *svm;       /* n_classes (all n_sv 0 when there is one class) */
    flann_index_t *flann;  /* n_classes (NULL until its class is first used, in place) */
    int *flann_exact;      /* n_classes */
    _Atomic uint32_t forests_loaded, forests_built; /* kd-forests read from the blob / built (the rest: exact) */
    double discriminant_noise; /* the discriminants' training noise / the bodies' scale (0: none) */
    struct mim__lda {
        uint32_t nf, n_classes; /* 0: none */
        float *mean;            /* nf: the mean of the class means */
        float *g;               /* n_classes * nf: S^-1 mu_c */
        double *b;              /* n_classes */
    } lda;                      /* in the blob's head when in place (borrowed or own) */
    struct mim__shape {         /* shape.c (issue 15); n_classes 0: none */
        uint32_t L, n_classes;
        double noise_max;       /* the top noise level, shape units (a fraction of the RMS radius) */
        double *mu;             /* n_classes * 3L: the class mean shapes, centred, unit RMS radius */
        double *S;              /* 3L * 3L: the shared within-class covariance of the aligned shapes, shrunk */
        int borrowed;           /* mu and S point into the blob (in place) */
        double *V, *lam, *Vmu;  /* S's eigenvectors (columns), eigenvalues, V^T mu_c: made at build and open */
        double *U;              /* 3 * 3L: V^T of a unit translation along x, y, z */
    } shape;
    struct mim__proportions {   /* proportions.c; on 0: frames as they are */
        uint32_t on;
        int32_t parent[MIM_LANDMARKS_MAX]; /* the landmark skeleton: each landmark's parent, -1 the root */
        float length[MIM_LANDMARKS_MAX];   /* the mean length of the segment to its parent (root: 0) */
    } prop;
    /* In place (blob.c): the arrays above, the label
     * strings and the SVMs' arrays point into the blob, which is not ours
     * (borrowed) or is our own aligned copy (own); lazy says which sections
     * are verified and which classes are ready. NULL lazy: all of it is. */
    int borrowed;
    void *own;
    struct mim__lazy *lazy;
};

/* blob.c: the lazily verified sections of an index used in place.
 * Per chunk of `rows` templates, "base" covers ids, subject, pose and the
 * descriptor rows, "extra" the further angles; per class, its rows (base)
 * verified and its k-NN index (forest or exact scan) made, once. States:
 * 0 not yet, 1 ready, 2 damaged (sticky). */
typedef struct mim__lazy {
    uint32_t rows, n_chunks;
    const unsigned char *ck;     /* n_chunks x (u64 base, u64 extra) checksums, in the blob's verified head */
    _Atomic uint8_t *base, *extra; /* n_chunks each */
    _Atomic uint8_t *cls;          /* n_classes: 0, 1, 2 rows damaged, 3 forest damaged */
    pthread_mutex_t *lock;         /* n_classes: the one thread that readies a class */
    uint32_t n_locks;              /* initialised */
    const unsigned char *ftab;     /* the forests' table in the head, nf entries */
    uint32_t nf;
    const unsigned char **forest;  /* n_classes: the saved forest's bytes in the blob (NULL: none) */
    uint64_t *forest_len, *forest_ck;
} mim__lazy_t;

/* 0 when templates lo..hi-1 (their base, and extra when asked) are
 * verified, verifying what is not yet; MIM_EFORMAT (with a message) when
 * damaged. No-op for an index that is not lazy. */
int mim__rows_ready(const mim_index_t *ix, uint32_t lo, uint32_t hi, int extra, mim_error_t *err);
/* 0 when class c's rows are verified and its k-NN index is made (once,
 * by one thread; the others wait for it). */
int mim__class_ready(const mim_index_t *ix, uint32_t c, mim_error_t *err);
/* One class's k-NN index from saved forest bytes (NULL: none) or built
 * (model.c). */
int mim__class_knn(mim_index_t *ix, uint32_t c, const void *bytes, size_t len, mim_error_t *err);
struct FLANNParameters mim__flann_params(const mim_index_t *ix, int exact);
/* blob.c: parses a blob in place (p 8-byte aligned and lasting as long
 * as ix); the head is verified now, the rest lazily. check_head 0: the
 * head's checksum is not checked (the fuzz harness's sealing). */
int mim__index_parse(mim_index_t **out, const unsigned char *p, size_t len, int check_head, mim_error_t *err);
void mim__lazy_free(mim_index_t *ix);
void mim__index_seal(unsigned char *p, size_t len); /* tests, fuzz: every checksum made right */

/* Every random choice of an index build (samples, folds, k-means++ seeds,
 * the folds of the Platt fits) draws from core's generator (mim_rng_t),
 * seeded with this and a stream of its own, so the same store always gives
 * the same index. Nothing here touches libc's rand(). */
#define MIM__INDEX_SEED 0x6d696dULL

/* lda.c: linear discriminants over all angles (issue 15). Build: from in's
 * templates of classes cls (input order, nc classes) and noisy copies at
 * sigma; none (nf 0) for one class or constant angles. */
typedef struct mim__lda mim__lda_t;
#define MIM__LDA_TEMPLATES 1024u /* templates sampled, over all classes (at least 4 a class) */
#define MIM__LDA_COPIES 4u       /* noisy copies of each */
#define MIM__LDA_SHRINK 0.5      /* of the mean variance added to S's diagonal (bench/RESULTS.md) */
int mim__lda_build(mim__lda_t *out, const mim_index_input_t *in, const uint32_t *cls, uint32_t nc, double sigma,
                   mim_error_t *err);
/* The class of a whole frame (positions of n_landmarks), -1 when there
 * are no discriminants or an angle is undefined; score (n_classes) gets
 * every class's discriminant (a log-likelihood up to a constant). */
int64_t mim__lda_class(const mim__lda_t *m, const float *positions, uint32_t n_landmarks, double *score);
void mim__lda_free(mim__lda_t *m);

/* cholesky.c: the lower-triangular Cholesky factor of the n x n row-major
 * a in place (0, or -1 when a is not positive definite); x = L^-1 x
 * returning |x|^2 afterwards (forward substitution); x = (L L^T)^-1 x. */
int mim__cholesky(double *a, uint32_t n);
double mim__chol_forward(const double *l, uint32_t n, double *x);
void mim__chol_solve(const double *l, uint32_t n, double *x);

/* shape.c: the least-squares similarity y = s R (x - cx) + ct that brings
 * the landmarks x (3L doubles) onto target over the present ones (NULL:
 * all), and its application to the present landmarks (the others left). */
typedef struct mim__similarity {
    double s, R[3][3], cx[3], ct[3];
} mim__similarity_t;
void mim__similarity_fit(const double *target, const double *x, const uint8_t *present, uint32_t L,
                         mim__similarity_t *f);
void mim__similarity_apply(const mim__similarity_t *f, const double *x, const uint8_t *present, uint32_t L,
                           double *y);

/* shape.c: the classes as Gaussians in landmark space (issue 15). Build:
 * from in's templates of classes cls (input order, nc classes), at most
 * MIM__SHAPE_TEMPLATES of them (spread over the classes); none
 * (n_classes 0) for one class or no shape. */
typedef struct mim__shape mim__shape_t;
#define MIM__SHAPE_TEMPLATES 65536u /* templates sampled, over all classes */
#define MIM__SHAPE_GPA 4            /* rounds of generalised Procrustes for the class means */
#define MIM__SHAPE_SHRINK 0.1       /* the least shrinkage intensity towards the mean variance (bench/RESULTS.md) */
#define MIM__SHAPE_LEVELS 4         /* noise levels 0 .. noise_max */
int mim__shape_build(mim__shape_t *out, const mim_index_input_t *in, const uint32_t *cls, uint32_t nc,
                     double noise_max, mim_error_t *err);
/* V, lam and Vmu from L, n_classes, mu and S (after loading them): 0,
 * MIM_ENOMEM, or MIM_EFORMAT when S is not positive definite. */
int mim__shape_prepare(mim__shape_t *m);
/* The class of a frame (positions of L landmarks, present may be NULL:
 * all; a NaN position counts as missing), -1 when there are no shape
 * discriminants or fewer than 3 landmarks; score (n_classes) gets every
 * class's log-likelihood (-inf for one that cannot be scored). */
int64_t mim__shape_class(const mim__shape_t *m, const float *positions, const uint8_t *present, double *score);
/* The frame's usable landmarks: here[l] (present and finite), idx the
 * coordinates (3l + c) of those, x all 3L of positions in double (0 where
 * not here); returns how many coordinates are here. */
uint32_t mim__shape_present(uint32_t L, const float *positions, const uint8_t *present, uint8_t *here, uint32_t *idx,
                            double *x);
void mim__shape_free(mim__shape_t *m);
/* shape_complete.c (issue 29): the frame's missing landmarks as the
 * classes' Gaussians' conditional mean given the present ones, mixed by
 * the classes' posteriors; out gets all L (present ones unchanged), cls
 * the most probable class, scores (n_classes; NULL: not wanted) every
 * class's log-likelihood as mim__shape_class gives it. 0, or -1 as
 * mim__shape_class (none, fewer than 3 landmarks) or out of memory. */
int mim__shape_complete(const mim__shape_t *m, const float *positions, const uint8_t *present, float *out,
                        uint32_t *cls, double *scores);

/* proportions.c: canonical proportions. check: 0 when parent (L
 * entries) is a tree over the L landmarks (one root, -1). build: the
 * skeleton and the mean segment lengths of in's templates (in->parent not
 * NULL): MIM_EINVAL when it is not a tree, or a segment has length 0 in
 * every template. apply: out (3L) = the frame redrawn on the canonical
 * lengths (lost landmarks, present 0 or not finite, kept as they are). */
typedef struct mim__proportions mim__proportions_t;
int mim__proportions_check(const int32_t *parent, uint32_t L);
int mim__proportions_build(mim__proportions_t *p, const mim_index_input_t *in, mim_error_t *err);
void mim__proportions_apply(const mim__proportions_t *p, uint32_t L, const float *pos, const uint8_t *present,
                            float *out);

/* classes.c: up to per_class templates of each class (cls, n templates,
 * nc classes), spread evenly over its templates in input order; their
 * indices into pick (n long), the count returned. */
uint32_t mim__class_sample(const uint32_t *cls, uint32_t n, uint32_t nc, uint32_t per_class, uint32_t *pick);

/* classes.c: k-means on rows x (n x f, NaN = unknown) into k clusters. */
int mim__kmeans(const float *x, uint32_t n, uint32_t f, uint32_t k, uint32_t *assign, mim_error_t *err);
uint32_t mim__kmeans_k(uint32_t n);

/* svm.c */
typedef struct {
    const double *x;     /* n * d */
    const uint32_t *y;   /* class per row */
    const uint32_t *group; /* subject per row (folds), NULL: none */
    uint32_t n, d, n_classes, n_groups;
} mim__svm_data_t;
int mim__svm_train_all(const mim__svm_data_t *data, const mim_index_options_t *opt, mim__svm_t *out,
                       double *C, double *gamma, double *cv_accuracy, mim_error_t *err);
/* Decision value over the features with mask[f] != 0 (NULL: all), the
 * partial squared distance rescaled by d / available. */
double mim__svm_decision(const mim__svm_t *m, double gamma, const double *x, const uint8_t *mask, uint32_t d);
double mim__svm_probability(const mim__svm_t *m, double f);
void mim__svm_free(mim__svm_t *m);

/* forest.c: a kd-forest as bytes (malloc'd) and back. Load returns NULL
 * when the bytes cannot be loaded (the caller builds the forest instead);
 * points must outlive the forest. */
int mim__forest_save(flann_index_t forest, void **bytes, size_t *len, mim_error_t *err);
flann_index_t mim__forest_load(const void *bytes, size_t len, float *points, uint32_t rows, uint32_t cols);

/* model.c: the per-class FLANN indexes of a filled index, built. */
int mim__index_build_knn(mim_index_t *ix, mim_error_t *err);

#endif
