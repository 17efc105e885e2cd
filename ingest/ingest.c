/* The ingest pipeline: reader threads parse, check and hash meshes (on all
 * cores); the calling thread, the store's single writer, takes them in file
 * order, checks them against the reference connectivity, labels them, and
 * commits one transaction per batch. Readers also compute each template's
 * transfer encoding (frames and W, seed 000 §3.1), stored beside it. With
 * a registrar (--register), readers also register a mesh of another
 * connectivity onto the store's (foreign.c), and its figures are stored
 * with it. A kill part-way loses at most the uncommitted batch; a re-run
 * skips what is stored (content hash; a registered source by its own
 * hash, so it is not registered again). */
#include "mim_ingest.h"
#include "mim_io.h"
#include "mim_register.h"
#include "mim_transfer.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct {
    int ready;
    int rc;
    mim_mesh_t mesh;
    uint64_t content_hash;
    float *encoding; /* 6n frames then 3n W (transfer's stored encoding) */
    mim_error_t err;
    /* a mesh of another connectivity, registered onto the store's */
    int registered;         /* 1: mesh now holds the registered result */
    uint64_t registered_as; /* > 0: this source was registered before, as that template */
    mim_db_registration_t reg;
} slot_t;

typedef struct {
    char **paths;
    size_t n;
    slot_t *slots;
    size_t next;   /* next file a reader claims */
    size_t base;   /* first file the writer has not finished */
    size_t window; /* files read ahead of the writer, at most */
    int stop;
    pthread_mutex_t mu;
    pthread_cond_t ready_cv, space_cv;
    /* --register */
    mim_db_t *db;
    const mim_ingest_options_t *opt;
    const mim_ingest_landmark_sources_t *sources;
    double max_distance_mm;
} work_t;

/* The transfer encoding of a mesh, on the reader's connectivity (rebuilt
 * when a mesh brings another one; such a mesh is rejected later unless it
 * is the store's). */
typedef struct {
    mim_xfer_topology_t *topo;
    double *work; /* 12 n doubles of encoding scratch, kept between meshes */
} reader_t;

static int encode(reader_t *r, slot_t *s, const char *path)
{
    const mim_mesh_t *m = &s->mesh;
    if (!r->topo || mim_xfer_check_mesh(r->topo, m, path, NULL)) {
        mim_xfer_topology_close(&r->topo);
        free(r->work);
        r->work = malloc(12 * (size_t)m->n_vertices * sizeof *r->work);
        int rc = r->work ? mim_xfer_topology_open(&r->topo, m->n_vertices, m->faces, m->n_faces, &s->err)
                         : mim_error_set(&s->err, MIM_ENOMEM, "%s: out of memory for its encoding", path);
        if (rc)
            return rc;
    }
    s->encoding = malloc(9 * (size_t)m->n_vertices * sizeof(float));
    if (!s->encoding)
        return mim_error_set(&s->err, MIM_ENOMEM, "%s: out of memory for its encoding", path);
    return mim_xfer_encoding_compute(r->topo, m->positions, s->encoding, s->encoding + 6 * (size_t)m->n_vertices,
                                     r->work, &s->err);
}

static int same_connectivity(const mim_mesh_t *m, const uint32_t *faces, uint32_t n, uint32_t n_faces)
{
    return m->n_vertices == n && m->n_faces == n_faces && !memcmp(m->faces, faces, (size_t)n_faces * 12);
}

/* A mesh of another connectivity (--register): found among earlier
 * registrations by its hash, or registered now; the slot's mesh then
 * becomes the result, on the store's connectivity. */
static int register_foreign(work_t *w, slot_t *s, const char *path)
{
    mim_ingest_registrar_t *r = w->opt->registrar;
    uint32_t nf;
    const uint32_t *faces = mim_ingest_registrar_faces(r, &nf);
    uint32_t n = mim_xfer_topology_n_vertices(mim_ingest_registrar_topology(r));
    if (same_connectivity(&s->mesh, faces, n, nf)) return 0;
    uint64_t hash = mim_ingest_mesh_hash(&s->mesh);
    mim_db_txn_t *t = NULL;
    mim_db_registration_t before;
    int rc = mim_db_begin(w->db, 0, &t, &s->err);
    if (!rc && (rc = mim_db_registration_find(t, hash, &before, &s->err)) == 0) s->registered_as = before.template_id;
    mim_db_abort(&t);
    if (rc != MIM_ENOTFOUND) return rc;
    const mim_landmark_map_t *map = mim_ingest_registrar_map(r);
    float lm[3 * MIM_LANDMARKS_MAX];
    char how[4200];
    if ((rc = mim_ingest_foreign_landmarks(path, &s->mesh, w->sources, map, lm, how, sizeof how, &s->err))) return rc;
    mim_mesh_t out = {0};
    if (mim_mesh_alloc(&out, n, nf)) return mim_error_set(&s->err, MIM_ENOMEM, "%s: out of memory", path);
    memcpy(out.faces, faces, (size_t)nf * 12);
    mim_reg_report_t rep;
    uint64_t from;
    if ((rc = mim_ingest_register_mesh(r, &s->mesh, lm, path, out.positions, &rep, &from, &s->err))) {
        mim_mesh_free(&out);
        return rc;
    }
    if (!(rep.p95_mm <= w->max_distance_mm)) {
        mim_mesh_free(&out);
        return mim_error_set(&s->err, MIM_ETOPOLOGY,
                             "%s: registration too far from the surface: distance p95 %.1f mm over the %g mm limit "
                             "(mean %.1f mm, landmarks %.1f mm off; from template %llu): not stored",
                             path, rep.p95_mm, w->max_distance_mm, rep.mean_mm, rep.landmark_mean_mm,
                             (unsigned long long)from);
    }
    s->reg = (mim_db_registration_t){0, hash, s->mesh.n_vertices, rep.iterations, rep.mean_mm, rep.p95_mm,
                                     rep.max_mm, rep.landmark_mean_mm, {0}};
    _Static_assert(MIM_DB_REG_REGIONS == MIM_REG_REGIONS, "the store keeps register/'s regions");
    if (isfinite(rep.volume_ratio) && rep.volume_ratio > 0) { /* a template of no volume (open) has none to keep */
        s->reg.quality.present = 1;
        s->reg.quality.landmark_max_mm = rep.landmark_max_mm;
        s->reg.quality.volume_ratio = rep.volume_ratio;
        memcpy(s->reg.quality.distortion_pct, rep.distortion_pct, sizeof s->reg.quality.distortion_pct);
    }
    mim_mesh_free(&s->mesh);
    s->mesh = out;
    s->registered = 1;
    return 0;
}

static void *reader_main(void *arg)
{
    work_t *w = arg;
    reader_t r = {0};
    for (;;) {
        pthread_mutex_lock(&w->mu);
        while (!w->stop && w->next < w->n && w->next >= w->base + w->window) pthread_cond_wait(&w->space_cv, &w->mu);
        if (w->stop || w->next >= w->n) {
            pthread_mutex_unlock(&w->mu);
            mim_xfer_topology_close(&r.topo);
            free(r.work);
            return NULL;
        }
        size_t i = w->next++;
        pthread_mutex_unlock(&w->mu);

        slot_t s = {0};
        s.rc = mim_io_read_mesh(w->paths[i], &s.mesh, &s.err);
        if (!s.rc) s.rc = mim_body_check(s.mesh.positions, s.mesh.n_vertices, w->paths[i], &s.err);
        if (!s.rc && w->opt->registrar) s.rc = register_foreign(w, &s, w->paths[i]);
        if (!s.rc && !s.registered_as) s.content_hash = mim_db_content_hash(s.mesh.positions, s.mesh.n_vertices);
        if (!s.rc && !s.registered_as) s.rc = encode(&r, &s, w->paths[i]);

        pthread_mutex_lock(&w->mu);
        s.ready = 1;
        w->slots[i] = s;
        pthread_cond_broadcast(&w->ready_cv);
        pthread_mutex_unlock(&w->mu);
    }
}

/* The writer's view of the store while ingesting. */
typedef struct {
    mim_db_txn_t *txn;
    int have_topology;
    uint32_t n_vertices, n_faces;
    uint64_t topo_hash;
    uint32_t *faces; /* own copy: store pointers die with each commit */
    mim_landmark_map_t landmarks;
    int have_landmarks;
} writer_t;

static int load_reference(mim_db_t *db, writer_t *wr, mim_error_t *err)
{
    mim_db_txn_t *t;
    int rc = mim_db_begin(db, 0, &t, err);
    if (rc) return rc;
    mim_db_topology_t topo;
    rc = mim_db_topology_get(t, &topo, err);
    if (rc == 0) {
        wr->have_topology = 1;
        wr->n_vertices = topo.n_vertices;
        wr->n_faces = topo.n_faces;
        wr->topo_hash = topo.hash;
        wr->faces = malloc((size_t)topo.n_faces * 12 + 1);
        if (!wr->faces) rc = MIM_ENOMEM;
        else memcpy(wr->faces, topo.faces, (size_t)topo.n_faces * 12);
    } else if (rc == MIM_ENOTFOUND) {
        rc = 0;
    }
    mim_db_abort(&t);
    return rc;
}

/* Checks a mesh against the reference; 0 or MIM_ETOPOLOGY with a message. */
static int check_topology(const writer_t *wr, const char *path, const mim_mesh_t *m, mim_error_t *err)
{
    if (m->n_vertices != wr->n_vertices || m->n_faces != wr->n_faces)
        return mim_error_set(err, MIM_ETOPOLOGY,
                             "%s: connectivity differs from the store's: %u vertices and %u faces, the store has %u and %u "
                             "(mimic ingest --register registers it onto the store's)",
                             path, m->n_vertices, m->n_faces, wr->n_vertices, wr->n_faces);
    if (mim_db_topology_hash(m->faces, m->n_faces, m->n_vertices) != wr->topo_hash ||
        memcmp(m->faces, wr->faces, (size_t)m->n_faces * 12) != 0) {
        uint32_t f = 0;
        while (f < m->n_faces && !memcmp(m->faces + 3 * (size_t)f, wr->faces + 3 * (size_t)f, 12)) f++;
        return mim_error_set(err, MIM_ETOPOLOGY,
                             "%s: connectivity differs from the store's: same counts, but face %u is (%u %u %u), the store's is (%u %u %u)",
                             path, f, m->faces[3 * (size_t)f], m->faces[3 * (size_t)f + 1], m->faces[3 * (size_t)f + 2],
                             wr->faces[3 * (size_t)f], wr->faces[3 * (size_t)f + 1], wr->faces[3 * (size_t)f + 2]);
    }
    return 0;
}

/* The first good mesh of an empty store fixes the connectivity, together
 * with the landmark map, in the same transaction as the first batch. */
static int set_reference(writer_t *wr, const char *path, const mim_mesh_t *m, mim_error_t *err)
{
    mim_error_t lm_err = {0};
    int rc = mim_landmarks_validate(&wr->landmarks, m->n_vertices, "landmark map", &lm_err);
    if (rc) return mim_error_set(err, rc, "%s (checked against the first mesh, %s)", lm_err.msg, path);
    wr->landmarks.topology_vertices = m->n_vertices;
    mim_error_t put_err = {0};
    if ((rc = mim_db_topology_put(wr->txn, m->faces, m->n_faces, m->n_vertices, &put_err))) {
        /* The store was empty when this run looked; another ingest's first
         * batch committed since (write transactions take turns). */
        mim_db_topology_t now;
        if (rc == MIM_EINVAL && mim_db_topology_get(wr->txn, &now, NULL) == 0)
            return mim_error_set(err, rc,
                                 "another ingest fixed the store's connectivity first (%u vertices, %u faces) while this "
                                 "one was starting on the empty store; nothing from this run was stored: re-run mimic ingest",
                                 now.n_vertices, now.n_faces);
        return mim_error_set(err, rc, "%s", put_err.msg[0] ? put_err.msg : mim_strerror(rc));
    }
    if ((rc = mim_db_landmarks_put(wr->txn, &wr->landmarks, err))) return rc;
    wr->have_topology = 1;
    wr->n_vertices = m->n_vertices;
    wr->n_faces = m->n_faces;
    wr->topo_hash = mim_db_topology_hash(m->faces, m->n_faces, m->n_vertices);
    wr->faces = malloc((size_t)m->n_faces * 12 + 1);
    if (!wr->faces) return MIM_ENOMEM;
    memcpy(wr->faces, m->faces, (size_t)m->n_faces * 12);
    return 0;
}

/* The landmark map of an empty store from the first readable mesh's
 * connectivity, when mimic knows it (register/'s built-in maps by the
 * faces' digest: SMPL's for FAUST and kin), so that a first ingest of such
 * scans needs no file. A note says which map was taken. */
static int builtin_map(mim_db_t *db, const mim_file_list_t *files, const mim_ingest_options_t *opt, writer_t *wr,
                       mim_error_t *err)
{
    mim_ingest_known_map_fn known = opt->known_map ? opt->known_map : mim_reg_known_map;
    for (size_t i = 0; i < files->count; i++) {
        mim_mesh_t m = {0};
        if (mim_io_read_mesh(files->paths[i], &m, NULL)) continue; /* reported with the others later */
        const char *name = NULL;
        int found = known(m.faces, m.n_faces, m.n_vertices, &wr->landmarks, &name);
        uint32_t nv = m.n_vertices;
        mim_mesh_free(&m);
        if (!found) break;
        wr->have_landmarks = 1;
        mim_log_emit(opt->log, opt->log_ctx, MIM_LOG_WARN,
                     "note: %s: landmarks from the built-in map %s (the connectivity of %s, %u vertices)",
                     mim_db_path(db), name ? name : "?", files->paths[i], nv);
        return 0;
    }
    return mim_error_set(err, MIM_ENOLANDMARKS,
                         "%s: the store is empty and needs a landmark map: pass --landmarks FILE, put landmarks.json "
                         "beside the meshes, or ingest meshes of a connectivity with a built-in map first (mimic "
                         "landmarks maps)",
                         mim_db_path(db));
}

int mim_ingest_run(mim_db_t *db, char *const *paths, size_t n_paths, const mim_ingest_options_t *opt,
                   mim_ingest_report_t *report, mim_error_t *err)
{
    mim_ingest_options_t defaults = {0};
    if (!opt) opt = &defaults;
    memset(report, 0, sizeof *report);
    double t0 = mim_now();
    uint32_t batch = opt->batch ? opt->batch : 64;
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    uint32_t threads = opt->threads ? opt->threads : (uint32_t)(ncpu > 0 ? ncpu : 1);

    writer_t wr = {0};
    mim_landmark_map_t dataset_map;
    char dataset_map_path[4096];
    mim_ingest_landmark_sources_t sources = {0};
    mim_manifest_t *manifest = NULL;
    mim_file_list_t files = {0};
    if (opt->dataset && !mim_ingest_dataset_valid(opt->dataset))
        return mim_error_set(err, MIM_EINVAL,
                             "dataset '%s': a name is 1 to %d of the letters, digits, '.', '_' and '-' (not . or ..)",
                             opt->dataset, MIM_INGEST_DATASET_MAX);
    int rc = load_reference(db, &wr, err), builtin = 0;
    if (!rc && !wr.have_topology) {
        /* An empty store needs a landmark map before anything goes in: a
         * file, else the built-in map of the first mesh's connectivity
         * (after the walk, below). */
        char found[4096];
        const char *lm = opt->landmarks_path;
        if (!lm && mim_discover_landmarks(paths, n_paths, found, sizeof found)) lm = found;
        if (!lm)
            builtin = 1;
        else if (!(rc = mim_landmarks_read(&wr.landmarks, lm, err)))
            wr.have_landmarks = 1;
    } else if (!rc && opt->registrar) {
        /* --register: a landmark map given or beside the dataset is the
         * map of the meshes' own connectivity, landmark source (a). */
        char found[4096];
        const char *lm = opt->landmarks_path;
        if (!lm && mim_discover_landmarks(paths, n_paths, found, sizeof found)) lm = found;
        if (lm && !(rc = mim_landmarks_read(&dataset_map, lm, err))) {
            snprintf(dataset_map_path, sizeof dataset_map_path, "%s", lm);
            sources.dataset_map = &dataset_map, sources.dataset_map_path = dataset_map_path;
        }
    } else if (!rc && opt->landmarks_path) {
        mim_log_emit(opt->log, opt->log_ctx, MIM_LOG_WARN, "note: the store already has a landmark map; ignoring %s",
                     opt->landmarks_path);
    }
    if (!rc && opt->manifest_path) rc = mim_manifest_load(&manifest, opt->manifest_path, err);
    if (!rc) rc = mim_discover(paths, n_paths, &files, err);
    if (!rc && builtin) rc = builtin_map(db, &files, opt, &wr, err);
    if (rc) goto out;
    /* what the walk found but cannot read: loops skipped, dangling links failed */
    for (size_t i = 0; i < files.n_skipped && !opt->quiet; i++)
        mim_log_emit(opt->log, opt->log_ctx, MIM_LOG_WARN, "%s", files.skipped[i]);
    for (size_t i = 0; i < files.n_failed && !opt->quiet; i++)
        mim_log_emit(opt->log, opt->log_ctx, MIM_LOG_ERROR, "%s", files.failed[i]);
    report->skipped = files.n_skipped;
    report->failed = files.n_failed;
    report->files = files.count + files.n_failed;

    work_t w = {0};
    w.db = db, w.opt = opt, w.sources = &sources;
    w.max_distance_mm = opt->max_distance_mm > 0 ? opt->max_distance_mm : MIM_INGEST_DEFAULT_MAX_DISTANCE_MM;
    w.paths = files.paths;
    w.n = files.count;
    w.window = batch + 4 * threads;
    w.slots = calloc(files.count ? files.count : 1, sizeof *w.slots);
    if (!w.slots) {
        rc = MIM_ENOMEM;
        goto out;
    }
    pthread_mutex_init(&w.mu, NULL);
    pthread_cond_init(&w.ready_cv, NULL);
    pthread_cond_init(&w.space_cv, NULL);
    pthread_t *tids = calloc(threads, sizeof *tids);
    uint32_t started = 0;
    for (; tids && started < threads; started++)
        if (pthread_create(&tids[started], NULL, reader_main, &w)) break;
    if (!started) {
        rc = mim_error_set(err, MIM_ENOMEM, "cannot start reader threads");
        goto join;
    }

    mim_progress_t prog = {.fn = opt->progress, .ctx = opt->progress_ctx};
    mim_progress_begin(&prog, "ingest", files.count);
    uint32_t pending = 0;
    for (size_t i = 0; i < files.count && !rc; i++) {
        pthread_mutex_lock(&w.mu);
        while (!w.slots[i].ready) pthread_cond_wait(&w.ready_cv, &w.mu);
        slot_t s = w.slots[i];
        pthread_mutex_unlock(&w.mu);

        const char *path = files.paths[i];
        if (!s.rc && wr.have_topology && !s.registered_as) s.rc = check_topology(&wr, path, &s.mesh, &s.err);
        if (!s.rc && s.registered_as) {
            report->duplicates++; /* this source was registered by an earlier run */
        } else if (s.rc) {
            report->failed++;
            if (!opt->quiet) mim_log_emit(opt->log, opt->log_ctx, MIM_LOG_ERROR, "%s", mim_error_text(&s.err));
        } else {
            if (!wr.txn && (rc = mim_db_begin(db, 1, &wr.txn, err))) break;
            if (!wr.have_topology && (rc = set_reference(&wr, path, &s.mesh, err))) break;
            mim_labels_t lab = {{0}, {0}};
            if (!(manifest && mim_manifest_lookup(manifest, path, &lab))) mim_labels_from_name(path, &lab);
            char real[4096], dataset[MIM_INGEST_DATASET_MAX + 1];
            if (opt->dataset) snprintf(dataset, sizeof dataset, "%s", opt->dataset);
            else mim_ingest_dataset_of(paths, n_paths, path, dataset, sizeof dataset);
            mim_template_in_t tin = {s.mesh.positions, s.mesh.n_vertices, s.content_hash,
                                     realpath(path, real) ? real : path, lab.subject, lab.pose, dataset};
            uint64_t id;
            int existed;
            if ((rc = mim_db_template_put(wr.txn, &tin, &id, &existed, err))) break;
            /* the encoding goes beside it; a template stored without one
             * (by an older mimic) gets it now */
            mim_db_encoding_t have;
            if (!existed || mim_db_encoding_get(wr.txn, id, &have, NULL) == MIM_ENOTFOUND) {
                const uint32_t n = s.mesh.n_vertices;
                if ((rc = mim_db_encoding_put(wr.txn, id, s.encoding, s.encoding + 6 * (size_t)n, n, err))) break;
                if (existed) pending++;
            }
            if (s.registered && !existed) {
                s.reg.template_id = id;
                if ((rc = mim_db_registration_put(wr.txn, &s.reg, err))) break;
                report->registered++;
            }
            if (existed) report->duplicates++;
            else report->added++, pending++;
            if (pending >= batch) {
                rc = mim_db_commit(&wr.txn, err);
                pending = 0;
            }
        }
        mim_mesh_free(&s.mesh);
        free(s.encoding);
        pthread_mutex_lock(&w.mu);
        w.slots[i].mesh.positions = NULL; /* freed above via the copy */
        w.slots[i].mesh.faces = NULL;
        w.slots[i].encoding = NULL;
        w.base = i + 1;
        pthread_cond_broadcast(&w.space_cv);
        pthread_mutex_unlock(&w.mu);
        mim_progress_update(&prog, i + 1);
    }
    if (!rc && wr.txn) rc = mim_db_commit(&wr.txn, err);
    mim_db_abort(&wr.txn); /* after a failure: the open batch is dropped, nothing half-written */
    mim_progress_end(&prog);

join:
    pthread_mutex_lock(&w.mu);
    w.stop = 1;
    pthread_cond_broadcast(&w.space_cv);
    pthread_mutex_unlock(&w.mu);
    for (uint32_t k = 0; k < started; k++) pthread_join(tids[k], NULL);
    free(tids);
    for (size_t i = 0; i < files.count; i++) {
        mim_mesh_free(&w.slots[i].mesh);
        free(w.slots[i].encoding);
    }
    free(w.slots);
    pthread_mutex_destroy(&w.mu);
    pthread_cond_destroy(&w.ready_cv);
    pthread_cond_destroy(&w.space_cv);
out:
    if (!rc) {
        mim_db_txn_t *t;
        mim_db_meta_t meta;
        if (!mim_db_begin(db, 0, &t, NULL)) {
            if (!mim_db_meta_get(t, &meta, NULL)) report->templates = meta.templates;
            mim_db_abort(&t);
        }
    }
    report->seconds = mim_now() - t0;
    free(wr.faces);
    mim_manifest_free(&manifest);
    mim_file_list_free(&files);
    return rc;
}
