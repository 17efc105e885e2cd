/* sample/ internals shared between its files (not installed). */
#ifndef MIM_SAMPLE_INTERNAL_H
#define MIM_SAMPLE_INTERNAL_H

#include "mim_sample.h"

#include <jansson.h>

/* The 34 joint labels of the files, "A.head" ... "B.neck", as a JSON
 * array (a new reference; NULL when out of memory): the samples' header
 * and the annotations name their joints with it, and their readers check
 * against it. */
json_t *mim__pairs_joint_labels(void);

/* The chi-squared cost between shape contexts (Belongie et al.), the mean
 * over n joints of 0.5 sum (a - b)^2 / (a + b) over their bins: D_S in 3D
 * and the shape density's distance in 2D. */
double mim__shape_cost(const float *a, const float *b, int n, int bins);

/* ---- 2D pose-pairs (pairs2d.c): the likelihood's comparisons ---- */
#define MIM__SC2_R 5
#define MIM__SC2_A 12
#define MIM__SC2_BINS (MIM__SC2_R * MIM__SC2_A)
/* Log-polar shape contexts of normalised 2D points (5 radial bins from
 * 1/8 to 2 of the mean joint distance, 12 angular; each count shared
 * linearly between neighbouring bins so that the cost is continuous). */
void mim__pairs2d_shape_contexts(const double *p, float sc[MIM_PAIR_JOINTS][MIM__SC2_BINS]);

/* ---- the evidence's items, for the likelihood (evidence.c) ---- */
struct mim_pairs_evidence;
const double *mim__evidence_points(const struct mim_pairs_evidence *e, uint32_t i); /* normalised 34 [x, y] */
const double *mim__evidence_dir(const struct mim_pairs_evidence *e, uint32_t i);    /* unit view, local frame */
const mim_ic_t *mim__evidence_ic(const struct mim_pairs_evidence *e, uint32_t i);
const float *mim__evidence_sc(const struct mim_pairs_evidence *e, uint32_t i);      /* NULL unless shape */

#endif
