/* Registration records (schema versions 3 and 4): how a template made by
 * register/ from a mesh of another connectivity came about. Two tables
 * (schemas/store.md):
 *   registrations  u64 template id -> record (little-endian):
 *     0  "MRG3" or "MRG4"  4  u32 record bytes (72 or 136)
 *     8  u64 checksum: XXH3-64 of bytes 16..end
 *    16  u64 template id  24  u64 source hash
 *    32  u32 source vertices  36 u32 iterations
 *    40  f64 mean mm      48  f64 p95 mm     56  f64 max mm
 *    64  f64 landmark mean mm
 *   MRG4 only, the correspondence quality:
 *    72  f64 landmark max mm   80  f64 volume ratio
 *    88  f64 distortion % x 6 (head, torso, arms, hands, legs, feet)
 *   by_source      u64 source hash -> sorted duplicate u64 template ids
 *                  (like by_hash): ingest's "is this source registered?"
 *                  in one lookup, without reading every registration.
 * A record is small: it lives inside LMDB's leaf pages and is copied out
 * (no alignment needed). Every read checks it lies inside the file, its
 * magic, size, checksum, that it names its own key, and that its figures
 * are distances; a by_source entry is only believed once the record it
 * names agrees. */
#include "internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define REG_SIZE 72    /* MRG3 */
#define REG4_SIZE 136  /* MRG4: REG_SIZE and the quality */

static int is_distance(double x) { return isfinite(x) && x >= 0; }

static int quality_valid(const mim_db_registration_quality_t *q)
{
    int ok = is_distance(q->landmark_max_mm) && isfinite(q->volume_ratio) && q->volume_ratio > 0;
    for (int g = 0; g < MIM_DB_REG_REGIONS; g++) ok = ok && is_distance(q->distortion_pct[g]);
    return ok;
}

int mim__db_registration_decode(const mim_db_txn_t *t, const MDB_val *v, uint64_t key, mim_db_registration_t *out,
                                mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    char what[48];
    snprintf(what, sizeof what, "registration %llu", (unsigned long long)key);
    int rc = mim__db_span(t, v, what, err);
    if (rc) return rc;
    const unsigned char *p = v->mv_data;
    const int v4 = v->mv_size >= 16 && !memcmp(p, "MRG4", 4);
    if (v->mv_size < 16 || (!v4 && memcmp(p, "MRG3", 4)))
        return mim__db_damaged(t->db, err, "%s: record is not a registration (bad magic)", what);
    uint32_t size, want = v4 ? REG4_SIZE : REG_SIZE;
    uint64_t ck;
    memcpy(&size, p + 4, 4);
    memcpy(&ck, p + MIM__CK_OFFSET, 8);
    if (size != want || v->mv_size != want)
        return mim__db_damaged(t->db, err, "%s: record has %zu bytes, its header says %u (a registration has %u)", what,
                               v->mv_size, size, want);
    if (ck != mim__db_checksum(p, v->mv_size)) return mim__db_damaged(t->db, err, "%s: checksum mismatch", what);
    mim_db_registration_t r;
    memcpy(&r.template_id, p + 16, 8);
    memcpy(&r.source_hash, p + 24, 8);
    memcpy(&r.source_vertices, p + 32, 4);
    memcpy(&r.iterations, p + 36, 4);
    memcpy(&r.mean_mm, p + 40, 8);
    memcpy(&r.p95_mm, p + 48, 8);
    memcpy(&r.max_mm, p + 56, 8);
    memcpy(&r.landmark_mean_mm, p + 64, 8);
    memset(&r.quality, 0, sizeof r.quality);
    if (v4) {
        r.quality.present = 1;
        memcpy(&r.quality.landmark_max_mm, p + 72, 8);
        memcpy(&r.quality.volume_ratio, p + 80, 8);
        memcpy(r.quality.distortion_pct, p + 88, 8 * MIM_DB_REG_REGIONS);
    }
    if (r.template_id != key || r.source_vertices == 0 || !is_distance(r.mean_mm) || !is_distance(r.p95_mm) ||
        !is_distance(r.max_mm) || !is_distance(r.landmark_mean_mm) || (v4 && !quality_valid(&r.quality)))
        return mim__db_damaged(t->db, err, "%s: record layout is inconsistent", what);
    *out = r;
    return 0;
}

/* The record of template id: 0, MIM_ENOTFOUND (err untouched), or the
 * damage. */
static int get_record(mim_db_txn_t *t, uint64_t id, mim_db_registration_t *out, mim_error_t *err)
{
    size_t key = (size_t)id;
    MDB_val k = {sizeof key, &key}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_REGISTRATIONS], &k, &v);
    if (rc == MDB_NOTFOUND) return MIM_ENOTFOUND;
    if (rc) return mim__db_fail(t->db, err, rc, "registrations");
    return mim__db_registration_decode(t, &v, id, out, err);
}

int mim_db_registration_get(mim_db_txn_t *t, uint64_t template_id, mim_db_registration_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!t->db->have_registrations) return MIM_ENOTFOUND; /* an older store, read-only */
    return get_record(t, template_id, out, err);
}

int mim_db_registration_find(mim_db_txn_t *t, uint64_t source_hash, mim_db_registration_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!t->db->have_registrations) return MIM_ENOTFOUND;
    MDB_cursor *c;
    int rc = mdb_cursor_open(t->txn, t->db->dbi[DBI_BY_SOURCE], &c);
    if (rc) return mim__db_fail(t->db, err, rc, "source index");
    size_t h = (size_t)source_hash;
    MDB_val k = {sizeof h, &h}, v;
    int ret = MIM_ENOTFOUND;
    /* the first entry decides: the lowest id (duplicates are sorted) */
    rc = mdb_cursor_get(c, &k, &v, MDB_SET);
    if (rc == 0) {
        size_t id;
        if (v.mv_size != sizeof id) {
            ret = mim__db_damaged(t->db, err, "source index: entry %016llx holds %zu bytes, not a template id",
                                  (unsigned long long)source_hash, v.mv_size);
        } else {
            memcpy(&id, v.mv_data, sizeof id);
            mim_db_registration_t r;
            ret = get_record(t, id, &r, err);
            if (ret == MIM_ENOTFOUND)
                ret = mim__db_damaged(t->db, err, "source index: entry %016llx names template %llu, which has no registration",
                                      (unsigned long long)source_hash, (unsigned long long)id);
            else if (!ret && r.source_hash != source_hash)
                ret = mim__db_damaged(t->db, err,
                                      "source index: entry %016llx names template %llu, registered from source %016llx",
                                      (unsigned long long)source_hash, (unsigned long long)id,
                                      (unsigned long long)r.source_hash);
            else if (!ret)
                *out = r;
        }
    } else if (rc != MDB_NOTFOUND) {
        ret = mim__db_fail(t->db, err, rc, "source index");
    }
    mdb_cursor_close(c);
    return ret;
}

int mim_db_registration_put(mim_db_txn_t *t, const mim_db_registration_t *r, mim_error_t *err)
{
    if (!t->write) return mim_error_set(err, MIM_EINVAL, "registration put needs a write transaction");
    unsigned long long id = (unsigned long long)r->template_id;
    if (r->source_vertices == 0 || !is_distance(r->mean_mm) || !is_distance(r->p95_mm) || !is_distance(r->max_mm) ||
        !is_distance(r->landmark_mean_mm) || (r->quality.present && !quality_valid(&r->quality)))
        return mim_error_set(err, MIM_EINVAL,
                             "registration of template %llu: %u source vertices, distances %g/%g/%g mm, landmarks %g "
                             "mm, or its quality figures (a source has vertices; distances and distortions are finite "
                             "and >= 0, a volume ratio > 0)",
                             id, r->source_vertices, r->mean_mm, r->p95_mm, r->max_mm, r->landmark_mean_mm);
    /* a registration never outlives its template: the template must be here */
    size_t key = (size_t)r->template_id;
    MDB_val k = {sizeof key, &key}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_TEMPLATES], &k, &v);
    if (rc == MDB_NOTFOUND)
        return mim_error_set(err, MIM_ENOTFOUND, "registration of template %llu: no such template in %s", id,
                             t->db->path);
    if (rc) return mim__db_fail(t->db, err, rc, "template");
    /* a replaced registration takes its source-index entry with it; a
     * damaged one stops the put (its entry could not be found) */
    mim_db_registration_t old;
    rc = get_record(t, r->template_id, &old, err);
    if (rc && rc != MIM_ENOTFOUND) return rc;
    if (rc == 0 && old.source_hash != r->source_hash) {
        size_t oh = (size_t)old.source_hash;
        MDB_val ok = {sizeof oh, &oh}, ov = {sizeof key, &key};
        rc = mdb_del(t->txn, t->db->dbi[DBI_BY_SOURCE], &ok, &ov);
        if (rc && rc != MDB_NOTFOUND) return mim__db_fail(t->db, err, rc, "source index");
    }

    /* without quality figures, the version 3 layout: nothing to leave blank */
    unsigned char rec[REG4_SIZE] = {0};
    uint32_t size = r->quality.present ? REG4_SIZE : REG_SIZE;
    memcpy(rec, r->quality.present ? "MRG4" : "MRG3", 4);
    memcpy(rec + 4, &size, 4);
    memcpy(rec + 16, &r->template_id, 8);
    memcpy(rec + 24, &r->source_hash, 8);
    memcpy(rec + 32, &r->source_vertices, 4);
    memcpy(rec + 36, &r->iterations, 4);
    memcpy(rec + 40, &r->mean_mm, 8);
    memcpy(rec + 48, &r->p95_mm, 8);
    memcpy(rec + 56, &r->max_mm, 8);
    memcpy(rec + 64, &r->landmark_mean_mm, 8);
    if (r->quality.present) {
        memcpy(rec + 72, &r->quality.landmark_max_mm, 8);
        memcpy(rec + 80, &r->quality.volume_ratio, 8);
        memcpy(rec + 88, r->quality.distortion_pct, 8 * MIM_DB_REG_REGIONS);
    }
    uint64_t ck = mim__db_checksum(rec, size);
    memcpy(rec + MIM__CK_OFFSET, &ck, 8);
    MDB_val d = {size, rec};
    if ((rc = mdb_put(t->txn, t->db->dbi[DBI_REGISTRATIONS], &k, &d, 0))) return mim__db_fail(t->db, err, rc, "registration");
    size_t h = (size_t)r->source_hash;
    MDB_val hk = {sizeof h, &h}, hv = {sizeof key, &key};
    rc = mdb_put(t->txn, t->db->dbi[DBI_BY_SOURCE], &hk, &hv, 0); /* already there: a no-op */
    return rc ? mim__db_fail(t->db, err, rc, "source index") : 0;
}
