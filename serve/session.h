/* What `mimic transfer`, `mimic morph` and `mimic serve` share: a store opened for
 * reading, its connectivity and landmark map, the avatar (a mesh file or a
 * template id) with its encoding, and templates read with their stored
 * encodings (seed 000 §3.1). */
#ifndef MIM_SERVE_SESSION_H
#define MIM_SERVE_SESSION_H

#include "mim_db.h"
#include "mim_transfer.h"

typedef struct mim_serve_session {
    mim_db_t *db;
    mim_xfer_topology_t *topo;
    mim_landmark_map_t map;
    mim_mesh_t mesh;    /* the store's faces with the avatar's rest positions */
    double *W;          /* the avatar's encoding, 3 * n */
    char avatar[4096];  /* how the avatar was named: path or "template N" */
} mim_serve_session_t;

/* Opens store read-only and loads the avatar: an all-digit argument is a
 * template id, anything else a mesh file, which must have the store's
 * connectivity. Errors name the store, the file or the id. */
int mim_serve_session_open(mim_serve_session_t *s, const char *store, const char *avatar, mim_error_t *err);
void mim_serve_session_close(mim_serve_session_t *s);

/* Template id's positions (3 * n floats) and frames (9 * n doubles; NULL
 * to skip), from its stored encoding, or computed when the store has none.
 * label (may be NULL) gets "subject/pose". MIM_ENOTFOUND for an unknown id. */
int mim_serve_session_template(mim_serve_session_t *s, uint64_t id, float *positions, double *frames, char *label,
                             size_t label_size, mim_error_t *err);

/* The landmark positions (3 * count floats) at the landmark vertices of a mesh. */
void mim_serve_landmarks_of(const mim_landmark_map_t *map, const float *positions, float *out);

/* Parses a template id argument (decimal, >= 1); -1 and a message if not. */
int mim_serve_template_id(const char *cmd, const char *text, uint64_t *id);

#endif
