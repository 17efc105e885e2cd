/* Rigged avatars as their authors ship them (issue 28): per avatar, what
 * it costs to take it in and to drive it, and how much it tears. Prints
 * figures; never passes or fails.
 *
 * The store: synth, 4 subjects x 12 poses at about --vertices (7000)
 * vertices (seed 1), ingested and indexed in a temporary folder, as
 * `mimic synth`, `mimic ingest`, `mimic index` make it. The avatars:
 * tests/support/rigged_avatar.h's GLBs of another body (seed 7, in no
 * store), and with mh-bodies (--mh DIR; default bench_mh_dir) one of its
 * scans, mh_s03_p00.ply, with its folder's landmarks.json and a 100 mm
 * registration limit (another body than the store's: its distance p95 may
 * exceed the 15 mm default). Per avatar:
 *   - register + bind: mim_session_open and mim_session_load_avatar on the
 *     store, the first time (registered, bound, the binding cached): one
 *     run, as the cache makes the next one another thing;
 *   - bind from cache: a new session's open + load of the same avatar (the
 *     binding read from the store): median of --loads (5);
 *   - per frame: mim_session_output of a posed proxy (the binding and the
 *     segments' follow), median of --runs (300), and in the same loop the
 *     reference: one key frame, mim_session_transfer of that template
 *     (mode (a), default relative transfer), median, and their ratio;
 *   - stretch: the avatar transferred into each of one store subject's 12
 *     template poses and mapped onto its own vertices; over its own faces
 *     (mim_session_output_mesh), the worst share of triangles with an edge
 *     over 3x its rest length (mim_reg_stretch) and the worst stretch, with
 *     the pose, the part (glTF primitive) and the landmark nearest the
 *     most stretched triangle at rest: where it is; and as a reference,
 *     the worst stretch of the proxy itself (the store's faces, the
 *     transfer's result against the proxy's rest) over the same poses.
 * What the session logged at the first load (registration distances,
 * pieces that follow a segment) is printed under the table.
 *
 * The second table, with mh-bodies: real scans as avatars in a store of
 * real scans. The store: mh-bodies subjects 0-6 (mh_s0[0-6]_p*.ply, 84
 * bodies of 13380 vertices) with the folder's landmarks.json as the
 * ingest's landmark map, ingested and indexed. The avatars, all subject
 * 7's rest body mh_s07_p00.ply (in no store):
 *   (a) as it is: the store's connectivity, no registration nor binding
 *       (what the transfer itself does to this body);
 *   (b) its vertices relabelled in reverse order (vertex i becomes
 *       n-1-i, faces remapped): registered and bound; its landmarks'
 *       positions in a sidecar NAME.landmarks.json that the session finds;
 *   (c) as (b), each hand first pulled into a fist (make_fists: the
 *       issue's "SCAPE fists bound to open hands"); its landmark positions
 *       passed as avatar_landmarks.
 * The same figures, over the 12 poses of the store's subject 1, and for
 * (b) and (c) the stretch through the binding alone (mim_reg_bind +
 * mim_reg_binding_apply, public: the session's binding without the
 * segments' follow) to show what the follow does.
 *
 * usage: bench_avatars [--vertices N] [--runs R] [--loads K] [--mh DIR | --no-mh] [--keep] */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_db.h"
#include "mim_ingest.h"
#include "mim_io.h"
#include "mim_query.h"
#include "mim_register.h"
#include "mim_session.h"
#include "mim_synth.h"
#include "rigged_avatar.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define POSES 12
#define SUBJECTS 4
#define STRETCH_LIMIT 3.0

typedef struct avatar {
    const char *label;
    ra_options_t ra; /* names etc.; unused for the scan */
    const char *path_given; /* the scan's file; NULL: written from ra */
    const char *landmarks;  /* the session's avatar_landmarks; NULL: a sidecar, or none */
    double max_distance_mm;
    /* The avatar's landmarks for naming places (a map of its connectivity,
     * or positions in the store map's order); NULL: from its rig (GLB), or
     * the store's map on it (the store's connectivity). */
    const char *lm_file;
    int bind_alone; /* also the stretch through the binding alone (no follow) */
} avatar_t;

/* The session's log of a load, kept to print under the table. */
typedef struct log_buf {
    char text[8192];
    size_t len;
    int registered; /* a "registered onto" line: the load registered (not from cache) */
} log_buf_t;

static char synth_pose_names[POSES][32], mh_pose_names[POSES][32];
static char (*pose_names)[32] = synth_pose_names; /* the store's, to name the poses in the table */
static uint32_t store_templates = SUBJECTS * POSES; /* the store's template ids are 1..this */

/* "subject/pose" as "pose name" (the store's numbering). */
static const char *pose_label(const char *label, char *buf, size_t size)
{
    const char *slash = strchr(label, '/');
    long p = slash ? strtol(slash + 1, NULL, 10) : -1;
    if (p >= 0 && p < POSES && pose_names[p][0]) snprintf(buf, size, "%ld %s", p, pose_names[p]);
    else snprintf(buf, size, "%s", label);
    return buf;
}

/* What the session logged at each first load, printed under the table. */
static char notes[65536];
static size_t notes_used;

static void keep_log(void *ctx, int level, const char *msg)
{
    log_buf_t *b = ctx;
    if (strstr(msg, "registered onto")) b->registered = 1;
    int w = snprintf(b->text + b->len, sizeof b->text - b->len, "  - %s%s\n", level == MIM_LOG_WARN ? "warning: " : "",
                     msg);
    if (w > 0) b->len += (size_t)w < sizeof b->text - b->len ? (size_t)w : sizeof b->text - b->len - 1;
}

static int open_load(mim_session_t **s, const char *store, const avatar_t *a, const char *path, log_buf_t *log,
                     mim_error_t *err)
{
    mim_session_options_t o = {.avatar_landmarks = a->landmarks, .max_distance_mm = a->max_distance_mm,
                               .log = keep_log, .log_ctx = log};
    int rc = mim_session_open(s, store, &o, err);
    if (!rc) rc = mim_session_load_avatar(*s, path, err);
    if (rc) mim_session_close(s);
    return rc;
}

/* The store: synth -> ingest -> index, in dir. */
static int make_store(const char *tmp, uint32_t vertices, char *store, size_t size)
{
    char bodies[4200];
    snprintf(bodies, sizeof bodies, "%s/bodies", tmp);
    snprintf(store, size, "%s/store", tmp);
    mim_error_t err = {0};
    mim_synth_t *sy = NULL;
    mim_synth_options_t so = {.subjects = SUBJECTS, .poses = POSES, .vertices = vertices, .seed = 1};
    mim_db_t *db = NULL;
    mim_db_options_t dbo = {0};
    mim_ingest_report_t irep;
    char *paths[1] = {bodies};
    int rc = mim_synth_create(&sy, &so, &err) || mim_synth_write_dataset(sy, bodies, &err) ||
             mim_db_open(&db, store, &dbo, &err) || mim_ingest_run(db, paths, 1, NULL, &irep, &err) ||
             mim_query_build_index(db, NULL, NULL, &err);
    mim_db_close(&db);
    for (uint32_t p = 0; !rc && p < POSES; p++) {
        const char *name = mim_synth_pose_name(sy, p);
        snprintf(synth_pose_names[p], sizeof synth_pose_names[p], "%s", name ? name : "");
    }
    mim_synth_destroy(&sy);
    if (rc) fprintf(stderr, "bench_avatars: store: %s\n", mim_error_text(&err));
    return rc ? 1 : 0;
}

/* The template ids of the subject of template `first`, in id order (its poses). */
static uint32_t subject_templates(mim_session_t *s, uint64_t first, uint64_t *ids, char labels[][MIM_SESSION_LABEL_MAX])
{
    char want[MIM_SESSION_LABEL_MAX], label[MIM_SESSION_LABEL_MAX];
    mim_error_t err = {0};
    if (mim_session_template(s, first, NULL, NULL, want, sizeof want, &err)) return 0;
    char *slash = strchr(want, '/');
    if (slash) slash[1] = 0;
    uint32_t k = 0;
    for (uint64_t id = 1; id <= store_templates && k < POSES; id++) {
        if (mim_session_template(s, id, NULL, NULL, label, sizeof label, &err)) continue;
        if (strncmp(label, want, strlen(want))) continue;
        ids[k] = id;
        snprintf(labels[k], MIM_SESSION_LABEL_MAX, "%s", label);
        k++;
    }
    return k;
}

/* The triangle whose edge stretched most (the one behind mim_reg_stretch's
 * largest stretch), and that stretch: to say where it is. */
static uint32_t most_stretched(const mim_mesh_t *m, const float *posed, double *ratio)
{
    uint32_t at = 0;
    *ratio = 0;
    for (uint32_t f = 0; f < m->n_faces; f++)
        for (int e = 0; e < 3; e++) {
            uint32_t a = m->faces[3 * f + e], b = m->faces[3 * f + (e + 1) % 3];
            double r2 = 0, p2 = 0;
            for (int c = 0; c < 3; c++) {
                double dr = m->positions[3 * a + c] - m->positions[3 * b + c], dp = posed[3 * a + c] - posed[3 * b + c];
                r2 += dr * dr, p2 += dp * dp;
            }
            if (r2 > 0 && sqrt(p2 / r2) > *ratio) *ratio = sqrt(p2 / r2), at = f;
        }
    return at;
}

/* The name of the avatar's landmark nearest the triangle's centroid, both
 * at rest in the avatar's own frame (a turned avatar's proxy is in another):
 * the landmark file's (a map's vertices, or positions), the store's map on
 * an avatar of its connectivity, else placed from its rig as the session
 * places them. */
static const char *near_landmark(mim_session_t *s, const avatar_t *a, const char *path, const mim_mesh_t *own,
                                 uint32_t f, char *name, size_t size)
{
    float lm[3 * MIM_LANDMARKS_MAX];
    mim_landmark_map_t file;
    const mim_landmark_map_t *map = mim_session_map(s);
    mim_error_t err = {0};
    snprintf(name, size, "?");
    if (a->lm_file) {
        mim_landmark_file_kind_t kind;
        if (mim_landmark_file_read(a->lm_file, map->count, &kind, &file, lm, &err)) return name;
        if (kind == MIM_LANDMARK_FILE_MAP) {
            map = &file;
            for (uint32_t l = 0; l < map->count; l++) {
                if (map->vertex[l] >= own->n_vertices) return name;
                memcpy(lm + 3 * l, own->positions + 3 * (size_t)map->vertex[l], 3 * sizeof(float));
            }
        }
    } else if (!mim_session_maps_output(s)) {
        for (uint32_t l = 0; l < map->count; l++)
            memcpy(lm + 3 * l, own->positions + 3 * (size_t)map->vertex[l], 3 * sizeof(float));
    } else {
        mim_io_scene_t scene;
        char how[512];
        if (mim_io_read_scene(path, NULL, &scene, &err)) return name;
        int rc = scene.mesh.n_vertices != own->n_vertices ||
                 mim_session_rig_landmarks(&scene.mesh, &scene.skin, map, lm, how, sizeof how, &err);
        mim_io_scene_free(&scene);
        if (rc) return name;
    }
    double c[3] = {0, 0, 0}, best = INFINITY;
    for (int k = 0; k < 3; k++)
        for (int d = 0; d < 3; d++) c[d] += own->positions[3 * (size_t)own->faces[3 * f + k] + d] / 3.0;
    for (uint32_t l = 0; l < map->count; l++) {
        double d2 = 0;
        for (int d = 0; d < 3; d++) d2 += pow(lm[3 * l + d] - c[d], 2);
        if (d2 < best) best = d2, snprintf(name, size, "%s", map->names[l]);
    }
    return name;
}

static int run_avatar(const char *tmp, const char *store, const avatar_t *a, int index, int runs, int loads,
                      int alone_cols, int *note_no)
{
    char path[4200], why[512];
    mim_error_t err = {0};
    if (a->path_given) {
        snprintf(path, sizeof path, "%s", a->path_given);
    } else {
        snprintf(path, sizeof path, "%s/avatar-%d.glb", tmp, index + 1);
        if (ra_write(&a->ra, path, NULL, why, sizeof why)) {
            fprintf(stderr, "bench_avatars: %s: %s\n", a->label, why);
            return 1;
        }
    }
    /* first load: registered and bound, the binding cached in the store */
    mim_session_t *s = NULL;
    log_buf_t first = {0}, again = {0};
    double t0 = mim_now();
    if (open_load(&s, store, a, path, &first, &err)) {
        fprintf(stderr, "bench_avatars: %s: %s\n", a->label, mim_error_text(&err));
        return 1;
    }
    double t_register = mim_now() - t0;
    mim_session_close(&s);
    /* again: from the cache */
    double *tl = malloc((size_t)loads * sizeof *tl);
    for (int k = 0; k < loads; k++) {
        mim_session_close(&s);
        t0 = mim_now();
        if (open_load(&s, store, a, path, &again, &err)) {
            fprintf(stderr, "bench_avatars: %s (again): %s\n", a->label, mim_error_text(&err));
            free(tl);
            return 1;
        }
        tl[k] = mim_now() - t0;
    }
    double t_cached = bench_median(tl, loads);
    free(tl);
    const mim_mesh_t *proxy = mim_session_mesh(s), *own = mim_session_output_mesh(s);
    uint32_t n_parts = 0;
    const mim_io_part_t *parts = mim_session_output_parts(s, &n_parts);
    uint64_t ids[POSES];
    char labels[POSES][MIM_SESSION_LABEL_MAX];
    uint32_t n_ids = subject_templates(s, 1 + POSES, ids, labels); /* the second subject's poses */
    if (n_ids == 0) {
        fprintf(stderr, "bench_avatars: no templates of the store's second subject\n");
        mim_session_close(&s);
        return 1;
    }
    float *pose = malloc(3 * (size_t)proxy->n_vertices * sizeof *pose);
    float *out = malloc(3 * (size_t)own->n_vertices * sizeof *out);
    double *vk = malloc((size_t)runs * sizeof *vk), *vo = malloc((size_t)runs * sizeof *vo);
    /* per frame: the pose of the subject's 8th template (wave, in synth's order) */
    const uint32_t timed = n_ids > 7 ? 7 : n_ids - 1;
    mim_session_request_t req = {.template_id = ids[timed]};
    mim_session_report_t rep;
    int rc = mim_session_transfer(s, &req, pose, NULL, &err); /* warm: the first reads every template's landmarks */
    for (int k = 0; !rc && k < runs; k++) {
        t0 = mim_now();
        rc = mim_session_transfer(s, &req, pose, &rep, &err);
        double t1 = mim_now();
        mim_session_output(s, pose, out);
        vk[k] = t1 - t0, vo[k] = mim_now() - t1;
    }
    /* the binding alone (no follow), as the session binds: its proxy and the avatar's own mesh */
    mim_reg_binding_t alone = {0};
    float *work = NULL, *out_alone = NULL;
    const int with_alone = a->bind_alone && mim_session_maps_output(s);
    if (!rc && with_alone) {
        work = malloc(3 * (size_t)proxy->n_vertices * sizeof *work);
        out_alone = malloc(3 * (size_t)own->n_vertices * sizeof *out_alone);
        if (!work || !out_alone) rc = mim_error_set(&err, MIM_ENOMEM, "out of memory");
        else rc = mim_reg_bind(proxy, own, &alone, &err);
    }
    double alone_share = 0, alone_ratio = 0, moved_mm = 0;
    uint32_t at_alone_share = 0, at_alone_ratio = 0, moved = 0, at_moved = 0;
    /* stretch over the subject's poses */
    double worst_share = 0, worst_ratio = 0, where_ratio = 0;
    uint32_t at_share = 0, at_ratio = 0, at_part = 0;
    uint32_t at_face = 0;
    double proxy_ratio = 0;
    uint32_t at_proxy = 0;
    for (uint32_t p = 0; !rc && p < n_ids; p++) {
        mim_session_request_t r = {.template_id = ids[p]};
        if ((rc = mim_session_transfer(s, &r, pose, NULL, &err))) break;
        mim_session_output(s, pose, out);
        double share = 0, ratio = 0, pshare = 0, pratio = 0;
        mim_reg_stretch(own->faces, own->n_faces, own->positions, out, STRETCH_LIMIT, &share, &ratio);
        /* the reference: the proxy's own stretch in that pose (what the transfer gives the binding) */
        mim_reg_stretch(proxy->faces, proxy->n_faces, proxy->positions, pose, STRETCH_LIMIT, &pshare, &pratio);
        if (pratio > proxy_ratio) proxy_ratio = pratio, at_proxy = p;
        if (share > worst_share) worst_share = share, at_share = p;
        if (with_alone) {
            double ashare = 0, aratio = 0, far = 0;
            uint32_t n_far = 0;
            mim_reg_binding_apply(&alone, proxy->faces, pose, work, out_alone);
            mim_reg_stretch(own->faces, own->n_faces, own->positions, out_alone, STRETCH_LIMIT, &ashare, &aratio);
            if (ashare > alone_share) alone_share = ashare, at_alone_share = p;
            if (aratio > alone_ratio) alone_ratio = aratio, at_alone_ratio = p;
            /* what the follow moved: vertices over 1 mm from the binding's place */
            for (uint32_t v = 0; v < own->n_vertices; v++) {
                double d2 = 0;
                for (int c = 0; c < 3; c++) d2 += pow(out[3 * (size_t)v + c] - out_alone[3 * (size_t)v + c], 2);
                if (d2 > 1e-6) n_far++;
                if (d2 > far) far = d2;
            }
            if (n_far > moved) moved = n_far, at_moved = p, moved_mm = 1e3 * sqrt(far);
        }
        if (ratio > worst_ratio) { /* where: the part, and the landmark nearest the triangle */
            worst_ratio = ratio, at_ratio = p;
            at_face = most_stretched(own, out, &where_ratio);
            for (uint32_t q = 0; q < n_parts; q++)
                if (at_face >= parts[q].first_face && at_face < parts[q].first_face + parts[q].n_faces) at_part = q;
        }
    }
    if (rc) {
        fprintf(stderr, "bench_avatars: %s: %s\n", a->label, mim_error_text(&err));
    } else {
        double mk = bench_median(vk, runs), mo = bench_median(vo, runs);
        const char *part = n_parts ? parts[at_part].name : "";
        char ps[64] = "-", pr[64];
        if (worst_share > 0) pose_label(labels[at_share], ps, sizeof ps);
        ++*note_no;
        char pp[64], where[MIM_LANDMARK_NAME_MAX + 8];
        near_landmark(s, a, path, own, at_face, where, sizeof where);
        printf("| %d. %s | %u | %u | %.2f | %.2f | %.3f | %.3f | %.3f | %.3f %% (%s) | %.2fx (%s, %s, near %s) | "
               "%.2fx (%s) |",
               *note_no, a->label, own->n_vertices, n_parts, t_register, t_cached, 1e3 * mo, 1e3 * mk, mo / mk,
               100 * worst_share, ps, worst_ratio, pose_label(labels[at_ratio], pr, sizeof pr),
               part[0] ? part : "the scan", where, proxy_ratio, pose_label(labels[at_proxy], pp, sizeof pp));
        if (alone_cols && with_alone) {
            char as[64] = "-", ar[64];
            if (alone_share > 0) pose_label(labels[at_alone_share], as, sizeof as);
            printf(" %.3f %% (%s) | %.2fx (%s) |", 100 * alone_share, as, alone_ratio,
                   pose_label(labels[at_alone_ratio], ar, sizeof ar));
        } else if (alone_cols) {
            printf(" - | - |");
        }
        printf("\n");
        if (fabs(where_ratio - worst_ratio) > 1e-3 * worst_ratio)
            fprintf(stderr, "bench_avatars: %s: the bench's most stretched edge (%.3fx) is not mim_reg_stretch's "
                            "(%.3fx): 'near' may name another place\n", a->label, where_ratio, worst_ratio);
        fflush(stdout);
        char pt[64];
        int w = snprintf(notes + notes_used, sizeof notes - notes_used,
                         "%d. %s, first load%s:\n%s%s  - (bench) per frame: template %llu (pose %s), %u solves a key "
                         "frame; proxy %u vertices\n",
                         *note_no, a->label,
                         !mim_session_maps_output(s) ? " (the store's connectivity: nothing registered nor bound)"
                         : first.registered          ? ""
                                                     : " (NOT registered: a stale cache?)",
                         first.text,
                         again.registered ? "  - warning: a later load registered again (no cache)\n" : "",
                         (unsigned long long)ids[timed], pose_label(labels[timed], pt, sizeof pt), rep.xfer.iterations,
                         proxy->n_vertices);
        if (w > 0 && (size_t)w < sizeof notes - notes_used) notes_used += (size_t)w;
        if (with_alone) {
            char pm[64];
            w = snprintf(notes + notes_used, sizeof notes - notes_used,
                         "  - (bench) the follow moves %u of its %u vertices (%.1f %%) over 1 mm from where the "
                         "binding alone puts them, at most %.1f mm (pose %s)\n",
                         moved, own->n_vertices, 100.0 * moved / own->n_vertices, moved_mm,
                         pose_label(labels[at_moved], pm, sizeof pm));
            if (w > 0 && (size_t)w < sizeof notes - notes_used) notes_used += (size_t)w;
        }
    }
    mim_reg_binding_free(&alone);
    free(work), free(out_alone);
    free(pose), free(out), free(vk), free(vo);
    mim_session_close(&s);
    return rc ? 1 : 0;
}

/* ---- the second table: real scans in a store of real scans ---- */
#define MH_SUBJECTS 7 /* subjects 0-6 in the store; 7 is the avatar */

/* The pose names of mh-bodies' manifest.csv (file,subject,pose,pose_name). */
static void read_mh_pose_names(const char *mh)
{
    char path[4200], line[512];
    snprintf(path, sizeof path, "%s/manifest.csv", mh);
    FILE *f = fopen(path, "r");
    if (!f) return;
    while (fgets(line, sizeof line, f)) {
        char file[256], name[32];
        int sub, pose;
        if (sscanf(line, "%255[^,],%d,%d,%31[^,\r\n]", file, &sub, &pose, name) == 4 && sub == 0 && pose >= 0 &&
            pose < POSES)
            snprintf(mh_pose_names[pose], sizeof mh_pose_names[pose], "%s", name);
    }
    fclose(f);
}

/* The store: mh-bodies subjects 0-6 with landmarks.json as the landmark
 * map, ingested and indexed in dir. */
static int make_mh_store(const char *tmp, const char *mh, char *store, size_t size, uint64_t *added)
{
    char *paths[MH_SUBJECTS * POSES], lm[4200];
    int rc = 0;
    for (uint32_t k = 0; k < MH_SUBJECTS * POSES; k++) {
        paths[k] = malloc(4200);
        if (!paths[k]) return 1;
        snprintf(paths[k], 4200, "%s/mh_s%02u_p%02u.ply", mh, k / POSES, k % POSES);
    }
    snprintf(lm, sizeof lm, "%s/landmarks.json", mh);
    snprintf(store, size, "%s/mh-store", tmp);
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_options_t dbo = {0};
    mim_ingest_options_t io = {.landmarks_path = lm, .quiet = 1};
    mim_ingest_report_t irep = {0};
    rc = mim_db_open(&db, store, &dbo, &err) || mim_ingest_run(db, paths, MH_SUBJECTS * POSES, &io, &irep, &err) ||
         mim_query_build_index(db, NULL, NULL, &err);
    mim_db_close(&db);
    for (uint32_t k = 0; k < MH_SUBJECTS * POSES; k++) free(paths[k]);
    if (rc) fprintf(stderr, "bench_avatars: mh store: %s\n", mim_error_text(&err));
    else if (irep.added != MH_SUBJECTS * POSES || irep.failed)
        fprintf(stderr, "bench_avatars: mh store: %llu added, %llu failed of %u\n", (unsigned long long)irep.added,
                (unsigned long long)irep.failed, MH_SUBJECTS * POSES), rc = 1;
    *added = irep.added;
    return rc ? 1 : 0;
}

/* Each hand pulled into a fist (the "SCAPE fists bound to the
 * store's open hands"): d the forearm's direction at the wrist, c 7 cm
 * beyond the wrist along it; every vertex within 25 cm of the wrist and
 * over 1 cm beyond it along d drawn towards c, by up to 55 % from 4 cm
 * beyond. Returns the vertices moved. */
static uint32_t make_fists(mim_mesh_t *m, const mim_landmark_map_t *map)
{
    uint32_t moved = 0;
    for (int side = 0; side < 2; side++) {
        int wi = mim_landmarks_find(map, side ? "r_wrist" : "l_wrist");
        int ei = mim_landmarks_find(map, side ? "r_elbow" : "l_elbow");
        if (wi < 0 || ei < 0) continue;
        const float *w = m->positions + 3 * (size_t)map->vertex[wi], *e = m->positions + 3 * (size_t)map->vertex[ei];
        double wrist[3] = {w[0], w[1], w[2]}, d[3], c[3], n = 0;
        for (int k = 0; k < 3; k++) d[k] = wrist[k] - e[k], n += d[k] * d[k];
        n = sqrt(n);
        for (int k = 0; k < 3; k++) d[k] /= n, c[k] = wrist[k] + 0.07 * d[k];
        for (uint32_t v = 0; v < m->n_vertices; v++) {
            float *p = m->positions + 3 * (size_t)v;
            double r2 = 0, along = 0;
            for (int k = 0; k < 3; k++) r2 += pow(p[k] - wrist[k], 2), along += (p[k] - wrist[k]) * d[k];
            if (r2 >= 0.25 * 0.25 || along <= 0.01) continue;
            double t = fmin(1.0, (along - 0.01) / 0.03), sc = 1 - 0.55 * t;
            for (int k = 0; k < 3; k++) p[k] = (float)(c[k] + sc * (p[k] - c[k]));
            moved++;
        }
    }
    return moved;
}

/* Positions file {"landmarks": [[x, y, z], ...]} of m's landmarks (map's
 * vertices, in its order). */
static int write_positions(const char *path, const mim_mesh_t *m, const mim_landmark_map_t *map)
{
    FILE *f = fopen(path, "w");
    if (!f) return 1;
    fprintf(f, "{\"landmarks\": [");
    for (uint32_t l = 0; l < map->count; l++) {
        const float *p = m->positions + 3 * (size_t)map->vertex[l];
        fprintf(f, "%s[%.9g, %.9g, %.9g]", l ? ", " : "", p[0], p[1], p[2]);
    }
    fprintf(f, "]}\n");
    return fclose(f) ? 1 : 0;
}

/* m with vertex i as n-1-i (faces remapped, their winding kept): the same
 * body in another vertex order. */
static void reverse_vertices(mim_mesh_t *m)
{
    const uint32_t n = m->n_vertices;
    for (uint32_t i = 0; i < n / 2; i++)
        for (int k = 0; k < 3; k++) {
            float t = m->positions[3 * (size_t)i + k];
            m->positions[3 * (size_t)i + k] = m->positions[3 * (size_t)(n - 1 - i) + k];
            m->positions[3 * (size_t)(n - 1 - i) + k] = t;
        }
    for (size_t f = 0; f < 3 * (size_t)m->n_faces; f++) m->faces[f] = n - 1 - m->faces[f];
}

/* The avatars of the second table: tmp/s07-reversed.ply with its sidecar
 * s07-reversed.landmarks.json, tmp/s07-fists.ply and s07-fists-landmarks.json
 * (not a sidecar: passed as avatar_landmarks). */
static int make_mh_avatars(const char *tmp, const char *rest, const char *lm, char *reversed, char *fists,
                           char *fists_lm, char *reversed_lm, size_t size, uint32_t *moved)
{
    mim_error_t err = {0};
    mim_mesh_t m = {0};
    mim_landmark_map_t map;
    snprintf(reversed, size, "%s/s07-reversed.ply", tmp);
    snprintf(reversed_lm, size, "%s/s07-reversed.landmarks.json", tmp);
    snprintf(fists, size, "%s/s07-fists.ply", tmp);
    snprintf(fists_lm, size, "%s/s07-fists-landmarks.json", tmp);
    int rc = mim_landmarks_read(&map, lm, &err) || mim_io_read_mesh(rest, &m, &err);
    if (!rc && map.topology_vertices != m.n_vertices)
        rc = mim_error_set(&err, MIM_ETOPOLOGY, "%s: %u vertices, %s is a map of %u", rest, m.n_vertices, lm,
                           map.topology_vertices);
    /* (b) */
    if (!rc && write_positions(reversed_lm, &m, &map)) rc = mim_error_set(&err, MIM_EIO, "cannot write %s", reversed_lm);
    if (!rc) {
        reverse_vertices(&m);
        rc = mim_io_write_mesh(reversed, &m, &err);
        reverse_vertices(&m);
    }
    /* (c) */
    if (!rc) {
        *moved = make_fists(&m, &map);
        if (write_positions(fists_lm, &m, &map)) rc = mim_error_set(&err, MIM_EIO, "cannot write %s", fists_lm);
    }
    if (!rc) {
        reverse_vertices(&m);
        rc = mim_io_write_mesh(fists, &m, &err);
    }
    mim_mesh_free(&m);
    if (rc) fprintf(stderr, "bench_avatars: mh avatars: %s\n", mim_error_text(&err));
    return rc ? 1 : 0;
}

static int mh_table(const char *tmp, const char *mh, int runs, int loads)
{
    char rest[4200], lm[4200];
    snprintf(rest, sizeof rest, "%s/mh_s07_p00.ply", mh);
    snprintf(lm, sizeof lm, "%s/landmarks.json", mh);
    for (uint32_t k = 0; k < MH_SUBJECTS * POSES; k++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/mh_s%02u_p%02u.ply", mh, k / POSES, k % POSES);
        if (access(path, R_OK)) {
            printf("\nmh-bodies: %s not found: no second table\n", path);
            return 0;
        }
    }
    if (access(rest, R_OK) || access(lm, R_OK)) {
        printf("\nmh-bodies: %s or %s not found: no second table\n", rest, lm);
        return 0;
    }
    char store[4200], reversed[4200], fists[4200], fists_lm[4200], reversed_lm[4200];
    uint64_t added = 0;
    uint32_t moved = 0;
    double t0 = mim_now();
    if (make_mh_store(tmp, mh, store, sizeof store, &added)) return 1;
    double t_store = mim_now() - t0;
    if (make_mh_avatars(tmp, rest, lm, reversed, fists, fists_lm, reversed_lm, sizeof reversed, &moved)) return 1;
    read_mh_pose_names(mh);
    pose_names = mh_pose_names, store_templates = (uint32_t)added;
    notes_used = 0, notes[0] = 0;
    printf("\n## Real scans as avatars in a store of real scans\n\n"
           "store: mh-bodies subjects 0-%d, %llu bodies of 13380 vertices, landmarks.json as the landmark map, "
           "ingested and indexed in %.1f s\n",
           MH_SUBJECTS - 1, (unsigned long long)added, t_store);
    printf("avatars: subject 7's rest body mh_s07_p00.ply (in no store); closed fists: %u vertices moved (both "
           "hands); per frame: median of %d runs; bind from cache: median of %d loads; stretch over the 12 poses of "
           "the store's subject 1; binding alone: mim_reg_bind + mim_reg_binding_apply (the session's binding, "
           "without the segments' follow)\n",
           moved, runs, loads);
    /* the reference: the store's subject 1 itself, each pose against its own rest (pose 0) */
    {
        mim_session_t *s = NULL;
        mim_error_t err = {0};
        uint64_t ids[POSES];
        char labels[POSES][MIM_SESSION_LABEL_MAX];
        uint32_t n_ids = 0;
        if (!mim_session_open(&s, store, NULL, &err)) n_ids = subject_templates(s, 1 + POSES, ids, labels);
        const mim_mesh_t *m = s ? mim_session_mesh(s) : NULL;
        float *rest_p = m ? malloc(3 * (size_t)m->n_vertices * sizeof *rest_p) : NULL;
        float *posed = m ? malloc(3 * (size_t)m->n_vertices * sizeof *posed) : NULL;
        double ws = 0, wr = 0;
        uint32_t at_s = 0, at_r = 0;
        int ok = n_ids == POSES && rest_p && posed && !mim_session_template(s, ids[0], rest_p, NULL, NULL, 0, &err);
        for (uint32_t p = 1; ok && p < n_ids; p++) {
            double share = 0, ratio = 0;
            if (mim_session_template(s, ids[p], posed, NULL, NULL, 0, &err)) ok = 0;
            else mim_reg_stretch(m->faces, m->n_faces, rest_p, posed, STRETCH_LIMIT, &share, &ratio);
            if (share > ws) ws = share, at_s = p;
            if (ratio > wr) wr = ratio, at_r = p;
        }
        char ps[64] = "-", pr[64] = "-";
        if (ok && ws > 0) pose_label(labels[at_s], ps, sizeof ps);
        if (ok) pose_label(labels[at_r], pr, sizeof pr);
        if (ok)
            printf("reference: the store's subject 1 itself, each of its poses against its own rest (0 rest), on the "
                   "store's faces: worst share over 3x %.3f %% (%s), worst stretch %.2fx (%s)\n\n",
                   100 * ws, ps, wr, pr);
        else
            printf("reference: the store's subject 1 itself: not measured (%s)\n\n", mim_error_text(&err));
        free(rest_p), free(posed);
        mim_session_close(&s);
    }
    const avatar_t avatars[] = {
        {"same connectivity (no binding): mh_s07_p00.ply as it is", {0}, rest, NULL, 0, NULL, 0},
        {"the same body, another vertex order (reversed; landmark positions in its sidecar)", {0}, reversed, NULL, 0,
         reversed_lm, 1},
        {"closed fists (as b, hands pulled into fists; landmark positions as avatar_landmarks)", {0}, fists, fists_lm,
         0, fists_lm, 1},
    };
    printf("| avatar | vertices | primitives | load: register + bind (s, one run) | load from cache (s) | output (ms) | "
           "key frame (ms) | output / key frame | worst share over 3x (pose) | worst stretch (pose, part, nearest "
           "landmark at rest) | reference: the proxy's worst stretch (pose) | binding alone: worst share over 3x "
           "(pose) | binding alone: worst stretch (pose) |\n"
           "|---|---:|---:|---:|---:|---:|---:|---:|---|---|---|---|---|\n");
    fflush(stdout);
    int failed = 0, row = 0;
    for (int k = 0; k < (int)(sizeof avatars / sizeof *avatars); k++)
        failed |= run_avatar(tmp, store, avatars + k, k, runs, loads, 1, &row);
    printf("\nThe session's log at each avatar's first load:\n\n%s\n", notes);
    return failed;
}

static void print_load(const char *when)
{
    char buf[256] = "";
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (!fgets(buf, sizeof buf, f)) buf[0] = 0;
        fclose(f);
    }
    buf[strcspn(buf, "\n")] = 0;
    printf("load average %s: %s\n", when, buf[0] ? buf : "unknown");
}

int main(int argc, char **argv)
{
    uint32_t vertices = 7000;
    int runs = 300, loads = 5, no_mh = 0, keep = 0;
    const char *mh = NULL;
    char mh_buf[4096];
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--vertices") && i + 1 < argc) vertices = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) runs = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--loads") && i + 1 < argc) loads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--mh") && i + 1 < argc) mh = argv[++i];
        else if (!strcmp(argv[i], "--no-mh")) no_mh = 1;
        else if (!strcmp(argv[i], "--keep")) keep = 1;
        else {
            fprintf(stderr, "usage: %s [--vertices N] [--runs R] [--loads K] [--mh DIR | --no-mh] [--keep]\n", argv[0]);
            return 2;
        }
    }
    if (runs < 1) runs = 1;
    if (loads < 1) loads = 1;
    if (!mh) mh = bench_mh_dir(mh_buf, sizeof mh_buf);
    char tmp[] = "/tmp/mimic-bench-avatars-XXXXXX";
    if (!mkdtemp(tmp)) return 1;
    char store[4200];
    print_load("at start");
    double t0 = mim_now();
    if (make_store(tmp, vertices, store, sizeof store)) return 1;
    printf("store: synth, %u subjects x %u poses at %u vertices (seed 1), ingested and indexed in %.1f s\n", SUBJECTS,
           POSES, vertices, mim_now() - t0);
    printf("avatars: rigged GLBs of synth seed 7 (tests/support/rigged_avatar.h), 3000 body vertices unless said; "
           "per frame: median of %d runs; bind from cache: median of %d loads; stretch over the 12 poses of the "
           "store's second subject\n\n",
           runs, loads);

    char scan[4200], scan_lm[4200];
    snprintf(scan, sizeof scan, "%s/mh_s03_p00.ply", mh);
    snprintf(scan_lm, sizeof scan_lm, "%s/landmarks.json", mh);
    const avatar_t avatars[] = {
        {"all: Mixamo, seams, joint rings first, shells, sword, cm, fists, texture, two primitives",
         {.names = RA_NAMES_MIXAMO, .split_seams = 1, .joint_rings_first = 1, .shells = 1, .prop = 1,
          .centimetres = 1, .fists = 1, .texture = 1, .two_primitives = 1, .seed = 7},
         NULL, NULL, 0, NULL, 0},
        {"VRM 0, flat shaded, cm", {.names = RA_NAMES_VRM0, .flat = 1, .centimetres = 1, .seed = 7}, NULL, NULL, 0, NULL, 0},
        {"VRM 1, shells", {.names = RA_NAMES_VRM1, .shells = 1, .seed = 7}, NULL, NULL, 0, NULL, 0},
        {"Blender, T-pose, fists, seams",
         {.names = RA_NAMES_BLENDER, .tpose = 1, .fists = 1, .split_seams = 1, .seed = 7}, NULL, NULL, 0, NULL, 0},
        {"Mixamo, 50 000 body vertices", {.names = RA_NAMES_MIXAMO, .vertices = 50000, .seed = 7}, NULL, NULL, 0, NULL, 0},
        {"real scan: mh-bodies mh_s03_p00.ply (fingers), its landmarks.json, limit 100 mm", {0}, scan, scan_lm, 100,
         scan_lm, 0},
    };
    const int n_avatars = sizeof avatars / sizeof *avatars;
    printf("| avatar | vertices | primitives | register + bind (s, one run) | bind from cache (s) | output (ms) | "
           "key frame (ms) | output / key frame | worst share over 3x (pose) | worst stretch (pose, part, nearest landmark at rest) | "
           "reference: the proxy's worst stretch (pose) |\n"
           "|---|---:|---:|---:|---:|---:|---:|---:|---|---|---|\n");
    fflush(stdout);
    int failed = 0, row = 0;
    for (int k = 0; k < n_avatars; k++) {
        if (avatars[k].path_given) {
            if (no_mh) continue;
            if (access(avatars[k].path_given, R_OK) || access(avatars[k].landmarks, R_OK)) {
                printf("| %s | not found: %s |\n", avatars[k].label, avatars[k].path_given);
                continue;
            }
        }
        failed |= run_avatar(tmp, store, avatars + k, k, runs, loads, 0, &row);
    }
    printf("\nThe session's log at each avatar's first load:\n\n%s\n", notes);
    if (!no_mh) failed |= mh_table(tmp, mh, runs, loads);
    print_load("at end");
    if (!keep) {
        char cmd[4300];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
        if (system(cmd)) fprintf(stderr, "bench_avatars: could not remove %s\n", tmp);
    } else {
        printf("kept %s\n", tmp);
    }
    return failed;
}
