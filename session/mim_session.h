/* mimic session: the one place where an opened store, its recognition
 * index, an avatar, its encoding and the avatar's Cholesky factor meet,
 * and where "landmarks -> nearest template -> its frames -> transfer"
 * (seed 000, Sections 3.3-3.4) is written once. `mimic transfer`, `mimic
 * morph`, `mimic query`'s JSON, and `mimic serve` (its API and its vest
 * loop) all go through it.
 *
 * Thread safety: every function may be called from many threads at once.
 * Queries run concurrently; solves take turns on the one factor (a mutex
 * inside the session). What the accessors return is read-only and lives
 * until mim_session_close. */
#ifndef MIM_SESSION_H
#define MIM_SESSION_H

#include "mim_core.h"
#include "mim_db.h"
#include "mim_io.h"
#include "mim_query.h"
#include "mim_transfer.h"

#include <jansson.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mim_session mim_session_t;

typedef struct mim_session_options {
    mim_xfer_formulation_t formulation; /* 0: least squares (mim_xfer_solver_options_t) */
    uint64_t map_size;                  /* the store's LMDB map size (mim_db_options_t); 0: default */
    /* An avatar of another connectivity: its landmarks (a file of either
     * form, mim_ingest_foreign_landmarks' (c)); NULL: NAME.landmarks.json
     * beside it, else a built-in map of its connectivity. */
    const char *avatar_landmarks;
    mim_log_fn log;                     /* registering and binding a foreign avatar; NULL: quiet */
    void *log_ctx;
    /* A glTF avatar: only the primitives of the meshes (or nodes) of these
     * names (`--avatar-mesh`, repeatable); 0: the whole scene. */
    const char *const *avatar_meshes;
    uint32_t n_avatar_meshes;
    /* A foreign avatar whose registration's surface distance p95 is over
     * this (mm) is refused; 0: MIM_INGEST_DEFAULT_MAX_DISTANCE_MM. */
    double max_distance_mm;
} mim_session_options_t;

/* Opens store read-only with its connectivity, landmark map and index (if
 * it has one). Errors, one line naming the store: the store's own (cannot
 * open, damaged, another schema), MIM_ENOTFOUND for an empty store,
 * MIM_ENOMEM. opt may be NULL. On error *out is NULL. */
int mim_session_open(mim_session_t **out, const char *store, const mim_session_options_t *opt, mim_error_t *err);
/* Loads the avatar, which transfers and morphs need: an all-digit argument
 * is a template id, anything else a mesh file; then factorises the
 * avatar's system for the store's landmark vertices (seed 000, eq. 3).
 * A mesh of another connectivity (issue 13) is registered once onto the
 * store's (its landmarks from opt->avatar_landmarks, a sidecar or a
 * built-in map; the nearest template through the index), its vertices
 * are bound to that proxy (mim_reg_bind), and the binding is kept in the
 * store, so a later session finds it; every transfer then runs on the
 * proxy, and mim_session_output maps a result onto the avatar's own
 * vertices. Errors, one line naming the file or the id: the mesh
 * reader's, MIM_ENOTFOUND for an unknown template id, MIM_ENOINDEX for a
 * foreign avatar when the store has no index, the landmarks' and the registration's (a
 * surface distance p95 over MIM_INGEST_DEFAULT_MAX_DISTANCE_MM is
 * MIM_ETOPOLOGY). The binding is cached under the avatar, its landmarks and
 * the store's connectivity; a store of an older schema version is not
 * written to (no cache; a warning). Caching reopens the store, so what
 * mim_session_query returned before this call is invalid after it. A
 * session has one avatar, and one attempt at it: a second call is
 * MIM_EINVAL. */
int mim_session_load_avatar(mim_session_t *s, const char *avatar, mim_error_t *err);
/* Another session on base's store (issue 16: many vests, each with its
 * own avatar, in one process): it shares base's store, index,
 * connectivity and completion table, and has its own avatar, factor and
 * template cache (mim_session_load_avatar next). LMDB allows a store to be
 * open once per process, hence the sharing. base must have loaded its own
 * avatar first, if it ever will (a foreign avatar's binding reopens the
 * store), and must be closed after every fork; a fork of a fork shares
 * the same base. A fork does not keep a foreign avatar's binding in the
 * store (a warning says so). opt NULL: base's. Errors: MIM_ENOMEM. */
int mim_session_fork(mim_session_t **out, mim_session_t *base, const mim_session_options_t *opt, mim_error_t *err);
void mim_session_close(mim_session_t **s); /* accepts NULL; nulls the pointer */

/* ---- what the session holds (read-only, valid until close; the avatar's
 * after mim_session_load_avatar) ---- */
const char *mim_session_store(const mim_session_t *s);  /* the store's path */
const char *mim_session_avatar(const mim_session_t *s); /* the path, or "template N" */
/* The store's faces with the avatar's rest positions (a foreign avatar's
 * proxy's): what transfers and morphs compute, 3 * n_vertices floats. */
const mim_mesh_t *mim_session_mesh(const mim_session_t *s);
/* The avatar as it is given (its own faces and rest positions): what every
 * output is in. The same as mim_session_mesh unless the avatar is foreign. */
const mim_mesh_t *mim_session_output_mesh(const mim_session_t *s);
int mim_session_maps_output(const mim_session_t *s); /* 1: a foreign avatar, outputs go through its binding */
/* The avatar's parts (its glTF primitives, in the file's scene order; one
 * part for other formats and template ids) over the output mesh's
 * vertices and faces: *n gets their count. */
const mim_io_part_t *mim_session_output_parts(const mim_session_t *s, uint32_t *n);
/* Sets seq's parts and look (mim_io_sequence_t) to the avatar's: its
 * primitives, and its file with the read options it was loaded with, so
 * that a GLB of its poses keeps its materials and textures. */
void mim_session_output_look(const mim_session_t *s, mim_io_sequence_t *seq);
/* A computed pose (3 * mim_session_mesh n floats) as the avatar's own
 * (3 * mim_session_output_mesh n floats): through the binding, or a copy.
 * Thread-safe; allocates nothing. */
void mim_session_output(mim_session_t *s, const float *positions, float *out);
const mim_landmark_map_t *mim_session_map(const mim_session_t *s);
const mim_xfer_topology_t *mim_session_topology(const mim_session_t *s);
const double *mim_session_encoding(const mim_session_t *s); /* the avatar's W, 3 * n */
/* The index, or NULL when the store has none; and its status at open. */
const mim_query_t *mim_session_query(const mim_session_t *s);
const mim_query_status_t *mim_session_index_status(const mim_session_t *s);
/* The store's and its index's status now (issue 30: another process may
 * have grown the store since the session opened it): a fresh read of
 * mim_query_status. Errors: the store's. Thread-safe. */
int mim_session_store_status(const mim_session_t *s, mim_query_status_t *out, mim_error_t *err);
double mim_session_factor_seconds(const mim_session_t *s); /* the factorisation's time */
int mim_session_has_avatar(const mim_session_t *s); /* 1 after a successful mim_session_load_avatar */
/* The avatar's segmentation (n entries), or NULL when it could not be
 * made (or before mim_session_load_avatar, with an empty reason); then
 * *why (may be NULL) gets the reason. *from_rig (may be NULL):
 * 1 when the weights are the avatar's own skin's (a skinned glTF whose
 * joint names map to the segments), 0 when made from the geometry. */
const mim_xfer_skin_t *mim_session_skin(const mim_session_t *s, const mim_error_t **why, int *from_rig);

/* ---- an avatar's rig (rig.c; issue 28) ---- */
/* A rig whose joint names give fewer segments than this is no body rig. */
#define MIM_SESSION_RIG_MIN_SEGMENTS 12
/* Each body segment's pivot from a rig (its mapped joint nearest the
 * root; mim_vest_segments_of_joints maps the names), have[] which ones,
 * *covered how many. 0, MIM_ENOTFOUND (no joints), MIM_ENOMEM. */
int mim_session_rig_pivots(const mim_io_skin_t *skin, double pivots[3 * MIM_SEGMENTS], uint8_t have[MIM_SEGMENTS],
                           uint32_t *covered);
/* The landmarks of map (each one of the 16 default names) on mesh, placed
 * from its rig (mim_reg_rig_landmarks' rules) when the rig's joints give
 * at least MIM_SESSION_RIG_MIN_SEGMENTS segments. how gets where they came
 * from. Errors: MIM_ENOLANDMARKS with why (no rig, too few segments, a
 * joint the rules need, a landmark without a rule), MIM_EFORMAT, MIM_ENOMEM. */
int mim_session_rig_landmarks(const mim_mesh_t *mesh, const mim_io_skin_t *skin, const mim_landmark_map_t *map,
                              float *out, char *how, size_t how_size, mim_error_t *err);

/* How the avatar stands at rest (issue 28), from its landmark skeleton:
 * the upper arms' mean angle below the horizontal (+Y up) into *arm_deg,
 * and MIM_VEST_POSE_T (under MIM_SESSION_T_POSE_MAX_DEG), MIM_VEST_POSE_A
 * (under MIM_SESSION_A_POSE_MAX_DEG) or MIM_VEST_POSE_REST (arms down);
 * -1 without the shoulder and elbow landmarks or an avatar. A vest tared in
 * another pose than the avatar's rest needs --vest-pose to say which. */
#define MIM_SESSION_T_POSE_MAX_DEG 20.0
#define MIM_SESSION_A_POSE_MAX_DEG 65.0
int mim_session_rest_pose(const mim_session_t *s, double *arm_deg);

/* ---- templates ---- */
/* Template id's positions (3 * n floats) and frames (9 * n doubles); each
 * NULL to skip, from its stored encoding, or computed when the store has none.
 * label (may be NULL) gets "subject/pose". MIM_ENOTFOUND for an unknown id. */
int mim_session_template(mim_session_t *s, uint64_t id, float *positions, double *frames, char *label,
                         size_t label_size, mim_error_t *err);

/* ---- the pipeline ---- */
/* What gives a key frame its vertex frames (issue 17). */
typedef enum mim_session_drive {
    /* orientations when the request has them and the avatar is segmented;
     * else the templates' frames where relative transfer's evidence holds
     * (MIM_SESSION_DEFAULT_RELATIVE); else, with landmarks and a segmented
     * avatar, the skeleton drive (MIM_SESSION_DEFAULT_PLAIN_SKELETON); else
     * the templates' frames */
    MIM_DRIVE_AUTO = 0,
    MIM_DRIVE_TEMPLATE = 1,    /* the templates' frames, iterated (seed 000) */
    MIM_DRIVE_ORIENTATION = 2, /* the avatar's rest frames turned by the measured segment rotations, one solve */
    MIM_DRIVE_SKELETON = 3     /* the same turned by its landmark skeleton's rotations onto the landmarks, one solve */
} mim_session_drive_t;
#define MIM_SESSION_DRIVES 4
/* "auto", "template", "orientation", "skeleton" -> the drive; -1 when unknown. */
int mim_session_drive_parse(const char *name);
extern const char *const mim_session_drive_names[MIM_SESSION_DRIVES];
/* The skeleton drive where relative transfer is not taken (the plain
 * path): the avatar's own rest frames, each segment turned as its landmark
 * skeleton turns from the avatar's rest landmarks onto the landmarks
 * (mim_xfer_segment_correction, the orientation drive's skin and one
 * solve). On the imitation set, whose subjects take each pose their own
 * way and whose store slides along the surface as registered scans do,
 * the templates' frames carry another body's way of taking the pose and
 * its slide: the skeleton drive has 0.72x their error (40.3 against 55.6
 * mm with the correction's 54.3) at a quarter of the key frame's time;
 * the one-rig sets take the relative path and do not change
 * (bench/RESULTS.md "The skeleton drive on the plain path"). */
#define MIM_SESSION_DEFAULT_PLAIN_SKELETON 1

/* The template drive blends the frames of the k templates nearest to the
 * landmarks, weighted by 1 / (query distance + the floor), each first
 * turned by the segment correction when asked (issue 15). Defaults chosen
 * on the imitation set (issue 29: subjects taking each pose their own way,
 * about 11 degrees a bone apart, with soft tissue and a registered store's
 * sliding vertices; bench/RESULTS.md "Defaults chosen on the imitation
 * set"), where a real store's held-out scans gained 7 % from blending 3:
 * the 3 nearest, 55.6 mm against 58.5 for the nearest alone. The
 * segment correction: below. */
#define MIM_SESSION_DEFAULT_BLEND 3
/* The segment correction by default on the plain path only (relative
 * transfer's frames are the avatar's own already turned, and correcting
 * them by another body's landmark skeleton is far worse there): on the
 * imitation set, which takes the plain path, it gains 2.4 % (54.31 against
 * 55.64 mm); on the one-rig sets, which take the relative path, nothing
 * changes (bench/RESULTS.md "The segment correction on the plain path"). */
#define MIM_SESSION_DEFAULT_PLAIN_CORRECTION 1
#define MIM_SESSION_BLEND_DISTANCE_FLOOR 1e-3 /* radians: two equal descriptors do not weigh infinitely */

/* Relative transfer (issue 15; mim_xfer_encoding_relative): the template
 * drive adds each template's change of encoding from its subject's
 * reference (that subject's template nearest, over all index angles, to
 * the avatar's rest landmarks), scaled by rms(W_avatar) / rms(W_ref), to
 * the avatar's W, and turns the avatar's rest frames by the template's
 * turn from its reference (mim_xfer_frames_relative). It presumes that the
 * template's subject moves as the avatar's body would, which holds where
 * one rig poses every subject (synth, mh-bodies: 19.9 -> 0.7 mm and 22.5
 * -> 2.5 mm) and not for real people, whose same pose differs by about 11
 * degrees a bone and whose registered scans slide centimetres along their
 * surface: there it made transfer 20 % worse (issue 29), and 25 % on the
 * imitation set that behaves so (bench/blend_accuracy.c, bench/RESULTS.md
 * "Defaults chosen on the imitation set"). So it is taken only where that
 * evidence is there: every template's reference stands within
 * MIM_SESSION_RELATIVE_GATE_DEG rms (over all index angles) of the
 * avatar's rest, as bodies of one rig do (synth 1-2, mh-bodies 1-5
 * degrees; the imitation set's 6-8); else the plain path. A template
 * without a subject label, or whose subject has no template of the store's
 * connectivity, takes the plain path; so does a blend in which any
 * template does. */
#define MIM_SESSION_DEFAULT_RELATIVE 1
#define MIM_SESSION_RELATIVE_GATE_DEG 5.0
/* And only in a store whose subjects take a pose alike
 * (mim_session_pose_spread at most MIM_SESSION_RELATIVE_SPREAD_DEG, or
 * unknown): a reference can stand within the gate by chance where people
 * imitate poses (other draws of the imitation set: from 4.3 degrees), and
 * relative transfer then costs up to 1.5x the skeleton drive's error. One
 * rig's stores spread 1.0-3.1 degrees (synth) and 3.8-4.8 (mh-bodies), the
 * imitation set's 7.0-8.8 (bench/RESULTS.md "The skeleton drive on the
 * plain path"). */
#define MIM_SESSION_RELATIVE_SPREAD_DEG 6.0
/* The median, over the pose labels that several subjects hold, of the
 * all-angle rms (degrees, mim_index_angles) between one subject's first
 * template of that pose and the next subject's (labels in sorted order),
 * over the first MIM_SESSION_SPREAD_TEMPLATES templates and at most
 * MIM_SESSION_SPREAD_PAIRS pairs; templates with an empty subject or pose
 * are left out. landmarks: count * n_landmarks * 3 floats. NAN when no
 * pose is held by two subjects (or out of memory). */
#define MIM_SESSION_SPREAD_TEMPLATES 65536u
#define MIM_SESSION_SPREAD_PAIRS 2048u
double mim_session_pose_spread(uint32_t count, uint32_t n_landmarks, const float *landmarks,
                               const char *const *subjects, const char *const *poses);
/* Relative transfer's blend (templates from the index): each template's
 * weight is (1 / (query distance + MIM_SESSION_BLEND_DISTANCE_FLOOR)) to
 * the power MIM_SESSION_RELATIVE_DISTANCE_POWER, times (1 / (build
 * distance + MIM_SESSION_BUILD_DISTANCE_FLOOR)) to the power
 * MIM_SESSION_RELATIVE_BUILD_POWER, the build distance being
 * mim_xfer_build_distance of the avatar's rest landmarks and the
 * template's reference's. What relative transfer carries over is a body's
 * change of encoding (its folds), which follows the body's build as well
 * as the pose; the frames are nearly the avatar's own already, so the
 * error is in that change (bench/blend_accuracy.c's bounds). Templates
 * given by id keep equal weights. And the solve stops after
 * MIM_SESSION_RELATIVE_ITERATIONS solves unless the request sets
 * xfer.max_iterations: each later solve takes its frames from the last
 * result, which are worse than the turned rest frames it started from.
 * Chosen where relative transfer runs, the one-rig sets (synth and
 * mh-bodies better, the imitation set, which takes the plain path, the
 * same: bench/RESULTS.md "Relative transfer on one-rig sets"). */
#define MIM_SESSION_RELATIVE_DISTANCE_POWER 2
#define MIM_SESSION_RELATIVE_BUILD_POWER 2
#define MIM_SESSION_BUILD_DISTANCE_FLOOR 1e-3 /* about the least build distance between two people */
#define MIM_SESSION_RELATIVE_ITERATIONS 2
typedef struct mim_session_request {
    uint64_t template_id;    /* the pose's template; 0: the nearest one to landmarks, through the index */
    /* Templates to blend, given (n_templates, 1..MIM_XFER_BLEND_MAX; equal
     * weights; template_id is then not read); 0: template_id, or the index's */
    const uint64_t *template_ids;
    uint32_t n_templates;
    uint32_t blend;          /* templates the index gives to blend (1..MIM_XFER_BLEND_MAX); 0: MIM_SESSION_DEFAULT_BLEND */
    int segment_correction;  /* each template's frames turned onto the landmarks first: 1 on, -1 off, 0 the
                              * default (MIM_SESSION_DEFAULT_PLAIN_CORRECTION: on the plain path only). 1 asks
                              * for the templates' frames: the auto drive then keeps them on the plain path */
    const float *landmarks;  /* 3 * map count floats, in map order; NULL: mode (a), the template's own
                                landmarks retargeted onto the avatar's proportions */
    mim_xfer_options_t xfer; /* iterations, tolerance, damping, warm start (start: 3 * n floats) */
    uint64_t start_template; /* with xfer.start: warm-start only when the pose's template is this one
                                (a stream's last key frame); 0: whatever the template */
    /* The 17 segment rotations from the avatar's rest mesh (MIM_SEGMENTS,
     * mim_segment_names order; a landmark frame's "orientations"), or NULL;
     * orient_present (17; NULL: all) marks the ones measured. A lost one
     * takes its neighbour's (mim_vest_rotations_fill), and where no
     * neighbour has one, the template's frames drive that region. */
    const mim_quat *orientations;
    const uint8_t *orient_present;
    mim_session_drive_t drive;
    /* The template drive's relative transfer: 0 default
     * (MIM_SESSION_DEFAULT_RELATIVE: on), 1 on, -1 off (the template's
     * frames and the avatar's rest W, as before issue 15). Other values:
     * MIM_EINVAL. The orientation drive does not read it. */
    int relative;
} mim_session_request_t;

#define MIM_SESSION_LABEL_MAX 160
typedef struct mim_session_report {
    uint64_t template_id;             /* the template whose frames gave the pose (the first blended) */
    uint32_t n_templates;             /* the templates blended (1 for the orientation drive) */
    uint64_t templates[MIM_XFER_BLEND_MAX];
    double weights[MIM_XFER_BLEND_MAX]; /* each template's share of the blend (n_templates; they sum to 1) */
    int corrected;                    /* 1: their frames were turned by the segment correction */
    char label[MIM_SESSION_LABEL_MAX]; /* its "subject/pose" */
    int queried;                      /* 1: the template came from the index */
    mim_index_answer_t answer;        /* when queried: the class and its probability */
    char class_name[MIM_SESSION_LABEL_MAX]; /* when queried: the class's name */
    float landmarks[3 * MIM_LANDMARKS_MAX]; /* the targets held: given, or mode (a)'s retargeted ones */
    int warm_started;                 /* the solve started from xfer.start */
    mim_xfer_report_t xfer;           /* the solve */
    double seconds_query, seconds_template, seconds_solve;
    mim_session_drive_t drive;        /* the drive used: template, orientation or skeleton (never auto) */
    uint32_t orient_filled;           /* lost segments that took a neighbour's rotation */
    uint32_t orient_from_template;    /* vertices whose frames came from the template (no neighbour) */
    int relative;                     /* 1: relative transfer (the templates' change of W from their references) */
    uint32_t frames_turned;           /* with relative: templates whose frames were the avatar's rest frames
                                         turned (reference within the gate); the others gave their own */
    uint64_t reference_id;            /* with relative: the first template's reference; else 0 */
    uint64_t references[MIM_XFER_BLEND_MAX]; /* each template's (n_templates) */
    /* Not empty when damage in the store changed this transfer: a record
     * that could not be read made it take a fallback (relative transfer
     * off for a subject or all). One line; the output is still a body, but
     * not the one an undamaged store gives. */
    char degraded[512];
} mim_session_report_t;

/* Transfers the avatar into one pose and writes its 3 * n positions to out:
 * the template (given, or the nearest to the landmarks; or several,
 * blended: template_ids, blend), its frames (the last templates' are kept
 * between calls), the landmarks (given, or mode (a) from the first
 * template), then the iterated solve with the cached factor (seed 000, eq. 3).
 * By default relative (req->relative; MIM_SESSION_DEFAULT_RELATIVE says
 * what): the solve takes the avatar's W plus the templates' change from
 * their references, and the frames turned from the avatar's own; each
 * subject's reference is found on the first transfer that needs it (the
 * first call also reads every template's landmarks, as completion does).
 * The orientation drive (req->drive, req->orientations) still finds the
 * template (the pose's label and id), but the frames are the avatar's own
 * rest frames turned per segment, and one solve with the landmarks gives
 * the pose; each measured orientation must be a unit quaternion (within
 * MIM_ORIENT_UNIT_TOL: MIM_EINVAL, MIM_ENONFINITE naming the segment); it
 * needs landmarks ("orientations need landmarks", MIM_EINVAL)
 * and, asked for explicitly, a segmented avatar (the reason, MIM_ENOLANDMARKS
 * or the skeleton's code). The skeleton drive (asked for, or auto on the
 * plain path: MIM_SESSION_DEFAULT_PLAIN_SKELETON) finds the template the
 * same way and turns the avatar's rest frames by its landmark skeleton onto
 * the landmarks (without landmarks, the template's retargeted), one solve;
 * asked for, it needs a segmented avatar too.
 * report may be NULL. Errors: MIM_EINVAL with neither a template nor
 * landmarks, a relative other than -1, 0 or 1, or before mim_session_load_avatar; MIM_ENOTFOUND for an unknown template, or for landmarks
 * alone when the store has no index ("store has no index (run mimic
 * index)"); the query's and the solver's own (MIM_ENONFINITE, ...). */
int mim_session_transfer(mim_session_t *s, const mim_session_request_t *req, float *out,
                         mim_session_report_t *report, mim_error_t *err);

/* The in-between pose at t between key poses a and b (mim_xfer_morph),
 * with the session's factor. Its landmarks: given (3 * map count, e.g. a
 * real vest frame's at that moment), else along the skeleton
 * (mim_xfer_landmarks_between: no limb shorter or longer than both of its
 * keys'), else lerped (a map without the 16 default landmarks). */
int mim_session_morph(mim_session_t *s, mim_xfer_morph_method_t method, const mim_xfer_key_t *a,
                      const mim_xfer_key_t *b, double t, const float *landmarks, float *out, mim_error_t *err);

/* A key pose of the orientation drive: its segment rotations (17; have
 * NULL: all measured), its landmarks (3 * map count) and its template. */
typedef struct mim_session_oriented_key {
    const mim_quat *R;
    const uint8_t *have;
    const float *landmarks;
    uint64_t template_id;
} mim_session_oriented_key_t;
/* The in-between pose at t (0..1) between two keys of the orientation
 * drive: the segment rotations slerped, the landmarks given or along the
 * skeleton as mim_session_morph's, one solve (issue 17: no template in
 * between; b's template names the pose, and with template_id 0 the index
 * finds one). A segment counts as measured when both keys measured it. a,
 * b, their R and landmarks, and out must not be NULL. Errors:
 * mim_session_transfer's. */
int mim_session_morph_oriented(mim_session_t *s, const mim_session_oriented_key_t *a,
                               const mim_session_oriented_key_t *b, double t, const float *landmarks, float *out,
                               mim_error_t *err);

/* ---- completion of lost landmarks (complete.c; seed 002, Section 6) ---- */
#define MIM_COMPLETE_MIN_SEEN 4
#define MIM_COMPLETE_DEFAULT_K 3
#define MIM_COMPLETE_MAX_K 256
#define MIM_COMPLETE_DEFAULT_SIGMA_M 0.3
#define MIM_COMPLETE_DEFAULT_GAUSSIAN 0.7 /* lowest mean error on the imitation set (bench/RESULTS.md) */
/* The local Gaussian of the nearest templates (complete.c; bench/RESULTS.md) */
#define MIM_COMPLETE_LOCAL_K 5          /* templates */
#define MIM_COMPLETE_LOCAL_RIDGE 0.05   /* of their mean variance */
#define MIM_COMPLETE_LOCAL_GATE_M 0.015 /* metres: the nearest template's RMS over the seen landmarks */
typedef struct mim_session_complete_options {
    uint32_t k;                  /* templates retrieved; 0: MIM_COMPLETE_DEFAULT_K (at most MIM_COMPLETE_MAX_K) */
    double sigma;                /* metres, the blend's Gaussian; 0: MIM_COMPLETE_DEFAULT_SIGMA_M */
    int no_blend;                /* 1: the median alone (with k 1: the nearest template alone, a baseline) */
    const char *exclude_subject; /* leave that subject's templates out; NULL: none */
    /* the share of the pose classes' Gaussians' answer (mim_index_complete)
     * in each lost landmark, the rest retrieval's: 0 means
     * MIM_COMPLETE_DEFAULT_GAUSSIAN, < 0 none, 1 the Gaussians alone (the
     * templates then only for the local Gaussian, no_local: no scan of
     * them); without an index (or one without shape discriminants)
     * retrieval alone. The local Gaussian of the nearest templates, where
     * it is gated in, overlays whichever answer (complete.c). */
    double gaussian;
    const mim_index_t *index;    /* whose Gaussians; NULL: the store's (a bench's leave-one-out index) */
    int no_turn;  /* 1: a lost wrist or ankle does not turn with its seen parent bone (complete.c; a baseline) */
    int no_local; /* 1: no local Gaussian of the nearest templates (complete.c; a baseline) */
} mim_session_complete_options_t;
/* Fills the landmarks that present marks 0 (positions: 3 * map count
 * floats, NaN or anything where lost): the store's templates nearest to the
 * seen landmarks (after each one's best similarity onto them), their
 * per-coordinate median, and that median blended onto the seen landmarks
 * with Gaussian weights (complete.c says how); mixed with the pose
 * classes' conditional answer (options' gaussian). out gets every landmark
 * (the seen ones unchanged), completed[l] 1 for each filled one. A
 * complete frame comes back as it is. opt may be NULL. The first call reads every template's
 * landmarks from the store (kept until close). Errors: MIM_EINVAL (fewer
 * than MIM_COMPLETE_MIN_SEEN seen), MIM_ENOTFOUND (no template to use), the
 * store's. Thread-safe. */
int mim_session_complete(mim_session_t *s, const float *positions, const uint8_t *present,
                         const mim_session_complete_options_t *opt, float *out, uint8_t *completed, mim_error_t *err);

/* ---- query results as JSON (schemas/query.schema.json, one frame) ---- */
/* {"class": ..., "probability": ..., "results": [{"id", "subject", "pose",
 * "distance"}, ...]} for an answer and its hits; NULL when out of memory.
 * The caller owns the reference. */
json_t *mim_session_answer_json(const mim_query_t *q, const mim_index_answer_t *a, const mim_index_hit_t *hits);

#ifdef __cplusplus
}
#endif
#endif
