/* Meshes of another connectivity (issue 13): their landmarks, wherever
 * they come from, and their registration onto the store's connectivity
 * (register/) with the nearest template the caller's index finds. ingest
 * (--register), mimic register and a session's foreign avatar all go
 * through here. */
#include "mim_ingest.h"
#include "mim_io.h"
#include "mim_register.h"

#include <pthread.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

uint64_t mim_ingest_mesh_hash(const mim_mesh_t *m)
{
    uint64_t h = mim_hash64(m->faces, (size_t)m->n_faces * 3 * sizeof *m->faces, m->n_vertices);
    return mim_hash64(m->positions, (size_t)m->n_vertices * 3 * sizeof *m->positions, h);
}

/* Positions of a map's landmarks on the mesh, reordered by name into the
 * store map's order. */
static int positions_from_map(const mim_landmark_map_t *fm, const mim_mesh_t *mesh, const mim_landmark_map_t *store,
                              const char *what, float *out, mim_error_t *err)
{
    int rc = mim_landmarks_validate(fm, mesh->n_vertices, what, err);
    if (rc) return rc;
    for (uint32_t l = 0; l < store->count; l++) {
        uint32_t k = 0;
        while (k < fm->count && strcmp(fm->names[k], store->names[l])) k++;
        if (k == fm->count)
            return mim_error_set(err, MIM_EFORMAT, "%s: has no landmark '%s', which the store's map needs", what,
                                 store->names[l]);
        memcpy(out + 3 * l, mesh->positions + 3 * (size_t)fm->vertex[k], 3 * sizeof *out);
    }
    return 0;
}

int mim_ingest_foreign_landmarks(const char *mesh_path, const mim_mesh_t *mesh,
                                 const mim_ingest_landmark_sources_t *src, const mim_landmark_map_t *store_map,
                                 float *out, char *how, size_t how_size, mim_error_t *err)
{
    mim_ingest_landmark_sources_t none = {0};
    if (!src) src = &none;
    char what[4200];
    mim_landmark_map_t fm;
    /* (c) the file the user gave, (b) the sidecar beside the mesh: a map of
     * this connectivity, or the positions themselves */
    char sidecar[4096];
    const char *file = src->landmarks_path;
    if (!file && mim_io_landmarks_sidecar(mesh_path, sidecar, sizeof sidecar) == 1) file = sidecar;
    if (file) {
        mim_landmark_file_kind_t kind;
        int rc = mim_landmark_file_read(file, store_map->count, &kind, &fm, out, err);
        if (rc) return rc;
        snprintf(how, how_size, "%s", file);
        if (kind == MIM_LANDMARK_FILE_POSITIONS) return mim_landmarks_check(out, NULL, store_map->count, file, -1, err);
        snprintf(what, sizeof what, "%s (landmark map for %s)", file, mesh_path);
        if (fm.topology_vertices && fm.topology_vertices != mesh->n_vertices)
            return mim_error_set(err, MIM_ETOPOLOGY, "%s: a landmark map of %u vertices, the mesh has %u", what,
                                 fm.topology_vertices, mesh->n_vertices);
        return positions_from_map(&fm, mesh, store_map, what, out, err);
    }
    /* (a) a landmark map of this connectivity that came with the dataset */
    if (src->dataset_map && src->dataset_map->topology_vertices == mesh->n_vertices) {
        snprintf(how, how_size, "%s", src->dataset_map_path ? src->dataset_map_path : "the dataset's landmark map");
        snprintf(what, sizeof what, "%s (for %s)", how, mesh_path);
        return positions_from_map(src->dataset_map, mesh, store_map, what, out, err);
    }
    /* (d) a connectivity mimic knows by its faces (SMPL: FAUST and kin) */
    const char *name = NULL;
    if (mim_reg_known_map(mesh->faces, mesh->n_faces, mesh->n_vertices, &fm, &name)) {
        snprintf(how, how_size, "built-in map %s", name);
        snprintf(what, sizeof what, "built-in map %s (for %s)", name, mesh_path);
        return positions_from_map(&fm, mesh, store_map, what, out, err);
    }
    char side_name[4096];
    if (mim_io_landmarks_sidecar(mesh_path, side_name, sizeof side_name) < 0) snprintf(side_name, sizeof side_name, "NAME.landmarks.json");
    return mim_error_set(err, MIM_ENOLANDMARKS,
                         "%s: no landmarks for a mesh of another connectivity (%u vertices): give %s FILE, "
                         "put %s beside it, or a landmark map of its connectivity",
                         mesh_path, mesh->n_vertices, src->option ? src->option : "--landmarks", side_name);
}

int mim_ingest_start_template(mim_db_t *db, const mim_landmark_map_t *map, mim_ingest_nearest_fn nearest, void *ctx,
                              const float *landmarks, uint64_t *id, mim_error_t *err)
{
    uint64_t ids[MIM_INGEST_CANDIDATES];
    uint32_t n = 0, L = map->count;
    int rc = nearest(ctx, landmarks, MIM_INGEST_CANDIDATES, ids, &n, err);
    if (rc) return rc;
    if (!n) return mim_error_set(err, MIM_ENOTFOUND, "the index found no template");
    float cand[MIM_INGEST_CANDIDATES * 3 * MIM_LANDMARKS_MAX];
    mim_db_txn_t *t = NULL;
    if ((rc = mim_db_begin(db, 0, &t, err))) return rc;
    for (uint32_t c = 0; c < n && !rc; c++) {
        mim_template_view_t v;
        if ((rc = mim_db_template_get(t, ids[c], &v, err))) break;
        for (uint32_t l = 0; l < L; l++) {
            if (map->vertex[l] >= v.n_vertices) {
                rc = mim_error_set(err, MIM_ETOPOLOGY, "template %llu: %u vertices, landmark %u is vertex %u",
                                   (unsigned long long)ids[c], v.n_vertices, l, map->vertex[l]);
                break;
            }
            memcpy(cand + ((size_t)c * L + l) * 3, v.positions + 3 * (size_t)map->vertex[l], 3 * sizeof(float));
        }
    }
    mim_db_abort(&t);
    if (rc) return rc;
    uint32_t best = 0;
    if (n > 1 && mim_reg_likest(landmarks, L, cand, n, &best, NULL)) best = 0; /* no fit: the index's nearest */
    *id = ids[best];
    return 0;
}

/* ---- the registrar ---- */
struct mim_ingest_registrar {
    mim_db_t *db;
    mim_reg_options_t opt;
    mim_ingest_nearest_fn nearest;
    void *nearest_ctx;
    uint32_t n, n_faces;
    uint32_t *faces;
    mim_landmark_map_t map;
    mim_xfer_topology_t *topo;
    pthread_mutex_t mu;
    mim_reg_t **free_ctx; /* registration contexts not in use, for any thread */
    uint32_t n_free, cap;
};

int mim_ingest_registrar_open(mim_ingest_registrar_t **out, mim_db_t *db, mim_ingest_nearest_fn nearest,
                              void *nearest_ctx, const mim_reg_options_t *opt, mim_error_t *err)
{
    *out = NULL;
    if (!db || !nearest) return mim_error_set(err, MIM_EINVAL, "registration needs a store and its index");
    mim_ingest_registrar_t *r = calloc(1, sizeof *r);
    if (!r) return mim_error_set(err, MIM_ENOMEM, "out of memory");
    r->db = db, r->nearest = nearest, r->nearest_ctx = nearest_ctx;
    if (opt) r->opt = *opt;
    pthread_mutex_init(&r->mu, NULL);
    mim_db_txn_t *t = NULL;
    mim_db_topology_t topo;
    int rc = mim_db_begin(db, 0, &t, err);
    if (!rc && (rc = mim_db_topology_get(t, &topo, err)) == MIM_ENOTFOUND)
        rc = mim_error_set(err, rc, "%s: the store is empty: there is no connectivity to register onto yet",
                           mim_db_path(db));
    if (!rc && (rc = mim_db_landmarks_get(t, &r->map, err)) == MIM_ENOTFOUND)
        rc = mim_error_set(err, MIM_ENOLANDMARKS, "%s: the store has no landmark map", mim_db_path(db));
    if (!rc) {
        r->n = topo.n_vertices, r->n_faces = topo.n_faces;
        r->faces = malloc((size_t)topo.n_faces * 3 * sizeof *r->faces);
        if (!r->faces) rc = mim_error_set(err, MIM_ENOMEM, "out of memory");
        else memcpy(r->faces, topo.faces, (size_t)topo.n_faces * 3 * sizeof *r->faces);
    }
    mim_db_abort(&t);
    if (!rc) rc = mim_xfer_topology_open(&r->topo, r->n, r->faces, r->n_faces, err);
    if (rc) {
        mim_ingest_registrar_close(&r);
        return rc;
    }
    *out = r;
    return 0;
}

void mim_ingest_registrar_close(mim_ingest_registrar_t **rp)
{
    if (!rp || !*rp) return;
    mim_ingest_registrar_t *r = *rp;
    for (uint32_t i = 0; i < r->n_free; i++) mim_reg_close(&r->free_ctx[i]);
    free(r->free_ctx);
    mim_xfer_topology_close(&r->topo);
    free(r->faces);
    pthread_mutex_destroy(&r->mu);
    free(r);
    *rp = NULL;
}

const mim_landmark_map_t *mim_ingest_registrar_map(const mim_ingest_registrar_t *r) { return &r->map; }
const mim_xfer_topology_t *mim_ingest_registrar_topology(const mim_ingest_registrar_t *r) { return r->topo; }
const uint32_t *mim_ingest_registrar_faces(const mim_ingest_registrar_t *r, uint32_t *n_faces)
{
    if (n_faces) *n_faces = r->n_faces;
    return r->faces;
}

/* A registration context for this call: one from the pool, or a new one
 * (each holds a factor and workspaces, so threads never share one). */
static int take_ctx(mim_ingest_registrar_t *r, mim_reg_t **ctx, mim_error_t *err)
{
    pthread_mutex_lock(&r->mu);
    *ctx = r->n_free ? r->free_ctx[--r->n_free] : NULL;
    pthread_mutex_unlock(&r->mu);
    return *ctx ? 0 : mim_reg_open(ctx, r->topo, &r->map, &r->opt, err);
}

static void give_ctx(mim_ingest_registrar_t *r, mim_reg_t *ctx)
{
    pthread_mutex_lock(&r->mu);
    if (r->n_free == r->cap) {
        uint32_t cap = r->cap ? 2 * r->cap : 4;
        mim_reg_t **p = realloc(r->free_ctx, cap * sizeof *p);
        if (p) r->free_ctx = p, r->cap = cap;
    }
    if (r->n_free < r->cap) r->free_ctx[r->n_free++] = ctx, ctx = NULL;
    pthread_mutex_unlock(&r->mu);
    mim_reg_close(&ctx);
}

int mim_ingest_register_mesh(mim_ingest_registrar_t *r, const mim_mesh_t *mesh, const float *landmarks,
                             const char *origin, float *out, mim_reg_report_t *report, uint64_t *template_id,
                             mim_error_t *err)
{
    uint64_t id = 0;
    /* landmarks that span no body (all at one point, or on a line) give
     * the index nothing to recognise: one plain line naming the mesh, before
     * the query says something of angles (issue 30) */
    {
        mim_reg_similarity_t sim;
        mim_error_t e = {0};
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t l = 0; l < r->map.count; l++)
            for (int c = 0; c < 3; c++)
                lo[c] = fmin(lo[c], landmarks[3 * l + c]), hi[c] = fmax(hi[c], landmarks[3 * l + c]);
        const double span = sqrt(pow(hi[0] - lo[0], 2) + pow(hi[1] - lo[1], 2) + pow(hi[2] - lo[2], 2));
        if (!(span > 0.01) || mim_reg_similarity_fit(landmarks, landmarks, r->map.count, &sim, &e))
            return mim_error_set(err, MIM_EFORMAT,
                                 "%s: its %u landmarks lie within %.1f mm of each other or on one line: "
                                 "registration needs them spread over the body",
                                 origin, r->map.count, 1e3 * (isfinite(span) ? span : 0));
    }
    int rc = mim_ingest_start_template(r->db, &r->map, r->nearest, r->nearest_ctx, landmarks, &id, err);
    if (rc) return rc;
    float *tmpl = malloc((size_t)3 * r->n * sizeof *tmpl);
    if (!tmpl) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
    mim_db_txn_t *t = NULL;
    mim_template_view_t v;
    if (!(rc = mim_db_begin(r->db, 0, &t, err)) && !(rc = mim_db_template_get(t, id, &v, err))) {
        if (v.n_vertices != r->n)
            rc = mim_error_set(err, MIM_ETOPOLOGY, "template %llu: %u vertices, the store's connectivity has %u",
                               (unsigned long long)id, v.n_vertices, r->n);
        else
            memcpy(tmpl, v.positions, (size_t)3 * r->n * sizeof *tmpl);
    }
    mim_db_abort(&t);
    mim_reg_t *ctx = NULL;
    if (!rc && !(rc = take_ctx(r, &ctx, err))) {
        rc = mim_reg_run(ctx, tmpl, mesh, landmarks, origin, out, report, err);
        give_ctx(r, ctx);
    }
    free(tmpl);
    if (!rc && template_id) *template_id = id;
    return rc;
}
