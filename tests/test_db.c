/* db/: store round trip, zero-copy views, schema mismatch, foreign stores,
 * two reader processes while one writes, kill -9 during an ingest, damaged
 * encodings, fresh environments, a full map; registrations and bindings
 * (schema version 3: round trips, damaged records, mimic list), and a
 * version-2 store read as it is and migrated to 3. (Damaged files, the
 * migration from version 1 and mimic store check: test_store_damage.c and
 * test_store_write.c.) */
#include "mim_db.h"
#include "test_support.h"

#include <jansson.h>
#include <lmdb.h>
#include <math.h>
#include <xxhash.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

static char *dir;

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("db");
    return dir ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir);
    return 0;
}

static void fill(float *p, uint32_t n, float seed)
{
    for (uint32_t i = 0; i < 3 * n; i++) p[i] = seed + 0.001f * (float)i;
}

static void test_round_trip(void **s)
{
    (void)s;
    char *store = ts_path(dir, "rt");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_db_txn_t *t;
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    uint32_t faces[] = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
    assert_int_equal(mim_db_topology_put(t, faces, 4, 4, &err), 0);
    assert_int_equal(mim_db_topology_put(t, faces, 4, 4, &err), MIM_EINVAL); /* set once */
    uint32_t lv[16];
    for (int i = 0; i < 16; i++) lv[i] = (uint32_t)i % 4;
    mim_landmark_map_t lm;
    mim_landmarks_default(&lm, lv, 4);
    assert_int_equal(mim_db_landmarks_put(t, &lm, &err), 0);
    /* sizes from tiny to a body, so both small and large records are covered */
    uint32_t sizes[] = {4, 100, 7000};
    uint64_t ids[3];
    for (int i = 0; i < 3; i++) {
        float *p = malloc(12 * sizes[i]);
        fill(p, sizes[i], (float)i);
        char subj[8];
        snprintf(subj, sizeof subj, "s%d", i);
        mim_template_in_t in = {p, sizes[i], mim_db_content_hash(p, sizes[i]), "/data/x.ply", subj, i == 2 ? "" : "sit",
                                i == 1 ? "faust" : NULL};
        int existed = -1;
        assert_int_equal(mim_db_template_put(t, &in, &ids[i], &existed, &err), 0);
        assert_int_equal(existed, 0);
        assert_int_equal(ids[i], (uint64_t)i + 1);
        free(p);
    }
    assert_int_equal(mim_db_commit(&t, &err), 0);
    assert_null(t);
    mim_db_close(&db);
    assert_null(db);

    mim_db_options_t ro = {.read_only = 1};
    int rc = mim_db_open(&db, store, &ro, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    mim_db_meta_t meta;
    assert_int_equal(mim_db_meta_get(t, &meta, &err), 0);
    assert_int_equal(meta.templates, 3);
    assert_int_equal(meta.next_id, 4);
    assert_string_equal(meta.created_by, "mimic " MIM_VERSION);
    mim_db_topology_t topo;
    assert_int_equal(mim_db_topology_get(t, &topo, &err), 0);
    assert_int_equal(topo.n_faces, 4);
    assert_memory_equal(topo.faces, faces, sizeof faces);
    assert_int_equal(topo.hash, mim_db_topology_hash(faces, 4, 4));
    mim_landmark_map_t back;
    assert_int_equal(mim_db_landmarks_get(t, &back, &err), 0);
    assert_int_equal(back.count, 16);
    assert_string_equal(back.names[3], "l_shoulder");
    assert_int_equal(back.mirror[3], 4);
    for (int i = 0; i < 3; i++) {
        mim_template_view_t v;
        assert_int_equal(mim_db_template_get(t, ids[i], &v, &err), 0);
        float *p = malloc(12 * sizes[i]);
        fill(p, sizes[i], (float)i);
        assert_int_equal(v.n_vertices, sizes[i]);
        assert_memory_equal(v.positions, p, 12 * sizes[i]);
        assert_int_equal(v.content_hash, mim_db_content_hash(p, sizes[i]));
        assert_int_equal((uintptr_t)v.positions % 16, 0); /* straight from the map, aligned */
        assert_string_equal(v.source, "/data/x.ply");
        assert_string_equal(v.pose, i == 2 ? "" : "sit");
        assert_string_equal(v.dataset, i == 1 ? "faust" : ""); /* none given: none, as records before datasets */
        /* zero-copy: a second lookup lends the same bytes */
        mim_template_view_t again;
        assert_int_equal(mim_db_template_get(t, ids[i], &again, &err), 0);
        assert_ptr_equal(again.positions, v.positions);
        free(p);
    }
    mim_template_view_t none;
    assert_int_equal(mim_db_template_get(t, 99, &none, &err), MIM_ENOTFOUND);
    /* writes are refused on a read-only store */
    mim_db_txn_t *w = NULL;
    mim_error_clear(&err);
    assert_int_equal(mim_db_begin(db, 1, &w, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "read-only"));
    mim_db_abort(&t);
    mim_db_close(&db);
    free(store);
}

static void test_dedupe(void **s)
{
    (void)s;
    char *store = ts_path(dir, "dd");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_db_txn_t *t;
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    float a[30], b[30];
    fill(a, 10, 1.0f);
    fill(b, 10, 2.0f);
    /* b claims a's hash: equal hashes alone must not merge different meshes */
    mim_template_in_t ia = {a, 10, mim_db_content_hash(a, 10), "a", "", "", NULL};
    mim_template_in_t ib = {b, 10, ia.content_hash, "b", "", "", NULL};
    uint64_t id1, id2, id3;
    int e1, e2, e3;
    assert_int_equal(mim_db_template_put(t, &ia, &id1, &e1, &err), 0);
    assert_int_equal(mim_db_template_put(t, &ib, &id2, &e2, &err), 0);
    assert_int_equal(mim_db_template_put(t, &ia, &id3, &e3, &err), 0);
    assert_false(e1);
    assert_false(e2);
    assert_true(e3);
    assert_int_not_equal(id1, id2);
    assert_int_equal(id3, id1);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    mim_db_close(&db);
    free(store);
}

/* A raw LMDB transaction on store, under mimic's feet (as another program,
 * an older mimic or damage would leave it); flags MDB_RDONLY or 0. */
static MDB_txn *raw_begin(const char *store, unsigned flags, MDB_env **env)
{
    assert_int_equal(mdb_env_create(env), 0);
    mdb_env_set_maxdbs(*env, 16);
    assert_int_equal(mdb_env_open(*env, store, flags, 0664), 0);
    MDB_txn *txn;
    assert_int_equal(mdb_txn_begin(*env, NULL, flags & MDB_RDONLY, &txn), 0);
    return txn;
}

static void test_schema_mismatch(void **s)
{
    (void)s;
    char *store = ts_path(dir, "schema");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_db_close(&db);
    /* rewrite the version underneath, as a future mimic would have written it */
    MDB_env *env;
    MDB_txn *txn = raw_begin(store, 0, &env);
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "meta", 0, &dbi), 0);
    uint64_t v = 99;
    MDB_val k = {14, "schema_version"}, d = {8, &v};
    assert_int_equal(mdb_put(txn, dbi, &k, &d, 0), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);

    assert_int_equal(mim_db_open(&db, store, NULL, &err), MIM_ESCHEMA);
    assert_null(db);
    assert_non_null(strstr(err.msg, "schema version 99"));
    assert_non_null(strstr(err.msg, store));
    /* and through the command line: one clear line, no crash */
    char *out = NULL, *errs = NULL;
    const char *args[] = {"info", "--store", store, NULL};
    assert_int_equal(ts_run_mimic(&out, &errs, args), 2);
    assert_non_null(strstr(errs, "schema version 99"));
    free(out), free(errs), free(store);
}

static void test_not_a_store(void **s)
{
    (void)s;
    mim_db_t *db;
    mim_error_t err = {0};
    char *d = ts_path(dir, "garbage");
    mkdir(d, 0755);
    char *f = ts_path(d, "data.mdb");
    char junk[8192];
    for (size_t i = 0; i < sizeof junk; i++) junk[i] = (char)(i * 7 + 3);
    ts_write_file(f, junk, sizeof junk);
    int rc = mim_db_open(&db, d, NULL, &err);
    assert_true(rc == MIM_ESTORE);
    assert_non_null(strstr(err.msg, d));
    assert_null(db);
    /* a file where a folder should be */
    mim_error_clear(&err);
    assert_int_equal(mim_db_open(&db, f, NULL, &err), MIM_EINVAL);
    /* read-only open of nothing */
    mim_db_options_t ro = {.read_only = 1};
    char *missing = ts_path(dir, "missing");
    mim_error_clear(&err);
    assert_int_equal(mim_db_open(&db, missing, &ro, &err), MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "missing"));
    free(missing), free(f), free(d);
}

/* n perturbed spheres of one connectivity + landmarks.json; returns the folder. */
static char *make_dataset(const char *name, int n, uint32_t rings)
{
    char *d = ts_path(dir, name);
    mkdir(d, 0755);
    for (int i = 0; i < n; i++) {
        ts_polymesh_t m;
        ts_sphere(&m, rings, 2 * rings, 0.4f + 0.001f * (float)i);
        char fn[64];
        snprintf(fn, sizeof fn, "ball_%04d.ply", i);
        char *p = ts_path(d, fn);
        ts_write_ply_binary(p, &m);
        free(p);
        ts_polymesh_free(&m);
    }
    char *p = ts_path(d, "landmarks.json");
    const char *lm = "{\"landmarks\":[{\"name\":\"a\",\"vertex\":0},{\"name\":\"b\",\"vertex\":1},"
                     "{\"name\":\"c\",\"vertex\":2},{\"name\":\"d\",\"vertex\":3}]}";
    ts_write_file(p, lm, strlen(lm));
    free(p);
    return d;
}

static uint64_t store_count(const char *store)
{
    mim_db_t *db;
    mim_db_options_t ro = {.read_only = 1};
    if (mim_db_open(&db, store, &ro, NULL)) return 0;
    mim_db_txn_t *t;
    mim_db_meta_t meta = {0};
    if (!mim_db_begin(db, 0, &t, NULL)) {
        mim_db_meta_get(t, &meta, NULL);
        mim_db_abort(&t);
    }
    mim_db_close(&db);
    return meta.templates;
}

typedef struct {
    uint64_t n, bad;
} verify_t;

static int verify_one(const mim_template_view_t *v, void *user)
{
    verify_t *vt = user;
    vt->n++;
    if (mim_db_content_hash(v->positions, v->n_vertices) != v->content_hash) vt->bad++;
    return 0;
}

/* A reader process: snapshots must be whole and counts never go back. */
static int reader_loop(const char *store, double seconds)
{
    mim_db_t *db = NULL;
    mim_db_options_t ro = {.read_only = 1};
    double t0 = mim_now();
    while (!db && mim_now() - t0 < 10)
        if (mim_db_open(&db, store, &ro, NULL)) usleep(1000);
    if (!db) return 3;
    uint64_t last = 0, distinct = 0, rounds = 0;
    while (mim_now() - t0 < seconds) {
        mim_db_txn_t *t;
        if (mim_db_begin(db, 0, &t, NULL)) return 4;
        mim_db_meta_t meta;
        verify_t vt = {0, 0};
        if (mim_db_meta_get(t, &meta, NULL) || mim_db_template_each(t, verify_one, &vt, NULL)) return 5;
        mim_db_abort(&t);
        if (vt.bad || vt.n != meta.templates) return 6; /* torn or inconsistent snapshot */
        if (meta.templates < last) return 7;
        if (meta.templates != last) distinct++;
        last = meta.templates;
        rounds++;
        if (last >= 400) break;
    }
    mim_db_close(&db);
    return distinct >= 2 && rounds >= 2 ? 0 : 8;
}

/* Whether the store has a named table `name` (a key of LMDB's main database). */
static int has_table(const char *store, const char *name)
{
    MDB_env *env;
    MDB_txn *txn = raw_begin(store, MDB_RDONLY, &env);
    MDB_dbi main_dbi;
    MDB_cursor *c;
    MDB_val k, d;
    int found = 0;
    assert_int_equal(mdb_dbi_open(txn, NULL, 0, &main_dbi), 0);
    assert_int_equal(mdb_cursor_open(txn, main_dbi, &c), 0);
    for (int r = mdb_cursor_get(c, &k, &d, MDB_FIRST); r == 0; r = mdb_cursor_get(c, &k, &d, MDB_NEXT))
        found |= k.mv_size == strlen(name) && !memcmp(k.mv_data, name, k.mv_size);
    mdb_cursor_close(c);
    mdb_txn_abort(txn);
    mdb_env_close(env);
    return found;
}

/* The dropped `descriptors` table: a new store has none, and a store made
 * before the drop (which has it, empty) still opens, read-only and for
 * writing, and keeps it. */
static void test_legacy_descriptors_table(void **s)
{
    (void)s;
    char *store = ts_path(dir, "legacy");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_db_close(&db);
    assert_false(has_table(store, "descriptors"));
    assert_true(has_table(store, "encodings"));
    /* add the table as an older mimic created it (integer keys, empty) */
    MDB_env *env;
    MDB_txn *txn = raw_begin(store, 0, &env);
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "descriptors", MDB_CREATE | MDB_INTEGERKEY, &dbi), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);
    assert_true(has_table(store, "descriptors"));

    mim_db_options_t ro = {.read_only = 1};
    int rc = mim_db_open(&db, store, &ro, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, 0);
    mim_db_close(&db);
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_db_txn_t *t;
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    float p[12];
    fill(p, 4, 1.0f);
    mim_template_in_t in = {p, 4, mim_db_content_hash(p, 4), "a.ply", "s", "p", NULL};
    uint64_t id = 0;
    assert_int_equal(mim_db_template_put(t, &in, &id, NULL, &err), 0);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    mim_db_close(&db);
    assert_true(has_table(store, "descriptors")); /* left as it was */
    assert_int_equal(store_count(store), 1);
    free(store);
}

/* The map size comes from the options only: the library reads no
 * environment variable (the mimic command turns MIMIC_MAP_SIZE into the
 * option). */
static void test_map_size_option(void **s)
{
    (void)s;
    char *store = ts_path(dir, "mapsize");
    const char *old = getenv("MIMIC_MAP_SIZE");
    char *saved = old ? strdup(old) : NULL;
    setenv("MIMIC_MAP_SIZE", "1048576", 1);
    mim_db_t *db;
    mim_db_stat_t st;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_stat(db, &st, &err), 0);
    assert_true(st.map_size == 256ULL << 30); /* the default, not the variable */
    mim_db_close(&db);
    mim_db_options_t o = {.map_size = 64ULL << 20};
    assert_int_equal(mim_db_open(&db, store, &o, &err), 0);
    assert_int_equal(mim_db_stat(db, &st, &err), 0);
    assert_true(st.map_size == 64ULL << 20);
    mim_db_close(&db);
    if (saved) setenv("MIMIC_MAP_SIZE", saved, 1);
    else unsetenv("MIMIC_MAP_SIZE");
    free(saved), free(store);
}

static void test_readers_while_writing(void **s)
{
    (void)s;
    char *data = make_dataset("conc", 400, 24);
    char *store = ts_path(dir, "conc_store");
    /* create the store first so readers can open it at once */
    mim_db_t *db;
    assert_int_equal(mim_db_open(&db, store, NULL, NULL), 0);
    mim_db_close(&db);
    pid_t readers[2];
    for (int r = 0; r < 2; r++) {
        readers[r] = fork();
        if (readers[r] == 0) _exit(reader_loop(store, 60));
    }
    char *out = NULL, *errs = NULL;
    const char *args[] = {"ingest", "--store", store, "--batch", "2", data, NULL};
    int rc = ts_run_mimic(&out, &errs, args);
    if (rc) fprintf(stderr, "%s\n%s\n", out, errs);
    assert_int_equal(rc, 0);
    for (int r = 0; r < 2; r++) {
        int st;
        waitpid(readers[r], &st, 0);
        assert_true(WIFEXITED(st));
        if (WEXITSTATUS(st)) fprintf(stderr, "reader %d exited %d\n", r, WEXITSTATUS(st));
        assert_int_equal(WEXITSTATUS(st), 0);
    }
    assert_int_equal(store_count(store), 400);
    free(out), free(errs), free(store), free(data);
}

typedef struct {
    char **names;
    uint64_t n, bad;
} sources_t;

static int collect(const mim_template_view_t *v, void *user)
{
    sources_t *s = user;
    if (mim_db_content_hash(v->positions, v->n_vertices) != v->content_hash) s->bad++;
    s->names[s->n++] = strdup(strrchr(v->source, '/') + 1);
    return 0;
}

static void test_kill_during_ingest(void **s)
{
    (void)s;
    enum { N = 600, BATCH = 3 };
    char *data = make_dataset("kill", N, 32);
    char *store = ts_path(dir, "kill_store");
    pid_t pid = fork();
    if (pid == 0) {
        int null = open("/dev/null", 1);
        dup2(null, 1), dup2(null, 2);
        execl(ts_mimic_bin(), ts_mimic_bin(), "ingest", "--store", store, "--batch", "3", data, (char *)NULL);
        _exit(127);
    }
    /* kill it once some batches are committed, while it is still going */
    double t0 = mim_now();
    uint64_t seen = 0;
    while (mim_now() - t0 < 60 && (seen = store_count(store)) < 4 * BATCH) usleep(500);
    kill(pid, SIGKILL);
    int st;
    waitpid(pid, &st, 0);
    assert_true(WIFSIGNALED(st));
    assert_int_equal(WTERMSIG(st), SIGKILL);

    /* the store opens, and holds exactly whole batches, in file order, intact */
    mim_db_t *db;
    mim_error_t err = {0};
    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&db, store, &ro, &err), 0);
    mim_db_txn_t *t;
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    sources_t src = {calloc(N, sizeof(char *)), 0, 0};
    assert_int_equal(mim_db_template_each(t, collect, &src, &err), 0);
    mim_db_abort(&t);
    mim_db_close(&db);
    fprintf(stderr, "killed after %llu committed templates of %d\n", (unsigned long long)src.n, N);
    assert_true(src.n >= seen);
    assert_true(src.n < N); /* it really was cut part-way */
    assert_int_equal(src.n % BATCH, 0);
    assert_int_equal(src.bad, 0);
    for (uint64_t i = 0; i < src.n; i++) {
        char want[64];
        snprintf(want, sizeof want, "ball_%04llu.ply", (unsigned long long)i);
        assert_string_equal(src.names[i], want);
        free(src.names[i]);
    }
    free(src.names);

    /* a re-run completes the work */
    char *out = NULL, *errs = NULL;
    const char *args[] = {"ingest", "--store", store, data, NULL};
    assert_int_equal(ts_run_mimic(&out, &errs, args), 0);
    assert_int_equal(store_count(store), N);
    assert_non_null(strstr(out, "already stored"));
    free(out), free(errs), free(store), free(data);
}

/* Encodings: a round trip, zero-copy and aligned, and a damaged record
 * (bad magic, a layout past its end) gets an error naming the template. */
static void test_encodings(void **s)
{
    (void)s;
    char *store = ts_path(dir, "encodings");
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    enum { N = 100 };
    float frames[6 * N], W[3 * N];
    for (int i = 0; i < 6 * N; i++) frames[i] = (float)i * 0.5f;
    for (int i = 0; i < 3 * N; i++) W[i] = -(float)i;
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_encoding_put(t, 7, frames, W, N, &err), 0);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    mim_db_encoding_t e;
    assert_int_equal(mim_db_encoding_get(t, 7, &e, &err), 0);
    assert_int_equal(e.n_vertices, N);
    assert_int_equal((uintptr_t)e.frames % 16, 0);
    assert_memory_equal(e.frames, frames, sizeof frames);
    assert_memory_equal(e.W, W, sizeof W);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_encoding_get(t, 8, &e, &err), MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "template 8: no encoding stored"));
    mim_db_abort(&t);
    mim_db_close(&db);

    /* damage records underneath, as a disk or another program could */
    MDB_env *env;
    MDB_txn *txn = raw_begin(store, 0, &env);
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "encodings", MDB_INTEGERKEY, &dbi), 0);
    unsigned char rec[4096] = {0};
    memcpy(rec, "XXXX", 4);
    size_t key = 9;
    MDB_val k = {sizeof key, &key}, d = {sizeof rec, rec};
    assert_int_equal(mdb_put(txn, dbi, &k, &d, 0), 0);
    /* right magic and checksum, but n_vertices says more than the record holds */
    uint32_t hdr = 48, n = 1000, fo = 48, wo = 48 + 24 * 1000;
    uint64_t id = 10;
    memcpy(rec, "MEN2", 4), memcpy(rec + 4, &hdr, 4), memcpy(rec + 16, &id, 8);
    memcpy(rec + 24, &n, 4), memcpy(rec + 28, &fo, 4), memcpy(rec + 32, &wo, 4);
    uint64_t ck = XXH3_64bits(rec + 16, sizeof rec - 16);
    memcpy(rec + 8, &ck, 8);
    key = 10;
    assert_int_equal(mdb_put(txn, dbi, &k, &d, 0), 0);
    /* a consistent record whose checksum does not match: one bit flipped */
    n = 10, wo = 48 + 240, id = 11;
    memcpy(rec + 16, &id, 8), memcpy(rec + 24, &n, 4), memcpy(rec + 32, &wo, 4);
    ck = XXH3_64bits(rec + 16, sizeof rec - 16);
    memcpy(rec + 8, &ck, 8);
    key = 11;
    assert_int_equal(mdb_put(txn, dbi, &k, &d, 0), 0);
    rec[100] ^= 4;
    key = 12, id = 12;
    memcpy(rec + 16, &id, 8);
    assert_int_equal(mdb_put(txn, dbi, &k, &d, 0), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);

    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    char want[512];
    err = (mim_error_t){0};
    assert_int_equal(mim_db_encoding_get(t, 9, &e, &err), MIM_ESTORE);
    snprintf(want, sizeof want, "store damaged: %s: template 9: encoding record has a bad magic", store);
    assert_string_equal(err.msg, want);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_encoding_get(t, 10, &e, &err), MIM_ESTORE);
    assert_non_null(strstr(err.msg, "template 10: encoding record layout is inconsistent"));
    err = (mim_error_t){0};
    assert_int_equal(mim_db_encoding_get(t, 12, &e, &err), MIM_ESTORE);
    assert_non_null(strstr(err.msg, "template 12: encoding checksum mismatch"));
    assert_null(e.frames); /* nothing lent out */
    err = (mim_error_t){0};
    assert_int_equal(mim_db_encoding_get(t, 11, &e, &err), 0); /* the intact one reads */
    assert_int_equal(e.n_vertices, 10);
    /* mimic store check lists each one */
    mim_db_abort(&t);
    mim_db_check_report_t r;
    assert_int_equal(mim_db_check(db, NULL, &r, &err), 0);
    assert_int_equal(r.encodings, 5);
    assert_true(r.problems >= 3);
    mim_db_close(&db);
    free(store);
}

/* An LMDB environment that never committed (a creation cut short between
 * LMDB's own set-up and mimic's first transaction) is no store yet: read-only
 * says so, a read-write open makes the store in it. One that committed but
 * holds no table is not a mimic store, and is left alone. */
static void test_fresh_environment(void **s)
{
    (void)s;
    char *store = ts_path(dir, "fresh");
    mkdir(store, 0755);
    MDB_env *env;
    assert_int_equal(mdb_env_create(&env), 0);
    assert_int_equal(mdb_env_open(env, store, 0, 0664), 0);
    mdb_env_close(env);
    mim_db_t *db;
    mim_error_t err = {0};
    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&db, store, &ro, &err), MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "no mimic store here"));
    err = (mim_error_t){0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_db_check_report_t r;
    assert_int_equal(mim_db_check(db, NULL, &r, &err), 0);
    assert_int_equal(r.problems, 0);
    assert_int_equal(r.schema_version, 4); /* schemas/store-version */
    mim_db_close(&db);

    char *other = ts_path(dir, "committed_empty");
    mkdir(other, 0755);
    MDB_txn *txn = raw_begin(other, 0, &env);
    MDB_dbi main_dbi;
    assert_int_equal(mdb_dbi_open(txn, NULL, 0, &main_dbi), 0);
    MDB_val k = {1, "k"}, v = {1, "v"};
    assert_int_equal(mdb_put(txn, main_dbi, &k, &v, 0), 0);
    assert_int_equal(mdb_del(txn, main_dbi, &k, NULL), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_open(&db, other, NULL, &err), MIM_ESTORE);
    assert_non_null(strstr(err.msg, "store damaged: "));
    assert_non_null(strstr(err.msg, "not a mimic store"));
    free(store), free(other);
}

/* A map that fills: the put fails saying so and that what was committed is
 * intact; it is. */
static void test_full_map(void **s)
{
    (void)s;
    char *store = ts_path(dir, "full");
    mim_db_options_t o = {.map_size = 1 << 20};
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, &o, &err), 0);
    enum { N = 20000 }; /* 240 KB a template */
    float *p = malloc(12 * N);
    int committed = 0, rc = 0;
    for (int i = 0; i < 8 && !rc; i++) {
        mim_db_txn_t *t;
        assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
        fill(p, N, (float)i);
        mim_template_in_t in = {p, N, mim_db_content_hash(p, N), "x.ply", "", "", NULL};
        rc = mim_db_template_put(t, &in, NULL, NULL, &err);
        if (!rc) rc = mim_db_commit(&t, &err);
        if (!rc) committed++;
        mim_db_abort(&t);
    }
    free(p);
    assert_int_equal(rc, MIM_ESTORE);
    assert_non_null(strstr(err.msg, store));
    assert_non_null(strstr(err.msg, "the store's map is full"));
    assert_non_null(strstr(err.msg, "everything committed before it is intact"));
    mim_db_close(&db);
    assert_true(committed >= 1);
    assert_int_equal(store_count(store), (uint64_t)committed);
    free(store);
}

/* ---- registrations and bindings (schema version 3) ---- */

/* A store with n small templates (ids 1..n), a connectivity, a landmark
 * map and, for the first n_enc, an encoding. */
static void make_store(const char *store, int n, int n_enc)
{
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    uint32_t faces[] = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
    assert_int_equal(mim_db_topology_put(t, faces, 4, 4, &err), 0);
    uint32_t lv[16];
    for (int i = 0; i < 16; i++) lv[i] = (uint32_t)i % 4;
    mim_landmark_map_t lm;
    mim_landmarks_default(&lm, lv, 4);
    assert_int_equal(mim_db_landmarks_put(t, &lm, &err), 0);
    for (int i = 0; i < n; i++) {
        float p[12], frames[24], W[12];
        fill(p, 4, (float)i);
        fill(frames, 8, (float)i);
        fill(W, 4, -(float)i);
        mim_template_in_t in = {p, 4, mim_db_content_hash(p, 4), "src.ply", "s", "p", NULL};
        uint64_t id = 0;
        assert_int_equal(mim_db_template_put(t, &in, &id, NULL, &err), 0);
        assert_int_equal(id, (uint64_t)i + 1);
        if (i < n_enc) assert_int_equal(mim_db_encoding_put(t, id, frames, W, 4, &err), 0);
    }
    assert_int_equal(mim_db_commit(&t, &err), 0);
    mim_db_close(&db);
}

static void assert_same_registration(const mim_db_registration_t *a, const mim_db_registration_t *b)
{
    assert_int_equal(a->template_id, b->template_id);
    assert_int_equal(a->source_hash, b->source_hash);
    assert_int_equal(a->source_vertices, b->source_vertices);
    assert_int_equal(a->iterations, b->iterations);
    assert_true(a->mean_mm == b->mean_mm && a->p95_mm == b->p95_mm && a->max_mm == b->max_mm &&
                a->landmark_mean_mm == b->landmark_mean_mm);
    /* the quality figures (MRG4) round trip; a version 3 record has none */
    assert_int_equal(a->quality.present, b->quality.present);
    if (a->quality.present) {
        assert_true(a->quality.landmark_max_mm == b->quality.landmark_max_mm &&
                    a->quality.volume_ratio == b->quality.volume_ratio);
        assert_memory_equal(a->quality.distortion_pct, b->quality.distortion_pct, sizeof a->quality.distortion_pct);
    }
}

/* Registrations: put, get and find by the source's hash round trip; an
 * unknown hash or template is MIM_ENOTFOUND with err untouched; the
 * lowest id answers for a source registered twice; a replaced source moves
 * its index entry; bad figures and templates that are not stored are
 * refused; store check is clean; mimic list shows them. */
static void test_registrations(void **s)
{
    (void)s;
    char *store = ts_path(dir, "registrations");
    make_store(store, 4, 0);
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    mim_db_registration_t r1 = {1, 0xA1A1A1A1A1A1A1A1ULL, 6890, 24, 0.41, 1.12, 3.5, 2.25, {0}};
    mim_db_registration_t r2 = {2, 0xB2, 12500, 30, 0.3, 0.9, 2.0, 1.5, {1, 4.5, 0.97, {1, 2, 3, 14, 5, 16}}}; /* MRG4 */
    mim_db_registration_t r3 = {3, r1.source_hash, 6890, 12, 0.5, 1.5, 4.0, 2.5, {0}}; /* r1's source again */
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &r3, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &r1, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &r2, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &r1, &err), 0); /* the same again: no second index entry */
    /* refused: a template that is not stored, a source without vertices, figures that are not distances */
    mim_db_registration_t bad = r1;
    bad.template_id = 99;
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_put(t, &bad, &err), MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "registration of template 99: no such template"));
    bad = r1;
    bad.source_vertices = 0;
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_put(t, &bad, &err), MIM_EINVAL);
    bad = r1;
    bad.p95_mm = NAN;
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_put(t, &bad, &err), MIM_EINVAL);
    bad = r1;
    bad.max_mm = -1;
    assert_int_equal(mim_db_registration_put(t, &bad, NULL), MIM_EINVAL);
    /* visible inside the writing transaction */
    mim_db_registration_t got;
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_find(t, r2.source_hash, &got, &err), 0);
    assert_same_registration(&got, &r2);
    assert_int_equal(mim_db_commit(&t, &err), 0);

    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    assert_int_equal(mim_db_registration_get(t, 1, &got, &err), 0);
    assert_same_registration(&got, &r1);
    assert_int_equal(mim_db_registration_get(t, 3, &got, &err), 0);
    assert_same_registration(&got, &r3);
    assert_int_equal(mim_db_registration_find(t, r1.source_hash, &got, &err), 0);
    assert_same_registration(&got, &r1); /* templates 1 and 3: the lowest id */
    assert_int_equal(mim_db_registration_find(t, r2.source_hash, &got, &err), 0);
    assert_same_registration(&got, &r2);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_find(t, 0xC3, &got, &err), MIM_ENOTFOUND);
    assert_int_equal(err.code, 0); /* an ordinary answer, not an error */
    assert_int_equal(got.template_id, 0);
    assert_int_equal(mim_db_registration_get(t, 4, &got, &err), MIM_ENOTFOUND); /* stored, not registered */
    assert_int_equal(mim_db_registration_get(t, 99, &got, &err), MIM_ENOTFOUND);
    assert_int_equal(err.code, 0);
    /* a read transaction cannot write */
    assert_int_equal(mim_db_registration_put(t, &r1, &err), MIM_EINVAL);
    mim_db_abort(&t);

    /* template 2 registered again from another source: its entry moves */
    mim_db_registration_t r2b = r2;
    r2b.source_hash = 0xC3;
    r2b.mean_mm = 0.25;
    err = (mim_error_t){0};
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &r2b, &err), 0);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    assert_int_equal(mim_db_registration_find(t, 0xB2, &got, &err), MIM_ENOTFOUND);
    assert_int_equal(mim_db_registration_find(t, 0xC3, &got, &err), 0);
    assert_same_registration(&got, &r2b);
    assert_int_equal(mim_db_registration_get(t, 2, &got, &err), 0);
    assert_same_registration(&got, &r2b);
    mim_db_abort(&t);
    mim_db_check_report_t r;
    assert_int_equal(mim_db_check(db, NULL, &r, &err), 0);
    assert_int_equal(r.problems, 0);
    assert_int_equal(r.registrations, 3);
    assert_int_equal(r.source_entries, 3);
    mim_db_close(&db);

    /* mimic list: the figures of registered templates, nothing for the others */
    char *out = NULL, *errs = NULL;
    const char *json_args[] = {"list", "--store", store, "--json", NULL};
    assert_int_equal(ts_run_mimic(&out, &errs, json_args), 0);
    json_error_t je;
    json_t *j = json_loads(out, 0, &je);
    assert_non_null(j);
    assert_int_equal(json_array_size(j), 4);
    json_t *reg = json_object_get(json_array_get(j, 0), "registration");
    assert_non_null(reg);
    assert_true(json_real_value(json_object_get(reg, "mean_mm")) == 0.41);
    assert_true(json_real_value(json_object_get(reg, "p95_mm")) == 1.12);
    assert_true(json_real_value(json_object_get(reg, "max_mm")) == 3.5);
    assert_int_equal(json_integer_value(json_object_get(reg, "iterations")), 24);
    assert_int_equal(json_integer_value(json_object_get(reg, "source_vertices")), 6890);
    assert_true(json_real_value(json_object_get(reg, "landmark_mean_mm")) == 2.25);
    assert_int_equal(json_object_size(reg), 6); /* a version 3 record: no quality figures */
    assert_true(json_real_value(json_object_get(json_object_get(json_array_get(j, 1), "registration"), "mean_mm")) == 0.25);
    assert_null(json_object_get(json_array_get(j, 3), "registration"));
    json_decref(j);
    free(out), free(errs);
    const char *text_args[] = {"list", "--store", store, NULL};
    assert_int_equal(ts_run_mimic(&out, &errs, text_args), 0);
    assert_non_null(strstr(out, "src.ply  registered 0.41/1.12 mm, landmarks 2.2 mm\n"));
    assert_non_null(strstr(out, "       4  s          p          src.ply\n")); /* not registered: as before */
    free(out), free(errs), free(store);
}

/* A registration record as mimic writes it (schemas/store.md), for raw puts. */
static void registration_bytes(unsigned char rec[72], const mim_db_registration_t *r)
{
    uint32_t size = 72;
    memset(rec, 0, 72);
    memcpy(rec, "MRG3", 4), memcpy(rec + 4, &size, 4);
    memcpy(rec + 16, &r->template_id, 8), memcpy(rec + 24, &r->source_hash, 8);
    memcpy(rec + 32, &r->source_vertices, 4), memcpy(rec + 36, &r->iterations, 4);
    memcpy(rec + 40, &r->mean_mm, 8), memcpy(rec + 48, &r->p95_mm, 8), memcpy(rec + 56, &r->max_mm, 8);
    memcpy(rec + 64, &r->landmark_mean_mm, 8);
    uint64_t ck = XXH3_64bits(rec + 16, 72 - 16);
    memcpy(rec + 8, &ck, 8);
}

typedef struct {
    char lines[16][512];
    char tables[16][32];
    uint64_t ids[16];
    int n;
} problems_t;

static void collect_problem(void *ctx, const mim_db_problem_t *p)
{
    problems_t *ps = ctx;
    if (ps->n >= 16) return;
    snprintf(ps->lines[ps->n], sizeof ps->lines[0], "%s", p->message);
    snprintf(ps->tables[ps->n], sizeof ps->tables[0], "%s", p->table);
    ps->ids[ps->n++] = p->id;
}

/* Whether check reported `line` ("store damaged: STORE: " + line) for table and id. */
static int has_problem(const problems_t *ps, const char *store, const char *line, const char *table, uint64_t id)
{
    char want[512];
    snprintf(want, sizeof want, "store damaged: %s: %s", store, line);
    for (int i = 0; i < ps->n; i++)
        if (!strcmp(ps->lines[i], want) && !strcmp(ps->tables[i], table) && ps->ids[i] == id) return 1;
    return 0;
}

/* Damaged registrations, written underneath through LMDB: a flipped byte
 * fails its checksum for get, find and mimic list; a registration of a
 * template that is not stored, one missing from the source index and a
 * source-index entry without a registration are each a problem for store
 * check; the intact registration still reads. */
static void test_registration_damaged(void **s)
{
    (void)s;
    char *store = ts_path(dir, "registrations_damaged");
    make_store(store, 2, 0);
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    mim_db_registration_t r1 = {1, 0xA1, 6890, 24, 0.41, 1.12, 3.5, 2.25, {0}}, r2 = {2, 0xB2, 6890, 20, 0.3, 0.9, 2.0, 1.5, {0}};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &r1, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &r2, &err), 0);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    mim_db_close(&db);

    MDB_env *env;
    MDB_txn *txn = raw_begin(store, 0, &env);
    MDB_dbi regs, by_source;
    assert_int_equal(mdb_dbi_open(txn, "registrations", MDB_INTEGERKEY, &regs), 0);
    assert_int_equal(mdb_dbi_open(txn, "by_source", MDB_INTEGERKEY | MDB_DUPSORT | MDB_DUPFIXED | MDB_INTEGERDUP,
                                  &by_source), 0);
    /* one bit of registration 1's p95 flipped */
    size_t key = 1;
    MDB_val k = {sizeof key, &key}, v;
    assert_int_equal(mdb_get(txn, regs, &k, &v), 0);
    assert_int_equal(v.mv_size, 72);
    unsigned char rec[72];
    memcpy(rec, v.mv_data, 72);
    rec[50] ^= 0x10;
    MDB_val d = {72, rec};
    assert_int_equal(mdb_put(txn, regs, &k, &d, 0), 0);
    /* a registration of template 42, which is not stored, and not in the source index */
    mim_db_registration_t r42 = {42, 0x42, 100, 1, 1, 2, 3, 4, {0}};
    registration_bytes(rec, &r42);
    key = 42;
    assert_int_equal(mdb_put(txn, regs, &k, &d, 0), 0);
    /* a source-index entry naming template 2, which has a registration of another source, and
     * one naming template 7, which has none */
    size_t h = 0xDEAD, id = 2;
    MDB_val hk = {sizeof h, &h}, hv = {sizeof id, &id};
    assert_int_equal(mdb_put(txn, by_source, &hk, &hv, 0), 0);
    h = 0xBEEF, id = 7;
    assert_int_equal(mdb_put(txn, by_source, &hk, &hv, 0), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);

    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&db, store, &ro, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    mim_db_registration_t got;
    char want[512];
    snprintf(want, sizeof want, "store damaged: %s: registration 1: checksum mismatch", store);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_get(t, 1, &got, &err), MIM_ESTORE);
    assert_string_equal(err.msg, want);
    assert_int_equal(got.template_id, 0); /* nothing handed out */
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_find(t, 0xA1, &got, &err), MIM_ESTORE);
    assert_string_equal(err.msg, want);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_find(t, 0xBEEF, &got, &err), MIM_ESTORE);
    assert_non_null(strstr(err.msg, "source index: entry 000000000000beef names template 7, which has no registration"));
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_find(t, 0xDEAD, &got, &err), MIM_ESTORE);
    assert_non_null(strstr(err.msg, "names template 2, registered from source 00000000000000b2"));
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_get(t, 2, &got, &err), 0); /* the intact one reads */
    assert_same_registration(&got, &r2);
    assert_int_equal(mim_db_registration_find(t, 0xB2, &got, &err), 0);
    mim_db_abort(&t);

    problems_t ps = {0};
    mim_db_check_options_t co = {.problem = collect_problem, .problem_ctx = &ps};
    mim_db_check_report_t r;
    assert_int_equal(mim_db_check(db, &co, &r, &err), 0);
    mim_db_close(&db);
    if (r.problems != 5)
        for (int i = 0; i < ps.n; i++) fprintf(stderr, "check: %s (%s)\n", ps.lines[i], ps.tables[i]);
    assert_int_equal(r.registrations, 3);
    assert_int_equal(r.source_entries, 4);
    assert_int_equal(r.problems, 5);
    assert_true(has_problem(&ps, store, "registration 1: checksum mismatch", "registrations", 1));
    assert_true(has_problem(&ps, store, "registration 42: template 42 is not stored", "registrations", 42));
    assert_true(has_problem(&ps, store, "registration 42: missing from the source index", "registrations", 42));
    assert_true(has_problem(&ps, store, "source index: entry 000000000000dead names template 2, registered from source "
                                        "00000000000000b2", "by_source", 2));
    assert_true(has_problem(&ps, store, "source index: entry 000000000000beef names template 7, which has no "
                                        "registration", "by_source", 7));

    /* mimic list refuses in one line, and so does a put beside the damage */
    char *out = NULL, *errs = NULL;
    const char *list[] = {"list", "--store", store, "--json", NULL};
    assert_int_equal(ts_run_mimic(&out, &errs, list), 2);
    snprintf(want, sizeof want, "mimic list: store damaged: %s: registration 1: checksum mismatch\n", store);
    assert_string_equal(errs, want);
    free(out), free(errs);
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_registration_put(t, &r1, &err), MIM_ESTORE);
    assert_non_null(strstr(err.msg, "registration 1: checksum mismatch"));
    mim_db_abort(&t);
    mim_db_close(&db);
    free(store);
}

/* Bindings: a 3 MB blob round trips zero-copy and aligned, a put replaces,
 * an unknown key is MIM_ENOTFOUND with err untouched, and a flipped byte
 * underneath fails its checksum (get and store check). */
static void test_bindings(void **s)
{
    (void)s;
    char *store = ts_path(dir, "bindings");
    make_store(store, 1, 0);
    enum { BIG = 3 << 20 };
    unsigned char *blob = malloc(BIG);
    mim_rng_t rng;
    mim_rng_seed(&rng, 3, 0);
    for (size_t i = 0; i < BIG; i++) blob[i] = (unsigned char)mim_rng_u64(&rng);
    const uint64_t k1 = 0x0123456789abcdefULL, k2 = 0xfedcba9876543210ULL, k3 = 5;
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_binding_put(t, k1, blob, BIG, &err), 0);
    assert_int_equal(mim_db_binding_put(t, k2, blob, BIG, &err), 0);
    assert_int_equal(mim_db_binding_put(t, k2, "small", 5, &err), 0); /* replaces */
    assert_int_equal(mim_db_binding_put(t, k3, NULL, 0, &err), 0);    /* empty is a blob too */
    assert_int_equal(mim_db_binding_put(t, 6, NULL, 10, &err), MIM_EINVAL);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    mim_db_close(&db);

    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&db, store, &ro, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    const void *got = NULL, *again = NULL;
    size_t len = 0, len2 = 0;
    assert_int_equal(mim_db_binding_get(t, k1, &got, &len, &err), 0);
    assert_int_equal(len, BIG);
    assert_memory_equal(got, blob, BIG);
    assert_int_equal((uintptr_t)got % 16, 0);
    assert_int_equal(mim_db_binding_get(t, k1, &again, &len2, &err), 0);
    assert_ptr_equal(again, got); /* zero-copy: the map's bytes */
    assert_int_equal(mim_db_binding_get(t, k2, &got, &len, &err), 0);
    assert_int_equal(len, 5);
    assert_memory_equal(got, "small", 5);
    assert_int_equal(mim_db_binding_get(t, k3, &got, &len, &err), 0);
    assert_int_equal(len, 0);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_binding_get(t, 77, &got, &len, &err), MIM_ENOTFOUND);
    assert_int_equal(err.code, 0);
    assert_null(got);
    assert_int_equal(mim_db_binding_put(t, 77, "x", 1, &err), MIM_EINVAL); /* a read transaction */
    mim_db_abort(&t);
    mim_db_check_report_t r;
    assert_int_equal(mim_db_check(db, NULL, &r, &err), 0);
    assert_int_equal(r.problems, 0);
    assert_int_equal(r.bindings, 3);
    mim_db_close(&db);

    /* one bit of the big blob flipped underneath */
    MDB_env *env;
    MDB_txn *txn = raw_begin(store, 0, &env);
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "bindings", MDB_INTEGERKEY, &dbi), 0);
    size_t key = (size_t)k1;
    MDB_val k = {sizeof key, &key}, v;
    assert_int_equal(mdb_get(txn, dbi, &k, &v), 0);
    unsigned char *copy = malloc(v.mv_size);
    memcpy(copy, v.mv_data, v.mv_size);
    copy[32 + BIG / 2] ^= 0x10;
    MDB_val d = {v.mv_size, copy};
    assert_int_equal(mdb_put(txn, dbi, &k, &d, 0), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);
    free(copy);

    assert_int_equal(mim_db_open(&db, store, &ro, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_binding_get(t, k1, &got, &len, &err), MIM_ESTORE);
    char want[512];
    snprintf(want, sizeof want, "store damaged: %s: binding 0123456789abcdef: checksum mismatch", store);
    assert_string_equal(err.msg, want);
    assert_null(got);
    assert_int_equal(mim_db_binding_get(t, k2, &got, &len, &err), 0); /* the others still read */
    mim_db_abort(&t);
    problems_t ps = {0};
    mim_db_check_options_t co = {.problem = collect_problem, .problem_ctx = &ps};
    assert_int_equal(mim_db_check(db, &co, &r, &err), 0);
    assert_int_equal(r.problems, 1);
    assert_true(has_problem(&ps, store, "binding 0123456789abcdef: checksum mismatch", "bindings", 0));
    mim_db_close(&db);
    free(blob), free(store);
}

static void on_log(void *ctx, int level, const char *msg)
{
    (void)level;
    snprintf(ctx, 512, "%s", msg);
}

/* A version-2 store: schema version 3 only added the registrations,
 * by_source and bindings tables (no record layout changed), so a store of
 * this mimic with those tables dropped and schema_version set to 2 is
 * exactly what mimic wrote at version 2. Read-only it reads as it is:
 * registrations and bindings are not found, without an error, store check
 * is clean, and nothing is created. The first read-write open migrates it
 * (tables and version in one transaction), keeping every template and
 * encoding. A version-2 store whose new table holds records is refused. */
static void test_migrate_v2(void **s)
{
    (void)s;
    char *store = ts_path(dir, "v2");
    make_store(store, 5, 3);
    static const char *const added[] = {"registrations", "by_source", "bindings"};
    MDB_env *env;
    MDB_txn *txn = raw_begin(store, 0, &env);
    for (int i = 0; i < 3; i++) {
        MDB_dbi dbi;
        assert_int_equal(mdb_dbi_open(txn, added[i], 0, &dbi), 0);
        assert_int_equal(mdb_drop(txn, dbi, 1), 0);
    }
    MDB_dbi meta;
    assert_int_equal(mdb_dbi_open(txn, "meta", 0, &meta), 0);
    uint64_t two = 2;
    MDB_val k = {14, "schema_version"}, d = {8, &two};
    assert_int_equal(mdb_put(txn, meta, &k, &d, 0), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);
    for (int i = 0; i < 3; i++) assert_false(has_table(store, added[i]));

    /* read-only: as it is */
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    mim_db_options_t ro = {.read_only = 1};
    int rc = mim_db_open(&db, store, &ro, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    mim_db_meta_t m;
    assert_int_equal(mim_db_meta_get(t, &m, &err), 0);
    assert_int_equal(m.schema_version, 2);
    assert_int_equal(m.templates, 5);
    mim_db_registration_t reg;
    const void *blob;
    size_t len;
    assert_int_equal(mim_db_registration_get(t, 1, &reg, &err), MIM_ENOTFOUND);
    assert_int_equal(mim_db_registration_find(t, 0xA1, &reg, &err), MIM_ENOTFOUND);
    assert_int_equal(mim_db_binding_get(t, 1, &blob, &len, &err), MIM_ENOTFOUND);
    assert_int_equal(err.code, 0);
    mim_template_view_t v;
    assert_int_equal(mim_db_template_get(t, 5, &v, &err), 0);
    mim_db_abort(&t);
    mim_db_check_report_t r;
    assert_int_equal(mim_db_check(db, NULL, &r, &err), 0);
    assert_int_equal(r.problems, 0);
    assert_int_equal(r.schema_version, 2);
    assert_int_equal(r.templates, 5);
    mim_db_close(&db);
    char *out = NULL, *errs = NULL;
    const char *list[] = {"list", "--store", store, "--json", NULL};
    assert_int_equal(ts_run_mimic(&out, &errs, list), 0);
    json_t *j = json_loads(out, 0, NULL);
    assert_int_equal(json_array_size(j), 5);
    assert_null(json_object_get(json_array_get(j, 0), "registration"));
    json_decref(j);
    free(out), free(errs);
    for (int i = 0; i < 3; i++) assert_false(has_table(store, added[i])); /* nothing created */

    /* a version-2 store holding records in a table it should not have is not migrated */
    char *odd = ts_path(dir, "v2_odd");
    mkdir(odd, 0755);
    char *src = ts_path(store, "data.mdb"), *dst = ts_path(odd, "data.mdb");
    size_t n = 0;
    char *bytes = ts_read_file(src, &n);
    assert_int_equal(ts_write_file(dst, bytes, n), 0);
    free(bytes), free(src), free(dst);
    txn = raw_begin(odd, 0, &env);
    MDB_dbi bind;
    assert_int_equal(mdb_dbi_open(txn, "bindings", MDB_CREATE | MDB_INTEGERKEY, &bind), 0);
    size_t bk = 1;
    MDB_val kk = {sizeof bk, &bk}, vv = {3, "abc"};
    assert_int_equal(mdb_put(txn, bind, &kk, &vv, 0), 0);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_open(&db, odd, NULL, &err), MIM_ESTORE);
    assert_non_null(strstr(err.msg, "store damaged: "));
    assert_non_null(strstr(err.msg, "with 1 records in its 'bindings' table (found while migrating"));
    assert_null(db);
    assert_false(has_table(odd, "registrations")); /* nothing changed */
    free(odd);

    /* the first read-write open migrates, in one transaction */
    char logged[512] = "";
    mim_db_options_t rw = {.log = on_log, .log_ctx = logged};
    err = (mim_error_t){0};
    rc = mim_db_open(&db, store, &rw, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, 0);
    mim_db_close(&db);
    char want[512];
    snprintf(want, sizeof want,
             "%s: migrated from schema version 2 to 4: added the registrations, by_source and bindings tables (empty)",
             store);
    assert_string_equal(logged, want);
    for (int i = 0; i < 3; i++) assert_true(has_table(store, added[i]));
    assert_int_equal(mim_db_open(&db, store, &ro, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    assert_int_equal(mim_db_meta_get(t, &m, &err), 0);
    assert_int_equal(m.schema_version, 4);
    assert_int_equal(m.templates, 5);
    assert_int_equal(m.next_id, 6);
    for (uint64_t id = 1; id <= 5; id++) {
        float p[12];
        fill(p, 4, (float)(id - 1));
        assert_int_equal(mim_db_template_get(t, id, &v, &err), 0);
        assert_memory_equal(v.positions, p, sizeof p);
        mim_db_encoding_t e;
        assert_int_equal(mim_db_encoding_get(t, id, &e, NULL), id <= 3 ? 0 : MIM_ENOTFOUND);
    }
    assert_int_equal(mim_db_registration_get(t, 1, &reg, &err), MIM_ENOTFOUND);
    mim_db_abort(&t);
    assert_int_equal(mim_db_check(db, NULL, &r, &err), 0);
    assert_int_equal(r.problems, 0);
    assert_int_equal(r.schema_version, 4);
    assert_int_equal(r.templates, 5);
    assert_int_equal(r.encodings, 3);
    mim_db_close(&db);
    /* and takes registrations; a second open has nothing to do */
    logged[0] = 0;
    assert_int_equal(mim_db_open(&db, store, &rw, &err), 0);
    assert_string_equal(logged, "");
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    mim_db_registration_t r1 = {1, 0xA1, 6890, 24, 0.41, 1.12, 3.5, 2.25, {0}};
    assert_int_equal(mim_db_registration_put(t, &r1, &err), 0);
    assert_int_equal(mim_db_binding_put(t, 1, "abc", 3, &err), 0);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    assert_int_equal(mim_db_registration_find(t, 0xA1, &reg, &err), 0);
    assert_same_registration(&reg, &r1);
    mim_db_abort(&t);
    mim_db_close(&db);
    free(store);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_dedupe),
        cmocka_unit_test(test_schema_mismatch),
        cmocka_unit_test(test_not_a_store),
        cmocka_unit_test(test_readers_while_writing),
        cmocka_unit_test(test_kill_during_ingest),
        cmocka_unit_test(test_encodings),
        cmocka_unit_test(test_legacy_descriptors_table),
        cmocka_unit_test(test_map_size_option),
        cmocka_unit_test(test_fresh_environment),
        cmocka_unit_test(test_full_map),
        cmocka_unit_test(test_registrations),
        cmocka_unit_test(test_registration_damaged),
        cmocka_unit_test(test_bindings),
        cmocka_unit_test(test_migrate_v2),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
