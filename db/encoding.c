/* Per-template intrinsic encodings (seed 000, Section 3.1): what a transfer
 * needs of a template, computed once at ingest instead of per query. Layout
 * of schema version 2 (little-endian, schemas/store.md):
 *   0  "MEN2"            4  u32 header bytes (48)
 *   8  u64 checksum: XXH3-64 of every byte from 16 to the record's end
 *  16  u64 id           24  u32 n_vertices      28  u32 frames offset
 *  32  u32 W offset     36  u32 flags (0)       40  u64 0
 *  frames offset: 6 * n float32, the local frame's f1 (normal) and f2
 *                 (tangent) per vertex (f3 = f1 x f2 is not stored);
 *  W offset:      3 * n float32, W = F^T L X.
 * Version 1 ("MEN1", 32-byte header: id at 8, n at 16, offsets at 20 and
 * 24, flags at 28; no checksum) is read from version-1 stores.
 * Padded to at least RECORD_MIN bytes like template records, so both arrays
 * are handed out zero-copy from the map. */
#include "internal.h"

#include <stdio.h>
#include <string.h>

#define ENC_HEADER 48
#define ENC_HEADER_V1 32
#define RECORD_MIN 2048

int mim__db_encoding_write(mim_db_txn_t *t, uint64_t id, const float *frames, const float *W, uint32_t n_vertices,
                           mim_error_t *err)
{
    size_t frames_off = ENC_HEADER, w_off = frames_off + (size_t)n_vertices * 6 * sizeof(float);
    w_off = (w_off + 15) & ~(size_t)15;
    size_t size = w_off + (size_t)n_vertices * 3 * sizeof(float);
    if (size > UINT32_MAX)
        return mim_error_set(err, MIM_EINVAL, "encoding of template %llu: %u vertices is too many",
                             (unsigned long long)id, n_vertices);
    if (size < RECORD_MIN)
        size = RECORD_MIN;
    size_t key = (size_t)id;
    MDB_val k = {sizeof key, &key}, v = {size, NULL};
    int rc = mdb_put(t->txn, t->db->dbi[DBI_ENCODINGS], &k, &v, MDB_RESERVE);
    if (rc)
        return mim__db_fail(t->db, err, rc, "encoding");
    unsigned char *p = v.mv_data;
    memset(p, 0, size);
    uint32_t hdr = ENC_HEADER, fo = (uint32_t)frames_off, wo = (uint32_t)w_off;
    memcpy(p, "MEN2", 4);
    memcpy(p + 4, &hdr, 4);
    memcpy(p + 16, &id, 8);
    memcpy(p + 24, &n_vertices, 4);
    memcpy(p + 28, &fo, 4);
    memcpy(p + 32, &wo, 4);
    memcpy(p + fo, frames, (size_t)n_vertices * 6 * sizeof(float));
    memcpy(p + wo, W, (size_t)n_vertices * 3 * sizeof(float));
    uint64_t ck = mim__db_checksum(p, size);
    memcpy(p + MIM__CK_OFFSET, &ck, 8);
    return 0;
}

int mim_db_encoding_put(mim_db_txn_t *t, uint64_t id, const float *frames, const float *W, uint32_t n_vertices,
                        mim_error_t *err)
{
    if (!t->write)
        return mim_error_set(err, MIM_EINVAL, "encoding put needs a write transaction");
    if (!frames || !W || n_vertices == 0)
        return mim_error_set(err, MIM_EINVAL, "encoding of template %llu: no data", (unsigned long long)id);
    return mim__db_encoding_write(t, id, frames, W, n_vertices, err);
}

int mim__db_encoding_decode(const mim_db_txn_t *t, uint32_t version, const MDB_val *v, uint64_t id,
                            mim_db_encoding_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    char what[48];
    snprintf(what, sizeof what, "template %llu", (unsigned long long)id);
    int rc = mim__db_span(t, v, what, err);
    if (rc)
        return rc;
    const unsigned char *p = v->mv_data;
    const int v2 = version >= 2;
    uint32_t hdr, n, fo, wo, want = v2 ? ENC_HEADER : ENC_HEADER_V1;
    uint64_t rid;
    if (v->mv_size < want || memcmp(p, v2 ? "MEN2" : "MEN1", 4) != 0)
        return mim__db_damaged(t->db, err, "%s: encoding record has a bad magic", what);
    memcpy(&hdr, p + 4, 4);
    if (v2) {
        uint64_t ck;
        memcpy(&ck, p + MIM__CK_OFFSET, 8);
        if (ck != mim__db_checksum(p, v->mv_size))
            return mim__db_damaged(t->db, err, "%s: encoding checksum mismatch", what);
        memcpy(&rid, p + 16, 8);
        memcpy(&n, p + 24, 4);
        memcpy(&fo, p + 28, 4);
        memcpy(&wo, p + 32, 4);
    } else {
        memcpy(&rid, p + 8, 8);
        memcpy(&n, p + 16, 4);
        memcpy(&fo, p + 20, 4);
        memcpy(&wo, p + 24, 4);
    }
    if (hdr != want || rid != id || n == 0 || fo < hdr || fo % 16 || wo % 16 ||
        (uint64_t)fo + (uint64_t)n * 24 > wo || (uint64_t)wo + (uint64_t)n * 12 > v->mv_size ||
        (uintptr_t)(p + fo) % sizeof(float))
        return mim__db_damaged(t->db, err, "%s: encoding record layout is inconsistent", what);
    out->n_vertices = n;
    out->frames = (const float *)(const void *)(p + fo);
    out->W = (const float *)(const void *)(p + wo);
    return 0;
}

int mim_db_encoding_get(mim_db_txn_t *t, uint64_t id, mim_db_encoding_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!t->db->have_encodings) /* a version-1 store from before encodings, read-only */
        return mim_error_set(err, MIM_ENOTFOUND, "template %llu: no encoding stored", (unsigned long long)id);
    size_t key = (size_t)id;
    MDB_val k = {sizeof key, &key}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_ENCODINGS], &k, &v);
    if (rc == MDB_NOTFOUND)
        return mim_error_set(err, MIM_ENOTFOUND, "template %llu: no encoding stored", (unsigned long long)id);
    if (rc)
        return mim__db_fail(t->db, err, rc, "encoding");
    return mim__db_encoding_decode(t, t->version, &v, id, out, err);
}
