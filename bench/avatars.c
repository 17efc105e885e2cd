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
    const char *landmarks;  /* the scan's landmark file */
    double max_distance_mm;
} avatar_t;

/* The session's log of a load, kept to print under the table. */
typedef struct log_buf {
    char text[8192];
    size_t len;
    int registered; /* a "registered onto" line: the load registered (not from cache) */
} log_buf_t;

static char pose_names[POSES][32]; /* synth's, to name the poses in the table */

/* "subject/pose" as "pose name" (synth's numbering). */
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
        snprintf(pose_names[p], sizeof pose_names[p], "%s", name ? name : "");
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
    for (uint64_t id = 1; id <= SUBJECTS * POSES && k < POSES; id++) {
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
 * the landmark file's vertices for the scan, else placed from its rig as
 * the session places them. */
static const char *near_landmark(mim_session_t *s, const avatar_t *a, const char *path, const mim_mesh_t *own,
                                 uint32_t f, char *name, size_t size)
{
    float lm[3 * MIM_LANDMARKS_MAX];
    mim_landmark_map_t file;
    const mim_landmark_map_t *map = mim_session_map(s);
    mim_error_t err = {0};
    snprintf(name, size, "?");
    if (a->landmarks) {
        if (mim_landmarks_read(&file, a->landmarks, &err)) return name;
        map = &file;
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
                      int *note_no)
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
               "%.2fx (%s) |\n",
               *note_no, a->label, own->n_vertices, n_parts, t_register, t_cached, 1e3 * mo, 1e3 * mk, mo / mk,
               100 * worst_share, ps, worst_ratio, pose_label(labels[at_ratio], pr, sizeof pr),
               part[0] ? part : "the scan", where, proxy_ratio, pose_label(labels[at_proxy], pp, sizeof pp));
        if (fabs(where_ratio - worst_ratio) > 1e-3 * worst_ratio)
            fprintf(stderr, "bench_avatars: %s: the bench's most stretched edge (%.3fx) is not mim_reg_stretch's "
                            "(%.3fx): 'near' may name another place\n", a->label, where_ratio, worst_ratio);
        fflush(stdout);
        char pt[64];
        int w = snprintf(notes + notes_used, sizeof notes - notes_used,
                         "%d. %s, first load%s:\n%s%s  - (bench) per frame: template %llu (pose %s), %u solves a key "
                         "frame; proxy %u vertices\n",
                         *note_no, a->label, first.registered ? "" : " (NOT registered: a stale cache?)", first.text,
                         again.registered ? "  - warning: a later load registered again (no cache)\n" : "",
                         (unsigned long long)ids[timed], pose_label(labels[timed], pt, sizeof pt), rep.xfer.iterations,
                         proxy->n_vertices);
        if (w > 0 && (size_t)w < sizeof notes - notes_used) notes_used += (size_t)w;
    }
    free(pose), free(out), free(vk), free(vo);
    mim_session_close(&s);
    return rc ? 1 : 0;
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
         NULL, NULL, 0},
        {"VRM 0, flat shaded, cm", {.names = RA_NAMES_VRM0, .flat = 1, .centimetres = 1, .seed = 7}, NULL, NULL, 0},
        {"VRM 1, shells", {.names = RA_NAMES_VRM1, .shells = 1, .seed = 7}, NULL, NULL, 0},
        {"Blender, T-pose, fists, seams",
         {.names = RA_NAMES_BLENDER, .tpose = 1, .fists = 1, .split_seams = 1, .seed = 7}, NULL, NULL, 0},
        {"Mixamo, 50 000 body vertices", {.names = RA_NAMES_MIXAMO, .vertices = 50000, .seed = 7}, NULL, NULL, 0},
        {"real scan: mh-bodies mh_s03_p00.ply (fingers), its landmarks.json, limit 100 mm", {0}, scan, scan_lm, 100},
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
        failed |= run_avatar(tmp, store, avatars + k, k, runs, loads, &row);
    }
    printf("\nThe session's log at each avatar's first load:\n\n%s\n", notes);
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
