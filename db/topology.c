/* The reference connectivity: one per store, fixed by the first ingest.
 * Record: u32 n_vertices, u32 n_faces, u64 hash, then 3 * n_faces u32,
 * zero-padded to at least RECORD_MIN bytes so that LMDB puts it on its own
 * page-aligned overflow pages and the faces can be lent zero-copy. The
 * hash is checked against the faces on every read: it is the record's
 * checksum, so the layout is the same in schema versions 1 and 2. */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

#define TOPO_HEADER 16
#define RECORD_MIN 2048 /* > half a 4 KiB page */

uint64_t mim_db_topology_hash(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices)
{
    return mim_hash64(faces, (size_t)n_faces * 3 * sizeof(uint32_t), 0x746f706fULL ^ (uint64_t)n_vertices);
}

int mim__db_topology_decode(const mim_db_txn_t *t, const MDB_val *v, mim_db_topology_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    int rc = mim__db_span(t, v, "topology", err);
    if (rc) return rc;
    const unsigned char *p = v->mv_data;
    if (v->mv_size < TOPO_HEADER) return mim__db_damaged(t->db, err, "topology: record is too short");
    memcpy(&out->n_vertices, p, 4);
    memcpy(&out->n_faces, p + 4, 4);
    memcpy(&out->hash, p + 8, 8);
    if (v->mv_size < TOPO_HEADER + (size_t)out->n_faces * 12)
        return mim__db_damaged(t->db, err, "topology: record has %zu bytes, expected %zu", v->mv_size,
                               TOPO_HEADER + (size_t)out->n_faces * 12);
    if ((uintptr_t)(p + TOPO_HEADER) % sizeof(uint32_t))
        return mim__db_damaged(t->db, err, "topology: record is misaligned");
    out->faces = (const uint32_t *)(const void *)(p + TOPO_HEADER);
    /* the hash of the faces is the record's checksum (every version) */
    if (mim_db_topology_hash(out->faces, out->n_faces, out->n_vertices) != out->hash) {
        out->faces = NULL;
        return mim__db_damaged(t->db, err, "topology: checksum mismatch (faces do not match their hash)");
    }
    return 0;
}

int mim_db_topology_get(mim_db_txn_t *t, mim_db_topology_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    MDB_val k = {5, "faces"}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_TOPOLOGY], &k, &v);
    if (rc == MDB_NOTFOUND) return MIM_ENOTFOUND;
    if (rc) return mim__db_fail(t->db, err, rc, "topology");
    return mim__db_topology_decode(t, &v, out, err);
}

int mim_db_topology_put(mim_db_txn_t *t, const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices,
                        mim_error_t *err)
{
    size_t used = TOPO_HEADER + (size_t)n_faces * 12, size = used < RECORD_MIN ? RECORD_MIN : used;
    MDB_val k = {5, "faces"}, v = {size, NULL};
    /* RESERVE: write the record in place, no staging copy; NOOVERWRITE: set once. */
    int rc = mdb_put(t->txn, t->db->dbi[DBI_TOPOLOGY], &k, &v, MDB_NOOVERWRITE | MDB_RESERVE);
    if (rc == MDB_KEYEXIST) return mim_error_set(err, MIM_EINVAL, "store already has a reference connectivity");
    if (rc) return mim__db_fail(t->db, err, rc, "topology");
    unsigned char *p = v.mv_data;
    uint64_t h = mim_db_topology_hash(faces, n_faces, n_vertices);
    memcpy(p, &n_vertices, 4);
    memcpy(p + 4, &n_faces, 4);
    memcpy(p + 8, &h, 8);
    memcpy(p + TOPO_HEADER, faces, (size_t)n_faces * 12);
    if (size > used) memset(p + used, 0, size - used);
    return 0;
}
