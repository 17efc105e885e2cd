/* session/ internals shared between its files (not installed). */
#ifndef MIM_SESSION_INTERNAL_H
#define MIM_SESSION_INTERNAL_H

#include "mim_session.h"

#include "mim_db.h"
#include "mim_query.h"
#include "mim_register.h"
#include "mim_transfer.h"

#include <pthread.h>

/* A template read for transfers: its positions and frames, and its frames
 * turned by the segment correction (allocated on first use). For relative
 * transfer also its W and its turn on the avatar's rest frames, made on
 * first use and kept with the slot (they depend only on the template, its
 * reference and the avatar: a held pose pays for them once). */
typedef struct template_slot {
    uint64_t id;                /* 0: empty */
    uint64_t used;              /* the session's tick when last used */
    float *pos;                 /* 3 * n */
    double *F, *cF;             /* 9 * n each */
    double *W;                  /* 3 * n, valid when has_W */
    double *rF;                 /* 9 * n, valid when has_rF */
    int has_W, has_rF;
    double *Q;                  /* 4 * n: quaternions of F (Q_of 1) or rF (Q_of 2) for blends; 0: none */
    int Q_of;
    char label[MIM_SESSION_LABEL_MAX];
} template_slot_t;

/* A template subject's reference for relative transfer: its template
 * nearest to the avatar's rest landmarks (over all index angles). Per
 * session, as it depends on the avatar; found on first need. id 0: none
 * (the subject's templates have no usable landmarks): the plain path. */
typedef struct subject_ref {
    char *subject;
    uint64_t id;
    int near;                   /* its pose within MIM_SESSION_RELATIVE_GATE_DEG rms of the avatar's rest */
    double scale;               /* mim_xfer_encoding_scale (NaN: the blend takes 1) */
    double build;               /* mim_xfer_build_distance from the avatar's rest landmarks (NaN: unknown) */
    double *W;                  /* its encoding, 3 * n */
    double *F;                  /* its frames, 9 * n; only when near (nothing else reads them) */
    mim_error_t damage;         /* why it has none although the subject has templates: its record is damaged */
} subject_ref_t;

struct mim_session {
    /* A fork (mim_session_fork) shares its base's store, index, connectivity
     * and landmark table: these fields are then the base's, not closed here. */
    mim_session_t *base;
    mim_db_t *db;
    mim_query_t *query;         /* NULL when the store has no index */
    mim_query_status_t index;   /* at open */
    mim_session_options_t opt;
    mim_xfer_topology_t *topo;
    mim_landmark_map_t map;
    mim_mesh_t mesh;            /* the store's faces with the avatar's rest positions (its proxy's, for a
                                   foreign avatar) */
    /* a foreign avatar (another connectivity): its own mesh, its binding to
     * the proxy, and the scratch of mapping a pose onto it (out_lock) */
    mim_mesh_t own;
    mim_io_part_t *parts;       /* the avatar's parts over own (or mesh) */
    uint32_t n_parts;
    mim_io_skin_t rig;          /* a glTF avatar's rig (n_joints 0: none) */
    mim_io_read_options_t read_opt; /* how the avatar's file was read (its meshes: the caller's options') */
    int read_opt_set;           /* the avatar is a file */
    mim_reg_binding_t binding;
    mim_reg_follow_t follow;    /* where it is far from the proxy, it follows the segments */
    float *crushed;             /* how crushed registration left each proxy vertex (NULL: none known) */
    int turned;                 /* it faces another way: registered and bound as canon = turn own */
    double turn[9];
    mim_mesh_t canon;
    char bound_note[8800];      /* how a new binding was made, said once the avatar is accepted */
    char turn_note[4300];       /* that it is driven turned, said then too */
    int foreign;
    pthread_mutex_t out_lock;
    float *out_work;            /* 3 * n: the proxy's normals */
    /* every template's landmarks, for completion (guarded by table_lock) */
    pthread_mutex_t table_lock;
    int table_built;
    mim_error_t table_failed;   /* the first failure to read it: kept, not read again */
    uint32_t table_count, table_cap;
    float *table_lm;
    char **table_subject;
    char **table_pose;          /* pose labels, qualified by dataset as the subjects are */
    uint64_t *table_id;         /* ascending (the store's id order) */
    int spread_known;           /* pose_spread computed (mim_session_pose_spread of the table) */
    double pose_spread;
    double *W;                  /* the avatar's encoding, 3 * n */
    double *restF;              /* the avatar's rest frames, 9 * n (relative transfer turns them) */
    double *restD;              /* its rest offsets F W, 3 * n (the orientation drive turns them) */
    mim_xfer_skin_t *skin;      /* its segmentation over the 17 vest segments; NULL: skin_failed says why */
    mim_error_t skin_failed;
    int skin_from_rig;          /* the skin's weights are the avatar's own rig's (a skinned glTF) */
    double t_factor;
    char store[4096];
    char avatar[4096];          /* how the avatar was named: path or "template N" */

    /* guarded by lock: the one factor, and the last templates' frames,
     * which most consecutive transfers share (a vest holding a pose) */
    pthread_mutex_t lock;
    mim_xfer_solver_t *solver;
    template_slot_t slot[MIM_XFER_BLEND_MAX];
    uint64_t tick;              /* the slots' clock (least recently used goes first) */
    double *bF;                 /* 9 * n: the blended templates' frames (with the segment correction) */
    double *bD;                 /* 3 * n: the blended templates' offsets (without it) */
    double *oD;                 /* 3 * n: the orientation drive's offsets */
    double *rW;                 /* 3 * n: relative transfer's W */
    subject_ref_t *refs;        /* the template subjects' references met so far */
    uint32_t n_refs, cap_refs;
    float *rest_angles;         /* the avatar's rest landmarks' angles (mim_index_angle_count), on first need */
    uint64_t label_id;          /* 0, or the template whose "subject/pose" label holds */
    char label[MIM_SESSION_LABEL_MAX];
};

/* Every template's landmark positions (count * map count * 3 floats, id
 * order), subject labels and ids (ascending; ids may be NULL), read from
 * the store on first use and kept until close (complete.c scans them;
 * relative transfer finds references in them). Thread-safe. */
int mim__session_landmark_table(mim_session_t *s, const float **lm, char *const **subjects, const uint64_t **ids,
                                uint32_t *count, mim_error_t *err);

/* The rms (radians) of two index angle descriptors over the angles both
 * have (a degenerate landmark triple is NaN); NaN when none (pose_spread.c). */
double mim__angles_rms(const float *a, const float *b, uint32_t na);

/* The store's mim_session_pose_spread (degrees; NAN: unknown), computed
 * from the landmark table on first need and kept. Thread-safe. */
double mim__session_store_spread(mim_session_t *s);

/* The drives' frames (frames.c, each under s->lock; their comments there):
 * template id's cache slot; the orientation and skeleton drives' offsets
 * into s->oD; the template drive's frames or offsets and W (which may take
 * the skeleton drive on the plain path: r->drive says). */
int mim__session_cache_template(mim_session_t *s, uint64_t id, uint32_t slots, template_slot_t **out, mim_error_t *err);
int mim__session_orientation_offsets(mim_session_t *s, const mim_session_request_t *req, mim_session_report_t *r,
                                     mim_error_t *err);
int mim__session_skeleton_offsets(mim_session_t *s, const float *u, mim_error_t *err);
int mim__session_template_frames(mim_session_t *s, const mim_session_request_t *req, mim_session_report_t *r,
                                 double *weights, const float *u, const double **frames, const double **offsets,
                                 const double **W, template_slot_t **first, mim_error_t *err);

/* Template id's reference for relative transfer (relative.c; under
 * s->lock), found on first need and kept in s->refs; *out NULL when it has
 * none (the plain path). When damage in the store is why (the landmark
 * table or the reference's record cannot be read), *damage says so and
 * the transfer reports it (mim_session_report_t.degraded). */
int mim__session_reference(mim_session_t *s, uint64_t id, subject_ref_t **out, mim_error_t *damage,
                           mim_error_t *err);

#endif
