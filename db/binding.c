/* Avatar bindings (schema version 3): a cache of register/'s binding
 * blobs, opaque here, keyed by the caller's u64 (its hash of the avatar
 * mesh and the store's connectivity). Table `bindings`, u64 key -> record
 * (little-endian, schemas/store.md):
 *    0  "MBN3"            4  u32 header bytes (32)
 *    8  u64 checksum: XXH3-64 of every byte from 16 to the record's end
 *   16  u64 key          24  u64 blob bytes
 *   32  the blob, then zero padding
 * Padded to at least RECORD_MIN bytes like template records, so LMDB keeps
 * every record on its own page-aligned overflow pages and the blob is lent
 * zero-copy, 16-byte aligned. A blob of a few MB costs a fraction of a
 * millisecond to checksum, which every read does before lending it. */
#include "internal.h"

#include <stdio.h>
#include <string.h>

#define BIN_HEADER 32
#define RECORD_MIN 2048 /* > half a 4 KiB page: always an overflow record */

static size_t record_size(size_t len)
{
    size_t n = BIN_HEADER + len;
    return n < RECORD_MIN ? RECORD_MIN : n;
}

int mim__db_binding_decode(const mim_db_txn_t *t, const MDB_val *v, uint64_t key, const void **blob, size_t *len,
                           mim_error_t *err)
{
    *blob = NULL;
    *len = 0;
    char what[48];
    snprintf(what, sizeof what, "binding %016llx", (unsigned long long)key);
    int rc = mim__db_span(t, v, what, err);
    if (rc) return rc;
    const unsigned char *p = v->mv_data;
    if (v->mv_size < BIN_HEADER || memcmp(p, "MBN3", 4))
        return mim__db_damaged(t->db, err, "%s: record is not a binding (bad magic)", what);
    uint32_t hdr;
    uint64_t ck, rkey, n;
    memcpy(&hdr, p + 4, 4);
    memcpy(&ck, p + MIM__CK_OFFSET, 8);
    memcpy(&rkey, p + 16, 8);
    memcpy(&n, p + 24, 8);
    if (ck != mim__db_checksum(p, v->mv_size)) return mim__db_damaged(t->db, err, "%s: checksum mismatch", what);
    if (hdr != BIN_HEADER || rkey != key || n > v->mv_size - BIN_HEADER || record_size((size_t)n) != v->mv_size ||
        (uintptr_t)(p + BIN_HEADER) % 16)
        return mim__db_damaged(t->db, err, "%s: record layout is inconsistent", what);
    *blob = p + BIN_HEADER;
    *len = (size_t)n;
    return 0;
}

int mim_db_binding_get(mim_db_txn_t *t, uint64_t key, const void **blob, size_t *len, mim_error_t *err)
{
    *blob = NULL;
    *len = 0;
    if (!t->db->have_bindings) return MIM_ENOTFOUND; /* an older store, read-only */
    size_t k64 = (size_t)key;
    MDB_val k = {sizeof k64, &k64}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_BINDINGS], &k, &v);
    if (rc == MDB_NOTFOUND) return MIM_ENOTFOUND;
    if (rc) return mim__db_fail(t->db, err, rc, "bindings");
    return mim__db_binding_decode(t, &v, key, blob, len, err);
}

int mim_db_binding_put(mim_db_txn_t *t, uint64_t key, const void *blob, size_t len, mim_error_t *err)
{
    if (!t->write) return mim_error_set(err, MIM_EINVAL, "binding put needs a write transaction");
    if ((!blob && len) || len > SIZE_MAX - RECORD_MIN)
        return mim_error_set(err, MIM_EINVAL, "binding %016llx: no blob of %zu bytes", (unsigned long long)key, len);
    size_t size = record_size(len), k64 = (size_t)key;
    MDB_val k = {sizeof k64, &k64}, v = {size, NULL};
    int rc = mdb_put(t->txn, t->db->dbi[DBI_BINDINGS], &k, &v, MDB_RESERVE);
    if (rc) return mim__db_fail(t->db, err, rc, "binding");
    unsigned char *p = v.mv_data;
    uint32_t hdr = BIN_HEADER;
    uint64_t n = len;
    memset(p, 0, BIN_HEADER);
    memcpy(p, "MBN3", 4);
    memcpy(p + 4, &hdr, 4);
    memcpy(p + 16, &key, 8);
    memcpy(p + 24, &n, 8);
    if (len) memcpy(p + BIN_HEADER, blob, len);
    if (size > BIN_HEADER + len) memset(p + BIN_HEADER + len, 0, size - BIN_HEADER - len);
    uint64_t ck = mim__db_checksum(p, size); /* last: covers everything above */
    memcpy(p + MIM__CK_OFFSET, &ck, 8);
    return 0;
}
