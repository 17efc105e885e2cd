/* mimic store: the store's own upkeep. `check` verifies every record
 * (mim_db_check; JSON: schemas/store-check.schema.json); `migrate` brings a
 * version-1 or version-2 store to the current schema version (what the
 * first read-write open does anyway), with progress; `copy` makes a
 * compacted snapshot of a live store (mim_db_copy; JSON:
 * schemas/store-copy.schema.json), to ship it to replicas. */
#include "args.h"
#include "commands.h"
#include "mim_db.h"
#include "output.h"

#include <getopt.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out, "usage: mimic store check --store DIR [--json]\n"
                 "       mimic store migrate --store DIR\n"
                 "       mimic store copy SRC DST [--json]\n\n"
                 "check    reads every record of the store and verifies it: each template, encoding,\n"
                 "         landmark map and index record decodes and passes its checksum, positions\n"
                 "         match their content hash, and the cross-references hold (each template's\n"
                 "         encoding has its vertex count, the hash index names stored templates, the\n"
                 "         landmark map and connectivity are valid). One line per problem, then a\n"
                 "         summary. Exit status 0: no problem; 1: damage found; 2: the store cannot be\n"
                 "         opened at all (the reason is the one line on stderr).\n"
                 "migrate  rewrites a store of schema version 1 or 2 as the current version, 3 (version-1\n"
                 "         records gain checksums; the registrations, by_source and bindings tables are\n"
                 "         added), in one transaction: all or nothing. Opening a store for writing\n"
                 "         (mimic ingest, mimic index) does the same; read-only commands read an older\n"
                 "         store as it is.\n"
                 "copy     a consistent snapshot of the store SRC, as one moment saw it, while other\n"
                 "         processes keep writing to it, compacted (no free pages), into the new\n"
                 "         directory DST: a store to ship to a replica. DST is made whole or not at all.\n\n"
                 "  --store DIR  the template store (or DIR as the argument after the subcommand)\n"
                 "  --json       check, copy: one JSON object on stdout (schemas/store-check.schema.json,\n"
                 "               schemas/store-copy.schema.json)\n"
                 "  -h, --help   this help\n");
}

typedef struct {
    json_t *problems; /* {table, id, message} in the order found */
    uint64_t dropped; /* beyond what is kept */
} found_t;

#define KEEP_MAX 100000

static void on_problem(void *ctx, const mim_db_problem_t *p)
{
    found_t *f = ctx;
    if (json_array_size(f->problems) >= KEEP_MAX) {
        f->dropped++;
        return;
    }
    json_array_append_new(f->problems, json_pack("{s:s, s:o, s:s}", "table", p->table, "id",
                                                 p->id ? json_integer((json_int_t)p->id) : json_null(), "message",
                                                 p->message));
}

static int check(const char *store, int as_json)
{
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_options_t o = mim_cli_db_options(1);
    int rc = mim_db_open(&db, store, &o, &err);
    if (rc) {
        fprintf(stderr, "mimic store check: %s\n", mim_error_text(&err));
        return 2;
    }
    found_t f = {json_array(), 0};
    mim_db_check_options_t co = {.problem = on_problem, .problem_ctx = &f, .progress = mim_cli_progress};
    mim_db_check_report_t r;
    rc = mim_db_check(db, &co, &r, &err);
    mim_db_close(&db);
    if (rc) {
        fprintf(stderr, "mimic store check: %s\n", mim_error_text(&err));
        json_decref(f.problems);
        return 2;
    }
    if (as_json) {
        json_t *root = json_pack("{s:s, s:I, s:b, s:I, s:o, s:{s:I, s:I, s:I, s:b, s:b, s:b}, s:I, s:f}", "store", store,
                                 "schema_version", (json_int_t)r.schema_version, "clean", r.problems == 0, "problems_found",
                                 (json_int_t)r.problems, "problems", json_incref(f.problems), "checked", "templates",
                                 (json_int_t)r.templates, "encodings", (json_int_t)r.encodings, "hash_entries",
                                 (json_int_t)r.hash_entries, "topology", r.topology, "landmarks", r.landmarks, "index",
                                 r.index, "templates_without_encoding", (json_int_t)r.templates_without_encoding,
                                 "seconds", r.seconds);
        char *s = root ? json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (s) printf("%s\n", s);
        free(s);
        json_decref(root);
    } else {
        size_t i;
        json_t *p;
        json_array_foreach(f.problems, i, p) printf("%s\n", json_string_value(json_object_get(p, "message")));
        if (f.dropped) printf("(%llu more problems not listed)\n", (unsigned long long)f.dropped);
        printf("store %s: schema version %u; checked %llu templates, %llu encodings, %llu hash-index entries%s%s%s: ",
               store, r.schema_version, (unsigned long long)r.templates, (unsigned long long)r.encodings,
               (unsigned long long)r.hash_entries, r.topology ? ", the connectivity" : "",
               r.landmarks ? ", the landmark map" : "", r.index ? ", the index" : "");
        if (r.problems) printf("%llu problem%s\n", (unsigned long long)r.problems, r.problems == 1 ? "" : "s");
        else printf("no problems (%.2f s)\n", r.seconds);
        if (r.templates_without_encoding)
            printf("note: %llu templates have no encoding (stored by an older mimic; readers compute it, a re-ingest "
                   "of the same files stores it)\n",
                   (unsigned long long)r.templates_without_encoding);
        if (r.schema_version < 2)
            printf("note: schema version 1: records carry no checksums (positions were checked against their content "
                   "hashes); mimic store migrate adds them\n");
    }
    json_decref(f.problems);
    return r.problems ? 1 : 0;
}

static void on_log(void *ctx, int level, const char *msg)
{
    *(int *)ctx = 1;
    mim_cli_log(NULL, level, msg);
}

static int migrate(const char *store)
{
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    int migrated = 0;
    mim_db_options_t o = mim_cli_db_options(0);
    o.progress = mim_cli_progress;
    o.log = on_log;
    o.log_ctx = &migrated;
    /* read-write open of an existing store: the migration, if one is due */
    mim_db_options_t ro = mim_cli_db_options(1);
    int rc = mim_db_open(&db, store, &ro, &err);
    mim_db_close(&db);
    if (!rc) rc = mim_db_open(&db, store, &o, &err);
    mim_db_txn_t *t = NULL;
    mim_db_meta_t meta = {0};
    if (!rc) rc = mim_db_begin(db, 0, &t, &err);
    if (!rc) rc = mim_db_meta_get(t, &meta, &err);
    mim_db_abort(&t);
    mim_db_close(&db);
    if (rc) {
        fprintf(stderr, "mimic store migrate: %s\n", mim_error_text(&err));
        return 2;
    }
    if (!migrated) printf("store %s: already at schema version %u, nothing to do\n", store, meta.schema_version);
    else printf("store %s: now at schema version %u (%llu templates)\n", store, meta.schema_version,
                (unsigned long long)meta.templates);
    return 0;
}

static int copy(const char *src, const char *dst, int as_json)
{
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_options_t o = mim_cli_db_options(1);
    int rc = mim_db_open(&db, src, &o, &err);
    if (rc) {
        fprintf(stderr, "mimic store copy: %s\n", mim_error_text(&err));
        return 2;
    }
    mim_db_txn_t *t = NULL;
    mim_db_meta_t meta = {0};
    uint64_t bytes = 0;
    mim_db_stat_t st = {0};
    double t0 = mim_now();
    rc = mim_db_stat(db, &st, &err);
    if (!rc) rc = mim_db_copy(db, dst, &bytes, &err);
    double seconds = mim_now() - t0;
    if (!rc) { /* the copy's own count, read back from it */
        mim_db_t *c = NULL;
        mim_error_t rerr = {0};
        rc = mim_db_open(&c, dst, &o, &rerr);
        if (!rc) rc = mim_db_begin(c, 0, &t, &rerr);
        if (!rc) rc = mim_db_meta_get(t, &meta, &rerr);
        mim_db_abort(&t);
        mim_db_close(&c);
        if (rc) mim_error_set(&err, rc, "%s: the copy is there, but reading it back failed: %s", dst, mim_error_text(&rerr));
    }
    mim_db_close(&db);
    if (rc) {
        fprintf(stderr, "mimic store copy: %s\n", mim_error_text(&err));
        return 1;
    }
    if (as_json) {
        json_t *root = json_pack("{s:s, s:s, s:I, s:I, s:I, s:f}", "source", src, "destination", dst, "templates",
                                 (json_int_t)meta.templates, "bytes", (json_int_t)bytes, "source_bytes",
                                 (json_int_t)st.file_bytes, "seconds", seconds);
        char *text = root ? json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (text) printf("%s\n", text);
        free(text);
        json_decref(root);
    } else {
        printf("store %s copied to %s: %llu templates, %.1f MiB (the source's file: %.1f MiB), %.2f s\n", src, dst,
               (unsigned long long)meta.templates, (double)bytes / (1 << 20), (double)st.file_bytes / (1 << 20), seconds);
    }
    return 0;
}

int mim_cmd_store(int argc, char **argv)
{
    if (argc < 2) {
        help(stderr);
        return 2;
    }
    const char *sub = argv[1];
    if (!strcmp(sub, "-h") || !strcmp(sub, "--help") || !strcmp(sub, "help")) return help(stdout), 0;
    if (strcmp(sub, "check") && strcmp(sub, "migrate") && strcmp(sub, "copy")) {
        fprintf(stderr, "mimic store: unknown subcommand '%s' (check, migrate or copy; see mimic store --help)\n", sub);
        return 2;
    }
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'}, {"json", no_argument, 0, 'j'}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    const char *store = NULL;
    int as_json = 0, c;
    optind = 0;
    opterr = 0;
    argc--, argv++; /* argv[0] is the subcommand now */
    while ((c = getopt_long(argc, argv, "s:jh", longopts, NULL)) != -1) {
        if (c == 's') store = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic store %s: unknown or incomplete option '%s' (see mimic store --help)\n", sub,
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!strcmp(sub, "copy")) {
        if (store || optind + 2 != argc) {
            fprintf(stderr, "mimic store copy: give SRC and DST (see mimic store --help)\n");
            return 2;
        }
        return copy(argv[optind], argv[optind + 1], as_json);
    }
    if (optind < argc) {
        if (store || optind + 1 < argc) {
            fprintf(stderr, "mimic store %s: one store only: unexpected '%s' (see mimic store --help)\n", sub,
                    argv[optind]);
            return 2;
        }
        store = argv[optind];
    }
    if (!store) {
        fprintf(stderr, "mimic store %s: --store DIR is required (see mimic store --help)\n", sub);
        return 2;
    }
    if (!strcmp(sub, "migrate")) {
        if (as_json) {
            fprintf(stderr, "mimic store migrate: --json is for mimic store check\n");
            return 2;
        }
        return migrate(store);
    }
    return check(store, as_json);
}
