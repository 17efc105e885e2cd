/* Per-template intrinsic encodings (seed 000, Section 3.1): what a transfer
 * needs of a template, computed once at ingest instead of per query. Layout
 * (little-endian, schemas/store.md):
 *   0  "MEN1"            4  u32 header bytes (32)
 *   8  u64 id           16  u32 n_vertices      20  u32 frames offset
 *  24  u32 W offset     28  u32 flags (0)
 *  frames offset: 6 * n float32, the local frame's f1 (normal) and f2
 *                 (tangent) per vertex (f3 = f1 x f2 is not stored);
 *  W offset:      3 * n float32, W = F^T L X.
 * Padded to at least RECORD_MIN bytes like template records, so both arrays
 * are handed out zero-copy from the map. */
#include "internal.h"

#include <string.h>

#define ENC_MAGIC "MEN1"
#define ENC_HEADER 32
#define RECORD_MIN 2048

int mim_db_encoding_put(mim_db_txn_t *t, uint64_t id, const float *frames, const float *W, uint32_t n_vertices,
                        mim_error_t *err)
{
    if (!t->write)
        return mim_error_set(err, MIM_EINVAL, "encoding put needs a write transaction");
    if (!frames || !W || n_vertices == 0)
        return mim_error_set(err, MIM_EINVAL, "encoding of template %llu: no data", (unsigned long long)id);
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
        return mim__db_fail(err, rc, "encoding");
    unsigned char *p = v.mv_data;
    memset(p, 0, size);
    uint32_t hdr = ENC_HEADER, fo = (uint32_t)frames_off, wo = (uint32_t)w_off;
    memcpy(p, ENC_MAGIC, 4);
    memcpy(p + 4, &hdr, 4);
    memcpy(p + 8, &id, 8);
    memcpy(p + 16, &n_vertices, 4);
    memcpy(p + 20, &fo, 4);
    memcpy(p + 24, &wo, 4);
    memcpy(p + fo, frames, (size_t)n_vertices * 6 * sizeof(float));
    memcpy(p + wo, W, (size_t)n_vertices * 3 * sizeof(float));
    return 0;
}

int mim_db_encoding_get(mim_db_txn_t *t, uint64_t id, mim_db_encoding_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    size_t key = (size_t)id;
    MDB_val k = {sizeof key, &key}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_ENCODINGS], &k, &v);
    if (rc == MDB_NOTFOUND)
        return mim_error_set(err, MIM_ENOTFOUND, "template %llu: no encoding stored", (unsigned long long)id);
    if (rc)
        return mim__db_fail(err, rc, "encoding");
    const unsigned char *p = v.mv_data;
    uint32_t hdr, n, fo, wo;
    uint64_t rid;
    if (v.mv_size < ENC_HEADER || memcmp(p, ENC_MAGIC, 4) != 0)
        return mim_error_set(err, MIM_ESTORE, "template %llu: encoding record has a bad magic",
                             (unsigned long long)id);
    memcpy(&hdr, p + 4, 4);
    memcpy(&rid, p + 8, 8);
    memcpy(&n, p + 16, 4);
    memcpy(&fo, p + 20, 4);
    memcpy(&wo, p + 24, 4);
    if (hdr != ENC_HEADER || rid != id || n == 0 || fo < hdr || fo % 16 || wo % 16 ||
        (uint64_t)fo + (uint64_t)n * 24 > wo || (uint64_t)wo + (uint64_t)n * 12 > v.mv_size ||
        (uintptr_t)(p + fo) % sizeof(float))
        return mim_error_set(err, MIM_ESTORE, "template %llu: encoding record layout is inconsistent",
                             (unsigned long long)id);
    out->n_vertices = n;
    out->frames = (const float *)(const void *)(p + fo);
    out->W = (const float *)(const void *)(p + wo);
    return 0;
}
