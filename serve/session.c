/* Store, avatar and templates for transfer, morph and serve (session.h). */
#include "session.h"

#include "mim_ingest.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int all_digits(const char *s)
{
    if (!*s)
        return 0;
    for (; *s; s++)
        if (*s < '0' || *s > '9')
            return 0;
    return 1;
}

int mim_serve_template_id(const char *cmd, const char *text, uint64_t *id)
{
    char *end = NULL;
    unsigned long long v = all_digits(text) ? strtoull(text, &end, 10) : 0;
    if (!v) {
        fprintf(stderr, "mimic %s: '%s' is not a template id (a number from mimic list)\n", cmd, text);
        return -1;
    }
    *id = v;
    return 0;
}

void mim_serve_landmarks_of(const mim_landmark_map_t *map, const float *positions, float *out)
{
    for (uint32_t k = 0; k < map->count; k++)
        for (int c = 0; c < 3; c++)
            out[3 * k + c] = positions[3 * (size_t)map->vertex[k] + c];
}

/* Reads the store's connectivity and landmark map into s. */
static int load_store(mim_serve_session_t *s, const char *store, mim_error_t *err)
{
    mim_db_options_t o = {.read_only = 1};
    int rc = mim_db_open(&s->db, store, &o, err);
    mim_db_txn_t *t = NULL;
    if (!rc)
        rc = mim_db_begin(s->db, 0, &t, err);
    mim_db_topology_t topo;
    if (!rc && (rc = mim_db_topology_get(t, &topo, NULL)) == MIM_ENOTFOUND)
        rc = mim_error_set(err, MIM_ENOTFOUND, "%s: the store is empty (run mimic ingest first)", store);
    else if (rc)
        rc = mim_error_set(err, rc, "%s: cannot read its connectivity", store);
    if (!rc && (rc = mim_db_landmarks_get(t, &s->map, err)) == 0 &&
        (rc = mim_mesh_alloc(&s->mesh, topo.n_vertices, topo.n_faces)) == 0) {
        memcpy(s->mesh.faces, topo.faces, 3 * (size_t)topo.n_faces * sizeof *topo.faces);
        rc = mim_xfer_topology_open(&s->topo, topo.n_vertices, topo.faces, topo.n_faces, err);
    }
    mim_db_abort(&t);
    return rc;
}

int mim_serve_session_open(mim_serve_session_t *s, const char *store, const char *avatar, mim_error_t *err)
{
    memset(s, 0, sizeof *s);
    int rc = load_store(s, store, err);
    const uint32_t n = s->mesh.n_vertices;
    if (!rc && !(s->W = malloc(3 * (size_t)n * sizeof *s->W)))
        rc = mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
    if (rc)
        return rc;
    if (all_digits(avatar)) {
        uint64_t id = strtoull(avatar, NULL, 10);
        snprintf(s->avatar, sizeof s->avatar, "template %llu", (unsigned long long)id);
        double *F = malloc(9 * (size_t)n * sizeof *F);
        if (!F)
            return mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
        rc = mim_serve_session_template(s, id, s->mesh.positions, F, NULL, 0, err);
        if (!rc)
            mim_xfer_encode(s->topo, s->mesh.positions, F, s->W);
        free(F);
        return rc;
    }
    snprintf(s->avatar, sizeof s->avatar, "%s", avatar);
    mim_mesh_t m = {0};
    rc = mim_mesh_read(avatar, &m, err);
    if (!rc)
        rc = mim_xfer_check_mesh(s->topo, &m, avatar, err);
    if (!rc) {
        double *F = malloc(9 * (size_t)n * sizeof *F);
        if (!F) {
            rc = mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
        } else {
            memcpy(s->mesh.positions, m.positions, 3 * (size_t)n * sizeof(float));
            mim_xfer_frames(s->topo, s->mesh.positions, F);
            mim_xfer_encode(s->topo, s->mesh.positions, F, s->W);
            free(F);
        }
    }
    mim_mesh_free(&m);
    return rc;
}

int mim_serve_session_template(mim_serve_session_t *s, uint64_t id, float *positions, double *frames, char *label,
                             size_t label_size, mim_error_t *err)
{
    mim_db_txn_t *t = NULL;
    int rc = mim_db_begin(s->db, 0, &t, err);
    mim_template_view_t v;
    if (!rc && (rc = mim_db_template_get(t, id, &v, NULL)) == MIM_ENOTFOUND)
        rc = mim_error_set(err, rc, "%s: no template %llu (see mimic list)", mim_db_path(s->db),
                           (unsigned long long)id);
    else if (rc)
        rc = mim_error_set(err, rc, "%s: cannot read template %llu", mim_db_path(s->db), (unsigned long long)id);
    if (!rc && v.n_vertices != s->mesh.n_vertices)
        rc = mim_error_set(err, MIM_ESTORE, "%s: template %llu has %u vertices, the store's connectivity %u",
                           mim_db_path(s->db), (unsigned long long)id, v.n_vertices, s->mesh.n_vertices);
    if (!rc) {
        memcpy(positions, v.positions, 3 * (size_t)v.n_vertices * sizeof(float));
        if (label)
            snprintf(label, label_size, "%s/%s", v.subject[0] ? v.subject : "-", v.pose[0] ? v.pose : "-");
        mim_db_encoding_t e;
        if (frames) {
            /* stored by ingest; a store from before encodings were kept gets them computed */
            if (mim_db_encoding_get(t, id, &e, NULL) == 0 && e.n_vertices == v.n_vertices)
                mim_xfer_encoding_unpack(e.n_vertices, e.frames, NULL, frames, NULL);
            else
                mim_xfer_frames(s->topo, positions, frames);
        }
    }
    mim_db_abort(&t);
    return rc;
}

void mim_serve_session_close(mim_serve_session_t *s)
{
    mim_xfer_topology_close(&s->topo);
    mim_mesh_free(&s->mesh);
    free(s->W);
    mim_db_close(&s->db);
    memset(s, 0, sizeof *s);
}
