/* The store's landmark map, kept as the same JSON a landmark file holds.
 * Schema version 2 puts a 16-byte header before it: "MLM2", u32 header
 * bytes (16), u64 XXH3-64 checksum of the JSON. Version 1 stored the JSON
 * alone. */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

#define LM_HEADER 16

int mim__db_landmarks_json(const mim_db_txn_t *t, uint32_t version, const MDB_val *v, const char **json,
                           size_t *len, mim_error_t *err)
{
    int rc = mim__db_span(t, v, "landmark map", err);
    if (rc) return rc;
    const unsigned char *p = v->mv_data;
    if (version < 2) {
        *json = (const char *)p;
        *len = v->mv_size;
        return 0;
    }
    uint32_t hdr;
    uint64_t ck;
    if (v->mv_size < LM_HEADER || memcmp(p, "MLM2", 4)) return mim__db_damaged(t->db, err, "landmark map: bad magic");
    memcpy(&hdr, p + 4, 4);
    memcpy(&ck, p + MIM__CK_OFFSET, 8);
    if (ck != mim__db_checksum(p, v->mv_size)) return mim__db_damaged(t->db, err, "landmark map: checksum mismatch");
    if (hdr != LM_HEADER) return mim__db_damaged(t->db, err, "landmark map: record layout is inconsistent");
    *json = (const char *)p + LM_HEADER;
    *len = v->mv_size - LM_HEADER;
    return 0;
}

int mim__db_landmarks_write(mim_db_txn_t *t, const char *json, size_t len, mim_error_t *err)
{
    MDB_val k = {3, "map"}, v = {LM_HEADER + len, NULL};
    int rc = mdb_put(t->txn, t->db->dbi[DBI_LANDMARKS], &k, &v, MDB_RESERVE);
    if (rc) return mim__db_fail(t->db, err, rc, "landmark map");
    unsigned char *p = v.mv_data;
    uint32_t hdr = LM_HEADER;
    memset(p, 0, LM_HEADER);
    memcpy(p, "MLM2", 4);
    memcpy(p + 4, &hdr, 4);
    memcpy(p + LM_HEADER, json, len);
    uint64_t ck = mim__db_checksum(p, v.mv_size);
    memcpy(p + MIM__CK_OFFSET, &ck, 8);
    return 0;
}

int mim_db_landmarks_get(mim_db_txn_t *t, mim_landmark_map_t *out, mim_error_t *err)
{
    MDB_val k = {3, "map"}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_LANDMARKS], &k, &v);
    if (rc == MDB_NOTFOUND) return MIM_ENOTFOUND;
    if (rc) return mim__db_fail(t->db, err, rc, "landmark map");
    const char *json = NULL;
    size_t len = 0;
    if ((rc = mim__db_landmarks_json(t, t->version, &v, &json, &len, err))) return rc;
    mim_error_t e = {0};
    if ((rc = mim_landmarks_parse(out, json, len, "store landmark map", &e)))
        return mim__db_damaged(t->db, err, "%s", e.msg);
    return 0;
}

int mim_db_landmarks_put(mim_db_txn_t *t, const mim_landmark_map_t *map, mim_error_t *err)
{
    if (!t->write) return mim_error_set(err, MIM_EINVAL, "landmark map put needs a write transaction");
    char *json = mim_landmarks_to_json(map);
    if (!json) return MIM_ENOMEM;
    int rc = mim__db_landmarks_write(t, json, strlen(json), err);
    free(json);
    return rc;
}
