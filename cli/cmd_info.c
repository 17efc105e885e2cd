/* mimic info: what a template store holds. JSON: schemas/info.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_db.h"
#include "mim_query.h"

#include <getopt.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out, "usage: mimic info --store DIR [--json]\n\n"
                 "Describes a template store: number of templates, counts by subject and by pose,\n"
                 "the reference connectivity, the landmark map, the schema version, the size on disk,\n"
                 "and the recognition index (mimic index): its classes (pose labels or k-means) and\n"
                 "whether it is stale (templates added since it was built).\n\n"
                 "  --store DIR  the template store\n"
                 "  --json       one JSON object on stdout (schemas/info.schema.json)\n"
                 "  -h, --help   this help\n");
}

/* Counts per label value, in first-seen order. */
static int count_label(json_t *counts, const char *label)
{
    const char *key = label[0] ? label : "";
    json_t *v = json_object_get(counts, key);
    return json_object_set_new(counts, key, json_integer(v ? json_integer_value(v) + 1 : 1));
}

typedef struct {
    json_t *subjects, *poses, *datasets;
    uint64_t unlabelled;
    int several; /* more than one dataset: labels are each dataset's own */
} tally_t;

static int tally_dataset(const mim_template_view_t *t, void *user)
{
    tally_t *ta = user;
    return count_label(ta->datasets, t->dataset);
}

/* A label as mim_db_labels_qualify makes it for the index. */
static int count_qualified(const tally_t *ta, json_t *counts, const mim_template_view_t *t, const char *label)
{
    if (!ta->several || !t->dataset[0] || !label[0]) return count_label(counts, label);
    char q[2 * 4096 + 2];
    snprintf(q, sizeof q, "%s/%s", t->dataset, label);
    return count_label(counts, q);
}

static int tally(const mim_template_view_t *t, void *user)
{
    tally_t *ta = user;
    if (!t->subject[0] && !t->pose[0]) {
        ta->unlabelled++;
        return 0;
    }
    count_qualified(ta, ta->subjects, t, t->subject);
    count_qualified(ta, ta->poses, t, t->pose);
    return 0;
}

static void print_counts(const char *what, json_t *counts)
{
    printf("%-12s", what);
    const char *k;
    json_t *v;
    int first = 1;
    json_object_foreach(counts, k, v) {
        printf("%s%s:%lld", first ? " " : ", ", k[0] ? k : "(none)", (long long)json_integer_value(v));
        first = 0;
    }
    if (first) printf(" (none)");
    printf("\n");
}

int mim_cmd_info(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'}, {"json", no_argument, 0, 'j'}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    const char *store = NULL;
    int as_json = 0, c;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:jh", longopts, NULL)) != -1) {
        if (c == 's') store = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic info: unknown or incomplete option '%s' (see mimic info --help)\n", argv[optind - 1]);
            return 2;
        }
    }
    if (!store) {
        fprintf(stderr, "mimic info: --store DIR is required (see mimic info --help)\n");
        return 2;
    }
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_options_t o = mim_cli_db_options(1);
    int rc = mim_db_open(&db, store, &o, &err);
    mim_db_txn_t *t = NULL;
    if (!rc) rc = mim_db_begin(db, 0, &t, &err);
    if (rc) {
        fprintf(stderr, "mimic info: %s\n", mim_error_text(&err));
        mim_db_close(&db);
        return 2;
    }
    mim_db_meta_t meta;
    mim_db_topology_t topo;
    mim_landmark_map_t lm;
    mim_db_stat_t st;
    tally_t ta = {json_object(), json_object(), json_object(), 0, 0};
    rc = mim_db_meta_get(t, &meta, &err);
    int have_topo = 0, have_lm = 0;
    if (!rc) {
        int r = mim_db_topology_get(t, &topo, &err);
        have_topo = r == 0;
        if (r && r != MIM_ENOTFOUND) rc = r;
    }
    if (!rc) {
        int r = mim_db_landmarks_get(t, &lm, &err);
        have_lm = r == 0;
        if (r && r != MIM_ENOTFOUND) rc = r;
    }
    if (!rc) rc = mim_db_template_each(t, tally_dataset, &ta, &err);
    ta.several = json_object_size(ta.datasets) > 1;
    if (!rc) rc = mim_db_template_each(t, tally, &ta, &err);
    if (!rc) rc = mim_db_stat(db, &st, &err);
    mim_query_status_t qs = {0};
    if (!rc) rc = mim_query_status(db, &qs, &err);
    if (rc) {
        fprintf(stderr, "mimic info: %s\n", mim_error_text(&err));
        goto done;
    }
    double per_template = meta.templates ? (double)st.template_bytes / (double)meta.templates : 0;
    if (as_json) {
        json_t *root = json_object();
        json_object_set_new(root, "store", json_string(store));
        json_object_set_new(root, "schema_version", json_integer(meta.schema_version));
        json_object_set_new(root, "created_by", json_string(meta.created_by));
        json_object_set_new(root, "templates", json_integer((json_int_t)meta.templates));
        json_object_set_new(root, "subjects", json_incref(ta.subjects));
        json_object_set_new(root, "poses", json_incref(ta.poses));
        json_object_set_new(root, "datasets", json_incref(ta.datasets));
        json_object_set_new(root, "unlabelled", json_integer((json_int_t)ta.unlabelled));
        if (have_topo) {
            char hex[20];
            snprintf(hex, sizeof hex, "%016llx", (unsigned long long)topo.hash);
            json_object_set_new(root, "connectivity",
                                json_pack("{s:I, s:I, s:s}", "vertices", (json_int_t)topo.n_vertices, "faces",
                                          (json_int_t)topo.n_faces, "hash", hex));
        } else {
            json_object_set_new(root, "connectivity", json_null());
        }
        if (have_lm) {
            char *s = mim_landmarks_to_json(&lm);
            json_object_set_new(root, "landmarks", s ? json_loads(s, 0, NULL) : json_null());
            free(s);
        } else {
            json_object_set_new(root, "landmarks", json_null());
        }
        json_object_set_new(root, "size",
                            json_pack("{s:I, s:I, s:I, s:I, s:f}", "disk_bytes", (json_int_t)st.disk_bytes, "file_bytes",
                                      (json_int_t)st.file_bytes, "used_bytes",
                                      (json_int_t)(st.pages_used * st.page_size), "template_bytes",
                                      (json_int_t)st.template_bytes, "bytes_per_template", per_template));
        if (qs.has_index)
            json_object_set_new(root, "index",
                                json_pack("{s:b, s:s, s:I, s:I, s:I}", "stale", qs.stale, "class_source",
                                          qs.built.class_source == MIM_CLASSES_KMEANS ? "kmeans" : "labels", "classes",
                                          (json_int_t)qs.built.n_classes, "features", (json_int_t)qs.built.d,
                                          "templates", (json_int_t)qs.built.templates));
        else
            json_object_set_new(root, "index", json_null());
        char *s = json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
        printf("%s\n", s);
        free(s);
        json_decref(root);
    } else {
        printf("store        %s (schema %u, created by %s)\n", store, meta.schema_version, meta.created_by);
        printf("templates    %llu\n", (unsigned long long)meta.templates);
        print_counts("subjects", ta.subjects);
        print_counts("poses", ta.poses);
        print_counts("datasets", ta.datasets);
        if (ta.unlabelled) printf("unlabelled   %llu\n", (unsigned long long)ta.unlabelled);
        if (have_topo)
            printf("connectivity %u vertices, %u faces, hash %016llx\n", topo.n_vertices, topo.n_faces,
                   (unsigned long long)topo.hash);
        else
            printf("connectivity (none yet)\n");
        if (have_lm) {
            printf("landmarks    %u:", lm.count);
            for (uint32_t i = 0; i < lm.count; i++) printf(" %s=%u", lm.names[i], lm.vertex[i]);
            printf("\n");
        } else {
            printf("landmarks    (none yet)\n");
        }
        if (qs.has_index)
            printf("index        %u classes from %s, %u angles, built over %llu templates%s\n", qs.built.n_classes,
                   qs.built.class_source == MIM_CLASSES_KMEANS ? "k-means (no pose labels)" : "pose labels",
                   qs.built.d, (unsigned long long)qs.built.templates,
                   qs.stale ? "; STALE: templates were added since (run mimic index)" : "");
        else
            printf("index        (none: run mimic index)\n");
        printf("size         %.1f MiB on disk, %.1f MiB in use, %.0f bytes per template\n",
               (double)st.disk_bytes / 1048576.0, (double)(st.pages_used * st.page_size) / 1048576.0, per_template);
    }
done:
    json_decref(ta.subjects);
    json_decref(ta.poses);
    json_decref(ta.datasets);
    mim_db_abort(&t);
    mim_db_close(&db);
    return rc ? 2 : 0;
}
