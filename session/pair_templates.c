/* Sampled pose-pairs become templates of the store (mim_session_pairs.h;
 * issue 14, seed 002's purpose in mimic): each person of a sample drives a
 * transfer of the avatar through the session's one pipeline, landmarks
 * mode (seed 000, Section 3.4: the nearest template's frames, the
 * landmarks held); the results go into the store as templates with their
 * encodings (seed 000, Section 3.1), in one transaction, and the
 * recognition index is rebuilt.
 *
 * The store's LMDB environment is opened once at a time in a process
 * (LMDB: never twice at once in one process), so the work runs in steps:
 * the session (read-only) computes every result into a temporary file;
 * the caller closes it; the store is opened for writing, the results go
 * in and are committed together; then the index is rebuilt.
 *
 * Pose labels are the index's classes (index/mim_index.h). A label of its
 * own for each sampled person makes one-template classes, which the
 * per-class SVMs recognise poorly and which make every rebuild slow (synth
 * store of 12, 100 pose-pairs: 78 of the 200 people found their own
 * template through mimic query, and the index took 60 s; with the class
 * label 198 of 200, and 3 s). So by default a sampled template joins the
 * class the index gives the person's own joints (those mimic query is
 * given to find it again; its classes see the bodies' proportions, so not
 * the landmarks retargeted onto the avatar's), and its source says where
 * it came from. */
#include "mim_session_pairs.h"

#include "internal.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One person to store: where it came from, what the transfer gave. */
typedef struct {
    uint32_t sample; /* index into the samples */
    long line;       /* its line in the file */
    char person;     /* 'a' or 'b' */
    uint32_t cls;    /* the pose class of its own joints, in classes_t */
    uint64_t id;     /* its template once stored (0: a duplicate, or not yet) */
} item_t;

/* The pose classes the index gave, each name once (there are few). */
typedef struct {
    char (*name)[MIM_SESSION_LABEL_MAX];
    uint32_t n, cap;
} classes_t;

struct mim_session_pairs {
    const mim_session_t *s;     /* prepared on */
    mim_progress_t *progress;
    char *origin;
    uint32_t n_samples, n, nl;  /* samples, people, landmarks a person */
    uint32_t n_vertices;        /* of each body */
    uint32_t features;          /* the index's angles, kept by the rebuild */
    int proportions;            /* the index's proportions (MIM_INDEX_PROPORTIONS_*), kept too */
    int labelled;               /* the index's classes are pose labels (not k-means clusters) */
    item_t *items;              /* n */
    float *lm;                  /* n * 3 * nl */
    float *own;                 /* n * 3 * nl: each person's own joints, the map's landmarks */
    FILE *spool;                /* the bodies, 3 * n_vertices floats each, once transferred */
    int stored;
    classes_t classes;
    uint64_t *ids;              /* the stored ones */
};

/* The index of name in c, added if new; -1 when out of memory. */
static long class_of(classes_t *c, const char *name)
{
    for (uint32_t k = 0; k < c->n; k++)
        if (!strcmp(c->name[k], name)) return (long)k;
    if (c->n == c->cap) {
        uint32_t cap = c->cap ? 2 * c->cap : 16;
        void *grown = realloc(c->name, (size_t)cap * sizeof *c->name);
        if (!grown) return -1;
        c->name = grown, c->cap = cap;
    }
    snprintf(c->name[c->n], sizeof c->name[0], "%s", name);
    return (long)c->n++;
}

/* The body's own left, horizontal (x, z with +Y up), from its hips and
 * shoulders; 0 when they lie along the vertical (no facing to take). */
static int left_of(const double *lh, const double *rh, const double *ls, const double *rs, double *x, double *z)
{
    *x = lh[0] - rh[0] + ls[0] - rs[0];
    *z = lh[2] - rh[2] + ls[2] - rs[2];
    return hypot(*x, *z) > 0.01; /* a few centimetres across hips and shoulders */
}

typedef struct {
    const mim_landmark_map_t *map;
    uint32_t nl;
    int idx[MIM_LANDMARKS_MAX]; /* store landmark -> sample joint */
    const float *rest;          /* the avatar's rest positions (3 * n) */
    float *scratch;             /* 3 * n: the person's landmarks at their vertices, for retargeting */
    int retarget;
    int turn;                   /* the avatar has hips and shoulders: turn each person to its facing */
    double avatar_left[2];      /* its horizontal left (x, z) */
    double avatar_centre[3];    /* the centre of its rest landmarks */
} prep_t;

/* The avatar's facing and centre, from its rest landmarks; the map's
 * landmarks as sample joints (all there: mim_session_pairs_check). */
static int prep_init(prep_t *pp, const mim_session_t *s, int retarget, mim_error_t *err)
{
    *pp = (prep_t){.map = mim_session_map(s), .nl = mim_session_map(s)->count, .retarget = retarget};
    const uint32_t n = mim_session_mesh(s)->n_vertices;
    for (uint32_t l = 0; l < pp->nl; l++) pp->idx[l] = mim_sample_joint_index(pp->map->names[l]);
    pp->rest = mim_session_mesh(s)->positions;
    pp->scratch = retarget ? calloc(3 * (size_t)n, sizeof *pp->scratch) : NULL;
    if (retarget && !pp->scratch) return mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
    for (uint32_t l = 0; l < pp->nl; l++)
        for (int k = 0; k < 3; k++) pp->avatar_centre[k] += pp->rest[3 * (size_t)pp->map->vertex[l] + k] / (double)pp->nl;
    int lh = mim_landmarks_find(pp->map, "l_hip"), rh = mim_landmarks_find(pp->map, "r_hip"),
        ls = mim_landmarks_find(pp->map, "l_shoulder"), rs = mim_landmarks_find(pp->map, "r_shoulder");
    if (lh >= 0 && rh >= 0 && ls >= 0 && rs >= 0) {
        double at[4][3];
        const int which[4] = {lh, rh, ls, rs};
        for (int q = 0; q < 4; q++)
            for (int k = 0; k < 3; k++) at[q][k] = pp->rest[3 * (size_t)pp->map->vertex[which[q]] + k];
        pp->turn = left_of(at[0], at[1], at[2], at[3], &pp->avatar_left[0], &pp->avatar_left[1]);
    }
    return 0;
}

/* The landmarks that pose the avatar for one person (joints: 17 x 3
 * doubles, metres): checked as every landmark input is, turned to the
 * avatar's facing, retargeted (when asked), moved onto the avatar, and
 * checked again. origin "FILE:LINE: person a" names it in errors. */
static int person_landmarks(const prep_t *pp, const double *joints, const char *origin, float *out, mim_error_t *err)
{
    const uint32_t nl = pp->nl;
    float raw[3 * MIM_LANDMARKS_MAX];
    for (uint32_t l = 0; l < nl; l++)
        for (int c = 0; c < 3; c++) raw[3 * l + c] = (float)joints[3 * pp->idx[l] + c];
    int rc = mim_landmarks_check(raw, NULL, nl, origin, -1, err);
    if (rc) return rc;
    /* turned about +Y through its centre: the template's frames then start
     * close to the pose (the descriptor's angles do not change) */
    double centre[3] = {0, 0, 0}, sx, sz, c = 1.0, s = 0.0;
    for (uint32_t l = 0; l < nl; l++)
        for (int k = 0; k < 3; k++) centre[k] += raw[3 * l + k] / (double)nl;
    const double *j = joints;
    if (pp->turn && left_of(j + 3 * mim_sample_joint_index("l_hip"), j + 3 * mim_sample_joint_index("r_hip"),
                            j + 3 * mim_sample_joint_index("l_shoulder"),
                            j + 3 * mim_sample_joint_index("r_shoulder"), &sx, &sz)) {
        double phi = atan2(pp->avatar_left[1], pp->avatar_left[0]) - atan2(sz, sx);
        c = cos(phi), s = sin(phi);
    }
    for (uint32_t l = 0; l < nl; l++) {
        double x = raw[3 * l] - centre[0], z = raw[3 * l + 2] - centre[2];
        out[3 * l] = (float)(centre[0] + c * x - s * z);
        out[3 * l + 1] = raw[3 * l + 1];
        out[3 * l + 2] = (float)(centre[2] + s * x + c * z);
    }
    if (pp->retarget) {
        for (uint32_t l = 0; l < nl; l++)
            memcpy(pp->scratch + 3 * (size_t)pp->map->vertex[l], out + 3 * l, 3 * sizeof *out);
        if ((rc = mim_xfer_retarget_landmarks(pp->map, pp->rest, pp->scratch, out, err))) return rc;
    }
    double now[3] = {0, 0, 0};
    for (uint32_t l = 0; l < nl; l++)
        for (int k = 0; k < 3; k++) now[k] += out[3 * l + k] / (double)nl;
    for (uint32_t l = 0; l < nl; l++)
        for (int k = 0; k < 3; k++) out[3 * l + k] = (float)(out[3 * l + k] + pp->avatar_centre[k] - now[k]);
    char what[4300]; /* origin is at most 4200 */
    snprintf(what, sizeof what, "%s (%s)", origin,
             pp->retarget ? "on the avatar's proportions" : "moved onto the avatar");
    return mim_landmarks_check(out, NULL, nl, what, -1, err);
}

/* The pose class index ix gives a person's own joints (own: the map's
 * landmarks as the sample holds them), as a name (valid while ix lives;
 * "" where the classes are not pose labels); who names the person in
 * errors. */
static int person_class(const mim_index_t *ix, int labelled, const float *own, const char *who, const char **name,
                        mim_error_t *err)
{
    mim_index_answer_t ans;
    mim_index_hit_t hit;
    mim_error_t e = {0};
    int rc = mim_index_query(ix, own, NULL, NULL, &ans, &hit, &e);
    if (rc) return mim_error_set(err, rc, "%s: its pose class: %s", who, mim_error_text(&e));
    *name = labelled ? mim_index_class_name(ix, ans.cls) : "";
    return 0;
}

int mim_session_pairs_prefix_ok(const char *p)
{
    if (!p || strlen(p) > MIM_SESSION_PAIRS_PREFIX_MAX) return 0;
    for (; *p; p++)
        if (*p <= ' ' || *p > '~' || *p == '/') return 0;
    return 1;
}

int mim_session_pairs_check(const mim_session_t *s, mim_error_t *err)
{
    const char *store = mim_session_store(s);
    if (!mim_session_query(s)) return mim_error_set(err, MIM_ENOINDEX, "%s: store has no index (run mimic index)", store);
    const mim_landmark_map_t *map = mim_session_map(s);
    for (uint32_t l = 0; l < map->count; l++)
        if (mim_sample_joint_index(map->names[l]) < 0)
            return mim_error_set(err, MIM_EUNSUPPORTED, "%s: the store's landmark '%s' is not a joint of pose-pair "
                                                        "samples (head, chest, pelvis, ..., spine, neck)",
                                 store, map->names[l]);
    return 0;
}

void mim_session_pairs_free(mim_session_pairs_t **pp)
{
    mim_session_pairs_t *p = pp ? *pp : NULL;
    if (!p) return;
    if (p->spool) fclose(p->spool);
    free(p->origin), free(p->items), free(p->lm), free(p->own), free(p->classes.name), free(p->ids);
    free(p);
    *pp = NULL;
}

int mim_session_pairs_prepare(mim_session_t *s, const mim_pairs_samples_t *smp,
                              const mim_session_pairs_options_t *opt, mim_session_pairs_t **out, mim_error_t *err)
{
    *out = NULL;
    static const mim_session_pairs_options_t defaults = {0};
    if (!opt) opt = &defaults;
    const char *origin = opt->origin ? opt->origin : "samples";
    const unsigned persons = opt->persons ? opt->persons : MIM_SESSION_PAIRS_PERSON_A | MIM_SESSION_PAIRS_PERSON_B;
    if (!s->solver) return mim_error_set(err, MIM_EINVAL, "%s: pose-pairs: no avatar loaded", s->store);
    if (persons & ~(MIM_SESSION_PAIRS_PERSON_A | MIM_SESSION_PAIRS_PERSON_B))
        return mim_error_set(err, MIM_EINVAL, "pose-pairs: persons %#x: person a (1), b (2) or both", persons);
    if (!smp || !smp->n || !smp->joints) return mim_error_set(err, MIM_EINVAL, "%s: no samples", origin);
    int rc = mim_session_pairs_check(s, err);
    if (rc) return rc;
    mim_session_pairs_t *p = calloc(1, sizeof *p);
    prep_t pp = {0};
    const uint32_t n_samples = opt->max && opt->max < smp->n ? opt->max : smp->n;
    const uint32_t per = persons == (MIM_SESSION_PAIRS_PERSON_A | MIM_SESSION_PAIRS_PERSON_B) ? 2 : 1;
    if (p) {
        *p = (mim_session_pairs_t){.s = s, .progress = opt->progress, .n_samples = n_samples, .n = n_samples * per,
                                   .nl = mim_session_map(s)->count, .n_vertices = mim_session_mesh(s)->n_vertices,
                                   .features = mim_session_index_status(s)->built.d,
                                   .labelled = mim_session_index_status(s)->built.class_source == MIM_CLASSES_LABELS};
        mim_index_info_t info;
        mim_index_get_info(mim_query_index(mim_session_query(s)), &info);
        p->proportions = info.canonical ? MIM_INDEX_PROPORTIONS_CANONICAL : MIM_INDEX_PROPORTIONS_BODY;
        p->origin = strdup(origin);
        p->items = calloc(p->n, sizeof *p->items);
    }
    if (!p || !p->origin || !p->items) {
        rc = mim_error_set(err, MIM_ENOMEM, "out of memory for %u samples", n_samples);
        goto done;
    }
    for (uint32_t i = 0, k = 0; i < n_samples; i++)
        for (int q = 0; q < 2; q++)
            if (persons & (1u << q))
                p->items[k++] = (item_t){.sample = i, .line = smp->line ? smp->line[i] : 2 + (long)i,
                                         .person = (char)('a' + q)};
    /* every person's landmarks first: a bad sample stops the run before
     * any transfer */
    if ((rc = prep_init(&pp, s, !opt->sample_proportions, err))) goto done;
    if (!(p->lm = malloc((size_t)p->n * 3 * p->nl * sizeof *p->lm)) ||
        !(p->own = malloc((size_t)p->n * 3 * p->nl * sizeof *p->own))) {
        rc = mim_error_set(err, MIM_ENOMEM, "out of memory for %u people's landmarks", p->n);
        goto done;
    }
    for (uint32_t i = 0; i < p->n && !rc; i++) {
        item_t *it = &p->items[i];
        char who[4200];
        snprintf(who, sizeof who, "%s:%ld: person %c", origin, it->line, it->person);
        const double *joints = smp->joints + (size_t)it->sample * 3 * MIM_PAIR_JOINTS +
                               (it->person == 'b' ? 3 * MIM_PAIR_PERSON_JOINTS : 0);
        rc = person_landmarks(&pp, joints, who, p->lm + (size_t)i * 3 * p->nl, err);
        float *own = p->own + (size_t)i * 3 * p->nl;
        for (uint32_t l = 0; l < p->nl; l++)
            for (int k = 0; k < 3; k++) own[3 * l + k] = (float)joints[3 * pp.idx[l] + k];
        const char *name = NULL;
        if (!rc) rc = person_class(mim_query_index(mim_session_query(s)), p->labelled, own, who, &name, err);
        long k = rc ? 0 : class_of(&p->classes, name);
        if (k < 0) rc = mim_error_set(err, MIM_ENOMEM, "out of memory");
        it->cls = (uint32_t)k;
    }
done:
    free(pp.scratch);
    if (rc) mim_session_pairs_free(&p);
    *out = p;
    return rc;
}

uint32_t mim_session_pairs_count(const mim_session_pairs_t *p, uint32_t *samples)
{
    if (samples) *samples = p->n_samples;
    return p->n;
}

int mim_session_pairs_person(const mim_session_pairs_t *p, uint32_t i, mim_session_pairs_person_t *out)
{
    if (i >= p->n) return MIM_EINVAL;
    const item_t *it = &p->items[i];
    *out = (mim_session_pairs_person_t){.sample = it->sample, .line = it->line, .person = it->person,
                                        .landmarks = p->lm + (size_t)i * 3 * p->nl,
                                        .pose_class = p->spool ? p->classes.name[it->cls] : NULL,
                                        .id = p->stored ? it->id : 0};
    return 0;
}

int mim_session_pairs_transfer(mim_session_t *s, mim_session_pairs_t *p, mim_error_t *err)
{
    if (p->s != s) return mim_error_set(err, MIM_EINVAL, "pose-pairs: transfer on another session than prepared");
    if (p->spool) return mim_error_set(err, MIM_EINVAL, "pose-pairs: transferred already");
    const uint32_t n = p->n_vertices;
    float *out = malloc(3 * (size_t)n * sizeof *out);
    if (!out) return mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
    if (!(p->spool = tmpfile())) {
        free(out);
        return mim_error_set(err, MIM_EIO, "cannot make a temporary file for the results (TMPDIR)");
    }
    mim_progress_t quiet = {0}, *pr = p->progress ? p->progress : &quiet;
    mim_progress_begin(pr, "transfer", p->n);
    int rc = 0;
    for (uint32_t i = 0; i < p->n && !rc; i++) {
        const item_t *it = &p->items[i];
        mim_session_request_t req = {.landmarks = p->lm + (size_t)i * 3 * p->nl};
        mim_session_report_t rep;
        mim_error_t e = {0};
        if ((rc = mim_session_transfer(s, &req, out, &rep, &e)) ||
            (rc = mim_body_check(out, n, "transfer result", &e)))
            mim_error_set(err, rc, "%s:%ld: person %c: %s", p->origin, it->line, it->person, mim_error_text(&e));
        else if (fwrite(out, sizeof *out, 3 * (size_t)n, p->spool) != 3 * (size_t)n)
            rc = mim_error_set(err, MIM_EIO, "cannot write the results to a temporary file (is the disk full?)");
        mim_progress_update(pr, i + 1);
    }
    mim_progress_end(pr);
    free(out);
    if (rc) fclose(p->spool), p->spool = NULL; /* no results: not transferred */
    return rc;
}

int mim_session_pairs_body(mim_session_pairs_t *p, uint32_t i, float *positions, mim_error_t *err)
{
    if (!p->spool || i >= p->n)
        return mim_error_set(err, MIM_EINVAL, "pose-pairs: no body %u (%u people%s)", i, p->n,
                             p->spool ? "" : ", not transferred");
    const size_t each = 3 * (size_t)p->n_vertices;
    if (fseeko(p->spool, (off_t)(i * each * sizeof *positions), SEEK_SET) ||
        fread(positions, sizeof *positions, each, p->spool) != each)
        return mim_error_set(err, MIM_EIO, "cannot read the results back from their temporary file");
    return 0;
}

/* A class name of the index without the dataset the pose will be stored
 * under ("ds/pose" where the store holds several datasets: the index's
 * names are qualified, mim_db_labels_qualify). */
static const char *unqualified(const char *cls, const char *dataset)
{
    size_t l = strlen(dataset);
    return l && !strncmp(cls, dataset, l) && cls[l] == '/' ? cls + l + 1 : cls;
}

/* The results into the store, one transaction; ids gets the new
 * templates' ids, added and dup the counts. */
static int store_all(mim_session_pairs_t *p, const char *store, const mim_session_pairs_store_options_t *opt,
                     uint32_t *added, uint32_t *dup, mim_error_t *err)
{
    const uint32_t n = p->n_vertices;
    const char *source = opt->source ? opt->source : p->origin, *prefix = opt->label_prefix;
    mim_db_t *db = NULL;
    mim_db_txn_t *t = NULL;
    mim_xfer_topology_t *topo = NULL;
    mim_db_options_t o = opt->db ? *opt->db : (mim_db_options_t){0};
    float *pos = malloc(12 * (size_t)n * sizeof *pos); /* positions, frames (6n), W (3n) */
    double *work = malloc(12 * (size_t)n * sizeof *work);
    char *subject = NULL, *dataset = NULL;
    int rc = pos && work ? 0 : mim_error_set(err, MIM_ENOMEM, "out of memory for %u vertices", n);
    if (!rc) rc = mim_db_open(&db, store, &o, err);
    if (!rc) rc = mim_db_begin(db, 1, &t, err);
    mim_db_topology_t tp;
    if (!rc) rc = mim_db_topology_get(t, &tp, err);
    if (!rc && tp.n_vertices != n)
        rc = mim_error_set(err, MIM_ETOPOLOGY, "%s: its connectivity changed while the transfers ran (%u vertices, "
                                               "not %u): nothing stored", store, tp.n_vertices, n);
    if (!rc) rc = mim_xfer_topology_open(&topo, tp.n_vertices, tp.faces, tp.n_faces, err);
    mim_template_view_t av;
    /* the avatar's subject of the avatar's dataset: the bodies are that person's */
    if (!rc && (rc = mim_db_template_get(t, opt->avatar_id, &av, err)) == 0 &&
        (!(subject = strdup(av.subject)) || !(dataset = strdup(av.dataset))))
        rc = mim_error_set(err, MIM_ENOMEM, "out of memory");
    if (rc) goto done;
    rewind(p->spool);
    mim_progress_t quiet = {0}, *pr = p->progress ? p->progress : &quiet;
    mim_progress_begin(pr, "store", p->n);
    mim_error_t e = {0}; /* a write's or the commit's, said with "nothing stored" */
    for (uint32_t i = 0; i < p->n && !rc; i++) {
        const item_t *it = &p->items[i];
        if (fread(pos, sizeof *pos, 3 * (size_t)n, p->spool) != 3 * (size_t)n) {
            rc = mim_error_set(&e, MIM_EIO, "cannot read the results back from their temporary file");
            break;
        }
        char pose[MIM_SESSION_LABEL_MAX + MIM_SESSION_PAIRS_PREFIX_MAX + 32], src[PATH_MAX + 64];
        if (prefix) snprintf(pose, sizeof pose, "%s%ld-%c", prefix, it->line, it->person);
        else snprintf(pose, sizeof pose, "%s", unqualified(p->classes.name[it->cls], dataset));
        snprintf(src, sizeof src, "sampled:%s:%ld:%c", source, it->line, it->person);
        mim_template_in_t tin = {pos, n, mim_db_content_hash(pos, n), src, subject, pose, dataset};
        uint64_t id;
        int existed;
        float *frames6 = pos + 3 * (size_t)n, *W = pos + 9 * (size_t)n;
        if ((rc = mim_db_template_put(t, &tin, &id, &existed, &e))) break;
        p->items[i].id = existed ? 0 : id;
        if (existed) {
            (*dup)++;
        } else {
            if ((rc = mim_xfer_encoding_compute(topo, pos, frames6, W, work, &e)) ||
                (rc = mim_db_encoding_put(t, id, frames6, W, n, &e)))
                break;
            p->ids[(*added)++] = id;
        }
        mim_progress_update(pr, i + 1);
    }
    mim_progress_end(pr);
    if (!rc) rc = mim_db_commit(&t, &e);
    if (rc) mim_error_set(err, rc, "%s: nothing stored", mim_error_text(&e));
done:
    mim_db_abort(&t); /* after a failure: nothing half-written */
    mim_db_close(&db);
    mim_xfer_topology_close(&topo);
    free(pos), free(work), free(subject), free(dataset);
    return rc;
}

/* Labels that hold: the rebuilt index learns its classes from the new
 * templates too, so the class it gives a person's own joints can move
 * from the one it gave before they joined (their label). Each person
 * whose class moved takes the new one, and the index is built again,
 * until none moves or after MIM__PAIRS_SETTLE_ROUNDS rebuilds (each costs
 * an index build). report's relabelled counts the labels changed, its
 * index is the last build's. */
#define MIM__PAIRS_SETTLE_ROUNDS 6
static int settle_labels(mim_session_pairs_t *p, mim_db_t *db, const mim_index_options_t *io,
                         mim_session_pairs_report_t *report, mim_error_t *err)
{
    uint32_t *moved_to = malloc(sizeof *moved_to * (p->n ? p->n : 1));
    if (!moved_to) return mim_error_set(err, MIM_ENOMEM, "out of memory for %u people", p->n);
    int rc = 0;
    for (int round = 0; round < MIM__PAIRS_SETTLE_ROUNDS && !rc; round++) {
        mim_query_t *q = NULL;
        uint32_t n_moved = 0;
        if ((rc = mim_query_open(&q, db, err))) break;
        for (uint32_t i = 0; i < p->n && !rc; i++) {
            const item_t *it = &p->items[i];
            moved_to[i] = it->cls;
            if (!it->id) continue;
            char who[4200];
            snprintf(who, sizeof who, "%s:%ld: person %c", p->origin, it->line, it->person);
            const char *name = "";
            rc = person_class(mim_query_index(q), p->labelled, p->own + (size_t)i * 3 * p->nl, who, &name, err);
            const long k = rc || !strcmp(name, p->classes.name[it->cls]) ? (long)it->cls : class_of(&p->classes, name);
            if (k < 0) rc = mim_error_set(err, MIM_ENOMEM, "out of memory");
            else if ((uint32_t)k != it->cls) moved_to[i] = (uint32_t)k, n_moved++;
        }
        mim_query_close(&q);
        if (rc || !n_moved) break;
        mim_db_txn_t *t = NULL;
        rc = mim_db_begin(db, 1, &t, err);
        for (uint32_t i = 0; i < p->n && !rc; i++) {
            if (moved_to[i] == p->items[i].cls) continue;
            mim_template_view_t v; /* its dataset: the label is stored without it, as store_all does */
            if ((rc = mim_db_template_get(t, p->items[i].id, &v, err))) break;
            const char *label = unqualified(p->classes.name[moved_to[i]], v.dataset);
            rc = mim_db_template_relabel(t, p->items[i].id, label, err);
        }
        if (!rc) rc = mim_db_commit(&t, err);
        mim_db_abort(&t);
        if (rc) break;
        for (uint32_t i = 0; i < p->n; i++) p->items[i].cls = moved_to[i];
        report->relabelled += n_moved;
        rc = mim_query_build_index(db, io, &report->index, err);
    }
    free(moved_to);
    return rc;
}

int mim_session_pairs_store(mim_session_pairs_t *p, const char *store, const mim_session_pairs_store_options_t *opt,
                            mim_session_pairs_report_t *report, mim_error_t *err)
{
    memset(report, 0, sizeof *report);
    if (!opt) return mim_error_set(err, MIM_EINVAL, "pose-pairs: store without options (the avatar's id)");
    if (!p->spool) return mim_error_set(err, MIM_EINVAL, "pose-pairs: store before the transfer");
    if (p->stored) return mim_error_set(err, MIM_EINVAL, "pose-pairs: stored already");
    if (opt->label_prefix && !mim_session_pairs_prefix_ok(opt->label_prefix))
        return mim_error_set(err, MIM_EINVAL, "pose-pairs: label prefix '%s': at most %d printable characters, no "
                                              "space or '/'", opt->label_prefix, MIM_SESSION_PAIRS_PREFIX_MAX);
    if (!p->ids && !(p->ids = calloc(p->n, sizeof *p->ids)))
        return mim_error_set(err, MIM_ENOMEM, "out of memory for %u samples", p->n_samples);
    report->ids = p->ids;
    int rc = store_all(p, store, opt, &report->added, &report->duplicates, err);
    if (rc) return rc; /* nothing stored: may be tried again */
    p->stored = 1;

    /* the index, as mimic index builds it, with the angles the store's had */
    mim_db_t *db = NULL;
    mim_db_options_t o = opt->db ? *opt->db : (mim_db_options_t){0};
    mim_index_options_t io = {.features = p->features, .proportions = p->proportions, .progress = p->progress};
    mim_error_t e = {0};
    rc = mim_db_open(&db, store, &o, &e);
    if (!rc) rc = mim_query_build_index(db, &io, &report->index, &e);
    if (!rc && p->labelled && !opt->label_prefix) rc = settle_labels(p, db, &io, report, &e);
    mim_db_close(&db);
    if (rc)
        mim_error_set(err, rc, "%u templates stored, but the index was not rebuilt: %s (run mimic index)",
                      report->added, mim_error_text(&e));
    return rc;
}
