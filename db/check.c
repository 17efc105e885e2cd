/* mim_db_check: every record of one snapshot, read and cross-checked
 * (mimic store check). Each record goes through the same decoder as a
 * normal read (bounds in the file, magic, checksum, layout), then:
 *   templates   positions match their content hash; the store's vertex
 *               count; an id below next_id; listed in by_hash
 *   encodings   belong to a stored template, with its vertex count
 *   by_hash     each entry names a stored template with that hash
 *   topology    hash of the faces; every face index below the vertex count
 *   landmarks   parses, and fits the topology
 *   index       build record and model checksums; built at or below next_id
 *   registrations  belong to a stored template; listed in by_source
 *   by_source   each entry names a registration from that source
 *   bindings    decode and pass their checksum (opaque otherwise)
 * Before any of that, every LMDB page of the snapshot is read from the
 * file and checked (lmdb_walk.c), so that damage inside LMDB's own trees
 * is reported instead of followed. Problems are reported one line each
 * and counted; the check goes on after a problem, so one run lists them
 * all. */
#include "internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

typedef struct {
    uint64_t id, hash;
    uint32_t n;
    uint8_t bad;          /* did not decode: no cross-checks */
    uint8_t has_encoding;
} tmpl_t;

typedef struct {
    uint64_t id, source_hash;
    uint8_t bad; /* did not decode: no cross-checks */
} reg_t;

typedef struct {
    mim_db_txn_t *t;
    const mim_db_check_options_t *opt;
    mim_db_check_report_t *out;
    mim_progress_t prog;
    uint64_t done;
    tmpl_t *tm;
    size_t n_tm, cap_tm;
    int templates_read; /* the templates table was read: encodings can be matched to it */
    reg_t *rg;          /* registrations read, in id order */
    size_t n_rg, cap_rg;
    int registrations_read;
} ctx_t;

static void report(ctx_t *c, const char *table, uint64_t id, const char *msg)
{
    c->out->problems++;
    if (c->opt->problem) {
        mim_db_problem_t p = {table, id, msg};
        c->opt->problem(c->opt->problem_ctx, &p);
    }
}

/* A problem from a decoder's error, or a formatted one. */
static void report_err(ctx_t *c, const char *table, uint64_t id, const mim_error_t *e)
{
    report(c, table, id, e->msg[0] ? e->msg : mim_strerror(e->code));
}

__attribute__((format(printf, 4, 5))) static void reportf(ctx_t *c, const char *table, uint64_t id, const char *fmt,
                                                           ...)
{
    char what[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    mim_error_t e = {0};
    mim__db_damaged(c->t->db, &e, "%s", what);
    report_err(c, table, id, &e);
}

static void walk_problem(void *ctx, const char *table, const char *msg) { report(ctx, table, 0, msg); }

static void step(ctx_t *c) { mim_progress_update(&c->prog, ++c->done); }

static tmpl_t *find_tmpl(ctx_t *c, uint64_t id)
{
    size_t lo = 0, hi = c->n_tm;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (c->tm[mid].id < id) lo = mid + 1;
        else hi = mid;
    }
    return lo < c->n_tm && c->tm[lo].id == id ? &c->tm[lo] : NULL;
}

static void check_file(ctx_t *c)
{
    mim_db_t *db = c->t->db;
    MDB_envinfo info;
    struct stat st;
    if (mdb_env_info(db->env, &info) == 0 && fstat(db->fd, &st) == 0 &&
        ((uint64_t)info.me_last_pgno + 1) * db->page_size > (uint64_t)st.st_size)
        reportf(c, "lmdb", 0, "data.mdb: truncated: the file has %llu bytes, the store uses %llu",
                (unsigned long long)st.st_size, ((unsigned long long)info.me_last_pgno + 1) * db->page_size);
}

static void check_meta(ctx_t *c, mim_db_meta_t *meta)
{
    mim_error_t e = {0};
    if (mim_db_meta_get(c->t, meta, &e)) {
        report_err(c, "meta", 0, &e);
        memset(meta, 0, sizeof *meta);
        meta->next_id = UINT64_MAX; /* unknown: no id is reported against it */
        return;
    }
    if (!meta->created_by[0]) reportf(c, "meta", 0, "its metadata has no created_by");
}

static int check_topology(ctx_t *c, mim_db_topology_t *topo)
{
    MDB_val k = {5, "faces"}, v;
    int rc = mdb_get(c->t->txn, c->t->db->dbi[DBI_TOPOLOGY], &k, &v);
    if (rc == MDB_NOTFOUND) return 0;
    mim_error_t e = {0};
    if (rc) mim__db_fail(c->t->db, &e, rc, "topology");
    else rc = mim__db_topology_decode(c->t, &v, topo, &e);
    c->out->topology = 1; /* present, even when damaged */
    if (rc) {
        report_err(c, "topology", 0, &e);
        return 0;
    }
    if (!topo->n_vertices || !topo->n_faces) {
        reportf(c, "topology", 0, "topology: %u vertices and %u faces", topo->n_vertices, topo->n_faces);
        return 0;
    }
    for (size_t i = 0; i < 3 * (size_t)topo->n_faces; i++)
        if (topo->faces[i] >= topo->n_vertices) {
            reportf(c, "topology", 0, "topology: face %zu names vertex %u of %u", i / 3, topo->faces[i], topo->n_vertices);
            return 0;
        }
    return 1;
}

static void check_landmarks(ctx_t *c, const mim_db_topology_t *topo, int topo_ok)
{
    MDB_val k = {3, "map"}, v;
    int rc = mdb_get(c->t->txn, c->t->db->dbi[DBI_LANDMARKS], &k, &v);
    if (rc == MDB_NOTFOUND) {
        if (c->out->topology) reportf(c, "landmarks", 0, "landmark map: missing (the connectivity has none)");
        return;
    }
    mim_error_t e = {0};
    const char *json = NULL;
    size_t len = 0;
    mim_landmark_map_t map;
    if (rc) mim__db_fail(c->t->db, &e, rc, "landmark map");
    else rc = mim__db_landmarks_json(c->t, c->t->version, &v, &json, &len, &e);
    if (rc) {
        report_err(c, "landmarks", 0, &e);
        return;
    }
    c->out->landmarks = 1;
    if (mim_landmarks_parse(&map, json, len, "landmark map", &e)) {
        reportf(c, "landmarks", 0, "%s", e.msg);
        return;
    }
    if (!c->out->topology) {
        reportf(c, "landmarks", 0, "landmark map: present without a connectivity");
        return;
    }
    if (topo_ok && mim_landmarks_validate(&map, topo->n_vertices, "landmark map", &e))
        reportf(c, "landmarks", 0, "%s", e.msg);
    else if (topo_ok && map.topology_vertices && map.topology_vertices != topo->n_vertices)
        reportf(c, "landmarks", 0, "landmark map: made for %u vertices, the connectivity has %u", map.topology_vertices,
                topo->n_vertices);
}

/* Walks an integer-keyed table; fn gets each record. */
typedef void (*visit_fn)(ctx_t *c, uint64_t id, const MDB_val *v, void *user);
static void walk(ctx_t *c, int dbi, const char *table, visit_fn fn, void *user)
{
    MDB_cursor *cur;
    int rc = mdb_cursor_open(c->t->txn, c->t->db->dbi[dbi], &cur);
    MDB_val k, v;
    uint64_t last = 0;
    if (!rc) {
        for (rc = mdb_cursor_get(cur, &k, &v, MDB_FIRST); rc == 0; rc = mdb_cursor_get(cur, &k, &v, MDB_NEXT)) {
            size_t id;
            if (k.mv_size != sizeof id) {
                reportf(c, table, 0, "%s: a key of %zu bytes", table, k.mv_size);
                step(c);
                continue;
            }
            memcpy(&id, k.mv_data, sizeof id);
            fn(c, id, &v, user);
            last = id;
            step(c);
        }
        mdb_cursor_close(cur);
    }
    if (rc != MDB_NOTFOUND)
        reportf(c, table, 0, "%s: cannot be read past key %llu (%s)", table, (unsigned long long)last, mdb_strerror(rc));
}

typedef struct {
    const mim_db_meta_t *meta;
    const mim_db_topology_t *topo;
    int topo_ok;
    MDB_cursor *by_hash;
} tmpl_user_t;

static void visit_template(ctx_t *c, uint64_t id, const MDB_val *v, void *user)
{
    tmpl_user_t *u = user;
    if (c->n_tm == c->cap_tm) {
        size_t cap = c->cap_tm ? 2 * c->cap_tm : 1024;
        tmpl_t *p = realloc(c->tm, cap * sizeof *p);
        if (!p) return; /* counted as read, not cross-checked */
        c->tm = p;
        c->cap_tm = cap;
    }
    tmpl_t *r = &c->tm[c->n_tm++];
    memset(r, 0, sizeof *r);
    r->id = id;
    c->out->templates++;
    mim_template_view_t view;
    mim_error_t e = {0};
    if (mim__db_template_decode(c->t, c->t->version, v, id, &view, &e)) {
        r->bad = 1;
        report_err(c, "templates", id, &e);
        return;
    }
    r->hash = view.content_hash;
    r->n = view.n_vertices;
    if (mim_db_content_hash(view.positions, view.n_vertices) != view.content_hash)
        reportf(c, "templates", id, "template %llu: positions do not match their content hash", (unsigned long long)id);
    if (u->topo_ok && view.n_vertices != u->topo->n_vertices)
        reportf(c, "templates", id, "template %llu: %u vertices, the connectivity has %u", (unsigned long long)id,
                view.n_vertices, u->topo->n_vertices);
    else if (!c->out->topology)
        reportf(c, "templates", id, "template %llu: stored without a connectivity", (unsigned long long)id);
    if (id == 0 || id >= u->meta->next_id)
        reportf(c, "templates", id, "template %llu: id is not below next_id (%llu)", (unsigned long long)id,
                (unsigned long long)u->meta->next_id);
    size_t h = (size_t)view.content_hash, key = (size_t)id;
    MDB_val hk = {sizeof h, &h}, hv = {sizeof key, &key};
    if (u->by_hash && mdb_cursor_get(u->by_hash, &hk, &hv, MDB_GET_BOTH) != 0)
        reportf(c, "templates", id, "template %llu: missing from the hash index", (unsigned long long)id);
}

static void visit_encoding(ctx_t *c, uint64_t id, const MDB_val *v, void *user)
{
    (void)user;
    c->out->encodings++;
    mim_db_encoding_t enc;
    mim_error_t e = {0};
    if (mim__db_encoding_decode(c->t, c->t->version, v, id, &enc, &e)) {
        report_err(c, "encodings", id, &e);
        if (find_tmpl(c, id)) find_tmpl(c, id)->has_encoding = 1; /* reported once, as damage */
        return;
    }
    tmpl_t *r = find_tmpl(c, id);
    if (!r) {
        if (c->templates_read)
            reportf(c, "encodings", id, "encoding of template %llu: no such template", (unsigned long long)id);
        return;
    }
    r->has_encoding = 1;
    if (!r->bad && r->n != enc.n_vertices)
        reportf(c, "encodings", id, "encoding of template %llu: %u vertices, the template has %u",
                (unsigned long long)id, enc.n_vertices, r->n);
}

static reg_t *find_reg(ctx_t *c, uint64_t id)
{
    size_t lo = 0, hi = c->n_rg;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (c->rg[mid].id < id) lo = mid + 1;
        else hi = mid;
    }
    return lo < c->n_rg && c->rg[lo].id == id ? &c->rg[lo] : NULL;
}

static void visit_registration(ctx_t *c, uint64_t id, const MDB_val *v, void *user)
{
    MDB_cursor *by_source = user;
    c->out->registrations++;
    reg_t *r = NULL;
    if (c->n_rg == c->cap_rg) {
        size_t cap = c->cap_rg ? 2 * c->cap_rg : 256;
        reg_t *p = realloc(c->rg, cap * sizeof *p);
        if (p) c->rg = p, c->cap_rg = cap;
    }
    if (c->n_rg < c->cap_rg) { /* else counted, and its source-index entries go unmatched */
        r = &c->rg[c->n_rg++];
        memset(r, 0, sizeof *r);
        r->id = id;
    }
    mim_db_registration_t reg;
    mim_error_t e = {0};
    if (mim__db_registration_decode(c->t, v, id, &reg, &e)) {
        if (r) r->bad = 1;
        report_err(c, "registrations", id, &e);
        return;
    }
    if (r) r->source_hash = reg.source_hash;
    if (c->templates_read && !find_tmpl(c, id))
        reportf(c, "registrations", id, "registration %llu: template %llu is not stored", (unsigned long long)id,
                (unsigned long long)id);
    size_t h = (size_t)reg.source_hash, key = (size_t)id;
    MDB_val hk = {sizeof h, &h}, hv = {sizeof key, &key};
    if (by_source && mdb_cursor_get(by_source, &hk, &hv, MDB_GET_BOTH) != 0)
        reportf(c, "registrations", id, "registration %llu: missing from the source index", (unsigned long long)id);
}

/* A hash index (by_hash: content hash -> template; by_source: source hash
 * -> registration): each entry well formed, naming a record that exists
 * and carries that hash. lookup gives the record's hash and whether it
 * decoded; 0 when there is none. */
typedef struct {
    int dbi;
    const char *table, *label;  /* "by_hash", "hash index" */
    const char *missing, *whose; /* "which is not stored", "whose hash is" */
    int (*lookup)(ctx_t *c, uint64_t id, uint64_t *hash, int *bad);
    uint64_t *count;
} hash_index_t;

static void check_hash_index(ctx_t *c, const hash_index_t *x)
{
    MDB_cursor *cur;
    MDB_val k, v;
    int rc = mdb_cursor_open(c->t->txn, c->t->db->dbi[x->dbi], &cur);
    if (!rc) {
        for (rc = mdb_cursor_get(cur, &k, &v, MDB_FIRST); rc == 0; rc = mdb_cursor_get(cur, &k, &v, MDB_NEXT)) {
            (*x->count)++;
            step(c);
            size_t h, id;
            if (k.mv_size != sizeof h || v.mv_size != sizeof id) {
                reportf(c, x->table, 0, "%s: an entry of %zu + %zu bytes", x->label, k.mv_size, v.mv_size);
                continue;
            }
            memcpy(&h, k.mv_data, sizeof h);
            memcpy(&id, v.mv_data, sizeof id);
            uint64_t have;
            int bad;
            if (!x->lookup(c, id, &have, &bad))
                reportf(c, x->table, id, "%s: entry %016llx names template %llu, %s", x->label, (unsigned long long)h,
                        (unsigned long long)id, x->missing);
            else if (!bad && have != h)
                reportf(c, x->table, id, "%s: entry %016llx names template %llu, %s %016llx", x->label,
                        (unsigned long long)h, (unsigned long long)id, x->whose, (unsigned long long)have);
        }
        mdb_cursor_close(cur);
    }
    if (rc != MDB_NOTFOUND) reportf(c, x->table, 0, "%s: cannot be read (%s)", x->label, mdb_strerror(rc));
}

static int lookup_registration(ctx_t *c, uint64_t id, uint64_t *hash, int *bad)
{
    reg_t *r = find_reg(c, id);
    if (r) *hash = r->source_hash, *bad = r->bad;
    return r != NULL;
}

static int lookup_template(ctx_t *c, uint64_t id, uint64_t *hash, int *bad)
{
    tmpl_t *r = find_tmpl(c, id);
    if (r) *hash = r->hash, *bad = r->bad;
    return r != NULL;
}

static void check_by_source(ctx_t *c)
{
    hash_index_t x = {DBI_BY_SOURCE, "by_source", "source index", "which has no registration", "registered from source",
                      lookup_registration, &c->out->source_entries};
    check_hash_index(c, &x);
}

static void visit_binding(ctx_t *c, uint64_t key, const MDB_val *v, void *user)
{
    (void)user;
    c->out->bindings++;
    const void *blob;
    size_t len;
    mim_error_t e = {0};
    if (mim__db_binding_decode(c->t, v, key, &blob, &len, &e)) report_err(c, "bindings", 0, &e);
}

static void check_by_hash(ctx_t *c)
{
    hash_index_t x = {DBI_BY_HASH, "by_hash", "hash index", "which is not stored", "whose hash is", lookup_template,
                      &c->out->hash_entries};
    check_hash_index(c, &x);
}

static void check_index(ctx_t *c, const mim_db_meta_t *meta)
{
    MDB_val kb = {11, "index.build"}, km = {11, "index.model"}, vb, vm;
    int rb = mdb_get(c->t->txn, c->t->db->dbi[DBI_META], &kb, &vb);
    int rm = mdb_get(c->t->txn, c->t->db->dbi[DBI_META], &km, &vm);
    if (rb == MDB_NOTFOUND && rm == MDB_NOTFOUND) return;
    c->out->index = 1;
    if (rb || rm) {
        reportf(c, "index", 0, "index: %s", rb ? "model without a build record" : "build record without a model");
        return;
    }
    mim_db_index_meta_t m;
    mim_error_t e = {0};
    if (mim__db_index_build_decode(c->t, c->t->version, &vb, &vm, &m, &e)) {
        report_err(c, "index", 0, &e);
        return;
    }
    if (m.next_id > meta->next_id)
        reportf(c, "index", 0, "index: built at next_id %llu, past the store's %llu", (unsigned long long)m.next_id,
                (unsigned long long)meta->next_id);
}

int mim_db_check(mim_db_t *db, const mim_db_check_options_t *opt, mim_db_check_report_t *out, mim_error_t *err)
{
    mim_db_check_options_t none = {0};
    if (!opt) opt = &none;
    memset(out, 0, sizeof *out);
    double t0 = mim_now();
    ctx_t c = {.opt = opt, .out = out};
    int rc = mim_db_begin(db, 0, &c.t, err);
    if (rc) return rc;
    out->schema_version = c.t->version;
    uint64_t total = 0;
    static const int counted[] = {DBI_TEMPLATES, DBI_ENCODINGS, DBI_BY_HASH, DBI_REGISTRATIONS, DBI_BY_SOURCE, DBI_BINDINGS};
    for (size_t i = 0; i < sizeof counted / sizeof *counted; i++) {
        MDB_stat st;
        if (mim__db_have(db, counted[i]) && !mdb_stat(c.t->txn, db->dbi[counted[i]], &st)) total += st.ms_entries;
    }
    c.prog = (mim_progress_t){.fn = opt->progress, .ctx = opt->progress_ctx};
    mim_progress_begin(&c.prog, "check", total);

    check_file(&c);
    /* LMDB's pages first, read from the file: a table whose tree is
     * damaged is not read through LMDB (it would follow the damage out of
     * the file), and its records are reported as not checked. */
    unsigned bad = 0;
    if ((rc = mim__db_walk(db, c.t->txn, 1, walk_problem, &c, &bad, NULL))) {
        mim_db_abort(&c.t);
        return mim_error_set(err, rc, "%s: out of memory checking the store", db->path);
    }
#define READABLE(i) (!(bad & (1u << MIM__WALK_LIST)) && !(bad & (1u << (i))))
    for (int i = 0; i < DBI_COUNT_; i++)
        if (!READABLE(i) && mim__db_have(db, i))
            reportf(&c, mim__db_table_names[i], 0, "table '%s': records not checked (its pages are damaged)",
                    mim__db_table_names[i]);
    mim_db_meta_t meta = {.next_id = UINT64_MAX};
    if (READABLE(DBI_META)) check_meta(&c, &meta);
    mim_db_topology_t topo = {0};
    int topo_ok = READABLE(DBI_TOPOLOGY) ? check_topology(&c, &topo) : 0;
    if (!READABLE(DBI_TOPOLOGY)) out->topology = 1; /* there, damaged */
    if (READABLE(DBI_LANDMARKS)) check_landmarks(&c, &topo, topo_ok);
    tmpl_user_t u = {&meta, &topo, topo_ok, NULL};
    c.templates_read = READABLE(DBI_TEMPLATES);
    if (!READABLE(DBI_BY_HASH) || mdb_cursor_open(c.t->txn, db->dbi[DBI_BY_HASH], &u.by_hash)) u.by_hash = NULL;
    if (c.templates_read) walk(&c, DBI_TEMPLATES, "templates", visit_template, &u);
    if (u.by_hash) mdb_cursor_close(u.by_hash);
    if (db->have_encodings && READABLE(DBI_ENCODINGS)) walk(&c, DBI_ENCODINGS, "encodings", visit_encoding, NULL);
    for (size_t i = 0; i < c.n_tm; i++) out->templates_without_encoding += !c.tm[i].has_encoding && !c.tm[i].bad;
    if (READABLE(DBI_BY_HASH) && c.templates_read) check_by_hash(&c);
    if (READABLE(DBI_META)) check_index(&c, &meta);
    if (db->have_registrations) {
        MDB_cursor *by_source = NULL;
        if (!READABLE(DBI_BY_SOURCE) || mdb_cursor_open(c.t->txn, db->dbi[DBI_BY_SOURCE], &by_source)) by_source = NULL;
        c.registrations_read = READABLE(DBI_REGISTRATIONS);
        if (c.registrations_read) walk(&c, DBI_REGISTRATIONS, "registrations", visit_registration, by_source);
        if (by_source) mdb_cursor_close(by_source);
        if (READABLE(DBI_BY_SOURCE) && c.registrations_read) check_by_source(&c);
    }
    if (db->have_bindings && READABLE(DBI_BINDINGS)) walk(&c, DBI_BINDINGS, "bindings", visit_binding, NULL);
#undef READABLE

    mim_progress_end(&c.prog);
    mim_db_abort(&c.t);
    free(c.tm);
    free(c.rg);
    out->seconds = mim_now() - t0;
    return 0;
}
