/* The recognition index in the store: two keys of the meta table (no new
 * table, so the layout of everything else is unchanged; schemas/store.md):
 *   "index.model"  the blob of mim_index_save (versioned, with its own
 *                  checksum, checked by index/ when it is loaded)
 *   "index.build"  build record, schema version 2 (64 bytes):
 *                  0 "MIB2", 4 u32 record bytes (64), 8 u64 checksum
 *                  (XXH3-64 of bytes 16..63), 16 u64 next_id, 24 u64
 *                  templates, 32 u32 class_source, 36 u32 n_classes,
 *                  40 u32 d, 44 u32 0, 48 f64 built_at, 56 u64 XXH3-64 of
 *                  the whole index.model value
 *                  version 1 (40 bytes): "MIB1", u32 class_source,
 *                  u64 next_id, u64 templates, u32 n_classes, u32 d,
 *                  f64 built_at
 * next_id and templates are the store's when the index was built: a store
 * whose next_id or template count differs has templates the index lacks. */
#include "internal.h"

#include <string.h>

#define BUILD_V1 40
#define BUILD_V2 64

int mim__db_index_build_write(mim_db_txn_t *t, const void *blob, size_t len, const mim_db_index_meta_t *m,
                              mim_error_t *err)
{
    unsigned char rec[BUILD_V2] = {0};
    uint32_t size = BUILD_V2;
    uint64_t model_ck = XXH3_64bits(blob, len);
    memcpy(rec, "MIB2", 4);
    memcpy(rec + 4, &size, 4);
    memcpy(rec + 16, &m->next_id, 8);
    memcpy(rec + 24, &m->templates, 8);
    memcpy(rec + 32, &m->class_source, 4);
    memcpy(rec + 36, &m->n_classes, 4);
    memcpy(rec + 40, &m->d, 4);
    memcpy(rec + 48, &m->built_at, 8);
    memcpy(rec + 56, &model_ck, 8);
    uint64_t ck = mim__db_checksum(rec, sizeof rec);
    memcpy(rec + MIM__CK_OFFSET, &ck, 8);
    MDB_val k2 = {11, "index.build"}, v2 = {sizeof rec, rec};
    int rc = mdb_put(t->txn, t->db->dbi[DBI_META], &k2, &v2, 0);
    return rc ? mim__db_fail(t->db, err, rc, "index") : 0;
}

int mim_db_index_put(mim_db_txn_t *t, const void *blob, size_t len, const mim_db_index_meta_t *m, mim_error_t *err)
{
    if (!t->write) return mim_error_set(err, MIM_EINVAL, "index put needs a write transaction");
    MDB_val k1 = {11, "index.model"}, v1 = {len, (void *)blob};
    int rc = mdb_put(t->txn, t->db->dbi[DBI_META], &k1, &v1, 0);
    if (rc) return mim__db_fail(t->db, err, rc, "index");
    return mim__db_index_build_write(t, blob, len, m, err);
}

int mim__db_index_build_decode(const mim_db_txn_t *t, uint32_t version, const MDB_val *build, const MDB_val *model,
                               mim_db_index_meta_t *m, mim_error_t *err)
{
    memset(m, 0, sizeof *m);
    int rc = mim__db_span(t, build, "index build record", err);
    if (!rc && model) rc = mim__db_span(t, model, "index model", err);
    if (rc) return rc;
    const unsigned char *p = build->mv_data;
    if (version < 2) {
        if (build->mv_size != BUILD_V1 || memcmp(p, "MIB1", 4))
            return mim__db_damaged(t->db, err, "index build record is malformed (run mimic index)");
        memcpy(&m->class_source, p + 4, 4);
        memcpy(&m->next_id, p + 8, 8);
        memcpy(&m->templates, p + 16, 8);
        memcpy(&m->n_classes, p + 24, 4);
        memcpy(&m->d, p + 28, 4);
        memcpy(&m->built_at, p + 32, 8);
        return 0;
    }
    uint64_t ck, model_ck;
    uint32_t size;
    if (build->mv_size != BUILD_V2 || memcmp(p, "MIB2", 4))
        return mim__db_damaged(t->db, err, "index build record is malformed (run mimic index)");
    memcpy(&size, p + 4, 4);
    memcpy(&ck, p + MIM__CK_OFFSET, 8);
    if (ck != mim__db_checksum(p, build->mv_size) || size != BUILD_V2)
        return mim__db_damaged(t->db, err, "index build record: checksum mismatch (run mimic index)");
    memcpy(&m->next_id, p + 16, 8);
    memcpy(&m->templates, p + 24, 8);
    memcpy(&m->class_source, p + 32, 4);
    memcpy(&m->n_classes, p + 36, 4);
    memcpy(&m->d, p + 40, 4);
    memcpy(&m->built_at, p + 48, 8);
    memcpy(&model_ck, p + 56, 8);
    if (model && XXH3_64bits(model->mv_data, model->mv_size) != model_ck)
        return mim__db_damaged(t->db, err, "index model: checksum mismatch (run mimic index)");
    return 0;
}

static int index_get(mim_db_txn_t *t, const void **blob, size_t *len, mim_db_index_meta_t *m, int whole,
                     mim_error_t *err);

int mim_db_index_get(mim_db_txn_t *t, const void **blob, size_t *len, mim_db_index_meta_t *m, mim_error_t *err)
{
    return index_get(t, blob, len, m, 1, err);
}

/* The whole value's XXH3-64 left to mim_db_check: at 1 000 000 templates it
 * alone reads 739 MiB, and the blob checks itself by section as it is used
 * (index/blob.c). The value is still checked to lie inside the file. */
int mim_db_index_lend(mim_db_txn_t *t, const void **blob, size_t *len, mim_db_index_meta_t *m, mim_error_t *err)
{
    return index_get(t, blob, len, m, 0, err);
}

static int index_get(mim_db_txn_t *t, const void **blob, size_t *len, mim_db_index_meta_t *m, int whole,
                     mim_error_t *err)
{
    memset(m, 0, sizeof *m);
    if (blob) *blob = NULL;
    if (len) *len = 0;
    MDB_val k1 = {11, "index.model"}, v1, k2 = {11, "index.build"}, v2;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_META], &k2, &v2);
    if (rc == MDB_NOTFOUND)
        return mim_error_set(err, MIM_ENOTFOUND, "%s: store has no index (run mimic index)", t->db->path);
    if (rc) return mim__db_fail(t->db, err, rc, "index");
    if (!blob) return mim__db_index_build_decode(t, t->version, &v2, NULL, m, err);
    rc = mdb_get(t->txn, t->db->dbi[DBI_META], &k1, &v1);
    if (rc == MDB_NOTFOUND)
        return mim__db_damaged(t->db, err, "index build record without a model (run mimic index)");
    if (rc) return mim__db_fail(t->db, err, rc, "index");
    if (!whole && (rc = mim__db_span(t, &v1, "index model", err))) return rc;
    if ((rc = mim__db_index_build_decode(t, t->version, &v2, whole ? &v1 : NULL, m, err))) return rc;
    *blob = v1.mv_data;
    *len = v1.mv_size;
    return 0;
}
