/* mimic template store: an LMDB environment in a directory.
 *
 * Named databases (layout: schemas/store.md, version: schemas/store-version):
 *   meta        schema version, creating mimic version, next template id,
 *               the recognition index (mim_db_index_put)
 *   topology    the reference connectivity (faces, vertex count, hash)
 *   landmarks   the landmark map (JSON)
 *   templates   id -> template record (labels, source, float32 positions)
 *   by_hash     content hash -> ids (dedupe)
 *   encodings   id -> the template's intrinsic encoding (ingest adds it)
 *   registrations  id -> how a registered template was made (register/)
 *   by_source   source-mesh hash -> ids (idempotent re-ingest)
 *   bindings    u64 key -> a cached avatar binding blob (register/)
 *
 * Many readers and one writer may work at once, from different processes.
 * Data lent out of the store (pointers in views) points into the memory map
 * and is valid until the transaction that produced it ends.
 *
 * Integrity (schema versions 2 and 3): every template, encoding, landmark,
 * index-build, registration and binding record carries an XXH3-64
 * checksum, written on put and checked on every read; the topology record
 * is checked against its own hash. A
 * record that fails is never lent out: the call fails with MIM_ESTORE and
 * "store damaged: DIR: template N: checksum mismatch" (or what else is
 * wrong). A damaged data.mdb (truncated, not LMDB, tables missing, a
 * damaged page in LMDB's table list or at the root of a table) fails
 * mim_db_open the same way. mim_db_check verifies a whole store.
 *
 * Older stores: a read-only open reads them as they are
 * (mim_db_meta_t.schema_version says 1 or 2; without the tables of version
 * 3, registrations and bindings are simply not found). The first
 * read-write open migrates them to version 3 in one transaction (all or
 * nothing): version 1 has every record rewritten with its checksum
 * (refusing if a template's positions do not match their content hash),
 * then versions 1 and 2 get the registrations, by_source and bindings
 * tables, empty. */
#ifndef MIM_DB_H
#define MIM_DB_H

#include "mim_core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mim_db mim_db_t;
typedef struct mim_db_txn mim_db_txn_t;

typedef struct mim_db_options {
    /* Bytes of address space to map, which is also the most the store can
     * hold; 0 means 256 GiB (sparse: only the pages in use take memory or
     * disk). A size below what the store already uses is raised to it.
     * When the store fills, writes fail with MIM_ESTORE ("store is full").
     * The library reads no environment variable: the mimic command passes
     * MIMIC_MAP_SIZE here. */
    uint64_t map_size;
    int read_only; /* open an existing store for reading only */
    /* A read-write open of an older store migrates it (above): progress
     * over its records (label "migrate") and one log line when done. NULL:
     * quiet. */
    mim_progress_fn progress;
    void *progress_ctx;
    mim_log_fn log;
    void *log_ctx;
} mim_db_options_t;

/* Opens (creating if missing and not read_only) the store in directory dir.
 * Fails with MIM_ESCHEMA for another schema version; MIM_ESTORE ("store
 * damaged: ...") for a data.mdb that is truncated, not LMDB, or an LMDB
 * environment that is not a complete mimic store (such a directory is
 * never written to); MIM_ENOTFOUND (read_only) when there is no store. */
int mim_db_open(mim_db_t **out, const char *dir, const mim_db_options_t *opt, mim_error_t *err);
void mim_db_close(mim_db_t **db); /* accepts NULL; nulls the pointer */
const char *mim_db_path(const mim_db_t *db);

/* Transactions: write ones serialise across threads and processes. A
 * write transaction's failure to commit, or a put's, because the map or the
 * disk is full says so (MIM_ESTORE, or -ENOSPC / -EIO / -EFBIG), and that
 * every transaction committed before it is intact. */
int mim_db_begin(mim_db_t *db, int write, mim_db_txn_t **out, mim_error_t *err);
int mim_db_commit(mim_db_txn_t **txn, mim_error_t *err); /* frees the txn, even on failure */
void mim_db_abort(mim_db_txn_t **txn);                   /* accepts NULL */

typedef struct mim_db_meta {
    uint32_t schema_version;
    char created_by[64]; /* "mimic 0.1.0" */
    uint64_t next_id;
    uint64_t templates;  /* number of template records */
} mim_db_meta_t;
int mim_db_meta_get(mim_db_txn_t *txn, mim_db_meta_t *out, mim_error_t *err);

/* ---- reference connectivity ---- */
typedef struct mim_db_topology {
    uint32_t n_vertices;
    uint32_t n_faces;
    uint64_t hash;
    const uint32_t *faces; /* 3 * n_faces, lent: valid until the txn ends */
} mim_db_topology_t;
uint64_t mim_db_topology_hash(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices);
/* MIM_ENOTFOUND while the store has none. */
int mim_db_topology_get(mim_db_txn_t *txn, mim_db_topology_t *out, mim_error_t *err);
/* Sets it once; MIM_EINVAL if the store already has one. */
int mim_db_topology_put(mim_db_txn_t *txn, const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices,
                        mim_error_t *err);

/* ---- landmark map ---- */
int mim_db_landmarks_get(mim_db_txn_t *txn, mim_landmark_map_t *out, mim_error_t *err); /* MIM_ENOTFOUND */
int mim_db_landmarks_put(mim_db_txn_t *txn, const mim_landmark_map_t *map, mim_error_t *err);

/* ---- templates ---- */
typedef struct mim_template_in {
    const float *positions; /* 3 * n_vertices */
    uint32_t n_vertices;
    uint64_t content_hash;  /* mim_db_content_hash(positions, n_vertices) */
    const char *source;     /* where it came from; may be NULL */
    const char *subject;    /* label, or NULL / "" for none */
    const char *pose;       /* label, or NULL / "" for none */
    const char *dataset;    /* the dataset it came with (its subjects and poses are its own), or NULL / "" */
} mim_template_in_t;

typedef struct mim_template_view {
    uint64_t id;
    uint64_t content_hash;
    uint32_t n_vertices;
    const float *positions; /* zero-copy from the map: valid until the txn ends */
    const char *source;     /* "" when unknown; lent like positions */
    const char *subject;    /* "" when unlabelled */
    const char *pose;       /* "" when unlabelled */
    const char *dataset;    /* "" when none (a template stored before datasets) */
} mim_template_view_t;

/* Labels across datasets (labels.c): whether the n templates' datasets
 * ("" or NULL: none) hold more than one value, and, when they do, each
 * labels[i] (malloc'd; "" stays) of a template with a dataset made the
 * malloc'd "DATASET/LABEL" (dataset names hold no '/'), except where
 * keep[i] (keep may be NULL). One dataset: labels untouched. Returns 0 or
 * MIM_ENOMEM (the labels then stay valid, some qualified). */
int mim_db_datasets_several(uint32_t n, const char *const *datasets);
int mim_db_labels_qualify(uint32_t n, const char *const *datasets, char **labels, const unsigned char *keep);

uint64_t mim_db_content_hash(const float *positions, uint32_t n_vertices);
/* Stores a template unless one with the same content exists: then *existed
 * is set and *id is the existing one. */
int mim_db_template_put(mim_db_txn_t *txn, const mim_template_in_t *t, uint64_t *id, int *existed,
                        mim_error_t *err);
int mim_db_template_get(mim_db_txn_t *txn, uint64_t id, mim_template_view_t *out, mim_error_t *err);
/* Gives template id the pose label pose (NULL or "": none); everything
 * else of it stays. A write transaction; MIM_ENOTFOUND for no such id.
 * The index is not marked stale by it (the store's counts stay): build it
 * again. */
int mim_db_template_relabel(mim_db_txn_t *txn, uint64_t id, const char *pose, mim_error_t *err);
/* Calls fn for every template in id order; stops early when fn returns non-zero
 * (and returns that value). Views are valid until the txn ends. */
typedef int (*mim_db_template_fn)(const mim_template_view_t *t, void *user);
int mim_db_template_each(mim_db_txn_t *txn, mim_db_template_fn fn, void *user, mim_error_t *err);

/* ---- recognition index (mimic index writes it, query reads it) ----
 * Kept under two keys of the meta table (schemas/store.md). */
typedef struct mim_db_index_meta {
    uint64_t next_id;      /* the store's next_id when the index was built */
    uint64_t templates;    /* and its template count */
    uint32_t class_source; /* MIM_CLASSES_* of mim_index.h: 0 pose labels, 1 k-means */
    uint32_t n_classes, d;
    double built_at;       /* Unix seconds */
} mim_db_index_meta_t;
/* Replaces the store's index blob and build record. */
int mim_db_index_put(mim_db_txn_t *txn, const void *blob, size_t len, const mim_db_index_meta_t *meta,
                     mim_error_t *err);
/* The build record, and (blob non-NULL) the blob, lent: valid until the txn
 * ends. MIM_ENOTFOUND when the store has no index. */
int mim_db_index_get(mim_db_txn_t *txn, const void **blob, size_t *len, mim_db_index_meta_t *meta,
                     mim_error_t *err);
/* As mim_db_index_get, lent the same way, but without the XXH3-64 of the
 * whole blob (the build record's own checksum is still checked, and the
 * blob is still checked to lie inside the file): for a reader that checks
 * the blob itself as it uses it (index/: by section).
 * mim_db_check still checks the whole blob. */
int mim_db_index_lend(mim_db_txn_t *txn, const void **blob, size_t *len, mim_db_index_meta_t *meta,
                      mim_error_t *err);

/* ---- intrinsic encodings (seed 000 Section 3.1), one per template ----
 * What a transfer needs of a template, stored by ingest so that no query
 * recomputes it (layout: schemas/store.md). */
typedef struct mim_db_encoding {
    uint32_t n_vertices;
    const float *frames; /* 6 * n: f1 (normal), f2 (tangent) per vertex; f3 = f1 x f2 */
    const float *W;      /* 3 * n: W = F^T L X */
} mim_db_encoding_t;        /* arrays lent from the map: valid until the txn ends */
/* Stores (or replaces) template id's encoding. */
int mim_db_encoding_put(mim_db_txn_t *txn, uint64_t id, const float *frames, const float *W, uint32_t n_vertices,
                        mim_error_t *err);
/* MIM_ENOTFOUND when the template has none (a store ingested before
 * encodings were kept: callers compute it from the positions). */
int mim_db_encoding_get(mim_db_txn_t *txn, uint64_t id, mim_db_encoding_t *out, mim_error_t *err);

/* ---- registrations (register/: meshes of another connectivity) ----
 * One record per template that ingest made by registering the store's
 * connectivity onto a foreign mesh: where it came from (the caller's hash
 * of the source mesh) and how well it fits it. The registered positions
 * depend on the store's state (its templates, its landmark map), so an
 * ingest that meets the same source again finds it by the source's hash
 * (mim_db_registration_find), not by the template's content hash.
 * Layout: schemas/store.md. */
#define MIM_DB_REG_REGIONS 6
typedef struct mim_db_registration {
    uint64_t template_id;
    uint64_t source_hash;     /* the caller's hash of the source mesh (positions and faces) */
    uint32_t source_vertices; /* vertex count of the source mesh */
    uint32_t iterations;
    double mean_mm, p95_mm, max_mm; /* surface distance, registered result to the source */
    double landmark_mean_mm;
    /* How well the correspondence holds (register/'s report), beside how
     * close the surface lies: absent (present 0) in records of schema
     * version 3. Regions: head, torso, arms, hands, legs, feet. */
    struct mim_db_registration_quality {
        int present;
        double landmark_max_mm;
        double volume_ratio;                       /* enclosed volume / the starting template's, > 0 */
        double distortion_pct[MIM_DB_REG_REGIONS]; /* rms change of edge lengths from the starting template, % */
    } quality;
} mim_db_registration_t;
typedef struct mim_db_registration_quality mim_db_registration_quality_t;
/* Stores (or replaces) the registration of r->template_id, which must be
 * stored (MIM_ENOTFOUND otherwise: a registration never outlives its
 * template). source_vertices > 0; the distances finite and >= 0
 * (MIM_EINVAL). Replacing a registration with another source_hash moves
 * its entry in the source index. A stored record that fails its checks
 * stops the put (MIM_ESTORE). Needs a write transaction. */
int mim_db_registration_put(mim_db_txn_t *txn, const mim_db_registration_t *r, mim_error_t *err);
/* MIM_ENOTFOUND when the template was not registered (and when the store
 * predates registrations, opened read-only); err is left untouched then,
 * as this is an ordinary answer. MIM_ESTORE ("store damaged: DIR:
 * registration N: ...") for a record that fails its checks. */
int mim_db_registration_get(mim_db_txn_t *txn, uint64_t template_id, mim_db_registration_t *out, mim_error_t *err);
/* The registration of this source, MIM_ENOTFOUND if none (err untouched).
 * When several templates were registered from one source, the one with
 * the lowest id. The hash is trusted as the source's identity: two
 * different meshes with one 64-bit hash are taken for the same source. */
int mim_db_registration_find(mim_db_txn_t *txn, uint64_t source_hash, mim_db_registration_t *out, mim_error_t *err);

/* ---- avatar bindings: a cache of register/'s binding blobs ----
 * Keyed by the caller's u64 (its hash of the avatar mesh and the store's
 * connectivity); a put replaces what the key held. Opaque to the store
 * beyond its checksum. */
int mim_db_binding_put(mim_db_txn_t *txn, uint64_t key, const void *blob, size_t len, mim_error_t *err);
/* The blob, zero-copy from the map and 16-byte aligned: lent, valid until
 * the txn ends (in a write transaction, until its next put). MIM_ENOTFOUND
 * (err untouched) when the key holds none, or the store predates bindings
 * (opened read-only); MIM_ESTORE ("store damaged: DIR: binding KEY: ...")
 * for a record that fails its checks. */
int mim_db_binding_get(mim_db_txn_t *txn, uint64_t key, const void **blob, size_t *len, mim_error_t *err);

/* ---- size ---- */
typedef struct mim_db_stat {
    uint64_t page_size;
    uint64_t pages_used;      /* pages holding data (incl. free list) */
    uint64_t file_bytes;      /* data.mdb size */
    uint64_t disk_bytes;      /* blocks allocated on disk for data.mdb + lock.mdb */
    uint64_t map_size;
    uint64_t template_bytes;  /* bytes of pages holding template records and their index */
} mim_db_stat_t;
int mim_db_stat(mim_db_t *db, mim_db_stat_t *out, mim_error_t *err);

/* ---- integrity check (mimic store check) ----
 * Reads every LMDB page of one snapshot from the file (a table whose pages
 * are damaged is reported and not read further), then every record, and
 * reports each problem found:
 * records that do not decode or fail their checksum, positions that do
 * not match their content hash, and broken cross-references (a template's
 * encoding missing its vertex count, a hash-index entry without its
 * template, a landmark map or connectivity that is not valid, an index
 * blob whose checksum fails, a next_id at or below a stored id, a
 * registration of a template that is not stored or missing from the
 * source index, a source-index entry without its registration). */
typedef struct mim_db_problem {
    /* "templates", "encodings", "by_hash", "topology", "landmarks", "meta", "index", "registrations",
     * "by_source", "bindings", "lmdb" */
    const char *table;
    uint64_t id;         /* the template the problem concerns; 0 when none */
    const char *message; /* one line: "store damaged: DIR: template 3: checksum mismatch" */
} mim_db_problem_t;
typedef void (*mim_db_problem_fn)(void *ctx, const mim_db_problem_t *p);

typedef struct mim_db_check_options {
    mim_db_problem_fn problem; /* each problem, as found; NULL: only counted */
    void *problem_ctx;
    mim_progress_fn progress;  /* records checked of records (label "check"); NULL: none */
    void *progress_ctx;
} mim_db_check_options_t;

typedef struct mim_db_check_report {
    uint32_t schema_version;
    uint64_t templates, encodings, hash_entries; /* records read */
    uint64_t templates_without_encoding;         /* allowed: readers compute it */
    uint64_t registrations, source_entries, bindings; /* records read (schema version 3) */
    int topology, landmarks, index;              /* present (and checked) */
    uint64_t problems;
    double seconds;
} mim_db_check_report_t;

/* 0 when the check ran (damage found or not: out->problems); an error when
 * it could not (no snapshot). */
int mim_db_check(mim_db_t *db, const mim_db_check_options_t *opt, mim_db_check_report_t *out, mim_error_t *err);

/* ---- a snapshot copy (copy.c) ---- */
/* Copies the store as one read transaction sees it, while writers go on,
 * compacted (LMDB's mdb_env_copy2 with MDB_CP_COMPACT), into the new
 * directory dst, which must not exist. The copy is made in a temporary
 * directory beside dst, flushed, and renamed to dst only when whole, so a
 * failure leaves nothing at dst. *bytes (may be NULL) gets the copy's
 * size. Errors: MIM_EINVAL (dst exists), -errno (the file system), an
 * LMDB failure as -errno or MIM_ESTORE. */
int mim_db_copy(mim_db_t *db, const char *dst, uint64_t *bytes, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
