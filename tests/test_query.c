/* query/ and the recognition index in the store: build -> store -> open
 * round trip, exact self-answers on a small synth store, staleness, bad
 * input, and the `mimic index` / `mimic query` / `mimic info` commands. */
#include "mim_query.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char *g_dir, *g_bodies, *g_store;

static int run(char **out, char **err, const char *const *args) { return ts_run_mimic(out, err, args); }

/* A synth store of 3 subjects x 12 poses, ingested through the CLI. */
static int setup(void **s)
{
    (void)s;
    g_dir = ts_tempdir("query");
    g_bodies = ts_path(g_dir, "bodies");
    g_store = ts_path(g_dir, "store");
    const char *a1[] = {"synth", "--out", g_bodies, "--subjects", "3", "--poses", "12", "--vertices", "1500", NULL};
    const char *a2[] = {"ingest", "--store", g_store, g_bodies, NULL};
    if (run(NULL, NULL, a1) || run(NULL, NULL, a2)) return -1;
    return 0;
}

static int teardown(void **s)
{
    (void)s;
    ts_rmtree(g_dir);
    free(g_dir), free(g_bodies), free(g_store);
    return 0;
}

typedef struct {
    const mim_landmark_map_t *map;
    uint32_t n;
    float lm[256][48];
    uint64_t ids[256];
    char subjects[256][16], poses[256][16];
} store_lm_t;

static int grab(const mim_template_view_t *t, void *user)
{
    store_lm_t *s = user;
    if (s->n == 256) return 1;
    for (uint32_t l = 0; l < s->map->count; l++) memcpy(s->lm[s->n] + 3 * l, t->positions + 3 * s->map->vertex[l], 12);
    s->ids[s->n] = t->id;
    snprintf(s->subjects[s->n], 16, "%s", t->subject);
    snprintf(s->poses[s->n], 16, "%s", t->pose);
    s->n++;
    return 0;
}

static void read_store(mim_db_t *db, store_lm_t *s, mim_landmark_map_t *map)
{
    mim_db_txn_t *t;
    assert_int_equal(mim_db_begin(db, 0, &t, NULL), 0);
    assert_int_equal(mim_db_landmarks_get(t, map, NULL), 0);
    s->map = map;
    s->n = 0;
    assert_int_equal(mim_db_template_each(t, grab, s, NULL), 0);
    mim_db_abort(&t);
}

/* The same from the store at g_store, opened for it. */
static void read_store_closed(store_lm_t *s, mim_landmark_map_t *map)
{
    mim_db_t *db;
    assert_int_equal(mim_db_open(&db, g_store, &(mim_db_options_t){.read_only = 1}, NULL), 0);
    read_store(db, s, map);
    mim_db_close(&db);
}

/* Writes frames (one per template listed) as a landmark-frames file. */
static void write_frames(const char *path, store_lm_t *s, const uint32_t *which, uint32_t n, int null_landmark)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "{\"frames\": [\n");
    for (uint32_t i = 0; i < n; i++) {
        fprintf(f, "  {\"landmarks\": [");
        for (uint32_t l = 0; l < 16; l++) {
            if ((int)l == null_landmark) fprintf(f, "%snull", l ? ", " : "");
            else {
                const float *p = s->lm[which[i]] + 3 * l;
                fprintf(f, "%s[%.9g, %.9g, %.9g]", l ? ", " : "", p[0], p[1], p[2]);
            }
        }
        fprintf(f, "]}%s\n", i + 1 < n ? "," : "");
    }
    fprintf(f, "]}\n");
    fclose(f);
}

static void test_no_index_then_round_trip(void **st)
{
    (void)st;
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, g_store, NULL, NULL), 0);
    /* no index yet: status says so, open is an error that names the fix */
    mim_query_status_t qs;
    assert_int_equal(mim_query_status(db, &qs, NULL), 0);
    assert_false(qs.has_index);
    mim_query_t *q = NULL;
    assert_int_equal(mim_query_open(&q, db, &err), MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "mimic index"));
    assert_null(q);

    /* build and store; then the stored index answers exactly like the one
     * built in memory from the same templates */
    mim_index_options_t o = {.features = 30};
    mim_index_report_t rep;
    assert_int_equal(mim_query_build_index(db, &o, &rep, NULL), 0);
    assert_int_equal(rep.n_classes, 12);
    assert_int_equal(mim_query_status(db, &qs, NULL), 0);
    assert_true(qs.has_index && !qs.stale);
    assert_int_equal(qs.built.templates, 36);
    assert_int_equal(qs.built.d, 30);
    assert_int_equal(mim_query_open(&q, db, NULL), 0);
    assert_int_equal(mim_query_landmark_count(q), 16);

    static store_lm_t s;
    mim_landmark_map_t map;
    read_store(db, &s, &map);
    assert_int_equal(s.n, 36);
    const char *sp[36], *pp[36];
    for (uint32_t t = 0; t < 36; t++) sp[t] = s.subjects[t], pp[t] = s.poses[t];
    int32_t parent[MIM_LANDMARKS_MAX]; /* the store's index has the landmark skeleton's proportions */
    assert_int_equal(mim_index_skeleton(&map, parent), 0);
    mim_index_input_t in = {36, 16, &s.lm[0][0], s.ids, sp, pp, map.mirror, parent};
    mim_index_t *mem = NULL;
    assert_int_equal(mim_index_build(&mem, &in, &o, NULL, NULL), 0);
    for (uint32_t t = 0; t < 36; t++) {
        mim_index_query_options_t qo = {.k = 4};
        mim_index_answer_t a1, a2;
        mim_index_hit_t h1[4], h2[4];
        assert_int_equal(mim_query_frame(q, s.lm[t], NULL, &qo, &a1, h1, NULL), 0);
        assert_int_equal(mim_index_query(mem, s.lm[t], NULL, &qo, &a2, h2, NULL), 0);
        /* exact: every template finds itself first, in its own pose class */
        assert_int_equal(h1[0].id, s.ids[t]);
        assert_true(h1[0].distance == 0);
        assert_string_equal(mim_index_class_name(mim_query_index(q), a1.cls), s.poses[t]);
        assert_int_equal(a1.cls, a2.cls);
        assert_true(a1.probability == a2.probability);
        assert_int_equal(a1.n_hits, 3); /* 3 subjects per pose class */
        for (uint32_t i = 0; i < a1.n_hits; i++) {
            assert_int_equal(h1[i].id, h2[i].id);
            assert_true(h1[i].distance == h2[i].distance);
        }
    }
    /* a batch with a wrong landmark count is refused */
    mim_landmark_frames_t f = {.n_frames = 1, .n_landmarks = 15, .positions = &s.lm[0][0], .present = (uint8_t[15]){0}};
    mim_index_answer_t a;
    mim_index_hit_t h;
    assert_int_equal(mim_query_batch(q, &f, NULL, &a, &h, &err), MIM_EINVAL);
    /* the index is used in place, in the store's map, and answers as the
     * same blob copied out of the store (mim_index_load) */
    mim_index_info_t info;
    mim_index_get_info(mim_query_index(q), &info);
    assert_int_equal(info.in_place, 1);
    {
        mim_db_txn_t *t;
        const void *blob;
        size_t len;
        mim_db_index_meta_t bm;
        mim_index_t *cp = NULL;
        assert_int_equal(mim_db_begin(db, 0, &t, NULL), 0);
        assert_int_equal(mim_db_index_get(t, &blob, &len, &bm, NULL), 0);
        assert_int_equal(mim_index_load(&cp, blob, len, NULL), 0);
        mim_db_abort(&t);
        uint64_t seed = 9;
        for (uint32_t t2 = 0; t2 < 72; t2++) {
            float lm[48];
            uint8_t present[16];
            memset(present, 1, 16);
            if (t2 >= 36) present[t2 % 16] = present[(t2 + 7) % 16] = 0;
            for (int i = 0; i < 48; i++) {
                seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
                lm[i] = s.lm[t2 % 36][i] + 0.03f * ((float)(seed >> 40) / 16777216.0f - 0.5f);
            }
            mim_index_query_options_t qo = {.k = 3};
            mim_index_answer_t a1, a2;
            mim_index_hit_t h1[3], h2[3];
            assert_int_equal(mim_query_frame(q, lm, present, &qo, &a1, h1, NULL), 0);
            assert_int_equal(mim_index_query(cp, lm, present, &qo, &a2, h2, NULL), 0);
            assert_int_equal(a1.cls, a2.cls);
            assert_true(a1.probability == a2.probability);
            assert_int_equal(a1.n_hits, a2.n_hits);
            for (uint32_t i = 0; i < a1.n_hits; i++) {
                assert_int_equal(h1[i].id, h2[i].id);
                assert_true(h1[i].distance == h2[i].distance);
                assert_string_equal(h1[i].pose, h2[i].pose);
            }
        }
        mim_index_close(&cp);
    }
    mim_index_close(&mem);
    mim_query_close(&q);
    mim_query_close(&q);

    /* a damaged blob in the store is an error, not a crash: its head fails
     * at open, a bulk section when it is first used (here: all of it) */
    mim_db_txn_t *t;
    const void *blob;
    size_t len;
    mim_db_index_meta_t bm;
    assert_int_equal(mim_db_begin(db, 0, &t, NULL), 0);
    assert_int_equal(mim_db_index_get(t, &blob, &len, &bm, NULL), 0);
    unsigned char *copy = malloc(len);
    memcpy(copy, blob, len);
    mim_db_abort(&t);
    copy[len / 2] ^= 1;
    assert_int_equal(mim_db_begin(db, 1, &t, NULL), 0);
    assert_int_equal(mim_db_index_put(t, copy, len, &bm, NULL), 0);
    assert_int_equal(mim_db_commit(&t, NULL), 0);
    mim_error_clear(&err);
    int orc = mim_query_open(&q, db, &err);
    if (!orc) orc = mim_index_verify(mim_query_index(q), &err);
    assert_int_equal(orc, MIM_EFORMAT);
    assert_true(strstr(err.msg, "checksum") || strstr(err.msg, "damaged"));
    mim_query_close(&q);
    /* the head flipped: open fails */
    copy[len / 2] ^= 1;
    copy[100] ^= 1;
    assert_int_equal(mim_db_begin(db, 1, &t, NULL), 0);
    assert_int_equal(mim_db_index_put(t, copy, len, &bm, NULL), 0);
    assert_int_equal(mim_db_commit(&t, NULL), 0);
    mim_error_clear(&err);
    assert_int_equal(mim_query_open(&q, db, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "checksum"));
    copy[100] ^= 1;
    copy[len / 2] ^= 1;
    copy[len / 2] ^= 1; /* put it back */
    assert_int_equal(mim_db_begin(db, 1, &t, NULL), 0);
    assert_int_equal(mim_db_index_put(t, copy, len, &bm, NULL), 0);
    assert_int_equal(mim_db_commit(&t, NULL), 0);
    free(copy);
    assert_int_equal(mim_query_open(&q, db, NULL), 0);
    mim_query_close(&q);
    mim_db_close(&db);
}

static void test_cli_query_and_bad_input(void **st)
{
    (void)st;
    char *out = NULL, *err = NULL;
    const char *h1[] = {"index", "--help", NULL}, *h2[] = {"query", "--help", NULL};
    assert_int_equal(run(&out, NULL, h1), 0);
    assert_non_null(strstr(out, "usage: mimic index"));
    free(out);
    assert_int_equal(run(&out, NULL, h2), 0);
    assert_non_null(strstr(out, "--exclude-subject"));
    /* issue 30: it says what the exclusion leaves in */
    assert_non_null(strstr(out, "the index's classifier was built with them and still knows"));
    free(out);
    const char *ix[] = {"index", "--store", g_store, NULL};
    assert_int_equal(run(&out, NULL, ix), 0);
    assert_non_null(strstr(out, "12 classes (pose labels)"));
    assert_non_null(strstr(out, "C = "));
    /* issue 30: every class exact here, and no "rest" named that is not there */
    assert_non_null(strstr(out, "k-NN         all 12 classes exact"));
    assert_null(strstr(out, "the rest kd-forests"));
    free(out);

    static store_lm_t s;
    mim_landmark_map_t map;
    read_store_closed(&s, &map);
    char *frames = ts_path(g_dir, "frames.json");
    uint32_t which[3] = {5, 17, 30};
    write_frames(frames, &s, which, 3, -1);
    const char *q[] = {"query", "--store", g_store, "--landmarks", frames, "-k", "2", "--json", NULL};
    assert_int_equal(run(&out, &err, q), 0);
    for (int i = 0; i < 3; i++) { /* each frame's first result is its own template */
        char needle[64];
        snprintf(needle, sizeof needle, "\"id\": %llu,", (unsigned long long)s.ids[which[i]]);
        assert_non_null(strstr(out, needle));
    }
    assert_null(strstr(err, "stale"));
    free(out), free(err);
    /* leave-one-subject-out: the subject never comes back */
    const char *qx[] = {"query", "--store", g_store, "--landmarks", frames, "-k", "3", "--exclude-subject",
                        s.subjects[5], "--json", NULL};
    assert_int_equal(run(&out, NULL, qx), 0);
    char needle[64];
    snprintf(needle, sizeof needle, "\"subject\": \"%s\"", s.subjects[5]);
    assert_null(strstr(out, needle));
    free(out);
    /* one missing landmark still answers */
    write_frames(frames, &s, which, 1, 7);
    const char *q1[] = {"query", "--store", g_store, "--landmarks", frames, NULL};
    assert_int_equal(run(&out, NULL, q1), 0);
    assert_non_null(strstr(out, "1 landmark missing"));
    free(out);

    /* bad input: wrong count, not finite, malformed JSON (line and column), too many nulls */
    struct {
        const char *text, *expect;
    } bad[] = {
        {"{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0]]}", "has 3 landmarks"},
        {"{\"frames\": [{\"landmarks\": [[0,0,0],[1,0,0],[0,1,0],[0,0,1e999]]}]}", NULL},
        {"{\"frames\": [\n  {\"landmarks\": [1, 2,]}\n]}", ":2:"},
        {"{\"landmarks\": [null, null, null, null, [0,0,0], [1,0,0], [0,1,0], [0,0,1], [1,1,0], [1,0,1], [0,1,1], "
         "[1,1,1], [2,0,0], [0,2,0], [0,0,2], [2,2,2]]}",
         "missing"},
        /* no body (plausible.c): 16 identical landmarks, and one at 3e38 */
        {"{\"landmarks\": [[0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], "
         "[0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0], [0.1,1,0]]}",
         "frames.json: frame 0: landmarks span 0.0 mm: not a body (at least 10 mm)"},
        {"{\"landmarks\": [[0,1.6,0],[0,1.3,0],[0,1,0],[0.2,1.4,0],[-0.2,1.4,0],[0.45,1.4,0],[-0.45,1.4,0],"
         "[3e38,1.4,0],[-0.7,1.4,0],[0.1,0.95,0],[-0.1,0.95,0],[0.1,0.5,0.02],[-0.1,0.5,0.02],[0.1,0.08,0],"
         "[-0.1,0.08,0],[0,1.15,-0.05]]}",
         "frames.json: frame 0, landmark 7: coordinate x = 3e+38 outside the 10 m box a body fits in"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(ts_write_file(frames, bad[i].text, strlen(bad[i].text)), 0);
        assert_int_equal(run(NULL, &err, q1), 1);
        assert_non_null(strstr(err, "frames.json"));
        if (bad[i].expect && !strstr(err, bad[i].expect)) fail_msg("case %zu: %s", i, err);
        assert_true(strchr(err, '\n') == err + strlen(err) - 1); /* one line */
        free(err);
    }
    /* a batch over 64 MiB is refused before it is parsed */
    FILE *big = fopen(frames, "wb");
    assert_non_null(big);
    assert_int_equal(ftruncate(fileno(big), (off_t)MIM_LANDMARK_FRAMES_MAX_BYTES + 1), 0);
    fclose(big);
    assert_int_equal(run(NULL, &err, q1), 1);
    assert_non_null(strstr(err, "frames.json: 67108865 bytes (64.0 MiB), more than the 64 MiB a landmark batch may have"));
    free(err);
    /* NaN in a coordinate: JSON has no NaN, so the file is malformed at that spot */
    const char *nan_text = "{\"landmarks\": [[0, 0, NaN]]}";
    assert_int_equal(ts_write_file(frames, nan_text, strlen(nan_text)), 0);
    assert_int_equal(run(NULL, &err, q1), 1);
    assert_non_null(strstr(err, "frames.json:1:"));
    free(err);
    free(frames);
}

/* A batch of about 20 MiB (the store's templates in turn): mimic query
 * answers every frame, in memory bounded by the frames, not by the text
 * (a tree of the text took 13 times its size). The peak of a run on one
 * frame is the baseline. */
static void test_cli_query_large_batch(void **st)
{
    (void)st;
    static store_lm_t s;
    mim_landmark_map_t map;
    read_store_closed(&s, &map);
    char *one = ts_path(g_dir, "one.json"), *big = ts_path(g_dir, "big.json");
    uint32_t first = 0;
    write_frames(one, &s, &first, 1, -1);
    enum { N = 30000 };
    uint32_t *which = malloc(N * sizeof *which);
    for (uint32_t i = 0; i < N; i++) which[i] = i % s.n;
    write_frames(big, &s, which, N, -1);
    struct stat sb;
    assert_int_equal(stat(big, &sb), 0);
    assert_true(sb.st_size > (18 << 20));
    char *out = NULL, *err = NULL;
    long peak_one, peak_big;
    const char *q1[] = {"query", "--store", g_store, "--landmarks", one, NULL};
    const char *qb[] = {"query", "--store", g_store, "--landmarks", big, NULL};
    assert_int_equal(ts_run_mimic_peak(&out, NULL, q1, &peak_one), 0);
    free(out);
    assert_int_equal(ts_run_mimic_peak(&out, &err, qb, &peak_big), 0);
    /* every frame answered, the last one by its own template */
    char needle[96];
    snprintf(needle, sizeof needle, "frame %u: class %s ", N - 1, s.poses[which[N - 1]]);
    char *last = strstr(out, needle);
    assert_non_null(last);
    snprintf(needle, sizeof needle, "   1. template %-8llu", (unsigned long long)s.ids[which[N - 1]]);
    assert_non_null(strstr(last, needle));
    double frames_kib = (double)N * 16 * 13 / 1024;
    print_message("%lld bytes, %u frames: peak %ld KiB (one frame: %ld KiB)\n", (long long)sb.st_size, N, peak_big,
                  peak_one);
    if ((double)(peak_big - peak_one) > 3 * frames_kib)
        fail_msg("mimic query took %ld KiB more for %lld bytes than for one frame, over 3 times the frames' %.0f KiB",
                 peak_big - peak_one, (long long)sb.st_size, frames_kib);
    free(out), free(err), free(which), free(one), free(big);
}

/* One body-like frame of 16 landmarks. */
static const char one_frame[] =
    "{\"landmarks\": [[0,1.6,0],[0,1.3,0],[0,1,0],[0.2,1.4,0],[-0.2,1.4,0],[0.45,1.4,0],[-0.45,1.4,0],"
    "[0.7,1.4,0],[-0.7,1.4,0],[0.1,0.95,0],[-0.1,0.95,0],[0.1,0.5,0.02],[-0.1,0.5,0.02],[0.1,0.08,0],"
    "[-0.1,0.08,0],[0,1.15,-0.05]]}";

static void test_stale_and_info(void **st)
{
    (void)st;
    char *out = NULL, *err = NULL;
    const char *ix[] = {"index", "--store", g_store, "--features", "25", NULL};
    assert_int_equal(run(NULL, NULL, ix), 0);
    const char *info[] = {"info", "--store", g_store, NULL};
    assert_int_equal(run(&out, NULL, info), 0);
    assert_non_null(strstr(out, "from pose labels, 25 angles, built over 36 templates"));
    assert_null(strstr(out, "STALE"));
    free(out);
    /* more templates: the index is stale until mimic index runs again */
    char *more = ts_path(g_dir, "more");
    const char *a1[] = {"synth", "--out", more, "--subjects", "1", "--poses", "3", "--vertices", "1500", "--seed", "77", NULL};
    /* more of the same dataset ("bodies", the first folder's name): its poses join the classes */
    const char *a2[] = {"ingest", "--store", g_store, "--dataset", "bodies", more, NULL};
    assert_int_equal(run(NULL, NULL, a1), 0);
    assert_int_equal(run(NULL, NULL, a2), 0);
    assert_int_equal(run(&out, NULL, info), 0);
    assert_non_null(strstr(out, "STALE"));
    free(out);
    const char *infoj[] = {"info", "--store", g_store, "--json", NULL};
    assert_int_equal(run(&out, NULL, infoj), 0);
    assert_non_null(strstr(out, "\"stale\": true"));
    free(out);
    char *frames = ts_path(g_dir, "one.json");
    assert_int_equal(ts_write_file(frames, one_frame, strlen(one_frame)), 0);
    const char *q[] = {"query", "--store", g_store, "--landmarks", frames, NULL};
    assert_int_equal(run(&out, &err, q), 0);
    assert_non_null(strstr(err, "stale"));
    assert_non_null(strstr(out, "frame 0: class"));
    free(out), free(err);
    assert_int_equal(run(NULL, NULL, ix), 0);
    assert_int_equal(run(&out, NULL, info), 0);
    assert_non_null(strstr(out, "built over 39 templates"));
    assert_null(strstr(out, "STALE"));
    free(out);
    assert_int_equal(run(&out, &err, q), 0);
    assert_null(strstr(err, "stale"));
    free(out), free(err);
    free(more), free(frames);
}

/* Issue 30 item 3: the k-NN line of mimic index says how many classes are
 * exact and how many kd-forests, naming no rest that is not there. On the
 * store as test_stale_and_info leaves it: 12 pose classes, 3 of 4
 * templates and 9 of 3. */
static void test_index_knn_line(void **st)
{
    (void)st;
    const struct {
        const char *exact_max, *line;
        int exact;
    } cases[] = {{"3", "k-NN         9 of 12 classes exact, 3 kd-forests\n", 9},
                 {"2", "k-NN         all 12 classes kd-forests\n", 0},
                 {"4", "k-NN         all 12 classes exact\n", 12}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char *out = NULL, want[64];
        const char *ix[] = {"index", "--store", g_store, "--exact-max", cases[k].exact_max, NULL};
        assert_int_equal(run(&out, NULL, ix), 0);
        if (!strstr(out, cases[k].line)) fail_msg("--exact-max %s: %s", cases[k].exact_max, out);
        assert_null(strstr(out, "the rest"));
        free(out);
        const char *ixj[] = {"index", "--store", g_store, "--exact-max", cases[k].exact_max, "--json", NULL};
        assert_int_equal(run(&out, NULL, ixj), 0);
        snprintf(want, sizeof want, "\"exact_classes\": %d,", cases[k].exact);
        assert_non_null(strstr(out, want));
        free(out);
    }
    const char *bad[] = {"index", "--store", g_store, "--exact-max", "0", NULL};
    char *err = NULL;
    assert_int_equal(run(NULL, &err, bad), 2);
    assert_non_null(strstr(err, "exact-max"));
    free(err);
    /* proportions: canonical by default (a store of the 16 default
     * landmarks), said in the text and the JSON; body on request */
    const char *props[][7] = {{"index", "--store", g_store, "--json", NULL},
                              {"index", "--store", g_store, "--proportions", "body", "--json", NULL},
                              {"index", "--store", g_store, NULL}};
    const char *want[] = {"\"proportions\": \"canonical\"", "\"proportions\": \"body\"",
                          "proportions  canonical angles"};
    for (int k = 0; k < 3; k++) {
        char *out = NULL;
        assert_int_equal(run(&out, NULL, props[k]), 0);
        if (!strstr(out, want[k])) fail_msg("%s: %s", want[k], out);
        free(out);
    }
}

/* Issue 30 item 14: an index blob of an older version in the store (of
 * version 5's layout: the current blob with its version field made 5,
 * which the head's checksum does not cover) makes mimic query exit 2 with
 * one line that says to rebuild it; after mimic index it answers. */
static void test_old_index_blob(void **st)
{
    (void)st;
    const char *ix[] = {"index", "--store", g_store, NULL};
    assert_int_equal(run(NULL, NULL, ix), 0);
    mim_db_t *db;
    mim_db_txn_t *t;
    const void *blob;
    size_t len;
    mim_db_index_meta_t bm;
    assert_int_equal(mim_db_open(&db, g_store, NULL, NULL), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, NULL), 0);
    assert_int_equal(mim_db_index_get(t, &blob, &len, &bm, NULL), 0);
    unsigned char *old = malloc(len);
    memcpy(old, blob, len);
    const uint32_t five = 5;
    memcpy(old + 4, &five, 4);
    assert_int_equal(mim_db_index_put(t, old, len, &bm, NULL), 0);
    assert_int_equal(mim_db_commit(&t, NULL), 0);
    mim_db_close(&db);
    free(old);
    char *frames = ts_path(g_dir, "old-index.json"), *out = NULL, *err = NULL;
    assert_int_equal(ts_write_file(frames, one_frame, strlen(one_frame)), 0);
    const char *q[] = {"query", "--store", g_store, "--landmarks", frames, NULL};
    assert_int_equal(run(NULL, &err, q), 2);
    assert_string_equal(err, "mimic query: index blob: version 5 is older than this mimic's (7): rebuild it (run mimic "
                             "index)\n");
    free(err);
    assert_int_equal(run(NULL, NULL, ix), 0);
    assert_int_equal(run(&out, &err, q), 0);
    assert_non_null(strstr(out, "frame 0: class"));
    assert_string_equal(err, "");
    free(out), free(err), free(frames);
}

/* A store without pose labels is clustered, and info says so; a query on a
 * store without an index is an error that names the fix. */
static void test_unlabelled_store(void **st)
{
    (void)st;
    char *dir = ts_path(g_dir, "plain"), *store = ts_path(g_dir, "plain-store");
    char cmd[4096];
    snprintf(cmd, sizeof cmd,
             "mkdir -p '%s' && cp '%s/landmarks.json' '%s/' && i=0 && for f in '%s'/*.ply; do i=$((i+1)); "
             "cp \"$f\" '%s'/body$i.ply; done",
             dir, g_bodies, dir, g_bodies, dir);
    assert_int_equal(system(cmd), 0);
    const char *a2[] = {"ingest", "--store", store, dir, NULL};
    assert_int_equal(run(NULL, NULL, a2), 0);
    char *out = NULL, *err = NULL;
    char *frames = ts_path(g_dir, "one.json");
    const char *q[] = {"query", "--store", store, "--landmarks", frames, NULL};
    assert_int_equal(run(NULL, &err, q), 2);
    assert_non_null(strstr(err, "no index (run mimic index)"));
    free(err);
    const char *ix[] = {"index", "--store", store, "--json", NULL};
    assert_int_equal(run(&out, NULL, ix), 0);
    assert_non_null(strstr(out, "\"class_source\": \"kmeans\""));
    free(out);
    const char *info[] = {"info", "--store", store, NULL};
    assert_int_equal(run(&out, NULL, info), 0);
    assert_non_null(strstr(out, "k-means (no pose labels)"));
    free(out);
    assert_int_equal(run(&out, NULL, q), 0);
    assert_non_null(strstr(out, "class cluster-"));
    free(out);
    /* index on a path that is not a store does not create one */
    char *none = ts_path(g_dir, "nothing-here");
    const char *ixn[] = {"index", "--store", none, NULL};
    assert_int_equal(run(NULL, &err, ixn), 2);
    assert_non_null(strstr(err, "nothing-here"));
    free(err);
    free(dir), free(store), free(frames), free(none);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_no_index_then_round_trip),
        cmocka_unit_test(test_cli_query_and_bad_input),
        cmocka_unit_test(test_cli_query_large_batch),
        cmocka_unit_test(test_stale_and_info),
        cmocka_unit_test(test_index_knn_line),
        cmocka_unit_test(test_old_index_blob),
        cmocka_unit_test(test_unlabelled_store),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
