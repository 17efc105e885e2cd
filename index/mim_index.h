/* mimic index: pose recognition from landmarks (seed 000, Sections 3.2-3.3).
 *
 * The pose descriptor is a set of angles: at landmark j, the angle between the
 * segments j->i and j->k, for every j and every unordered pair {i, k} of the
 * other landmarks (n (n-1) (n-2) / 2 candidates: 1680 for 16 landmarks). The
 * angles do not change when the landmark set is rotated, translated or
 * uniformly scaled. A decision tree trained on pose labels, with every sample
 * also mirrored left<->right (paper §3.2), selects the d most salient angles.
 *
 * Computation over caller-owned arrays; nothing here opens the store. */
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

#ifdef __cplusplus
}
#endif
#endif
