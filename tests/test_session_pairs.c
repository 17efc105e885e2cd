/* session/'s sampled pose-pairs (mim_session_pairs.h; issue 30 item 12:
 * the work of `mimic pairs templates`, through the library, no binary
 * between): each person's landmarks follow its own skeleton (its facing
 * from its left and right hips and shoulders, its place, its proportions
 * or the avatar's), the transferred bodies hold them, the store takes the
 * bodies as they were computed, and hostile input gets one line naming
 * the sample and the person, never a crash. On a synth store made here. */
#include "pairs_support.h"

#include "mim_db.h"
#include "mim_session_pairs.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define J TP_J

static char *dir, *bodies, *store, *noindex;
static mim_landmark_map_t map;
static double rest[J][3]; /* subject 0 at rest: the avatar, template 1 */
static double people[TP_PEOPLE][J][3];

/* ---- helpers ---- */

/* n samples, every joint 0 (set_pair fills them); no line numbers. */
static mim_pairs_samples_t new_samples(uint32_t n)
{
    mim_pairs_samples_t smp = {.n = n, .joints = calloc((size_t)n * 3 * MIM_PAIR_JOINTS, sizeof(double))};
    assert_non_null(smp.joints);
    return smp;
}

static void set_pair(mim_pairs_samples_t *smp, uint32_t i, double a[J][3], double b[J][3])
{
    double *dst = smp->joints + (size_t)i * 3 * MIM_PAIR_JOINTS;
    memcpy(dst, a, sizeof(double) * 3 * J);
    memcpy(dst + 3 * J, b, sizeof(double) * 3 * J);
}

/* A session on st with template 1 as its avatar. */
static mim_session_t *open_session(const char *st)
{
    mim_session_t *s = NULL;
    mim_error_t err = {0};
    int rc = mim_session_open(&s, st, NULL, &err);
    if (!rc) rc = mim_session_load_avatar(s, "1", &err);
    if (rc) fail_msg("session on %s: %s", st, mim_error_text(&err));
    return s;
}

/* rc is want, with one line in err holding each NULL-terminated phrase. */
static void expect_error(int rc, const mim_error_t *err, int want, const char *const *phrases)
{
    const char *msg = mim_error_text(err);
    if (rc != want) fail_msg("returned %d (%s), not %d: %s", rc, mim_strerror(rc), want, msg);
    if (!*msg || strchr(msg, '\n')) fail_msg("not one line: '%s'", msg);
    for (; phrases && *phrases; phrases++)
        if (!strstr(msg, *phrases)) fail_msg("'%s' does not say '%s'", msg, *phrases);
}
#define SAY(...) ((const char *const[]){__VA_ARGS__, NULL})

/* prepare, which must succeed. */
static mim_session_pairs_t *prepare(mim_session_t *s, const mim_pairs_samples_t *smp,
                                    const mim_session_pairs_options_t *opt)
{
    mim_session_pairs_t *p = NULL;
    mim_error_t err = {0};
    if (mim_session_pairs_prepare(s, smp, opt, &p, &err)) fail_msg("prepare: %s", mim_error_text(&err));
    return p;
}

static const float *landmarks(const mim_session_pairs_t *p, uint32_t i)
{
    mim_session_pairs_person_t who;
    assert_int_equal(mim_session_pairs_person(p, i, &who), 0);
    return who.landmarks;
}

static int lm(const char *name) { return mim_landmarks_find(&map, name); }

static double dist(const float *a, const float *b)
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* The person's landmarks moved so that their centre is the avatar's: what
 * the sample's own proportions give a person who faces the avatar's way. */
static void moved_onto_avatar(double p[J][3], float *out)
{
    float avatar[3 * MIM_LANDMARKS_MAX], raw[3 * MIM_LANDMARKS_MAX];
    tp_landmarks_of(&map, rest, avatar);
    tp_landmarks_of(&map, p, raw);
    double shift[3] = {0, 0, 0};
    for (uint32_t l = 0; l < map.count; l++)
        for (int c = 0; c < 3; c++) shift[c] += ((double)avatar[3 * l + c] - raw[3 * l + c]) / map.count;
    for (uint32_t l = 0; l < map.count; l++)
        for (int c = 0; c < 3; c++) out[3 * l + c] = (float)(raw[3 * l + c] + shift[c]);
}

static void assert_near(const float *got, const float *want, uint32_t n, double tol, const char *what)
{
    for (uint32_t k = 0; k < 3 * n; k++)
        if (!(fabs((double)got[k] - want[k]) <= tol))
            fail_msg("%s: landmark %u coordinate %u: %.6f, not %.6f", what, k / 3, k % 3, got[k], want[k]);
}

/* What a progress callback heard: the labels begun, in order, and the
 * last step of each. */
typedef struct {
    char begun[256];
    uint64_t done, total;
    int open;
} heard_t;

static void hear(void *ctx, int phase, const char *label, uint64_t done, uint64_t total)
{
    heard_t *h = ctx;
    if (phase == MIM_PROGRESS_BEGIN) {
        size_t at = strlen(h->begun);
        snprintf(h->begun + at, sizeof h->begun - at, "%s%s", at ? "," : "", label);
        h->open++;
    } else if (phase == MIM_PROGRESS_END) {
        h->open--;
    }
    h->done = done, h->total = total;
}

/* ---- fixture ---- */

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("session-pairs");
    int rc = tp_synth_store(dir, &bodies, &store, &map, rest);
    if (!rc) tp_make_people(rest, people);
    noindex = ts_path(dir, "noindex");
    char *p0 = ts_path(bodies, "synth_s00_p00.ply"), *p1 = ts_path(bodies, "synth_s00_p01.ply");
    const char *ingest[] = {"ingest", "--store", noindex, p0, p1, NULL};
    if (!rc) rc = ts_run_mimic(NULL, NULL, ingest);
    free(p0), free(p1);
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir), free(bodies), free(store), free(noindex);
    return 0;
}

/* ---- tests ---- */

/* The parser keeps each sample's line: the origins of errors and the
 * templates' sources name it. */
static void test_sample_lines(void **state)
{
    (void)state;
    char *h = mim_pairs_jsonl_header(), *a = mim_pairs_jsonl_line(&people[0][0][0], NAN), text[65536];
    assert_true(h && a);
    snprintf(text, sizeof text, "\n%s\n%s\n  \n\n%s\n%s", h, a, a, a);
    mim_pairs_samples_t smp;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_samples_parse(text, strlen(text), "s.jsonl", &smp, &err), 0);
    assert_int_equal(smp.n, 3);
    assert_non_null(smp.line);
    assert_int_equal(smp.line[0], 3);
    assert_int_equal(smp.line[1], 6);
    assert_int_equal(smp.line[2], 7);
    mim_pairs_samples_free(&smp);
    assert_null(smp.line);
    free(h), free(a);
}

/* Each person's landmarks: its joints by name, moved onto the avatar;
 * turned so that its own left (from its skeleton's left and right hips
 * and shoulders) is the avatar's, whichever way the sample faces; on the
 * avatar's proportions by default. */
static void test_landmarks_follow_the_skeleton(void **state)
{
    (void)state;
    mim_session_t *s = open_session(store);
    const uint32_t nl = map.count;
    /* 0a: the left arm forward, facing the avatar's way; 0b: the same,
     * turned a quarter and 1.6 m away; 1a: 0a with left and right
     * swapped (its labels say it faces the other way); 1b: 0a a quarter
     * taller */
    double turned[J][3], swapped[J][3], tall[J][3];
    memcpy(turned, people[0], sizeof turned);
    tp_place(turned, M_PI / 2, 1.5, -0.7);
    for (uint32_t l = 0; l < nl; l++)
        memcpy(swapped[tp_joint(map.names[l])], people[0][tp_joint(map.names[map.mirror[l]])], sizeof swapped[0]);
    memcpy(swapped[tp_joint("neck")], people[0][tp_joint("neck")], sizeof swapped[0]);
    for (int j = 0; j < J; j++)
        for (int c = 0; c < 3; c++) tall[j][c] = 1.25 * people[0][j][c];
    mim_pairs_samples_t smp = new_samples(2);
    set_pair(&smp, 0, people[0], turned);
    set_pair(&smp, 1, swapped, tall);

    /* the sample's proportions: the joints as they are, moved and turned */
    mim_session_pairs_options_t opt = {.sample_proportions = 1};
    mim_session_pairs_t *p = prepare(s, &smp, &opt);
    uint32_t samples = 0;
    assert_int_equal(mim_session_pairs_count(p, &samples), 4);
    assert_int_equal(samples, 2);
    float want[3 * MIM_LANDMARKS_MAX];
    moved_onto_avatar(people[0], want);
    assert_near(landmarks(p, 0), want, nl, 1e-5, "0a: the sample's joints, on the avatar");
    assert_near(landmarks(p, 1), want, nl, 1e-5, "0b: turned back to the avatar's facing");
    /* 1a's left landmarks are 0a's right ones turned half round the
     * vertical: its labels, not its coordinates, say where its left is */
    double centre[3] = {0, 0, 0};
    for (uint32_t l = 0; l < nl; l++)
        for (int c = 0; c < 3; c++) centre[c] += want[3 * l + c] / nl;
    const float *m = landmarks(p, 2);
    for (uint32_t l = 0; l < nl; l++) {
        const float *o = want + 3 * map.mirror[l];
        const float rot[3] = {(float)(2 * centre[0] - o[0]), o[1], (float)(2 * centre[2] - o[2])};
        assert_near(m + 3 * l, rot, 1, 1e-5, "1a: left and right swapped");
    }
    /* every person's left hip and shoulder on the avatar's left */
    const double left_x = rest[tp_joint("l_hip")][0] - rest[tp_joint("r_hip")][0];
    assert_true(left_x > 0.05); /* synth: the body's left is +X */
    for (uint32_t i = 0; i < 4; i++) {
        const float *q = landmarks(p, i);
        assert_true(q[3 * lm("l_hip")] > q[3 * lm("r_hip")]);
        assert_true(q[3 * lm("l_shoulder")] > q[3 * lm("r_shoulder")]);
    }
    const double arm_tall = dist(landmarks(p, 3) + 3 * lm("l_shoulder"), landmarks(p, 3) + 3 * lm("l_elbow"));
    mim_session_pairs_free(&p);
    assert_null(p);

    /* the avatar's proportions (default): the taller person's segments take
     * the avatar's lengths and keep their directions; a person of the
     * avatar's own proportions is unchanged */
    p = prepare(s, &smp, NULL);
    assert_near(landmarks(p, 0), want, nl, 1e-4, "0a on the avatar's proportions");
    float avatar[3 * MIM_LANDMARKS_MAX];
    tp_landmarks_of(&map, rest, avatar);
    const float *t = landmarks(p, 3), *o = want;
    const char *seg[][2] = {{"l_shoulder", "l_elbow"}, {"l_elbow", "l_wrist"}, {"r_hip", "r_knee"},
                            {"r_knee", "r_ankle"}, {"chest", "head"}};
    for (size_t k = 0; k < sizeof seg / sizeof seg[0]; k++) {
        const int u = lm(seg[k][0]), v = lm(seg[k][1]);
        const double lt = dist(t + 3 * u, t + 3 * v), la = dist(avatar + 3 * u, avatar + 3 * v);
        if (fabs(lt - la) > 1e-3) fail_msg("1b: %s-%s %.4f m, the avatar's %.4f", seg[k][0], seg[k][1], lt, la);
        const double lo = dist(o + 3 * u, o + 3 * v);
        double cosine = 0;
        for (int c = 0; c < 3; c++) cosine += (t[3 * v + c] - t[3 * u + c]) * (o[3 * v + c] - o[3 * u + c]) / (lt * lo);
        if (cosine < cos(0.5 * M_PI / 180)) fail_msg("1b: %s-%s turned by %g degrees", seg[k][0], seg[k][1],
                                                     acos(fmin(1, cosine)) * 180 / M_PI);
    }
    if (!(fabs(arm_tall - 1.25 * dist(avatar + 3 * lm("l_shoulder"), avatar + 3 * lm("l_elbow"))) < 1e-3))
        fail_msg("1b with its own proportions: upper arm %.4f m", arm_tall);
    mim_session_pairs_free(&p);
    mim_pairs_samples_free(&smp);
    mim_session_close(&s);
}

/* The bodies hold their people's landmarks and keep their joints'
 * distances; the store takes them as computed, with their sources and
 * labels, and the index is rebuilt with them. */
static void test_bodies_into_the_store(void **state)
{
    (void)state;
    char *st = tp_copy_store(dir, store, "stored");
    mim_session_t *s = open_session(st);
    const uint32_t n = mim_session_mesh(s)->n_vertices, nl = map.count;
    mim_pairs_samples_t smp = new_samples(2);
    set_pair(&smp, 0, people[0], people[1]);
    set_pair(&smp, 1, people[2], people[3]);
    heard_t heard = {.open = 0};
    mim_progress_t pr = {.fn = hear, .ctx = &heard};
    mim_session_pairs_options_t opt = {.origin = "mem.jsonl", .progress = &pr};
    mim_session_pairs_t *p = prepare(s, &smp, &opt);
    mim_error_t err = {0};
    float *body = malloc(3 * (size_t)n * TP_PEOPLE * sizeof *body);
    assert_non_null(body);
    expect_error(mim_session_pairs_body(p, 0, body, &err), &err, MIM_EINVAL, SAY("not transferred"));
    mim_session_pairs_person_t who;
    assert_int_equal(mim_session_pairs_person(p, 0, &who), 0);
    assert_null(who.pose_class);
    if (mim_session_pairs_transfer(s, p, &err)) fail_msg("transfer: %s", mim_error_text(&err));
    assert_string_equal(heard.begun, "transfer"); /* reported, not printed */
    assert_int_equal(heard.done, TP_PEOPLE);
    assert_int_equal(heard.total, TP_PEOPLE);
    assert_int_equal(heard.open, 0);
    for (uint32_t i = 0; i < TP_PEOPLE; i++) {
        float *b = body + 3 * (size_t)n * i;
        assert_int_equal(mim_session_pairs_body(p, i, b, NULL), 0);
        assert_int_equal(mim_session_pairs_person(p, i, &who), 0);
        assert_int_equal(who.sample, i / 2);
        assert_int_equal(who.line, 2 + i / 2); /* no line numbers: a header, then a sample a line */
        assert_int_equal(who.person, 'a' + (int)(i % 2));
        assert_non_null(who.pose_class);
        assert_true(strlen(who.pose_class) == 1 && who.pose_class[0] >= '0' && who.pose_class[0] <= '3');
        assert_int_equal(mim_body_check(b, n, "body", NULL), 0);
        /* the landmarks held at their vertices */
        for (uint32_t l = 0; l < nl; l++) assert_near(b + 3 * (size_t)map.vertex[l], who.landmarks + 3 * l, 1, 1e-4, "held");
        /* the person's joints up to a rigid motion: distances within 5 mm */
        float joints[3 * MIM_LANDMARKS_MAX];
        tp_landmarks_of(&map, people[i], joints);
        for (uint32_t u = 0; u < nl; u++)
            for (uint32_t v = u + 1; v < nl; v++) {
                double d = dist(b + 3 * (size_t)map.vertex[u], b + 3 * (size_t)map.vertex[v]);
                if (fabs(d - dist(joints + 3 * u, joints + 3 * v)) > 0.005)
                    fail_msg("person %u: %s-%s %.4f m, the sample's %.4f", i, map.names[u], map.names[v], d,
                             dist(joints + 3 * u, joints + 3 * v));
            }
    }
    err = (mim_error_t){0};
    expect_error(mim_session_pairs_transfer(s, p, &err), &err, MIM_EINVAL, SAY("transferred already"));
    mim_session_close(&s); /* one environment at a time */

    mim_session_pairs_store_options_t so = {.avatar_id = 1, .source = "/x/mem.jsonl", .label_prefix = "t-"};
    mim_session_pairs_report_t rep;
    err = (mim_error_t){0};
    if (mim_session_pairs_store(p, st, &so, &rep, &err)) fail_msg("store: %s", mim_error_text(&err));
    assert_int_equal(rep.added, TP_PEOPLE);
    assert_int_equal(rep.duplicates, 0);
    assert_non_null(strstr(heard.begun, "transfer,store,")); /* then the index's */
    assert_int_equal(heard.open, 0);
    assert_int_equal(rep.index.d, 60);                        /* the store's angles */
    assert_int_equal(rep.index.n_classes, TP_POSES + TP_PEOPLE); /* a class a prefixed person */
    mim_db_t *db;
    mim_db_txn_t *t;
    tp_begin_read(st, &db, &t);
    for (uint32_t i = 0; i < TP_PEOPLE; i++) {
        mim_template_view_t v;
        assert_int_equal(rep.ids[i], TP_OLD + 1 + i);
        tp_template_encoded(t, rep.ids[i], &v);
        assert_memory_equal(v.positions, body + 3 * (size_t)n * i, 3 * (size_t)n * sizeof(float));
        char src[64], pose[32];
        snprintf(src, sizeof src, "sampled:/x/mem.jsonl:%u:%c", 2 + i / 2, 'a' + (int)(i % 2));
        snprintf(pose, sizeof pose, "t-%u-%c", 2 + i / 2, 'a' + (int)(i % 2));
        assert_string_equal(v.source, src);
        assert_string_equal(v.pose, pose);
        assert_string_equal(v.subject, "0"); /* the avatar's */
    }
    mim_db_abort(&t);
    mim_db_close(&db);
    err = (mim_error_t){0};
    expect_error(mim_session_pairs_store(p, st, &so, &rep, &err), &err, MIM_EINVAL, SAY("stored already"));
    mim_session_pairs_free(&p);
    mim_pairs_samples_free(&smp);
    ts_rmtree(st);
    free(st), free(body);
}

/* Hostile input: one line naming the sample and the person (or what is
 * missing), no crash, nothing made. */
static void test_hostile_input(void **state)
{
    (void)state;
    mim_session_pairs_t *p = NULL;
    mim_error_t err = {0};
    mim_pairs_samples_t smp = new_samples(2);
    set_pair(&smp, 0, people[0], people[1]);
    set_pair(&smp, 1, people[2], people[3]);
    mim_session_pairs_options_t opt = {.origin = "bad.jsonl"};
#define PREPARE(s_, smp_, opt_) (err = (mim_error_t){0}, mim_session_pairs_prepare(s_, smp_, opt_, &p, &err))

    /* no avatar yet */
    mim_session_t *s = NULL;
    assert_int_equal(mim_session_open(&s, store, NULL, NULL), 0);
    expect_error(PREPARE(s, &smp, &opt), &err, MIM_EINVAL, SAY("no avatar loaded"));
    assert_null(p);
    mim_session_close(&s);
    /* a store without an index */
    assert_int_equal(mim_session_open(&s, noindex, NULL, NULL), 0);
    err = (mim_error_t){0};
    expect_error(mim_session_pairs_check(s, &err), &err, MIM_ENOINDEX, SAY(noindex, "no index"));
    mim_session_close(&s);

    s = open_session(store);
    assert_int_equal(mim_session_pairs_check(s, NULL), 0);
    /* no samples, or no joints */
    mim_pairs_samples_t none = {0};
    expect_error(PREPARE(s, &none, &opt), &err, MIM_EINVAL, SAY("bad.jsonl", "no samples"));
    expect_error(PREPARE(s, NULL, &opt), &err, MIM_EINVAL, SAY("no samples"));
    none.n = 3;
    expect_error(PREPARE(s, &none, &opt), &err, MIM_EINVAL, SAY("no samples"));
    /* persons other than a and b */
    mim_session_pairs_options_t bad = {.persons = 4};
    expect_error(PREPARE(s, &smp, &bad), &err, MIM_EINVAL, SAY("person"));
    assert_null(p);

    /* a NaN joint: sample 1 (line 3), person b's left knee */
    double *b1 = smp.joints + 3 * MIM_PAIR_JOINTS + 3 * (J + tp_joint("l_knee"));
    b1[1] = NAN;
    expect_error(PREPARE(s, &smp, &opt), &err, MIM_ENONFINITE, SAY("bad.jsonl:3: person b"));
    assert_null(p);
    /* the persons and samples not chosen are not read */
    mim_session_pairs_options_t only_a = {.persons = MIM_SESSION_PAIRS_PERSON_A}, first = {.max = 1};
    assert_int_equal(PREPARE(s, &smp, &only_a), 0);
    assert_int_equal(mim_session_pairs_count(p, NULL), 2);
    mim_session_pairs_free(&p);
    assert_int_equal(PREPARE(s, &smp, &first), 0);
    assert_int_equal(mim_session_pairs_count(p, NULL), 2);
    mim_session_pairs_person_t who;
    assert_int_equal(mim_session_pairs_person(p, 2, &who), MIM_EINVAL);
    mim_session_pairs_free(&p);
    b1[1] = 1.0;
    /* an infinite coordinate, with the file's line numbers */
    long lines[2] = {7, 12};
    smp.line = lines;
    smp.joints[0] = INFINITY;
    expect_error(PREPARE(s, &smp, &opt), &err, MIM_ENONFINITE, SAY("bad.jsonl:7: person a"));
    /* person b of line 12 at one point: no body */
    smp.joints[0] = people[0][0][0];
    for (int j = 0; j < J; j++)
        for (int c = 0; c < 3; c++) smp.joints[3 * MIM_PAIR_JOINTS + 3 * (J + j) + c] = 0.5;
    expect_error(PREPARE(s, &smp, &opt), &err, MIM_EFORMAT, SAY("bad.jsonl:12: person b", "not a body"));
    assert_null(p);
    smp.line = NULL;
    set_pair(&smp, 1, people[2], people[3]);

    /* steps out of order, or on another session */
    mim_session_pairs_options_t one = {.max = 1, .persons = MIM_SESSION_PAIRS_PERSON_A};
    assert_int_equal(PREPARE(s, &smp, &one), 0);
    mim_session_pairs_report_t rep;
    mim_session_pairs_store_options_t so = {.avatar_id = 1};
    expect_error(mim_session_pairs_store(p, store, &so, &rep, &err), &err, MIM_EINVAL, SAY("before the transfer"));
    mim_session_t *f = NULL;
    assert_int_equal(mim_session_fork(&f, s, NULL, NULL), 0);
    err = (mim_error_t){0};
    expect_error(mim_session_pairs_transfer(f, p, &err), &err, MIM_EINVAL, SAY("another session"));
    mim_session_close(&f);
    mim_session_pairs_free(&p);
    mim_session_pairs_free(&p); /* again: nothing */
    mim_session_pairs_free(NULL);

    /* label prefixes */
    assert_true(mim_session_pairs_prefix_ok("sampled-"));
    assert_true(mim_session_pairs_prefix_ok(""));
    assert_false(mim_session_pairs_prefix_ok("a b"));
    assert_false(mim_session_pairs_prefix_ok("a/b"));
    assert_false(mim_session_pairs_prefix_ok("caf\xc3\xa9"));
    char longest[MIM_SESSION_PAIRS_PREFIX_MAX + 2];
    memset(longest, 'x', sizeof longest - 1);
    longest[sizeof longest - 1] = 0;
    assert_false(mim_session_pairs_prefix_ok(longest));
    longest[MIM_SESSION_PAIRS_PREFIX_MAX] = 0;
    assert_true(mim_session_pairs_prefix_ok(longest));
    mim_session_close(&s);
    mim_pairs_samples_free(&smp);
#undef PREPARE
}

/* The store refuses what it cannot take, with one line, and keeps what it
 * had: no options, a bad prefix, an unknown avatar id; then, asked right,
 * it takes the bodies. */
static void test_store_refusals(void **state)
{
    (void)state;
    char *st = tp_copy_store(dir, store, "refusals");
    mim_session_t *s = open_session(st);
    mim_pairs_samples_t smp = new_samples(1);
    set_pair(&smp, 0, people[0], people[1]);
    mim_session_pairs_t *p = prepare(s, &smp, NULL);
    mim_error_t err = {0};
    assert_int_equal(mim_session_pairs_transfer(s, p, &err), 0);
    mim_session_close(&s);
    mim_session_pairs_report_t rep;
    expect_error(mim_session_pairs_store(p, st, NULL, &rep, &err), &err, MIM_EINVAL, SAY("avatar"));
    err = (mim_error_t){0};
    mim_session_pairs_store_options_t so = {.avatar_id = 1, .label_prefix = "a b"};
    expect_error(mim_session_pairs_store(p, st, &so, &rep, &err), &err, MIM_EINVAL, SAY("'a b'"));
    err = (mim_error_t){0};
    so = (mim_session_pairs_store_options_t){.avatar_id = 999};
    expect_error(mim_session_pairs_store(p, st, &so, &rep, &err), &err, MIM_ENOTFOUND, SAY("999"));
    assert_int_equal(rep.added, 0);
    /* nothing stored */
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_template_view_t v;
    tp_begin_read(st, &db, &t);
    assert_int_equal(mim_db_template_get(t, TP_OLD, &v, NULL), 0);
    assert_int_equal(mim_db_template_get(t, TP_OLD + 1, &v, NULL), MIM_ENOTFOUND);
    mim_db_abort(&t);
    mim_db_close(&db);
    /* asked right: both people, subject 1's (template 5), class labels */
    so.avatar_id = 5;
    assert_int_equal(mim_session_pairs_store(p, st, &so, &rep, NULL), 0);
    assert_int_equal(rep.added, 2);
    assert_int_equal(rep.index.n_classes, TP_POSES);
    tp_begin_read(st, &db, &t);
    tp_template_encoded(t, rep.ids[1], &v);
    assert_string_equal(v.subject, "1");
    assert_string_equal(v.source, "sampled:samples:2:b"); /* no origin, no source: "samples" */
    mim_db_abort(&t);
    mim_db_close(&db);
    mim_session_pairs_free(&p);
    mim_pairs_samples_free(&smp);
    ts_rmtree(st);
    free(st);
}

/* A store whose map lacks a landmark that retargeting needs (the spine):
 * the avatar's proportions cannot be taken (MIM_EUNSUPPORTED, one line),
 * the sample's can. */
static void test_map_without_spine(void **state)
{
    (void)state;
    mim_landmark_map_t m15 = map;
    const int spine = lm("spine");
    assert_int_equal(spine, (int)map.count - 1); /* the last, its own mirror */
    m15.count--;
    char *path = ts_path(dir, "lm15.json"), *st = ts_path(dir, "store15");
    assert_int_equal(mim_landmarks_write(&m15, path, NULL), 0);
    const char *ingest[] = {"ingest", "--store", st, "--landmarks", path, bodies, NULL};
    const char *index[] = {"index", "--store", st, NULL};
    char *e = NULL;
    for (int k = 0; k < 2; k++, free(e), e = NULL)
        if (ts_run_mimic(NULL, &e, k ? index : ingest)) fail_msg("mimic %s: %s", k ? "index" : "ingest", e);
    mim_session_t *s = open_session(st);
    mim_pairs_samples_t smp = new_samples(1);
    set_pair(&smp, 0, people[0], people[1]);
    mim_session_pairs_t *p = NULL;
    mim_error_t err = {0};
    expect_error(mim_session_pairs_prepare(s, &smp, NULL, &p, &err), &err, MIM_EUNSUPPORTED, SAY("16 default"));
    assert_null(p);
    p = prepare(s, &smp, &(mim_session_pairs_options_t){.sample_proportions = 1});
    assert_int_equal(mim_session_pairs_count(p, NULL), 2);
    mim_session_pairs_free(&p);
    mim_pairs_samples_free(&smp);
    mim_session_close(&s);
    free(path), free(st);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sample_lines),
        cmocka_unit_test(test_landmarks_follow_the_skeleton),
        cmocka_unit_test(test_bodies_into_the_store),
        cmocka_unit_test(test_hostile_input),
        cmocka_unit_test(test_store_refusals),
        cmocka_unit_test(test_map_without_spine),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
