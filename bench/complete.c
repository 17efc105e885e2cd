/* Completion of lost landmarks by retrieval (issue 14, seed 002 Section
 * 6): error on 3 lost landmarks, strict leave-one-subject-out. Prints
 * figures; never passes or fails.
 *
 * Each body of the set (every subject, every pose) loses 3 of its 16
 * landmarks (every one of 40 fixed triples drawn once from seed 1), and
 * mim_session_complete fills them from the other subjects' templates
 * (--exclude-subject). Rows: the nearest template alone (k 1, no blend),
 * and the median of k templates with and without the Gaussian blend.
 * Error: distance from each filled landmark to the truth, pooled.
 *
 * Replay (the baseline the issue names): a vest replay in which sensors
 * are lost for a stretch of a moving motion. The motion's landmark frames
 * are what `mimic vest simulate --expected` writes: the motion (the
 * built-in demo; with the shared data also MakeHuman's zombieWalk1.bvh, a
 * walk cycle, and CMU's 20_11 ASF/AMC take) streamed by the
 * simulated vest at its default rate (mim_vest_sim_orientations) and
 * turned into a store subject's landmarks by forward kinematics
 * (mim_vest_fk_orient) through a rig estimated from that subject's rest
 * template, pose "0" or "rest" (mim_vest_skeleton_estimate,
 * mim_vest_calibrate; tare pose chosen from the motion's rest pose as vest
 * simulate does). Every
 * subject of the store is the wearer in turn and is left out of the
 * retrieval. Lost sets are what lost sensors leave (a forearm sensor its
 * wrist, a shin its ankle, the head its head, an upper arm its elbow and
 * wrist): 1, 2 and 3 landmarks, ends of chains first. Stretches start
 * every 0.25 s (from 0.25 s) and last 0.25, 0.5, 1 or 2 s, when they fit
 * in the replay; a looped motion (a walk cycle) plays for 12 s, as vest
 * simulate --loop does. Error of each lost landmark in each lost frame
 * against the true position: (a) holding its last seen position (the
 * frame before the stretch), (b) mim_session_complete on that frame
 * (default options). A frame's completion does not depend on the stretch,
 * so it is computed once per frame and lost set. A last line gives how far
 * the store is from the frames: the RMS distance of each frame (every 4th)
 * to the nearest template of another subject, against the same for the
 * static bodies.
 *
 * Each row's templates and pose classes leave the body's subject out: the
 * store's scan by --exclude-subject, the classes' Gaussians (issue 29) by
 * an index built without that subject (as `mimic index` builds one).
 *
 * usage: bench_complete [--vertices N] [--mh DIR | --no-mh] [--imitation DEG | --no-imitation]
 * Stores are built in a temporary folder from the data set's files. The
 * real motions are read from the folder that holds mh-bodies (the shared
 * data): --no-mh leaves them out too. */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_db.h"
#include "mim_ingest.h"
#include "mim_register.h"
#include "mim_session.h"
#include "mim_synth.h"
#include "mim_vest_kinematics.h"
#include "mim_vest_motion.h"
#include "mim_vest_simulate.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define TRIPLES 40

/* ---- leave-one-subject-out indexes: the pose classes' Gaussians without the subject ---- */
typedef struct loso {
    uint32_t n;
    char (*subject)[64];
    mim_index_t **ix;
} loso_t;

static void loso_free(loso_t *lo)
{
    for (uint32_t i = 0; i < lo->n; i++) mim_index_close(&lo->ix[i]);
    free(lo->subject), free(lo->ix);
    memset(lo, 0, sizeof *lo);
}

/* --proportions body: indexes whose angles see each body's own
 * proportions (the index's default before canonical proportions) */
static int body_proportions;

/* One index per subject over the other subjects' templates (landmarks tl,
 * L each, n templates), as `mimic index` builds it (default options). */
static int loso_build(loso_t *lo, const float *tl, char (*subj)[64], char (*pose)[64], uint32_t n, uint32_t L,
                      const mim_landmark_map_t *map)
{
    memset(lo, 0, sizeof *lo);
    lo->subject = calloc(n, sizeof *lo->subject), lo->ix = calloc(n, sizeof *lo->ix);
    float *lm = malloc(sizeof *lm * 3 * L * n);
    const char **sp = malloc(sizeof *sp * n), **pp = malloc(sizeof *pp * n);
    uint64_t *id = malloc(sizeof *id * n);
    int rc = !lo->subject || !lo->ix || !lm || !sp || !pp || !id;
    for (uint32_t t = 0; t < n && !rc; t++) {
        uint32_t i = 0;
        while (i < lo->n && strcmp(lo->subject[i], subj[t])) i++;
        if (i < lo->n) continue;
        memcpy(lo->subject[lo->n++], subj[t], 64);
        uint32_t m = 0;
        for (uint32_t u = 0; u < n; u++)
            if (strcmp(subj[u], subj[t])) {
                memcpy(lm + (size_t)3 * L * m, tl + (size_t)3 * L * u, sizeof *lm * 3 * L);
                sp[m] = subj[u], pp[m] = pose[u], id[m] = u + 1, m++;
            }
        int32_t parent[MIM_LANDMARKS_MAX];
        mim_index_input_t in = {m, L, lm, id, sp, pp, map->mirror,
                                body_proportions || mim_index_skeleton(map, parent) ? NULL : parent};
        mim_error_t err = {0};
        if (mim_index_build(&lo->ix[i], &in, NULL, NULL, &err)) {
            fprintf(stderr, "leave-one-out index without %s: %s\n", subj[t], mim_error_text(&err));
            rc = 1;
        }
    }
    free(lm), free(sp), free(pp), free(id);
    if (rc) loso_free(lo);
    return rc;
}

static const mim_index_t *loso_find(const loso_t *lo, const char *subject)
{
    for (uint32_t i = 0; i < lo->n; i++)
        if (!strcmp(lo->subject[i], subject)) return lo->ix[i];
    return NULL;
}

/* ---- replay: hold the last value against completion ---- */
#define REPLAY_LOOP_S 12.0   /* a looped motion plays this long */
#define STRETCH_EVERY_S 0.25 /* a stretch starts this often */
static const double loss_s[] = {0.25, 0.5, 1, 2};
#define LOSSES ((int)(sizeof loss_s / sizeof *loss_s))
/* what lost sensors leave lost: forearm -> wrist, shin -> ankle, head ->
 * head, upper arm -> elbow and wrist */
static const char *const lost_sets[][3] = {
    {"l_wrist"}, {"r_wrist"}, {"l_ankle"}, {"r_ankle"}, {"head"},
    {"l_wrist", "r_wrist"}, {"l_ankle", "r_ankle"}, {"l_elbow", "l_wrist"}, {"r_elbow", "r_wrist"},
    {"l_wrist", "r_ankle"}, {"r_wrist", "l_ankle"},
    {"l_elbow", "l_wrist", "r_wrist"}, {"r_elbow", "r_wrist", "l_wrist"}, {"head", "l_wrist", "r_wrist"},
    {"l_wrist", "l_ankle", "r_ankle"}, {"r_wrist", "l_ankle", "r_ankle"},
};
#define LOST_SETS ((int)(sizeof lost_sets / sizeof *lost_sets))

typedef struct motion {
    char name[64];
    mim_vest_motion_t m;
    int loop; /* a cycle: looped for REPLAY_LOOP_S */
} motion_t;

typedef struct errs {
    double *v;
    size_t n, cap;
} errs_t;

static int errs_push(errs_t *e, double x)
{
    if (e->n == e->cap) {
        size_t cap = e->cap ? 2 * e->cap : 4096;
        double *nv = realloc(e->v, cap * sizeof *nv);
        if (!nv) return -1;
        e->v = nv, e->cap = cap;
    }
    e->v[e->n++] = x;
    return 0;
}

static double dist_mm(const float *a, const float *b)
{
    return 1000 * sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* RMS distance (mm) from landmarks x to the nearest of the n templates'
 * landmarks tl (L each) after each one's best similarity onto x, leaving
 * out the templates of subject skip: how far the store is from a frame. */
static double nearest_rms(const float *x, const float *tl, char (*subj)[64], uint32_t n, uint32_t L, const char *skip)
{
    double best = INFINITY;
    float moved[3 * MIM_LANDMARKS_MAX];
    for (uint32_t t = 0; t < n; t++) {
        mim_reg_similarity_t sim;
        if (!strcmp(subj[t], skip) || mim_reg_similarity_fit(tl + (size_t)t * L * 3, x, L, &sim, NULL)) continue;
        mim_reg_similarity_apply(&sim, tl + (size_t)t * L * 3, L, moved);
        double d = 0;
        for (uint32_t k = 0; k < 3 * L; k++) d += (moved[k] - x[k]) * (moved[k] - x[k]);
        if (d < best) best = d;
    }
    return 1000 * sqrt(best / L);
}

/* " mean | p95 |" of e (sorted here), " - | - |" when empty. */
static void print_stat(errs_t *e)
{
    if (!e->n) {
        printf(" - | - |");
        return;
    }
    double sum = 0;
    for (size_t i = 0; i < e->n; i++) sum += e->v[i];
    qsort(e->v, e->n, sizeof *e->v, cmp_d);
    printf(" %.1f | %.1f |", sum / (double)e->n, e->v[(size_t)(0.95 * (double)(e->n - 1))]);
}

/* The store's subjects as vest wearers: each one's skeleton, estimated from
 * its rest template (pose label "0" or "rest"), as `vest simulate --avatar`
 * estimates an avatar's. */
typedef struct wearer {
    char subject[64];
    mim_vest_skeleton_t sk;
} wearer_t;

static int wearers_load(const char *store, const mim_landmark_map_t *map, wearer_t **out, uint32_t *count,
                        mim_error_t *err)
{
    mim_db_t *db = NULL;
    mim_db_options_t o = {.read_only = 1};
    mim_db_txn_t *t = NULL;
    mim_db_meta_t meta = {0};
    mim_db_topology_t top = {0};
    wearer_t *w = NULL;
    uint32_t n = 0;
    int rc = mim_db_open(&db, store, &o, err);
    if (!rc) rc = mim_db_begin(db, 0, &t, err);
    if (!rc) rc = mim_db_meta_get(t, &meta, err);
    if (!rc) rc = mim_db_topology_get(t, &top, err);
    if (!rc && !(w = calloc(meta.templates ? meta.templates : 1, sizeof *w))) rc = MIM_ENOMEM;
    for (uint64_t id = 1; !rc && id < meta.next_id && n < meta.templates; id++) {
        mim_template_view_t v;
        if (mim_db_template_get(t, id, &v, NULL) || v.n_vertices != top.n_vertices) continue;
        if (strcmp(v.pose, "0") && strcmp(v.pose, "rest")) continue;
        int dup = 0;
        for (uint32_t i = 0; i < n; i++) dup |= !strcmp(w[i].subject, v.subject);
        if (dup) continue;
        mim_mesh_t mesh = {v.n_vertices, top.n_faces, (float *)v.positions, (uint32_t *)top.faces};
        snprintf(w[n].subject, sizeof w[n].subject, "%s", v.subject);
        rc = mim_vest_skeleton_estimate(&w[n].sk, &mesh, map, err);
        n++;
    }
    mim_db_abort(&t);
    mim_db_close(&db);
    if (rc) {
        free(w);
        return rc;
    }
    *out = w, *count = n;
    return 0;
}

/* The replay section: every motion, every wearer, every lost set; rows
 * per loss length (all sets) and per lost count (all lengths). */
static int replay(mim_session_t *s, const char *store, const char *name, const motion_t *motions, int nm,
                  const float *tl, char (*subj)[64], uint32_t nt, const loso_t *lo)
{
    const mim_landmark_map_t *map = mim_session_map(s);
    const uint32_t L = map->count;
    mim_error_t err = {0};
    wearer_t *w = NULL;
    uint32_t nw = 0;
    if (wearers_load(store, map, &w, &nw, &err)) {
        fprintf(stderr, "%s replay: %s\n", name, mim_error_text(&err));
        return 1;
    }
    if (!nw) {
        printf("\n(%s: no subject has a rest template, pose 0: replay skipped)\n", name);
        free(w);
        return 0;
    }
    /* the lost sets as landmark indices; a set naming a landmark the map lacks is left out */
    int set_n[LOST_SETS];
    uint32_t set_l[LOST_SETS][3];
    for (int q = 0; q < LOST_SETS; q++) {
        set_n[q] = 0;
        for (int c = 0; c < 3 && lost_sets[q][c]; c++) {
            uint32_t l = 0;
            while (l < L && strcmp(map->names[l], lost_sets[q][c])) l++;
            if (l == L) {
                set_n[q] = 0;
                break;
            }
            set_l[q][set_n[q]++] = l;
        }
    }
    printf("\n### %s: vest replay, sensors lost for a stretch: hold the last value or complete; each of %u subjects is "
           "the wearer in turn, left out\n\n",
           name, nw);
    printf("| motion | loss (s) | lost landmarks | landmark-frames | hold last: mean (mm) | hold last: p95 (mm) | "
           "completion: mean (mm) | completion: p95 (mm) |\n|---|---|---|---|---|---|---|---|\n");
    int rc = 0;
    char far[1024];
    int at = 0;
    for (int mi = 0; mi < nm && !rc; mi++) {
        const motion_t *mo = &motions[mi];
        int pose = MIM_VEST_POSE_REST; /* the tare pose, as vest simulate chooses it */
        if (mo->m.rest_arm_deg >= 0) pose = mo->m.rest_arm_deg > 67.5 ? MIM_VEST_POSE_T : MIM_VEST_POSE_A;
        mim_vest_sim_options_t so = {.loop = mo->loop};
        mim_vest_sim_t *sim = NULL;
        if (mim_vest_sim_open(&sim, &mo->m, &so, &err)) {
            fprintf(stderr, "%s replay %s: %s\n", name, mo->name, mim_error_text(&err));
            rc = 1;
            break;
        }
        const double rate = mim_vest_sim_rate(sim);
        const uint64_t N = mo->loop ? (uint64_t)llround(REPLAY_LOOP_S * rate) : mim_vest_sim_n_frames(sim);
        float *truth = malloc(N * L * 3 * sizeof *truth), *comp = malloc(N * 9 * sizeof *comp);
        errs_t e[2][LOSSES + 3];
        memset(e, 0, sizeof e);
        int oom = !truth || !comp, missing = 0;
        double far_sum = 0;
        uint64_t far_n = 0;
        for (uint32_t wi = 0; wi < nw && !rc && !oom && !missing; wi++) {
            mim_vest_rig_t rig;
            mim_vest_calib_options_t co = {pose};
            if (mim_vest_calibrate(&rig, &w[wi].sk, &co, NULL, &err)) {
                fprintf(stderr, "%s replay %s, subject %s: %s\n", name, mo->name, w[wi].subject, mim_error_text(&err));
                rc = 1;
                break;
            }
            /* the true landmarks: what vest simulate --expected writes for this wearer */
            for (uint64_t k = 0; k < N; k++) {
                mim_quat q[MIM_VEST_SEGMENTS];
                uint8_t have[MIM_VEST_SEGMENTS], present[MIM_LANDMARKS_MAX];
                mim_vest_sim_orientations(sim, k, q, have, NULL);
                missing |= mim_vest_fk_orient(&rig, q, have, truth + k * L * 3, present) != L;
            }
            for (uint64_t k = 0; k < N && !missing; k += 4)
                far_sum += nearest_rms(truth + k * L * 3, tl, subj, nt, L, w[wi].subject), far_n++;
            mim_session_complete_options_t co2 = {.exclude_subject = w[wi].subject,
                                                   .index = loso_find(lo, w[wi].subject)};
            for (int q = 0; q < LOST_SETS && !rc && !oom && !missing; q++) {
                if (!set_n[q]) continue;
                /* completion of each frame (frame 0 is never lost: there is nothing to hold) */
                for (uint64_t k = 1; k < N; k++) {
                    uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
                    float in[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX];
                    memcpy(in, truth + k * L * 3, (size_t)L * 12);
                    memset(present, 1, L);
                    for (int c = 0; c < set_n[q]; c++) present[set_l[q][c]] = 0, in[3 * set_l[q][c]] = NAN;
                    if (mim_session_complete(s, in, present, &co2, out, done, &err)) {
                        fprintf(stderr, "%s replay %s: %s\n", name, mo->name, mim_error_text(&err));
                        rc = 1;
                        break;
                    }
                    for (int c = 0; c < set_n[q]; c++) memcpy(comp + (k * 3 + c) * 3, out + 3 * set_l[q][c], 12);
                }
                for (int li = 0; li < LOSSES && !rc; li++) {
                    const uint64_t len = (uint64_t)llround(loss_s[li] * rate);
                    for (int j = 1;; j++) {
                        const uint64_t s0 = (uint64_t)llround(j * STRETCH_EVERY_S * rate);
                        if (s0 + len > N) break;
                        for (uint64_t k = s0; k < s0 + len; k++)
                            for (int c = 0; c < set_n[q]; c++) {
                                const uint32_t l = set_l[q][c];
                                const float *g = truth + (k * L + l) * 3;
                                const double hold = dist_mm(truth + ((s0 - 1) * L + l) * 3, g);
                                const double fill = dist_mm(comp + (k * 3 + c) * 3, g);
                                oom |= errs_push(&e[0][li], hold) | errs_push(&e[0][LOSSES + set_n[q] - 1], hold);
                                oom |= errs_push(&e[1][li], fill) | errs_push(&e[1][LOSSES + set_n[q] - 1], fill);
                            }
                    }
                }
            }
        }
        if (oom) {
            fprintf(stderr, "%s replay %s: out of memory\n", name, mo->name);
            rc = 1;
        } else if (missing) {
            printf("| %s | - | - | 0 | the motion leaves some landmark missing: skipped | | | |\n", mo->name);
        } else if (!rc) {
            char what[128];
            snprintf(what, sizeof what, "%s (%.1f s at %.0f Hz%s)", mo->name, (double)N / rate, rate,
                     mo->loop ? ", looped" : "");
            for (int g = 0; g < LOSSES + 3; g++) {
                if (g < LOSSES) printf("| %s | %.2g | all | %zu |", g ? mo->name : what, loss_s[g], e[0][g].n);
                else printf("| %s | all | %d | %zu |", mo->name, g - LOSSES + 1, e[0][g].n);
                print_stat(&e[0][g]);
                print_stat(&e[1][g]);
                printf("\n");
            }
            if (at < (int)sizeof far)
                at += snprintf(far + at, sizeof far - (size_t)at, "%s %.0f mm, ", mo->name, far_sum / (double)far_n);
        }
        for (int a = 0; a < 2; a++)
            for (int g = 0; g < LOSSES + 3; g++) free(e[a][g].v);
        free(truth), free(comp);
        mim_vest_sim_close(&sim);
    }
    if (!rc) {
        /* the same for the static bodies of the leave-one-subject-out rows */
        double sum = 0;
        for (uint32_t b = 0; b < nt; b++) sum += nearest_rms(tl + (size_t)b * L * 3, tl, subj, nt, L, subj[b]);
        printf("\nNearest template of another subject (RMS over the %u landmarks after the best similarity, mean "
               "over every 4th replay frame): %sthe static bodies above %.0f mm.\n",
               L, at ? far : "", sum / (nt ? nt : 1));
    }
    free(w);
    return rc;
}

static int run(const char *name, const char *folder, const char *tmp, const motion_t *motions, int nm)
{
    char store[4096];
    snprintf(store, sizeof store, "%s/%s-store", tmp, name);
    mim_db_t *db = NULL;
    mim_error_t err = {0};
    mim_db_options_t o = {0};
    mim_ingest_report_t rep;
    char *paths[1] = {(char *)folder};
    if (mim_db_open(&db, store, &o, &err) || mim_ingest_run(db, paths, 1, NULL, &rep, &err)) {
        fprintf(stderr, "%s: %s\n", name, mim_error_text(&err));
        return 1;
    }
    mim_db_close(&db);
    mim_session_t *s = NULL;
    if (mim_session_open(&s, store, NULL, &err)) {
        fprintf(stderr, "%s: %s\n", name, mim_error_text(&err));
        return 1;
    }
    const mim_landmark_map_t *map = mim_session_map(s);
    const uint32_t L = map->count;
    /* every template's landmarks and subject, from the store */
    mim_db_t *rd = NULL;
    mim_db_options_t ro = {.read_only = 1};
    mim_db_open(&rd, store, &ro, &err);
    mim_db_txn_t *t = NULL;
    mim_db_begin(rd, 0, &t, &err);
    mim_db_meta_t meta;
    mim_db_meta_get(t, &meta, &err);
    uint32_t n = (uint32_t)meta.templates;
    float *truth = malloc((size_t)n * L * 3 * sizeof *truth);
    char (*subject)[64] = malloc((size_t)n * sizeof *subject), (*pose)[64] = malloc((size_t)n * sizeof *pose);
    uint32_t k = 0;
    for (uint64_t id = 1; id < meta.next_id && k < n; id++) {
        mim_template_view_t v;
        if (mim_db_template_get(t, id, &v, NULL)) continue;
        for (uint32_t l = 0; l < L; l++) memcpy(truth + ((size_t)k * L + l) * 3, v.positions + 3 * (size_t)map->vertex[l], 12);
        snprintf(subject[k], 64, "%s", v.subject);
        snprintf(pose[k], 64, "%s", v.pose);
        k++;
    }
    mim_db_abort(&t);
    mim_db_close(&rd);
    n = k;
    /* the triples of lost landmarks */
    uint32_t tri[TRIPLES][3];
    mim_rng_t r;
    mim_rng_seed(&r, 1, 0);
    for (int q = 0; q < TRIPLES; q++) {
        do {
            for (int c = 0; c < 3; c++) tri[q][c] = (uint32_t)mim_rng_below(&r, L);
        } while (tri[q][0] == tri[q][1] || tri[q][0] == tri[q][2] || tri[q][1] == tri[q][2]);
    }
    loso_t lo;
    if (loso_build(&lo, truth, subject, pose, n, L, map)) return 1;
    struct { const char *name; mim_session_complete_options_t o; } rows[] = {
        {"nearest template alone (k 1, no blend)", {.k = 1, .no_blend = 1, .gaussian = -1, .no_local = 1}},
        {"median of k 3, no blend", {.k = 3, .no_blend = 1, .gaussian = -1, .no_local = 1}},
        {"retrieval: median of k 3, Gaussian blend (before issue 29)", {.k = 3, .gaussian = -1, .no_local = 1}},
        {"median of k 8, Gaussian blend", {.k = 8, .gaussian = -1, .no_local = 1}},
        {"median of k 16, Gaussian blend", {.k = 16, .gaussian = -1, .no_local = 1}},
        {"pose classes' conditional mean alone, ends not turned, no local Gaussian", {.gaussian = 1, .no_turn = 1, .no_local = 1}},
        {"retrieval 0.3 + classes 0.7, ends not turned, no local Gaussian (default before)", {.no_turn = 1, .no_local = 1}},
        {"pose classes' conditional mean alone (ends turned), no local Gaussian", {.gaussian = 1, .no_local = 1}},
        {"retrieval 0.3 + classes 0.7, ends turned, no local Gaussian", {.no_local = 1}},
        {"retrieval 0.2 + classes 0.8, ends turned, no local Gaussian", {.gaussian = 0.8, .no_local = 1}},
        {"retrieval k 3 + blend, local Gaussian gated in", {.k = 3, .gaussian = -1}},
        {"retrieval 0.5 + classes 0.5, ends turned, local Gaussian gated in", {.gaussian = 0.5}},
        {"retrieval 0.3 + classes 0.7, ends not turned, local Gaussian gated in", {.no_turn = 1}},
        {"retrieval 0.3 + classes 0.7, ends turned, local Gaussian gated in (default)", {0}},
    };
    const int R = (int)(sizeof rows / sizeof *rows);
    size_t total = (size_t)n * TRIPLES * 3;
    double *e = malloc(total * sizeof *e);
    printf("\n### %s: %u bodies, %d triples of lost landmarks each, leave one subject out\n\n", name, n, TRIPLES);
    printf("| method | mean (mm) | median (mm) | p95 (mm) |\n|---|---|---|---|\n");
    for (int row = 0; row < R; row++) {
        size_t m = 0;
        for (uint32_t b = 0; b < n; b++) {
            mim_session_complete_options_t co = rows[row].o;
            co.exclude_subject = subject[b];
            co.index = loso_find(&lo, subject[b]);
            for (int q = 0; q < TRIPLES; q++) {
                uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
                float in[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX];
                memcpy(in, truth + (size_t)b * L * 3, (size_t)L * 12);
                memset(present, 1, L);
                for (int c = 0; c < 3; c++) present[tri[q][c]] = 0, in[3 * tri[q][c]] = NAN;
                if (mim_session_complete(s, in, present, &co, out, done, &err)) {
                    fprintf(stderr, "%s: %s\n", name, mim_error_text(&err));
                    return 1;
                }
                for (int c = 0; c < 3; c++) {
                    const float *a = out + 3 * tri[q][c], *g = truth + ((size_t)b * L + tri[q][c]) * 3;
                    e[m++] = 1000 * sqrt((a[0] - g[0]) * (a[0] - g[0]) + (a[1] - g[1]) * (a[1] - g[1]) + (a[2] - g[2]) * (a[2] - g[2]));
                }
            }
        }
        double sum = 0;
        for (size_t i = 0; i < m; i++) sum += e[i];
        qsort(e, m, sizeof *e, cmp_d);
        printf("| %s | %.1f | %.1f | %.1f |\n", rows[row].name, sum / m, e[m / 2], e[(size_t)(0.95 * (m - 1))]);
    }
    free(e);
    int rc = replay(s, store, name, motions, nm, truth, subject, n, &lo);
    loso_free(&lo);
    free(truth), free(subject), free(pose);
    mim_session_close(&s);
    return rc;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i)) continue;
        if (!strcmp(argv[i], "--proportions") && i + 1 < argc) {
            body_proportions = !strcmp(argv[++i], "body");
            continue;
        }
        fprintf(stderr,
                "usage: %s [--vertices N] [--mh DIR | --no-mh] [--imitation DEG | --no-imitation] "
                "[--proportions canonical|body]\n",
                argv[0]);
        return 2;
    }
    mim_error_t err = {0};
    const char *mh = NULL;
    if (!sets.no_mh) mh = sets.mh ? sets.mh : bench_mh_dir(sets.mh_buf, sizeof sets.mh_buf);
    /* the replay's motions: the built-in demo; with the shared data (the
     * folder that holds mh-bodies) a walk cycle, looped, and a CMU take */
    motion_t motions[3];
    int nm = 0;
    memset(motions, 0, sizeof motions);
    if (mim_vest_motion_demo(&motions[nm].m, &err)) {
        fprintf(stderr, "bench_complete: demo motion: %s\n", mim_error_text(&err));
        return 1;
    }
    snprintf(motions[nm++].name, sizeof motions[0].name, "demo");
    if (mh && access(mh, R_OK) == 0) {
        char root[4096], a[4200], b[4200];
        snprintf(root, sizeof root, "%s/..", mh);
        snprintf(a, sizeof a, "%s/makehuman-motion/animations/zombieWalk1.bvh", root);
        if (access(a, R_OK)) printf("\n(%s not found: that replay is skipped)\n", a);
        else if (mim_vest_motion_read_bvh(&motions[nm].m, a, &err)) fprintf(stderr, "bench_complete: %s\n", mim_error_text(&err));
        else snprintf(motions[nm].name, sizeof motions[0].name, "zombieWalk1.bvh"), motions[nm++].loop = 1;
        snprintf(a, sizeof a, "%s/cmu-mocap/20.asf", root);
        snprintf(b, sizeof b, "%s/cmu-mocap/20_11.amc", root);
        if (access(a, R_OK) || access(b, R_OK)) printf("\n(%s not found: that replay is skipped)\n", b);
        else if (mim_vest_motion_read_amc(&motions[nm].m, a, b, &err)) fprintf(stderr, "bench_complete: %s\n", mim_error_text(&err));
        else snprintf(motions[nm++].name, sizeof motions[0].name, "cmu 20_11.amc");
    }
    char tmp[] = "/tmp/mimic-bench-complete-XXXXXX";
    if (!mkdtemp(tmp)) return 1;
    /* synth: 6 subjects x 12 poses, written as files and ingested */
    char synth_dir[4096];
    snprintf(synth_dir, sizeof synth_dir, "%s/synth", tmp);
    mim_synth_t *sy = NULL;
    mim_synth_options_t so = {.subjects = 6, .poses = 12, .vertices = sets.vertices, .seed = 1};
    int rc = mim_synth_create(&sy, &so, &err) || mim_synth_write_dataset(sy, synth_dir, &err);
    mim_synth_destroy(&sy);
    if (rc || run("synth", synth_dir, tmp, motions, nm)) rc = 1;
    if (!rc && sets.imitation_deg > 0) { /* the same subjects, each imitating each pose its own way (issue 29) */
        snprintf(synth_dir, sizeof synth_dir, "%s/imitation", tmp);
        so.imitation_deg = sets.imitation_deg, so.tissue_mm = BENCH_TISSUE_MM, so.slide_mm = BENCH_SLIDE_MM;
        rc = mim_synth_create(&sy, &so, &err) || mim_synth_write_dataset(sy, synth_dir, &err);
        mim_synth_destroy(&sy);
        if (rc || run("imitation", synth_dir, tmp, motions, nm)) rc = 1;
    }
    if (!rc && !sets.no_mh) {
        if (mh && access(mh, R_OK) == 0) rc = run("mh-bodies", mh, tmp, motions, nm);
        else printf("\n(mh-bodies not found: skipped)\n");
    }
    for (int i = 0; i < nm; i++) mim_vest_motion_free(&motions[i].m);
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd)) fprintf(stderr, "bench_complete: could not remove %s\n", tmp);
    return rc;
}
