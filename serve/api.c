/* The JSON API handlers of mimic serve (mim_serve.h lists the routes and
 * their schemas). Bodies are untrusted: every problem is a 400 with the
 * reason (jansson's line and column for malformed JSON); a template id
 * that is not in the store is a 404, and what needs the recognition index
 * is a 503 without one. Handlers only fill in a reply (internal.h): the
 * service thread sends it, and query, transfer and avatar run on the
 * worker pool (workers.c). */
#include "internal.h"
#include "mim_io.h"

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

int mim__api_status(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    (void)rq;
    const mim_query_status_t *qs = mim_session_index_status(sv->s);
    json_t *index = json_pack("{s:b, s:b, s:I}", "present", qs->has_index, "stale", qs->stale, "templates",
                              (json_int_t)(qs->has_index ? qs->built.templates : 0));
    json_t *j = json_pack("{s:s, s:s, s:I, s:i, s:i, s:i, s:o, s:f, s:I, s:I, s:I, s:I, s:o, s:o}", "store",
                          sv->store, "avatar", mim_session_avatar(sv->s), "templates", (json_int_t)qs->templates,
                          "vertices", (int)sv->out_mesh->n_vertices, "faces", (int)sv->out_mesh->n_faces, "landmarks",
                          (int)sv->map->count, "index", index, "uptime_s", mim_now() - sv->t_start, "vest_frames",
                          (json_int_t)mim__metrics_get(&sv->m, MIM__C_VEST_FRAMES), "frames",
                          (json_int_t)mim__metrics_get(&sv->m, MIM__C_FRAMES), "key_frames",
                          (json_int_t)mim__metrics_get(&sv->m, MIM__C_KEY_FRAMES), "frames_dropped",
                          (json_int_t)mim__metrics_get(&sv->m, MIM__C_DROPS), "stream", mim__ws_status(sv->ws),
                          "vest", mim__loop_status(sv->loop));
    return mim__reply_json(rp, 200, j);
}

int mim__api_avatar(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    (void)rq;
    const mim_mesh_t *m = sv->out_mesh;
    json_t *pos = json_array(), *faces = json_array();
    for (size_t i = 0; pos && i < 3 * (size_t)m->n_vertices; i++)
        json_array_append_new(pos, json_real(m->positions[i]));
    for (size_t i = 0; faces && i < 3 * (size_t)m->n_faces; i++)
        json_array_append_new(faces, json_integer(m->faces[i]));
    json_t *j = json_pack("{s:s, s:i, s:i, s:o, s:o}", "avatar", mim_session_avatar(sv->s), "vertices", (int)m->n_vertices,
                          "faces", (int)m->n_faces, "positions", pos, "indices", faces);
    return mim__reply_json(rp, 200, j);
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

/* The request of /api/transfer: {"template": ID} and/or {"landmarks": [...]}. */
typedef struct xfer_req {
    uint64_t id;                       /* 0: the nearest template of the landmarks */
    int has_landmarks;
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
        json_object_foreach(root, key, v) if (!rc && strcmp(key, "template") && strcmp(key, "landmarks")) rc =
            mim_error_set(err, MIM_EFORMAT, "request body: unknown member \"%s\" (use template, landmarks)", key);
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
    const char *body = rq->body;
    size_t len = rq->len;
    mim_error_t err = {0};
    xfer_req_t *r = calloc(1, sizeof *r);
    const uint32_t n = sv->mesh->n_vertices, n_own = sv->out_mesh->n_vertices;
    float *out = malloc(3 * (size_t)n * sizeof *out);
    float *own = mim_session_maps_output(sv->s) ? malloc(3 * (size_t)n_own * sizeof *own) : out;
    int rc = r && out && own ? 0 : mim_error_set(&err, MIM_ENOMEM, "out of memory for %u vertices", n);
    if (!rc)
        rc = parse_transfer(sv, body, len, r, &err);
    mim_session_report_t rep = {0};
    int status = 0;
    if (!rc && !r->id && !sv->q) {
        /* landmarks alone need the index to find their template: as /api/query */
        status = mim__reply_error(rp, 503, no_index, sv->store);
        rc = MIM_ENOTFOUND;
    } else if (!rc) {
        mim_session_request_t req = {.template_id = r->id, .landmarks = r->has_landmarks ? r->u : NULL};
        rc = mim_session_transfer(sv->s, &req, out, &rep, &err);
        /* the one thing a well-formed request can name that is not there */
        if (rc == MIM_ENOTFOUND)
            status = mim__reply_error(rp, r->id ? 404 : 500, "%s", mim_error_text(&err));
    }
    unsigned char *glb = NULL;
    size_t glen = 0;
    if (!rc) {
        mim__metrics_observe(&sv->m, MIM__H_TRANSFER, rep.seconds_solve);
        mim__metrics_add(&sv->m, MIM__C_TRANSFERS, 1);
        mim_session_output(sv->s, out, own); /* in the avatar's own connectivity */
        mim_mesh_t m = {n_own, sv->out_mesh->n_faces, own, sv->out_mesh->faces};
        rc = mim_io_encode_glb(&m, "transfer", &glb, &glen, &err);
        if (rc && status_of(rc) == 400)
            rc = MIM_EIO; /* an encoder failure is ours, not the client's */
    }
    if (rc && !status) {
        status = mim__reply_error(rp, status_of(rc), "%s", mim_error_text(&err));
    } else if (!rc) {
        /* the label is "subject/pose" from the store: keep header-safe bytes */
        for (char *p = rep.label; *p; p++)
            if ((unsigned char)*p < 0x20 || *p == 0x7f) *p = '?';
        status = mim__reply_take(rp, 200, "model/gltf-binary", glb, glen);
        glb = NULL;
        if (status == 200)
            snprintf(rp->headers, sizeof rp->headers,
                     "X-Mimic-Template: %llu\r\nX-Mimic-Template-Label: %s\r\nX-Mimic-Iterations: %u\r\n",
                     (unsigned long long)rep.template_id, rep.label, rep.xfer.iterations);
    }
    if (own != out) free(own);
    free(glb), free(r), free(out);
    return status;
}

int mim__api_metrics(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp)
{
    (void)rq;
    mim__metrics_set(&sv->m, MIM__G_WS_CLIENTS, mim__ws_clients(sv->ws));
    char *txt = mim__metrics_text(&sv->m);
    if (!txt)
        return mim__reply_error(rp, 500, "out of memory for the metrics");
    return mim__reply_take(rp, 200, "text/plain; version=0.0.4; charset=utf-8", txt, strlen(txt));
}
