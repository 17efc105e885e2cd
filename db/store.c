/* The store's environment: open/create, schema check, metadata,
 * transactions, size. LMDB gives the ACID and multi-process guarantees:
 * a write transaction is all or nothing, so a kill -9 part-way leaves the
 * last committed state, and readers never block the single writer. */
#include "internal.h"
#include "mim_schema_version.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *const dbi_names[DBI_COUNT_] = {"meta",    "topology", "landmarks",
                                                  "templates", "by_hash", "encodings"};
/* Tables a store of this schema version may hold that mimic no longer
 * opens: stores created before it was dropped have an empty `descriptors`
 * table (reserved, never written; schemas/store.md). They are left as they
 * are, and do not make a store "someone else's". */
static const char *const legacy_names[] = {"descriptors"};

int mim__db_fail(mim_error_t *err, int rc, const char *what)
{
    switch (rc) {
    case MDB_MAP_FULL:
        return mim_error_set(err, MIM_ESTORE, "%s: store is full (map size reached); raise MIMIC_MAP_SIZE", what);
    case MDB_CORRUPTED:
    case MDB_PAGE_NOTFOUND:
        return mim_error_set(err, MIM_ESTORE, "%s: store is corrupted: %s", what, mdb_strerror(rc));
    case MDB_INVALID:
        return mim_error_set(err, MIM_ESTORE, "%s: not an LMDB store (data.mdb is not a database)", what);
    case MDB_VERSION_MISMATCH:
        return mim_error_set(err, MIM_ESTORE, "%s: store was written by an incompatible LMDB", what);
    case MDB_NOTFOUND:
        return mim_error_set(err, MIM_ENOTFOUND, "%s: not found", what);
    default:
        if (rc > 0) /* LMDB passes errno values through */
            return mim_error_set(err, -rc, "%s: %s", what, strerror(rc));
        return mim_error_set(err, MIM_ESTORE, "%s: %s", what, mdb_strerror(rc));
    }
}

static int put_meta_u64(MDB_txn *t, MDB_dbi dbi, const char *key, uint64_t v)
{
    MDB_val k = {strlen(key), (void *)key}, d = {sizeof v, &v};
    return mdb_put(t, dbi, &k, &d, 0);
}

static int get_meta(MDB_txn *t, MDB_dbi dbi, const char *key, MDB_val *out)
{
    MDB_val k = {strlen(key), (void *)key};
    return mdb_get(t, dbi, &k, out);
}

/* Opens the named databases; on a new store (no meta), writes the metadata. */
static int init_store(mim_db_t *db, mim_error_t *err)
{
    MDB_txn *t = NULL;
    int rc = mdb_txn_begin(db->env, NULL, db->read_only ? MDB_RDONLY : 0, &t);
    if (rc) return mim__db_fail(err, rc, db->path);

    /* Any named database but ours means someone else's LMDB store. */
    MDB_dbi main_dbi;
    MDB_cursor *c = NULL;
    int foreign = 0, has_meta = 0;
    if ((rc = mdb_dbi_open(t, NULL, 0, &main_dbi)) == 0 && (rc = mdb_cursor_open(t, main_dbi, &c)) == 0) {
        MDB_val k, d;
        for (int r = mdb_cursor_get(c, &k, &d, MDB_FIRST); r == 0; r = mdb_cursor_get(c, &k, &d, MDB_NEXT)) {
            int ours = 0;
            for (int i = 0; i < DBI_COUNT_; i++)
                if (k.mv_size == strlen(dbi_names[i]) && memcmp(k.mv_data, dbi_names[i], k.mv_size) == 0) ours = 1;
            for (size_t i = 0; i < sizeof legacy_names / sizeof *legacy_names; i++)
                if (k.mv_size == strlen(legacy_names[i]) && memcmp(k.mv_data, legacy_names[i], k.mv_size) == 0)
                    ours = 1;
            if (k.mv_size == 4 && memcmp(k.mv_data, "meta", 4) == 0) has_meta = 1;
            if (!ours) foreign = 1;
        }
        mdb_cursor_close(c);
    }
    if (rc) {
        mdb_txn_abort(t);
        return mim__db_fail(err, rc, db->path);
    }
    if (foreign) {
        mdb_txn_abort(t);
        return mim_error_set(err, MIM_ESTORE, "%s: this LMDB environment is not a mimic store", db->path);
    }
    if (!has_meta && db->read_only) {
        mdb_txn_abort(t);
        return mim_error_set(err, MIM_ENOTFOUND, "%s: no mimic store here (run mimic ingest first)", db->path);
    }
    unsigned flags = db->read_only ? 0 : MDB_CREATE;
    for (int i = 0; i < DBI_COUNT_ && !rc; i++) {
        unsigned f = flags;
        if (i == DBI_TEMPLATES || i == DBI_ENCODINGS) f |= MDB_INTEGERKEY;
        if (i == DBI_BY_HASH) f |= MDB_INTEGERKEY | MDB_DUPSORT | MDB_DUPFIXED | MDB_INTEGERDUP;
        rc = mdb_dbi_open(t, dbi_names[i], f, &db->dbi[i]);
        if (rc == MDB_NOTFOUND && db->read_only) {
            mdb_txn_abort(t);
            return mim_error_set(err, MIM_ESTORE, "%s: store lacks its '%s' table", db->path, dbi_names[i]);
        }
    }
    if (rc) {
        mdb_txn_abort(t);
        return mim__db_fail(err, rc, db->path);
    }

    MDB_val v;
    rc = get_meta(t, db->dbi[DBI_META], "schema_version", &v);
    if (rc == MDB_NOTFOUND && !db->read_only) {
        /* A new store: written in the same transaction as the tables, so a
         * crash leaves either nothing or a complete empty store. */
        uint64_t ver = MIM_STORE_SCHEMA_VERSION;
        const char *by = "mimic " MIM_VERSION;
        MDB_val k = {strlen("created_by"), "created_by"}, d = {strlen(by), (void *)by};
        if (!(rc = put_meta_u64(t, db->dbi[DBI_META], "schema_version", ver)) &&
            !(rc = mdb_put(t, db->dbi[DBI_META], &k, &d, 0)) &&
            !(rc = put_meta_u64(t, db->dbi[DBI_META], "next_id", 1)))
            rc = mdb_txn_commit(t);
        else
            mdb_txn_abort(t);
        return rc ? mim__db_fail(err, rc, db->path) : 0;
    }
    if (rc) {
        mdb_txn_abort(t);
        return mim__db_fail(err, rc, db->path);
    }
    uint64_t ver = 0;
    if (v.mv_size == sizeof ver) memcpy(&ver, v.mv_data, sizeof ver);
    if (ver != MIM_STORE_SCHEMA_VERSION) {
        mdb_txn_abort(t);
        return mim_error_set(err, MIM_ESCHEMA,
                             "%s: store has schema version %llu; this mimic reads version %d (see schemas/store.md)",
                             db->path, (unsigned long long)ver, MIM_STORE_SCHEMA_VERSION);
    }
    /* Commit even when read-only: an aborted transaction closes the table
     * handles it opened. */
    if ((rc = mdb_txn_commit(t))) return mim__db_fail(err, rc, db->path);
    return 0;
}

int mim_db_open(mim_db_t **out, const char *dir, const mim_db_options_t *opt, mim_error_t *err)
{
    if (!out || !dir) return MIM_EINVAL;
    *out = NULL;
    mim_db_options_t defaults = {0};
    if (!opt) opt = &defaults;
    struct stat st;
    if (stat(dir, &st) != 0) {
        if (errno != ENOENT || opt->read_only)
            return mim_error_set(err, errno == ENOENT ? MIM_ENOTFOUND : -errno, "%s: no store: %s", dir,
                                 strerror(errno));
        if (mkdir(dir, 0775) != 0 && errno != EEXIST)
            return mim_error_set(err, -errno, "%s: cannot create store directory: %s", dir, strerror(errno));
    } else if (!S_ISDIR(st.st_mode)) {
        return mim_error_set(err, MIM_EINVAL, "%s: a store is a directory, this is a file", dir);
    }

    mim_db_t *db = calloc(1, sizeof *db);
    if (!db) return MIM_ENOMEM;
    db->path = strdup(dir);
    db->read_only = opt->read_only;
    uint64_t map = opt->map_size ? opt->map_size : 256ULL << 30;

    int rc = mdb_env_create(&db->env);
    if (!rc) rc = mdb_env_set_maxdbs(db->env, DBI_COUNT_ + 2);
    if (!rc) rc = mdb_env_set_mapsize(db->env, map);
    if (!rc) rc = mdb_env_set_maxreaders(db->env, 256);
    /* NOTLS: read transactions may move between threads. Sync stays on:
     * a committed batch survives a crash. */
    if (!rc) rc = mdb_env_open(db->env, dir, MDB_NOTLS | (db->read_only ? MDB_RDONLY : 0), 0664);
    if (rc) {
        if (rc == ENOENT && db->read_only) rc = mim_error_set(err, MIM_ENOTFOUND, "%s: no mimic store here", dir);
        else rc = mim__db_fail(err, rc, dir);
        mim_db_close(&db);
        return rc;
    }
    /* Clear reader slots left by processes that died (kill -9). */
    int dead = 0;
    mdb_reader_check(db->env, &dead);
    if ((rc = init_store(db, err))) {
        mim_db_close(&db);
        return rc;
    }
    *out = db;
    return 0;
}

void mim_db_close(mim_db_t **pdb)
{
    if (!pdb || !*pdb) return;
    mim_db_t *db = *pdb;
    if (db->env) mdb_env_close(db->env);
    free(db->path);
    free(db);
    *pdb = NULL;
}

const char *mim_db_path(const mim_db_t *db) { return db ? db->path : ""; }

int mim_db_begin(mim_db_t *db, int write, mim_db_txn_t **out, mim_error_t *err)
{
    *out = NULL;
    if (write && db->read_only) return mim_error_set(err, MIM_EINVAL, "%s: store is open read-only", db->path);
    mim_db_txn_t *t = calloc(1, sizeof *t);
    if (!t) return MIM_ENOMEM;
    int rc = mdb_txn_begin(db->env, NULL, write ? 0 : MDB_RDONLY, &t->txn);
    if (rc) {
        free(t);
        return mim__db_fail(err, rc, db->path);
    }
    t->db = db;
    t->write = write;
    *out = t;
    return 0;
}

int mim_db_commit(mim_db_txn_t **pt, mim_error_t *err)
{
    if (!pt || !*pt) return MIM_EINVAL;
    mim_db_txn_t *t = *pt;
    int rc = mdb_txn_commit(t->txn);
    const char *path = t->db->path;
    free(t);
    *pt = NULL;
    return rc ? mim__db_fail(err, rc, path) : 0;
}

void mim_db_abort(mim_db_txn_t **pt)
{
    if (!pt || !*pt) return;
    mdb_txn_abort((*pt)->txn);
    free(*pt);
    *pt = NULL;
}

int mim_db_meta_get(mim_db_txn_t *t, mim_db_meta_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    MDB_val v;
    int rc = get_meta(t->txn, t->db->dbi[DBI_META], "schema_version", &v);
    if (rc) return mim__db_fail(err, rc, "store metadata");
    uint64_t x = 0;
    if (v.mv_size == 8) memcpy(&x, v.mv_data, 8);
    out->schema_version = (uint32_t)x;
    if (!get_meta(t->txn, t->db->dbi[DBI_META], "created_by", &v)) {
        size_t n = v.mv_size < sizeof out->created_by - 1 ? v.mv_size : sizeof out->created_by - 1;
        memcpy(out->created_by, v.mv_data, n);
    }
    if (!get_meta(t->txn, t->db->dbi[DBI_META], "next_id", &v) && v.mv_size == 8) memcpy(&out->next_id, v.mv_data, 8);
    MDB_stat ms;
    if ((rc = mdb_stat(t->txn, t->db->dbi[DBI_TEMPLATES], &ms))) return mim__db_fail(err, rc, "store metadata");
    out->templates = ms.ms_entries;
    return 0;
}

int mim_db_stat(mim_db_t *db, mim_db_stat_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    MDB_envinfo info;
    MDB_stat est;
    int rc = mdb_env_info(db->env, &info);
    if (!rc) rc = mdb_env_stat(db->env, &est);
    if (rc) return mim__db_fail(err, rc, db->path);
    out->page_size = est.ms_psize;
    out->pages_used = (uint64_t)info.me_last_pgno + 1;
    out->map_size = info.me_mapsize;
    char p[4096];
    struct stat st;
    snprintf(p, sizeof p, "%s/data.mdb", db->path);
    if (stat(p, &st) == 0) {
        out->file_bytes = (uint64_t)st.st_size;
        out->disk_bytes = (uint64_t)st.st_blocks * 512;
    }
    snprintf(p, sizeof p, "%s/lock.mdb", db->path);
    if (stat(p, &st) == 0) out->disk_bytes += (uint64_t)st.st_blocks * 512;

    MDB_txn *t;
    if ((rc = mdb_txn_begin(db->env, NULL, MDB_RDONLY, &t))) return mim__db_fail(err, rc, db->path);
    int idx[] = {DBI_TEMPLATES, DBI_BY_HASH};
    for (int i = 0; i < 2; i++) {
        MDB_stat s;
        if (!mdb_stat(t, db->dbi[idx[i]], &s))
            out->template_bytes += (s.ms_branch_pages + s.ms_leaf_pages + s.ms_overflow_pages) * (uint64_t)s.ms_psize;
    }
    mdb_txn_abort(t);
    return 0;
}
