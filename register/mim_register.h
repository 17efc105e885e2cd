/* mimic register: non-rigid registration of the store's connectivity onto
 * another surface, and the binding of a foreign avatar to its registered
 * proxy.
 *
 * Computation over caller-owned arrays, like transfer/: nothing here opens
 * the store, reads a file or prints. It uses transfer/ (the uniform
 * Laplacian, frames, encoding and the constrained solver) for the initial
 * shape, CHOLMOD for the non-rigid ICP, FLANN for closest points and
 * LAPACKE for the similarity fit.
 *
 * The method (register.c, nicp.c), landmark-guided:
 *   1. similarity fit (Umeyama 1991) of the template's landmarks onto the
 *      target's;
 *   2. initial shape: the caller's nearest template, moved by that fit and
 *      transferred into the target's landmark positions with transfer/'s
 *      solver (seed 000, eq. 3, mode (b): the template is its own avatar);
 *   3. non-rigid ICP with decreasing stiffness (Amberg et al. 2007,
 *      "Optimal step nonrigid ICP"): closest points on the target's
 *      surface (and, early on, the target's vertices' nearest vertices),
 *      rejected across a boundary, by normal or by distance; a stiffness
 *      term on the initial shape's Laplacian offsets in the current local
 *      frames; the landmarks as soft constraints. See nicp.c;
 *   4. steps 2-3 once more, the transfer now from the frames of step 3's
 *      result (a start closer to the target's pose).
 * The landmarks and the initial shape carry the correspondence (vertex i
 * lands where vertex i of a body belongs); ICP only closes the distance.
 *
 * Binding (bind.c): each vertex of a foreign avatar is bound to its closest
 * triangle of the registered proxy, with barycentric coordinates and an
 * offset in the local frame there, so that posing the proxy poses the
 * avatar in its own connectivity and vertex order. */
#ifndef MIM_REGISTER_H
#define MIM_REGISTER_H

#include "mim_core.h"
#include "mim_transfer.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- similarity fit (fit.c) ---- */
typedef struct mim_reg_similarity {
    double scale;
    double R[9]; /* rotation, column-major like mim_quat_to_matrix */
    double t[3];
} mim_reg_similarity_t;
/* The similarity x -> scale * R x + t that best maps src onto dst in least
 * squares (Umeyama 1991; a reflection is never returned). n >= 3 points,
 * 3 * n floats each. MIM_EINVAL for fewer than 3 points or points that span
 * no plane (a degenerate fit), MIM_EUNSUPPORTED when the SVD fails. */
int mim_reg_similarity_fit(const float *src, const float *dst, uint32_t n, mim_reg_similarity_t *out,
                           mim_error_t *err);
void mim_reg_similarity_apply(const mim_reg_similarity_t *s, const float *in, uint32_t n, float *out);
/* Of nc candidate bodies' landmarks (cand: nc x 3n floats), the one a
 * similarity brings nearest to the target's landmarks (3n floats), in RMS
 * distance: the body most like the target's, where registration starts
 * (the index's nearest by angles in the target's pose class does not see
 * proportions). *best gets its index; a candidate whose fit fails is
 * passed over. MIM_EINVAL when nc is 0 or every fit fails. */
int mim_reg_likest(const float *target, uint32_t n, const float *cand, uint32_t nc, uint32_t *best, mim_error_t *err);

/* ---- the target surface (surface.c) ---- */
/* Checks that a mesh can be registered onto: finite, a body
 * (mim_body_check), every edge shared by at most two triangles (no
 * non-manifold edge), one connected piece, every vertex on a triangle.
 * One line naming origin and what is wrong: "scan.ply: non-manifold: edge
 * 12-40 is shared by 3 triangles", "scan.ply: disconnected: 3 pieces (the
 * largest has 4000 of 4200 vertices)". MIM_ETOPOLOGY, MIM_ENONFINITE or
 * the body check's. */
int mim_reg_target_check(const mim_mesh_t *target, const char *origin, mim_error_t *err);

/* ---- welding split vertices (weld.c) ---- */
/* An avatar as exporters write it has its vertices split along UV and
 * normal seams (a flat-shaded one splits every triangle): the copies sit
 * at the same place, so the surface falls apart into pieces that are one
 * piece. Welds vertices whose positions agree within tol metres (0:
 * MIM_REG_WELD_TOL) into one: out gets the welded mesh (triangles whose
 * corners merged dropped), map (n_vertices of in) the welded vertex of
 * each input vertex. The output keeps the split copies: only registration
 * and stretch measures use the weld. Errors: MIM_EINVAL, MIM_ENOMEM. */
#define MIM_REG_WELD_TOL 1e-5
int mim_reg_weld(const mim_mesh_t *in, double tol, mim_mesh_t *out, uint32_t *map, mim_error_t *err);
/* The connected pieces of a mesh (faces in range: the caller's check), or
 * MIM_ENOMEM. An avatar of more pieces than MIM_REG_MAX_PIECES once welded
 * is no body mimic drives (a scene of loose triangles, a particle cloud). */
#define MIM_REG_MAX_PIECES 4096
int64_t mim_reg_pieces(const mim_mesh_t *m);

/* ---- landmarks from a rig (rig_landmarks.c) ---- */
/* The 16 default landmarks (mim_reg_rig_landmark_names, mim_landmarks
 * default order) of an avatar from its rig's joints: pivots holds, per
 * body segment (MIM_SEGMENTS, mim_segment_names order), the world
 * position of the joint that turns it (3 doubles each), have marks the
 * ones the rig has. rig_landmarks.c states the rule of each landmark. The
 * head, both upper arms, forearms, hands, thighs, shins and feet are
 * needed; missing (may be NULL) gets the names of those the rig lacks.
 * out: 3 * 16 floats, each on a vertex of mesh. Errors: MIM_ENOLANDMARKS
 * (a needed joint missing, no surface near one), MIM_EFORMAT (joints that
 * make no upright body), MIM_EINVAL. */
#define MIM_REG_RIG_LANDMARKS 16
extern const char *const mim_reg_rig_landmark_names[MIM_REG_RIG_LANDMARKS];
int mim_reg_rig_landmarks(const mim_mesh_t *mesh, const double *pivots, const uint8_t *have, float *out,
                          char *missing, size_t missing_size, mim_error_t *err);

/* ---- registration (register.c) ---- */
#define MIM_REG_DEFAULT_ROUNDS 2u             /* initial shape + ICP; the second round from the first's frames */
#define MIM_REG_DEFAULT_STAGES 5u             /* stiffness stages per round */
#define MIM_REG_DEFAULT_ITERATIONS 3u         /* ICP steps per stage, at most */
#define MIM_REG_DEFAULT_STIFFNESS_FIRST 2.0   /* alpha of the first stage */
#define MIM_REG_DEFAULT_STIFFNESS_LAST 0.005  /* alpha of the last stage (geometric in between) */
#define MIM_REG_DEFAULT_LANDMARK_WEIGHT 1.0   /* beta of the first stage (it shrinks like alpha) */
#define MIM_REG_DEFAULT_MAX_ANGLE_DEG 60.0    /* normal rejection at the last stage (90 at the first) */
#define MIM_REG_DEFAULT_MAX_DISTANCE 0.05     /* metres: distance rejection at the last stage (4x at the first) */
/* The weight of closest points at the hands and feet (vertices whose
 * nearest landmark is a wrist or an ankle) against 1 elsewhere. Closest
 * points pull fingers onto their neighbours and a hand by the body onto
 * the hip, toes onto the instep: there ICP made the correspondence worse
 * than the initial shape's (hands 2.5 against 1.2 mm on synth, 7.3 against
 * 4.3 on mh-bodies, feet 67.6 against 47.1 on the imitation set), so the
 * extremities keep the initial shape's correspondence and ride on their
 * stiffness, while their surface still closes to within a millimetre or
 * two (bench/RESULTS.md, "Hands and feet that keep their correspondence";
 * chosen on the imitation set: 0.001..0.1 tried). */
#define MIM_REG_DEFAULT_EXTREMITY_WEIGHT 0.01

typedef struct mim_reg_options {
    uint32_t rounds;          /* 0: MIM_REG_DEFAULT_ROUNDS */
    uint32_t stages;          /* 0: MIM_REG_DEFAULT_STAGES */
    uint32_t iterations;      /* per stage; 0: MIM_REG_DEFAULT_ITERATIONS */
    double stiffness_first;   /* 0: default */
    double stiffness_last;    /* 0: default */
    double landmark_weight;   /* 0: default */
    double max_angle_deg;     /* 0: default */
    double max_distance;      /* 0: default */
    double extremity_weight;  /* 0: MIM_REG_DEFAULT_EXTREMITY_WEIGHT; < 0: 1 (no difference) */
    int no_icp;               /* 1: the initial shape only (the baseline the bench compares against) */
    int pieces;               /* 1: the target may be several pieces (an avatar's body, eyes, boots, props:
                                 issue 28), welded first (mim_reg_weld); an edge of three triangles is no
                                 boundary. 0: one manifold piece (a scan) */
} mim_reg_options_t;

typedef struct mim_reg_report {
    uint32_t iterations;       /* ICP steps done over all stages */
    double scale;              /* of the similarity fit, template onto target */
    /* Surface distance from each result vertex to the target's surface (mm). */
    double mean_mm, p95_mm, max_mm;
    /* Distance of each result landmark vertex to the target's landmark (mm). */
    uint32_t n_landmarks;
    double landmark_mm[MIM_LANDMARKS_MAX];
    double landmark_mean_mm, landmark_max_mm;
    double rejected;           /* fraction of vertices without a closest point at the last step */
    double seconds_initial, seconds_icp, seconds;
    /* Correspondence quality (issue 29; surface distance hides sliding):
     * per body region (mim_reg_region_names: a vertex's nearest landmark's),
     * the rms stretch of the template's edges, percent of their length
     * (log ratio), against the template moved by the similarity fit; and
     * the result's enclosed volume over the moved template's. */
    double distortion_pct[6];
    double volume_ratio;
} mim_reg_report_t;
#define MIM_REG_REGIONS 6
enum { MIM_REG_REGION_HEAD, MIM_REG_REGION_TORSO, MIM_REG_REGION_ARMS, MIM_REG_REGION_HANDS, MIM_REG_REGION_LEGS,
       MIM_REG_REGION_FEET };
extern const char *const mim_reg_region_names[MIM_REG_REGIONS]; /* head, torso, arms, hands, legs, feet */
/* A registration enclosing less than this share of its template's volume
 * (flat, degenerate, inside out) is refused (MIM_ETOPOLOGY). */
#define MIM_REG_MIN_VOLUME_RATIO 0.5

typedef struct mim_reg mim_reg_t;
/* One registration context for a connectivity and its landmark map (16 or
 * any >= 4 landmarks, vertices < n): the transfer solver of the initial
 * shape and the symbolic analysis of the ICP system, done once and reused
 * by every mim_reg_run. topo and map must outlive it. One run at a time per
 * context (workspaces are shared); open one per thread. Errors: MIM_EINVAL,
 * MIM_ENOMEM, the solver's (MIM_ETOPOLOGY: a piece of the mesh without a
 * landmark). opt may be NULL. */
int mim_reg_open(mim_reg_t **out, const mim_xfer_topology_t *topo, const mim_landmark_map_t *map,
                 const mim_reg_options_t *opt, mim_error_t *err);
void mim_reg_close(mim_reg_t **r); /* accepts NULL, nulls */

/* Registers the connectivity onto target. tmpl: the starting template (3 *
 * n floats, the connectivity's), normally the store's nearest pose to the
 * target's landmarks; target_landmarks: 3 * map count floats, in map
 * order, on the target. Writes 3 * n floats to out (the connectivity's
 * vertices on the target) and fills report (may be NULL). origin names the
 * target in messages. Errors: the target check's (mim_reg_target_check),
 * MIM_ENONFINITE for NaN landmarks, MIM_EINVAL, MIM_ENOMEM,
 * MIM_EUNSUPPORTED (a solve failed). */
int mim_reg_run(mim_reg_t *r, const float *tmpl, const mim_mesh_t *target, const float *target_landmarks,
                const char *origin, float *out, mim_reg_report_t *report, mim_error_t *err);

/* Surface distance (metres) from each of n points to the target's surface,
 * into dist (n doubles): what the report's figures are made of, public so
 * that a caller can measure any mesh against a surface. Same errors as the
 * target check. */
int mim_reg_surface_distance(const mim_mesh_t *target, const float *points, uint32_t n, double *dist,
                             mim_error_t *err);

/* ---- binding a foreign avatar to its registered proxy (bind.c) ---- */
/* One entry per avatar vertex, in the order of the proxy triangles they
 * are bound to (so that posing reads the proxy in order, whatever the
 * avatar's vertex order). */
typedef struct mim_reg_binding {
    uint32_t n_vertices;       /* the avatar's */
    uint32_t n_proxy_vertices; /* the proxy's (the store's connectivity) */
    uint32_t n_proxy_faces;
    float *proxy_rest;         /* 3 * n_proxy_vertices: the proxy registered onto the avatar at rest */
    uint32_t *vertex;          /* n_vertices: the avatar vertex of each entry (a permutation) */
    uint32_t *face;            /* n_vertices: the proxy triangle of each entry, non-decreasing */
    float *bary;               /* 2 * n_vertices: barycentric (u, v) on it; w = 1 - u - v */
    float *offset;             /* 3 * n_vertices: offset in the local frame there (tangent, bitangent, normal) */
} mim_reg_binding_t;

/* Binds each avatar vertex to its closest point on the proxy (proxy: the
 * store's faces with the registered rest positions, which the binding
 * copies). Errors: MIM_EINVAL, MIM_ENOMEM, MIM_ENONFINITE. On error *out
 * is empty. */
int mim_reg_bind(const mim_mesh_t *proxy, const mim_mesh_t *avatar, mim_reg_binding_t *out, mim_error_t *err);
void mim_reg_binding_free(mim_reg_binding_t *b); /* accepts an empty one; empties it */

/* The avatar's positions (3 * n_vertices floats) for the proxy posed at
 * proxy_positions (3 * n_proxy_vertices floats; faces: the proxy's).
 * work: 3 * n_proxy_vertices floats of scratch (the proxy's normals).
 * Allocates nothing: the per-frame path. */
void mim_reg_binding_apply(const mim_reg_binding_t *b, const uint32_t *proxy_faces, const float *proxy_positions,
                           float *work, float *out);

/* A binding as bytes, to cache (malloc'd; the caller frees), and back.
 * decode checks every field against n_proxy_vertices and n_proxy_faces
 * (a damaged cache entry is MIM_EFORMAT, never trusted: faces in range
 * and in order, vertex a permutation, every number finite). */
int mim_reg_binding_encode(const mim_reg_binding_t *b, void **blob, size_t *len, mim_error_t *err);
int mim_reg_binding_decode(const void *blob, size_t len, uint32_t n_proxy_vertices, uint32_t n_proxy_faces,
                           mim_reg_binding_t *out, mim_error_t *err);

/* ---- following the segments where the proxy is far (follow.c; issue 28) ---- */
/* Where the avatar lies far from its proxy (fists against open hands,
 * hair, boots, props), the binding alone tears it: follow.c says why. A
 * vertex at distance d takes a share smoothstep(near, far, d) of the rigid
 * motions of the segments under its closest proxy point (fitted to the
 * proxy each frame); a piece whose p90 distance is over far follows one
 * segment rigidly (its rig's, else its nearest). */
#define MIM_REG_FOLLOW_NEAR 0.005         /* metres: closer follows the surface alone */
#define MIM_REG_FOLLOW_FAR 0.03           /* metres: further follows the segments alone */
#define MIM_REG_FOLLOW_MAX_FAR_SHARE 0.35 /* more of the avatar in far pieces: not one body */
typedef struct mim_reg_follow_options {
    double near, far;      /* 0: the defaults above */
    double max_far_share;  /* 0: MIM_REG_FOLLOW_MAX_FAR_SHARE */
    /* How crushed each proxy vertex is (n_proxy_vertices, 0..1;
     * mim_reg_crushed; NULL: not at all): an avatar vertex follows the
     * segments at least as much as the crush at its closest point, and no
     * segment's motion is fitted to a crushed vertex. */
    const float *crush;
    /* Segments (bit g: mim_segment_names[g]) whose vertices follow them
     * rigidly in the measure of their weight; 0: MIM_REG_FOLLOW_RIGID_DEFAULT
     * (the hands); MIM_REG_FOLLOW_RIGID_NONE: none. */
    uint32_t rigid;
} mim_reg_follow_options_t;
#define MIM_REG_FOLLOW_RIGID_DEFAULT ((1u << 2) | (1u << 9) | (1u << 10) | (1u << 15) | (1u << 16)) /* head, hands, feet */
#define MIM_REG_FOLLOW_RIGID_NONE (1u << 31)
typedef struct mim_reg_follow {
    uint32_t n_vertices, n_proxy_vertices;
    uint32_t n_entries;      /* the vertices that take some of the segments' motion */
    uint32_t *vertex;        /* n_entries avatar vertices */
    float *alpha;            /* n_entries: their share of it */
    uint8_t (*bone)[4];      /* n_entries: segments (mim_segment_names order) */
    float (*weight)[4];      /* n_entries: their weights, summing to 1 */
    float *rest;             /* 3 * n_entries: their rest positions */
    uint32_t sample_start[MIM_SEGMENTS + 1];
    uint32_t n_samples;
    uint32_t *samples;       /* proxy vertices each segment's motion is fitted to */
    uint32_t pieces, far_pieces, far_vertices; /* the avatar's pieces (welded), the rigid ones, their vertices */
} mim_reg_follow_t;
/* Builds it from the binding b of avatar (the same vertices), the
 * proxy's faces and its segment skin (n_proxy_vertices entries, e.g.
 * mim_xfer_skin_from_bones over the vest's segments), and optionally the
 * avatar's own rig's segment per vertex (rig_segment, -1: none; NULL).
 * Errors: MIM_EINVAL, MIM_ENOMEM, MIM_ETOPOLOGY when more than
 * max_far_share of the avatar lies in far pieces (two bodies, a body and a
 * large scene: "N of its M vertices ... lie over F mm from the registered
 * body"; pieces and far_* are still filled). opt may be NULL. */
int mim_reg_follow_build(const mim_reg_binding_t *b, const uint32_t *proxy_faces, const mim_xfer_skin_t *proxy_skin,
                         const mim_mesh_t *avatar, const int *rig_segment, const mim_reg_follow_options_t *opt,
                         mim_reg_follow_t *out, mim_error_t *err);
void mim_reg_follow_free(mim_reg_follow_t *f); /* accepts an empty one; empties it */
/* Blends the segments' motion into out (the avatar's positions as
 * mim_reg_binding_apply gave them), for the proxy going from proxy_rest
 * to proxy_posed. Allocates nothing; thread-safe on distinct outputs. */
void mim_reg_follow_apply(const mim_reg_follow_t *f, const float *proxy_rest, const float *proxy_posed, float *out);

/* Where registration crushed the proxy (fingers of an open hand pressed
 * into a fist, folds at the face): how far each proxy vertex is from a
 * surface that moves smoothly, in [0, 1] (n_vertices floats into crush).
 * A triangle whose area against the same triangle of the template the
 * registration started from (times scale^2, the similarity's) is off by a
 * factor r counts smoothstep(MIM_REG_CRUSH_FROM, MIM_REG_CRUSH_TO, |ln r|);
 * a vertex takes its worst triangle's, then fades out over
 * MIM_REG_CRUSH_RINGS rings around, so that what follows from it changes
 * smoothly over the surface. Such a region's frames turn wildly in a
 * transfer. Returns the number of vertices with crush > 0. */
#define MIM_REG_CRUSH_FROM 1.05 /* |ln r|: areas within 2.9x of the template's are fine */
#define MIM_REG_CRUSH_TO 1.9    /* 6.7x off: crushed */
#define MIM_REG_CRUSH_RINGS 3u
uint32_t mim_reg_crushed(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices, const float *proxy,
                         const float *tmpl, double scale, float *crush);

/* Tearing, measured (issue 28): over the triangles (faces, n_faces) of a
 * mesh at rest and posed, the share whose longest edge stretched over
 * limit times its rest length, and the largest stretch. Triangles with an
 * edge of zero length at rest are not counted. */
void mim_reg_stretch(const uint32_t *faces, uint32_t n_faces, const float *rest, const float *posed, double limit,
                     double *share_over, double *max_ratio);

/* ---- landmark maps of known connectivities, built in (known_maps.c) ---- */
/* The built-in landmark map of the connectivity of these faces, found by
 * the SHA-256 of the faces (little-endian uint32, three per triangle, in
 * order) against the fingerprints shipped with mimic (SMPL's 6890-vertex
 * body: FAUST and every SMPL-family mesh). Returns 1 and fills map (and
 * name, the map's file name, if not NULL) when known, 0 when not. */
int mim_reg_known_map(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices, mim_landmark_map_t *map,
                      const char **name);
/* The built-in maps, for listing and export: how many, each one's file
 * name ("smpl-6890.json") and its text (a landmark map file with
 * "topology_vertices" and "faces_sha256"). NULL past the end. */
uint32_t mim_reg_known_map_count(void);
const char *mim_reg_known_map_name(uint32_t i);
const char *mim_reg_known_map_text(uint32_t i);
/* The SHA-256 of the faces as above, as 64 lowercase hex digits and a NUL. */
void mim_reg_faces_sha256(const uint32_t *faces, uint32_t n_faces, char hex[65]);

#ifdef __cplusplus
}
#endif
#endif
