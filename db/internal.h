/* Internal to db/: the environment, transactions and LMDB error mapping. */
#ifndef MIM_DB_INTERNAL_H
#define MIM_DB_INTERNAL_H

#include "mim_db.h"

#include <lmdb.h>

enum { DBI_META, DBI_TOPOLOGY, DBI_LANDMARKS, DBI_TEMPLATES, DBI_BY_HASH, DBI_ENCODINGS, DBI_COUNT_ };

struct mim_db {
    MDB_env *env;
    MDB_dbi dbi[DBI_COUNT_];
    char *path;
    int read_only;
};

struct mim_db_txn {
    mim_db_t *db;
    MDB_txn *txn;
    int write;
};

/* Maps an LMDB return code to a MIM_E* code with a one-line message. */
int mim__db_fail(mim_error_t *err, int mdb_rc, const char *what);

#endif
