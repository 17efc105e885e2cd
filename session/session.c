/* The session (mim_session.h): a store opened for reading, its index, the
 * avatar and its encoding W = F^T L X (seed 000, Section 3.1), the factor
 * of the avatar's constrained system (eq. 3), and the one pipeline from
 * landmarks to a transferred mesh (Sections 3.3-3.4). */
#include "internal.h"

#include "mim_schema_version.h"

#include "mim_index.h"
#include "mim_ingest.h"
#include "mim_io.h"
#include "mim_register.h"
#include "mim_vest_kinematics.h"

#include <math.h>
#include <pthread.h>
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

/* Reads the store's connectivity and landmark map into s. */
static int load_store(mim_session_t *s, const char *store, uint64_t map_size, mim_error_t *err)
{
    mim_db_options_t o = {.read_only = 1, .map_size = map_size};
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

/* The binding cache's key: the avatar mesh, the landmarks it was
 * registered with (other landmarks, another registration), the store's
 * connectivity and landmark map (another store, another entry). */
static uint64_t binding_key(const mim_session_t *s, const mim_mesh_t *m, const float *lm)
{
    uint64_t h = mim_ingest_mesh_hash(m);
    h = mim_hash64(lm, 3 * (size_t)s->map.count * sizeof *lm, h);
    h = mim_hash64(s->mesh.faces, 3 * (size_t)s->mesh.n_faces * sizeof *s->mesh.faces, h);
    return mim_hash64(s->map.vertex, s->map.count * sizeof *s->map.vertex, h);
}

/* Keeps a new binding in the store for the next start. The session's
 * store is open read-only: it is closed, opened for writing just for this,
 * and opened read-only again (no transaction is open meanwhile). A store
 * that cannot be written keeps nothing, with a warning. */
static int cache_binding(mim_session_t *s, uint64_t key, mim_error_t *err)
{
    if (s->base) { /* the store is shared and in use: it cannot be closed for writing now */
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN,
                     "%s: the avatar's binding is not kept in %s: the store is shared by other sessions (mimic "
                     "transfer --avatar with this avatar keeps it, and later sessions find it)",
                     s->avatar, s->store);
        return 0;
    }
    /* Opening an older store for writing would migrate it (mim_db.h): a
     * command that only reads the store must not, so its binding is not
     * kept there. */
    mim_db_txn_t *rt = NULL;
    mim_db_meta_t meta = {0};
    if (!mim_db_begin(s->db, 0, &rt, NULL)) mim_db_meta_get(rt, &meta, NULL);
    mim_db_abort(&rt);
    if (meta.schema_version != MIM_STORE_SCHEMA_VERSION) {
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN,
                     "%s: the avatar's binding is not kept: %s is of schema version %u (mimic store migrate brings it "
                     "to %d, and then it is)",
                     s->avatar, s->store, meta.schema_version, MIM_STORE_SCHEMA_VERSION);
        return 0;
    }
    void *blob = NULL;
    size_t len = 0;
    mim_error_t e = {0};
    int rc = mim_reg_binding_encode(&s->binding, &blob, &len, &e);
    mim_query_close(&s->query);
    mim_db_close(&s->db);
    mim_db_t *w = NULL;
    mim_db_txn_t *t = NULL;
    mim_db_options_t wo = {.map_size = s->opt.map_size};
    if (!rc && !(rc = mim_db_open(&w, s->store, &wo, &e)) && !(rc = mim_db_begin(w, 1, &t, &e)) &&
        !(rc = mim_db_binding_put(t, key, blob, len, &e)))
        rc = mim_db_commit(&t, &e);
    mim_db_abort(&t);
    mim_db_close(&w);
    free(blob);
    if (rc)
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN, "%s: the avatar's binding is not kept in the store: %s",
                     s->avatar, mim_error_text(&e));
    mim_db_options_t ro = {.read_only = 1, .map_size = s->opt.map_size};
    rc = mim_db_open(&s->db, s->store, &ro, err);
    if (!rc && s->index.has_index) rc = mim_query_open(&s->query, s->db, err);
    return rc;
}

/* A cached binding is used only when it gives the avatar back at rest
 * (within BINDING_REST_TOL metres): a record that decodes, fields in
 * range and checksum right, can still be another proxy's or hold other
 * offsets, and would pose the avatar wrongly. One application of the
 * binding, about what one frame costs. 0, or MIM_EFORMAT with why in e. */
#define BINDING_REST_TOL 1e-4
static int binding_fits(const mim_session_t *s, const mim_mesh_t *m, mim_error_t *e)
{
    if (s->binding.n_vertices != m->n_vertices)
        return mim_error_set(e, MIM_EFORMAT, "binding: made for %u avatar vertices, not %u", s->binding.n_vertices,
                             m->n_vertices);
    float *work = malloc(3 * (size_t)s->mesh.n_vertices * sizeof *work);
    float *back = malloc(3 * (size_t)m->n_vertices * sizeof *back);
    int rc = work && back ? 0 : mim_error_set(e, MIM_ENOMEM, "binding: out of memory");
    if (!rc) {
        mim_reg_binding_apply(&s->binding, s->mesh.faces, s->binding.proxy_rest, work, back);
        double worst = 0.0;
        uint32_t at = 0;
        for (size_t i = 0; i < 3 * (size_t)m->n_vertices; i++) {
            double d = fabs((double)back[i] - m->positions[i]);
            if (!(d <= worst)) /* a NaN too */
                worst = d, at = (uint32_t)(i / 3);
        }
        if (!(worst <= BINDING_REST_TOL))
            rc = mim_error_set(e, MIM_EFORMAT, "binding: not this avatar's: at rest it puts vertex %u %.2f mm off", at,
                               1e3 * worst);
    }
    free(work), free(back);
    return rc;
}

static int no_index(const mim_session_t *s, const char *path, const mim_mesh_t *m, mim_error_t *err)
{
    return mim_error_set(err, MIM_ENOINDEX,
                         "%s: an avatar of another connectivity (%u vertices, the store's %u) is registered from the "
                         "nearest template, and %s has no index (run mimic index)",
                         path, m->n_vertices, s->mesh.n_vertices, s->store);
}

/* An avatar that faces another way than the store's bodies (+Y up,
 * facing +Z, its own left +X; a VRM 0.x model faces -Z) is driven turned
 * into that frame, and its outputs are turned back: the templates' and a
 * vest's poses are in that frame. From its landmarks: up from the hips to
 * the shoulders, left from the right ones to the left. Returns 1 and
 * fills R (canonical = R p, row-major) when it is more than 60 degrees off. */
static int facing_turn(const mim_landmark_map_t *map, const float *lm, double R[9])
{
    int at[4] = {-1, -1, -1, -1};
    static const char *const want[4] = {"l_shoulder", "r_shoulder", "l_hip", "r_hip"};
    for (uint32_t l = 0; l < map->count; l++)
        for (int k = 0; k < 4; k++)
            if (!strcmp(map->names[l], want[k])) at[k] = (int)l;
    if (at[0] < 0 || at[1] < 0 || at[2] < 0 || at[3] < 0) return 0;
    mim_vec3 p[4];
    for (int k = 0; k < 4; k++) p[k] = mim_v3(lm[3 * at[k]], lm[3 * at[k] + 1], lm[3 * at[k] + 2]);
    mim_vec3 U = mim_v3_normalize(mim_v3_sub(mim_v3_add(p[0], p[1]), mim_v3_add(p[2], p[3])));
    mim_vec3 L = mim_v3_add(mim_v3_sub(p[0], p[1]), mim_v3_sub(p[2], p[3]));
    L = mim_v3_normalize(mim_v3_sub(L, mim_v3_scale(U, mim_v3_dot(L, U))));
    mim_vec3 F = mim_v3_cross(L, U);
    if (!(mim_v3_norm(L) > 0.5) || !(mim_v3_norm(U) > 0.5) || (F.z >= 0.5 && U.y >= 0.5)) return 0;
    const mim_vec3 rows[3] = {L, U, F};
    for (int r = 0; r < 3; r++) R[3 * r] = rows[r].x, R[3 * r + 1] = rows[r].y, R[3 * r + 2] = rows[r].z;
    return 1;
}

static void turn_points(const double R[9], int transpose, const float *in, uint32_t n, float *out)
{
    for (uint32_t i = 0; i < n; i++) {
        const double x = in[3 * (size_t)i], y = in[3 * (size_t)i + 1], z = in[3 * (size_t)i + 2];
        for (int r = 0; r < 3; r++) {
            const double *row = transpose ? NULL : R + 3 * r;
            out[3 * (size_t)i + r] = transpose ? (float)(R[r] * x + R[3 + r] * y + R[6 + r] * z)
                                               : (float)(row[0] * x + row[1] * y + row[2] * z);
        }
    }
}

/* The proxy's vertices that registration crushed (mim_reg_crushed): its
 * triangles against the template registration started from, found as the
 * registrar finds it (mim_ingest_start_template), so that a binding
 * from the cache gets the same flags. NULL without an index or that
 * template (then nothing is flagged). */
static float *proxy_crushed(mim_session_t *s, const float *lm)
{
    const uint32_t n = s->mesh.n_vertices, count = s->map.count;
    uint64_t id = 0;
    mim_error_t e = {0};
    if (!s->query || mim_ingest_start_template(s->db, &s->map, mim_query_nearest, s->query, lm, &id, &e))
        return NULL;
    float *t = malloc(3 * (size_t)n * sizeof *t), tl[3 * MIM_LANDMARKS_MAX];
    float *flags = malloc(((size_t)n + 1) * sizeof *flags);
    if (!t || !flags || mim_session_template(s, id, t, NULL, NULL, 0, &e)) {
        free(t), free(flags);
        return NULL;
    }
    for (uint32_t l = 0; l < count; l++) memcpy(tl + 3 * l, t + 3 * (size_t)s->map.vertex[l], 3 * sizeof(float));
    mim_reg_similarity_t sim;
    if (mim_reg_similarity_fit(tl, lm, count, &sim, &e)) sim.scale = 1;
    mim_reg_crushed(s->mesh.faces, s->mesh.n_faces, n, s->binding.proxy_rest, t, sim.scale, flags);
    free(t);
    return flags;
}

/* A foreign avatar m: its binding from the store's cache, or registered
 * now (issue 13: landmarks as for any foreign mesh, the nearest template
 * through the index, then bound and cached). Fills s->binding and the
 * proxy's rest positions into s->mesh. */
static int load_foreign_avatar(mim_session_t *s, const char *path, const mim_mesh_t *m, mim_error_t *err)
{
    mim_ingest_landmark_sources_t src = {.landmarks_path = s->opt.avatar_landmarks, .option = "--avatar-landmarks"};
    float lm[3 * MIM_LANDMARKS_MAX];
    char how[4200];
    mim_error_t lm_err = {0};
    int rc = mim_ingest_foreign_landmarks(path, m, &src, &s->map, lm, how, sizeof how, &lm_err);
    if (rc == MIM_ENOLANDMARKS && s->rig.n_joints) { /* no file, no known map: the rig places them (issue 28) */
        mim_error_t rig_err = {0};
        int rig_rc = mim_session_rig_landmarks(m, &s->rig, &s->map, lm, how, sizeof how, &rig_err);
        if (!rig_rc)
            rc = 0;
        else
            rc = mim_error_set(&lm_err, rig_rc, "%s; nor from its rig: %s", mim_error_text(&lm_err),
                               mim_error_text(&rig_err));
    }
    if (rc && !s->query) /* the index is what it needs first: without landmarks no cached binding is found either */
        return no_index(s, path, m, err);
    if (rc) return mim_error_set(err, rc, "%s", mim_error_text(&lm_err));
    uint64_t key = binding_key(s, m, lm);
    if (facing_turn(&s->map, lm, s->turn)) { /* registered, bound and followed turned (facing_turn) */
        if (mim_mesh_alloc(&s->canon, m->n_vertices, m->n_faces))
            return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
        memcpy(s->canon.faces, m->faces, 3 * (size_t)m->n_faces * sizeof *m->faces);
        turn_points(s->turn, 0, m->positions, m->n_vertices, s->canon.positions);
        turn_points(s->turn, 0, lm, s->map.count, lm);
        s->turned = 1;
        m = &s->canon;
        snprintf(s->turn_note, sizeof s->turn_note, /* said once the avatar is accepted */
                 "%s: it faces another way than the store's bodies (+Y up, facing +Z): driven turned, output "
                 "as it stands", path);
    }
    mim_db_txn_t *t = NULL;
    const void *blob;
    size_t len;
    int cached = 0, got = MIM_ENOTFOUND;
    rc = mim_db_begin(s->db, 0, &t, err);
    mim_error_t e = {0};
    if (!rc)
        got = mim_db_binding_get(t, key, &blob, &len, &e);
    if (!rc && got == 0) {
        cached = mim_reg_binding_decode(blob, len, s->mesh.n_vertices, s->mesh.n_faces, &s->binding, &e) == 0 &&
                 binding_fits(s, m, &e) == 0;
        if (!cached)
            mim_reg_binding_free(&s->binding);
    }
    if (!rc && !cached && got != MIM_ENOTFOUND) /* a damaged record (the store's checks) or one not this avatar's */
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN, "%s: cached binding not usable (%s): binding again",
                     path, mim_error_text(&e));
    mim_db_abort(&t);
    if (rc) return rc;
    if (!cached) {
        if (!s->query) return no_index(s, path, m, err);
        /* registered onto the avatar welded (seams and flat shading split
         * it; issue 28), all its pieces at once; bound below in its own
         * split vertices, which coincident copies bind alike */
        mim_ingest_registrar_t *r = NULL;
        mim_reg_report_t rep;
        mim_mesh_t welded = {0};
        uint32_t *weld_map = malloc(((size_t)m->n_vertices + 1) * sizeof *weld_map);
        const mim_reg_options_t ro = {.pieces = 1};
        if (!weld_map) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
        rc = mim_reg_weld(m, 0, &welded, weld_map, err);
        free(weld_map);
        int64_t pieces = rc ? 0 : mim_reg_pieces(&welded);
        if (!rc && pieces > MIM_REG_MAX_PIECES)
            rc = mim_error_set(err, MIM_ETOPOLOGY,
                               "%s: %lld pieces once its seams are welded, more than the %d mimic drives as one body",
                               path, (long long)pieces, MIM_REG_MAX_PIECES);
        else if (!rc && pieces < 0)
            rc = mim_error_set(err, (int)pieces, "%s: out of memory", path);
        if (!rc && !(rc = mim_ingest_registrar_open(&r, s->db, mim_query_nearest, s->query, &ro, err)))
            rc = mim_ingest_register_mesh(r, &welded, lm, path, s->mesh.positions, &rep, NULL, err);
        mim_ingest_registrar_close(&r);
        mim_mesh_free(&welded);
        if (rc) return rc;
        const double limit = s->opt.max_distance_mm > 0 ? s->opt.max_distance_mm : MIM_INGEST_DEFAULT_MAX_DISTANCE_MM;
        if (!(rep.p95_mm <= limit))
            return mim_error_set(err, MIM_ETOPOLOGY,
                                 "%s: registration too far from the avatar's surface: distance p95 %.1f mm over the "
                                 "%g mm limit (mean %.1f mm; --max-distance-mm raises it)",
                                 path, rep.p95_mm, limit, rep.mean_mm);
        if ((rc = mim_reg_bind(&s->mesh, m, &s->binding, err))) return rc;
        /* said once the avatar is accepted whole (follow_segments may still refuse it) */
        snprintf(s->bound_note, sizeof s->bound_note,
                 "%s: registered onto the store's connectivity (landmarks from %s; surface distance mean %.2f mm, "
                 "p95 %.2f mm) and bound, %.2f s",
                 path, how, rep.mean_mm, rep.p95_mm, rep.seconds);
        if ((rc = cache_binding(s, key, err))) return rc;
    } else {
        memcpy(s->mesh.positions, s->binding.proxy_rest, 3 * (size_t)s->mesh.n_vertices * sizeof(float));
    }
    s->crushed = proxy_crushed(s, lm);
    s->out_work = malloc(3 * (size_t)s->mesh.n_vertices * sizeof *s->out_work);
    if (!s->out_work) return mim_error_set(err, MIM_ENOMEM, "out of memory");
    s->foreign = 1;
    return 0;
}

/* The avatar's rest positions (a template id or a mesh file) and its W. */
static int load_avatar(mim_session_t *s, const char *avatar, mim_error_t *err)
{
    const uint32_t n = s->mesh.n_vertices;
    double *F = malloc(9 * (size_t)n * sizeof *F);
    if (!F)
        return mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
    int rc;
    if (all_digits(avatar)) {
        uint64_t id = strtoull(avatar, NULL, 10);
        snprintf(s->avatar, sizeof s->avatar, "template %llu", (unsigned long long)id);
        rc = mim_session_template(s, id, s->mesh.positions, F, NULL, 0, err);
        if (!rc) /* stored by an older mimic, which did not check bodies */
            rc = mim_body_check(s->mesh.positions, n, s->avatar, err);
    } else {
        snprintf(s->avatar, sizeof s->avatar, "%s", avatar);
        mim_io_scene_t scene;
        s->read_opt = (mim_io_read_options_t){.meshes = s->opt.avatar_meshes, .n_meshes = s->opt.n_avatar_meshes};
        s->read_opt_set = 1;
        rc = mim_io_read_scene(avatar, &s->read_opt, &scene, err);
        mim_mesh_t m = scene.mesh;
        if (!rc) {
            s->parts = scene.parts, s->n_parts = scene.n_parts;
            if (scene.skin_rc == 0)
                s->rig = scene.skin;
            else if (scene.skin_rc != MIM_ENOTFOUND) /* no skin (a PLY) is no news; a broken one is */
                mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN, "%s; its rig is not used", scene.skin_msg);
            else
                mim_io_skin_free(&scene.skin);
        }
        if (!rc) /* an avatar must be a body (a 10 m box, not a point) before it is factored */
            rc = mim_body_check(m.positions, m.n_vertices, avatar, err);
        mim_error_t topo_err = {0};
        if (!rc && mim_xfer_check_mesh(s->topo, &m, avatar, &topo_err) == 0) {
            memcpy(s->mesh.positions, m.positions, 3 * (size_t)n * sizeof(float));
            mim_mesh_free(&m);
        } else if (!rc && topo_err.code == MIM_ETOPOLOGY) {
            /* another connectivity: drive it through a registered proxy */
            rc = load_foreign_avatar(s, avatar, &m, err);
            s->own = m;
        } else {
            if (!rc) rc = mim_error_set(err, topo_err.code, "%s", mim_error_text(&topo_err));
            mim_mesh_free(&m);
        }
        if (!rc)
            mim_xfer_frames(s->topo, s->mesh.positions, F);
    }
    if (!rc)
        mim_xfer_encode(s->topo, s->mesh.positions, F, s->W);
    if (rc)
        free(F);
    else
        s->restF = F;
    return rc;
}

/* A skinned glTF avatar segments by its own rig where its joint names map
 * to the vest's segments (mim_vest_segments_of_joints), by geometry where
 * a vertex hangs on unmapped joints only. A rig that covers fewer than
 * MIN_RIG_SEGMENTS segments is no body rig: the geometry decides alone. A
 * foreign avatar's rig is on its own vertices: each proxy vertex takes the
 * weights of the avatar vertices bound to its triangles, by their
 * barycentric share. */
#define MIN_RIG_SEGMENTS 12
static void rig_weights(mim_session_t *s)
{
    const mim_io_skin_t rig = s->rig; /* read with the avatar (load_avatar) */
    if (!rig.n_joints) return;
    const uint32_t n = s->mesh.n_vertices, G = MIM_VEST_SEGMENTS;
    const char **names = malloc(rig.n_joints * sizeof *names);
    int *bone = malloc(rig.n_joints * sizeof *bone);
    float *dense = calloc((size_t)n * G, sizeof *dense);
    const uint32_t want = s->foreign ? s->own.n_vertices : n;
    uint32_t covered = 0;
    if (!names || !bone || !dense) {
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN, "%s: out of memory for its skin: segmenting by the geometry",
                     s->avatar);
    } else if (rig.n_vertices != want) {
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN,
                     "%s: its skin has %u vertices, the mesh %u: segmenting by the geometry", s->avatar, rig.n_vertices,
                     want);
    } else {
        for (uint32_t j = 0; j < rig.n_joints; j++) names[j] = rig.names[j];
        covered = mim_vest_segments_of_joints(names, rig.n_joints, bone);
        if (covered < MIN_RIG_SEGMENTS)
            mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN,
                         "%s: its skin's joint names give %u of the 17 segments (at least %d needed): segmenting "
                         "by the geometry",
                         s->avatar, covered, MIN_RIG_SEGMENTS);
    }
    if (covered >= MIN_RIG_SEGMENTS) {
        /* a rig vertex's joints summed per segment, onto the proxy's corners it sits between */
        const uint32_t entries = s->foreign ? s->binding.n_vertices : n;
        for (uint32_t i = 0; i < entries; i++) {
            uint32_t a = s->foreign ? s->binding.vertex[i] : i, corner[3] = {i, i, i};
            float share[3] = {1, 0, 0};
            if (s->foreign) {
                const uint32_t *fv = s->mesh.faces + 3 * (size_t)s->binding.face[i];
                float u = s->binding.bary[2 * i], v = s->binding.bary[2 * i + 1];
                corner[0] = fv[0], corner[1] = fv[1], corner[2] = fv[2];
                share[0] = 1 - u - v, share[1] = u, share[2] = v;
            }
            for (int k = 0; k < 4; k++) {
                int g = bone[rig.joints[4 * (size_t)a + k]];
                if (g < 0) continue;
                for (int c = 0; c < 3; c++)
                    dense[(size_t)corner[c] * G + g] += share[c] > 0 ? share[c] * rig.weights[4 * (size_t)a + k] : 0;
            }
        }
        uint32_t by_geometry = mim_xfer_skin_from_dense(n, dense, G, s->skin, s->skin); /* in place */
        s->skin_from_rig = 1;
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_INFO,
                     "%s: segments from its skin (%u joints on %u of the 17 segments; %u vertices by geometry)",
                     s->avatar, rig.n_joints, covered, by_geometry);
    }
    free(names), free(bone), free(dense);
}

/* The avatar's segmentation (issue 17): bones of the vest skeleton under
 * its landmarks, skinned over its surface. A map without the 16 default
 * landmarks cannot be segmented: the orientation drive is then refused
 * with skin_failed's reason, and auto falls back to templates. */
static void segment_avatar(mim_session_t *s)
{
    mim_vest_skeleton_t sk;
    double bones[MIM_VEST_SEGMENTS * 6];
    int rc = mim_vest_skeleton_estimate(&sk, &s->mesh, &s->map, &s->skin_failed);
    if (!rc) {
        mim_vest_skeleton_bones(&sk, bones);
        if (!(s->skin = malloc((size_t)s->mesh.n_vertices * sizeof *s->skin)))
            rc = mim_error_set(&s->skin_failed, MIM_ENOMEM, "out of memory for the avatar's segments");
    }
    if (!rc)
        rc = mim_xfer_skin_from_bones_wide(s->topo, s->mesh.positions, bones, MIM_VEST_SEGMENTS,
                                           MIM_XFER_DEFAULT_SKIN_SMOOTHING, MIM_XFER_SKIN_WIDE_SEGMENTS,
                                           MIM_XFER_DEFAULT_SKIN_SMOOTHING_WIDE, s->skin, &s->skin_failed);
    if (!rc)
        rig_weights(s);
    if (rc) {
        free(s->skin);
        s->skin = NULL;
        mim_error_t why = s->skin_failed;
        s->skin_failed = (mim_error_t){0};
        mim_error_set(&s->skin_failed, rc, "%s: the avatar cannot be segmented for the orientation drive: %s",
                      s->avatar, mim_error_text(&why));
    }
}

/* Each avatar vertex's heaviest segment by its own rig (-1: none), so
 * that a prop follows the bone its author hung it on. NULL without a rig
 * that maps to the segments. */
static int *rig_segments(const mim_session_t *s)
{
    const mim_io_skin_t *r = &s->rig;
    if (!r->n_joints || r->n_vertices != s->own.n_vertices) return NULL;
    const char **names = malloc(r->n_joints * sizeof *names);
    int *seg = malloc(r->n_joints * sizeof *seg), *out = malloc(((size_t)r->n_vertices + 1) * sizeof *out);
    if (!names || !seg || !out) {
        free(names), free(seg), free(out);
        return NULL;
    }
    for (uint32_t j = 0; j < r->n_joints; j++) names[j] = r->names[j];
    mim_vest_segments_of_joints(names, r->n_joints, seg);
    for (uint32_t v = 0; v < r->n_vertices; v++) {
        float w[MIM_SEGMENTS] = {0};
        out[v] = -1;
        for (int k = 0; k < 4; k++) {
            int g = seg[r->joints[4 * (size_t)v + k]];
            if (g >= 0) w[g] += r->weights[4 * (size_t)v + k];
        }
        for (int g = 0; g < MIM_SEGMENTS; g++)
            if (w[g] > 0 && (out[v] < 0 || w[g] > w[out[v]])) out[v] = g;
    }
    free(names), free(seg);
    return out;
}

/* A foreign avatar far from its proxy follows the segments there
 * (mim_reg_follow_build; issue 28: no tearing at fists, boots, props).
 * Without a segmentation the binding alone carries it, with a warning. */
static int follow_segments(mim_session_t *s, mim_error_t *err)
{
    if (!s->skin) {
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_WARN,
                     "%s: parts far from the registered body follow its surface alone (%s)", s->avatar,
                     mim_error_text(&s->skin_failed));
        return 0;
    }
    int *rig = rig_segments(s);
    mim_error_t e = {0};
    const mim_reg_follow_options_t fo = {.crush = s->crushed};
    int rc = mim_reg_follow_build(&s->binding, s->mesh.faces, s->skin, s->turned ? &s->canon : &s->own, rig, &fo,
                                  &s->follow, &e);
    free(rig);
    if (rc) return mim_error_set(err, rc, "%s: %s", s->avatar, mim_error_text(&e));
    if (s->follow.far_pieces)
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_INFO,
                     "%s: %u of its %u pieces lie away from the body (props, shells) and follow one segment each",
                     s->avatar, s->follow.far_pieces, s->follow.pieces);
    return 0;
}

static mim_session_t *session_new(const char *store, const mim_session_options_t *opt)
{
    mim_session_t *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->opt = opt ? *opt : (mim_session_options_t){0};
    pthread_mutex_init(&s->lock, NULL);
    pthread_mutex_init(&s->out_lock, NULL);
    pthread_mutex_init(&s->table_lock, NULL);
    snprintf(s->store, sizeof s->store, "%s", store);
    return s;
}

int mim_session_open(mim_session_t **out, const char *store, const mim_session_options_t *opt, mim_error_t *err)
{
    *out = NULL;
    mim_session_t *s = session_new(store, opt);
    if (!s)
        return mim_error_set(err, MIM_ENOMEM, "out of memory");
    int rc = load_store(s, store, s->opt.map_size, err);
    if (!rc)
        rc = mim_query_status(s->db, &s->index, err);
    if (!rc && s->index.has_index)
        rc = mim_query_open(&s->query, s->db, err);
    if (rc) {
        mim_session_close(&s);
        return rc;
    }
    *out = s;
    return 0;
}

int mim_session_fork(mim_session_t **out, mim_session_t *base, const mim_session_options_t *opt, mim_error_t *err)
{
    *out = NULL;
    if (base->base)
        base = base->base; /* a fork of a fork shares the one store */
    mim_session_t *s = session_new(base->store, opt ? opt : &base->opt);
    if (!s || mim_mesh_alloc(&s->mesh, base->mesh.n_vertices, base->mesh.n_faces)) {
        mim_session_close(&s);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory for another session", base->store);
    }
    s->base = base;
    s->db = base->db, s->query = base->query, s->topo = base->topo;
    s->index = base->index, s->map = base->map;
    memcpy(s->mesh.faces, base->mesh.faces, 3 * (size_t)base->mesh.n_faces * sizeof *s->mesh.faces);
    *out = s;
    return 0;
}

int mim_session_load_avatar(mim_session_t *s, const char *avatar, mim_error_t *err)
{
    /* one avatar a session, and one attempt: a failed load may leave part
     * of a foreign avatar's state behind */
    if (s->solver || s->avatar[0])
        return mim_error_set(err, MIM_EINVAL, "%s: the session already has an avatar, or tried one (%s)", avatar,
                             s->avatar);
    const uint32_t n = s->mesh.n_vertices;
    if (!s->W) {
        s->W = malloc(3 * (size_t)n * sizeof *s->W);
        s->bF = malloc(9 * (size_t)n * sizeof *s->bF);
        s->bD = malloc(3 * (size_t)n * sizeof *s->bD);
        s->oD = malloc(3 * (size_t)n * sizeof *s->oD);
        s->restD = malloc(3 * (size_t)n * sizeof *s->restD);
        s->rW = malloc(3 * (size_t)n * sizeof *s->rW);
        if (!s->W || !s->bF || !s->bD || !s->oD || !s->restD || !s->rW)
            return mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
    }
    int rc = load_avatar(s, avatar, err);
    if (!rc)
        mim_xfer_decode(n, s->restF, s->W, s->restD);
    if (!rc && !s->n_parts) { /* a template id: one part, the whole mesh */
        const mim_mesh_t *o = mim_session_output_mesh(s);
        if (!(s->parts = calloc(1, sizeof *s->parts))) return mim_error_set(err, MIM_ENOMEM, "out of memory");
        *s->parts = (mim_io_part_t){.node = -1, .material = -1, .n_vertices = o->n_vertices, .n_faces = o->n_faces};
        s->n_parts = 1;
    }
    if (!rc) {
        /* one factor for every session of a store: it depends on the
         * connectivity and the landmark vertices, not on the avatar */
        mim_xfer_solver_options_t so = {.formulation = s->opt.formulation};
        mim_xfer_solver_t *shared = s->base && s->base->opt.formulation == s->opt.formulation ? s->base->solver : NULL;
        double t0 = mim_now();
        rc = shared ? mim_xfer_solver_share(&s->solver, shared, err)
                    : mim_xfer_solver_open(&s->solver, s->topo, s->map.vertex, s->map.count, &so, err);
        s->t_factor = mim_now() - t0;
    }
    if (!rc)
        segment_avatar(s);
    if (!rc && s->foreign)
        rc = follow_segments(s, err);
    if (!rc && s->turn_note[0])
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_INFO, "%s", s->turn_note);
    if (!rc && s->bound_note[0])
        mim_log_emit(s->opt.log, s->opt.log_ctx, MIM_LOG_INFO, "%s", s->bound_note);
    return rc;
}

void mim_session_close(mim_session_t **ps)
{
    mim_session_t *s = ps ? *ps : NULL;
    if (!s)
        return;
    mim_xfer_solver_close(&s->solver);
    if (!s->base) { /* a fork's are its base's */
        mim_query_close(&s->query);
        mim_xfer_topology_close(&s->topo);
        mim_db_close(&s->db);
    }
    mim_mesh_free(&s->mesh);
    mim_mesh_free(&s->own);
    mim_mesh_free(&s->canon);
    free(s->parts);
    mim_io_skin_free(&s->rig);
    mim_reg_binding_free(&s->binding);
    mim_reg_follow_free(&s->follow);
    free(s->crushed);
    free(s->out_work);
    for (int k = 0; k < MIM_XFER_BLEND_MAX; k++)
        free(s->slot[k].pos), free(s->slot[k].F), free(s->slot[k].cF), free(s->slot[k].W), free(s->slot[k].rF),
            free(s->slot[k].Q);
    for (uint32_t i = 0; i < s->n_refs; i++)
        free(s->refs[i].subject), free(s->refs[i].W), free(s->refs[i].F);
    free(s->refs), free(s->rest_angles), free(s->rW);
    free(s->W), free(s->bF), free(s->bD), free(s->oD), free(s->restF), free(s->restD), free(s->skin);
    pthread_mutex_destroy(&s->lock);
    pthread_mutex_destroy(&s->out_lock);
    pthread_mutex_destroy(&s->table_lock);
    for (uint32_t i = 0; i < s->table_count; i++) free(s->table_subject[i]), free(s->table_pose[i]);
    free(s->table_subject), free(s->table_pose), free(s->table_lm), free(s->table_id);
    free(s);
    *ps = NULL;
}

const char *mim_session_store(const mim_session_t *s) { return s->store; }
const char *mim_session_avatar(const mim_session_t *s) { return s->avatar; }
const mim_mesh_t *mim_session_mesh(const mim_session_t *s) { return &s->mesh; }
const mim_mesh_t *mim_session_output_mesh(const mim_session_t *s) { return s->foreign ? &s->own : &s->mesh; }
int mim_session_maps_output(const mim_session_t *s) { return s->foreign; }

const mim_io_part_t *mim_session_output_parts(const mim_session_t *s, uint32_t *n)
{
    *n = s->n_parts;
    return s->parts;
}

void mim_session_output_look(const mim_session_t *s, mim_io_sequence_t *seq)
{
    seq->parts = s->parts, seq->n_parts = s->n_parts;
    seq->look = s->read_opt_set ? s->avatar : NULL; /* a file, not a template id */
    seq->look_read = &s->read_opt;
}

void mim_session_output(mim_session_t *s, const float *positions, float *out)
{
    if (!s->foreign) {
        if (out != positions) memcpy(out, positions, 3 * (size_t)s->mesh.n_vertices * sizeof *out);
        return;
    }
    pthread_mutex_lock(&s->out_lock);
    mim_reg_binding_apply(&s->binding, s->mesh.faces, positions, s->out_work, out);
    pthread_mutex_unlock(&s->out_lock);
    mim_reg_follow_apply(&s->follow, s->binding.proxy_rest, positions, out);
    if (s->turned) turn_points(s->turn, 1, out, s->own.n_vertices, out); /* as the avatar stands */
}
const mim_landmark_map_t *mim_session_map(const mim_session_t *s) { return &s->map; }
const mim_xfer_topology_t *mim_session_topology(const mim_session_t *s) { return s->topo; }
const double *mim_session_encoding(const mim_session_t *s) { return s->W; }
const mim_query_t *mim_session_query(const mim_session_t *s) { return s->query; }
const mim_query_status_t *mim_session_index_status(const mim_session_t *s) { return &s->index; }
int mim_session_store_status(const mim_session_t *s, mim_query_status_t *out, mim_error_t *err)
{
    return mim_query_status(s->db, out, err);
}
double mim_session_factor_seconds(const mim_session_t *s) { return s->t_factor; }
int mim_session_has_avatar(const mim_session_t *s) { return s->solver != NULL; }
const mim_xfer_skin_t *mim_session_skin(const mim_session_t *s, const mim_error_t **why, int *from_rig)
{
    if (why)
        *why = &s->skin_failed;
    if (from_rig)
        *from_rig = s->skin_from_rig;
    return s->skin;
}

const char *const mim_session_drive_names[MIM_SESSION_DRIVES] = {"auto", "template", "orientation", "skeleton"};

int mim_session_drive_parse(const char *name)
{
    for (int d = 0; d < MIM_SESSION_DRIVES; d++)
        if (name && !strcmp(name, mim_session_drive_names[d]))
            return d;
    return -1;
}

int mim_session_template(mim_session_t *s, uint64_t id, float *positions, double *frames, char *label,
                         size_t label_size, mim_error_t *err)
{
    mim_db_txn_t *t = NULL;
    int rc = mim_db_begin(s->db, 0, &t, err);
    mim_template_view_t v;
    if (!rc && (rc = mim_db_template_get(t, id, &v, NULL)) == MIM_ENOTFOUND)
        rc = mim_error_set(err, rc, "%s: no template %llu (see mimic list)", s->store, (unsigned long long)id);
    else if (rc)
        rc = mim_error_set(err, rc, "%s: cannot read template %llu", s->store, (unsigned long long)id);
    if (!rc && v.n_vertices != s->mesh.n_vertices)
        rc = mim_error_set(err, MIM_ESTORE, "%s: template %llu has %u vertices, the store's connectivity %u",
                           s->store, (unsigned long long)id, v.n_vertices, s->mesh.n_vertices);
    if (!rc) {
        if (positions)
            memcpy(positions, v.positions, 3 * (size_t)v.n_vertices * sizeof(float));
        if (label)
            snprintf(label, label_size, "%s/%s", v.subject[0] ? v.subject : "-", v.pose[0] ? v.pose : "-");
        mim_db_encoding_t e;
        if (frames) {
            /* stored by ingest; a store from before encodings were kept gets them computed */
            if (mim_db_encoding_get(t, id, &e, NULL) == 0 && e.n_vertices == v.n_vertices)
                mim_xfer_encoding_unpack(e.n_vertices, e.frames, NULL, frames, NULL);
            else
                mim_xfer_frames(s->topo, v.positions, frames);
        }
    }
    mim_db_abort(&t);
    return rc;
}

/* The k nearest templates of complete landmarks u, through the index, into
 * r->templates, and their weights (the inverse of the query distance:
 * bench/blend_accuracy.c). */
static int nearest(mim_session_t *s, const float *u, uint32_t k, mim_session_report_t *r, double *weights,
                   mim_error_t *err)
{
    if (!s->query)
        return mim_error_set(err, MIM_ENOTFOUND, "%s: store has no index (run mimic index)", s->store);
    mim_index_query_options_t qo = {.k = k};
    mim_index_hit_t hits[MIM_XFER_BLEND_MAX];
    int rc = mim_query_frame(s->query, u, NULL, &qo, &r->answer, hits, err);
    if (!rc && !r->answer.n_hits)
        rc = mim_error_set(err, MIM_ENOTFOUND, "%s: the index returned no template", s->store);
    if (rc)
        return rc;
    r->queried = 1;
    r->n_templates = r->answer.n_hits;
    for (uint32_t j = 0; j < r->n_templates; j++)
        r->templates[j] = hits[j].id, weights[j] = 1.0 / (hits[j].distance + MIM_SESSION_BLEND_DISTANCE_FLOOR);
    snprintf(r->class_name, sizeof r->class_name, "%s", mim_index_class_name(mim_query_index(s->query), r->answer.cls));
    return 0;
}

int mim_session_transfer(mim_session_t *s, const mim_session_request_t *req, float *out,
                         mim_session_report_t *report, mim_error_t *err)
{
    mim_session_report_t local, *r = report ? report : &local;
    memset(r, 0, sizeof *r);
    if (!s->solver)
        return mim_error_set(err, MIM_EINVAL, "%s: transfer: no avatar loaded", s->store);
    if (!req->template_id && !req->n_templates && !req->landmarks)
        return mim_error_set(err, MIM_EINVAL, "transfer: give a template, landmarks, or both");
    if (req->drive < MIM_DRIVE_AUTO || req->drive > MIM_DRIVE_SKELETON)
        return mim_error_set(err, MIM_EINVAL, "transfer: unknown drive %d", (int)req->drive);
    if (req->relative < -1 || req->relative > 1)
        return mim_error_set(err, MIM_EINVAL, "transfer: relative %d (0 default, 1 on, -1 off)", req->relative);
    if (req->n_templates && !req->template_ids)
        return mim_error_set(err, MIM_EINVAL, "transfer: %u templates to blend, but no ids", req->n_templates);
    if (req->n_templates > MIM_XFER_BLEND_MAX || req->blend > MIM_XFER_BLEND_MAX)
        return mim_error_set(err, MIM_EINVAL, "transfer: %u templates to blend (at most %d)",
                             req->n_templates > req->blend ? req->n_templates : req->blend, MIM_XFER_BLEND_MAX);
    for (uint32_t j = 0; j < req->n_templates; j++)
        if (!req->template_ids[j])
            return mim_error_set(err, MIM_EINVAL, "transfer: template id 0 in the list to blend");
    int measured = 0; /* segments with an orientation */
    for (int g = 0; req->orientations && g < MIM_VEST_SEGMENTS; g++)
        measured += !req->orient_present || req->orient_present[g];
    if (req->drive == MIM_DRIVE_ORIENTATION && !measured)
        return mim_error_set(err, MIM_EINVAL, "transfer: the orientation drive needs orientations (none measured)");
    if ((req->drive == MIM_DRIVE_ORIENTATION || req->drive == MIM_DRIVE_SKELETON) && !s->skin)
        return mim_error_set(err, s->skin_failed.code, "%s", mim_error_text(&s->skin_failed));
    /* auto: orientations when some are measured and the avatar is segmented; the skeleton drive on the
     * plain path is decided with the templates (template_frames) */
    r->drive = req->drive == MIM_DRIVE_SKELETON                                       ? MIM_DRIVE_SKELETON
               : measured && s->skin && req->drive != MIM_DRIVE_TEMPLATE ? MIM_DRIVE_ORIENTATION
                                                                                      : MIM_DRIVE_TEMPLATE;
    if (r->drive == MIM_DRIVE_ORIENTATION) {
        if (!req->landmarks)
            return mim_error_set(err, MIM_EINVAL, "transfer: orientations need landmarks (the solve holds them)");
        for (int g = 0; g < MIM_VEST_SEGMENTS; g++) {
            const mim_quat q = req->orientations[g];
            double norm = sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
            if ((!req->orient_present || req->orient_present[g]) && !(fabs(norm - 1) <= MIM_ORIENT_UNIT_TOL))
                return mim_error_set(err, isfinite(norm) ? MIM_EINVAL : MIM_ENONFINITE,
                                     "transfer: orientation '%s' is not a unit quaternion (norm %.3g)",
                                     mim_segment_names[g], norm);
        }
    }
    double t0 = mim_now();
    int rc = 0;
    double weights[MIM_XFER_BLEND_MAX];
    if (req->n_templates) { /* given: equal weights */
        r->n_templates = req->n_templates;
        for (uint32_t j = 0; j < r->n_templates; j++)
            r->templates[j] = req->template_ids[j], weights[j] = 1.0;
    } else if (req->template_id) {
        r->n_templates = 1, r->templates[0] = req->template_id, weights[0] = 1.0;
    } else { /* outside the lock: queries run concurrently; the orientation and skeleton drives name the pose by one */
        uint32_t k = r->drive != MIM_DRIVE_TEMPLATE ? 1 : req->blend ? req->blend : MIM_SESSION_DEFAULT_BLEND;
        rc = nearest(s, req->landmarks, k, r, weights, err);
    }
    r->template_id = r->templates[0];
    double t1 = mim_now();
    r->seconds_query = t1 - t0;
    if (rc)
        return rc;
    const uint32_t n = s->mesh.n_vertices, nl = s->map.count;
    float *u = r->landmarks;
    pthread_mutex_lock(&s->lock);
    const double *frames = NULL, *offsets = NULL, *W = s->W;
    template_slot_t *first = NULL;
    if (r->drive != MIM_DRIVE_TEMPLATE) {
        r->n_templates = 1;
        if (req->landmarks)
            memcpy(u, req->landmarks, 3 * (size_t)nl * sizeof *u);
        else { /* the skeleton drive in mode (a): the template's landmarks on the avatar's proportions */
            template_slot_t *t0slot = NULL;
            rc = mim__session_cache_template(s, r->templates[0], 1, &t0slot, err);
            if (!rc)
                rc = mim_xfer_retarget_landmarks(&s->map, s->mesh.positions, t0slot->pos, u, err);
        }
        if (!rc)
            rc = r->drive == MIM_DRIVE_ORIENTATION ? mim__session_orientation_offsets(s, req, r, err)
                                                    : mim__session_skeleton_offsets(s, u, err);
        offsets = s->oD;
        /* the label without reading the template's mesh unless it is cached
         * (kept: a stream holds a pose) */
        for (int k = 0; !rc && k < MIM_XFER_BLEND_MAX && !r->label[0]; k++)
            if (s->slot[k].id == r->template_id)
                snprintf(r->label, sizeof r->label, "%s", s->slot[k].label);
        if (!rc && !r->label[0] && s->label_id != r->template_id) {
            s->label_id = 0;
            rc = mim_session_template(s, r->template_id, NULL, NULL, s->label, sizeof s->label, err);
            if (!rc)
                s->label_id = r->template_id;
        }
        if (!rc && !r->label[0])
            snprintf(r->label, sizeof r->label, "%s", s->label);
    } else {
        template_slot_t *t0slot = NULL;
        rc = mim__session_cache_template(s, r->templates[0], r->n_templates, &t0slot, err);
        if (!rc && req->landmarks) /* mode (b): the tracked landmarks, held */
            memcpy(u, req->landmarks, 3 * (size_t)nl * sizeof *u);
        else if (!rc) /* mode (a): the first template's landmarks on the avatar's proportions */
            rc = mim_xfer_retarget_landmarks(&s->map, s->mesh.positions, t0slot->pos, u, err);
        if (!rc)
            rc = mim__session_template_frames(s, req, r, weights, u, &frames, &offsets, &W, &first, err);
        if (!rc)
            snprintf(r->label, sizeof r->label, "%s", first->label);
    }
    double t2 = mim_now();
    r->seconds_template = t2 - t1;
    mim_xfer_options_t xo = req->xfer;
    if (xo.start && req->start_template && req->start_template != r->template_id)
        xo.start = NULL; /* a warm start from another template's pose would mislead the first solve */
    if (r->drive != MIM_DRIVE_TEMPLATE) /* the frames are the pose's own: one solve, nothing to iterate */
        xo.max_iterations = 1, xo.start = NULL;
    else if (r->relative && !xo.max_iterations) /* later solves' frames are worse than the turned rest frames */
        xo.max_iterations = MIM_SESSION_RELATIVE_ITERATIONS;
    double tw = 0; /* the blend's shares; a weight that is not positive counts 0, and with none the first's */
    for (uint32_t j = 0; j < r->n_templates; j++)
        tw += isfinite(weights[j]) && weights[j] > 0 ? weights[j] : 0;
    for (uint32_t j = 0; j < r->n_templates; j++)
        r->weights[j] = tw > 0 ? (isfinite(weights[j]) && weights[j] > 0 ? weights[j] / tw : 0) : j == 0;
    r->warm_started = xo.start != NULL;
    if (!rc && offsets)
        rc = mim_xfer_transfer_offsets(s->solver, W, n, offsets, u, nl, &xo, out, &r->xfer, err);
    else if (!rc)
        rc = mim_xfer_transfer(s->solver, W, n, frames, u, nl, &xo, out, &r->xfer, err);
    pthread_mutex_unlock(&s->lock);
    r->seconds_solve = mim_now() - t2;
    return rc;
}

int mim_session_morph(mim_session_t *s, mim_xfer_morph_method_t method, const mim_xfer_key_t *a,
                      const mim_xfer_key_t *b, double t, const float *landmarks, float *out, mim_error_t *err)
{
    if (!s->solver)
        return mim_error_set(err, MIM_EINVAL, "%s: morph: no avatar loaded", s->store);
    /* the landmarks along the skeleton (issue 29: lerped ones fold a
     * swinging limb), where the map is the 16 default landmarks */
    float u[3 * MIM_LANDMARKS_MAX];
    const int skeletal = !landmarks && method == MIM_XFER_MORPH_FRAMES && a && b && a->landmarks && b->landmarks &&
                         mim_xfer_landmarks_between(&s->map, a->landmarks, b->landmarks, t, u, NULL) == 0;
    /* the torsos' turn, so that a half turn turns every frame one way round */
    double ta[4], tb[4];
    mim_xfer_key_t ka = a ? *a : (mim_xfer_key_t){0}, kb = b ? *b : (mim_xfer_key_t){0};
    if (method == MIM_XFER_MORPH_FRAMES && a && b && a->landmarks && b->landmarks && !ka.torso && !kb.torso &&
        mim_xfer_landmarks_torso(&s->map, a->landmarks, ta, NULL) == 0 &&
        mim_xfer_landmarks_torso(&s->map, b->landmarks, tb, NULL) == 0)
        ka.torso = ta, kb.torso = tb;
    pthread_mutex_lock(&s->lock);
    int rc = mim_xfer_morph_between(s->solver, method, a ? &ka : NULL, b ? &kb : NULL, t,
                                    landmarks ? landmarks : skeletal ? u : NULL, out, err);
    pthread_mutex_unlock(&s->lock);
    return rc;
}

int mim_session_morph_oriented(mim_session_t *s, const mim_session_oriented_key_t *a,
                               const mim_session_oriented_key_t *b, double t, const float *landmarks, float *out,
                               mim_error_t *err)
{
    const uint32_t L = s->map.count;
    mim_quat R[MIM_VEST_SEGMENTS];
    uint8_t have[MIM_VEST_SEGMENTS];
    float u[3 * MIM_LANDMARKS_MAX];
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) {
        R[g] = mim_quat_slerp(a->R[g], b->R[g], t);
        have[g] = (!a->have || a->have[g]) && (!b->have || b->have[g]);
    }
    if (landmarks)
        memcpy(u, landmarks, 3 * (size_t)L * sizeof *u);
    else if (mim_xfer_landmarks_between(&s->map, a->landmarks, b->landmarks, t, u, NULL)) /* not the default 16 */
        for (uint32_t i = 0; i < 3 * L; i++)
            u[i] = (float)((1.0 - t) * a->landmarks[i] + t * b->landmarks[i]);
    mim_session_request_t req = {.template_id = b->template_id, .landmarks = u, .orientations = R,
                                 .orient_present = have, .drive = MIM_DRIVE_ORIENTATION};
    return mim_session_transfer(s, &req, out, NULL, err);
}

json_t *mim_session_answer_json(const mim_query_t *q, const mim_index_answer_t *a, const mim_index_hit_t *hits)
{
    json_t *res = json_array();
    for (uint32_t j = 0; res && j < a->n_hits; j++)
        json_array_append_new(res, json_pack("{s:I, s:s, s:s, s:f}", "id", (json_int_t)hits[j].id, "subject",
                                             hits[j].subject, "pose", hits[j].pose, "distance",
                                             (double)hits[j].distance));
    return res ? json_pack("{s:s, s:f, s:o}", "class", mim_index_class_name(mim_query_index(q), a->cls),
                           "probability", a->probability, "results", res)
               : NULL;
}
