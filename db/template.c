/* Template records. Layout of schema versions 2 to 4 (little-endian,
 * schemas/store.md):
 *   0  "MTP2"            4  u32 header bytes (48)
 *   8  u64 checksum: XXH3-64 of every byte from 16 to the record's end
 *  16  u64 id           24  u64 content hash
 *  32  u32 n_vertices   36  u32 positions offset (multiple of 16)
 *  40  u16 source len   42  u16 subject len   44 u16 pose len   46 u16 dataset len
 *  48  source NUL subject NUL pose NUL [dataset NUL], zero padding, then
 *      float32 x y z. The dataset (schema version 4) took the u16 that
 *      was always 0: a record written before it reads as one of no dataset.
 * Version 1 ("MTP1", no checksum) had id, content hash, n_vertices and the
 * positions offset at 8, 16, 24, 28, the lengths at 32, flags at 40; a
 * version-1 store opened read-only is read in that layout.
 * A record is padded to at least RECORD_MIN bytes so LMDB keeps it on its
 * own overflow pages, which start page-aligned: the positions can then be
 * handed out as a float pointer straight into the map (zero-copy). */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define REC_HEADER 48
#define RECORD_MIN 2048 /* > half a 4 KiB page: always an overflow record */

uint64_t mim_db_content_hash(const float *positions, uint32_t n_vertices)
{
    return mim_hash64(positions, (size_t)n_vertices * 3 * sizeof(float), 0x706f7365ULL);
}

static size_t str_len16(const char *s)
{
    size_t n = s ? strlen(s) : 0;
    return n > 4095 ? 4095 : n; /* labels and paths longer than this are cut */
}

static int next_id(mim_db_txn_t *t, uint64_t *id, mim_error_t *err)
{
    MDB_val k = {7, "next_id"}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_META], &k, &v);
    if (rc) return mim__db_fail(t->db, err, rc, "store metadata next_id");
    uint64_t cur = 0;
    if (v.mv_size != 8) return mim__db_damaged(t->db, err, "its metadata has a malformed next_id");
    memcpy(&cur, v.mv_data, 8);
    *id = cur;
    cur++;
    MDB_val nv = {8, &cur};
    rc = mdb_put(t->txn, t->db->dbi[DBI_META], &k, &nv, 0);
    return rc ? mim__db_fail(t->db, err, rc, "store metadata next_id") : 0;
}

int mim__db_template_decode(const mim_db_txn_t *t, uint32_t version, const MDB_val *v, uint64_t key,
                            mim_template_view_t *out, mim_error_t *err)
{
    const unsigned char *p = v->mv_data;
    memset(out, 0, sizeof *out);
    char what[48];
    snprintf(what, sizeof what, "template %llu", (unsigned long long)key);
    int rc = mim__db_span(t, v, what, err);
    if (rc) return rc;
    const char *magic = version >= 2 ? "MTP2" : "MTP1";
    if (v->mv_size < REC_HEADER || memcmp(p, magic, 4) != 0)
        return mim__db_damaged(t->db, err, "%s: record is not a template (bad magic)", what);
    uint32_t hdr, pos_off;
    uint16_t ls, lsub, lpose, lds = 0;
    memcpy(&hdr, p + 4, 4);
    if (version >= 2) {
        uint64_t ck;
        memcpy(&ck, p + MIM__CK_OFFSET, 8);
        if (ck != mim__db_checksum(p, v->mv_size))
            return mim__db_damaged(t->db, err, "%s: checksum mismatch", what);
    }
    /* the fields are laid out alike in both versions; v2's checksum moved them 8 bytes on */
    const unsigned char *f = p + (version >= 2 ? 16 : 8);
    memcpy(&out->id, f, 8);
    memcpy(&out->content_hash, f + 8, 8);
    memcpy(&out->n_vertices, f + 16, 4);
    memcpy(&pos_off, f + 20, 4);
    memcpy(&ls, f + 24, 2);
    memcpy(&lsub, f + 26, 2);
    memcpy(&lpose, f + 28, 2);
    if (version >= 2) memcpy(&lds, f + 30, 2); /* version 1 kept flags there */
    size_t strings_end = (size_t)hdr + ls + 1 + lsub + 1 + lpose + 1 + (lds ? lds + 1u : 0u);
    if (hdr != REC_HEADER || strings_end > pos_off || pos_off % 16 ||
        (uint64_t)pos_off + (uint64_t)out->n_vertices * 12 > v->mv_size || out->id != key)
        return mim__db_damaged(t->db, err, "%s: record layout is inconsistent", what);
    const char *s = (const char *)p + hdr;
    const char *ds = s + ls + 1 + lsub + 1 + lpose + 1;
    if (s[ls] || s[ls + 1 + lsub] || s[ls + 1 + lsub + 1 + lpose] || (lds && ds[lds]))
        return mim__db_damaged(t->db, err, "%s: label strings are not terminated", what);
    if ((uintptr_t)(p + pos_off) % sizeof(float))
        return mim__db_damaged(t->db, err, "%s: positions are misaligned in the map", what);
    out->source = s;
    out->subject = s + ls + 1;
    out->pose = s + ls + 1 + lsub + 1;
    out->dataset = lds ? ds : "";
    out->positions = (const float *)(const void *)(p + pos_off);
    return 0;
}

size_t mim__db_template_size(const mim_template_in_t *in, size_t *pos_off)
{
    size_t ls = str_len16(in->source), lsub = str_len16(in->subject), lpose = str_len16(in->pose);
    size_t lds = str_len16(in->dataset);
    *pos_off = (REC_HEADER + ls + lsub + lpose + 3 + (lds ? lds + 1 : 0) + 15) & ~(size_t)15;
    size_t size = *pos_off + (size_t)in->n_vertices * 12;
    return size < RECORD_MIN ? RECORD_MIN : size;
}

void mim__db_template_encode(unsigned char *p, size_t size, size_t pos_off, uint64_t id, const mim_template_in_t *in)
{
    size_t ls = str_len16(in->source), lsub = str_len16(in->subject), lpose = str_len16(in->pose);
    size_t lds = str_len16(in->dataset);
    size_t end = pos_off + (size_t)in->n_vertices * 12;
    memset(p, 0, pos_off);
    memcpy(p, "MTP2", 4);
    uint32_t hdr = REC_HEADER, po = (uint32_t)pos_off;
    uint16_t l1 = (uint16_t)ls, l2 = (uint16_t)lsub, l3 = (uint16_t)lpose, l4 = (uint16_t)lds;
    memcpy(p + 4, &hdr, 4);
    memcpy(p + 16, &id, 8);
    memcpy(p + 24, &in->content_hash, 8);
    memcpy(p + 32, &in->n_vertices, 4);
    memcpy(p + 36, &po, 4);
    memcpy(p + 40, &l1, 2);
    memcpy(p + 42, &l2, 2);
    memcpy(p + 44, &l3, 2);
    memcpy(p + 46, &l4, 2);
    char *s = (char *)p + REC_HEADER;
    if (ls) memcpy(s, in->source, ls);
    if (lsub) memcpy(s + ls + 1, in->subject, lsub);
    if (lpose) memcpy(s + ls + 1 + lsub + 1, in->pose, lpose);
    if (lds) memcpy(s + ls + 1 + lsub + 1 + lpose + 1, in->dataset, lds);
    memcpy(p + pos_off, in->positions, (size_t)in->n_vertices * 12);
    if (size > end) memset(p + end, 0, size - end);
    uint64_t ck = mim__db_checksum(p, size); /* last: covers everything above */
    memcpy(p + MIM__CK_OFFSET, &ck, 8);
}

int mim_db_template_get(mim_db_txn_t *t, uint64_t id, mim_template_view_t *out, mim_error_t *err)
{
    size_t key = (size_t)id;
    MDB_val k = {sizeof key, &key}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_TEMPLATES], &k, &v);
    if (rc == MDB_NOTFOUND)
        return mim_error_set(err, MIM_ENOTFOUND, "template %llu: not in the store", (unsigned long long)id);
    if (rc) return mim__db_fail(t->db, err, rc, "template");
    return mim__db_template_decode(t, t->version, &v, id, out, err);
}

int mim_db_template_relabel(mim_db_txn_t *t, uint64_t id, const char *pose, mim_error_t *err)
{
    if (!t->write) return mim_error_set(err, MIM_EINVAL, "template relabel needs a write transaction");
    mim_template_view_t v;
    int rc = mim_db_template_get(t, id, &v, err);
    if (rc) return rc;
    /* the record is rewritten in place of the old, which the view lends
     * from: its fields are copied first */
    float *pos = malloc((size_t)v.n_vertices * 12);
    char *source = strdup(v.source), *subject = strdup(v.subject), *dataset = strdup(v.dataset);
    if (!pos || !source || !subject || !dataset) {
        free(pos), free(source), free(subject), free(dataset);
        return mim_error_set(err, MIM_ENOMEM, "template %llu: out of memory", (unsigned long long)id);
    }
    memcpy(pos, v.positions, (size_t)v.n_vertices * 12);
    const mim_template_in_t in = {pos, v.n_vertices, v.content_hash, source, subject, pose, dataset};
    size_t pos_off, size = mim__db_template_size(&in, &pos_off), key = (size_t)id;
    MDB_val k = {sizeof key, &key}, nv = {size, NULL};
    rc = mdb_put(t->txn, t->db->dbi[DBI_TEMPLATES], &k, &nv, MDB_RESERVE);
    if (rc) rc = mim__db_fail(t->db, err, rc, "template");
    else mim__db_template_encode(nv.mv_data, size, pos_off, id, &in);
    free(pos), free(source), free(subject), free(dataset);
    return rc;
}

/* Looks for a stored template with the same content; *found = its id or 0.
 * A stored record that fails its checks stops the put: new data is not
 * written beside damage. */
static int find_same(mim_db_txn_t *t, const mim_template_in_t *in, uint64_t *found, mim_error_t *err)
{
    *found = 0;
    MDB_cursor *c;
    int rc = mdb_cursor_open(t->txn, t->db->dbi[DBI_BY_HASH], &c);
    if (rc) return mim__db_fail(t->db, err, rc, "store hash index");
    size_t h = (size_t)in->content_hash;
    MDB_val k = {sizeof h, &h}, v;
    int bad = 0;
    for (rc = mdb_cursor_get(c, &k, &v, MDB_SET); rc == 0; rc = mdb_cursor_get(c, &k, &v, MDB_NEXT_DUP)) {
        size_t id;
        memcpy(&id, v.mv_data, sizeof id);
        mim_template_view_t view;
        /* equal hashes: compare the positions, so a collision never merges two meshes */
        mim_error_t e = {0};
        int r = mim_db_template_get(t, id, &view, &e);
        if (r == MIM_ESTORE) {
            bad = mim_error_set(err, r, "%s", e.msg);
            break;
        }
        if (r == 0 && view.n_vertices == in->n_vertices &&
            memcmp(view.positions, in->positions, (size_t)in->n_vertices * 12) == 0) {
            *found = id;
            break;
        }
    }
    mdb_cursor_close(c);
    if (bad) return bad;
    if (rc && rc != MDB_NOTFOUND) return mim__db_fail(t->db, err, rc, "store hash index");
    return 0;
}

int mim_db_template_put(mim_db_txn_t *t, const mim_template_in_t *in, uint64_t *id_out, int *existed,
                        mim_error_t *err)
{
    if (existed) *existed = 0;
    if (!t->write) return mim_error_set(err, MIM_EINVAL, "template put needs a write transaction");
    uint64_t same;
    int rc = find_same(t, in, &same, err);
    if (rc) return rc;
    if (same) {
        if (id_out) *id_out = same;
        if (existed) *existed = 1;
        return 0;
    }
    uint64_t id = 0;
    if ((rc = next_id(t, &id, err))) return rc;

    size_t pos_off, size = mim__db_template_size(in, &pos_off);
    size_t key = (size_t)id;
    MDB_val k = {sizeof key, &key}, v = {size, NULL};
    rc = mdb_put(t->txn, t->db->dbi[DBI_TEMPLATES], &k, &v, MDB_NOOVERWRITE | MDB_RESERVE);
    if (rc == MDB_KEYEXIST)
        return mim__db_damaged(t->db, err, "template %llu: exists, but next_id says it is the next new id",
                               (unsigned long long)id);
    if (rc) return mim__db_fail(t->db, err, rc, "template");
    mim__db_template_encode(v.mv_data, size, pos_off, id, in);

    size_t h = (size_t)in->content_hash;
    MDB_val hk = {sizeof h, &h}, hv = {sizeof key, &key};
    rc = mdb_put(t->txn, t->db->dbi[DBI_BY_HASH], &hk, &hv, 0);
    if (rc) return mim__db_fail(t->db, err, rc, "store hash index");
    if (id_out) *id_out = id;
    return 0;
}

int mim_db_template_each(mim_db_txn_t *t, mim_db_template_fn fn, void *user, mim_error_t *err)
{
    MDB_cursor *c;
    int rc = mdb_cursor_open(t->txn, t->db->dbi[DBI_TEMPLATES], &c);
    if (rc) return mim__db_fail(t->db, err, rc, "templates");
    MDB_val k, v;
    int ret = 0;
    for (rc = mdb_cursor_get(c, &k, &v, MDB_FIRST); rc == 0; rc = mdb_cursor_get(c, &k, &v, MDB_NEXT)) {
        size_t key;
        if (k.mv_size != sizeof key) {
            ret = mim__db_damaged(t->db, err, "templates: a key of %zu bytes", k.mv_size);
            break;
        }
        memcpy(&key, k.mv_data, sizeof key);
        mim_template_view_t view;
        if ((ret = mim__db_template_decode(t, t->version, &v, key, &view, err))) break;
        if ((ret = fn(&view, user))) break;
    }
    mdb_cursor_close(c);
    if (!ret && rc && rc != MDB_NOTFOUND) ret = mim__db_fail(t->db, err, rc, "templates");
    return ret;
}
