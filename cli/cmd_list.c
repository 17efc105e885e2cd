/* mimic list: one row per template. JSON: schemas/list.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_register.h"
#include "mim_db.h"

#include <getopt.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out, "usage: mimic list --store DIR [--subject S] [--pose P] [--json]\n\n"
                 "Lists the templates of a store: id, subject, pose and source path, and for a\n"
                 "template registered from a mesh of another connectivity its fit to that mesh\n"
                 "(\"registered MEAN/P95 mm\": mean and 95th-percentile surface distance) and its\n"
                 "landmarks' mean distance to the mesh's; --json adds how well the correspondence\n"
                 "holds: the largest landmark distance, the enclosed volume against the starting\n"
                 "template's, and the distortion of each body region.\n\n"
                 "  --store DIR    the template store\n"
                 "  --subject S    only templates of subject S\n"
                 "  --pose P       only templates in pose P\n"
                 "  --json         a JSON array on stdout (schemas/list.schema.json)\n"
                 "  -h, --help     this help\n");
}

typedef struct {
    const char *subject, *pose;
    mim_db_txn_t *txn;
    mim_error_t *err;
    json_t *rows; /* NULL: print text */
    uint64_t shown;
} list_t;

static int row(const mim_template_view_t *t, void *user)
{
    list_t *l = user;
    if (l->subject && strcmp(l->subject, t->subject)) return 0;
    if (l->pose && strcmp(l->pose, t->pose)) return 0;
    l->shown++;
    mim_db_registration_t reg;
    int rc = mim_db_registration_get(l->txn, t->id, &reg, l->err);
    if (rc && rc != MIM_ENOTFOUND) return rc; /* damage: the message is in l->err */
    const int registered = rc == 0;
    if (l->rows) {
        json_t *o = json_pack("{s:I, s:s, s:s, s:s, s:s}", "id", (json_int_t)t->id, "subject", t->subject, "pose",
                              t->pose, "dataset", t->dataset, "source", t->source);
        json_t *rj = registered ? json_pack("{s:f, s:f, s:f, s:f, s:I, s:I}", "mean_mm", reg.mean_mm, "p95_mm",
                                            reg.p95_mm, "max_mm", reg.max_mm, "landmark_mean_mm", reg.landmark_mean_mm,
                                            "iterations", (json_int_t)reg.iterations, "source_vertices",
                                            (json_int_t)reg.source_vertices)
                                : NULL;
        if (rj && reg.quality.present) { /* how well the correspondence holds, beside how close the surface lies */
            json_t *dist = json_object();
            for (int g = 0; g < MIM_DB_REG_REGIONS; g++)
                json_object_set_new(dist, mim_reg_region_names[g], json_real(reg.quality.distortion_pct[g]));
            json_object_set_new(rj, "landmark_max_mm", json_real(reg.quality.landmark_max_mm));
            json_object_set_new(rj, "volume_ratio", json_real(reg.quality.volume_ratio));
            json_object_set_new(rj, "distortion_percent", dist);
        }
        if (o && rj) json_object_set_new(o, "registration", rj);
        if (!o || json_array_append_new(l->rows, o)) return mim_error_set(l->err, MIM_ENOMEM, "out of memory");
        return 0;
    }
    printf("%8llu  %-10s %-10s %s", (unsigned long long)t->id, t->subject[0] ? t->subject : "-",
           t->pose[0] ? t->pose : "-", t->source);
    if (t->dataset[0]) printf("  dataset %s", t->dataset);
    if (registered) printf("  registered %.2f/%.2f mm, landmarks %.1f mm", reg.mean_mm, reg.p95_mm, reg.landmark_mean_mm);
    printf("\n");
    return 0;
}

int mim_cmd_list(int argc, char **argv)
{
    static const struct option longopts[] = {{"store", required_argument, 0, 's'}, {"subject", required_argument, 0, 'S'},
                                              {"pose", required_argument, 0, 'p'},  {"json", no_argument, 0, 'j'},
                                              {"help", no_argument, 0, 'h'},        {0, 0, 0, 0}};
    const char *store = NULL;
    list_t l = {0};
    int as_json = 0, c;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:S:p:jh", longopts, NULL)) != -1) {
        if (c == 's') store = optarg;
        else if (c == 'S') l.subject = optarg;
        else if (c == 'p') l.pose = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic list: unknown or incomplete option '%s' (see mimic list --help)\n", argv[optind - 1]);
            return 2;
        }
    }
    if (!store) {
        fprintf(stderr, "mimic list: --store DIR is required (see mimic list --help)\n");
        return 2;
    }
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_options_t o = mim_cli_db_options(1);
    mim_db_txn_t *t = NULL;
    int rc = mim_db_open(&db, store, &o, &err);
    if (!rc) rc = mim_db_begin(db, 0, &t, &err);
    l.txn = t;
    l.err = &err;
    if (!rc) {
        if (as_json) l.rows = json_array();
        else printf("%8s  %-10s %-10s %s\n", "id", "subject", "pose", "source");
        rc = mim_db_template_each(t, row, &l, &err);
    }
    if (!rc && as_json) {
        char *s = json_dumps(l.rows, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
        printf("%s\n", s ? s : "[]");
        free(s);
    }
    if (rc) fprintf(stderr, "mimic list: %s\n", mim_error_text(&err));
    json_decref(l.rows);
    mim_db_abort(&t);
    mim_db_close(&db);
    return rc ? 2 : 0;
}
