/* Internal to db/: the environment, transactions, LMDB error mapping, and
 * what the record files share (checksums, the bounds of the data file). */
#ifndef MIM_DB_INTERNAL_H
#define MIM_DB_INTERNAL_H

#include "mim_db.h"

#include <lmdb.h>
#include <stdatomic.h>
#include <xxhash.h>

enum {
    DBI_META,
    DBI_TOPOLOGY,
    DBI_LANDMARKS,
    DBI_TEMPLATES,
    DBI_BY_HASH,
    DBI_ENCODINGS,
    DBI_REGISTRATIONS, /* schema version 3 */
    DBI_BY_SOURCE,     /* schema version 3 */
    DBI_BINDINGS,      /* schema version 3 */
    DBI_COUNT_
};

/* Table names, in DBI_* order, and the LMDB flags each is opened with. */
extern const char *const mim__db_table_names[DBI_COUNT_];
unsigned mim__db_table_flags(int dbi);

struct mim_db {
    MDB_env *env;
    MDB_dbi dbi[DBI_COUNT_];
    int have_encodings; /* 0: a version-1 store without the table, opened read-only */
    /* 0: a store of version 1 or 2 without these tables, opened read-only
     * (registrations: both `registrations` and `by_source`) */
    int have_registrations, have_bindings;
    char *path;
    int read_only;
    uint32_t page_size;
    /* Bytes of data.mdb known to exist: records are checked to lie inside
     * it before they are read (a page past the end of a mapped file is
     * SIGBUS, not an error). The file only grows; refreshed by fstat when
     * a record ends past the value cached here. */
    _Atomic uint64_t file_bytes;
    const char *map_base; /* LMDB's map, to tell map pointers from a writer's own pages */
    uint64_t map_bytes;
    int fd;               /* data.mdb, LMDB's descriptor (for fstat) */
};

struct mim_db_txn {
    mim_db_t *db;
    MDB_txn *txn;
    int write;
    uint32_t version; /* the store's schema version in this transaction's snapshot */
};

/* Maps an LMDB return code to a MIM_E* code with a one-line message that
 * names the store: "store damaged: DIR: WHAT: ..." for damage, what a full
 * map or disk means for a write (nothing committed is lost), and so on. */
int mim__db_fail(const mim_db_t *db, mim_error_t *err, int mdb_rc, const char *what);
/* MIM_ESTORE with "store damaged: DIR: " and the formatted rest. */
int mim__db_damaged(const mim_db_t *db, mim_error_t *err, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* 0 when the value lies inside data.mdb (or in memory of the writing
 * transaction), else the "store damaged" error naming `what`. Called
 * before any byte of a record is read. */
int mim__db_span(const mim_db_txn_t *t, const MDB_val *v, const char *what, mim_error_t *err);

/* Record checksums (schema version 2): XXH3-64 of every byte of a record
 * after its first 16 (magic, u32 header size, u64 checksum). */
#define MIM__CK_OFFSET 8
#define MIM__CK_FROM 16
static inline uint64_t mim__db_checksum(const void *rec, size_t size)
{
    return size > MIM__CK_FROM ? XXH3_64bits((const unsigned char *)rec + MIM__CK_FROM, size - MIM__CK_FROM)
                               : XXH3_64bits(NULL, 0);
}

/* Checks the two meta pages of DIR/data.mdb against the file before LMDB
 * maps it: both valid, and the newer one's last page inside the file.
 * *exists = 0 (and 0 returned) when there is no data.mdb. */
int mim__db_file_check(const char *dir, int *exists, uint32_t *page_size, mim_error_t *err);

/* Checks LMDB's b-tree pages of the snapshot of txn by reading them (not
 * through the map): the table list and the root page of every table, or
 * (full) every page. Each damaged page goes to problem (table: a table
 * name, or "lmdb"; msg: "store damaged: DIR: LMDB page N (table 'x'): ..."); *bad_tables gets
 * a bit per DBI_* whose tree is damaged, MIM__WALK_LIST for the table list
 * (or a table that is not mimic's), MIM__WALK_FREE for the free-page list.
 * 0, or MIM_ENOMEM. */
enum { MIM__WALK_LIST = DBI_COUNT_, MIM__WALK_FREE = DBI_COUNT_ + 1 };
typedef void (*mim__db_walk_fn)(void *ctx, const char *table, const char *msg);
int mim__db_walk(mim_db_t *db, MDB_txn *txn, int full, mim__db_walk_fn problem, void *ctx, unsigned *bad_tables,
                 uint64_t *pages);

/* ---- record codecs shared by the getters, the migration and the check ---- */
/* Template record of schema version `version` (1: MTP1, 2: MTP2). */
int mim__db_template_decode(const mim_db_txn_t *t, uint32_t version, const MDB_val *v, uint64_t key,
                            mim_template_view_t *out, mim_error_t *err);
/* Bytes of a version-2 record for these lengths, and where the positions go. */
size_t mim__db_template_size(const mim_template_in_t *in, size_t *pos_off);
/* Writes a version-2 record of `size` bytes (mim__db_template_size) at p. */
void mim__db_template_encode(unsigned char *p, size_t size, size_t pos_off, uint64_t id, const mim_template_in_t *in);

int mim__db_encoding_decode(const mim_db_txn_t *t, uint32_t version, const MDB_val *v, uint64_t key,
                            mim_db_encoding_t *out, mim_error_t *err);
/* Puts a version-2 encoding record (used by put and by the migration). */
int mim__db_encoding_write(mim_db_txn_t *t, uint64_t id, const float *frames, const float *W, uint32_t n,
                           mim_error_t *err);

/* The landmark map's JSON from its record (v2: "MLM2" header + JSON). */
int mim__db_landmarks_json(const mim_db_txn_t *t, uint32_t version, const MDB_val *v, const char **json,
                           size_t *len, mim_error_t *err);
int mim__db_landmarks_write(mim_db_txn_t *t, const char *json, size_t len, mim_error_t *err);

/* The topology record, its hash checked against its faces. */
int mim__db_topology_decode(const mim_db_txn_t *t, const MDB_val *v, mim_db_topology_t *out, mim_error_t *err);

/* The index build record; with the model's bytes (v2: their checksum is
 * checked against the record's). */
int mim__db_index_build_decode(const mim_db_txn_t *t, uint32_t version, const MDB_val *build, const MDB_val *model,
                               mim_db_index_meta_t *out, mim_error_t *err);
int mim__db_index_build_write(mim_db_txn_t *t, const void *blob, size_t len, const mim_db_index_meta_t *m,
                              mim_error_t *err);

/* Whether the table of DBI_* i is open in db (tables added by a later
 * schema version are missing from an older store opened read-only). */
static inline int mim__db_have(const mim_db_t *db, int i)
{
    if (i == DBI_ENCODINGS) return db->have_encodings;
    if (i == DBI_REGISTRATIONS || i == DBI_BY_SOURCE) return db->have_registrations;
    if (i == DBI_BINDINGS) return db->have_bindings;
    return 1;
}

/* Registration records (registration.c): the record of template `key`,
 * checked (bounds, magic, size, checksum, id, values). */
int mim__db_registration_decode(const mim_db_txn_t *t, const MDB_val *v, uint64_t key, mim_db_registration_t *out,
                                mim_error_t *err);
/* Binding records (binding.c): the blob of key `key`, checked, lent. */
int mim__db_binding_decode(const mim_db_txn_t *t, const MDB_val *v, uint64_t key, const void **blob, size_t *len,
                           mim_error_t *err);

/* Brings a store of schema version t->version (1 or 2) to the current
 * version inside the write transaction t, whose tables the caller has
 * opened or created (1 -> 2: every record rewritten with its checksum;
 * 2 -> 3: the new tables, created empty by the caller; then
 * schema_version). The caller commits; an error leaves t to be aborted,
 * the store as it was. */
int mim__db_migrate(mim_db_txn_t *t, const mim_db_options_t *opt, mim_error_t *err);

#endif
