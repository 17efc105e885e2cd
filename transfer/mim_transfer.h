/* mimic transfer: intrinsic encoding and Cholesky-reused pose transfer
 * (seed 000, Lifkooee et al. 2019, Sections 3.1 and 3.4).
 *
 * Computation over caller-owned arrays: nothing here opens the store. The
 * caller keeps what is worth keeping (a template's frames, an avatar's
 * encoding W) and hands it back.
 *
 * Objects:
 *   mim_xfer_topology_t  one connectivity: one-ring adjacency (the uniform
 *                        Laplacian L), the faces, the fixed frame neighbour.
 *   mim_xfer_solver_t    one (connectivity, constrained vertex set,
 *                        formulation): the CHOLMOD analysis and factor, done
 *                        once at open and reused by every transfer, plus
 *                        all workspaces (no allocation per transfer).
 *
 * Arrays: positions are float x y z per vertex (mim_mesh_t layout); frames
 * are double, 9 per vertex, F(v_i) column-major: frames[9i+3k+c] is
 * component c of f_{k+1} (f1 normal, f2 tangent, f3 = f1 x f2); encodings W
 * are double, 3 per vertex. */
#ifndef MIM_TRANSFER_H
#define MIM_TRANSFER_H

#include "mim_core.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- connectivity and the uniform Laplacian (laplacian.c) ---- */
typedef struct mim_xfer_topology mim_xfer_topology_t;

/* Builds the one-ring adjacency from triangles (3 * n_faces indices).
 * Returns 0, MIM_EINVAL (NULL, zero counts), MIM_EINDEX (index past
 * n_vertices), MIM_EFORMAT (a face repeating a vertex) or MIM_ENOMEM. */
int mim_xfer_topology_open(mim_xfer_topology_t **out, uint32_t n_vertices, const uint32_t *faces,
                           uint32_t n_faces, mim_error_t *err);
void mim_xfer_topology_close(mim_xfer_topology_t **t); /* accepts NULL, nulls */
uint32_t mim_xfer_topology_n_vertices(const mim_xfer_topology_t *t);
/* Its faces (3 * *n_faces, the copy the topology keeps; valid until close). */
const uint32_t *mim_xfer_topology_faces(const mim_xfer_topology_t *t, uint32_t *n_faces);
/* Sorted one-ring neighbours of v (deg(v) = *count); NULL if v is out of range. */
const uint32_t *mim_xfer_neighbors(const mim_xfer_topology_t *t, uint32_t v, uint32_t *count);
/* y = L x (3 columns, x y z per vertex), L_ii = deg(v_i), L_ij = -1 on edges. */
void mim_xfer_laplacian_apply(const mim_xfer_topology_t *t, const double *x, double *y);

/* Checks that a mesh is on this connectivity (same vertex count, same
 * faces) and has finite positions: MIM_ETOPOLOGY / MIM_ENONFINITE with the
 * vertex or face in the message; origin names the mesh in it. */
int mim_xfer_check_mesh(const mim_xfer_topology_t *t, const mim_mesh_t *m, const char *origin,
                        mim_error_t *err);

/* ---- local frames (frames.c) ---- */
/* frames (9 * n) of the mesh with these positions (3 * n floats). */
void mim_xfer_frames(const mim_xfer_topology_t *t, const float *positions, double *frames);
/* The same from double positions. */
void mim_xfer_frames_d(const mim_xfer_topology_t *t, const double *positions, double *frames);

/* ---- encoding W = F^T L X (encode.c) ---- */
/* W (3 * n) of the mesh with these positions and their frames (from
 * mim_xfer_frames on the same positions). */
void mim_xfer_encode(const mim_xfer_topology_t *t, const float *positions, const double *frames,
                     double *W);
/* delta_i = F(v_i) W_i (3 * n): the Laplacian offsets W asks for in frames. */
void mim_xfer_decode(uint32_t n_vertices, const double *frames, const double *W, double *delta);

/* The stored encoding of a template (mim_db_encoding_t): frames6 (6 * n
 * floats: f1 and f2 of each vertex) and W (3 * n floats) of the mesh with
 * these positions. work: 12 * n doubles of scratch, or NULL to allocate
 * it. MIM_ENOMEM only. */
int mim_xfer_encoding_compute(const mim_xfer_topology_t *t, const float *positions, float *frames6, float *W,
                              double *work, mim_error_t *err);
/* Back to the solver's form: frames (9 * n doubles, f3 = f1 x f2, made
 * orthonormal again) and W (3 * n doubles); either pair may be NULL. */
void mim_xfer_encoding_unpack(uint32_t n_vertices, const float *frames6, const float *W, double *frames,
                              double *W_out);

/* ---- the constrained solver (solver.c) ---- */
typedef enum mim_xfer_formulation {
    /* min ||L X - F*W||^2 over the free vertices, constrained vertices fixed:
     * normal matrix L_f^T L_f (mimic's default: about half the error). */
    MIM_XFER_LEAST_SQUARES = 0,
    /* The paper's system (3): L^c X_f = F*W + b^c, constrained rows and
     * columns removed. */
    MIM_XFER_SQUARE = 1
} mim_xfer_formulation_t;

typedef struct mim_xfer_solver_options {
    mim_xfer_formulation_t formulation; /* 0: least squares */
    int supernodal;                     /* 0: simplicial (faster at this size) */
    /* Least squares only. 0 (default): factor L^c and solve the normal
     * equations through a rank-c update (Woodbury; solver.c), so a solve
     * costs one L^c solve plus an n_free x c product. 1: factor the normal
     * matrix L_:f^T L_:f itself (about 2.7x the fill; kept as the
     * reference the bench compares against; also used when more than
     * MIM_LANDMARKS_MAX vertices are constrained). */
    int normal_factor;
} mim_xfer_solver_options_t;

typedef struct mim_xfer_solver mim_xfer_solver_t;

/* Analyses and factors once for this connectivity and constrained vertex
 * set (count >= 1, distinct, < n; every connected component of the mesh
 * must hold one). t must outlive the solver. One transfer at a time per
 * solver (workspaces are shared). Returns 0, MIM_EINVAL, MIM_ETOPOLOGY (a
 * component without constraint), MIM_ENOMEM, or MIM_EUNSUPPORTED (CHOLMOD
 * failed: the message says why). */
int mim_xfer_solver_open(mim_xfer_solver_t **out, const mim_xfer_topology_t *t,
                         const uint32_t *constrained, uint32_t count,
                         const mim_xfer_solver_options_t *opt, mim_error_t *err);
void mim_xfer_solver_close(mim_xfer_solver_t **s); /* accepts NULL, nulls */
/* A solver of the same system as base (its connectivity, constrained set
 * and formulation) that shares base's factor and everything else that
 * depends only on those, read-only, with workspaces of its own: so that
 * many avatars of one store (serve's sessions) hold one factor. Either
 * may be closed first; the last frees the factor. Each solver is used by
 * one thread at a time, as before; two sharing one factor may solve at
 * once. Its stats count its own solves (no analysis, no factorisation).
 * Errors: MIM_EINVAL, MIM_ENOMEM, MIM_EUNSUPPORTED. */
int mim_xfer_solver_share(mim_xfer_solver_t **out, mim_xfer_solver_t *base, mim_error_t *err);

typedef struct mim_xfer_solver_stats {
    uint32_t n_free, n_constrained;
    uint64_t analyses, factorizations, solves; /* counted since open */
    double t_analyze, t_factorize;             /* seconds */
    double factor_nnz;                         /* entries of the Cholesky factor */
} mim_xfer_solver_stats_t;
void mim_xfer_solver_stats(const mim_xfer_solver_t *s, mim_xfer_solver_stats_t *st);
/* One plain CHOLMOD solve with the cached factor (L^c, or the normal
 * matrix with normal_factor) and a 3-column right-hand side (3 * n_free
 * doubles, column-major x then y then z) into x (same layout): the
 * reference the bench measures an iteration against. */
int mim_xfer_solver_solve(mim_xfer_solver_t *s, const double *rhs, double *x, mim_error_t *err);
/* The same for the first `columns` (1..3) of the right-hand side (x gets
 * as many): a thread's share of a solve split across threads, which
 * bench/keyframe.c measures against the whole. A solver keeps workspaces
 * for one column count: alternating counts reallocates them. */
int mim_xfer_solver_solve_columns(mim_xfer_solver_t *s, const double *rhs, uint32_t columns, double *x,
                                  mim_error_t *err);

/* ---- the transfer iteration (transfer.c) ---- */
#define MIM_XFER_DEFAULT_MAX_ITERATIONS 10u
#define MIM_XFER_DEFAULT_TOL 1e-4     /* metres: largest vertex move */
/* The result no longer moves: the iteration stops once the largest vertex
 * move falls below this fraction of the targets' extent (the diagonal of
 * their bounding box: 18 mm on a person, whatever the unit). Against
 * iterating on to the 0.1 mm floor: plain synth's mean error +0.75 %,
 * imitation's unchanged (its poses lie between the templates: nothing
 * settles early), mh-bodies' lower; the session's relative transfer on
 * synth settles after two solves instead of 3.3. 1.25 % and more cost
 * plain synth over 1 % (bench/transfer_accuracy.c, bench/blend_accuracy.c
 * --settle; bench/RESULTS.md, "Key frames within twice a solve"). */
#define MIM_XFER_DEFAULT_SETTLE 0.01
/* Defaults measured with bench/transfer_accuracy.c (synth 7k and mh-bodies
 * 13k vertices): without damping the error is lowest at iteration 2 and
 * then grows; damping 0.5 with an early stop as soon as the largest move no
 * longer halves gives the lowest mean and p95 on both (3-4 iterations).
 * The tolerance is a floor: the iteration rarely gets that still. */
#define MIM_XFER_DEFAULT_DAMPING 0.5    /* step fraction towards each new solve */
#define MIM_XFER_DEFAULT_STOP_RATIO 0.5 /* stop when the move no longer halves */

typedef struct mim_xfer_options {
    uint32_t max_iterations; /* 0: MIM_XFER_DEFAULT_MAX_ITERATIONS */
    /* Convergence: stop when the largest vertex move falls below tol
     * metres. 0: the larger of MIM_XFER_DEFAULT_TOL and settle times the
     * targets' extent (the diagonal of their bounding box; 0 for one
     * target); > 0: tol exactly; < 0: never converge. */
    double tol;
    double settle;           /* 0: MIM_XFER_DEFAULT_SETTLE; < 0: none (the default tol alone) */
    double damping;          /* 0: MIM_XFER_DEFAULT_DAMPING; in (0, 1] */
    /* Early stop. With k counting the iterates so far (the solves, plus one
     * for a warm start) and move_k the largest vertex move from iterate
     * k-1 to k: from k = 3 on, stop as soon as the move no longer shrinks
     * by stop_ratio, move_k > stop_ratio * move_{k-1} (with the default
     * 0.5: no longer halves), and return the mean of the last two
     * iterates, the middle of an oscillation. It is tested before tol. */
    int no_early_stop;       /* 1: never stop early (only tol or the cap) */
    double stop_ratio;       /* 0: MIM_XFER_DEFAULT_STOP_RATIO; > 0 */
    /* Warm start (3 * n, optional): a previous solution, e.g. the last key
     * frame's of a real-time stream. It counts as the first iterate: the
     * first solve (with frames0) is damped from it and the move tests count
     * it, so the iteration stops about one solve sooner; on slowly changing
     * landmarks that costs ~0.6x the time at ~13 % more error (bench/warm_start.c).
     * NULL: start from frames0 alone (the paper). */
    const float *start;
    const float *truth;      /* optional ground truth (3 * n) for error_by_iteration */
    double *error_by_iteration; /* optional: max_iterations entries, mean |x - truth| */
} mim_xfer_options_t;

typedef struct mim_xfer_report {
    uint32_t iterations; /* solves done */
    double last_move;    /* largest vertex move of the last iteration (metres) */
    int converged;       /* last_move under the tolerance (tol, or settle times the targets' extent) */
    int early_stopped;   /* stopped because the move no longer shrank by stop_ratio; the
                            result is the mean of the last two iterates */
} mim_xfer_report_t;

/* Transfers the avatar (its encoding W, 3 * n) to the pose given by the
 * frames `frames0` (9 * n, usually the template's) and the positions of the
 * solver's constrained vertices `targets` (3 * count floats, in the order
 * given to mim_xfer_solver_open). Mode (b): a solver on all landmark
 * vertices, targets = the tracked landmarks. Mode (a) "template only": the
 * same solver, targets = mim_xfer_retarget_landmarks of the template (the
 * paper's single pelvis anchor also works, a solver on that vertex alone,
 * but nothing then holds the low frequencies and the body drifts: see
 * bench/RESULTS.md).
 * n_vertices (the length of W, frames0 and out, in vertices) must be the
 * connectivity's, n_targets the solver's constrained count.
 * Writes 3 * n floats to out. report may be NULL. Returns 0, MIM_EINVAL
 * (NULL arrays, bad options, wrong landmark count), MIM_ETOPOLOGY (vertex
 * count differs), MIM_ENONFINITE (a NaN/inf target or W) or
 * MIM_EUNSUPPORTED (solve failed). */
int mim_xfer_transfer(mim_xfer_solver_t *s, const double *W, uint32_t n_vertices,
                      const double *frames0, const float *targets, uint32_t n_targets,
                      const mim_xfer_options_t *opt, float *out, mim_xfer_report_t *report,
                      mim_error_t *err);
/* The same with the first solve's right-hand side given as Laplacian
 * offsets (3 * n) instead of frames: offsets0_i = F0(v_i) W_i, as
 * mim_xfer_skin_offsets and mim_xfer_offsets_blend make them without
 * materialising frames; later solves take their frames from the result
 * and W as mim_xfer_transfer's do. Errors as mim_xfer_transfer's. */
int mim_xfer_transfer_offsets(mim_xfer_solver_t *s, const double *W, uint32_t n_vertices, const double *offsets0,
                              const float *targets, uint32_t n_targets, const mim_xfer_options_t *opt, float *out,
                              mim_xfer_report_t *report, mim_error_t *err);

/* ---- segment skinning for the orientation drive (skin.c; issue 17) ---- */
#define MIM_XFER_SKIN_INFLUENCES 4 /* segments per vertex, as a glTF skin's JOINTS_0 */
#define MIM_XFER_SKIN_MAX_BONES 64
/* Diffusion steps of the skin's weights. bench/orient_accuracy.c's sweep
 * (0..32): mh-bodies is lowest at 2-8 (within 0.1 mm; more smears the
 * forearm's turn into the fingers), synth keeps falling to 32 (1.3 mm
 * lower there); 8 is the compromise (bench/RESULTS.md). */
#define MIM_XFER_DEFAULT_SKIN_SMOOTHING 8
/* Diffusion steps where a ball joint or the spine turns: vertices whose
 * heaviest bone (after MIM_XFER_DEFAULT_SKIN_SMOOTHING steps) is one of
 * MIM_XFER_SKIN_WIDE_SEGMENTS take the weights of this many steps. Soft
 * tissue at the shoulders and hips follows both segments over a wide band
 * (the rigid fits of upper arms and thighs leave 16-26 mm, forearms 2);
 * wrists and ankles turn sharply. On the imitation set the orientation
 * drive's mean falls 1.4 %, on synth 3.3 %, on mh-bodies 1.8 %; 64 steps
 * gain nothing more (bench/RESULTS.md, "The skin at the shoulders and
 * hips"). */
#define MIM_XFER_DEFAULT_SKIN_SMOOTHING_WIDE 32
/* The pelvis, chest, head, shoulders, upper arms and thighs, as bits of
 * mim_segment_names' ids. */
#define MIM_XFER_SKIN_WIDE_SEGMENTS                                                                              \
    ((1ull << 0) | (1ull << 1) | (1ull << 2) | (1ull << 3) | (1ull << 4) | (1ull << 5) | (1ull << 6) |        \
     (1ull << 11) | (1ull << 12))
/* A vertex's segments and their weights, heaviest first; the weights sum
 * to 1, unused slots weigh 0. */
typedef struct mim_xfer_skin {
    uint8_t bone[MIM_XFER_SKIN_INFLUENCES];
    float weight[MIM_XFER_SKIN_INFLUENCES];
} mim_xfer_skin_t;
/* Weights (n vertices of t) from bones (n_bones x 6 doubles: a pivot's x y
 * z, then its end's) on the mesh with these positions: the nearest bone,
 * diffused over the surface for `smoothing` steps (skin.c says how).
 * Errors: MIM_EINVAL (NULL, 0 or more than MIM_XFER_SKIN_MAX_BONES bones),
 * MIM_ENONFINITE (a bone end), MIM_ENOMEM. */
int mim_xfer_skin_from_bones(const mim_xfer_topology_t *t, const float *positions, const double *bones,
                             uint32_t n_bones, uint32_t smoothing, mim_xfer_skin_t *skin, mim_error_t *err);
/* The same with two widths: a vertex whose heaviest bone after `smoothing`
 * steps has its bit in `wide_bones` takes its weights after
 * `wide_smoothing` steps instead (ignored when not above `smoothing`).
 * The segment skin of an avatar: the defaults above, over MIM_SEGMENTS
 * bones. Errors as mim_xfer_skin_from_bones'. */
int mim_xfer_skin_from_bones_wide(const mim_xfer_topology_t *t, const float *positions, const double *bones,
                                  uint32_t n_bones, uint32_t smoothing, uint64_t wide_bones, uint32_t wide_smoothing,
                                  mim_xfer_skin_t *skin, mim_error_t *err);
/* Weights from dense per-bone weights (n_vertices x n_bones floats, >= 0,
 * e.g. a rig's skin summed per segment; bones past MIM_XFER_SKIN_MAX_BONES
 * are not read): each vertex keeps its heaviest MIM_XFER_SKIN_INFLUENCES,
 * normalised. A vertex with no weight takes fallback's entry (NULL: bone 0
 * alone); fallback may be skin itself. Returns how many did. w and skin
 * must not be NULL. */
uint32_t mim_xfer_skin_from_dense(uint32_t n_vertices, const float *w, uint32_t n_bones, const mim_xfer_skin_t *fallback,
                                  mim_xfer_skin_t *skin);
/* The blended rotation of one vertex from its segments' rotations (rot:
 * unit quaternions indexed by bone, one for every bone id the skin uses). */
mim_quat mim_xfer_skin_rotation(const mim_xfer_skin_t *s, const mim_quat *rot);
/* The frames (9 * n) of a pose: each vertex's rest frame (rest_frames,
 * mim_xfer_frames of the rest mesh) turned by its blended rotation (rot as
 * above; no argument may be NULL).
 * mim_xfer_transfer with these frames and one iteration is the
 * orientation-driven solve. */
void mim_xfer_skin_frames(uint32_t n_vertices, const mim_xfer_skin_t *skin, const double *rest_frames,
                          const mim_quat *rot, double *frames);
/* The Laplacian offsets (3 * n) the solve asks for in those frames,
 * without the frames: each vertex's rest offset (rest_offsets,
 * mim_xfer_decode of the rest frames and W) turned by its blended
 * rotation, R_i F_i W_i. mim_xfer_transfer_offsets with them and one
 * iteration is the orientation-driven solve, a few times cheaper than the
 * frames' way and equal to it within rounding. No argument may be NULL;
 * the arrays must not overlap. */
void mim_xfer_skin_offsets(uint32_t n_vertices, const mim_xfer_skin_t *skin, const double *rest_offsets,
                           const mim_quat *rot, double *offsets);
/* ---- several templates (blend.c; issue 15) ---- */
#define MIM_XFER_BLEND_MAX 16 /* templates one blend reads at most */
/* The per-vertex weighted average of k templates' frames (each 9 * n,
 * rotations) into out (9 * n; may be frames[0]). weights (k, >= 0; NULL:
 * equal); a weight that is not a positive finite number counts 0, and
 * when none is positive out gets frames[0]. k above MIM_XFER_BLEND_MAX
 * reads the first MIM_XFER_BLEND_MAX. */
void mim_xfer_frames_blend(uint32_t n_vertices, uint32_t k, const double *const *frames, const double *weights,
                           double *out);
/* The Laplacian offsets (3 * n) of that blend applied to W (3 * n), without
 * the frames: F_blend(v_i) W_i, with each template's frames given as
 * quaternions (quats: k arrays of 4 * n, mim_xfer_frames_to_quats of its
 * frames, which a caller keeps with the template). Weights as
 * mim_xfer_frames_blend's; the same within rounding as
 * mim_xfer_decode(n, blended frames, W) at a fraction of the cost. */
void mim_xfer_offsets_blend(uint32_t n_vertices, uint32_t k, const double *const *quats, const double *weights,
                            const double *W, double *offsets);
/* The segment correction: the rotation of each of the MIM_SEGMENTS body
 * segments that takes the landmark skeleton `from` (3 * map->count floats,
 * a template's landmarks) onto `to` (the target's). With a skin,
 * mim_xfer_skin_frames(n, skin, template_frames, R, out) turns the
 * template's frames by them. Errors: MIM_EUNSUPPORTED (a default landmark
 * missing from map), MIM_ENONFINITE. */
int mim_xfer_segment_correction(const mim_landmark_map_t *map, const float *from, const float *to,
                                mim_quat R[MIM_SEGMENTS], mim_error_t *err);
/* The template's turn on the avatar's own frames (deformation transfer of
 * the frames): out_i = P_i R_i^T A_i, where P are the template's frames in
 * the pose, R the same subject's frames in the avatar's rest pose (its
 * reference template) and A the avatar's rest frames (each 9 * n). The
 * template's frames carry its body's surface (a thicker arm tilts its
 * normals); P R^T keeps only how its surface turned from rest to pose.
 * out may be any of the inputs. */
void mim_xfer_frames_relative(uint32_t n_vertices, const double *pose, const double *ref, const double *avatar_rest,
                              double *out);
/* The avatar's encoding in the templates' pose: W_avatar (3 * n) plus the
 * weighted mean over k templates of how each one's encoding changed from
 * its reference (W_ref[j], the same subject in the avatar's rest pose) to
 * the pose (W_pose[j]), the change times scale[j] (NULL: 1). W is only
 * nearly pose-invariant: a bent joint folds the surface, and the folds of
 * bodies in one pose are alike. weights as mim_xfer_frames_blend's; none
 * positive (or k = 0): out = W_avatar. out may be W_avatar. */
void mim_xfer_encoding_relative(uint32_t n_vertices, uint32_t k, const double *const *W_pose,
                                const double *const *W_ref, const double *weights, const double *scale,
                                const double *W_avatar, double *out);
/* How unlike two bodies' builds are, scale-free: over every pair of
 * landmarks (count of them, 3 * count floats each, taken in one pose,
 * e.g. the avatar's rest and a reference's), the pair's distance divided
 * by the sum of all its set's pair distances, compared between the sets;
 * the root of the summed squared differences. 0 for one body at any size
 * (16 landmarks: about 0.001-0.005 between two people).
 * Relative transfer weighs a template's change by it: a subject built like
 * the avatar folds as the avatar would (bench/blend_accuracy.c). NaN when
 * a landmark is not finite or a set has all its landmarks at one point. */
double mim_xfer_build_distance(const float *a, const float *b, uint32_t count);
/* The scale for mim_xfer_encoding_relative: rms(W_avatar) / rms(W_ref)
 * over n vertices (3 * n each). W is a Laplacian in local frames, so it
 * grows with the body's size; a smaller body folds less in millimetres.
 * NaN when W_ref is all zero or an entry of either is not finite (the
 * blend then takes 1). */
double mim_xfer_encoding_scale(uint32_t n_vertices, const double *W_avatar, const double *W_ref);
/* ---- mode (a): landmarks from the template alone (retarget.c) ---- */
/* Landmark positions (3 * map->count floats) in the template's pose with
 * the avatar's proportions: from the template's pelvis, each segment of the
 * landmark skeleton (pelvis-spine-chest-head, chest-shoulder-elbow-wrist,
 * pelvis-hip-knee-ankle) keeps the template's direction and takes the
 * avatar's rest length; the whole set is then moved so that the midpoint
 * of its ankles is the template's. avatar_rest and tmpl are full meshes (3 * n
 * floats). MIM_EUNSUPPORTED when the map is not the 16 default landmarks. */
int mim_xfer_retarget_landmarks(const mim_landmark_map_t *map, const float *avatar_rest, const float *tmpl,
                                float *out, mim_error_t *err);

/* ---- in-between landmarks along the skeleton (inbetween.c; issue 29) ---- */
/* The landmarks (3 * map->count floats, map order) at t in [0, 1] between
 * keys a and b, interpolated as a skeleton: the torso's frame slerped,
 * each bone of the landmark tree turned on a great circle in that frame
 * (opposite directions through the body's side) with its length lerped,
 * the pelvis lerped. So no bone is ever shorter or longer than both of its
 * keys' (lerped landmarks collapse a swinging arm). t = 0 and 1 give the
 * keys exactly. Errors: MIM_EUNSUPPORTED (not the 16 default landmarks),
 * MIM_EINVAL, MIM_ENONFINITE. */
int mim_xfer_landmarks_between(const mim_landmark_map_t *map, const float *a, const float *b, double t, float *out,
                               mim_error_t *err);
/* The torso's frame of a landmark set (columns: the body's left, up from
 * the pelvis to the chest, forward) as a unit quaternion x y z w: what
 * mim_xfer_key_t's torso takes. Errors as mim_xfer_landmarks_between's. */
int mim_xfer_landmarks_torso(const mim_landmark_map_t *map, const float *u, double q[4], mim_error_t *err);

/* ---- morphing between key poses (morph.c; seed 000 Section 3.5) ---- */
typedef enum mim_xfer_morph_method {
    MIM_XFER_MORPH_LINEAR = 0, /* the paper: positions interpolated linearly */
    MIM_XFER_MORPH_FRAMES = 1  /* frames slerped, landmarks lerped, one solve */
} mim_xfer_morph_method_t;
/* Each vertex frame's rotation as a unit quaternion (4 * n doubles, x y z w). */
void mim_xfer_frames_to_quats(uint32_t n_vertices, const double *frames, double *quats);
/* A key pose: its positions (3 * n floats); for FRAMES also its frames as
 * quaternions (mim_xfer_frames_to_quats of mim_xfer_frames of the
 * positions), its own encoding W (mim_xfer_encode with those frames) and
 * its landmark positions (3 * constrained count, the solver's order). */
typedef struct mim_xfer_key {
    const float *positions;
    const double *quats;
    const double *W;
    const float *landmarks;
    /* Optional (NULL: none): the key's torso frame as a quaternion x y z w
     * (mim_xfer_landmarks_torso). With both keys', FRAMES slerps each
     * vertex's frame relative to the torso and turns the result by the
     * torsos' own slerp, so that a half turn of the body turns every frame
     * the same way round (alone, each would take its own shortest way). */
    const double *torso;
} mim_xfer_key_t;
/* The in-between pose at t in [0, 1] between key poses a and b. LINEAR
 * lerps positions; FRAMES slerps frames, lerps W and solves once with the
 * solver's cached factor (allocating nothing), its landmarks lerped (here)
 * or given (mim_xfer_morph_between: e.g. mim_xfer_landmarks_between's,
 * which keep the bones' lengths); both return the keys themselves at t = 0
 * and 1. Writes 3 * n floats to out. */
int mim_xfer_morph(mim_xfer_solver_t *s, mim_xfer_morph_method_t method, const mim_xfer_key_t *a,
                   const mim_xfer_key_t *b, double t, float *out, mim_error_t *err);
/* The same with the in-between's landmarks given (3 * constrained count,
 * the solver's order; NULL: lerped); LINEAR does not read them. */
int mim_xfer_morph_between(mim_xfer_solver_t *s, mim_xfer_morph_method_t method, const mim_xfer_key_t *a,
                           const mim_xfer_key_t *b, double t, const float *landmarks, float *out, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
