/* mimic sample: seed 002 (Yin et al. 2019, "A sampling approach to
 * generating closely interacting 3D pose-pairs from 2D annotations").
 * This part: pose-pairs, interaction coordinates (Section 4.3), the three
 * dissimilarities of Section 6 (D_I, D_C, D_S) and the coverage measure
 * (eq. 13). The MCMC sampler, annotations and completion come on top.
 *
 * Computation over caller arrays, like transfer/ and index/: nothing here
 * opens a file or prints.
 *
 * A pose-pair is 2 x 17 joints, person A's then person B's, each in
 * mim_sample_joint_names order (the 16 landmarks of DESIGN.md, then neck),
 * positions x y z (3D) or x y (2D) per joint, in metres for 3D pairs.
 *
 * Choices where the paper is silent (and why):
 * - Delaunay through qhull ("d Qt Qbb Qz"): Qt triangulates non-simplicial
 *   facets so that every edge of a cospherical set is used; Qz adds a point
 *   at infinity for cospherical input. Joints at one place (a CMU hip joint
 *   and its parent share a point) are merged before triangulating and
 *   joined by an edge after, so qhull never sees duplicates. 3D input that
 *   is flat (both people in one plane) is joggled (QJ) as a fallback: qhull's
 *   generator keeps its state in its own context, so the result is the
 *   same on every run and no process-wide state is touched.
 * - Comparing two pose-pairs in 3D (D_I, D_C, D_S): the second is first
 *   brought onto the first by the least-squares rigid motion over the 34
 *   joints (Kabsch, as the paper does in 2D with M of eq. 9): samples live
 *   in a local frame, ground truth in the world.
 * - D_C: the root mean square of the 34 joint distances after that motion.
 * - LIMBS (not the paper's; the figure lifting is judged by): the mean
 *   distance of each person's 12 limb joints (shoulders, elbows, wrists,
 *   hips, knees, ankles), the rigid fit made over those 24 joints only
 *   (head, spine and pelvis are not fitted: what the measure sees is what
 *   the fit sees, so that D_C's centroid-distance bound holds for it), and
 *   the better of the two orders of the two people (the truth does not say
 *   which of a sample's people is which).
 * - D_S: 3D shape contexts (Belongie et al. 2002, the paper's [45]): for
 *   each joint, a log-polar histogram of where the other 33 joints lie (5
 *   radial bins, log-spaced from 1/8 to 2 of the pair's mean joint
 *   distance; 8 azimuth and 4 elevation bins about the world's up axis;
 *   each count shared linearly between neighbouring bins, so that the
 *   measure does not jump when a joint sits on a bin's edge);
 *   the cost of a joint is the chi-squared distance between its two
 *   histograms, and D_S the mean over the joints (correspondence is known:
 *   joint i is joint i).
 * - d_I (eq. 8) with beta = 0.05 (the paper's default; metres in 3D). */
#ifndef MIM_SAMPLE_H
#define MIM_SAMPLE_H

#include "mim_core.h"

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MIM_PAIR_PERSON_JOINTS 17
#define MIM_PAIR_JOINTS (2 * MIM_PAIR_PERSON_JOINTS)
/* head, chest, pelvis, l_shoulder, r_shoulder, l_elbow, r_elbow, l_wrist,
 * r_wrist, l_hip, r_hip, l_knee, r_knee, l_ankle, r_ankle, spine, neck */
extern const char *const mim_sample_joint_names[MIM_PAIR_PERSON_JOINTS];
/* The index of a joint by its name in mim_sample_joint_names; -1 when none. */
int mim_sample_joint_index(const char *name);

/* ---- a person's joints in a motion file (joints.c) ---- */
/* out[k]: the index among the motion's n joint names of joint k
 * (mim_sample_joint_names order). custom_json (NULL: none) is a user's map,
 * {"head": "Head", "chest": "Spine1", ...}, all 17 keys; otherwise the
 * names are matched (case-insensitively) against the schemes mimic knows:
 * CMU/Biovision (Hips, LeftUpLeg, Spine1, Neck ...), MakeHuman (root,
 * upperleg01.L, spine01, neck01 ...), ASF (lfemur, thorax, lowerneck ...)
 * and the short lower-case one (root, lhip, lknee, lowerneck ...). scheme
 * (may be NULL) gets the scheme's name. Errors, one line naming origin:
 * MIM_ENOTFOUND (a joint missing: the nearest scheme and the joint, or a
 * map's name the motion lacks), MIM_EFORMAT (a malformed map, with line
 * and column). */
int mim_pair_joint_map(const char (*names)[64], uint32_t n, const char *custom_json, const char *origin,
                       int32_t out[MIM_PAIR_PERSON_JOINTS], const char **scheme, mim_error_t *err);

/* The metres per unit of a motion file whose person spans `span` units
 * from head to the middle of the ankles: metres (0.8..2.5), CMU's ASF
 * unit of 0.0254/0.45 m (14..45), inches (45..100), centimetres
 * (100..250), millimetres (800..2500). MIM_ENOTFOUND outside them (the
 * caller asks for the unit). name (may be NULL) gets the unit's name. */
int mim_pair_unit_guess(double span, double *metres_per_unit, const char **name);

/* ---- interaction coordinates (ic.c; Section 4.3) ---- */
/* At most every pair of the 34 joints. */
#define MIM_IC_MAX_EDGES (MIM_PAIR_JOINTS * (MIM_PAIR_JOINTS - 1) / 2)
typedef struct mim_ic {
    int dim;          /* 2 or 3 */
    uint32_t n_edges; /* edges (i, j), i < j, sorted */
    uint8_t edge[MIM_IC_MAX_EDGES][2];
} mim_ic_t;

/* The Delaunay triangulation (dim 2) or tetrahedralisation (dim 3) of a
 * pose-pair's 34 joints (dim doubles each): its edges. Errors, one line:
 * MIM_EINVAL (dim), MIM_ENONFINITE (a NaN joint, naming it), MIM_EFORMAT
 * (the joints span no triangle / tetrahedron: qhull's reason), MIM_ENOMEM. */
int mim_ic_build(const double *joints, int dim, mim_ic_t *out, mim_error_t *err);

/* ---- dissimilarities (distance.c; eq. 8 and Section 6) ---- */
#define MIM_IC_DEFAULT_BETA 0.05
/* d_I of eq. 8 between pose-pairs a and b (34 joints, dim each) with their
 * own triangulations ta and tb (mim_ic_build of each): for each
 * triangulation, the sum over its edges of |u_ij(a) - u_ij(b)| weighted by
 * 1 / max(beta, |u_ij|) of that triangulation's pair, divided by the sum
 * of the weights; the two halves added. Symmetric, 0 for a == b. beta <= 0
 * means MIM_IC_DEFAULT_BETA. As in eq. 8, no alignment: see
 * mim_sample_distance for pairs in different frames. */
double mim_ic_distance(const double *a, const mim_ic_t *ta, const double *b, const mim_ic_t *tb, double beta);

/* The least-squares rigid motion (rotation, no reflection, and translation)
 * that brings b onto a over the 34 joints (dim 2 or 3), applied: b_aligned. */
void mim_sample_align(const double *a, const double *b, int dim, double *b_aligned);
/* The same fit in 3D, each joint weighted by use[i] (NULL: all 34 alike;
 * 0: left out; at least 3 weighted joints not on one line for a unique
 * answer), as a rotation R (row-major) and a translation t: a_i ~ R b_i + t. */
void mim_sample_rigid_fit(const double *a, const double *b, const uint8_t *use, double R[9], double t[3]);

typedef enum mim_sample_metric {
    MIM_METRIC_IC = 0,
    MIM_METRIC_CARTESIAN = 1,
    MIM_METRIC_SHAPE = 2,
    MIM_METRIC_LIMBS = 3
} mim_sample_metric_t;
/* The limb joints of each person (shoulders, elbows, wrists, hips, knees,
 * ankles): mim_sample_joint_names indices FIRST .. FIRST + COUNT - 1. */
#define MIM_LIMB_FIRST 3
#define MIM_LIMB_COUNT 12

/* A pose-pair prepared for comparisons: its joints, its triangulation (for
 * D_I) and its shape contexts (for D_S), computed once. parts says which
 * of the two were made (MIM_PREP_*). */
#define MIM_SC_BINS (5 * 8 * 4)
#define MIM_PREP_TRIANGULATION 1u  /* ic: D_I reads both pose-pairs' */
#define MIM_PREP_SHAPE_CONTEXTS 2u /* sc: D_S reads a's alone (b's are made after the alignment) */
#define MIM_PREP_ALL 3u
typedef struct mim_pair_prep {
    int dim;
    unsigned parts;
    double joints[3 * MIM_PAIR_JOINTS];
    mim_ic_t ic;
    float sc[MIM_PAIR_JOINTS][MIM_SC_BINS];
} mim_pair_prep_t;
/* Prepares a 3D pose-pair (34 x 3 doubles), every part. Errors as
 * mim_ic_build. */
int mim_pair_prepare(const double *joints, mim_pair_prep_t *out, mim_error_t *err);
/* Prepares n pose-pairs (n x 34 x 3 doubles) on `threads` threads (0: 1),
 * the parts asked for (MIM_PREP_*; the samples of coverage need no shape
 * contexts, and no triangulation unless for D_I: the 3D triangulation is
 * most of the cost, and the shape contexts most of the memory; a
 * pose-pair the same as the one before it, as a sampler's refused steps
 * are, takes that one's parts rather than being prepared again). On an
 * error, *failed (may be NULL) is the first pair that failed and err says
 * why, as mim_pair_prepare. */
int mim_pair_prepare_many(const double *joints, uint32_t n, uint32_t threads, unsigned parts, mim_pair_prep_t *out,
                          uint32_t *failed, mim_error_t *err);
/* The parts a metric reads of the truth (a) and of the sample (b). */
unsigned mim_sample_metric_parts(mim_sample_metric_t metric, int sample);

/* D_I, D_C or D_S (Section 6) between prepared 3D pose-pairs a and b, after
 * bringing b onto a (mim_sample_align); or LIMBS, the mean distance (metres)
 * of the 24 limb joints after the least-squares rigid motion over those 24
 * joints alone, the smaller of b as it is and b with its people swapped. D_I: eq. 8 on a's and b's own
 * triangulations (b's vectors turned by the alignment). Symmetric up to the
 * alignment's direction; 0 for a pair against itself, moved rigidly. NaN
 * when a or b lacks a part the metric reads (mim_sample_metric_parts). */
double mim_sample_distance(const mim_pair_prep_t *a, const mim_pair_prep_t *b, mim_sample_metric_t metric);

/* ---- 2D annotations (annotate.c) ---- */
/* A perspective camera: world point p goes to camera coordinates
 * q = R (p - position) (rows of R: x right, y down, z forward) and to
 * pixels (focal_px q.x / q.z + cx, focal_px q.y / q.z + cy). */
typedef struct mim_pairs_camera {
    double position[3];
    double R[9]; /* row-major */
    double focal_px, cx, cy;
    uint32_t width, height;
    double dist; /* from the pair's centre when drawn (mim_pairs_camera_follow keeps it) */
} mim_pairs_camera_t;
/* The 34 joints' pixels (2 per joint) through cam: 1 when every joint is
 * in front of the camera and inside the image, else 0 (NaN for a joint
 * behind it). */
int mim_pairs_project(const mim_pairs_camera_t *cam, const double *joints, double *uv);
/* A random camera that sees the whole pose-pair (choices: annotate.c),
 * drawn from rng. MIM_ENOTFOUND when 1000 draws all leave a joint out
 * (a pair spread over tens of metres). */
int mim_pairs_camera_random(mim_rng_t *rng, const double *joints, mim_pairs_camera_t *cam);
/* A video camera: cam, drawn by mim_pairs_camera_random for an earlier
 * frame, follows the pair to this frame's joints (it keeps its distance,
 * direction and lens, as a camera operator keeps the pair framed). 1 when
 * it still sees the whole pair, else 0 (cam moved all the same). */
int mim_pairs_camera_follow(mim_pairs_camera_t *cam, const double *joints);

/* A set of annotations: n 2D pose-pairs (34 [u, v] pixels each) in images
 * of width x height, each from a take, a frame and a view, and a shot: the
 * annotations of one shot are frames of one camera's video, in the order
 * of their frames (MIM_PAIRS_NO_SHOT: a photo of its own). */
#define MIM_PAIRS_ANNOTATIONS_MAX 1000000u
#define MIM_PAIRS_NO_SHOT UINT32_MAX
typedef struct mim_pairs_annotations {
    uint32_t n, width, height;
    uint32_t *take, *frame, *view, *shot;
    double *points; /* n * 34 * 2 */
} mim_pairs_annotations_t;
/* The annotations file (schemas/pair-annotations.schema.json) for a, with
 * the takes' names; the cameras file (schemas/pair-cameras.schema.json),
 * one camera per annotation. malloc'd text; NULL when out of memory. */
char *mim_pairs_annotations_json(const mim_pairs_annotations_t *a, const char *const *takes, uint32_t n_takes);
char *mim_pairs_cameras_json(const mim_pairs_annotations_t *a, const mim_pairs_camera_t *cams);
/* Reads an annotations file. Errors, one line naming origin (and the
 * annotation and joint): MIM_EFORMAT (malformed JSON with line:column,
 * another format, joint names, image size, a point that is not [u, v]),
 * MIM_ENONFINITE (a coordinate that is no pixel), MIM_EEMPTY (no
 * annotations), MIM_EUNSUPPORTED (over MIM_PAIRS_ANNOTATIONS_MAX),
 * MIM_ENOMEM. On error *out is empty. */
int mim_pairs_annotations_parse(const char *text, size_t len, const char *origin, mim_pairs_annotations_t *out,
                                mim_error_t *err);
void mim_pairs_annotations_free(mim_pairs_annotations_t *a); /* accepts NULL and an empty set */

/* Annotating a take (annotate.c): V views per frame through random
 * cameras (video: each view one camera that follows the pair, a new shot
 * when it loses it), Gaussian noise of noise_px on every coordinate. */
#define MIM_PAIRS_ANNOTATE_MAX_VIEWS 1000
typedef struct mim_pairs_annotate_options {
    uint32_t views;
    int video;
    double noise_px;
    uint64_t seed;
} mim_pairs_annotate_options_t;
/* The n pose-pairs of a take (34 x 3 each, frame numbers first, first +
 * every, ...) annotated and appended to a (the image 1920 x 1080), their
 * cameras to *cams (grown alongside; cams NULL: none); shots are numbered
 * on from *shots. Each (take, frame, view) draws from its own stream of
 * seed: the same seed, the same annotations. Errors: MIM_ENOTFOUND (no
 * camera sees frame *bad_frame whole), MIM_EINVAL (views 0 or over the
 * maximum), MIM_EUNSUPPORTED (over MIM_PAIRS_ANNOTATIONS_MAX), MIM_ENOMEM;
 * a then also holds the annotations made before the error. */
int mim_pairs_annotate_take(const double *frames, uint32_t n, uint32_t first, uint32_t every, uint32_t take,
                            const mim_pairs_annotate_options_t *o, mim_pairs_annotations_t *a,
                            mim_pairs_camera_t **cams, uint32_t *shots, uint32_t *bad_frame);

/* ---- penetration between bones (penetration.c; eq. 2's eta, through ODE) ---- */
/* One context per thread, used on the thread that opened it (ODE keeps
 * per-thread data, which open allocates; the program frees it with
 * dCleanupODEAllDataForThread when the thread is done, or dCloseODE). The
 * program must have initialised ODE once (dInitODE2) before: ODE's state
 * is process-wide, which a library does not own. Errors: MIM_EUNSUPPORTED
 * (ODE not initialised), MIM_ENOMEM. */
typedef struct mim_penetration mim_penetration_t;
int mim_penetration_open(mim_penetration_t **out, mim_error_t *err);
void mim_penetration_close(mim_penetration_t **p); /* accepts NULL; nulls */
/* The penetration depth (metres, 0 when apart) of two capsules: segments
 * a0-a1 and b0-b1 with radii ra and rb. */
double mim_penetration_capsules(mim_penetration_t *p, const double a0[3], const double a1[3], double ra,
                                const double b0[3], const double b1[3], double rb);
/* eta of a 3D pose-pair (34 x 3 doubles, metres): the sum of the
 * penetration depths over its bones' capsule pairs (penetration.c), each
 * beyond its allowance in allowed (MIM_PENETRATION_ALLOWANCES entries, from
 * mim_penetration_learn; NULL: none). */
#define MIM_PENETRATION_ALLOWANCES (2 * 16 * 16)
double mim_penetration_pair(mim_penetration_t *p, const double *joints, const double *allowed);
/* Raises each of allowed's entries (zeroed by the caller before the first
 * pose-pair) to the depth its pair of bones shows in joints. */
void mim_penetration_learn(mim_penetration_t *p, const double *joints, double *allowed);

/* ---- camera views relative to a pair (views.c; Section 4.2, eqs. 3-5) ---- */
#define MIM_VIEW_DEFAULT_SIGMA 0.5 /* radians: eq. 5's bandwidth, the paper's default */
/* The pair's local frame of eq. 3 as a rotation (columns i, j, k: local
 * to world): i from A's pelvis to B's, j the mean of the two backbones
 * (pelvis to chest) made orthogonal to i, k = i x j. MIM_EINVAL when the
 * roots coincide or the backbones lie along the line between them. */
int mim_pairs_local_frame(const double *joints, double R[9]);
/* A direction (world) as eq. 4's angles in that frame: psi in (-pi, pi]
 * about j from i towards k, phi in [0, pi] from j. */
void mim_pairs_view_angles(const double R[9], const double dir[3], double *psi, double *phi);
/* Back: the unit world direction of the view (psi, phi). */
void mim_pairs_view_direction(const double R[9], double psi, double phi, double dir[3]);
/* eq. 5: the kernel density of n views (psi, phi pairs) at (psi, phi),
 * sigma the bandwidth (psi wraps around the circle); and one draw from it
 * (a view at random, then its kernel; phi reflected into [0, pi]). */
double mim_pairs_view_density(const double *views, uint32_t n, double sigma, double psi, double phi);
void mim_pairs_view_draw(const double *views, uint32_t n, double sigma, mim_rng_t *rng, double *psi, double *phi);

/* ---- the view of a 2D annotation (view_estimate.c; Section 4.2) ---- */
/* A person's mean torso: pelvis, l_hip, r_hip, spine, chest, neck,
 * l_shoulder, r_shoulder, metres, in the person's own frame (origin at the
 * pelvis; x from r_hip to l_hip, or r_shoulder to l_shoulder when the hips
 * sit on the pelvis; y up the back, pelvis to chest, made orthogonal to x;
 * z = x x y, the person's forward). */
#define MIM_PAIRS_TORSO_POINTS 8
typedef struct mim_pairs_torso {
    double point[MIM_PAIRS_TORSO_POINTS][3];
} mim_pairs_torso_t;
/* Learned from n 3D pose-pairs (34 x 3 doubles each): both people of every
 * pair, each brought into its own frame, averaged; a person whose frame is
 * degenerate (NaN, backbone along the hips) is skipped. MIM_EINVAL for n of
 * 0 or when no person has a frame. */
int mim_pairs_torso_learn(const double *pairs, uint32_t n, mim_pairs_torso_t *out, mim_error_t *err);
/* The view of a 2D annotation (uv: 34 [u, v] pixels, x right, y down, in
 * an image of width x height) as eq. 4's (psi, phi): what
 * mim_pairs_view_angles gives for the camera's forward axis in the pair's
 * local frame (mim_pairs_local_frame). Each person's torso is fitted to
 * its 8 torso pixels (method and accuracy: view_estimate.c). MIM_EINVAL
 * when a torso cannot be fitted (NaN, all points at one place), the frame
 * is degenerate or width is 0. */
int mim_pairs_annotation_view(const mim_pairs_torso_t *torso, const double *uv, uint32_t width, uint32_t height,
                              double *psi, double *phi);

/* ---- samples as JSON lines (samples_file.c; schemas/pair-samples.md) ---- */
/* The header line and a sample line (malloc'd, no newline; NULL when out
 * of memory). A NaN log density is written as null. */
char *mim_pairs_jsonl_header(void);
char *mim_pairs_jsonl_line(const double *joints, double log_density);

#define MIM_PAIRS_SAMPLES_MAX 10000000u
typedef struct mim_pairs_samples {
    uint32_t n;
    double *joints;      /* n * 34 * 3, metres */
    double *log_density; /* n; NaN when the file gives null or none */
    long *line;          /* n: each sample's line in the text (from 1); NULL in a set not parsed */
} mim_pairs_samples_t;
/* Parses a samples file: its header (the format and the 34 joint names, in
 * order) and every line after it (blank lines skipped). Errors, one line
 * with origin:line(:column): MIM_EFORMAT (malformed JSON, another format,
 * a wrong joint count or name, a joint that is not [x, y, z]),
 * MIM_ENONFINITE (a coordinate that is not finite or beyond 1 km),
 * MIM_EEMPTY (no header or no samples), MIM_EUNSUPPORTED (over
 * MIM_PAIRS_SAMPLES_MAX), MIM_ENOMEM. On error *out is empty. */
int mim_pairs_samples_parse(const char *text, size_t len, const char *origin, mim_pairs_samples_t *out,
                            mim_error_t *err);
void mim_pairs_samples_free(mim_pairs_samples_t *s); /* accepts NULL and an empty set */

/* ---- pose-pairs as BVH (bvh_write.c) ---- */
/* The BVH text (malloc'd; NULL when out of memory, n == 0, pairs NULL or
 * person not 0 or 1) of person (0: A, 1: B) over n pose-pairs (34 x 3
 * doubles each, metres), one frame each, frame_time seconds per frame (0,
 * negative or not finite: 1/30). CMU joint names (mim_pair_joint_map finds them), units
 * metres, rest pose frame 0 (its bone vectors are the OFFSETs), rotations
 * Zrotation Xrotation Yrotation in degrees (choices: bvh_write.c). Reading
 * it back gives the input when the bone lengths are frame 0's in every
 * frame (forward kinematics); otherwise each bone points where the input's
 * does with frame 0's length. No NaN is written: a bone with a non-finite
 * end is left out of its joint's rotation, a non-finite root place is 0. */
char *mim_pairs_bvh_text(const double *pairs, uint32_t n, int person, double frame_time);

/* ---- 2D pose-pairs as the likelihood compares them (pairs2d.c; eq. 9) ---- */
/* The 34 joints (x y z) seen orthographically along the unit direction
 * dir: 34 [x, y], the image's axes two that make (x, y, dir) right-handed
 * like a camera's right, down and forward (eq. 9's M then removes the turn
 * about dir, never a mirror). */
void mim_pairs2d_project(const double *joints, const double dir[3], double *uv);
/* in (34 [x, y]) centred on its mean and scaled to unit RMS radius into
 * out: the radius, 0 when every point is at one place or one is NaN. */
double mim_pairs2d_normalise(const double *in, double *out);
/* The 2D rotation (cos, sin) of least squares that brings normalised b
 * onto normalised a (eq. 9's M), and the mean squared distance per joint
 * after it; mim_pairs2d_rotate applies it. */
double mim_pairs2d_align(const double *a, const double *b, double *c, double *s);
void mim_pairs2d_rotate(const double *b, double c, double s, double *out);

/* ---- retrieval: a 3D pose-pair for a 2D annotation (retrieve.c; Fig. 2) ---- */
typedef struct mim_pairs_match {
    uint32_t sample; /* the sample's index; UINT32_MAX: none */
    double residual; /* eq. 9's 2D distance (mim_pairs2d_align): mean squared distance per joint of the
                      * two point sets at unit RMS radius after the in-plane rotation; 0 a perfect match */
    double dir[3];   /* the view: the unit direction the camera looks along, the samples' frame (y up) */
} mim_pairs_match_t;
/* The sample of samples (n x 34 x 3, metres, y up) whose orthographic
 * projection best matches the annotation uv (34 [u, v] pixels) over views
 * (the search and where it can miss: retrieve.c). Ties go to the lowest
 * index. 0; MIM_EINVAL for no samples or an annotation whose points are
 * all at one place or NaN; MIM_ENOTFOUND when no sample projects. */
int mim_pairs_retrieve(const double *samples, uint32_t n, const double *uv, mim_pairs_match_t *out);
/* mim_pairs_retrieve for every annotation of ann into out[ann->n] (an
 * annotation that fails keeps sample UINT32_MAX), on threads (0: 1), with
 * progress "retrieve" over the annotations (NULL: quiet). */
void mim_pairs_retrieve_many(const double *samples, uint32_t n, const mim_pairs_annotations_t *ann, uint32_t threads,
                             mim_progress_t *progress, mim_pairs_match_t *out);

/* ---- pose-pair completion (pair_complete.c; Fig. 12) ---- */
#define MIM_PAIRS_COMPLETE_DEFAULT_K 3
#define MIM_PAIRS_COMPLETE_MAX_K 64
typedef struct mim_pairs_complete_options {
    uint32_t k;      /* samples whose answers are blended (0: the default; at most MAX_K) */
    int person_only; /* 1: match on the missing joints' own person only (single-person completion) */
} mim_pairs_complete_options_t;
/* pair (34 x 3, metres) with the joints where missing[j] is 1 filled in
 * from the samples (n x 34 x 3) into out (the seen joints copied): the k
 * samples that fit the seen joints best after a rigid fit, each placing a
 * missing joint by its offsets from the seen joints around it (method:
 * pair_complete.c). o may be NULL. 0; MIM_EINVAL (no samples, NULL, k over
 * the most); MIM_EEMPTY (fewer than 3 joints to match on);
 * MIM_ENONFINITE (a seen joint that is not finite); MIM_ENOTFOUND (no
 * sample fits). Nothing missing: out is pair. */
int mim_pairs_complete(const double *samples, uint32_t n, const double *pair, const uint8_t *missing,
                       const mim_pairs_complete_options_t *o, double *out);

/* ---- coverage (coverage.c; eq. 13) ---- */
typedef struct mim_sample_coverage_options {
    uint32_t threads;         /* threads to work on, the calling one among them; 0: 1 */
    int exhaustive;           /* 1: every truth against every sample, no bounds (the reference) */
    mim_progress_t *progress; /* over the truth pairs, label "coverage"; NULL: quiet */
} mim_sample_coverage_options_t;
typedef struct mim_sample_coverage {
    double coverage;    /* C(G, S) */
    double *nearest;    /* NULL, or the caller's m entries: each truth's min_j D(g_i, s_j) */
    uint32_t *which;    /* NULL, or the caller's m entries: that j, the lowest of equal ones
                           (UINT32_MAX when no distance is below infinity) */
    uint64_t distances; /* distances computed */
    uint64_t aligned;   /* D_I, D_S: samples aligned and bounded again (coverage_bounds.c) */
    uint64_t cut;       /* D_I, D_S: of those, the ones given up, a bound having passed the nearest */
} mim_sample_coverage_t;
/* C(G, S) = 1/m sum_i min_j D(g_i, s_j) over the m truth pairs g and the k
 * samples s, in the metric given, into out (its nearest and which filled
 * when given). A distance is computed only for the samples that lower
 * bounds (coverage_bounds.c) leave as possibly nearest; every answer is
 * the one the exhaustive scan gives, to the bit, whatever the threads.
 * opt NULL: defaults. Errors: MIM_EINVAL (m or k of 0, or a pose-pair
 * without a part the metric reads: mim_sample_metric_parts), MIM_ENOMEM. */
int mim_sample_coverage(const mim_pair_prep_t *truth, uint32_t m, const mim_pair_prep_t *samples, uint32_t k,
                        mim_sample_metric_t metric, const mim_sample_coverage_options_t *opt, mim_sample_coverage_t *out,
                        mim_error_t *err);
/* The same in n of the metrics at once (each at most once; out[q] for
 * metrics[q], each answer as mim_sample_coverage gives it): D_I and D_S
 * asked for together align each sample they both measure once for both
 * (the measures' bound features are held side by side: 7.8 KB a sample
 * for all four). Errors as above, and MIM_EINVAL for n outside 1 to 4, a
 * metric repeated or none of the four. */
int mim_sample_coverage_many(const mim_pair_prep_t *truth, uint32_t m, const mim_pair_prep_t *samples, uint32_t k,
                             const mim_sample_metric_t *metrics, uint32_t n, const mim_sample_coverage_options_t *opt,
                             mim_sample_coverage_t *out, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
