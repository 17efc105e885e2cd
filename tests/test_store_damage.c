/* The store survives damage (issue 12, defect 3): a truncated, random or
 * foreign data.mdb, and a flipped byte in any record, each give one line
 * starting "store damaged" that names the store, never a crash and never a
 * write; `mimic store check` names the damaged record. Shared helpers and
 * the fixture: support/store_support.c. */
#include "mim_db.h"
#include "store_support.h"
#include "mim_session.h"
#include "mim_query.h"
#include "serve_support.h"

#include <jansson.h>
#include <lmdb.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* A truncated data.mdb: 0 bytes, one page, the two meta pages only, half,
 * all but its last page. Before: SIGBUS from 8192 bytes up, and an empty
 * file was taken for a new store. */
static void test_truncated(void **s)
{
    (void)s;
    size_t size = st_good_size();
    size_t keeps[] = {0, 4096, 8192, size / 2, size - 4096};
    for (size_t i = 0; i < sizeof keeps / sizeof *keeps; i++) {
        char name[32];
        snprintf(name, sizeof name, "cut_%zu", keeps[i]);
        char *store = st_copy_store(name, keeps[i]);
        st_assert_refused(store);
        /* the library says the same, read-only and for writing */
        mim_db_t *db = NULL;
        mim_error_t err = {0};
        mim_db_options_t ro = {.read_only = 1};
        assert_int_equal(mim_db_open(&db, store, &ro, &err), MIM_ESTORE);
        assert_null(db);
        assert_non_null(strstr(err.msg, "store damaged: "));
        err = (mim_error_t){0};
        assert_int_equal(mim_db_open(&db, store, NULL, &err), MIM_ESTORE);
        if (keeps[i] >= 8192) assert_non_null(strstr(err.msg, "truncated"));
        free(store);
    }
}

/* Random bytes, zeros, and the good store's two meta pages over random
 * pages (LMDB then follows garbage: SIGBUS or SIGSEGV before). */
static void test_garbage(void **s)
{
    (void)s;
    size_t size = st_good_size();
    mim_rng_t rng;
    mim_rng_seed(&rng, 12, 0);
    char *bytes = malloc(size), *src = ts_path(st_good, "data.mdb"), *orig = ts_read_file(src, NULL);
    uint32_t psize;
    memcpy(&psize, orig + 40, 4);
    for (int variant = 0; variant < 3; variant++) {
        for (size_t i = 0; i < size; i++) bytes[i] = variant == 1 ? 0 : (char)mim_rng_u64(&rng);
        if (variant == 2) memcpy(bytes, orig, 2 * (size_t)psize);
        char name[32];
        snprintf(name, sizeof name, "garbage_%d", variant);
        char *store = ts_path(st_dir, name), *file = ts_path(store, "data.mdb");
        mkdir(store, 0755);
        assert_int_equal(ts_write_file(file, bytes, size), 0);
        st_assert_refused(store);
        free(store), free(file);
    }
    free(bytes), free(src), free(orig);
}

/* An LMDB environment that is not (or no longer) a whole mimic store:
 * someone else's tables, a mimic table missing, a table of the wrong
 * kind. Before: "no mimic store here (run mimic ingest first)" for some,
 * and ingest wrote into them. */
static void raw_edit(const char *store, void (*edit)(MDB_txn *txn))
{
    MDB_env *env;
    MDB_txn *txn;
    assert_int_equal(mdb_env_create(&env), 0);
    mdb_env_set_maxdbs(env, 16);
    assert_int_equal(mdb_env_open(env, store, 0, 0664), 0);
    assert_int_equal(mdb_txn_begin(env, NULL, 0, &txn), 0);
    edit(txn);
    assert_int_equal(mdb_txn_commit(txn), 0);
    mdb_env_close(env);
}
static void add_foreign(MDB_txn *txn)
{
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "users", MDB_CREATE, &dbi), 0);
}
static void drop_templates(MDB_txn *txn)
{
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "templates", MDB_INTEGERKEY, &dbi), 0);
    assert_int_equal(mdb_drop(txn, dbi, 1), 0);
}
/* a table of schema version 3 missing from a version-3 store */
static void drop_bindings(MDB_txn *txn)
{
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "bindings", MDB_INTEGERKEY, &dbi), 0);
    assert_int_equal(mdb_drop(txn, dbi, 1), 0);
}
static void templates_wrong_kind(MDB_txn *txn)
{
    drop_templates(txn);
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, "templates", MDB_CREATE | MDB_DUPSORT, &dbi), 0);
}
static void only_foreign(MDB_txn *txn)
{
    MDB_dbi dbi;
    assert_int_equal(mdb_dbi_open(txn, NULL, 0, &dbi), 0);
    MDB_val k = {3, "key"}, v = {5, "value"};
    assert_int_equal(mdb_put(txn, dbi, &k, &v, 0), 0);
    assert_int_equal(mdb_del(txn, dbi, &k, NULL), 0); /* committed, and empty */
}

static void test_not_mimic(void **s)
{
    (void)s;
    struct {
        const char *name, *says;
        void (*edit)(MDB_txn *);
        int from_good;
    } cases[] = {
        {"foreign", "table 'users'", add_foreign, 1},
        {"no_templates", "lacks its 'templates' table", drop_templates, 1},
        {"no_bindings", "lacks its 'bindings' table", drop_bindings, 1},
        {"wrong_kind", "'templates' table is not of the kind", templates_wrong_kind, 1},
        {"other_program", "not a mimic store", only_foreign, 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char *store;
        if (cases[i].from_good) {
            store = st_copy_store(cases[i].name, (size_t)-1);
        } else {
            store = ts_path(st_dir, cases[i].name);
            mkdir(store, 0755);
        }
        raw_edit(store, cases[i].edit);
        char *out = NULL, *err = NULL;
        const char *info[] = {"info", "--store", store, NULL};
        assert_int_equal(st_exit_code(st_run(&out, &err, info), "info"), 2);
        if (!strstr(err, cases[i].says)) fprintf(stderr, "%s: %s", cases[i].name, err);
        assert_non_null(strstr(err, cases[i].says));
        free(out), free(err);
        st_assert_refused(store);
        free(store);
    }
}

/* Every page of the store overwritten with random bytes in turn (valid
 * metas, garbage where LMDB's trees or records were): mimic info and mimic
 * store check exit normally every time, never by a signal, a refusal is
 * one "store damaged" line, and store check finds the damage unless the
 * page was free. Before: mimic info said nothing for most pages (exit 0,
 * garbage served) and there was no store check. */
static void test_every_page(void **s)
{
    (void)s;
    size_t size = st_good_size();
    char *src = ts_path(st_good, "data.mdb");
    char *orig = ts_read_file(src, NULL);
    uint32_t psize;
    memcpy(&psize, orig + 40, 4); /* LMDB's page size, in its first meta page */
    size_t page = psize;
    char *store = ts_path(st_dir, "page_garbage"), *file = ts_path(store, "data.mdb");
    mkdir(store, 0755);
    mim_rng_t rng;
    mim_rng_seed(&rng, 7, 0);
    char *b = malloc(size);
    int found[3] = {0};
    for (size_t pg = 2; pg < size / page; pg++) {
        memcpy(b, orig, size);
        for (size_t i = 0; i < page; i++) b[pg * page + i] = (char)mim_rng_u64(&rng);
        assert_int_equal(ts_write_file(file, b, size), 0);
        const char *info[] = {"info", "--store", store, NULL};
        const char *check[] = {"store", "check", store, NULL};
        const char *const *runs[] = {info, check};
        for (int r = 0; r < 2; r++) {
            char *out = NULL, *err = NULL;
            int code = st_exit_code(st_run(&out, &err, runs[r]), r ? "store check" : "info");
            if (code > 2 || (code == 2 && !strstr(err, "store damaged: ")))
                fprintf(stderr, "page %zu: %s exit %d: %s", pg, runs[r][0], code, err);
            assert_true(code <= 2);
            if (code == 2) st_assert_damaged_line(r ? "store check" : "info", store, err);
            if (r) found[code]++;
            free(out), free(err);
        }
    }
    fprintf(stderr, "%zu pages overwritten: store check found nothing %d times (free pages), damage %d, refused %d\n",
            size / page - 2, found[0], found[1], found[2]);
    assert_true(found[1] > 0 && found[2] > 0);
    free(b), free(orig), free(src), free(store), free(file);
}

/* One byte flipped inside each kind of record: found by its bytes in the
 * file. Before: served as if nothing happened (mimic info exit 0). */
static void test_flipped_byte(void **s)
{
    (void)s;
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    st_begin_read(st_good, &db, &t);
    mim_template_view_t v;
    mim_db_encoding_t e;
    mim_db_topology_t topo;
    mim_landmark_map_t map;
    assert_int_equal(mim_db_template_get(t, 2, &v, &err), 0);
    assert_int_equal(mim_db_encoding_get(t, 3, &e, &err), 0);
    assert_int_equal(mim_db_topology_get(t, &topo, &err), 0);
    assert_int_equal(mim_db_landmarks_get(t, &map, &err), 0);
    size_t n_pos = 12 * (size_t)v.n_vertices, n_w = 12 * (size_t)e.n_vertices, n_faces = 12 * (size_t)topo.n_faces;
    float *pos = malloc(n_pos), *W = malloc(n_w);
    uint32_t *faces = malloc(n_faces);
    memcpy(pos, v.positions, n_pos), memcpy(W, e.W, n_w), memcpy(faces, topo.faces, n_faces);
    char *json = mim_landmarks_to_json(&map);
    mim_db_abort(&t);
    mim_db_close(&db);

    /* a template's positions: every reader refuses it by id */
    char *store = st_copy_store("flip_template", (size_t)-1);
    st_flip_byte(store, st_find_bytes(store, pos, n_pos) + n_pos / 2);
    const char *cmds[][6] = {{"info", "--store", store, NULL}, {"list", "--store", store, NULL}};
    for (int i = 0; i < 2; i++) {
        char *out = NULL, *errs = NULL;
        int code = st_exit_code(st_run(&out, &errs, cmds[i]), cmds[i][0]);
        if (code != 2) fprintf(stderr, "%s: exit %d: %s%s", cmds[i][0], code, out, errs);
        assert_int_equal(code, 2);
        char want[512];
        snprintf(want, sizeof want, "mimic %s: store damaged: %s: template 2: checksum mismatch\n", cmds[i][0], store);
        assert_string_equal(errs, want);
        free(out), free(errs);
    }
    st_begin_read(store, &db, &t);
    err = (mim_error_t){0};
    assert_int_equal(mim_db_template_get(t, 2, &v, &err), MIM_ESTORE);
    assert_null(v.positions); /* nothing lent out */
    assert_int_equal(mim_db_template_get(t, 1, &v, &err), 0); /* the others still read */
    mim_db_abort(&t);
    mim_db_close(&db);
    st_assert_check_finds(store, "template 2: checksum mismatch", 2, "templates");
    /* completion, which reads every template's landmarks: the damage, each
     * time, and the table is not rebuilt (nor grown) on every call */
    {
        mim_session_t *ses = NULL;
        mim_error_t e1 = {0}, e2 = {0};
        assert_int_equal(mim_session_open(&ses, store, NULL, &e1), 0);
        const mim_landmark_map_t *lm = mim_session_map(ses);
        float x[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX];
        uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
        for (uint32_t l = 0; l < lm->count; l++) memcpy(x + 3 * l, pos + 3 * (size_t)lm->vertex[l], 12), present[l] = 1;
        present[7] = 0;
        assert_int_equal(mim_session_complete(ses, x, present, NULL, out, done, &e1), MIM_ESTORE);
        assert_int_equal(mim_session_complete(ses, x, present, NULL, out, done, &e2), MIM_ESTORE);
        assert_non_null(strstr(e1.msg, "template 2: checksum mismatch"));
        assert_string_equal(e1.msg, e2.msg);
        mim_session_close(&ses);
    }
    /* ingest does not write beside damage it meets (the same content again) */
    free(store);

    store = st_copy_store("flip_encoding", (size_t)-1);
    st_flip_byte(store, st_find_bytes(store, W, n_w) + 7);
    st_assert_check_finds(store, "template 3: encoding checksum mismatch", 3, "encodings");
    free(store);

    store = st_copy_store("flip_topology", (size_t)-1);
    st_flip_byte(store, st_find_bytes(store, faces, n_faces) + n_faces - 5);
    st_assert_check_finds(store, "topology: checksum mismatch (faces do not match their hash)", 0, "topology");
    free(store);

    store = st_copy_store("flip_landmarks", (size_t)-1);
    st_flip_byte(store, st_find_bytes(store, json, strlen(json)) + strlen(json) / 2);
    st_assert_check_finds(store, "landmark map: checksum mismatch", 0, "landmarks");
    free(store);

    /* a registration and a binding (schema version 3), added to a copy */
    store = st_copy_store("flip_registration", (size_t)-1);
    mim_db_registration_t reg = {2, 0x5eed5eed5eed5eedULL, 6890, 24, 0.41, 1.12, 3.5, 2.25, {0}};
    enum { BLOB = 64 << 10 };
    unsigned char *blob = malloc(BLOB);
    for (size_t i = 0; i < BLOB; i++) blob[i] = (unsigned char)(i * 131 + 7);
    mim_db_options_t rw = {0};
    assert_int_equal(mim_db_open(&db, store, &rw, &err), 0);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_registration_put(t, &reg, &err), 0);
    assert_int_equal(mim_db_binding_put(t, 0xb1d, blob, BLOB, &err), 0);
    assert_int_equal(mim_db_commit(&t, &err), 0);
    mim_db_close(&db);
    char *bound = st_copy_store("flip_binding", (size_t)-1);
    char *src = ts_path(store, "data.mdb"), *dst = ts_path(bound, "data.mdb");
    size_t n = 0;
    char *bytes = ts_read_file(src, &n);
    assert_int_equal(ts_write_file(dst, bytes, n), 0);
    free(bytes), free(src), free(dst);
    /* the registration's fields from its template id on (schemas/store.md) */
    unsigned char fields[56];
    memcpy(fields, &reg.template_id, 8), memcpy(fields + 8, &reg.source_hash, 8);
    memcpy(fields + 16, &reg.source_vertices, 4), memcpy(fields + 20, &reg.iterations, 4);
    memcpy(fields + 24, &reg.mean_mm, 8), memcpy(fields + 32, &reg.p95_mm, 8), memcpy(fields + 40, &reg.max_mm, 8);
    memcpy(fields + 48, &reg.landmark_mean_mm, 8);
    st_flip_byte(store, st_find_bytes(store, fields, sizeof fields) + 30);
    st_assert_check_finds(store, "registration 2: checksum mismatch", 2, "registrations");
    char *out = NULL, *errs = NULL;
    const char *list[] = {"list", "--store", store, "--json", NULL};
    assert_int_equal(st_exit_code(st_run(&out, &errs, list), "list"), 2);
    char want[512];
    snprintf(want, sizeof want, "mimic list: store damaged: %s: registration 2: checksum mismatch\n", store);
    assert_string_equal(errs, want);
    free(out), free(errs);
    free(store);
    st_flip_byte(bound, st_find_bytes(bound, blob, BLOB) + BLOB / 3);
    st_assert_check_finds(bound, "binding 0000000000000b1d: checksum mismatch", 0, "bindings");
    free(bound), free(blob);

    /* and the intact store is clean */
    const char *check[] = {"store", "check", st_good, NULL};
    assert_int_equal(st_exit_code(st_run(&out, &errs, check), "store check"), 0);
    assert_non_null(strstr(out, "no problems"));
    assert_non_null(strstr(out, "checked 6 templates, 6 encodings, 6 hash-index entries, the connectivity, the landmark map, the index"));
    free(out), free(errs);
    free(pos), free(W), free(faces), free(json);
}

/* A byte flipped in the index's bulk (a template's descriptor angles,
 * issue 16): the index opens in place (only its head is read then), the
 * first query that needs those templates fails with MIM_EFORMAT, and every
 * later one, never reading them; mimic store check names the index. */
/* mimic transfer --json with --avatar 1 --template 5 (subject 1's pose 1;
 * its reference for relative transfer: template 4, subject 1 at rest) on
 * store: exit 0, the report parsed, stderr in *errs. */
static json_t *transfer_report(const char *store, char **errs)
{
    char *out = NULL, *o = ts_path(st_dir, "degraded.ply");
    const char *args[] = {"transfer", "--store", store, "--avatar", "1", "--template", "5", "--json", "-o", o, NULL};
    int code = st_exit_code(st_run(&out, errs, args), "transfer");
    if (code) fail_msg("transfer on %s: exit %d: %s", store, code, *errs);
    json_error_t je;
    json_t *j = json_loads(out, 0, &je);
    assert_non_null(j);
    free(out), free(o);
    return j;
}

/* Issue 30 item 6: damage elsewhere in the store (neither the avatar nor
 * the chosen template) that makes a transfer take a fallback is said: a
 * warning line and "degraded" in the report, not exit 0 in silence. */
static void test_damage_fallback_reported(void **s)
{
    (void)s;
    size_t n_pos = 0;
    float *pos = st_template_positions(st_good, 3, &n_pos); /* another subject's template */

    /* undamaged: relative transfer over template 4, nothing degraded */
    char *errs = NULL;
    json_t *j = transfer_report(st_good, &errs);
    assert_true(json_is_true(json_object_get(j, "relative")));
    assert_int_equal(json_integer_value(json_object_get(j, "reference")), 4);
    assert_true(json_is_null(json_object_get(j, "degraded")));
    assert_null(strstr(errs, "warning"));
    json_decref(j), free(errs);

    /* another subject's template damaged: the templates cannot all be read */
    char *store = st_copy_store("degraded_table", (size_t)-1);
    st_flip_byte(store, st_find_bytes(store, pos, n_pos) + n_pos / 3);
    j = transfer_report(store, &errs);
    assert_true(json_is_false(json_object_get(j, "relative")));
    const char *why = json_string_value(json_object_get(j, "degraded"));
    assert_non_null(why);
    assert_non_null(strstr(why, "relative transfer is off: the store's templates cannot be read"));
    assert_non_null(strstr(why, "template 3: checksum mismatch"));
    char want[1024];
    snprintf(want, sizeof want, "mimic transfer: warning: %s\n", why);
    assert_string_equal(errs, want);
    json_decref(j), free(errs), free(store);

    free(pos);
}

static void test_index_bulk_damage(void **s)
{
    (void)s;
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_error_t err = {0};
    st_begin_read(st_good, &db, &t);
    const void *blob;
    size_t len;
    mim_db_index_meta_t bm;
    assert_int_equal(mim_db_index_get(t, &blob, &len, &bm, &err), 0);
    mim_landmark_map_t map;
    mim_template_view_t v;
    assert_int_equal(mim_db_landmarks_get(t, &map, &err), 0);
    assert_int_equal(mim_db_template_get(t, 2, &v, &err), 0);
    float frame[3 * MIM_LANDMARKS_MAX];
    for (uint32_t l = 0; l < map.count; l++) memcpy(frame + 3 * l, v.positions + 3 * (size_t)map.vertex[l], 12);
    /* the descriptor section (index/blob.c): after the head, ids,
     * subjects and poses, each 64-byte aligned */
    uint32_t ver, n;
    uint64_t hb;
    memcpy(&ver, (const char *)blob + 4, 4);
    memcpy(&hb, (const char *)blob + 32, 8);
    memcpy(&n, (const char *)blob + 64 + 8, 4);
    assert_int_equal(ver, 7);
    uint64_t at = (64 + hb + 63) / 64 * 64;
    at = (at + 8ull * n + 63) / 64 * 64;
    at = (at + 4ull * n + 63) / 64 * 64;
    at = (at + 4ull * n + 63) / 64 * 64;
    unsigned char desc[64];
    memcpy(desc, (const char *)blob + at, sizeof desc);
    mim_db_abort(&t);
    mim_db_close(&db);

    char *store = st_copy_store("flip_index_bulk", (size_t)-1);
    st_flip_byte(store, st_find_bytes(store, desc, sizeof desc) + 21);
    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&db, store, &ro, &err), 0);
    mim_query_t *q = NULL;
    assert_int_equal(mim_query_open(&q, db, &err), 0);
    for (int i = 0; i < 2; i++) {
        mim_index_answer_t a;
        mim_index_hit_t h;
        mim_error_clear(&err);
        assert_int_equal(mim_query_frame(q, frame, NULL, NULL, &a, &h, &err), MIM_EFORMAT);
        assert_non_null(strstr(err.msg, "damaged"));
        assert_int_equal(a.n_hits, 0);
    }
    mim_query_close(&q);
    mim_db_close(&db);
    st_assert_check_finds(store, "index model: checksum mismatch (run mimic index)", 0, "index");
    /* mimic serve on it: it starts (the damage is in one class's part),
     * readies the index on its own thread, finds the damage and says so in
     * its status, and stops cleanly */
    char *dir = ts_tempdir("damaged_serve");
    const char *args[] = {"serve", "--store", store, "--avatar", "1", "--listen", "127.0.0.1:0", NULL};
    ss_svc_t sv = {0};
    assert_int_equal(ss_serve_start(&sv, dir, "damaged", args), 0);
    json_t *ix = NULL;
    for (int i = 0; i < 600; i++) {
        json_t *st = ss_get_status(sv.port);
        ix = json_incref(json_object_get(st, "index"));
        json_decref(st);
        if (json_object_get(ix, "error")) break;
        json_decref(ix), ix = NULL;
        ss_sleep_ms(100);
    }
    assert_non_null(ix);
    assert_true(json_is_false(json_object_get(ix, "ready")));
    const char *why = json_string_value(json_object_get(ix, "error"));
    if (!strstr(why, "damaged")) fail_msg("index.error '%s' lacks 'damaged'", why);
    json_decref(ix);
    ss_svc_term(&sv);
    ss_svc_free(&sv);
    ts_rmtree(dir);
    free(dir);
    free(store);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_truncated),  cmocka_unit_test(test_garbage),      cmocka_unit_test(test_not_mimic),
        cmocka_unit_test(test_every_page), cmocka_unit_test(test_flipped_byte),
        cmocka_unit_test(test_index_bulk_damage), cmocka_unit_test(test_damage_fallback_reported),
    };
    return cmocka_run_group_tests(tests, st_setup, st_teardown);
}
