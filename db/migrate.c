/* Migrations, in the one write transaction that opens an older store for
 * writing, so the store is wholly of its old version or wholly of the
 * current one and readers of either snapshot see a consistent one
 * (schemas/store.md):
 *   1 -> 2  every template, encoding, landmark-map and index-build record
 *           rewritten with its checksum. Nothing damaged is stamped with a
 *           fresh checksum: a version-1 template whose positions do not
 *           match their content hash, or a record that does not decode,
 *           stops the migration and the store stays as it was. The
 *           topology record does not change (its hash is its checksum);
 *           nor does by_hash.
 *   2 -> 3  the registrations, by_source and bindings tables, empty (the
 *           caller, init_store, creates every missing table in this same
 *           transaction); no record changes.
 * A version-1 store goes 1 -> 2 -> 3 in the one transaction; then
 * schema_version is set to the current version. */
#include "internal.h"
#include "mim_schema_version.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define STR_(x) #x
#define STR(x) STR_(x)
static const char damage_suffix[] = " (found while migrating the store to schema version " STR(MIM_STORE_SCHEMA_VERSION)
                                    ": nothing was changed; mimic store check lists every problem)";
static const char other_suffix[] =
    " (while migrating the store to schema version " STR(MIM_STORE_SCHEMA_VERSION) ": nothing was changed)";

/* A record copied out of the map (after its bounds are checked), so that
 * rewriting it never reads pages LMDB is handing back. */
static int copy_out(mim_db_txn_t *t, const MDB_val *v, const char *what, void **buf, MDB_val *copy, mim_error_t *err)
{
    int rc = mim__db_span(t, v, what, err);
    if (rc) return rc;
    void *p = realloc(*buf, v->mv_size ? v->mv_size : 1);
    if (!p) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory migrating %s", t->db->path, what);
    memcpy(p, v->mv_data, v->mv_size);
    *buf = p;
    copy->mv_data = p;
    copy->mv_size = v->mv_size;
    return 0;
}

typedef int (*rewrite_fn)(mim_db_txn_t *t, uint64_t id, const MDB_val *v1, mim_error_t *err);

static int rewrite_template(mim_db_txn_t *t, uint64_t id, const MDB_val *rec, mim_error_t *err)
{
    mim_template_view_t view;
    int rc = mim__db_template_decode(t, 1, rec, id, &view, err);
    if (rc) return rc;
    if (mim_db_content_hash(view.positions, view.n_vertices) != view.content_hash)
        return mim__db_damaged(t->db, err, "template %llu: positions do not match their content hash",
                               (unsigned long long)id);
    mim_template_in_t in = {view.positions, view.n_vertices, view.content_hash, view.source, view.subject, view.pose,
                            view.dataset};
    size_t pos_off, size = mim__db_template_size(&in, &pos_off), key = (size_t)id;
    MDB_val k = {sizeof key, &key}, v = {size, NULL};
    if ((rc = mdb_put(t->txn, t->db->dbi[DBI_TEMPLATES], &k, &v, MDB_RESERVE)))
        return mim__db_fail(t->db, err, rc, "migrating templates");
    mim__db_template_encode(v.mv_data, size, pos_off, id, &in);
    return 0;
}

static int rewrite_encoding(mim_db_txn_t *t, uint64_t id, const MDB_val *rec, mim_error_t *err)
{
    mim_db_encoding_t e;
    int rc = mim__db_encoding_decode(t, 1, rec, id, &e, err);
    if (rc) return rc;
    return mim__db_encoding_write(t, id, e.frames, e.W, e.n_vertices, err);
}

/* Rewrites every record of an integer-keyed table, in key order. */
static int rewrite_table(mim_db_txn_t *t, int dbi, const char *what, rewrite_fn fn, mim_progress_t *prog,
                         uint64_t *done, mim_error_t *err)
{
    MDB_cursor *c;
    int rc = mdb_cursor_open(t->txn, t->db->dbi[dbi], &c);
    if (rc) return mim__db_fail(t->db, err, rc, what);
    void *buf = NULL;
    size_t key = 0;
    MDB_cursor_op op = MDB_FIRST;
    for (;;) {
        MDB_val k = {sizeof key, &key}, v, copy = {0, NULL};
        /* re-positioned after every put: the put may move the cursor's page */
        rc = mdb_cursor_get(c, &k, &v, op);
        if (rc == MDB_NOTFOUND) {
            rc = 0;
            break;
        }
        if (rc) {
            rc = mim__db_fail(t->db, err, rc, what);
            break;
        }
        if (k.mv_size != sizeof key) {
            rc = mim__db_damaged(t->db, err, "%s: a key of %zu bytes", what, k.mv_size);
            break;
        }
        memcpy(&key, k.mv_data, sizeof key);
        if ((rc = copy_out(t, &v, what, &buf, &copy, err)) || (rc = fn(t, key, &copy, err))) break;
        mim_progress_update(prog, ++*done);
        if (key == SIZE_MAX) break;
        key++;
        op = MDB_SET_RANGE;
    }
    mdb_cursor_close(c);
    free(buf);
    return rc;
}

static int migrate_landmarks(mim_db_txn_t *t, mim_error_t *err)
{
    MDB_val k = {3, "map"}, v, copy = {0, NULL};
    int rc = mdb_get(t->txn, t->db->dbi[DBI_LANDMARKS], &k, &v);
    if (rc == MDB_NOTFOUND) return 0;
    if (rc) return mim__db_fail(t->db, err, rc, "landmark map");
    void *buf = NULL;
    if (!(rc = copy_out(t, &v, "landmark map", &buf, &copy, err))) {
        mim_landmark_map_t map;
        mim_error_t e = {0};
        if (mim_landmarks_parse(&map, copy.mv_data, copy.mv_size, "store landmark map", &e))
            rc = mim__db_damaged(t->db, err, "%s", e.msg);
        else
            rc = mim__db_landmarks_write(t, copy.mv_data, copy.mv_size, err);
    }
    free(buf);
    return rc;
}

static int migrate_index(mim_db_txn_t *t, mim_error_t *err)
{
    MDB_val kb = {11, "index.build"}, km = {11, "index.model"}, vb, vm, model = {0, NULL};
    int rc = mdb_get(t->txn, t->db->dbi[DBI_META], &kb, &vb);
    if (rc == MDB_NOTFOUND) return 0;
    if (rc) return mim__db_fail(t->db, err, rc, "index");
    mim_db_index_meta_t m;
    if ((rc = mim__db_index_build_decode(t, 1, &vb, NULL, &m, err))) return rc;
    rc = mdb_get(t->txn, t->db->dbi[DBI_META], &km, &vm);
    if (rc == MDB_NOTFOUND) return mim__db_damaged(t->db, err, "index build record without a model (run mimic index)");
    if (rc) return mim__db_fail(t->db, err, rc, "index");
    void *buf = NULL;
    if (!(rc = copy_out(t, &vm, "index model", &buf, &model, err)))
        rc = mim__db_index_build_write(t, model.mv_data, model.mv_size, &m, err);
    free(buf);
    return rc;
}

/* 1 -> 2: every record gains its checksum. Decodes with version 1 (t's),
 * writes version 2. */
static int migrate_checksums(mim_db_txn_t *t, mim_progress_t *prog, mim_error_t *e)
{
    uint64_t done = 0;
    mim_db_topology_t topo;
    int rc = mim_db_topology_get(t, &topo, e);
    if (rc == MIM_ENOTFOUND) rc = 0;
    if (!rc) rc = migrate_landmarks(t, e);
    if (!rc) rc = rewrite_table(t, DBI_TEMPLATES, "templates", rewrite_template, prog, &done, e);
    if (!rc) rc = rewrite_table(t, DBI_ENCODINGS, "encodings", rewrite_encoding, prog, &done, e);
    if (!rc) rc = migrate_index(t, e);
    if (!rc) t->version = 2;
    return rc;
}

/* 2 -> 3: the new tables must be there, empty (the caller created them in
 * this transaction; a store of version 2 that already held one with
 * records is not one mimic wrote). */
static int migrate_tables(mim_db_txn_t *t, mim_error_t *e)
{
    static const int added[] = {DBI_REGISTRATIONS, DBI_BY_SOURCE, DBI_BINDINGS};
    for (size_t i = 0; i < sizeof added / sizeof *added; i++) {
        MDB_stat s;
        int rc = mdb_stat(t->txn, t->db->dbi[added[i]], &s);
        if (rc) return mim__db_fail(t->db, e, rc, mim__db_table_names[added[i]]);
        if (s.ms_entries)
            return mim__db_damaged(t->db, e, "a store of schema version 2 with %llu records in its '%s' table",
                                   (unsigned long long)s.ms_entries, mim__db_table_names[added[i]]);
    }
    t->version = 3;
    return 0;
}

/* 3 -> 4: nothing to rewrite. Version 4 added a template's dataset (the
 * u16 at offset 46 every earlier record holds as 0: no dataset) and
 * registration records with quality figures ("MRG4"; "MRG3" ones stay
 * valid). An older mimic must refuse such a store rather than misread it. */
static int migrate_none(mim_db_txn_t *t)
{
    t->version = 4;
    return 0;
}

_Static_assert(MIM_STORE_SCHEMA_VERSION == 4, "a new schema version needs its step in mim__db_migrate");

int mim__db_migrate(mim_db_txn_t *t, const mim_db_options_t *opt, mim_error_t *err)
{
    mim_db_t *db = t->db;
    const uint32_t from = t->version;
    MDB_stat st, se;
    int rc = mdb_stat(t->txn, db->dbi[DBI_TEMPLATES], &st);
    if (!rc) rc = mdb_stat(t->txn, db->dbi[DBI_ENCODINGS], &se);
    if (rc) return mim__db_fail(db, err, rc, "migration");
    if (from < 1 || from >= MIM_STORE_SCHEMA_VERSION)
        return mim_error_set(err, MIM_EINVAL, "%s: no migration from schema version %u", db->path, from);
    mim_progress_t prog = {.fn = opt ? opt->progress : NULL, .ctx = opt ? opt->progress_ctx : NULL};
    mim_progress_begin(&prog, "migrate", from == 1 ? st.ms_entries + se.ms_entries : 0);
    mim_error_t e = {0};
    if (t->version == 1) rc = migrate_checksums(t, &prog, &e);
    if (!rc && t->version == 2) rc = migrate_tables(t, &e);
    if (!rc && t->version == 3) rc = migrate_none(t);
    if (!rc) {
        uint64_t ver = MIM_STORE_SCHEMA_VERSION;
        MDB_val k = {14, "schema_version"}, d = {8, &ver};
        if ((rc = mdb_put(t->txn, db->dbi[DBI_META], &k, &d, 0))) rc = mim__db_fail(db, &e, rc, "migration");
    }
    mim_progress_end(&prog);
    if (rc)
        return mim_error_set(err, rc, "%s%s", e.msg[0] ? e.msg : mim_strerror(rc),
                             strncmp(e.msg, "store damaged", 13) ? other_suffix : damage_suffix);
    t->version = MIM_STORE_SCHEMA_VERSION;
    if (opt && opt->log) {
        char checksums[160] = "";
        if (from == 1)
            snprintf(checksums, sizeof checksums, "%llu templates and %llu encodings now carry checksums; ",
                     (unsigned long long)st.ms_entries, (unsigned long long)se.ms_entries);
        mim_log_emit(opt->log, opt->log_ctx, MIM_LOG_INFO, "%s: migrated from schema version %u to %d: %s%s", db->path,
                     from, MIM_STORE_SCHEMA_VERSION, checksums,
                     from < 3 ? "added the registrations, by_source and bindings tables (empty)"
                              : "nothing rewritten (templates may now carry a dataset, registrations quality figures)");
    }
    return 0;
}
