/* The JSON API handlers of mimic serve (mim_serve.h lists the routes and
 * their schemas). Bodies are untrusted: every problem is a 400 with the
 * reason (jansson's line and column for malformed JSON); a template id
 * that is not in the store is a 404, and what needs the recognition index
 * is a 503 without one. Handlers only fill in a reply (internal.h): the
 * service thread sends it, and query, transfer and avatar run on the
 * worker pool (workers.c). */
#include "internal.h"
#include "mim_io.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A store or avatar error caused by the request (bad input) or by us. */
static int status_of(int rc)
{
    return rc == MIM_EFORMAT || rc == MIM_ENONFINITE || rc == MIM_EINVAL || rc == MIM_ENOTFOUND ? 400 : 500;
}

static const char no_index[] = "%s: the store has no index (run mimic index, then restart serve)";

/* The session a request names (?session=NAME; absent: the first one),
 * with a reference; else NULL and the reply (400 for a malformed name, 404
 * for none). */
static mim__vs_t *request_session(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp, int *status)
{
    if (rq->session_given < 0 || (rq->session_given > 0 && !mim__session_name_ok(rq->session))) {
        *status = mim__reply_error(rp, 400, "query string: session must be " MIM_SERVE_SESSION_NAME_RULE);
        return NULL;
    }
    mim__vs_t *vs = mim__sessions_get(sv, rq->session_given > 0 ? rq->session : NULL);
    if (!vs && rq->session_given > 0)
        *status = mim__reply_error(rp, 404, "session %s: no such session (GET /api/sessions lists them)", rq->session);
    else if (!vs)
        *status = mim__reply_error(rp, 404, "%s: the service has no session yet (POST /api/sessions adds one)", rq->path);
    return vs;
}

int mim__api_status(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    (void)rq;
    /* the store as it is now: another process may have grown it (issue 30) */
    mim_query_status_t fresh;
    const mim_query_status_t *qs =
        mim_session_store_status(sv->s, &fresh, NULL) == 0 ? &fresh : mim_session_index_status(sv->s);
    int ready = atomic_load(&sv->index_ready);
    json_t *index = json_pack("{s:b, s:b, s:I, s:b}", "present", qs->has_index, "stale", qs->stale, "templates",
                              (json_int_t)(qs->has_index ? qs->built.templates : 0), "ready", sv->q && ready == 1);
    if (sv->q && ready < 0)
        json_object_set_new(index, "error", json_string(sv->index_error));
    size_t n = 0;
    mim__vs_t **all = mim__sessions_all(sv, &n);
    uint64_t count[MIM__C_COUNT] = {0};
    json_t *sessions = json_array(), *vest = json_null();
    for (size_t i = 0; i < n; i++) {
        for (int c = 0; c < MIM__C_COUNT; c++)
            count[c] += mim__metrics_get(&all[i]->m, (mim__counter_t)c);
        json_t *one = mim__vs_status(all[i]);
        if (i == 0 && one) /* the first session's vest, as before sessions */
            json_decref(vest), vest = json_incref(json_object_get(one, "vest"));
        json_array_append_new(sessions, one);
    }
    /* the first session's avatar: the one /ws and /api/avatar give without ?session= */
    const mim_mesh_t *m = n ? all[0]->out_mesh : NULL;
    mim__fair_choice_t choice;
    double capacity;
    mim__fair_state(&sv->fair, &choice, &capacity);
    json_t *compute = json_pack("{s:i, s:i, s:f, s:i, s:b, s:b}", "cores", (int)sv->cpu.cores, "slots",
                                (int)sv->gate.slots, "capacity", capacity, "shared_key_interval", (int)choice.k,
                                "warm", choice.warm, "linear", choice.linear);
    json_t *j = json_pack("{s:s, s:o, s:I, s:i, s:i, s:i, s:o, s:f, s:I, s:I, s:I, s:I, s:o, s:o, s:o, s:o}", "store",
                          sv->store, "avatar", n ? json_string(mim_session_avatar(all[0]->s)) : json_null(),
                          "templates", (json_int_t)qs->templates, "vertices", m ? (int)m->n_vertices : 0, "faces",
                          m ? (int)m->n_faces : 0, "landmarks", (int)sv->map->count, "index", index, "uptime_s",
                          mim_now() - sv->t_start, "vest_frames", (json_int_t)count[MIM__C_VEST_FRAMES], "frames",
                          (json_int_t)count[MIM__C_FRAMES], "key_frames", (json_int_t)count[MIM__C_KEY_FRAMES],
                          "frames_dropped", (json_int_t)count[MIM__C_DROPS], "stream", mim__ws_status(sv->ws, NULL),
                          "vest", vest, "sessions", sessions, "compute", compute);
    mim__sessions_release_all(all, n);
    return mim__reply_json(rp, 200, j);
}

int mim__api_avatar(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    int status = 0;
    mim__vs_t *vs = request_session(sv, rq, rp, &status);
    if (!vs)
        return status;
    const mim_mesh_t *m = vs->out_mesh;
    json_t *pos = json_array(), *faces = json_array();
    for (size_t i = 0; pos && i < 3 * (size_t)m->n_vertices; i++)
        json_array_append_new(pos, json_real(m->positions[i]));
    for (size_t i = 0; faces && i < 3 * (size_t)m->n_faces; i++)
        json_array_append_new(faces, json_integer(m->faces[i]));
    /* its parts (issue 28): each glTF primitive's range of the vertices and
     * faces, which every frame keeps; the textured GLB at /api/avatar.glb */
    uint32_t np = 0;
    const mim_io_part_t *pt = mim_session_output_parts(vs->s, &np);
    json_t *parts = json_array();
    for (uint32_t k = 0; parts && k < np; k++)
        json_array_append_new(parts, json_pack("{s:s, s:i, s:i, s:i, s:i, s:i}", "name", pt[k].name, "first_vertex",
                                               (int)pt[k].first_vertex, "vertices", (int)pt[k].n_vertices,
                                               "first_face", (int)pt[k].first_face, "faces", (int)pt[k].n_faces,
                                               "material", (int)pt[k].material));
    json_t *j = json_pack("{s:s, s:s, s:i, s:i, s:o, s:o, s:o, s:s}", "session", vs->name, "avatar",
                          mim_session_avatar(vs->s), "vertices", (int)m->n_vertices, "faces", (int)m->n_faces,
                          "positions", pos, "indices", faces, "parts", parts, "glb", "/api/avatar.glb");
    mim__vs_release(vs);
    return mim__reply_json(rp, 200, j);
}

/* The avatar at rest as a GLB in its own parts and look (materials,
 * textures, UVs: issue 28), for a viewer that shows it as its author made
 * it and then moves its vertices with each frame. */
int mim__api_avatar_glb(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    int status = 0;
    mim__vs_t *vs = request_session(sv, rq, rp, &status);
    if (!vs)
        return status;
    mim_io_sequence_t sq = {.mesh = vs->out_mesh, .n_frames = 1, .positions = vs->out_mesh->positions};
    mim_session_output_look(vs->s, &sq);
    unsigned char *glb = NULL;
    size_t glen = 0;
    mim_error_t err = {0};
    int rc = mim_io_encode_sequence_glb(&sq, "avatar", &glb, &glen, &err);
    mim__vs_release(vs);
    if (rc) return mim__reply_error(rp, 500, "%s", mim_error_text(&err));
    return mim__reply_take(rp, 200, "model/gltf-binary", glb, glen);
}

/* k from the query string (?k=N, 1..1000), else 1. 0 if malformed. */
static uint32_t query_k(const mim__request_t *rq)
{
    if (!rq->k_given)
        return 1;
    if (rq->k_given < 0 || rq->k[0] < '0' || rq->k[0] > '9')
        return 0;
    char *end = NULL;
    unsigned long k = strtoul(rq->k, &end, 10);
    return !*end && k >= 1 && k <= 1000 ? (uint32_t)k : 0;
}

int mim__api_query(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    const char *body = rq->body;
    size_t len = rq->len;
    if (!sv->q)
        return mim__reply_error(rp, 503, no_index, sv->store);
    mim_index_query_options_t qo = {.k = query_k(rq)};
    if (!qo.k)
        return mim__reply_error(rp, 400, "query string: k must be a whole number from 1 to 1000");
    mim_error_t err = {0};
    mim_landmark_frames_t f = {0};
    int rc = mim_landmark_frames_parse(body, len, "request body", mim_query_landmark_count(sv->q), 3, &f, &err);
    if (!rc && f.n_frames != 1)
        rc = mim_error_set(&err, MIM_EFORMAT, "request body: has %u frames; /api/query takes one", f.n_frames);
    mim_index_answer_t a;
    mim_index_hit_t *hits = rc ? NULL : calloc(qo.k, sizeof *hits);
    if (!rc && !hits)
        rc = mim_error_set(&err, MIM_ENOMEM, "out of memory for %u results", qo.k);
    double t0 = mim_now();
    if (!rc)
        rc = mim_query_batch(sv->q, &f, &qo, &a, hits, &err);
    int status;
    if (rc) {
        status = mim__reply_error(rp, status_of(rc), "%s", mim_error_text(&err));
    } else {
        mim__metrics_observe(&sv->m, MIM__H_QUERY, mim_now() - t0);
        mim__metrics_add(&sv->m, MIM__C_QUERIES, 1);
        status = mim__reply_json(rp, 200, json_pack("{s:[o]}", "frames", mim_session_answer_json(sv->q, &a, hits)));
    }
    free(hits);
    mim_landmark_frames_free(&f);
    return status;
}

/* The request of /api/transfer: {"template": ID} and/or {"landmarks": [...]},
 * and "relative": true|false (absent: the service's --relative). */
typedef struct xfer_req {
    uint64_t id;                       /* 0: the nearest template of the landmarks */
    int has_landmarks;
    int relative;                      /* mim_session_request_t's: 0 the service's, 1 on, -1 off */
    float u[3 * MIM_LANDMARKS_MAX];
} xfer_req_t;

static int parse_transfer(mim_serve_t *sv, const char *body, size_t len, xfer_req_t *r, mim_error_t *err)
{
    json_error_t je;
    json_t *root = json_loadb(body, len, JSON_REJECT_DUPLICATES, &je);
    if (!root)
        return mim_error_set(err, MIM_EFORMAT, "request body:%d:%d: %s", je.line, je.column, je.text);
    int rc = 0;
    const char *key;
    json_t *v;
    if (!json_is_object(root))
        rc = mim_error_set(err, MIM_EFORMAT, "request body: expected an object with \"template\" and/or "
                                             "\"landmarks\"");
    else
        json_object_foreach(root, key, v) if (!rc && strcmp(key, "template") && strcmp(key, "landmarks") &&
                                              strcmp(key, "relative")) rc =
            mim_error_set(err, MIM_EFORMAT, "request body: unknown member \"%s\" (use template, landmarks, relative)",
                          key);
    json_t *rel = rc ? NULL : json_object_get(root, "relative");
    if (rel && !json_is_boolean(rel))
        rc = mim_error_set(err, MIM_EFORMAT, "request body: \"relative\" must be true or false");
    else if (rel)
        r->relative = json_is_true(rel) ? 1 : -1;
    json_t *t = rc ? NULL : json_object_get(root, "template");
    if (t && (!json_is_integer(t) || json_integer_value(t) < 1))
        rc = mim_error_set(err, MIM_EFORMAT, "request body: \"template\" must be a template id (an integer >= 1)");
    else if (t)
        r->id = (uint64_t)json_integer_value(t);
    json_t *l = rc ? NULL : json_object_get(root, "landmarks");
    if (l) {
        /* the landmark-frame parser owns that format: hand it the member alone */
        json_t *one = json_pack("{s:O}", "landmarks", l);
        char *txt = one ? json_dumps(one, JSON_COMPACT) : NULL;
        mim_landmark_frames_t f = {0};
        rc = txt ? mim_landmark_frames_parse(txt, strlen(txt), "request body", sv->map->count, 0, &f, err)
                 : mim_error_set(err, MIM_ENOMEM, "out of memory");
        if (!rc)
            memcpy(r->u, f.positions, 3 * (size_t)sv->map->count * sizeof(float));
        r->has_landmarks = !rc;
        mim_landmark_frames_free(&f);
        free(txt);
        json_decref(one);
    }
    if (!rc && !t && !l)
        rc = mim_error_set(err, MIM_EFORMAT, "request body: give \"template\" and/or \"landmarks\"");
    json_decref(root);
    return rc;
}

int mim__api_transfer(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    int status = 0;
    mim__vs_t *vs = request_session(sv, rq, rp, &status);
    if (!vs)
        return status;
    const char *body = rq->body;
    size_t len = rq->len;
    mim_error_t err = {0};
    xfer_req_t *r = calloc(1, sizeof *r);
    const uint32_t n = vs->mesh->n_vertices, n_own = vs->out_mesh->n_vertices;
    float *out = malloc(3 * (size_t)n * sizeof *out);
    float *own = mim_session_maps_output(vs->s) ? malloc(3 * (size_t)n_own * sizeof *own) : out;
    int rc = r && out && own ? 0 : mim_error_set(&err, MIM_ENOMEM, "out of memory for %u vertices", n);
    if (!rc)
        rc = parse_transfer(sv, body, len, r, &err);
    mim_session_report_t rep = {0};
    if (!rc && !r->id && !sv->q) {
        /* landmarks alone need the index to find their template: as /api/query */
        status = mim__reply_error(rp, 503, no_index, sv->store);
        rc = MIM_ENOTFOUND;
    } else if (!rc) {
        /* the drive as the service's vests have it without orientations (--drive, --blend,
         * --segment-correction, --relative), unless the request says relative */
        mim_session_request_t req = {.template_id = r->id,
                                     .landmarks = r->has_landmarks ? r->u : NULL,
                                     .drive = sv->opt.drive == MIM_DRIVE_ORIENTATION ? MIM_DRIVE_AUTO
                                                                                     : (mim_session_drive_t)sv->opt.drive,
                                     .blend = r->id ? 0 : sv->opt.blend,
                                     .segment_correction = sv->opt.segment_correction,
                                     .relative = r->relative ? r->relative : sv->opt.relative};
        rc = mim_session_transfer(vs->s, &req, out, &rep, &err);
        /* the one thing a well-formed request can name that is not there */
        if (rc == MIM_ENOTFOUND)
            status = mim__reply_error(rp, r->id ? 404 : 500, "%s", mim_error_text(&err));
    }
    unsigned char *glb = NULL;
    size_t glen = 0;
    if (!rc) {
        mim__metrics_observe(&sv->m, MIM__H_TRANSFER, rep.seconds_solve);
        mim__metrics_add(&sv->m, MIM__C_TRANSFERS, 1);
        mim_session_output(vs->s, out, own); /* in the avatar's own connectivity */
        mim_mesh_t m = {n_own, vs->out_mesh->n_faces, own, vs->out_mesh->faces};
        mim_io_sequence_t sq = {.mesh = &m, .n_frames = 1, .positions = own};
        mim_session_output_look(vs->s, &sq); /* its parts and look (issue 28) */
        rc = mim_io_encode_sequence_glb(&sq, "transfer", &glb, &glen, &err);
        if (rc && status_of(rc) == 400)
            rc = MIM_EIO; /* an encoder failure is ours, not the client's */
    }
    if (rc && !status) {
        status = mim__reply_error(rp, status_of(rc), "%s", mim_error_text(&err));
    } else if (!rc) {
        /* the label is "subject/pose" from the store: keep header-safe bytes */
        for (char *p = rep.label; *p; p++)
            if ((unsigned char)*p < 0x20 || *p == 0x7f) *p = '?';
        for (char *p = rep.degraded; *p; p++)
            if ((unsigned char)*p < 0x20 || *p >= 0x7f) *p = '?';
        status = mim__reply_take(rp, 200, "model/gltf-binary", glb, glen);
        glb = NULL;
        if (status == 200)
            snprintf(rp->headers, sizeof rp->headers,
                     "X-Mimic-Template: %llu\r\nX-Mimic-Template-Label: %s\r\nX-Mimic-Iterations: %u\r\n"
                     "X-Mimic-Relative: %d\r\nX-Mimic-Drive: %s\r\n%s%.300s%s",
                     (unsigned long long)rep.template_id, rep.label, rep.xfer.iterations, rep.relative,
                     mim_session_drive_names[rep.drive],
                     rep.degraded[0] ? "X-Mimic-Degraded: " : "", rep.degraded, rep.degraded[0] ? "\r\n" : "");
    }
    if (own != out) free(own);
    free(glb), free(r), free(out);
    mim__vs_release(vs);
    return status;
}

int mim__api_metrics(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    (void)rq;
    size_t n = 0;
    mim__vs_t **all = mim__sessions_all(sv, &n);
    mim__metrics_t **m = n ? malloc(n * sizeof *m) : NULL;
    const char **names = n ? malloc(n * sizeof *names) : NULL;
    char *txt = NULL;
    if (!n || (m && names)) {
        for (size_t i = 0; i < n; i++) {
            mim__metrics_set(&all[i]->m, MIM__G_WS_CLIENTS, mim__ws_clients(sv->ws, all[i]));
            m[i] = &all[i]->m, names[i] = all[i]->name;
        }
        txt = mim__metrics_text(&sv->m, m, names, n);
    }
    free(m), free(names);
    mim__sessions_release_all(all, n);
    if (!txt)
        return mim__reply_error(rp, 500, "out of memory for the metrics");
    return mim__reply_take(rp, 200, "text/plain; version=0.0.4; charset=utf-8", txt, strlen(txt));
}

/* ---- sessions ---- */
int mim__api_sessions(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    (void)rq;
    size_t n = 0;
    mim__vs_t **all = mim__sessions_all(sv, &n);
    json_t *list = json_array();
    for (size_t i = 0; i < n; i++)
        json_array_append_new(list, mim__vs_status(all[i]));
    mim__sessions_release_all(all, n);
    return mim__reply_json(rp, 200, json_pack("{s:o}", "sessions", list));
}

int mim__api_session_add(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    /* the service reads the avatar's file and opens the vest: a browser must
     * not be able to make another site's page do it with a "simple" request
     * (text/plain needs no preflight; application/json does) */
    if (!rq->json)
        return mim__reply_error(rp, 415, "%s: send the session as Content-Type: application/json", rq->path);
    json_error_t je;
    json_t *j = json_loadb(rq->body, rq->len, JSON_REJECT_DUPLICATES, &je);
    if (!j)
        return mim__reply_error(rp, 400, "request body:%d:%d: %s", je.line, je.column, je.text);
    mim_serve_session_spec_t spec;
    mim_error_t err = {0};
    int rc = mim_serve_session_spec_json(j, "request body", &spec, &err);
    json_decref(j);
    if (rc)
        return mim__reply_error(rp, 400, "%s", mim_error_text(&err));
    if ((rc = mim_serve_session_add(sv, &spec, &err))) {
        /* a taken name is a conflict, a full service busy; an avatar or a vest that cannot be had is the
         * request's */
        int status = rc == -EEXIST ? 409 : rc == -ENOSPC ? 503 : rc == MIM_ENOMEM ? 500 : 400;
        return mim__reply_error(rp, status, "%s", mim_error_text(&err));
    }
    mim__vs_t *vs = mim__sessions_get(sv, spec.name);
    json_t *one = vs ? mim__vs_status(vs) : json_pack("{s:s}", "name", spec.name); /* (removed at once) */
    mim__vs_release(vs);
    return mim__reply_json(rp, 201, one);
}

/* The session of /api/sessions/NAME, with a reference; else NULL and a 404. */
static mim__vs_t *path_session(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp, int *status)
{
    mim__vs_t *vs = mim__session_name_ok(rq->name) ? mim__sessions_get(sv, rq->name) : NULL;
    if (!vs)
        *status = mim__reply_error(rp, 404, "%s: no such session (GET /api/sessions lists them)", rq->path);
    return vs;
}

int mim__api_session(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    int status = 0;
    mim__vs_t *vs = path_session(sv, rq, rp, &status);
    if (!vs)
        return status;
    json_t *j = mim__vs_status(vs);
    mim__vs_release(vs);
    return mim__reply_json(rp, 200, j);
}

int mim__api_session_remove(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    mim_error_t err = {0};
    if (!mim__session_name_ok(rq->name) || mim_serve_session_remove(sv, rq->name, &err))
        return mim__reply_error(rp, 404, "%s: no such session (GET /api/sessions lists them)", rq->path);
    return mim__reply_json(rp, 200, json_pack("{s:s, s:b}", "name", rq->name, "removed", 1));
}
