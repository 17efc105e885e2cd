/* The recognition index in the store: two keys of the meta table (no new
 * table, so the layout of everything else is unchanged; schemas/store.md):
 *   "index.model"  the blob of mim_index_save (versioned, with a checksum)
 *   "index.build"  build record: "MIB1", u32 class_source, u64 next_id,
 *                  u64 templates, u32 n_classes, u32 d, f64 built_at
 * next_id and templates are the store's when the index was built: a store
 * whose next_id or template count differs has templates the index lacks. */
#include "internal.h"

#include <string.h>

#define BUILD_BYTES 40

int mim_db_index_put(mim_db_txn_t *t, const void *blob, size_t len, const mim_db_index_meta_t *m, mim_error_t *err)
{
    unsigned char rec[BUILD_BYTES] = {0};
    memcpy(rec, "MIB1", 4);
    memcpy(rec + 4, &m->class_source, 4);
    memcpy(rec + 8, &m->next_id, 8);
    memcpy(rec + 16, &m->templates, 8);
    memcpy(rec + 24, &m->n_classes, 4);
    memcpy(rec + 28, &m->d, 4);
    memcpy(rec + 32, &m->built_at, 8);
    MDB_val k1 = {11, "index.model"}, v1 = {len, (void *)blob};
    MDB_val k2 = {11, "index.build"}, v2 = {sizeof rec, rec};
    int rc = mdb_put(t->txn, t->db->dbi[DBI_META], &k1, &v1, 0);
    if (!rc) rc = mdb_put(t->txn, t->db->dbi[DBI_META], &k2, &v2, 0);
    return rc ? mim__db_fail(err, rc, "store index") : 0;
}

int mim_db_index_get(mim_db_txn_t *t, const void **blob, size_t *len, mim_db_index_meta_t *m, mim_error_t *err)
{
    memset(m, 0, sizeof *m);
    if (blob) *blob = NULL;
    if (len) *len = 0;
    MDB_val k1 = {11, "index.model"}, v1, k2 = {11, "index.build"}, v2;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_META], &k2, &v2);
    if (rc == MDB_NOTFOUND)
        return mim_error_set(err, MIM_ENOTFOUND, "%s: store has no index (run mimic index)", t->db->path);
    if (rc) return mim__db_fail(err, rc, "store index");
    if (v2.mv_size != BUILD_BYTES || memcmp(v2.mv_data, "MIB1", 4))
        return mim_error_set(err, MIM_ESTORE, "%s: index build record is damaged (run mimic index)", t->db->path);
    const unsigned char *p = v2.mv_data;
    memcpy(&m->class_source, p + 4, 4);
    memcpy(&m->next_id, p + 8, 8);
    memcpy(&m->templates, p + 16, 8);
    memcpy(&m->n_classes, p + 24, 4);
    memcpy(&m->d, p + 28, 4);
    memcpy(&m->built_at, p + 32, 8);
    if (!blob) return 0;
    rc = mdb_get(t->txn, t->db->dbi[DBI_META], &k1, &v1);
    if (rc == MDB_NOTFOUND)
        return mim_error_set(err, MIM_ESTORE, "%s: index build record without a model (run mimic index)", t->db->path);
    if (rc) return mim__db_fail(err, rc, "store index");
    *blob = v1.mv_data;
    *len = v1.mv_size;
    return 0;
}
