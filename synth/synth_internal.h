/* Internals of mimic synth, shared by its files only (mim__ names).
 *
 * Pipeline: subject parameters (subject.c) -> rest skeleton (skeleton.c) ->
 * body-part cross-section keys (shape.c) -> coarse polygon cage with skin
 * weights per cage vertex (body.c, weights.c) -> one Catmull-Clark level as a
 * fixed linear stencil, triangulated along fixed diagonals (subdivide.c) ->
 * posed with linear blend skinning (pose.c). The cage topology, the stencil,
 * the diagonals and the landmarks are decided once on a fixed reference
 * subject, so every subject and pose shares one connectivity. */
#ifndef MIM_SYNTH_INTERNAL_H
#define MIM_SYNTH_INTERNAL_H

#include "mim_synth.h"

#include <stdint.h>

/* ---- skeleton joints (parents before children) ---- */
enum {
    MIM__J_PELVIS, MIM__J_SPINE, MIM__J_CHEST, MIM__J_NECK, MIM__J_HEAD,
    MIM__J_LCLAV, MIM__J_RCLAV, MIM__J_LUARM, MIM__J_RUARM, MIM__J_LFARM, MIM__J_RFARM,
    MIM__J_LHAND, MIM__J_RHAND, MIM__J_LTHIGH, MIM__J_RTHIGH, MIM__J_LSHIN, MIM__J_RSHIN,
    MIM__J_LFOOT, MIM__J_RFOOT, MIM__NJ
};
extern const char *const mim__joint_name[MIM__NJ];
extern const int mim__joint_parent[MIM__NJ];
/* The joint's left/right counterpart (itself on the midline). */
extern const int mim__joint_mirror[MIM__NJ];

/* Skinning bones: the joints, then MIM__HK - 1 helper bones per joint that
 * turn about the joint's pivot by k / MIM__HK of its rotation (weights.c). */
#define MIM__HK 4
#define MIM__NB (MIM__NJ * MIM__HK)
#define MIM__HELPER(j, k) (MIM__NJ + (j) * (MIM__HK - 1) + (k) - 1)
int mim__bone_mirror(int b);

/* ---- subject: shape parameters (multipliers are about 1) ---- */
typedef struct mim__subject {
    double height;          /* stature in rest pose, metres */
    double masc;            /* 0..1: narrower hips / wider shoulders / flatter chest */
    double weight;          /* 0..1: girth and belly */
    double leg, arm;        /* limb length multipliers */
    double shoulder, hip;   /* width multipliers */
    double girth, limb;     /* torso and limb radius multipliers */
    double belly, chest;    /* front depth multipliers (waist, chest) */
    double head;            /* head size multiplier */
} mim__subject_t;
void mim__subject_make(mim__subject_t *sub, uint64_t seed, uint32_t index);
void mim__subject_reference(mim__subject_t *sub);

/* ---- rest skeleton (A-pose) ---- */
#define MIM__ARM_ANGLE_DEG 45.0 /* rest arms, from vertical */
typedef struct mim__skeleton {
    double H;                 /* stature */
    mim_vec3 j[MIM__NJ];      /* rest joint positions */
    mim_vec3 head_top;        /* crown */
    mim_vec3 hand_tip, toe_tip; /* left side */
    double y_crotch;
    double ua, fa, hand;      /* left arm segment lengths */
} mim__skeleton_t;
void mim__skeleton_make(mim__skeleton_t *sk, const mim__subject_t *sub);
/* The rest arm axis (shoulder to hand) and its lateral (up-out) normal, left arm. */
mim_vec3 mim__arm_dir(void);
mim_vec3 mim__arm_lat(void);

/* ---- body-part cross sections ---- */
/* A ring: centre c, axes e1 (angle psi = 90 deg) and e2 (psi = 0), radii on
 * each side, superellipse exponent p (2 = ellipse). */
typedef struct mim__key {
    double s; /* position along the part, metres */
    mim_vec3 c, e1, e2;
    double r1p, r1n, r2p, r2n, p;
} mim__key_t;

enum { MIM__PART_TORSO, MIM__PART_HEAD, MIM__PART_ARM, MIM__PART_LEG, MIM__NPART };
#define MIM__MAXKEYS 24
typedef struct mim__part {
    int n;
    mim__key_t k[MIM__MAXKEYS];
    mim_vec3 tip;   /* pole of the end cap (head, arm, leg) */
    double s_mark[4]; /* torso: armpit, shoulder top, neck base */
} mim__part_t;

typedef struct mim__shape {
    mim__part_t part[MIM__NPART]; /* arm and leg: the left one (right = mirror) */
    mim__key_t leg_loop;          /* the ring where the left thigh leaves the torso */
    mim_vec3 crotch_front, crotch_back, crotch;
    double phi_patch;             /* half the angle the arm opening spans on the torso */
} mim__shape_t;
void mim__shape_make(mim__shape_t *sh, const mim__subject_t *sub, const mim__skeleton_t *sk);
void mim__key_at(const mim__part_t *p, double s, mim__key_t *out);
mim_vec3 mim__key_point(const mim__key_t *k, double psi);
double mim__key_perimeter(const mim__key_t *k);

/* ---- layout: the cage topology, decided from the vertex budget ---- */
#define MIM__MAXRINGS 400
typedef struct mim__layout {
    int level;               /* Catmull-Clark levels: 0 or 1 */
    uint32_t m;              /* ring size of neck, head, arms; the torso has 2m */
    uint32_t nc;             /* crotch vertices between the thighs (odd) */
    uint32_t L;              /* leg ring size (m + 1 + nc) */
    uint32_t a, b, c0;       /* arm opening: a rings tall, b columns wide, from column c0 */
    uint32_t n_low, n_trap, n_head, n_arm, n_leg;
    double u_low[MIM__MAXRINGS], u_head[MIM__MAXRINGS], u_arm[MIM__MAXRINGS], u_leg[MIM__MAXRINGS];
} mim__layout_t;
/* Chooses the layout whose final vertex count is nearest `vertices`. */
int mim__layout_choose(mim__layout_t *lay, uint32_t vertices);
/* Final vertex count of a layout, without building it. */
uint32_t mim__layout_count(const mim__layout_t *lay);

/* ---- cage: polygon mesh with skin weights per vertex ---- */
#define MIM__CW 4 /* influences per cage vertex */
typedef struct mim__cage {
    uint32_t nv, nf, ncorner;
    uint32_t cap_v, cap_f, cap_c; /* allocated sizes while building */
    double *pos;       /* 3 * nv */
    uint32_t *fstart;  /* nf + 1 */
    uint32_t *fv;      /* ncorner */
    uint8_t *wj;       /* MIM__CW * nv bone ids (joints and helpers) */
    float *ww;         /* MIM__CW * nv weights (sum 1) */
} mim__cage_t;
int mim__cage_build(mim__cage_t *c, const mim__layout_t *lay, const mim__subject_t *sub);
void mim__cage_free(mim__cage_t *c);
/* Makes face orientation consistent (BFS) and outward (positive volume). */
int mim__cage_orient(mim__cage_t *c);

/* Edges of a closed manifold cage (topology.c): edge k joins ev[2k] <
 * ev[2k+1] and is side ecorner[2k], ecorner[2k+1] of two faces (a corner c
 * is the edge from fv[c] to the next vertex of its face). */
typedef struct mim__edges {
    uint32_t ne;
    uint32_t *ev, *ecorner;
    uint32_t *corner_edge, *corner_face;
} mim__edges_t;
int mim__edges_build(mim__edges_t *e, const mim__cage_t *c); /* MIM_ETOPOLOGY if not closed manifold */
void mim__edges_free(mim__edges_t *e);

/* Skin weights of one cage vertex (weights.c). `part` is a MIM__PART_*,
 * `side` 0 left / 1 right, `s` the ring position along its part, `p` the
 * (left-side) rest position. Writes up to MIM__CW influences. */
void mim__weights(const mim__skeleton_t *sk, const mim__shape_t *sh, int part, int ring, double s,
                  mim_vec3 p, int side, uint8_t *wj, float *ww);

/* ---- refinement: final vertices as a fixed linear stencil of the cage ---- */
typedef struct mim__refine {
    uint32_t nv;          /* final vertices; the first cage.nv are the cage's */
    uint32_t *st_start;   /* nv + 1 */
    uint32_t *st_col;
    double *st_w;
    uint32_t npoly;       /* quads and triangles */
    uint32_t *poly;       /* 4 per polygon; poly[4i+3] == UINT32_MAX for a triangle */
} mim__refine_t;
int mim__refine_build(mim__refine_t *r, const mim__cage_t *c, int level);
void mim__refine_free(mim__refine_t *r);
/* out[i] = sum_k w_ik in[col_ik] for dim-vectors. */
void mim__refine_apply(const mim__refine_t *r, const double *in, double *out, int dim);
/* Triangles of the refined mesh (3 per face), splitting each quad along the
 * diagonal that gives the larger minimum angle on `pos`. Returns the count. */
uint32_t mim__triangulate(const mim__refine_t *r, const double *pos, uint32_t *faces);

/* ---- poses and skinning ---- */
#define MIM__NW 8 /* influences per final vertex */
#define MIM__POSE_TABLE 12 /* rest + 11 designed poses */
void mim__pose_angles(uint32_t pose, uint64_t seed, double deg[MIM__NJ][3]);
/* The subject's own way of taking the pose (mim_synth_options_t's
 * imitation_deg): deg perturbed in place; nothing for sigma 0 or the rest. */
void mim__pose_imitate(uint32_t subject, uint32_t pose, uint64_t seed, double sigma_deg, double deg[MIM__NJ][3]);
const char *mim__pose_table_name(uint32_t pose); /* NULL past the table */
void mim__pose_quats(const double deg[MIM__NJ][3], mim_quat q[MIM__NJ]);
/* Forward kinematics: world rotations G and posed joint positions P (root
 * at its rest place). */
void mim__fk(const mim__skeleton_t *sk, const mim_quat q[MIM__NJ], mim_quat G[MIM__NJ], mim_vec3 P[MIM__NJ]);
/* Linear blend skinning of n vertices (rest positions, MIM__NW weights each). */
void mim__lbs(const mim__skeleton_t *sk, const mim_quat q[MIM__NJ], const mim_quat G[MIM__NJ],
              const mim_vec3 P[MIM__NJ], uint32_t n, const double *rest, const uint8_t *wj, const float *ww,
              double *out);

/* ---- the generator ---- */
struct mim_synth {
    mim_synth_options_t opt;
    mim__layout_t lay;
    mim__refine_t ref;
    uint32_t nv, nf;
    uint32_t *faces;
    uint32_t landmark[MIM_LANDMARKS_DEFAULT_COUNT];
    char (*pose_name)[24];
    mim_progress_fn progress; /* of mim_synth_write_dataset; NULL: quiet */
    void *progress_ctx;
};

/* One subject, evaluated: rest mesh, final weights, skeleton. */
typedef struct mim__body {
    mim__subject_t sub;
    mim__skeleton_t sk;
    double *rest;  /* 3 * nv */
    uint8_t *wj;   /* MIM__NW * nv */
    float *ww;     /* MIM__NW * nv */
} mim__body_t;
int mim__body_eval(const mim_synth_t *s, const mim__subject_t *sub, mim__body_t *b);
void mim__body_free(mim__body_t *b);
/* Poses b: positions (3 * nv, may be NULL) and joints (3 * MIM__NJ, may be
 * NULL), lowest vertex at y = 0. `work` holds 3 * nv doubles. */
void mim__body_pose(const mim_synth_t *s, const mim__body_t *b, uint32_t subject, uint32_t pose, double *work,
                    float *positions, float *joints);

/* Soft tissue (tissue.c): pos (3 * nv, posed) bulged in place for this
 * subject and pose; nothing when opt.tissue_mm is 0. rest: the subject's
 * rest mesh (bumps are placed on it). */
void mim__tissue_apply(const mim_synth_t *s, const double *rest, uint32_t subject, uint32_t pose, double *pos);

/* Landmark vertices chosen on a rest body (landmarks.c). */
void mim__landmarks_pick(const mim__body_t *b, uint32_t nv, uint32_t out[MIM_LANDMARKS_DEFAULT_COUNT]);

#endif
