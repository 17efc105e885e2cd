/* mimic pairs templates: sampled pose-pairs become templates (issue 14,
 * seed 002's purpose in mimic: the store grows by the poses it samples).
 * Each person of a sample drives a transfer of the avatar (a template of
 * the store) through the session's one pipeline, landmarks mode (seed 000,
 * Section 3.4: the nearest template's frames, the landmarks held); the
 * results go into the store as templates with their encodings, in one
 * transaction, and the recognition index is rebuilt. JSON report:
 * schemas/pairs-templates.schema.json.
 *
 * The store's LMDB environment is opened once at a time in this process
 * (LMDB: never twice at once in one process), so the work runs in phases:
 * the session (read-only) computes every result into a temporary file;
 * it is closed; the store is opened for writing, the results go in and
 * are committed together; then the index is rebuilt.
 *
 * Pose labels are the index's classes (index/mim_index.h). A label of its
 * own for each sampled person makes one-template classes, which the
 * per-class SVMs recognise poorly and which make every rebuild slow (synth
 * store of 12, 100 pose-pairs: 78 of the 200 people found their own
 * template through mimic query, and the index took 60 s; with the class
 * label 198 of 200, and 3 s). So by default a sampled template joins the
 * class the index gives its landmarks, and its source says where it came
 * from. */
#include "args.h"
#include "commands.h"
#include "mim_db.h"
#include "mim_query.h"
#include "mim_sample.h"
#include "mim_session.h"
#include "mim_transfer.h"
#include "output.h"

#include <getopt.h>
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CMD "pairs templates"
#define PREFIX_MAX 48

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic pairs templates --store DIR --samples SAMPLES.jsonl --avatar ID [--max N]\n"
            "                             [--person a|b|both] [--proportions avatar|sample]\n"
            "                             [--pose-label class|sample [--label-prefix P]] [--json]\n\n"
            "Sampled pose-pairs become templates of the store. For each sample of SAMPLES\n"
            "(schemas/pair-samples.md; metres, +Y up) and each person in it, the person's joints\n"
            "give the store's landmarks (matched by name: head, chest, ..., spine, neck), which\n"
            "pose the avatar as mimic transfer --landmarks does (the nearest template's frames,\n"
            "the landmarks held). Each result is stored as a new template: subject the avatar's,\n"
            "source sampled:SAMPLES:LINE:PERSON (e.g. sampled:/data/s.jsonl:12:a: line 12, person a),\n"
            "pose label the pose class the index gives the person (see --pose-label). All of them\n"
            "are committed in one transaction, then the recognition index is rebuilt (with the same\n"
            "number of angles), so that mimic query recognises the new poses.\n\n"
            "Before the transfer each person is turned about +Y to face the avatar's way (its\n"
            "hips and shoulders) and moved onto the avatar (the centres of their landmarks\n"
            "coincide); with --proportions avatar (default) each segment of the landmark skeleton\n"
            "keeps the sample's direction and takes the avatar's length (joints of a motion\n"
            "capture skeleton are not the avatar's surface landmarks; as mimic transfer --template\n"
            "does); sample holds the sample's joints as they are.\n\n"
            "  --store DIR           the template store; it needs its index (mimic index)\n"
            "  --samples FILE        pose-pair samples, JSON lines (mimic pairs sample, pairs export)\n"
            "  --avatar ID           the template (mimic list) that takes each sampled pose\n"
            "  --max N               the first N samples (default: all)\n"
            "  --person a|b|both     which person of each sample (default both)\n"
            "  --proportions WHICH   avatar (default) or sample (above)\n"
            "  --pose-label WHICH    class (default): the pose class the index gives the person's\n"
            "                        landmarks (its nearest template's pose label; none in a store\n"
            "                        whose index clusters by k-means), so that a sampled pose joins\n"
            "                        the class it resembles; sample: P LINE-PERSON (sampled-12-a),\n"
            "                        one pose class per person: the index then trains an SVM for\n"
            "                        each, which is slow and recognises such one-template classes\n"
            "                        poorly (a query often lands in an old class)\n"
            "  --label-prefix P      P for --pose-label sample (default \"sampled-\"; up to %d\n"
            "                        printable characters, no space or '/'); implies it\n"
            "  --json                {\"templates\": n, \"ids\": [...], \"duplicates\": d, \"seconds\": s}\n"
            "                        on stdout (schemas/pairs-templates.schema.json)\n"
            "  -h, --help            this help\n\n"
            "A result equal to a stored template is not stored twice (counted as a duplicate).\n"
            "Nothing is stored unless every selected person is transferred.\n"
            "Exit status: 0 done, 1 an input failed (the samples file, a sample's landmarks, an\n"
            "unknown avatar id, a transfer), 2 bad usage or the command could not run (the store,\n"
            "its index).\n",
            PREFIX_MAX);
}

/* One person to store: where it came from, what the transfer gave. */
typedef struct {
    uint32_t sample; /* index into the parsed samples */
    long line;       /* its line in the file */
    char person;     /* 'a' or 'b' */
    uint32_t cls;    /* the pose class of its landmarks, in classes_t */
} item_t;

/* The pose classes the index gave, each name once (there are few). */
typedef struct {
    char (*name)[MIM_SESSION_LABEL_MAX];
    uint32_t n, cap;
} classes_t;

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

/* The file line of each of the first n samples: the parser's rule
 * (samples_file.c), blank lines skipped, the first other line the header. */
static void sample_lines(const char *text, size_t len, uint32_t n, long *lines)
{
    const char *p = text, *end = text + len;
    long line_no = 0;
    uint32_t k = 0;
    int header = 0;
    while (p < end && k < n) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t m = nl ? (size_t)(nl - p) : (size_t)(end - p);
        line_no++;
        size_t i = 0;
        while (i < m && (p[i] == ' ' || p[i] == '\t' || p[i] == '\r')) i++;
        if (i < m) {
            if (header) lines[k++] = line_no;
            header = 1;
        }
        p = nl ? nl + 1 : end;
    }
    for (; k < n; k++) lines[k] = 0; /* not reached: the parser counted them */
}

static int joint_index(const char *name)
{
    for (int j = 0; j < MIM_PAIR_PERSON_JOINTS; j++)
        if (!strcmp(mim_sample_joint_names[j], name)) return j;
    return -1;
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
    if (pp->turn && left_of(j + 3 * joint_index("l_hip"), j + 3 * joint_index("r_hip"),
                            j + 3 * joint_index("l_shoulder"), j + 3 * joint_index("r_shoulder"), &sx, &sz)) {
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

static int prefix_ok(const char *p)
{
    if (strlen(p) > PREFIX_MAX) return 0;
    for (; *p; p++)
        if (*p <= ' ' || *p > '~' || *p == '/') return 0;
    return 1;
}

/* The store, read-only, with its index, and landmarks that pose-pair
 * samples give (all but the store's own failures are the command's:
 * checked before the samples are read). Returns an exit status. */
static int open_store(const char *store, mim_session_t **s)
{
    mim_error_t err = {0};
    mim_session_options_t so;
    mim_cli_session_options(&so, NULL);
    int rc = mim_session_open(s, store, &so, &err);
    if (!rc && !mim_session_query(*s))
        rc = mim_error_set(&err, MIM_ENOINDEX, "%s: store has no index (run mimic index)", store);
    const mim_landmark_map_t *map = rc ? NULL : mim_session_map(*s);
    for (uint32_t l = 0; !rc && l < map->count; l++)
        if (joint_index(map->names[l]) < 0)
            rc = mim_error_set(&err, MIM_EUNSUPPORTED, "%s: the store's landmark '%s' is not a joint of pose-pair "
                                                       "samples (head, chest, pelvis, ..., spine, neck)",
                               store, map->names[l]);
    if (rc) { /* the command cannot run (docs/reference.md: exit statuses) */
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
        mim_session_close(s);
        return 2;
    }
    return 0;
}

/* Phase 1: every selected person through the session, each result's
 * positions (3 * n floats) appended to spool. Returns an exit status. */
static int transfer_all(mim_session_t *s, const char *avatar, const mim_pairs_samples_t *smp,
                        const char *samples_path, item_t *items, uint32_t n_items, int retarget, FILE *spool,
                        classes_t *classes, uint32_t *n_vertices, uint32_t *features)
{
    mim_error_t err = {0};
    *features = mim_session_index_status(s)->built.d;
    const int labelled = mim_session_index_status(s)->built.class_source == MIM_CLASSES_LABELS;
    prep_t pp = {.map = mim_session_map(s), .nl = mim_session_map(s)->count, .retarget = retarget};
    for (uint32_t l = 0; l < pp.nl; l++) pp.idx[l] = joint_index(pp.map->names[l]); /* all there: open_store */
    int status = 1, rc;
    float *out = NULL;
    if ((rc = mim_session_load_avatar(s, avatar, &err))) {
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
        goto done;
    }
    const uint32_t n = mim_session_mesh(s)->n_vertices;
    *n_vertices = n;
    pp.rest = mim_session_mesh(s)->positions;
    pp.scratch = retarget ? calloc(3 * (size_t)n, sizeof *pp.scratch) : NULL;
    out = malloc(3 * (size_t)n * sizeof *out);
    if (!out || (retarget && !pp.scratch)) {
        fprintf(stderr, "mimic " CMD ": out of memory for %u vertices\n", n);
        goto done;
    }
    /* the avatar's facing and centre, from its rest landmarks */
    for (uint32_t l = 0; l < pp.nl; l++)
        for (int k = 0; k < 3; k++) pp.avatar_centre[k] += pp.rest[3 * (size_t)pp.map->vertex[l] + k] / (double)pp.nl;
    int lh = mim_landmarks_find(pp.map, "l_hip"), rh = mim_landmarks_find(pp.map, "r_hip"), ls = mim_landmarks_find(pp.map, "l_shoulder"),
        rs = mim_landmarks_find(pp.map, "r_shoulder");
    if (lh >= 0 && rh >= 0 && ls >= 0 && rs >= 0) {
        double at[4][3];
        const int which[4] = {lh, rh, ls, rs};
        for (int q = 0; q < 4; q++)
            for (int k = 0; k < 3; k++) at[q][k] = pp.rest[3 * (size_t)pp.map->vertex[which[q]] + k];
        pp.turn = left_of(at[0], at[1], at[2], at[3], &pp.avatar_left[0], &pp.avatar_left[1]);
    }
    /* every person's landmarks first: a bad sample stops the run before
     * any transfer */
    float *lm = malloc((size_t)n_items * 3 * pp.nl * sizeof *lm);
    if (!lm) {
        fprintf(stderr, "mimic " CMD ": out of memory for %u people's landmarks\n", n_items);
        goto done;
    }
    for (uint32_t i = 0; i < n_items; i++) {
        char origin[4200];
        snprintf(origin, sizeof origin, "%s:%ld: person %c", samples_path, items[i].line, items[i].person);
        const double *joints = smp->joints + (size_t)items[i].sample * 3 * MIM_PAIR_JOINTS +
                               (items[i].person == 'b' ? 3 * MIM_PAIR_PERSON_JOINTS : 0);
        if ((rc = person_landmarks(&pp, joints, origin, lm + (size_t)i * 3 * pp.nl, &err))) {
            if (rc == MIM_EUNSUPPORTED) /* retargeting needs the 16 default landmarks */
                fprintf(stderr, "mimic " CMD ": %s (use --proportions sample)\n", mim_error_text(&err));
            else
                fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
            free(lm);
            goto done;
        }
    }
    mim_progress_t pr = {.fn = mim_cli_progress};
    mim_progress_begin(&pr, "transfer", n_items);
    for (uint32_t i = 0; i < n_items && !rc; i++) {
        mim_session_request_t req = {.landmarks = lm + (size_t)i * 3 * pp.nl};
        mim_session_report_t rep;
        if ((rc = mim_session_transfer(s, &req, out, &rep, &err)))
            fprintf(stderr, "mimic " CMD ": %s:%ld: person %c: %s\n", samples_path, items[i].line, items[i].person,
                    mim_error_text(&err));
        else if ((rc = mim_body_check(out, n, "transfer result", &err)))
            fprintf(stderr, "mimic " CMD ": %s:%ld: person %c: %s\n", samples_path, items[i].line, items[i].person,
                    mim_error_text(&err));
        else if (fwrite(out, sizeof *out, 3 * (size_t)n, spool) != 3 * (size_t)n) {
            fprintf(stderr, "mimic " CMD ": cannot write the results to a temporary file (is the disk full?)\n");
            rc = MIM_EIO;
        }
        long k = rc ? 0 : class_of(classes, labelled ? rep.class_name : "");
        if (k < 0) {
            fprintf(stderr, "mimic " CMD ": out of memory\n");
            rc = MIM_ENOMEM;
        }
        items[i].cls = (uint32_t)k;
        mim_progress_update(&pr, i + 1);
    }
    mim_progress_end(&pr);
    free(lm);
    status = !rc ? 0 : rc == MIM_EIO || rc == MIM_ENOMEM ? 2 : 1; /* the system's, or a transfer's */
done:
    free(out), free(pp.scratch);
    return status;
}

/* Phase 2: the results into the store, one transaction. Returns an exit
 * status (every failure here is the store's or the system's: 2); ids gets
 * the new templates' ids, *dup the results already stored. */
static int store_all(const char *store, uint64_t avatar_id, const char *samples_real, const char *prefix,
                     const item_t *items, uint32_t n_items, const classes_t *classes, uint32_t n, FILE *spool,
                     uint64_t *ids, uint32_t *added, uint32_t *dup)
{
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_txn_t *t = NULL;
    mim_xfer_topology_t *topo = NULL;
    mim_db_options_t o = mim_cli_db_options(0);
    float *pos = malloc(12 * (size_t)n * sizeof *pos); /* positions, frames (6n), W (3n) */
    double *work = malloc(12 * (size_t)n * sizeof *work);
    char *subject = NULL;
    int status = 2, rc = pos && work ? 0 : mim_error_set(&err, MIM_ENOMEM, "out of memory for %u vertices", n);
    if (!rc) rc = mim_db_open(&db, store, &o, &err);
    if (!rc) rc = mim_db_begin(db, 1, &t, &err);
    mim_db_topology_t tp;
    if (!rc) rc = mim_db_topology_get(t, &tp, &err);
    if (!rc && tp.n_vertices != n)
        rc = mim_error_set(&err, MIM_ETOPOLOGY, "%s: its connectivity changed while the transfers ran (%u vertices, "
                                                "not %u): nothing stored", store, tp.n_vertices, n);
    if (!rc) rc = mim_xfer_topology_open(&topo, tp.n_vertices, tp.faces, tp.n_faces, &err);
    mim_template_view_t av;
    if (!rc && (rc = mim_db_template_get(t, avatar_id, &av, &err)) == 0 && !(subject = strdup(av.subject)))
        rc = mim_error_set(&err, MIM_ENOMEM, "out of memory");
    if (rc) {
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
        goto done;
    }
    rewind(spool);
    mim_progress_t pr = {.fn = mim_cli_progress};
    mim_progress_begin(&pr, "store", n_items);
    *added = *dup = 0;
    for (uint32_t i = 0; i < n_items && !rc; i++) {
        if (fread(pos, sizeof *pos, 3 * (size_t)n, spool) != 3 * (size_t)n) {
            rc = mim_error_set(&err, MIM_EIO, "cannot read the results back from their temporary file");
            break;
        }
        char pose[MIM_SESSION_LABEL_MAX + PREFIX_MAX + 32], source[PATH_MAX + 64];
        if (prefix) snprintf(pose, sizeof pose, "%s%ld-%c", prefix, items[i].line, items[i].person);
        else snprintf(pose, sizeof pose, "%s", classes->name[items[i].cls]);
        snprintf(source, sizeof source, "sampled:%s:%ld:%c", samples_real, items[i].line, items[i].person);
        mim_template_in_t tin = {pos, n, mim_db_content_hash(pos, n), source, subject, pose};
        uint64_t id;
        int existed;
        float *frames6 = pos + 3 * (size_t)n, *W = pos + 9 * (size_t)n;
        if ((rc = mim_db_template_put(t, &tin, &id, &existed, &err))) break;
        if (existed) {
            (*dup)++;
        } else {
            if ((rc = mim_xfer_encoding_compute(topo, pos, frames6, W, work, &err)) ||
                (rc = mim_db_encoding_put(t, id, frames6, W, n, &err)))
                break;
            ids[(*added)++] = id;
        }
        mim_progress_update(&pr, i + 1);
    }
    mim_progress_end(&pr);
    if (!rc) rc = mim_db_commit(&t, &err);
    if (rc) {
        fprintf(stderr, "mimic " CMD ": %s: nothing stored\n", mim_error_text(&err));
        goto done;
    }
    status = 0;
done:
    mim_db_abort(&t); /* after a failure: nothing half-written */
    mim_db_close(&db);
    mim_xfer_topology_close(&topo);
    free(pos), free(work), free(subject);
    return status;
}

int mim_cmd_pairs_templates(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'},        {"samples", required_argument, 0, 'S'},
        {"avatar", required_argument, 0, 'a'},       {"max", required_argument, 0, 'n'},
        {"person", required_argument, 0, 'p'},       {"proportions", required_argument, 0, 'P'},
        {"pose-label", required_argument, 0, 'L'},   {"label-prefix", required_argument, 0, 'l'},
        {"json", no_argument, 0, 'j'},               {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    const char *store = NULL, *samples_path = NULL, *avatar = NULL, *prefix = NULL; /* NULL: the class */
    int by_sample = -1; /* --pose-label: -1 not given, 0 class, 1 sample */
    uint64_t max = UINT32_MAX, avatar_id = 0;
    int as_json = 0, persons = 3, retarget = 1, c; /* persons: bit 0 a, bit 1 b */
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:S:a:n:p:P:L:l:jh", longopts, NULL)) != -1) {
        switch (c) {
        case 's': store = optarg; break;
        case 'S': samples_path = optarg; break;
        case 'a': avatar = optarg; break;
        case 'n':
            if (mim_cli_number(CMD, "max", optarg, 1, MIM_PAIRS_SAMPLES_MAX, &max)) return 2;
            break;
        case 'p':
            if (!strcmp(optarg, "a")) persons = 1;
            else if (!strcmp(optarg, "b")) persons = 2;
            else if (!strcmp(optarg, "both")) persons = 3;
            else {
                fprintf(stderr, "mimic " CMD ": --person '%s': use a, b or both\n", optarg);
                return 2;
            }
            break;
        case 'P':
            if (!strcmp(optarg, "avatar")) retarget = 1;
            else if (!strcmp(optarg, "sample")) retarget = 0;
            else {
                fprintf(stderr, "mimic " CMD ": --proportions '%s': use avatar or sample\n", optarg);
                return 2;
            }
            break;
        case 'L':
            if (!strcmp(optarg, "class")) by_sample = 0;
            else if (!strcmp(optarg, "sample")) by_sample = 1;
            else {
                fprintf(stderr, "mimic " CMD ": --pose-label '%s': use class or sample\n", optarg);
                return 2;
            }
            break;
        case 'l':
            if (!prefix_ok(optarg)) {
                fprintf(stderr, "mimic " CMD ": --label-prefix '%s': at most %d printable characters, no space or "
                                "'/'\n", optarg, PREFIX_MAX);
                return 2;
            }
            prefix = optarg;
            break;
        case 'j': as_json = 1; break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic " CMD ": unknown or incomplete option '%s' (see mimic " CMD " --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "mimic " CMD ": unexpected argument '%s' (see mimic " CMD " --help)\n", argv[optind]);
        return 2;
    }
    if (!store || !samples_path || !avatar) {
        fprintf(stderr, "mimic " CMD ": --store, --samples and --avatar are required (see mimic " CMD " --help)\n");
        return 2;
    }
    if (prefix && !by_sample) {
        fprintf(stderr, "mimic " CMD ": --label-prefix is for --pose-label sample, not class\n");
        return 2;
    }
    if (by_sample == 1 && !prefix) prefix = "sampled-";
    if (mim_cli_template_id(CMD, "avatar", avatar, &avatar_id)) return 2;

    const double t0 = mim_now();
    mim_session_t *s = NULL;
    if (open_store(store, &s)) return 2;
    mim_error_t err = {0};
    char *text = NULL, real[PATH_MAX];
    size_t len = 0;
    mim_pairs_samples_t smp = {0};
    if (mim_file_read(samples_path, 0, &text, &len, &err) ||
        mim_pairs_samples_parse(text, len, samples_path, &smp, &err)) {
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
        mim_session_close(&s);
        free(text);
        return 1;
    }
    const char *samples_real = realpath(samples_path, real) ? real : samples_path;
    const uint32_t n_samples = smp.n < max ? smp.n : (uint32_t)max;
    const uint32_t per = persons == 3 ? 2 : 1, n_items = n_samples * per;
    long *lines = malloc((size_t)n_samples * sizeof *lines);
    item_t *items = calloc(n_items, sizeof *items);
    uint64_t *ids = calloc(n_items, sizeof *ids);
    FILE *spool = tmpfile();
    int status = 1;
    uint32_t n_vertices = 0, features = 0, added = 0, dup = 0;
    classes_t classes = {0};
    if (!lines || !items || !ids) {
        fprintf(stderr, "mimic " CMD ": out of memory for %u samples\n", n_samples);
        status = 2;
        goto done;
    }
    if (!spool) {
        fprintf(stderr, "mimic " CMD ": cannot make a temporary file for the results (TMPDIR)\n");
        status = 2;
        goto done;
    }
    sample_lines(text, len, n_samples, lines);
    for (uint32_t i = 0, k = 0; i < n_samples; i++)
        for (int q = 0; q < 2; q++)
            if (persons & (1 << q)) items[k++] = (item_t){.sample = i, .line = lines[i], .person = (char)('a' + q)};

    status = transfer_all(s, avatar, &smp, samples_path, items, n_items, retarget, spool, &classes, &n_vertices,
                          &features);
    mim_session_close(&s); /* before the store is opened for writing: one environment at a time */
    if (status) goto done;
    status = store_all(store, avatar_id, samples_real, prefix, items, n_items, &classes, n_vertices, spool, ids, &added,
                       &dup);
    if (status) goto done;

    /* the index, as mimic index builds it, with the angles the store's had */
    mim_db_t *db = NULL;
    mim_db_options_t rw = mim_cli_db_options(0);
    mim_progress_t pr = {.fn = mim_cli_progress};
    mim_index_options_t io = {.features = features, .progress = &pr};
    mim_index_report_t irep;
    int rc = mim_db_open(&db, store, &rw, &err);
    if (!rc) rc = mim_query_build_index(db, &io, &irep, &err);
    mim_db_close(&db);
    if (rc) {
        fprintf(stderr, "mimic " CMD ": %u templates stored, but the index was not rebuilt: %s (run mimic index)\n",
                added, mim_error_text(&err));
        status = 2;
        goto done;
    }
    const double seconds = mim_now() - t0;
    if (as_json) {
        json_t *arr = json_array();
        for (uint32_t i = 0; arr && i < added; i++) json_array_append_new(arr, json_integer((json_int_t)ids[i]));
        json_t *j = arr ? json_pack("{s:I, s:o, s:I, s:f}", "templates", (json_int_t)added, "ids", arr, "duplicates",
                                    (json_int_t)dup, "seconds", seconds)
                        : NULL;
        char *txt = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (txt) printf("%s\n", txt);
        else fprintf(stderr, "mimic " CMD ": cannot make the JSON report (out of memory)\n"), status = 1;
        free(txt);
        json_decref(j);
    } else {
        printf("pairs templates: %u template%s from %u sample%s of %s", added, added == 1 ? "" : "s", n_samples,
               n_samples == 1 ? "" : "s", samples_path);
        if (added) printf(" (ids %llu..%llu)", (unsigned long long)ids[0], (unsigned long long)ids[added - 1]);
        if (dup) printf(", %u already stored", dup);
        printf(" in %.2f s; index rebuilt: %u classes, %u angles\n", seconds, irep.n_classes, irep.d);
    }
done:
    mim_session_close(&s);
    if (spool) fclose(spool);
    free(lines), free(items), free(ids), free(text), free(classes.name);
    mim_pairs_samples_free(&smp);
    return status;
}
