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

/* 0, or MIM_ENONFINITE naming the first joint (of 34, dim coordinates
 * each) that is not finite (ic.c). */
int mim__joints_finite(const double *joints, int dim, mim_error_t *err);

/* The edges of the Delaunay tetrahedralisation of n (4 to 34) distinct
 * points (3 doubles each), set in have[i][j], i < j: 0, or -1 when no
 * margin proves the answer (qhull's to find) (delaunay.c). */
int mim__delaunay3_edges(const double *pts, uint32_t n, uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS]);
/* mim_ic_build by qhull alone (ic.c): what the above must agree with. */
int mim__ic_build_qhull(const double *joints, int dim, mim_ic_t *out, mim_error_t *err);

/* A pose-pair samples line (samples_file.c) in the form mimic writes it,
 * read without jansson: 1, or 0 for jansson to read (or refuse). */
int mim__pairs_line_fast(const char *line, size_t n, double *joints, double *log_density);

/* The joint pair (i, j), i < j, among the 561 taken row by row. */
#define MIM__JOINT_PAIRS (MIM_PAIR_JOINTS * (MIM_PAIR_JOINTS - 1) / 2)
static inline int mim__pair_index(int i, int j) { return i * (2 * MIM_PAIR_JOINTS - i - 1) / 2 + (j - i - 1); }
/* The 561 pairs' distances (shape_context.c). */
void mim__pair_distances(const double *p, double *len);
/* eq. 8's weight of an edge of length len (distance.c). */
static inline double mim__ic_weight(double len, double beta) { return 1.0 / (len > beta ? len : beta); }

/* Loops that coverage runs for every truth and sample, made twice: for
 * AVX2 and FMA where the processor has them (chosen as the library
 * loads), and for any x86-64. On static functions only (compilers differ
 * on clones called from another file), each called by the exported one.
 * Only bounds use it: what they compute carries its own allowance for
 * rounding, so that either gives a bound. */
#if !defined(MIM__VECTOR_CLONES) && defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define MIM__VECTOR_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#elif !defined(MIM__VECTOR_CLONES)
#define MIM__VECTOR_CLONES
#endif
/* The same with a clone for AVX-512 too (x86-64-v4), for D_S's rows'
 * angles, whose loop over 40 lanes takes 3 steps of 16 in place of 5 of
 * 8 (24 % less time in it where the processor has AVX-512; D_I's loops
 * were slower with it). */
#if !defined(MIM__WIDE_CLONES) && defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define MIM__WIDE_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#elif !defined(MIM__WIDE_CLONES)
#define MIM__WIDE_CLONES MIM__VECTOR_CLONES
#endif

/* 8 floats as one vector (GCC's and clang's vector extensions: one AVX
 * register, or two SSE ones), and their bits, for masks: for loops whose
 * lanes the compilers do not find alone. Only inside functions (as an
 * argument or result it would change the ABI between the clones). */
typedef float mim__v8f __attribute__((vector_size(8 * sizeof(float))));
typedef int32_t mim__v8i __attribute__((vector_size(8 * sizeof(int32_t))));

/* ---- 3D shape contexts (shape_context.c; D_S) ---- */
#define MIM__SC_R 5  /* radial bins */
#define MIM__SC_AZ 8 /* azimuth */
#define MIM__SC_EL 4 /* elevation */
void mim__shape_contexts(const double *p, float sc[MIM_PAIR_JOINTS][MIM_SC_BINS]);
/* The same a joint at a time (for the scan's histograms where no bound
 * passes). What the joints share comes first: each joint pair's (i < j,
 * row by row) distance and elevation (begin), then its radial bin
 * coordinate and the elevation's cosine (finish); p must outlive w.
 * begin_lazy takes the distances and each pair's up component alone,
 * finish_lazy the radial bins' range, and joint_ready the elevations,
 * coordinates and cosines of joint i's pairs (begin's and finish's
 * values) before mim__sc_joint(i). */
typedef struct mim__sc_pairs {
    const double *p;
    double r[MIM__JOINT_PAIRS], el[MIM__JOINT_PAIRS], fr[MIM__JOINT_PAIRS], cos_el[MIM__JOINT_PAIRS];
    double r0, r1;                  /* the radial bins' log range */
    double up[MIM__JOINT_PAIRS];    /* each pair's vector's up component */
    uint8_t made[MIM__JOINT_PAIRS]; /* joint_ready: el, fr, cos_el made */
} mim__sc_pairs_t;
void mim__sc_pairs_begin(const double *p, mim__sc_pairs_t *w);
void mim__sc_pairs_begin_lazy(const double *p, mim__sc_pairs_t *w);
void mim__sc_pairs_finish(mim__sc_pairs_t *w);
void mim__sc_pairs_finish_lazy(mim__sc_pairs_t *w);
void mim__sc_pairs_joint_ready(mim__sc_pairs_t *w, int i);
void mim__sc_joint(const mim__sc_pairs_t *w, int i, float sc[MIM_SC_BINS]);

/* A joint's row, for D_S's aligned bound: its pairs side by side
 * (MIM__SC_ROW lanes, so that they vectorise), in floats, made from the
 * joints alone, so that a joint's bound needs no other joint's pairs.
 * coords: a pose-pair's joints split by coordinate (the padding 0). */
#define MIM__SC_ROW 40
typedef struct mim__sc_coords {
    double x[MIM__SC_ROW], y[MIM__SC_ROW], z[MIM__SC_ROW];
} mim__sc_coords_t;
void mim__sc_coords(const double *p, mim__sc_coords_t *c);
/* Row i: for each joint j, the pair's radial bin coordinate (from fr, the
 * 561 of mim__sc_pair_radii; -2, in no bin, for j = i and the padding),
 * j's elevation bin coordinate seen from i (both as binning clamps them),
 * its azimuth bin coordinate (mim__sc_bound_azimuth's) and the
 * elevation's cosine. */
typedef struct mim__sc_row {
    float fr[MIM__SC_ROW], fe[MIM__SC_ROW], fa[MIM__SC_ROW], cosel[MIM__SC_ROW];
} mim__sc_row_t;
/* At most how far the rows' elevation coordinates (bins) and cosines lie
 * from those of libm's asin(up / r) and its cosine, the coordinates both
 * clamped: coverage_bounds.c allows for it. */
#define MIM__BOUND_EL_COORD_ERR 4e-6
#define MIM__BOUND_COS_ERR 1e-6
void mim__sc_row(const mim__sc_coords_t *c, const float *fr, int i, mim__sc_row_t *row);
/* The row's histogram, in floats, laid out as MIM__SC_WORK: azimuth
 * innermost (a histogram of mim__shape_contexts has elevation innermost,
 * (r * MIM__SC_AZ + a) * MIM__SC_EL + e). */
#define MIM__SC_WORK(r, e, a) (((r) * MIM__SC_EL + (e)) * MIM__SC_AZ + (a))
void mim__sc_row_histogram(const mim__sc_row_t *row, float sc[MIM_SC_BINS]);
/* The azimuth bin coordinate of the vector (x, ., z), within
 * MIM__BOUND_AZ_COORD_ERR bins of (atan2(z, x) + pi) / 2pi 8 - 1/2. */
#define MIM__BOUND_AZ_COORD_ERR 4e-6
float mim__sc_bound_azimuth(float x, float z);
/* One bin's chi-squared term: 0.5 (x - y)^2 / (x + y), 0 for empty bins. */
static inline double mim__chi_term(double x, double y) { return x + y > 0 ? 0.5 * (x - y) * (x - y) / (x + y) : 0.0; }

/* Their sums over bins, whose cost bounds D_S from below (coverage_bounds.c).
 * fr: the joint pairs' radial bin coordinates as floats, clamped as
 * binning clamps them (which a rigid motion keeps). From them the
 * histograms summed over azimuth and elevation (rad: 34 x MIM__SC_R), in
 * double: what mim__shape_contexts' histograms sum to in exact
 * arithmetic; and the same sums of a computed histogram. */
void mim__sc_pair_radii(const double *p, float *fr);
void mim__sc_radial(const float *fr, double *rad);
void mim__sc_histogram_marginals(const float sc[MIM_PAIR_JOINTS][MIM_SC_BINS], double *rad);

/* ---- work on threads (parallel.c) ---- */
/* Runs fn(ctx, w) for w = 0 .. threads - 1 (0 means 1), w 0 on the calling
 * thread and the others on threads of their own, and returns when all are
 * done. fn takes its share from a counter in ctx, so that a thread that
 * cannot be started only leaves its share to the others. */
void mim__parallel(uint32_t threads, void (*fn)(void *ctx, uint32_t worker), void *ctx);

/* ---- alignment over any points (distance.c) ---- */
/* mim_sample_align over n points. */
void mim__align_points(const double *a, const double *b, int n, int dim, double *out);
/* mim_sample_align (3D) in two steps, for one pose-pair against many:
 * each pose-pair's centroid c and its joints less it p, made once; then
 * b (its joints less its centroid, bc) onto a. mim_sample_align (3D) is
 * the two in turn, so either gives the same bits. */
typedef struct mim__centred {
    double c[3], p[3 * MIM_PAIR_JOINTS];
} mim__centred_t;
void mim__align_centre(const double *p, mim__centred_t *out);
void mim__align_centred(const mim__centred_t *a, const double *bc, double *out);
/* The 24 limb joints (x y z) of pose-pair p, A's then B's, or B's then A's
 * (swap 1). */
void mim__limb_joints(const double *p, int swap, double *out);

/* ---- lower bounds of D_I, D_C, D_S and LIMBS (coverage_bounds.c) ---- */
/* Floats per sample of a metric's first bound's features (a multiple of
 * 8), and of all its features (D_S's aligned bound's after them). */
uint32_t mim__bound_dim(mim_sample_metric_t metric);
uint32_t mim__bound_stride(mim_sample_metric_t metric);
/* The features of a sample (b of mim_sample_distance; stride floats) or
 * of a truth (a, truth 1; dim floats). */
void mim__bound_features(mim_sample_metric_t metric, const mim_pair_prep_t *p, int truth, float *f);
/* What a pose-pair adds to its bounds' slack (its rounding grows with its
 * size and its distance from the origin). */
double mim__bound_slack(mim_sample_metric_t metric, const mim_pair_prep_t *p);
/* lb[t k + j] <= D(a_t, b_j) as mim_sample_distance computes it, for the
 * k samples' features fb (k x stride) against n truths' fa (n x dim, n up
 * to MIM__BOUND_TRUTHS); slack[t]: a_t's mim__bound_slack plus the
 * samples' largest. */
#define MIM__BOUND_TRUTHS 16
void mim__bound_lower(mim_sample_metric_t metric, const float *fa, uint32_t n, const float *fb, uint32_t k,
                      const double *slack, float *lb);
/* What D_S's aligned bound takes from truth a, made once a truth: its
 * histograms (laid out as the rows'), their sums over azimuth and
 * elevation (its first bound's features), and the gains, which it learns
 * from each sample, the joints in the order of the sample before. One
 * for each truth and thread. */
#define MIM__SC_RADIAL ((MIM_PAIR_JOINTS * MIM__SC_R + 7) / 8 * 8)
typedef struct mim__shape_truth {
    float sc[MIM_PAIR_JOINTS][MIM_SC_BINS];
    float rad[MIM__SC_RADIAL];
    double gain[MIM_PAIR_JOINTS];
    int order[MIM_PAIR_JOINTS];
} mim__shape_truth_t;
void mim__shape_truth(const mim_pair_prep_t *a, mim__shape_truth_t *ta);
/* D_S of sample b against truth a, b aligned onto a (bb: from
 * mim__align_centred, as mim_sample_align makes it; fb: b's features), as
 * mim_sample_distance gives it, to the bit (*exact 1); or a lower bound of
 * it above best (*exact 0) as soon as one turns up: the joints'
 * histograms in floats a joint at a time, with their first bound's terms
 * for the joints not yet made; the scan's histograms only where no bound
 * passes best. One alignment serves D_I and D_S. */
double mim__shape_distance_aligned(const mim_pair_prep_t *a, mim__shape_truth_t *ta, const double *bb, const float *fb,
                                   double slack, double best, int *exact);
/* D_I of sample b (bb and fb as above) against truth a (fa: its
 * features), as mim_sample_distance gives it, to the bit (*exact 1), or a
 * lower bound of it above best (*exact 0): eq. 8 in floats. */
double mim__ic_distance_aligned(const mim_pair_prep_t *a, const float *fa, const mim_pair_prep_t *b, const double *bb,
                                const float *fb, double slack, double best, int *exact);
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
