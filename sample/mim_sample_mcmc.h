/* mimic sample: seed 002's lifting by sampling (Sections 3-5): the pose-pair
 * model the chains walk in, the physical prior of eq. 2, the likelihood of
 * eqs. 6 and 9 over a set of 2D annotations, and the Metropolis-Hastings
 * chain with the velocity-biased proposal (eq. 12) and the truncated
 * density (eq. 11). Computation over caller arrays: no file, no print, no
 * thread (the program runs one chain per thread; everything built here is
 * read-only once built and may be shared by the chains).
 *
 * Choices where the paper is silent (and why):
 * - theta, the parameters (Section 3's "two root rotations, two root
 *   translations and the rotations of the non-root joints"): per person the
 *   root's rotation and translation and a local rotation for each of the
 *   11 joints with a child (a leaf's rotation moves nothing), over the bone
 *   vectors of a rest pose-pair (the chain's seed). Person A's root is held
 *   where the seed has it: the likelihood and the prior do not change when
 *   the whole pair moves rigidly, so that motion would only be a random
 *   walk the chain pays for. 72 free parameters in 24 groups of 3.
 * - The joint-angle validity of eq. 2 (the paper uses Akhter & Black's
 *   learned limits): a nonparametric model learned from the prior motions.
 *   12 checks per person, each a bone's direction in a frame made from the
 *   joints it depends on (the pelvis frame for the spine, the thighs and
 *   the upper body's turn; the chest frame for the head and upper arms;
 *   the upper bone's frame for forearms and shins, conditioned on the upper
 *   bone as Akhter & Black condition them). A check is valid within
 *   MIM_PAIRS_VALID_TOL of some example of the prior (both people, and
 *   the mirror image of every example); theta-bar's distance is the
 *   excess angle beyond it. isvalid = 0 beyond 8 invalid checks (the
 *   paper's number).
 * - eq. 6's views: m views drawn from eq. 5's KDE once per chain (and per
 *   restart) and held, so that f(theta|D) is one deterministic function
 *   for the chain and Metropolis-Hastings samples it exactly; views drawn
 *   afresh at every step would make a noisy target that sticks at lucky
 *   overestimates.
 * - eq. 9 in 2D: the projection along a view is orthographic (the pair is
 *   small against the camera distance); every 2D pose-pair, annotation or
 *   projection, is centred and scaled to unit RMS radius before comparing,
 *   since pixels and metres do not compare; M of eq. 9 is then the 2D
 *   rotation of least squares. "A subset of D with similar views": the
 *   annotations whose view is within sigma_v (eq. 5's bandwidth) of the
 *   view drawn (the 8 nearest views when fewer); among them the 8 nearest
 *   by the aligned Cartesian distance are measured with the density's own
 *   distance (d_I, or 2D shape contexts), since the max of eq. 9 is
 *   decided among the near ones.
 * - eq. 12: the differential of annotation p is the change of each
 *   parameter group's 2D counterpart from p to the next annotation of the
 *   same shot (one camera's video): the 2D angle of a joint's bones, of a
 *   person's pelvis-to-neck line for a root's rotation, and B's pelvis
 *   relative to A's (scaled to the pose-pair's RMS radius) for B's root
 *   translation. A group's three components share the variance. */
#ifndef MIM_SAMPLER_H
#define MIM_SAMPLER_H

#include "mim_sample.h"

#include <stdatomic.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- the pose-pair model (skeleton.c) ---- */
#define MIM_PAIRS_ROT 12                      /* per person: the root, then 11 joints with a child */
#define MIM_PAIRS_GROUPS (2 * MIM_PAIRS_ROT + 2) /* rotations of A, of B, then A's and B's root translation */
#define MIM_PAIRS_GROUP_TRANS(person) (2 * MIM_PAIRS_ROT + (person))
/* The joint (mim_sample_joint_names index) of rotation r; the parent of a
 * joint (-1 for the pelvis). */
extern const int8_t mim_pairs_rot_joint[MIM_PAIRS_ROT];
extern const int8_t mim_pairs_parent[MIM_PAIR_PERSON_JOINTS];
/* Whether group g moves (A's root rotation and translation do not). */
int mim_pairs_group_free(int g);

typedef struct mim_pairs_pose {
    double offset[2][MIM_PAIR_PERSON_JOINTS][3]; /* rest bone vectors from the parent (world, metres) */
    mim_quat rot[2][MIM_PAIRS_ROT];              /* local rotations; the root's is global */
    double root[2][3];                           /* the pelvis positions */
} mim_pairs_pose_t;
/* The pose whose rest is pair (34 x 3): all rotations identity, so that
 * mim_pairs_pose_joints gives pair back. */
void mim_pairs_pose_rest(const double *pair, mim_pairs_pose_t *pose);
/* Forward kinematics: the 34 joints (x y z) of pose. */
void mim_pairs_pose_joints(const mim_pairs_pose_t *pose, double *joints);

/* ---- joint-angle validity (validity.c; eq. 2's isvalid and theta-bar) ---- */
#define MIM_PAIRS_CHECKS 12 /* per person */
#define MIM_PAIRS_VALID_TOL 0.35 /* radians (20 degrees) */
typedef struct mim_pairs_validity mim_pairs_validity_t;
/* Learned from n prior pose-pairs (34 x 3 each). MIM_EINVAL for n == 0 or
 * when no person has the joints apart, MIM_ENOMEM. */
int mim_pairs_validity_learn(const double *pairs, uint32_t n, mim_pairs_validity_t **out, mim_error_t *err);
void mim_pairs_validity_free(mim_pairs_validity_t **v); /* accepts NULL; nulls */
/* |theta - theta-bar|^2 (radians^2: the sum over the 24 checks of the
 * squared excess angle) of a pose-pair; *invalid gets the checks beyond
 * the tolerance. */
double mim_pairs_validity_excess(const mim_pairs_validity_t *v, const double *joints, uint32_t *invalid);

/* ---- the annotations as evidence (evidence.c) ---- */
typedef enum mim_pairs_density {
    MIM_DENSITY_IC = 0,
    MIM_DENSITY_CARTESIAN = 1,
    MIM_DENSITY_SHAPE = 2,
    MIM_DENSITY_PRIOR = 3
} mim_pairs_density_t;
/* "ic", "cartesian", "shape", "prior" -> the density; -1 when unknown. */
int mim_pairs_density_parse(const char *name);
extern const char *const mim_pairs_density_names[4];

typedef struct mim_pairs_evidence mim_pairs_evidence_t;
/* The annotations prepared for the likelihood: each one normalised, its
 * 2D interaction coordinates (qhull) and shape contexts, its view in the
 * pair's local frame (mim_pairs_annotation_view with torso) and its eq. 12
 * differentials (the next annotation of its shot: same take and view, the
 * next frame). Annotations whose view cannot be estimated are dropped
 * (*dropped). Shape contexts are made for the shape density only.
 * Errors: MIM_EEMPTY (none left), MIM_EFORMAT (qhull's reason,
 * naming the annotation), MIM_ENOMEM. Progress (may be NULL) label "annotations". */
int mim_pairs_evidence_build(const mim_pairs_annotations_t *ann, const mim_pairs_torso_t *torso,
                             mim_pairs_density_t density, mim_pairs_evidence_t **out, uint32_t *dropped, mim_progress_t *progress,
                             mim_error_t *err);
void mim_pairs_evidence_free(mim_pairs_evidence_t **e); /* accepts NULL; nulls */
uint32_t mim_pairs_evidence_count(const mim_pairs_evidence_t *e);
/* The views (psi, phi pairs, eq. 4) of the annotations, for eq. 5. */
const double *mim_pairs_evidence_views(const mim_pairs_evidence_t *e);

/* ---- the likelihood (likelihood.c; eqs. 6 and 9) ---- */
#define MIM_PAIRS_DEFAULT_SIGMA_L 0.1 /* the paper's 0.01 freezes every chain in mimic's units (chain.c) */
#define MIM_PAIRS_MAX_VIEWS 64
/* log L(theta) of eq. 6 for the 34 joints over the m views (psi, phi
 * pairs in the pair's local frame), each view's projection compared with
 * the annotations whose view lies within cone radians of it (pi: all; the
 * 8 nearest views when the cone holds fewer), with eq. 9's kernel of bandwidth
 * sigma_l on the density's distance (d_I for IC, the aligned RMS for
 * CARTESIAN, the 2D shape-context cost for SHAPE). nearest (m entries, may
 * be NULL) gets the annotation that decided each view (eq. 12's D*).
 * Returns -INFINITY when the pair has no local frame or no view's
 * projection has a triangulation (such a view alone counts as no match). */
double mim_pairs_log_likelihood(const mim_pairs_evidence_t *e, mim_pairs_density_t density, double sigma_l,
                                double cone, const double *joints, const double *views, uint32_t m, uint32_t *nearest);
/* eq. 12's mean squared differential of each group over the annotations
 * nearest[0..m), with the pair's RMS radius (metres) for the translation
 * group: out[g], radians^2 or metres^2. */
void mim_pairs_velocity(const mim_pairs_evidence_t *e, const uint32_t *nearest, uint32_t m, double rms_radius,
                        double out[MIM_PAIRS_GROUPS]);

/* ---- Metropolis-Hastings (mh.c; Section 5, eqs. 10-12) ---- */
/* A chain over any state whose proposal moves `groups` groups of `width`
 * reals by a Gaussian whose variances depend on the state (eq. 12): the
 * acceptance of eq. 10 then carries the proposal's asymmetry, Q(x|x') /
 * Q(x'|x), which needs the variances at x' as well (a move by eps is
 * undone by -eps in every model here: a translation, or a rotation
 * exp(eps) applied on the left). The density is truncated as eq. 11 says,
 * relative to the seed's f0. */
typedef struct mim_mh_ops {
    uint32_t groups, width;
    size_t state_size;
    /* to = from moved by eps (groups x width reals) */
    void (*move)(void *ctx, const void *from, const double *eps, void *to);
    /* log f (untruncated, up to a constant) of state, and the proposal's
     * variance of each group at it (0: the group stays). It may return
     * -INFINITY as soon as log f is sure to lie below floor. */
    double (*evaluate)(void *ctx, const void *state, double floor, double *sig2);
    /* after step i: the chain's state and its log f */
    void (*emit)(void *ctx, uint32_t i, const void *state, double log_f);
} mim_mh_ops_t;

typedef struct mim_mh_stats {
    uint64_t steps, accepted;
    uint64_t zero; /* proposals of density 0 under eq. 11 (invalid, or below f0 / c) */
    double seed_log_density;
} mim_mh_stats_t;

/* n steps from seed. c of eq. 11 (<= 1 or infinite: no truncation). rng
 * is the chain's own; *done (may be NULL) counts steps. Errors: MIM_EINVAL
 * (the seed's density is 0), MIM_ENOMEM. */
int mim_mh_run(const mim_mh_ops_t *ops, void *ctx, const void *seed, double c, mim_rng_t *rng, uint32_t n,
               mim_mh_stats_t *stats, _Atomic uint64_t *done, mim_error_t *err);

/* ---- the chain (chain.c; Section 5) ---- */
typedef struct mim_pairs_sampler_options {
    mim_pairs_density_t density;
    uint32_t views;       /* m of eq. 6 (default 8) */
    double sigma_l;       /* eq. 9 (default MIM_PAIRS_DEFAULT_SIGMA_L) */
    double cone;          /* eq. 9's "similar views": radians (default eq. 5's sigma_v) */
    double sigma_p;       /* eq. 2 (default 0.05) */
    double alpha;         /* eq. 2 (default 10) */
    uint32_t max_invalid; /* eq. 2's isvalid (default 8) */
    double c;             /* eq. 11 (default 100) */
    double sigma0_rot;    /* eq. 12's sigma_0, radians (default 0.02) */
    double sigma0_trans;  /* eq. 12's sigma_0 of a translation, metres (default 0.01) */
    double velocity_scale; /* eq. 12's sum is scaled by this squared (default 0.05: the 2D turns between
                            * annotated frames, 1/12 s apart in mocap, are far larger than one step) */
} mim_pairs_sampler_options_t;
/* The defaults above. */
void mim_pairs_sampler_defaults(mim_pairs_sampler_options_t *o);

typedef struct mim_pairs_target {
    mim_pairs_sampler_options_t opt;
    const mim_pairs_validity_t *validity;
    const mim_pairs_evidence_t *evidence; /* NULL for the prior density */
    const double *allowed;                /* eta's allowances (mim_penetration_learn); NULL: none */
} mim_pairs_target_t;


/* One chain from seed (34 x 3, a valid pose-pair of finite density) over
 * n steps: out_joints (n x 34 x 3) and out_log_density (n, the untruncated
 * log f(theta|D) up to its constant) get the state after each step. rng is
 * the chain's own. penetration: this thread's context (eq. 2's eta).
 * *done (may be NULL) counts the steps as they go, for progress. Errors:
 * MIM_EINVAL (the seed has no finite density: it names why), MIM_ENOMEM. */
int mim_pairs_chain_run(const mim_pairs_target_t *t, const double *seed, mim_rng_t *rng, mim_penetration_t *pen,
                        uint32_t n, double *out_joints, double *out_log_density, mim_mh_stats_t *stats,
                        _Atomic uint64_t *done, mim_error_t *err);
/* A rough seed, as the paper's is one annotation lifted to 3D and edited by
 * hand (Section 5): pair (34 x 3) with every free joint turned by a rotation
 * vector of rot_sd radians a component and B's pelvis moved by trans_sd
 * metres a component (the moves of eq. 12), into out (34 x 3, may not alias
 * pair). Bone lengths are kept; the result may be invalid under the prior. */
void mim_pairs_seed_jitter(const double *pair, double rot_sd, double trans_sd, mim_rng_t *rng, double *out);
/* log f(theta|D) (eqs. 1, 2, 6, 9) of a pose-pair under the chain's
 * views: prior plus likelihood; -INFINITY when invalid. The building block
 * of mim_pairs_chain_run, public for tests and for choosing seeds. */
double mim_pairs_log_density(const mim_pairs_target_t *t, mim_penetration_t *pen, const double *joints,
                             const double *views, uint32_t m, uint32_t *nearest);

/* ---- seeds lifted from annotations (lift.c) ---- */
/* Each bone's length (the joint's distance from its parent; 0 for the
 * pelvis): the mean over n pose-pairs (34 x 3 each) and both people. */
void mim_pairs_bone_lengths(const double *pairs, uint32_t n, double len[MIM_PAIR_PERSON_JOINTS]);
/* Each bone's length as one take's annotations show it (Taylor's relative
 * lengths, from 2D; lift.c): the prior's lengths (len_prior) describe
 * another skeleton where the annotated takes come from elsewhere (a
 * motion capture's chest, neck and shoulders sit differently). Iterated
 * from len_prior: per annotation and person the scale (the largest 2D
 * length over 3D length among the bones of at least MIN_BONE metres), each
 * bone's 2D length over it, the MIM_PAIRS_LENGTH_QUANTILE over the take's
 * annotations; then scaled so that the legs (knee and ankle bones, which
 * skeletons place alike) keep len_prior's length. A take with fewer than
 * MIM_PAIRS_LENGTH_MIN_ANNOTATIONS annotations keeps len_prior. */
#define MIM_PAIRS_LENGTH_QUANTILE 0.9
#define MIM_PAIRS_LENGTH_MIN_ANNOTATIONS 10
void mim_pairs_bone_lengths_2d(const mim_pairs_annotations_t *a, uint32_t take,
                               const double len_prior[MIM_PAIR_PERSON_JOINTS], double out[MIM_PAIR_PERSON_JOINTS]);
/* A pose-pair (34 x 3 into out, y up, metres) that one annotation uv (34
 * [u, v] pixels in an image of width x height) shows, each person lifted
 * scaled-orthographically with bones of lengths len, each bone's depth
 * sign chosen by t's joint limits (eq. 2) from random starts drawn from
 * rng (choices: lift.c). MIM_EINVAL when a person has no bone in 2D or
 * no signs found keep the invalid checks within those allowed. */
int mim_pairs_lift(const mim_pairs_target_t *t, const double *uv, uint32_t width, uint32_t height,
                   const double len[MIM_PAIR_PERSON_JOINTS], mim_rng_t *rng, double *out);

#ifdef __cplusplus
}
#endif
#endif
