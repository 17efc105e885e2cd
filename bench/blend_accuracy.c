/* Transfer from several templates (issue 15): one template against the k
 * nearest blended, each with and without the segment correction, on body
 * data the index has never seen. Prints figures; never passes or fails.
 *
 * Setting, strict leave one subject out: for each subject A, the
 * recognition index is built from the other subjects only (mim_index_build,
 * defaults); A's 16 landmarks in pose p (p != 0) are the query and the
 * solve's targets; the avatar is A in pose 0; the truth is A in pose p.
 * The templates are the index's hits for the query (k = 8 asked): exactly
 * what `mimic transfer --landmarks` retrieves. The segment correction needs
 * A's skin (the vest skeleton's bones, default smoothing), as the
 * orientation drive does. Errors: per-vertex distances in mm, pooled, and
 * by region (each vertex's heaviest segment).
 *
 * Methods: the single nearest template (the default before issue 15); the
 * first k hits (k = 2, 3, 5, all) blended, weights equal or by inverse
 * query distance; and each with the segment correction. Every method
 * iterates as mimic's default does (least squares, damping 0.5, early
 * stop). Times: the frames' preparation (correction and blend; the
 * templates' own frames are computed once, as the session caches them)
 * and the whole key frame, median over the runs.
 *
 * Relative rows (h2): each template's change from its subject's reference
 * (that subject's template in A's rest pose, found by querying the index
 * with A's rest landmarks) applied to A: the frames' turn
 * (mim_xfer_frames_relative) and the encoding's change
 * (mim_xfer_encoding_relative, scaled by mim_xfer_encoding_scale); and the
 * bounds with A's own frames and encoding in the pose. The references and
 * their scales are per avatar and subject, computed outside the timing.
 *
 * Gated relative rows (issue 29, --gated-only runs these alone): the
 * session's path (relative over the hits whose references stand within
 * MIM_SESSION_RELATIVE_GATE_DEG of A's rest, else plain), its default with
 * the session's constants, and the candidates measured for it: weights
 * 1/d^p and by build (mim_xfer_build_distance), k, the gate, the segment
 * correction on relative frames and its change version, the encoding's
 * scale per segment or vertex, a one-ring map on A's W, a cap on the
 * solves; bounds that say whether frames or encoding carry the error; and
 * each gated row's mean by query pose.
 *
 * usage: bench_blend_accuracy [--vertices N] [--mh DIR | --no-mh] [--no-imitation] [--iterations N]
 *                             [--settle S] [--damping D] [--new-only] [--gated-only] [--other-pose]
 *                             [--no-rest-ref] [--proportions canonical|body]
 *   --iterations N: N solves, no early stop (default: mimic's iteration)
 *   --settle S: mim_xfer_options_t.settle (< 0: none, as before issue 31)
 *   --damping D: mim_xfer_options_t.damping (0: mimic's)
 *   --new-only: of the plain rows only the nearest and 2 nearest by 1/distance
 *   --gated-only: only the gated relative rows (the session's path since issue 29) and their candidates
 *   --other-pose: templates from poses other than the query's (all-angle 1-NN)
 *   --no-rest-ref: references from poses other than A's rest
 *   --proportions body: indexes that see each body's own proportions (default: canonical, as mimic index) */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_index.h"
#include "mim_session.h"
#include "mim_transfer.h"
#include "mim_vest_kinematics.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define K_ASK 8
enum { W_EQUAL, W_INVERSE, N_WEIGHTING };
static const uint32_t ks[] = {1, 2, 3, 5, K_ASK};
#define N_K (sizeof ks / sizeof ks[0])
#define N_METHOD (N_K * N_WEIGHTING * 2)
enum { X_LANDMARKS, X_LANDMARKS_ONE, X_LANDMARKS_NEAREST, N_EXTRA }; /* the rows after the blends */
static const char *const extra_names[N_EXTRA] = {
    "avatar's rest frames turned by the landmark skeleton's segment rotations",
    "the same, one solve",
    "those, blended with the nearest template's (equal weights)"};
#define MAX_RUNS 4096
#define MAX_POSES 64
/* Deformation transfer of the frames (mim_xfer_frames_relative): each
 * template's turn from its subject's reference template (the index's hit
 * of that subject for A's rest landmarks) to the pose, on A's rest frames. */
/* frames: the templates' own; relative (mim_xfer_frames_relative); relative
 * on A's rest frames first turned by the segment rotations from A's rest
 * landmark skeleton onto the reference's (for a reference in another pose);
 * the truth's */
enum { FR_TEMPLATE, FR_RELATIVE, FR_RELATIVE_Q, FR_GATED, FR_GATED_ALL, FR_TRUTH };
/* FR_GATED: relative frames when the reference's pose is within GATE_DEG
 * (rms over all angles) of A's rest, else the template's own frames: a
 * reference in another pose carries that pose into relative frames. */
#define GATE_DEG 8.0
/* FR_GATED_ALL (issue 29, mimic's relative transfer since): the whole
 * relative path (frames and encoding change) over the hits whose
 * references lie within the session's gate of A's rest (the others left
 * out of the blend), the plain path over all hits when none does: a
 * reference that stands otherwise is another body's way of moving. */
#define GATE_ALL_DEG MIM_SESSION_RELATIVE_GATE_DEG
/* A's encoding; EN_DELTA_SEG: each change scaled per segment of A's skin
 * (rms of A's W over the rms of the reference's there, blended by the
 * skin's weights); EN_DELTA_LOCAL: per vertex, the global scale times
 * sqrt((|W_A|^2 + c) / (s^2 |W_ref|^2 + c)), c the mean |W_A|^2 */
/* EN_AFFINE: each template's one-ring deformation from its reference to
 * the pose, fitted per vertex in the local frames (G = B A^T (A A^T)^-1,
 * A and B the ring's edges), applied to A's own W: G W_A (W is linear in
 * the ring's edges: the uniform Laplacian) */
enum { EN_REST, EN_DELTA, EN_DELTA_SCALED, EN_DELTA_ROT, EN_TRUTH, EN_DELTA_SEG, EN_DELTA_LOCAL, EN_AFFINE };
enum { ORD_INDEX, ORD_SHAPE }; /* the hits in the index's order, or by rest build nearest A's */
/* corrections of the gated relative rows (issue 29): none; the session's
 * segment correction (each template's landmark skeleton onto the targets,
 * on its relative frames); the change version (the avatar's turn from its
 * rest landmarks to the targets against the template's from its
 * reference's landmarks, R_A R_T^-1, which leaves body shape out) */
/* CO_PLAIN_SEGMENT: the segment correction on the plain fallback only; CO_PLAIN_SKELETON: the skeleton
 * drive there (A's rest frames turned by its landmark skeleton onto the targets, one solve: the session's
 * auto drive) */
enum { CO_NONE, CO_SEGMENT, CO_CHANGE, CO_PLAIN_SEGMENT, CO_PLAIN_SKELETON };
typedef struct {
    uint32_t k;
    int weighting, frames, enc;
    const char *name;
    int order;
    double power;   /* FR_GATED_ALL: weights 1/d^power (0: 1) */
    double gate;    /* FR_GATED_ALL: the gate in degrees (0: GATE_ALL_DEG) */
    int correct;    /* CO_* */
    int gated_set;  /* run with --gated-only */
    double mu;      /* EN_AFFINE's pull towards the identity */
    double build_power; /* FR_GATED_ALL: weights also 1/build distance^build_power (0: not) */
    uint32_t max_iter;  /* on the relative path: at most this many solves unless --iterations (0: mimic's) */
    int spread;         /* FR_GATED_ALL: the plain path too where the store's pose spread passes its gate */
} rel_method_t;
/* rows give the fields they set; the rest are 0 (the table predates them) */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
static const rel_method_t rel_methods[] = {
    {1, W_EQUAL, FR_RELATIVE, EN_REST, "relative frames, nearest template", ORD_INDEX},
    {2, W_INVERSE, FR_RELATIVE, EN_REST, "relative frames, 2 nearest, 1/distance", ORD_INDEX},
    {K_ASK, W_EQUAL, FR_RELATIVE, EN_REST, "relative frames, all hits, equal", ORD_INDEX},
    {1, W_EQUAL, FR_TRUTH, EN_REST, "bound: A's own frames in the pose (the truth's)", ORD_INDEX},
    {1, W_EQUAL, FR_TRUTH, EN_TRUTH, "bound: A's own frames and encoding in the pose", ORD_INDEX},
    {1, W_EQUAL, FR_TEMPLATE, EN_TRUTH, "bound: nearest template's frames, A's own encoding in the pose", ORD_INDEX},
    {1, W_EQUAL, FR_TEMPLATE, EN_DELTA, "encoding change, nearest template (its frames)", ORD_INDEX},
    {1, W_EQUAL, FR_RELATIVE, EN_DELTA, "encoding change + relative frames, nearest", ORD_INDEX},
    {1, W_EQUAL, FR_RELATIVE, EN_DELTA_SCALED, "encoding change scaled + relative frames, nearest", ORD_INDEX},
    {2, W_INVERSE, FR_RELATIVE, EN_DELTA, "encoding change + relative frames, 2 nearest, 1/distance", ORD_INDEX},
    {3, W_INVERSE, FR_RELATIVE, EN_DELTA, "encoding change + relative frames, 3 nearest, 1/distance", ORD_INDEX},
    {K_ASK, W_EQUAL, FR_RELATIVE, EN_DELTA, "encoding change + relative frames, all hits, equal", ORD_INDEX},
    {K_ASK, W_INVERSE, FR_RELATIVE, EN_DELTA, "encoding change + relative frames, all hits, 1/distance", ORD_INDEX},
    {K_ASK, W_EQUAL, FR_RELATIVE, EN_DELTA_SCALED, "encoding change scaled + relative frames, all hits, equal", ORD_INDEX},
    {2, W_INVERSE, FR_RELATIVE, EN_DELTA_SCALED, "encoding change scaled + relative frames, 2 nearest, 1/distance", ORD_INDEX},
    {3, W_INVERSE, FR_RELATIVE, EN_DELTA_SCALED, "encoding change scaled + relative frames, 3 nearest, 1/distance", ORD_INDEX},
    {1, W_EQUAL, FR_RELATIVE, EN_DELTA_ROT, "encoding change scaled, in A's frames + relative frames, nearest", ORD_INDEX},
    {2, W_INVERSE, FR_RELATIVE, EN_DELTA_ROT, "encoding change scaled, in A's frames + relative frames, 2 nearest", ORD_INDEX},
    {1, W_EQUAL, FR_RELATIVE, EN_DELTA_SCALED, "encoding change scaled + relative frames, nearest build", ORD_SHAPE},
    {2, W_INVERSE, FR_RELATIVE, EN_DELTA_SCALED, "encoding change scaled + relative frames, 2 nearest builds", ORD_SHAPE},
    {1, W_EQUAL, FR_TEMPLATE, EN_REST, "nearest build's template (plain)", ORD_SHAPE},
    {1, W_EQUAL, FR_TEMPLATE, EN_DELTA_SCALED, "encoding change scaled, nearest template (its frames)", ORD_INDEX},
    {2, W_INVERSE, FR_TEMPLATE, EN_DELTA_SCALED, "encoding change scaled, 2 nearest, 1/distance (their frames)", ORD_INDEX},
    {1, W_EQUAL, FR_RELATIVE_Q, EN_DELTA_SCALED, "encoding change scaled + relative frames via the reference's skeleton, nearest", ORD_INDEX},
    {2, W_INVERSE, FR_RELATIVE_Q, EN_DELTA_SCALED, "encoding change scaled + relative frames via the reference's skeleton, 2 nearest", ORD_INDEX},
    {1, W_EQUAL, FR_GATED, EN_DELTA_SCALED, "encoding change scaled + relative frames if the reference is within 8 deg rms of A's rest, nearest", ORD_INDEX},
    {1, W_EQUAL, FR_GATED_ALL, EN_DELTA_SCALED, "relative over the hits whose references are within the gate, else plain; nearest", ORD_INDEX},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "relative over the hits whose references are within the gate, else plain; 3 nearest, 1/distance (the default before)", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "the same, relative weights 1/distance^2 x 1/build distance^2, at most 2 solves (the session's default)", ORD_INDEX, .power = MIM_SESSION_RELATIVE_DISTANCE_POWER, .build_power = MIM_SESSION_RELATIVE_BUILD_POWER, .max_iter = MIM_SESSION_RELATIVE_ITERATIONS, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "the same, relative weights 1/distance^2 x 1/build distance^2, mimic's iteration", ORD_INDEX, .power = MIM_SESSION_RELATIVE_DISTANCE_POWER, .build_power = MIM_SESSION_RELATIVE_BUILD_POWER, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "the template drive's default before the store's gate, + segment correction on the plain path only", ORD_INDEX, .power = MIM_SESSION_RELATIVE_DISTANCE_POWER, .build_power = MIM_SESSION_RELATIVE_BUILD_POWER, .max_iter = MIM_SESSION_RELATIVE_ITERATIONS, .correct = CO_PLAIN_SEGMENT, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "the template drive's default (the store's gate too)", ORD_INDEX, .power = MIM_SESSION_RELATIVE_DISTANCE_POWER, .build_power = MIM_SESSION_RELATIVE_BUILD_POWER, .max_iter = MIM_SESSION_RELATIVE_ITERATIONS, .correct = CO_PLAIN_SEGMENT, .gated_set = 1, .spread = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "the skeleton drive on the plain path, without the store's gate", ORD_INDEX, .power = MIM_SESSION_RELATIVE_DISTANCE_POWER, .build_power = MIM_SESSION_RELATIVE_BUILD_POWER, .max_iter = MIM_SESSION_RELATIVE_ITERATIONS, .correct = CO_PLAIN_SKELETON, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "the session's default (auto drive): the relative path where both gates pass, else the skeleton drive", ORD_INDEX, .power = MIM_SESSION_RELATIVE_DISTANCE_POWER, .build_power = MIM_SESSION_RELATIVE_BUILD_POWER, .max_iter = MIM_SESSION_RELATIVE_ITERATIONS, .correct = CO_PLAIN_SKELETON, .gated_set = 1, .spread = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "the same, 1/distance, at most 2 solves", ORD_INDEX, .max_iter = MIM_SESSION_RELATIVE_ITERATIONS, .gated_set = 1},
    {1, W_EQUAL, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, nearest, at most 2 solves", ORD_INDEX, .max_iter = MIM_SESSION_RELATIVE_ITERATIONS, .gated_set = 1},
    /* issue 29, "figures to reach": candidates on the gated relative path, and where its error comes from */
    {1, W_EQUAL, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, nearest (the old default on one-rig sets)", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_TRUTH, "bound: gated relative frames (3 nearest), A's own encoding in the pose", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_TRUTH, EN_DELTA_SCALED, "bound: A's own frames, gated relative encoding (3 nearest)", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest + segment correction", ORD_INDEX, .correct = CO_SEGMENT, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest + change correction", ORD_INDEX, .correct = CO_CHANGE, .gated_set = 1},
    {1, W_EQUAL, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, nearest + change correction", ORD_INDEX, .correct = CO_CHANGE, .gated_set = 1},
    {2, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 2 nearest, 1/distance", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^2", ORD_INDEX, .power = 2, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^4", ORD_INDEX, .power = 4, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance, gate 3 deg", ORD_INDEX, .gate = 3, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance, gate 4 deg", ORD_INDEX, .gate = 4, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA, "gated relative, 3 nearest, encoding change unscaled", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_ROT, "gated relative, 3 nearest, encoding change in A's frames", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SEG, "gated relative, 3 nearest, encoding change scaled per segment", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_LOCAL, "gated relative, 3 nearest, encoding change scaled per vertex", ORD_INDEX, .gated_set = 1},
    {1, W_EQUAL, FR_GATED_ALL, EN_DELTA_SEG, "gated relative, nearest, encoding change scaled per segment", ORD_INDEX, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_AFFINE, "gated relative, 3 nearest, ring map on A's W (mu 0.01)", ORD_INDEX, .mu = 0.01, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_AFFINE, "gated relative, 3 nearest, ring map on A's W (mu 0.1)", ORD_INDEX, .mu = 0.1, .gated_set = 1},
    {1, W_EQUAL, FR_GATED_ALL, EN_AFFINE, "gated relative, nearest, ring map on A's W (mu 0.01)", ORD_INDEX, .mu = 0.01, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^3", ORD_INDEX, .power = 3, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^8", ORD_INDEX, .power = 8, .gated_set = 1},
    {5, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 5 nearest, 1/distance^4", ORD_INDEX, .power = 4, .gated_set = 1},
    {K_ASK, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, all hits, 1/distance^4", ORD_INDEX, .power = 4, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^4, gate 6 deg", ORD_INDEX, .power = 4, .gate = 6, .gated_set = 1},
    {3, W_EQUAL, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest builds, 1/build distance^4", ORD_SHAPE, .build_power = 4, .gated_set = 1},
    {K_ASK, W_EQUAL, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, all hits, 1/build distance^4", ORD_SHAPE, .build_power = 4, .gated_set = 1},
    {1, W_EQUAL, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, nearest build", ORD_SHAPE, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^2 x 1/build distance^2", ORD_INDEX, .power = 2, .build_power = 2, .gated_set = 1},
    {K_ASK, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, all hits, 1/distance^4 x 1/build distance^4", ORD_INDEX, .power = 4, .build_power = 4, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^1 x 1/build distance^1", ORD_INDEX, .power = 1, .build_power = 1, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^2 x 1/build distance^1", ORD_INDEX, .power = 2, .build_power = 1, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^1 x 1/build distance^2", ORD_INDEX, .power = 1, .build_power = 2, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^3 x 1/build distance^1", ORD_INDEX, .power = 3, .build_power = 1, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^3 x 1/build distance^3", ORD_INDEX, .power = 3, .build_power = 3, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^4 x 1/build distance^2", ORD_INDEX, .power = 4, .build_power = 2, .gated_set = 1},
    {3, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 3 nearest, 1/distance^2 x 1/build distance^4", ORD_INDEX, .power = 2, .build_power = 4, .gated_set = 1},
    {K_ASK, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, all hits, 1/distance^2 x 1/build distance^2", ORD_INDEX, .power = 2, .build_power = 2, .gated_set = 1},
    {2, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 2 nearest, 1/distance^2 x 1/build distance^2", ORD_INDEX, .power = 2, .build_power = 2, .gated_set = 1},
    {5, W_INVERSE, FR_GATED_ALL, EN_DELTA_SCALED, "gated relative, 5 nearest, 1/distance^2 x 1/build distance^2", ORD_INDEX, .power = 2, .build_power = 2, .gated_set = 1},
};
#pragma GCC diagnostic pop
static int new_only, gated_only;
/* Robustness (both off by default):
 * other_pose: the templates are the other subjects' nearest over all
 * angles whose pose is NOT the query's (a store without the exact pose);
 * no_rest_ref: each subject's reference is its nearest template to A's rest
 * over all angles among poses other than A's rest pose (a store without
 * the avatar's rest pose). */
static int other_pose, no_rest_ref;
/* --proportions body: indexes without the landmark skeleton, each body's
 * own proportions (the index's default before canonical proportions) */
static int body_proportions;

static double angle_distance(const float *x, const float *y, uint32_t na)
{
    double d = 0;
    for (uint32_t i = 0; i < na; i++)
        if (isfinite(x[i]) && isfinite(y[i]))
            d += (x[i] - y[i]) * (x[i] - y[i]);
    return sqrt(d);
}

/* The k templates nearest over all angles to query qa among subjects other
 * than a, skipping pose skip_pose; per_subject: the nearest of each
 * subject only. Returns how many (sorted, nearest first). */
static uint32_t nearest_by_angles(const float *ang, uint32_t na, const float *qa, uint32_t S, uint32_t P, uint32_t a,
                                  uint32_t skip_pose, mim_index_hit_t *hits, uint32_t k)
{
    uint32_t got = 0;
    for (uint32_t t = 0; t < S * P; t++) {
        if (t / P == a || t % P == skip_pose)
            continue;
        double dt = angle_distance(ang + (size_t)na * t, qa, na);
        if (got == k && dt >= hits[k - 1].distance)
            continue;
        uint32_t at = got < k ? got++ : k - 1;
        while (at > 0 && hits[at - 1].distance > dt)
            hits[at] = hits[at - 1], at--;
        hits[at].id = t + 1, hits[at].distance = (float)dt, hits[at].subject = hits[at].pose = "";
    }
    return got;
}

/* delta W of template j in A's frames: C^T (W_pose - W_ref), C = R^T A, times s. */
static void add_rotated(uint32_t n, const double *Wp, const double *Wr, const double *R, const double *A, double c,
                        double *out)
{
    for (size_t i = 0; i < n; i++) {
        const double *r = R + 9 * i, *av = A + 9 * i;
        double dw[3] = {Wp[3 * i] - Wr[3 * i], Wp[3 * i + 1] - Wr[3 * i + 1], Wp[3 * i + 2] - Wr[3 * i + 2]};
        double g[3]; /* R dw: the change in rest-pose world axes */
        for (int k = 0; k < 3; k++)
            g[k] = r[k] * dw[0] + r[3 + k] * dw[1] + r[6 + k] * dw[2];
        for (int k = 0; k < 3; k++) /* A^T g */
            out[3 * i + k] += c * (av[3 * k] * g[0] + av[3 * k + 1] * g[1] + av[3 * k + 2] * g[2]);
    }
}
/* out += c * s_i (Wp - Wr), s_i per vertex as EN_DELTA_SEG or EN_DELTA_LOCAL say (sg: the global scale) */
static void add_local(uint32_t n, int enc, const double *Wp, const double *Wr, const double *WA,
                      const mim_xfer_skin_t *skin, double sg, double c, double *out)
{
    double sA[MIM_XFER_SKIN_MAX_BONES] = {0}, sR[MIM_XFER_SKIN_MAX_BONES] = {0}, mA = 0;
    for (size_t i = 0; i < n; i++) {
        double a2 = WA[3 * i] * WA[3 * i] + WA[3 * i + 1] * WA[3 * i + 1] + WA[3 * i + 2] * WA[3 * i + 2];
        double r2 = Wr[3 * i] * Wr[3 * i] + Wr[3 * i + 1] * Wr[3 * i + 1] + Wr[3 * i + 2] * Wr[3 * i + 2];
        sA[skin[i].bone[0]] += a2, sR[skin[i].bone[0]] += r2, mA += a2 / n;
    }
    if (!isfinite(sg)) sg = 1;
    for (size_t i = 0; i < n; i++) {
        double si = 0;
        if (enc == EN_DELTA_SEG) {
            for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES; k++)
                si += skin[i].weight[k] * (sR[skin[i].bone[k]] > 0 ? sqrt(sA[skin[i].bone[k]] / sR[skin[i].bone[k]]) : sg);
        } else {
            double a2 = WA[3 * i] * WA[3 * i] + WA[3 * i + 1] * WA[3 * i + 1] + WA[3 * i + 2] * WA[3 * i + 2];
            double r2 = Wr[3 * i] * Wr[3 * i] + Wr[3 * i + 1] * Wr[3 * i + 1] + Wr[3 * i + 2] * Wr[3 * i + 2];
            si = sg * sqrt((a2 + mA) / (sg * sg * r2 + mA));
        }
        for (int k = 0; k < 3; k++)
            out[3 * i + k] += c * si * (Wp[3 * i + k] - Wr[3 * i + k]);
    }
}
/* out += c (G_i W_A,i - W_A,i), G_i the ring's map from the reference (positions xr, frames Fr) to the
 * pose (xp, Fp), pulled towards the identity by mu times the ring's mean squared edge */
static void add_affine(const mim_xfer_topology_t *topo, uint32_t n, const float *xr, const double *Fr,
                       const float *xp, const double *Fp, const double *WA, double mu, double c, double *out)
{
    for (uint32_t i = 0; i < n; i++) {
        uint32_t deg;
        const uint32_t *nb = mim_xfer_neighbors(topo, i, &deg);
        double AA[9] = {0}, BA[9] = {0}, e2 = 0; /* row-major 3x3 */
        const double *fr = Fr + 9 * (size_t)i, *fp = Fp + 9 * (size_t)i;
        for (uint32_t k = 0; k < deg; k++) {
            const uint32_t j = nb[k];
            double er[3], ep[3], a[3], b[3];
            for (int c3 = 0; c3 < 3; c3++)
                er[c3] = (double)xr[3 * j + c3] - xr[3 * i + c3], ep[c3] = (double)xp[3 * j + c3] - xp[3 * i + c3];
            for (int r = 0; r < 3; r++) /* F^T e: column r of F dotted with e */
                a[r] = fr[3 * r] * er[0] + fr[3 * r + 1] * er[1] + fr[3 * r + 2] * er[2],
                b[r] = fp[3 * r] * ep[0] + fp[3 * r + 1] * ep[1] + fp[3 * r + 2] * ep[2];
            for (int r = 0; r < 3; r++)
                for (int q = 0; q < 3; q++)
                    AA[3 * r + q] += a[r] * a[q], BA[3 * r + q] += b[r] * a[q];
            e2 += a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
        }
        const double lam = deg ? mu * e2 / deg : 1;
        for (int r = 0; r < 3; r++)
            AA[4 * r] += lam, BA[4 * r] += lam;
        /* G = BA AA^-1 */
        double inv[9], det = AA[0] * (AA[4] * AA[8] - AA[5] * AA[7]) - AA[1] * (AA[3] * AA[8] - AA[5] * AA[6]) +
                             AA[2] * (AA[3] * AA[7] - AA[4] * AA[6]);
        inv[0] = (AA[4] * AA[8] - AA[5] * AA[7]) / det, inv[1] = (AA[2] * AA[7] - AA[1] * AA[8]) / det,
        inv[2] = (AA[1] * AA[5] - AA[2] * AA[4]) / det, inv[3] = (AA[5] * AA[6] - AA[3] * AA[8]) / det,
        inv[4] = (AA[0] * AA[8] - AA[2] * AA[6]) / det, inv[5] = (AA[2] * AA[3] - AA[0] * AA[5]) / det,
        inv[6] = (AA[3] * AA[7] - AA[4] * AA[6]) / det, inv[7] = (AA[1] * AA[6] - AA[0] * AA[7]) / det,
        inv[8] = (AA[0] * AA[4] - AA[1] * AA[3]) / det;
        const double *w = WA + 3 * (size_t)i;
        for (int r = 0; r < 3; r++) {
            double g = 0;
            for (int q = 0; q < 3; q++) {
                double G = BA[3 * r] * inv[q] + BA[3 * r + 1] * inv[3 + q] + BA[3 * r + 2] * inv[6 + q];
                g += G * w[q];
            }
            out[3 * (size_t)i + r] += c * (g - w[r]);
        }
    }
}
#define N_REL (sizeof rel_methods / sizeof rel_methods[0])
#define N_ROWS (N_METHOD + N_EXTRA + N_REL)

typedef struct row {
    bench_err_t e;
    double rsum[BENCH_REGIONS];
    uint64_t rcnt[BENCH_REGIONS];
    double *t_prep, *t_key;
    uint32_t runs;
    uint64_t solves;
    double psum[MAX_POSES]; /* by the query's pose */
    uint64_t pcnt[MAX_POSES];
} row_t;

static int method_index(uint32_t ki, int weighting, int corrected)
{
    return (int)((ki * N_WEIGHTING + (uint32_t)weighting) * 2 + (uint32_t)corrected);
}

static void method_name(uint32_t ki, int weighting, int corrected, char *buf, size_t size)
{
    char who[64];
    if (ks[ki] == K_ASK)
        snprintf(who, sizeof who, "all hits (<= %d)", K_ASK);
    else
        snprintf(who, sizeof who, "%u nearest", ks[ki]);
    snprintf(buf, size, "%s%s%s", ks[ki] == 1 ? "nearest template" : who,
             ks[ki] == 1 ? "" : weighting == W_EQUAL ? ", equal weights" : ", 1/distance weights",
             corrected ? " + segment correction" : "");
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One key frame's errors and times (t0 .. t1 the frames, .. t2 the solve). */
static void record(row_t *r, const float *out, const float *truth, const uint8_t *region, uint32_t n, uint32_t pose,
                   double t0, double t1, double t2, const mim_xfer_report_t *rep)
{
    r->solves += rep->iterations;
    if (r->runs < MAX_RUNS)
        r->t_prep[r->runs] = 1000 * (t1 - t0), r->t_key[r->runs] = 1000 * (t2 - t0);
    r->runs++;
    for (uint32_t i = 0; i < n; i++) {
        double dx = out[3 * i] - truth[3 * i], dy = out[3 * i + 1] - truth[3 * i + 1], dz = out[3 * i + 2] - truth[3 * i + 2];
        double mm = 1000 * sqrt(dx * dx + dy * dy + dz * dz);
        bench_err_add_mm(&r->e, mm);
        r->rsum[region[i]] += mm, r->rcnt[region[i]]++;
        if (pose < MAX_POSES)
            r->psum[pose] += mm, r->pcnt[pose]++;
    }
}

static void print_row(row_t *r, const char *name)
{
    uint32_t nr = r->runs < MAX_RUNS ? r->runs : MAX_RUNS;
    qsort(r->t_prep, nr, sizeof(double), cmp_double);
    qsort(r->t_key, nr, sizeof(double), cmp_double);
    printf("| %s | %.2f | %.2f |", name, bench_err_mean(&r->e), bench_err_p95(&r->e));
    for (int g = 0; g < BENCH_REGIONS; g++)
        printf(" %.2f |", r->rcnt[g] ? r->rsum[g] / (double)r->rcnt[g] : 0.0);
    printf(" %.3f | %.3f | %.2f |\n", r->t_prep[nr / 2], r->t_key[nr / 2], r->runs ? (double)r->solves / r->runs : 0.0);
}

static int run_set(const bench_dataset_t *d, void *user)
{
    const mim_xfer_options_t *xo = user;
    mim_error_t err = {0};
    const uint32_t n = d->n, L = d->map.count, S = d->subjects, P = d->poses;
    mim_xfer_topology_t *topo = NULL;
    mim_xfer_solver_t *ls = NULL;
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err) ||
        mim_xfer_solver_open(&ls, topo, d->map.vertex, L, NULL, &err)) {
        fprintf(stderr, "bench: %s\n", mim_error_text(&err));
        return 1;
    }
    /* every body's landmarks and frames, once */
    const uint32_t T = S * P;
    float *lm = malloc(sizeof(float) * 3 * L * T);
    double **F = calloc(T, sizeof *F), **WT = calloc(T, sizeof *WT);
    for (uint32_t t = 0; t < T; t++) {
        for (uint32_t l = 0; l < L; l++)
            memcpy(lm + 3 * (L * t + l), d->pos[t] + 3 * (size_t)d->map.vertex[l], 3 * sizeof(float));
        F[t] = malloc(9 * sizeof(double) * n);
        mim_xfer_frames(topo, d->pos[t], F[t]);
        WT[t] = malloc(3 * sizeof(double) * n);
        mim_xfer_encode(topo, d->pos[t], F[t], WT[t]);
    }
    const uint32_t na = mim_index_angle_count(L);
    float *ang = malloc(sizeof(float) * na * T);
    for (uint32_t t = 0; t < T; t++)
        mim_index_angles(lm + 3 * L * t, NULL, L, ang + (size_t)na * t);
    uint32_t wrong_refs = 0, n_refd = 0, n_hitd = 0, n_agree = 0, n_spread = 0;
    double spreads[64];
    double refd[64 * 64], hitd[MAX_RUNS], agree[MAX_RUNS];
    row_t rows[N_ROWS];
    memset(rows, 0, sizeof rows);
    for (uint32_t m = 0; m < N_ROWS; m++) {
        bench_err_init(&rows[m].e);
        rows[m].t_prep = malloc(MAX_RUNS * sizeof(double));
        rows[m].t_key = malloc(MAX_RUNS * sizeof(double));
    }
    double *W = malloc(3 * sizeof(double) * n), *Wx = malloc(3 * sizeof(double) * n), *Fa = malloc(9 * sizeof(double) * n);
    int near_of[64];     /* per subject: its reference's pose is near A's rest (FR_GATED) */
    int near_all_of[64]; /* the same within GATE_ALL_DEG (FR_GATED_ALL) */
    double ref_rms_of[64]; /* per subject: its reference's rms angle from A's rest (radians) */
    double scale_of[64]; /* per subject, as a session caches it with the reference */
    uint32_t ref_of[64], ref_misses = 0, rest_right = 0;
    double *Fc[K_ASK], *Fb = malloc(9 * sizeof(double) * n);
    for (int j = 0; j < K_ASK; j++)
        Fc[j] = malloc(9 * sizeof(double) * n);
    float *out = malloc(3 * sizeof(float) * n);
    mim_xfer_skin_t *skin = malloc(sizeof *skin * n);
    uint8_t *region = malloc(n);
    uint64_t *ids = malloc(sizeof(uint64_t) * T);
    char (*subj)[16] = malloc(16 * T), (*pose)[16] = malloc(16 * T);
    const char **sp = malloc(sizeof(char *) * T), **pp = malloc(sizeof(char *) * T);
    uint32_t queries = 0, same_pose_hits = 0, hits_total = 0, right_class = 0;
    for (uint32_t t = 0; t < T; t++) {
        snprintf(subj[t], 16, "s%u", t / P), snprintf(pose[t], 16, "p%u", t % P);
        sp[t] = subj[t], pp[t] = pose[t], ids[t] = t + 1;
    }
    int rc = 1;
    mim_xfer_report_t rep;
    for (uint32_t a = 0; a < S; a++) {
        const float *rest = d->pos[a * P];
        mim_mesh_t mesh = {n, d->n_faces, (float *)rest, d->faces};
        mim_vest_skeleton_t sk;
        double bones[MIM_SEGMENTS * 6];
        if (mim_vest_skeleton_estimate(&sk, &mesh, &d->map, &err))
            goto fail;
        mim_vest_skeleton_bones(&sk, bones);
        if (mim_xfer_skin_from_bones_wide(topo, rest, bones, MIM_SEGMENTS, MIM_XFER_DEFAULT_SKIN_SMOOTHING,
                                          MIM_XFER_SKIN_WIDE_SEGMENTS, MIM_XFER_DEFAULT_SKIN_SMOOTHING_WIDE, skin, &err))
            goto fail;
        for (uint32_t i = 0; i < n; i++)
            region[i] = (uint8_t)bench_region_of_segment(skin[i].bone[0]);
        mim_xfer_frames(topo, rest, Fa);
        mim_xfer_encode(topo, rest, Fa, W);
        /* the index of the other subjects */
        uint32_t ntrain = 0;
        float *tlm = malloc(sizeof(float) * 3 * L * T);
        const char **tsp = malloc(sizeof(char *) * T), **tpp = malloc(sizeof(char *) * T);
        uint64_t *tid = malloc(sizeof(uint64_t) * T);
        for (uint32_t t = 0; t < T; t++)
            if (t / P != a) {
                memcpy(tlm + 3 * L * ntrain, lm + 3 * L * t, sizeof(float) * 3 * L);
                tsp[ntrain] = sp[t], tpp[ntrain] = pp[t], tid[ntrain] = ids[t], ntrain++;
            }
        int32_t parent[MIM_LANDMARKS_MAX]; /* the landmark skeleton: canonical proportions, as a store's index */
        const int skeleton = !body_proportions && !mim_index_skeleton(&d->map, parent);
        mim_index_input_t in = {ntrain, L, tlm, tid, tsp, tpp, d->map.mirror, skeleton ? parent : NULL};
        mim_index_t *ix = NULL;
        int brc = mim_index_build(&ix, &in, NULL, NULL, &err);
        /* how alike the other subjects take a pose: the session's store gate (MIM_SESSION_RELATIVE_SPREAD_DEG) */
        const double spread = mim_session_pose_spread(ntrain, L, tlm, tsp, tpp);
        if (n_spread < 64) spreads[n_spread++] = spread;
        free(tlm), free(tsp), free(tpp), free(tid);
        if (brc)
            goto fail;
        { /* each other subject's reference: its hit for A's rest landmarks */
            mim_index_query_options_t qo = {.k = K_ASK};
            mim_index_answer_t ans;
            mim_index_hit_t hits[K_ASK];
            if (mim_index_query(ix, lm + 3 * L * (a * P), NULL, &qo, &ans, hits, &err)) {
                mim_index_close(&ix);
                goto fail;
            }
            for (uint32_t s = 0; s < S && s < 64; s++)
                ref_of[s] = UINT32_MAX;
            for (uint32_t h = 0; h < ans.n_hits; h++) {
                uint32_t t = (uint32_t)hits[h].id - 1;
                rest_right += t % P == 0;
                if (t / P < 64 && ref_of[t / P] == UINT32_MAX)
                    ref_of[t / P] = t;
            }
            for (uint32_t s = 0; s < S && s < 64; s++)
                if (s != a && ref_of[s] == UINT32_MAX)
                    ref_of[s] = s * P, ref_misses++; /* not among the hits: its pose 0 */
            if (no_rest_ref)
                for (uint32_t s = 0; s < S && s < 64; s++) {
                    if (s == a)
                        continue;
                    float best = INFINITY;
                    for (uint32_t pp2 = 1; pp2 < P; pp2++) {
                        float dt = (float)angle_distance(ang + (size_t)na * (s * P + pp2), ang + (size_t)na * (a * P), na);
                        if (dt < best)
                            best = dt, ref_of[s] = s * P + pp2;
                    }
                    wrong_refs++;
                }
            for (uint32_t s = 0; s < S && s < 64; s++)
                scale_of[s] = s == a ? 1.0 : mim_xfer_encoding_scale(n, WT[a * P], WT[ref_of[s]]);
            for (uint32_t s = 0; s < S && s < 64; s++) {
                near_of[s] = near_all_of[s] = 0, ref_rms_of[s] = INFINITY;
                if (s == a) continue;
                const double rms = angle_distance(ang + (size_t)na * ref_of[s], ang + (size_t)na * (a * P), na) /
                                   sqrt((double)na);
                ref_rms_of[s] = rms;
                near_of[s] = rms < GATE_DEG * M_PI / 180;
                near_all_of[s] = rms < GATE_ALL_DEG * M_PI / 180;
            }
        }
        for (uint32_t p = 1; p < P; p++) {
            const uint32_t q = a * P + p;
            const float *truth = d->pos[q], *u = lm + 3 * L * q;
            mim_index_query_options_t qo = {.k = K_ASK};
            mim_index_answer_t ans;
            mim_index_hit_t hits[K_ASK];
            if (mim_index_query(ix, u, NULL, &qo, &ans, hits, &err) || !ans.n_hits) {
                mim_index_close(&ix);
                goto fail;
            }
            if (other_pose)
                ans.n_hits = nearest_by_angles(ang, na, ang + (size_t)na * q, S, P, a, p, hits, K_ASK);
            queries++;
            right_class += !strcmp(hits[0].pose, pose[q]);
            for (uint32_t h = 0; h < ans.n_hits; h++)
                same_pose_hits += !strcmp(hits[h].pose, pose[q]), hits_total++;
            for (uint32_t ki = 0; ki < N_K; ki++)
                for (int wt = 0; wt < N_WEIGHTING; wt++)
                    for (int corrected = 0; corrected < 2; corrected++) {
                        if (ks[ki] == 1 && wt != W_EQUAL)
                            continue;
                        if (gated_only || (new_only && (corrected || !(ks[ki] == 1 || (ks[ki] == 2 && wt == W_INVERSE)))))
                            continue;
                        row_t *r = &rows[method_index(ki, wt, corrected)];
                        uint32_t k = ks[ki] < ans.n_hits ? ks[ki] : ans.n_hits;
                        double w[K_ASK];
                        const double *src[K_ASK];
                        double t0 = mim_now();
                        for (uint32_t j = 0; j < k; j++) {
                            const uint32_t t = (uint32_t)hits[j].id - 1;
                            w[j] = wt == W_EQUAL ? 1.0 : 1.0 / (hits[j].distance + 1e-3);
                            src[j] = F[t];
                            if (corrected) {
                                mim_quat R[MIM_SEGMENTS];
                                if (mim_xfer_segment_correction(&d->map, lm + 3 * L * t, u, R, &err)) {
                                    mim_index_close(&ix);
                                    goto fail;
                                }
                                mim_xfer_skin_frames(n, skin, F[t], R, Fc[j]);
                                src[j] = Fc[j];
                            }
                        }
                        const double *frames = src[0];
                        if (k > 1) {
                            mim_xfer_frames_blend(n, k, src, w, Fb);
                            frames = Fb;
                        }
                        double t1 = mim_now();
                        if (mim_xfer_transfer(ls, W, n, frames, u, L, xo, out, &rep, &err)) {
                            mim_index_close(&ix);
                            goto fail;
                        }
                        record(r, out, truth, region, n, p, t0, t1, mim_now(), &rep);
                    }
            /* the avatar's own frames, turned as its landmark skeleton
             * onto the targets (no template); then blended with the nearest */
            for (int x = 0; x < N_EXTRA && !new_only && !gated_only; x++) {
                double t0 = mim_now();
                mim_quat R[MIM_SEGMENTS];
                if (mim_xfer_segment_correction(&d->map, lm + 3 * L * (a * P), u, R, &err)) {
                    mim_index_close(&ix);
                    goto fail;
                }
                mim_xfer_skin_frames(n, skin, Fa, R, Fc[0]);
                const double *frames = Fc[0];
                if (x == X_LANDMARKS_NEAREST) {
                    const double *src[2] = {Fc[0], F[hits[0].id - 1]};
                    mim_xfer_frames_blend(n, 2, src, NULL, Fb);
                    frames = Fb;
                }
                double t1 = mim_now();
                mim_xfer_options_t x1 = *xo;
                if (x == X_LANDMARKS_ONE) x1.max_iterations = 1;
                if (mim_xfer_transfer(ls, W, n, frames, u, L, &x1, out, &rep, &err)) {
                    mim_index_close(&ix);
                    goto fail;
                }
                record(&rows[N_METHOD + x], out, truth, region, n, p, t0, t1, mim_now(), &rep);
            }
            /* the hits by build, nearest A's first (the reference's rest landmarks) */
            mim_index_hit_t by_build[K_ASK];
            double bd[K_ASK];
            for (uint32_t h = 0; h < ans.n_hits; h++) {
                double dh = mim_xfer_build_distance(lm + 3 * L * (a * P), lm + 3 * L * ref_of[(hits[h].id - 1) / P], L);
                uint32_t at = h;
                while (at > 0 && bd[at - 1] > dh)
                    bd[at] = bd[at - 1], by_build[at] = by_build[at - 1], at--;
                bd[at] = dh, by_build[at] = hits[h];
            }
            if (n_hitd < MAX_RUNS) /* how far the first hit's pose is from the query's (all angles) */
                hitd[n_hitd++] = angle_distance(ang + (size_t)na * (hits[0].id - 1), ang + (size_t)na * (a * P + p), na) /
                                 sqrt((double)na) * 180.0 / M_PI;
            if (n_agree < MAX_RUNS && ans.n_hits > 1) /* how far the first two hits stand apart (all angles) */
                agree[n_agree++] = angle_distance(ang + (size_t)na * (hits[0].id - 1), ang + (size_t)na * (hits[1].id - 1), na) /
                                   sqrt((double)na) * 180.0 / M_PI;
            if (p == 1) /* how far each reference's pose is from A's rest (all angles) */
                for (uint32_t s2 = 0; s2 < S && s2 < 64; s2++)
                    if (s2 != a && n_refd < 64 * 64)
                        refd[n_refd++] = angle_distance(ang + (size_t)na * ref_of[s2], ang + (size_t)na * (a * P), na);
            for (uint32_t m = 0; m < N_REL; m++) {
                const rel_method_t *rm = &rel_methods[m];
                uint32_t k = rm->k < ans.n_hits ? rm->k : ans.n_hits;
                const mim_index_hit_t *hh = rm->order == ORD_SHAPE ? by_build : hits;
                double w[K_ASK], sc[K_ASK];
                const double *src[K_ASK], *wp[K_ASK], *wr[K_ASK];
                double t0 = mim_now();
                /* FR_GATED_ALL as the session: the hits whose references are near, blended relative; with
                 * none, the plain path over them all */
                if (gated_only && !rm->gated_set)
                    continue;
                const int gated = rm->frames == FR_GATED_ALL || rm->gated_set;
                const double gate = (rm->gate > 0 ? rm->gate : GATE_ALL_DEG) * M_PI / 180;
                mim_index_hit_t sel[K_ASK];
                uint32_t n_sel = 0;
                for (uint32_t j = 0; j < k; j++)
                    if (ref_rms_of[((uint32_t)hh[j].id - 1) / P] < gate) sel[n_sel++] = hh[j];
                const int plain = gated && (!n_sel || (rm->spread && spread > MIM_SESSION_RELATIVE_SPREAD_DEG));
                if (gated && !plain) hh = sel, k = n_sel;
                mim_quat RA[MIM_SEGMENTS]; /* A's turn from its rest landmarks to the targets (CO_CHANGE) */
                if (rm->correct == CO_CHANGE && !plain &&
                    mim_xfer_segment_correction(&d->map, lm + 3 * L * (a * P), u, RA, &err)) {
                    mim_index_close(&ix);
                    goto fail;
                }
                for (uint32_t j = 0; j < k; j++) {
                    const uint32_t t = (uint32_t)hh[j].id - 1, r = ref_of[t / P];
                    w[j] = rm->weighting == W_EQUAL ? 1.0 : 1.0 / (hh[j].distance + 1e-3);
                    if (rm->power > 0 && !plain) w[j] = pow(w[j], rm->power); /* the plain path keeps 1/d */
                    if (rm->build_power > 0 && !plain) /* and by how like A's build the subject's is */
                        w[j] *= pow(1.0 / (mim_xfer_build_distance(lm + 3 * L * (a * P), lm + 3 * L * r, L) +
                                           MIM_SESSION_BUILD_DISTANCE_FLOOR), rm->build_power);
                    src[j] = F[t];
                    if (rm->frames == FR_RELATIVE || (rm->frames == FR_GATED && near_of[t / P]) ||
                        (rm->frames == FR_GATED_ALL && !plain)) {
                        mim_xfer_frames_relative(n, F[t], F[r], Fa, Fc[j]);
                        src[j] = Fc[j];
                    } else if (rm->frames == FR_RELATIVE_Q) {
                        mim_quat Q[MIM_SEGMENTS];
                        if (mim_xfer_segment_correction(&d->map, lm + 3 * L * (a * P), lm + 3 * L * r, Q, &err)) {
                            mim_index_close(&ix);
                            goto fail;
                        }
                        mim_xfer_skin_frames(n, skin, Fa, Q, Fc[j]);
                        mim_xfer_frames_relative(n, F[t], F[r], Fc[j], Fc[j]);
                        src[j] = Fc[j];
                    }
                    wp[j] = WT[t], wr[j] = WT[r], sc[j] = scale_of[t / P];
                    if ((rm->correct != CO_NONE && rm->correct != CO_PLAIN_SEGMENT && rm->correct != CO_PLAIN_SKELETON &&
                         !plain) ||
                        (rm->correct == CO_PLAIN_SEGMENT && plain)) {
                        mim_quat R[MIM_SEGMENTS];
                        const int seg = rm->correct == CO_SEGMENT || rm->correct == CO_PLAIN_SEGMENT;
                        const float *from = seg ? lm + 3 * L * t : lm + 3 * L * r, *to = seg ? u : lm + 3 * L * t;
                        if (mim_xfer_segment_correction(&d->map, from, to, R, &err)) {
                            mim_index_close(&ix);
                            goto fail;
                        }
                        if (rm->correct == CO_CHANGE) /* R_A R_T^-1 */
                            for (int g = 0; g < MIM_SEGMENTS; g++)
                                R[g] = mim_quat_normalize(mim_quat_mul(
                                    RA[g], (mim_quat){-R[g].x, -R[g].y, -R[g].z, R[g].w}));
                        mim_xfer_skin_frames(n, skin, src[j], R, Fc[j]);
                        src[j] = Fc[j];
                    }
                }
                const double *frames = rm->frames == FR_TRUTH ? F[q] : src[0];
                const int skeleton = rm->correct == CO_PLAIN_SKELETON && plain;
                if (skeleton) {
                    mim_quat R[MIM_SEGMENTS];
                    if (mim_xfer_segment_correction(&d->map, lm + 3 * L * (a * P), u, R, &err)) {
                        mim_index_close(&ix);
                        goto fail;
                    }
                    mim_xfer_skin_frames(n, skin, Fa, R, Fb);
                    frames = Fb;
                } else if (k > 1 && rm->frames != FR_TRUTH) {
                    mim_xfer_frames_blend(n, k, src, w, Fb);
                    frames = Fb;
                }
                const double *Wq = rm->enc == EN_TRUTH ? WT[q] : W;
                if ((rm->enc == EN_DELTA || rm->enc == EN_DELTA_SCALED) && !plain) {
                    mim_xfer_encoding_relative(n, k, wp, wr, w, rm->enc == EN_DELTA_SCALED ? sc : NULL, W, Wx);
                    Wq = Wx;
                } else if ((rm->enc == EN_DELTA_SEG || rm->enc == EN_DELTA_LOCAL || rm->enc == EN_AFFINE ||
                            rm->enc == EN_DELTA_ROT) && !plain) { /* each template's change, weighted, onto A's W */
                    double tw = 0;
                    for (uint32_t j = 0; j < k; j++)
                        tw += w[j];
                    memcpy(Wx, W, 3 * sizeof(double) * n);
                    for (uint32_t j = 0; j < k; j++) {
                        const uint32_t t = (uint32_t)hh[j].id - 1, r = ref_of[t / P];
                        if (rm->enc == EN_AFFINE)
                            add_affine(topo, n, d->pos[r], F[r], d->pos[t], F[t], W, rm->mu, w[j] / tw, Wx);
                        else if (rm->enc == EN_DELTA_ROT)
                            add_rotated(n, wp[j], wr[j], F[r], Fa, w[j] / tw * sc[j], Wx);
                        else
                            add_local(n, rm->enc, wp[j], wr[j], W, skin, sc[j], w[j] / tw, Wx);
                    }
                    Wq = Wx;
                }
                double t1 = mim_now();
                mim_xfer_options_t xr = *xo;
                if (rm->max_iter && !plain && !xr.max_iterations)
                    xr.max_iterations = rm->max_iter;
                if (skeleton && !xr.max_iterations)
                    xr.max_iterations = 1;
                if (mim_xfer_transfer(ls, Wq, n, frames, u, L, &xr, out, &rep, &err)) {
                    mim_index_close(&ix);
                    goto fail;
                }
                record(&rows[N_METHOD + N_EXTRA + m], out, truth, region, n, p, t0, t1, mim_now(), &rep);
            }
        }
        mim_index_close(&ix);
        fprintf(stderr, "%s: subject %u of %u\n", d->name, a + 1, S);
    }
    printf("\n### %s: %u vertices, %u subjects x %u poses, %u queries (leave one subject out)\n\n", d->name, n, S, P,
           queries);
    printf("The index's first hit has the true pose in %u of %u queries; %u of its %u hits (k = %d asked) do.\n\n",
           right_class, queries, same_pose_hits, hits_total, K_ASK);
    printf("| method | mean mm | p95 mm |");
    for (int g = 0; g < BENCH_REGIONS; g++)
        printf(" %s |", bench_region_names[g]);
    printf(" frames ms | key frame ms | solves |\n|---|---:|---:|");
    for (int g = 0; g < BENCH_REGIONS; g++)
        printf("---:|");
    printf("---:|---:|---:|\n");
    for (uint32_t ki = 0; ki < N_K; ki++)
        for (int wt = 0; wt < N_WEIGHTING; wt++)
            for (int corrected = 0; corrected < 2; corrected++) {
                row_t *r = &rows[method_index(ki, wt, corrected)];
                if (!r->runs)
                    continue;
                char name[200];
                method_name(ki, wt, corrected, name, sizeof name);
                print_row(r, name);
            }
    for (int x = 0; x < N_EXTRA && !new_only && !gated_only; x++)
        print_row(&rows[N_METHOD + x], extra_names[x]);
    for (uint32_t m = 0; m < N_REL; m++)
        if (rows[N_METHOD + N_EXTRA + m].runs)
            print_row(&rows[N_METHOD + N_EXTRA + m], rel_methods[m].name);
    /* where the error is, by pose (issue 29: before tuning) */
    printf("\nMean mm by query pose (p1 .. p%u):\n\n| method |", P - 1);
    for (uint32_t p = 1; p < P && p < MAX_POSES; p++)
        printf(" p%u |", p);
    printf("\n|---|");
    for (uint32_t p = 1; p < P && p < MAX_POSES; p++)
        printf("---:|");
    printf("\n");
    for (uint32_t m = 0; m < N_REL; m++) {
        const row_t *r = &rows[N_METHOD + N_EXTRA + m];
        if (!r->runs || !rel_methods[m].gated_set)
            continue;
        printf("| %s |", rel_methods[m].name);
        for (uint32_t p = 1; p < P && p < MAX_POSES; p++)
            printf(" %.2f |", r->pcnt[p] ? r->psum[p] / (double)r->pcnt[p] : 0.0);
        printf("\n");
    }
    if (other_pose)
        printf("\n(--other-pose: the templates are the nearest over all angles in poses other than the query's.)\n");
    if (no_rest_ref)
        printf("\n(--no-rest-ref: %u references taken among poses other than A's rest.)\n", wrong_refs);
    if (n_refd) {
        double med = bench_median(refd, (int)n_refd);
        printf("\nReference to A's rest, all-angle distance (rad): min %.3f median %.3f max %.3f (rms deg: %.2f %.2f %.2f)\n",
               refd[0], med, refd[n_refd - 1], refd[0] / sqrt((double)na) * 180.0 / M_PI,
               med / sqrt((double)na) * 180.0 / M_PI, refd[n_refd - 1] / sqrt((double)na) * 180.0 / M_PI);
    }
    if (n_hitd) {
        double med = bench_median(hitd, (int)n_hitd);
        printf("\nQuery to its first hit, all-angle rms (deg): min %.3f median %.3f max %.3f\n", hitd[0], med,
               hitd[n_hitd - 1]);
    }
    if (n_spread) {
        printf("\nThe other subjects' pose spread (mim_session_pose_spread, deg), per held-out subject:");
        for (uint32_t i = 0; i < n_spread; i++)
            printf(" %.2f", spreads[i]);
        printf("\n");
    }
    if (n_agree) {
        double med = bench_median(agree, (int)n_agree);
        printf("\nThe first two hits apart, all-angle rms (deg): min %.3f median %.3f max %.3f\n", agree[0], med,
               agree[n_agree - 1]);
    }
    printf("\nReferences: %u of A's rest queries' hits had pose 0; %u subjects missing from them took their pose 0.\n",
           rest_right, ref_misses);
    rc = 0;
fail:
    if (rc)
        fprintf(stderr, "bench: %s\n", mim_error_text(&err));
    for (uint32_t m = 0; m < N_ROWS; m++)
        bench_err_free(&rows[m].e), free(rows[m].t_prep), free(rows[m].t_key);
    for (uint32_t t = 0; t < T; t++)
        free(F[t]), free(WT[t]);
    free(WT), free(Wx), free(ang);
    for (int j = 0; j < K_ASK; j++)
        free(Fc[j]);
    free(F), free(lm), free(W), free(Fa), free(Fb), free(out), free(skin), free(region), free(ids), free(subj),
        free(pose), free(sp), free(pp);
    mim_xfer_solver_close(&ls);
    mim_xfer_topology_close(&topo);
    return rc;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    mim_xfer_options_t xo = {0};
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i))
            continue;
        if (!strcmp(argv[i], "--new-only")) {
            new_only = 1;
        } else if (!strcmp(argv[i], "--gated-only")) {
            gated_only = 1;
        } else if (!strcmp(argv[i], "--other-pose")) {
            other_pose = 1;
        } else if (!strcmp(argv[i], "--no-rest-ref")) {
            no_rest_ref = 1;
        } else if (!strcmp(argv[i], "--proportions") && i + 1 < argc) {
            body_proportions = !strcmp(argv[++i], "body");
        } else if (!strcmp(argv[i], "--iterations") && i + 1 < argc) {
            xo.max_iterations = (uint32_t)strtoul(argv[++i], NULL, 10);
            xo.tol = -1, xo.no_early_stop = 1;
        } else if (!strcmp(argv[i], "--damping") && i + 1 < argc) {
            xo.damping = strtod(argv[++i], NULL);
        } else if (!strcmp(argv[i], "--settle") && i + 1 < argc) {
            xo.settle = strtod(argv[++i], NULL);
        } else {
            fprintf(stderr, "usage: %s [--vertices N] [--mh DIR | --no-mh] [--iterations N] [--settle S] [--damping D] [--new-only] [--gated-only] [--other-pose] [--no-rest-ref] [--proportions canonical|body]\n", argv[0]);
            return 2;
        }
    }
    printf("iterations: %s, settle %g\n", xo.max_iterations ? "fixed" : "mimic's default",
           xo.settle != 0 ? xo.settle : MIM_XFER_DEFAULT_SETTLE);
    return bench_sets_run(&sets, 4, 12, run_set, &xo);
}
