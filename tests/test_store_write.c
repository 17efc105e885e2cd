/* The store's writes: a version-1 store is read as it is and migrated
 * (1 -> 2 -> 3 in one transaction), every record intact; a full map or file says so and keeps every committed
 * batch (issue 12, defect 9a); two first ingests racing on one empty store
 * end clearly (9b). Shared helpers and the fixture: support/store_support.c. */
#include "mim_db.h"
#include "store_support.h"

#include <jansson.h>
#include <lmdb.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

/* ---- schema version 1: written here in the old layouts through LMDB ---- */
typedef struct {
    MDB_txn *txn;
    MDB_dbi templates, by_hash, encodings;
    mim_db_txn_t *src;
    int with_encodings;
} v1_writer_t;

static void put_padded(MDB_txn *txn, MDB_dbi dbi, MDB_val *k, const void *p, size_t len)
{
    size_t size = len < 2048 ? 2048 : len;
    MDB_val v = {size, NULL};
    assert_int_equal(mdb_put(txn, dbi, k, &v, MDB_RESERVE), 0);
    memset(v.mv_data, 0, size);
    memcpy(v.mv_data, p, len);
}

static int v1_template(const mim_template_view_t *t, void *user)
{
    v1_writer_t *w = user;
    size_t ls = strlen(t->source), lsub = strlen(t->subject), lpose = strlen(t->pose);
    size_t pos_off = (48 + ls + lsub + lpose + 3 + 15) & ~(size_t)15, len = pos_off + 12 * (size_t)t->n_vertices;
    unsigned char *r = calloc(1, len);
    uint32_t hdr = 48, po = (uint32_t)pos_off;
    uint16_t l1 = (uint16_t)ls, l2 = (uint16_t)lsub, l3 = (uint16_t)lpose;
    memcpy(r, "MTP1", 4), memcpy(r + 4, &hdr, 4), memcpy(r + 8, &t->id, 8), memcpy(r + 16, &t->content_hash, 8);
    memcpy(r + 24, &t->n_vertices, 4), memcpy(r + 28, &po, 4);
    memcpy(r + 32, &l1, 2), memcpy(r + 34, &l2, 2), memcpy(r + 36, &l3, 2);
    memcpy(r + 48, t->source, ls), memcpy(r + 48 + ls + 1, t->subject, lsub);
    memcpy(r + 48 + ls + 1 + lsub + 1, t->pose, lpose);
    memcpy(r + pos_off, t->positions, 12 * (size_t)t->n_vertices);
    size_t key = (size_t)t->id, h = (size_t)t->content_hash;
    MDB_val k = {sizeof key, &key}, hk = {sizeof h, &h}, hv = {sizeof key, &key};
    put_padded(w->txn, w->templates, &k, r, len);
    assert_int_equal(mdb_put(w->txn, w->by_hash, &hk, &hv, 0), 0);
    free(r);
    mim_db_encoding_t e;
    if (w->with_encodings && mim_db_encoding_get(w->src, t->id, &e, NULL) == 0) {
        size_t wo = (32 + 24 * (size_t)e.n_vertices + 15) & ~(size_t)15, elen = wo + 12 * (size_t)e.n_vertices;
        unsigned char *er = calloc(1, elen);
        uint32_t ehdr = 32, n = e.n_vertices, fo = 32, wo32 = (uint32_t)wo;
        memcpy(er, "MEN1", 4), memcpy(er + 4, &ehdr, 4), memcpy(er + 8, &t->id, 8), memcpy(er + 16, &n, 4);
        memcpy(er + 20, &fo, 4), memcpy(er + 24, &wo32, 4);
        memcpy(er + 32, e.frames, 24 * (size_t)n), memcpy(er + wo, e.W, 12 * (size_t)n);
        put_padded(w->txn, w->encodings, &k, er, elen);
        free(er);
    }
    return 0;
}

/* Writes the records of src (a current store) into a new store dst in the
 * layouts of schema version 1, as mimic 0.1.0 did. */
static void write_v1_store(const char *src, const char *dst, int with_encodings)
{
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    st_begin_read(src, &db, &t);
    mim_db_meta_t meta;
    mim_db_topology_t topo;
    mim_landmark_map_t map;
    mim_db_index_meta_t im;
    const void *blob;
    size_t blob_len;
    assert_int_equal(mim_db_meta_get(t, &meta, &err), 0);
    assert_int_equal(mim_db_topology_get(t, &topo, &err), 0);
    assert_int_equal(mim_db_landmarks_get(t, &map, &err), 0);
    int has_index = mim_db_index_get(t, &blob, &blob_len, &im, NULL) == 0;

    mkdir(dst, 0755);
    MDB_env *env;
    assert_int_equal(mdb_env_create(&env), 0);
    mdb_env_set_maxdbs(env, 16);
    mdb_env_set_mapsize(env, 1ULL << 30);
    assert_int_equal(mdb_env_open(env, dst, 0, 0664), 0);
    v1_writer_t w = {.src = t, .with_encodings = with_encodings};
    MDB_dbi meta_dbi, topo_dbi, lm_dbi;
    assert_int_equal(mdb_txn_begin(env, NULL, 0, &w.txn), 0);
    assert_int_equal(mdb_dbi_open(w.txn, "meta", MDB_CREATE, &meta_dbi), 0);
    assert_int_equal(mdb_dbi_open(w.txn, "topology", MDB_CREATE, &topo_dbi), 0);
    assert_int_equal(mdb_dbi_open(w.txn, "landmarks", MDB_CREATE, &lm_dbi), 0);
    assert_int_equal(mdb_dbi_open(w.txn, "templates", MDB_CREATE | MDB_INTEGERKEY, &w.templates), 0);
    assert_int_equal(mdb_dbi_open(w.txn, "by_hash",
                                  MDB_CREATE | MDB_INTEGERKEY | MDB_DUPSORT | MDB_DUPFIXED | MDB_INTEGERDUP, &w.by_hash),
                     0);
    if (with_encodings)
        assert_int_equal(mdb_dbi_open(w.txn, "encodings", MDB_CREATE | MDB_INTEGERKEY, &w.encodings), 0);
    uint64_t one = 1;
    const char *by = "mimic 0.1.0";
    MDB_val k1 = {14, "schema_version"}, d1 = {8, &one}, k2 = {10, "created_by"}, d2 = {strlen(by), (void *)by};
    MDB_val k3 = {7, "next_id"}, d3 = {8, &meta.next_id};
    assert_int_equal(mdb_put(w.txn, meta_dbi, &k1, &d1, 0), 0);
    assert_int_equal(mdb_put(w.txn, meta_dbi, &k2, &d2, 0), 0);
    assert_int_equal(mdb_put(w.txn, meta_dbi, &k3, &d3, 0), 0);
    size_t tlen = 16 + 12 * (size_t)topo.n_faces;
    unsigned char *tr = calloc(1, tlen);
    memcpy(tr, &topo.n_vertices, 4), memcpy(tr + 4, &topo.n_faces, 4), memcpy(tr + 8, &topo.hash, 8);
    memcpy(tr + 16, topo.faces, 12 * (size_t)topo.n_faces);
    MDB_val tk = {5, "faces"};
    put_padded(w.txn, topo_dbi, &tk, tr, tlen);
    free(tr);
    char *json = mim_landmarks_to_json(&map);
    MDB_val lk = {3, "map"}, lv = {strlen(json), json};
    assert_int_equal(mdb_put(w.txn, lm_dbi, &lk, &lv, 0), 0);
    free(json);
    assert_int_equal(mim_db_template_each(t, v1_template, &w, &err), 0);
    if (has_index) {
        unsigned char rec[40] = {0};
        memcpy(rec, "MIB1", 4), memcpy(rec + 4, &im.class_source, 4), memcpy(rec + 8, &im.next_id, 8);
        memcpy(rec + 16, &im.templates, 8), memcpy(rec + 24, &im.n_classes, 4), memcpy(rec + 28, &im.d, 4);
        memcpy(rec + 32, &im.built_at, 8);
        MDB_val mk = {11, "index.model"}, mv = {blob_len, (void *)blob}, bk = {11, "index.build"}, bv = {40, rec};
        assert_int_equal(mdb_put(w.txn, meta_dbi, &mk, &mv, 0), 0);
        assert_int_equal(mdb_put(w.txn, meta_dbi, &bk, &bv, 0), 0);
    }
    assert_int_equal(mdb_txn_commit(w.txn), 0);
    mdb_env_close(env);
    mim_db_abort(&t);
    mim_db_close(&db);
}

/* Everything two stores hold is the same (b read through the API). */
typedef struct {
    mim_db_txn_t *other;
    int checked;
} same_t;

static int same_template(const mim_template_view_t *a, void *user)
{
    same_t *s = user;
    mim_template_view_t b;
    mim_error_t err = {0};
    assert_int_equal(mim_db_template_get(s->other, a->id, &b, &err), 0);
    assert_int_equal(a->n_vertices, b.n_vertices);
    assert_int_equal(a->content_hash, b.content_hash);
    assert_memory_equal(a->positions, b.positions, 12 * (size_t)a->n_vertices);
    assert_string_equal(a->source, b.source);
    assert_string_equal(a->subject, b.subject);
    assert_string_equal(a->pose, b.pose);
    mim_db_encoding_t eb;
    if (mim_db_encoding_get(s->other, a->id, &eb, NULL) == 0) {
        assert_int_equal(eb.n_vertices, a->n_vertices);
        s->checked++;
    }
    return 0;
}

static void assert_same_stores(const char *a_dir, const char *b_dir, uint32_t b_version, int encodings)
{
    mim_db_t *a, *b;
    mim_error_t err = {0};
    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&a, a_dir, &ro, &err), 0);
    int rc = mim_db_open(&b, b_dir, &ro, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, 0);
    mim_db_txn_t *ta, *tb;
    assert_int_equal(mim_db_begin(a, 0, &ta, &err), 0);
    assert_int_equal(mim_db_begin(b, 0, &tb, &err), 0);
    mim_db_meta_t ma, mb;
    assert_int_equal(mim_db_meta_get(ta, &ma, &err), 0);
    assert_int_equal(mim_db_meta_get(tb, &mb, &err), 0);
    assert_int_equal(mb.schema_version, b_version);
    assert_int_equal(ma.templates, mb.templates);
    assert_int_equal(ma.next_id, mb.next_id);
    mim_db_topology_t pa, pb;
    assert_int_equal(mim_db_topology_get(ta, &pa, &err), 0);
    assert_int_equal(mim_db_topology_get(tb, &pb, &err), 0);
    assert_int_equal(pa.n_faces, pb.n_faces);
    assert_memory_equal(pa.faces, pb.faces, 12 * (size_t)pa.n_faces);
    mim_landmark_map_t la, lb;
    assert_int_equal(mim_db_landmarks_get(ta, &la, &err), 0);
    assert_int_equal(mim_db_landmarks_get(tb, &lb, &err), 0);
    char *ja = mim_landmarks_to_json(&la), *jb = mim_landmarks_to_json(&lb);
    assert_string_equal(ja, jb);
    free(ja), free(jb);
    const void *ba, *bb;
    size_t na, nb;
    mim_db_index_meta_t ia, ib;
    assert_int_equal(mim_db_index_get(ta, &ba, &na, &ia, &err), 0);
    assert_int_equal(mim_db_index_get(tb, &bb, &nb, &ib, &err), 0);
    assert_int_equal(na, nb);
    assert_memory_equal(ba, bb, na);
    assert_memory_equal(&ia, &ib, sizeof ia);
    same_t s = {tb, 0};
    assert_int_equal(mim_db_template_each(ta, same_template, &s, &err), 0);
    assert_int_equal(s.checked, encodings ? (int)ma.templates : 0);
    mim_db_abort(&ta), mim_db_abort(&tb);
    mim_db_close(&a), mim_db_close(&b);
}

/* A landmark frame of template 1, for mimic query. */
static char *frame_file(void)
{
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    st_begin_read(st_good, &db, &t);
    mim_template_view_t v;
    mim_landmark_map_t map;
    assert_int_equal(mim_db_template_get(t, 1, &v, &err), 0);
    assert_int_equal(mim_db_landmarks_get(t, &map, &err), 0);
    char *path = ts_path(st_dir, "frame.json");
    FILE *f = fopen(path, "w");
    fprintf(f, "{\"landmarks\": [");
    for (uint32_t i = 0; i < map.count; i++) {
        const float *p = v.positions + 3 * (size_t)map.vertex[i];
        fprintf(f, "%s[%.9g, %.9g, %.9g]", i ? ", " : "", p[0], p[1], p[2]);
    }
    fprintf(f, "]}\n");
    fclose(f);
    mim_db_abort(&t);
    mim_db_close(&db);
    return path;
}

static char *query(const char *store, const char *frame)
{
    char *out = NULL, *err = NULL;
    const char *args[] = {"query", "--store", store, "--landmarks", frame, "-k", "3", "--json", NULL};
    int code = st_exit_code(st_run(&out, &err, args), "query");
    if (code) fprintf(stderr, "query %s: %s", store, err);
    assert_int_equal(code, 0);
    free(err);
    return out;
}

static void on_log(void *ctx, int level, const char *msg)
{
    (void)level;
    snprintf(ctx, 512, "%s", msg);
}

/* A version-1 store: read as it is read-only (info says version 1, query
 * answers), migrated by the first read-write open to version 3 with every
 * record the same and the tables of version 3 (registrations, bindings)
 * there and working, then checked clean and queried. */
static void test_migrate_v1(void **s)
{
    (void)s;
    char *v1 = ts_path(st_dir, "v1");
    write_v1_store(st_good, v1, 1);
    char *frame = frame_file();
    char *want = query(st_good, frame);

    assert_same_stores(st_good, v1, 1, 1);
    char *out = NULL, *err = NULL;
    const char *info[] = {"info", "--store", v1, "--json", NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, info), "info"), 0);
    json_t *j = json_loads(out, 0, NULL);
    assert_int_equal(json_integer_value(json_object_get(j, "schema_version")), 1);
    json_decref(j);
    free(out), free(err);
    char *got = query(v1, frame);
    assert_string_equal(got, want);
    free(got);
    const char *check[] = {"store", "check", v1, NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, check), "store check"), 0);
    assert_non_null(strstr(out, "schema version 1"));
    free(out), free(err);

    /* the first read-write open migrates, in one transaction */
    char logged[512] = "";
    mim_db_options_t rw = {.log = on_log, .log_ctx = logged};
    mim_db_t *db;
    mim_error_t e = {0};
    int rc = mim_db_open(&db, v1, &rw, &e);
    if (rc) fprintf(stderr, "%s\n", e.msg);
    assert_int_equal(rc, 0);
    mim_db_close(&db);
    assert_non_null(strstr(logged, "migrated from schema version 1 to 4: 6 templates and 6 encodings now carry "
                                   "checksums; added the registrations, by_source and bindings tables (empty)"));
    assert_same_stores(st_good, v1, 4, 1); /* schemas/store-version */
    mim_db_check_report_t r;
    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&db, v1, &ro, &e), 0);
    assert_int_equal(mim_db_check(db, NULL, &r, &e), 0);
    mim_db_close(&db);
    assert_int_equal(r.problems, 0);
    assert_int_equal(r.schema_version, 4);
    assert_int_equal(r.templates, 6);
    assert_int_equal(r.registrations + r.source_entries + r.bindings, 0);
    assert_int_equal(r.encodings, 6);
    assert_true(r.index && r.landmarks && r.topology);
    got = query(v1, frame);
    assert_string_equal(got, want);
    free(got);
    /* a second open has nothing to do; the tables of version 3 take records */
    logged[0] = 0;
    assert_int_equal(mim_db_open(&db, v1, &rw, &e), 0);
    assert_string_equal(logged, "");
    mim_db_txn_t *wt;
    mim_db_registration_t reg = {4, 0x5eed, 6890, 10, 0.5, 1.0, 2.0, 3.0, {0}}, back;
    const void *blob;
    size_t blob_len;
    assert_int_equal(mim_db_begin(db, 1, &wt, &e), 0);
    assert_int_equal(mim_db_registration_put(wt, &reg, &e), 0);
    assert_int_equal(mim_db_binding_put(wt, 99, "binding", 7, &e), 0);
    assert_int_equal(mim_db_commit(&wt, &e), 0);
    assert_int_equal(mim_db_begin(db, 0, &wt, &e), 0);
    assert_int_equal(mim_db_registration_find(wt, 0x5eed, &back, &e), 0);
    assert_int_equal(back.template_id, 4);
    assert_int_equal(mim_db_binding_get(wt, 99, &blob, &blob_len, &e), 0);
    assert_int_equal(blob_len, 7);
    mim_db_abort(&wt);
    mim_db_close(&db);

    /* mimic store migrate, on a version-1 store filled before encodings */
    char *v1b = ts_path(st_dir, "v1_no_encodings");
    write_v1_store(st_good, v1b, 0);
    assert_same_stores(st_good, v1b, 1, 0); /* read-only without the table */
    const char *migrate[] = {"store", "migrate", "--store", v1b, NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, migrate), "store migrate"), 0);
    assert_non_null(strstr(out, "now at schema version 4"));
    free(out), free(err);
    assert_int_equal(st_exit_code(st_run(&out, &err, migrate), "store migrate"), 0);
    assert_non_null(strstr(out, "already at schema version 4"));
    free(out), free(err);
    const char *check_b[] = {"store", "check", v1b, NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, check_b), "store check"), 0);
    assert_non_null(strstr(out, "note: 6 templates have no encoding"));
    free(out), free(err);
    /* ingest of the same files adds the encodings */
    const char *ingest[] = {"ingest", "--store", v1b, st_data, NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, ingest), "ingest"), 0);
    free(out), free(err);
    assert_same_stores(st_good, v1b, 4, 1);

    /* a damaged version-1 store: check finds it; migration refuses and
     * leaves it as it was */
    char *v1c = ts_path(st_dir, "v1_damaged");
    write_v1_store(st_good, v1c, 1);
    mim_template_view_t v;
    mim_db_txn_t *t;
    st_begin_read(st_good, &db, &t);
    assert_int_equal(mim_db_template_get(t, 4, &v, &e), 0);
    st_flip_byte(v1c, st_find_bytes(v1c, v.positions, 12 * (size_t)v.n_vertices) + 100);
    mim_db_abort(&t);
    mim_db_close(&db);
    st_assert_check_finds(v1c, "template 4: positions do not match their content hash", 4, "templates");
    char *file = ts_path(v1c, "data.mdb");
    size_t before_len = 0, after_len = 0;
    char *before = ts_read_file(file, &before_len);
    const char *ingest_c[] = {"ingest", "--store", v1c, st_data, NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, ingest_c), "ingest"), 2);
    st_assert_damaged_line("ingest", v1c, err);
    assert_non_null(strstr(err, "template 4: positions do not match their content hash (found while migrating"));
    free(out), free(err);
    char *after = ts_read_file(file, &after_len);
    assert_int_equal(before_len, after_len);
    assert_memory_equal(before, after, before_len);
    free(before), free(after), free(file);

    free(want), free(frame), free(v1), free(v1b), free(v1c);
}

/* ---- 9a: a full map or file ---- */
static uint64_t count_templates(const char *store)
{
    mim_db_t *db;
    mim_error_t e = {0};
    mim_db_options_t ro = {.read_only = 1};
    int rc = mim_db_open(&db, store, &ro, &e);
    if (rc) fprintf(stderr, "%s\n", e.msg);
    assert_int_equal(rc, 0);
    mim_db_check_report_t r;
    assert_int_equal(mim_db_check(db, NULL, &r, &e), 0);
    mim_db_close(&db);
    assert_int_equal(r.problems, 0);
    return r.templates;
}

/* A store with the first two meshes; returns its data.mdb size. */
static size_t start_store(const char *store)
{
    char *f1 = ts_path(st_data, "synth_s00_p00.ply"), *f2 = ts_path(st_data, "synth_s00_p01.ply");
    char *lm = ts_path(st_data, "landmarks.json");
    const char *args[] = {"ingest", "--store", store, "--landmarks", lm, f1, f2, NULL};
    char *out = NULL, *err = NULL;
    assert_int_equal(st_exit_code(st_run(&out, &err, args), "ingest"), 0);
    free(out), free(err), free(f1), free(f2), free(lm);
    struct stat st;
    char *file = ts_path(store, "data.mdb");
    assert_int_equal(stat(file, &st), 0);
    free(file);
    return (size_t)st.st_size;
}

/* ingest (one mesh a batch) in a store that fills part-way: the message
 * says what is full and that nothing committed is lost; every earlier
 * batch is there, the store checks clean, and a re-run completes it. */
static void fill_and_check(const char *store, const st_run_env_t *env, const char *says)
{
    char *out = NULL, *err = NULL;
    const char *args[] = {"ingest", "--store", store, "--batch", "1", "--threads", "1", st_data, NULL};
    int code = st_exit_code(st_run_env(env, &out, &err, args), "ingest");
    if (code != 2 || !strstr(err, says)) fprintf(stderr, "ingest: exit %d\n%s%s", code, out, err);
    assert_int_equal(code, 2);
    assert_int_equal(st_count_lines(err), 1);
    assert_non_null(strstr(err, says));
    assert_non_null(strstr(err, store));
    assert_non_null(strstr(err, "everything committed before it is intact"));
    free(out), free(err);
    uint64_t n = count_templates(store);
    fprintf(stderr, "%s: %llu of 6 templates committed before it filled\n", store, (unsigned long long)n);
    assert_true(n >= 2 && n < 6);
    const char *again[] = {"ingest", "--store", store, st_data, NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, again), "ingest"), 0);
    free(out), free(err);
    assert_int_equal(count_templates(store), 6);
}

static void test_map_full(void **s)
{
    (void)s;
    char *store = ts_path(st_dir, "map_full");
    size_t size = start_store(store);
    char map[32];
    snprintf(map, sizeof map, "%zu", size + 160 * 1024);
    st_run_env_t env = {.map_size = map};
    fill_and_check(store, &env, "the store's map is full");
    free(store);
}

/* The disk filling, portably: a file size limit (ulimit -f) makes LMDB's
 * writes fail part-way, as a full disk does. */
static void test_file_limit(void **s)
{
    (void)s;
    char *store = ts_path(st_dir, "file_limit");
    size_t size = start_store(store);
    st_run_env_t env = {.fsize = size + 160 * 1024};
    fill_and_check(store, &env, "data.mdb reached the file size limit");
    free(store);
}

/* A real full disk, where the machine lets a test mount a small tmpfs in
 * a mount namespace of its own (root, or CAP_SYS_ADMIN; skipped otherwise,
 * as in most CI containers): LMDB's short write is reported as the disk
 * being full, not as "Input/output error". */
static int disk_full_child(const char *mnt)
{
    if (unshare(CLONE_NEWNS) != 0 || mount("none", "/", NULL, MS_REC | MS_PRIVATE, NULL) != 0) return 77;
    mkdir(mnt, 0755);
    if (mount("tmpfs", mnt, "tmpfs", 0, "size=300k") != 0) return 77;
    /* no cmocka assert in this child: a failure would run the rest of the suite here */
    char *store = ts_path(mnt, "s"), *f1 = ts_path(st_data, "synth_s00_p00.ply"), *lm = ts_path(st_data, "landmarks.json");
    char *out = NULL, *err = NULL;
    const char *first[] = {"ingest", "--store", store, "--landmarks", lm, f1, NULL};
    int st = st_run(&out, &err, first);
    free(out), free(err), free(f1), free(lm);
    if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) return 3;
    const char *args[] = {"ingest", "--store", store, "--batch", "1", st_data, NULL};
    st = st_run(&out, &err, args);
    int bad = !WIFEXITED(st) || WEXITSTATUS(st) != 2 || st_count_lines(err) != 1 ||
              !strstr(err, "the store's disk is full") || !strstr(err, "everything committed before it is intact");
    fprintf(stderr, "%s", err);
    free(out), free(err);
    if (bad) return 1;
    const char *check[] = {"store", "check", store, NULL};
    st = st_run(&out, &err, check);
    bad = !WIFEXITED(st) || WEXITSTATUS(st) != 0 || !strstr(out, "no problems");
    fprintf(stderr, "%s", out);
    free(out), free(err), free(store);
    return bad ? 2 : 0;
}

static void test_disk_full(void **s)
{
    (void)s;
    char *mnt = ts_path(st_dir, "small_disk");
    pid_t pid = fork();
    if (pid == 0) _exit(disk_full_child(mnt));
    int st;
    waitpid(pid, &st, 0);
    free(mnt);
    assert_true(WIFEXITED(st));
    if (WEXITSTATUS(st) == 77) {
        fprintf(stderr, "no tmpfs mount allowed here: the file size limit test stands in for a full disk\n");
        skip();
    }
    assert_int_equal(WEXITSTATUS(st), 0);
}

/* ---- 9b: two first ingests racing on one empty store ---- */
static void test_two_first_ingests(void **s)
{
    (void)s;
    int conflicts = 0;
    for (int round = 0; round < 8; round++) {
        int same = round % 2 == 0;
        char name[32];
        snprintf(name, sizeof name, "race_%d", round);
        char *store = ts_path(st_dir, name);
        const char *srcs[2] = {st_data, same ? st_data : st_data_b};
        char *tmp = ts_tempdir("race"), *o[2], *e[2];
        pid_t pid[2];
        for (int i = 0; i < 2; i++) {
            char fn[16];
            snprintf(fn, sizeof fn, "out%d", i), o[i] = ts_path(tmp, fn);
            snprintf(fn, sizeof fn, "err%d", i), e[i] = ts_path(tmp, fn);
        }
        const char *a0[] = {"ingest", "--store", store, srcs[0], NULL};
        const char *a1[] = {"ingest", "--store", store, srcs[1], NULL};
        pid[0] = st_spawn(NULL, o[0], e[0], a0);
        pid[1] = st_spawn(NULL, o[1], e[1], a1);
        int code[2];
        for (int i = 0; i < 2; i++) {
            int st;
            waitpid(pid[i], &st, 0);
            code[i] = st_exit_code(st, "ingest");
        }
        for (int i = 0; i < 2; i++) {
            char *errs = ts_read_file(e[i], NULL);
            if (code[i] == 2) {
                /* the loser: one clear line, and its re-run goes normally */
                if (!strstr(errs, "another ingest fixed the store's connectivity first")) fprintf(stderr, "%s", errs);
                assert_int_equal(st_count_lines(errs), 1);
                assert_non_null(strstr(errs, "another ingest fixed the store's connectivity first"));
                assert_non_null(strstr(errs, "re-run"));
                conflicts++;
                char *out = NULL, *err2 = NULL;
                const char *again[] = {"ingest", "--store", store, srcs[i], NULL};
                int c2 = st_exit_code(st_run(&out, &err2, again), "ingest");
                if (same) assert_int_equal(c2, 0);
                else {
                    assert_int_equal(c2, 1); /* each file: connectivity differs */
                    assert_non_null(strstr(err2, "connectivity differs from the store's"));
                }
                free(out), free(err2);
            } else {
                assert_null(strstr(errs, "already has a reference connectivity"));
                if (same) assert_int_equal(code[i], 0);
                else assert_true(code[i] == 0 || code[i] == 1);
            }
            free(errs);
        }
        if (same) assert_int_equal(count_templates(store), 6);
        for (int i = 0; i < 2; i++) free(o[i]), free(e[i]);
        ts_rmtree(tmp);
        free(tmp), free(store);
    }
    fprintf(stderr, "two first ingests: %d of 8 rounds had a loser\n", conflicts);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_migrate_v1), cmocka_unit_test(test_map_full),          cmocka_unit_test(test_file_limit),
        cmocka_unit_test(test_disk_full),  cmocka_unit_test(test_two_first_ingests),
    };
    return cmocka_run_group_tests(tests, st_setup, st_teardown);
}
