/* The store's environment: open/create, damage and schema checks,
 * metadata, transactions, size. LMDB gives the ACID and multi-process
 * guarantees: a write transaction is all or nothing, so a kill -9 part-way
 * leaves the last committed state, and readers never block the single
 * writer. What LMDB does not give, mimic checks: that data.mdb is whole
 * before it is mapped (lmdb_file.c), that the environment is a complete
 * mimic store before anything is written to it, and that each record is
 * inside the file and passes its checksum before it is lent out. */
#include "internal.h"
#include "mim_schema_version.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

const char *const mim__db_table_names[DBI_COUNT_] = {"meta",      "topology",      "landmarks", "templates", "by_hash",
                                                     "encodings", "registrations", "by_source", "bindings"};
/* Tables a store of this schema version may hold that mimic no longer
 * opens: stores created before it was dropped have an empty `descriptors`
 * table (reserved, never written; schemas/store.md). They are left as they
 * are, and do not make a store "someone else's". */
static const char *const legacy_names[] = {"descriptors"};

/* The flags LMDB keeps with a table. */
#define PERSISTENT (MDB_REVERSEKEY | MDB_DUPSORT | MDB_INTEGERKEY | MDB_DUPFIXED | MDB_INTEGERDUP | MDB_REVERSEDUP)

unsigned mim__db_table_flags(int i)
{
    if (i == DBI_TEMPLATES || i == DBI_ENCODINGS || i == DBI_REGISTRATIONS || i == DBI_BINDINGS) return MDB_INTEGERKEY;
    if (i == DBI_BY_HASH || i == DBI_BY_SOURCE) return MDB_INTEGERKEY | MDB_DUPSORT | MDB_DUPFIXED | MDB_INTEGERDUP;
    return 0;
}

static const char *db_path(const mim_db_t *db) { return db && db->path ? db->path : "store"; }

int mim__db_damaged(const mim_db_t *db, mim_error_t *err, const char *fmt, ...)
{
    char what[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return mim_error_set(err, MIM_ESTORE, "store damaged: %s: %s", db_path(db), what);
}

/* A write that could not be made: say whether the map, the disk or the
 * file size limit is full, and that the committed state is untouched. LMDB
 * reports a short write (a disk that filled part-way) as EIO. */
static int write_failed(const mim_db_t *db, mim_error_t *err, int rc)
{
    static const char intact[] =
        "this transaction was not committed; everything committed before it is intact (LMDB commits are atomic)";
    const char *dir = db_path(db);
    if (rc == MDB_MAP_FULL) {
        MDB_envinfo info;
        unsigned long long map = db && db->env && !mdb_env_info(db->env, &info) ? (unsigned long long)info.me_mapsize : 0;
        return mim_error_set(err, MIM_ESTORE, "%s: the store's map is full (map size %llu bytes): %s; raise MIMIC_MAP_SIZE and run again",
                             dir, map, intact);
    }
    char file[4096];
    snprintf(file, sizeof file, "%s/data.mdb", dir);
    struct stat st;
    struct rlimit rl;
    struct statvfs vfs;
    unsigned long long free_bytes = statvfs(dir, &vfs) == 0 ? (unsigned long long)vfs.f_bavail * vfs.f_frsize : ~0ULL;
    if (rc == EFBIG || (rc == EIO && getrlimit(RLIMIT_FSIZE, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY &&
                        stat(file, &st) == 0 && (unsigned long long)st.st_size + (1u << 20) >= rl.rlim_cur))
        return mim_error_set(err, -rc, "%s: data.mdb reached the file size limit (ulimit -f: %llu bytes): %s", dir,
                             getrlimit(RLIMIT_FSIZE, &rl) == 0 ? (unsigned long long)rl.rlim_cur : 0ULL, intact);
    if (rc == ENOSPC || rc == EDQUOT || (rc == EIO && free_bytes < (16u << 20)))
        return mim_error_set(err, -rc, "%s: the store's disk is full (%s, %llu bytes free): %s; free some space and run again",
                             dir, rc == EIO ? "a short write" : strerror(rc), free_bytes, intact);
    return mim_error_set(err, -rc, "%s: write error on the store's disk (%s): %s", dir, strerror(rc), intact);
}

int mim__db_fail(const mim_db_t *db, mim_error_t *err, int rc, const char *what)
{
    switch (rc) {
    case MDB_MAP_FULL:
    case ENOSPC:
    case EDQUOT:
    case EFBIG:
    case EIO:
        return write_failed(db, err, rc);
    case MDB_CORRUPTED:
    case MDB_PAGE_NOTFOUND:
    case MDB_INVALID:
    case MDB_INCOMPATIBLE:
    case MDB_BAD_VALSIZE:
        return mim__db_damaged(db, err, "%s: %s", what, mdb_strerror(rc));
    case MDB_VERSION_MISMATCH:
        return mim_error_set(err, MIM_ESTORE, "%s: %s: store was written by an incompatible LMDB", db_path(db), what);
    case MDB_NOTFOUND:
        return mim_error_set(err, MIM_ENOTFOUND, "%s: %s: not found", db_path(db), what);
    default:
        if (rc > 0) /* LMDB passes errno values through */
            return mim_error_set(err, -rc, "%s: %s: %s", db_path(db), what, strerror(rc));
        return mim_error_set(err, MIM_ESTORE, "%s: %s: %s", db_path(db), what, mdb_strerror(rc));
    }
}

int mim__db_span(const mim_db_txn_t *t, const MDB_val *v, const char *what, mim_error_t *err)
{
    mim_db_t *db = t->db;
    const char *p = v->mv_data;
    if (!db->map_base || p < db->map_base || (uint64_t)(p - db->map_base) >= db->map_bytes)
        return 0; /* the writer's own page, in memory */
    uint64_t off = (uint64_t)(p - db->map_base), end = off + v->mv_size;
    if (end >= off && end <= atomic_load_explicit(&db->file_bytes, memory_order_relaxed)) return 0;
    struct stat st;
    if (end >= off && fstat(db->fd, &st) == 0) {
        atomic_store_explicit(&db->file_bytes, (uint64_t)st.st_size, memory_order_relaxed);
        if (end <= (uint64_t)st.st_size) return 0;
    }
    return mim__db_damaged(db, err, "%s: its record (%zu bytes at byte %llu) runs past the end of data.mdb", what,
                           v->mv_size, (unsigned long long)off);
}

static int put_meta_u64(MDB_txn *t, MDB_dbi dbi, const char *key, uint64_t v)
{
    MDB_val k = {strlen(key), (void *)key}, d = {sizeof v, &v};
    return mdb_put(t, dbi, &k, &d, 0);
}

/* A u64 of the meta table: 0, MDB_NOTFOUND, or MDB_BAD_VALSIZE when it is
 * not 8 bytes. */
static int get_meta_u64(MDB_txn *t, MDB_dbi dbi, const char *key, uint64_t *out)
{
    MDB_val k = {strlen(key), (void *)key}, v;
    int rc = mdb_get(t, dbi, &k, &v);
    if (rc) return rc;
    if (v.mv_size != 8) return MDB_BAD_VALSIZE;
    memcpy(out, v.mv_data, 8);
    return 0;
}

/* The schema version a table first appeared in: an older store may lack it. */
static int table_since(int i)
{
    if (i == DBI_ENCODINGS) return 2; /* optional in version 1 (stores filled before ingest kept encodings) */
    if (i == DBI_REGISTRATIONS || i == DBI_BY_SOURCE || i == DBI_BINDINGS) return 3;
    return 1;
}

static int schema_error(const mim_db_t *db, mim_error_t *err, uint64_t ver)
{
    return mim_error_set(err, MIM_ESCHEMA,
                         "%s: store has schema version %llu; this mimic reads versions 1 to %d (see schemas/store.md)",
                         db->path, (unsigned long long)ver, MIM_STORE_SCHEMA_VERSION);
}

/* A table name for a message: printable, short. */
static void printable_name(char *out, size_t size, const MDB_val *k)
{
    size_t n = 0;
    for (size_t i = 0; i < k->mv_size && n + 1 < size; i++) {
        unsigned char ch = ((const unsigned char *)k->mv_data)[i];
        out[n++] = ch >= 32 && ch < 127 && ch != '\'' ? (char)ch : '?';
    }
    out[n] = 0;
}

/* A new store: every table and the metadata, in one transaction, so a
 * crash leaves either nothing or a complete empty store. */
static int create_store(mim_db_t *db, MDB_txn *t, mim_error_t *err)
{
    int rc = 0;
    for (int i = 0; i < DBI_COUNT_ && !rc; i++)
        rc = mdb_dbi_open(t, mim__db_table_names[i], MDB_CREATE | mim__db_table_flags(i), &db->dbi[i]);
    const char *by = "mimic " MIM_VERSION;
    MDB_val k = {strlen("created_by"), "created_by"}, d = {strlen(by), (void *)by};
    if (!rc) rc = put_meta_u64(t, db->dbi[DBI_META], "schema_version", MIM_STORE_SCHEMA_VERSION);
    if (!rc) rc = mdb_put(t, db->dbi[DBI_META], &k, &d, 0);
    if (!rc) rc = put_meta_u64(t, db->dbi[DBI_META], "next_id", 1);
    if (rc) {
        mdb_txn_abort(t);
        return mim__db_fail(db, err, rc, "creating the store");
    }
    db->have_encodings = db->have_registrations = db->have_bindings = 1;
    return (rc = mdb_txn_commit(t)) ? mim__db_fail(db, err, rc, "creating the store") : 0;
}

/* Opens the named databases of an existing store, creates a new one in an
 * environment that never held anything, and refuses anything else. */
static int init_store(mim_db_t *db, const mim_db_options_t *opt, mim_error_t *err)
{
    MDB_txn *t = NULL;
    int rc = mdb_txn_begin(db->env, NULL, db->read_only ? MDB_RDONLY : 0, &t);
    if (rc) return mim__db_fail(db, err, rc, "first transaction");

    /* The table list: LMDB's main database names each table. */
    MDB_dbi main_dbi;
    MDB_cursor *c = NULL;
    int present[DBI_COUNT_] = {0}, n_tables = 0, r = MDB_NOTFOUND;
    char foreign[64] = "";
    if ((rc = mdb_dbi_open(t, NULL, 0, &main_dbi)) == 0 && (rc = mdb_cursor_open(t, main_dbi, &c)) == 0) {
        MDB_val k, d;
        for (r = mdb_cursor_get(c, &k, &d, MDB_FIRST); r == 0; r = mdb_cursor_get(c, &k, &d, MDB_NEXT)) {
            int ours = 0;
            n_tables++;
            for (int i = 0; i < DBI_COUNT_; i++)
                if (k.mv_size == strlen(mim__db_table_names[i]) && !memcmp(k.mv_data, mim__db_table_names[i], k.mv_size))
                    ours = present[i] = 1;
            for (size_t i = 0; i < sizeof legacy_names / sizeof *legacy_names; i++)
                if (k.mv_size == strlen(legacy_names[i]) && !memcmp(k.mv_data, legacy_names[i], k.mv_size)) ours = 1;
            if (!ours && !foreign[0]) printable_name(foreign, sizeof foreign, &k);
        }
        mdb_cursor_close(c);
    }
    if (rc || r != MDB_NOTFOUND) {
        mdb_txn_abort(t);
        return mim__db_damaged(db, err, "its table list cannot be read (%s)", mdb_strerror(rc ? rc : r));
    }
    if (foreign[0]) {
        mdb_txn_abort(t);
        return mim__db_damaged(db, err, "it holds a table '%s' that mimic never writes: not a mimic store", foreign);
    }
    if (n_tables == 0) {
        /* LMDB's own fresh environment (a creation cut short is one too)
         * is a new store; one that has committed something is not. */
        MDB_envinfo info;
        if (mdb_env_info(db->env, &info) == 0 && info.me_last_txnid != 0) {
            mdb_txn_abort(t);
            return mim__db_damaged(db, err, "an LMDB environment without mimic's tables (after %zu transactions): "
                                            "not a mimic store", info.me_last_txnid);
        }
        if (db->read_only) {
            mdb_txn_abort(t);
            return mim_error_set(err, MIM_ENOTFOUND, "%s: no mimic store here (run mimic ingest first)", db->path);
        }
        return create_store(db, t, err);
    }

    /* An existing store: every table there, and of the kind mimic writes.
     * Tables of a later schema version may be missing (encodings from a
     * version-1 store filled before ingest kept encodings; registrations,
     * by_source and bindings from versions 1 and 2); nothing is created
     * before the version is known. */
    for (int i = 0; i < DBI_COUNT_; i++) {
        if (!present[i]) {
            if (table_since(i) > 1) continue;
            mdb_txn_abort(t);
            return mim__db_damaged(db, err, "it lacks its '%s' table", mim__db_table_names[i]);
        }
        /* LMDB 0.9 opens an existing table with its stored flags, whatever
         * is asked: compare them (integer keys, sorted duplicates). */
        unsigned have = 0;
        rc = mdb_dbi_open(t, mim__db_table_names[i], mim__db_table_flags(i), &db->dbi[i]);
        if (!rc && !(rc = mdb_dbi_flags(t, db->dbi[i], &have)) && (have & PERSISTENT) != mim__db_table_flags(i))
            rc = MDB_INCOMPATIBLE;
        if (rc) {
            mdb_txn_abort(t);
            if (rc == MDB_INCOMPATIBLE)
                return mim__db_damaged(db, err, "its '%s' table is not of the kind mimic writes", mim__db_table_names[i]);
            return mim__db_fail(db, err, rc, mim__db_table_names[i]);
        }
    }
    uint64_t ver = 0, next = 0;
    const char *bad = NULL;
    if ((rc = get_meta_u64(t, db->dbi[DBI_META], "schema_version", &ver))) bad = "schema_version";
    else if ((rc = get_meta_u64(t, db->dbi[DBI_META], "next_id", &next)) || next == 0) bad = "next_id";
    if (bad) {
        mdb_txn_abort(t);
        if (rc && rc != MDB_NOTFOUND && rc != MDB_BAD_VALSIZE) return mim__db_fail(db, err, rc, "store metadata");
        return mim__db_damaged(db, err, "its metadata has %s %s", rc == MDB_NOTFOUND ? "no" : "a malformed", bad);
    }
    if (ver < 1 || ver > MIM_STORE_SCHEMA_VERSION) {
        mdb_txn_abort(t);
        return schema_error(db, err, ver);
    }
    /* A table of the store's own version must be there; one of a later
     * version is created by a read-write open (in this transaction, with
     * the migration below) and is missing from a read-only one. */
    for (int i = 0; i < DBI_COUNT_; i++) {
        if (present[i]) continue;
        if ((uint64_t)table_since(i) <= ver) {
            mdb_txn_abort(t);
            return mim__db_damaged(db, err, "it lacks its '%s' table", mim__db_table_names[i]);
        }
        if (!db->read_only &&
            (rc = mdb_dbi_open(t, mim__db_table_names[i], MDB_CREATE | mim__db_table_flags(i), &db->dbi[i]))) {
            mdb_txn_abort(t);
            return mim__db_fail(db, err, rc, mim__db_table_names[i]);
        }
    }
    db->have_encodings = present[DBI_ENCODINGS] || !db->read_only;
    /* (a version-2 store read as it is has none, whatever it holds) */
    db->have_registrations = db->have_bindings = ver >= 3 || !db->read_only;
    const int migrating = ver != MIM_STORE_SCHEMA_VERSION && !db->read_only;
    if (migrating) {
        mim_db_txn_t wt = {db, t, 1, (uint32_t)ver};
        if ((rc = mim__db_migrate(&wt, opt, err))) {
            mdb_txn_abort(t);
            return rc;
        }
    }
    /* Commit even when read-only: an aborted transaction closes the table
     * handles it opened. */
    if ((rc = mdb_txn_commit(t))) return mim__db_fail(db, err, rc, migrating ? "migration" : "opening");
    return 0;
}

/* The first damaged page an open finds is its error. */
static void open_problem(void *ctx, const char *table, const char *msg)
{
    (void)table;
    mim_error_t *err = ctx;
    if (err && !err->code) mim_error_set(err, MIM_ESTORE, "%s", msg);
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
    /* Before LMDB maps it (a truncated file would be SIGBUS) or writes to
     * it (an empty file would become a new store). */
    int exists = 0;
    uint32_t psize = 0;
    int rc = mim__db_file_check(dir, &exists, &psize, err);
    if (rc) return rc;
    if (!exists && opt->read_only) return mim_error_set(err, MIM_ENOTFOUND, "%s: no mimic store here", dir);

    mim_db_t *db = calloc(1, sizeof *db);
    if (!db) return MIM_ENOMEM;
    db->path = strdup(dir);
    db->read_only = opt->read_only;
    db->fd = -1;
    uint64_t map = opt->map_size ? opt->map_size : 256ULL << 30;

    rc = mdb_env_create(&db->env);
    if (!rc) rc = mdb_env_set_maxdbs(db->env, DBI_COUNT_ + 2);
    if (!rc) rc = mdb_env_set_mapsize(db->env, map);
    if (!rc) rc = mdb_env_set_maxreaders(db->env, 256);
    /* NOTLS: read transactions may move between threads. Sync stays on:
     * a committed batch survives a crash. */
    if (!rc) rc = mdb_env_open(db->env, dir, MDB_NOTLS | (db->read_only ? MDB_RDONLY : 0), 0664);
    if (rc) {
        if (rc == ENOENT && db->read_only) rc = mim_error_set(err, MIM_ENOTFOUND, "%s: no mimic store here", dir);
        else rc = mim__db_fail(db, err, rc, "data.mdb");
        mim_db_close(&db);
        return rc;
    }
    /* The map LMDB now uses must fit in the file as it is (the check above
     * read the same metas, unless the file changed in between). */
    MDB_envinfo info;
    MDB_stat est;
    if (!(rc = mdb_env_info(db->env, &info)) && !(rc = mdb_env_stat(db->env, &est)) &&
        !(rc = mdb_env_get_fd(db->env, &db->fd))) {
        db->page_size = est.ms_psize;
        db->map_base = info.me_mapaddr;
        db->map_bytes = info.me_mapsize;
        uint64_t need = ((uint64_t)info.me_last_pgno + 1) * est.ms_psize;
        if (fstat(db->fd, &st) != 0) rc = errno;
        else if ((uint64_t)st.st_size < need)
            rc = mim_error_set(err, MIM_ESTORE, "store damaged: %s/data.mdb: truncated: the file has %llu bytes, the store uses %llu",
                               dir, (unsigned long long)st.st_size, (unsigned long long)need);
        else
            atomic_store(&db->file_bytes, (uint64_t)st.st_size);
    }
    if (rc) {
        if (rc > 0) rc = mim__db_fail(db, err, rc, "data.mdb");
        mim_db_close(&db);
        return rc;
    }
    /* LMDB's trees, read before LMDB follows them: the table list whole,
     * the root page of each table (mim_db_check reads every page). */
    if (!rc) {
        MDB_txn *rt = NULL;
        unsigned bad = 0;
        if (!(rc = mdb_txn_begin(db->env, NULL, MDB_RDONLY, &rt))) {
            rc = mim__db_walk(db, rt, 0, open_problem, err, &bad, NULL);
            mdb_txn_abort(rt);
            if (!rc && bad) rc = MIM_ESTORE; /* the message is the first problem's */
        } else {
            rc = mim__db_fail(db, err, rc, "data.mdb");
        }
    }
    if (rc) {
        mim_db_close(&db);
        return rc;
    }
    /* Clear reader slots left by processes that died (kill -9). */
    int dead = 0;
    mdb_reader_check(db->env, &dead);
    if ((rc = init_store(db, opt, err))) {
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
        return mim__db_fail(db, err, rc, "transaction");
    }
    t->db = db;
    t->write = write;
    /* The version of this snapshot decides how records decode: another
     * process may have migrated the store since it was opened. */
    uint64_t ver = 0;
    rc = get_meta_u64(t->txn, db->dbi[DBI_META], "schema_version", &ver);
    if (rc == MDB_NOTFOUND || rc == MDB_BAD_VALSIZE)
        rc = mim__db_damaged(db, err, "its metadata has %s schema_version", rc == MDB_NOTFOUND ? "no" : "a malformed");
    else if (rc)
        rc = mim__db_fail(db, err, rc, "store metadata");
    else if (ver < 1 || ver > MIM_STORE_SCHEMA_VERSION || (write && ver != MIM_STORE_SCHEMA_VERSION))
        rc = schema_error(db, err, ver);
    if (rc) {
        mdb_txn_abort(t->txn);
        free(t);
        return rc;
    }
    t->version = (uint32_t)ver;
    *out = t;
    return 0;
}

int mim_db_commit(mim_db_txn_t **pt, mim_error_t *err)
{
    if (!pt || !*pt) return MIM_EINVAL;
    mim_db_txn_t *t = *pt;
    int rc = mdb_txn_commit(t->txn);
    mim_db_t *db = t->db;
    free(t);
    *pt = NULL;
    return rc ? mim__db_fail(db, err, rc, "commit") : 0;
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
    MDB_dbi meta = t->db->dbi[DBI_META];
    uint64_t x = 0;
    int rc = get_meta_u64(t->txn, meta, "schema_version", &x);
    if (rc == MDB_NOTFOUND || rc == MDB_BAD_VALSIZE) return mim__db_damaged(t->db, err, "its metadata has no valid schema_version");
    if (rc) return mim__db_fail(t->db, err, rc, "store metadata");
    out->schema_version = (uint32_t)x;
    MDB_val k = {10, "created_by"}, v;
    if (!mdb_get(t->txn, meta, &k, &v)) {
        size_t n = v.mv_size < sizeof out->created_by - 1 ? v.mv_size : sizeof out->created_by - 1;
        memcpy(out->created_by, v.mv_data, n);
    }
    rc = get_meta_u64(t->txn, meta, "next_id", &out->next_id);
    if (rc == MDB_NOTFOUND || rc == MDB_BAD_VALSIZE) return mim__db_damaged(t->db, err, "its metadata has no valid next_id");
    if (rc) return mim__db_fail(t->db, err, rc, "store metadata");
    MDB_stat ms;
    if ((rc = mdb_stat(t->txn, t->db->dbi[DBI_TEMPLATES], &ms))) return mim__db_fail(t->db, err, rc, "store metadata");
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
    if (rc) return mim__db_fail(db, err, rc, "size");
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
    if ((rc = mdb_txn_begin(db->env, NULL, MDB_RDONLY, &t))) return mim__db_fail(db, err, rc, "size");
    int idx[] = {DBI_TEMPLATES, DBI_BY_HASH};
    for (int i = 0; i < 2; i++) {
        MDB_stat s;
        if (!mdb_stat(t, db->dbi[idx[i]], &s))
            out->template_bytes += (s.ms_branch_pages + s.ms_leaf_pages + s.ms_overflow_pages) * (uint64_t)s.ms_psize;
    }
    mdb_txn_abort(t);
    return 0;
}
