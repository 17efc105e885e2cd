/* mimic index: build the recognition index of a store (seed 000, §3.2-3.3)
 * and keep it in the store. JSON: schemas/index.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_ingest.h"
#include "mim_query.h"
#include "output.h"

#include <getopt.h>
#include <jansson.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>

static const char *pose_class(void *ctx, const char *dataset, const char *pose)
{
    return mim_pose_map_class(ctx, dataset, pose);
}

static void help(FILE *out)
{
    fprintf(out, "usage: mimic index --store DIR [--features D] [--noise F] [--augment N] [--shape-noise F]\n"
                 "                   [--discriminants F] [--exact-max N] [--proportions canonical|body]\n"
                 "                   [--pose-map CSV] [--json]\n\n"
                 "Builds the pose recognition index of a store and keeps it in the store, so that\n"
                 "mimic query opens it in milliseconds: the D most salient landmark angles (a\n"
                 "decision tree on the pose labels, mirrored samples included), one SVM per pose\n"
                 "class (RBF, C and gamma chosen by cross-validation, probability outputs) and a\n"
                 "k-NN index inside each class. A store without pose labels is clustered by\n"
                 "k-means (k = round(sqrt(templates / 2))). Run it again after ingesting more.\n"
                 "The tree and the SVMs also learn from noisy copies of every template, so that\n"
                 "vest landmarks a few cm off are still recognised, and shape discriminants (the\n"
                 "pose classes as Gaussians of one covariance over the landmarks, each frame\n"
                 "brought onto each pose's mean shape, at noise levels up to --shape-noise)\n"
                 "classify every frame, whole or with landmarks missing (bench/RESULTS.md, issue 15).\n\n"
                 "  --store DIR     the template store\n"
                 "  --features D    angles in the descriptor (default 60)\n"
                 "  --noise F       sigma of the training noise, a fraction of the bodies' RMS\n"
                 "                  landmark radius (about 0.5 m for adults; default 0.025, about\n"
                 "                  1.3 cm); 0 turns the augmentation off\n"
                 "  --augment N     noisy copies per template, 1..64 (default 4)\n"
                 "  --shape-noise F the shape discriminants' top noise level, as --noise (default\n"
                 "                  0.06, about 3 cm); 0: none (frames go to the SVMs)\n"
                 "  --discriminants F  also linear discriminants over all angles (the default\n"
                 "                  before the shape discriminants), trained with noise sigma F,\n"
                 "                  as --noise (0.04 measured best); used for whole frames when\n"
                 "                  there are no shape discriminants (default: none)\n"
                 "  --exact-max N   a class of up to N templates is searched by an exact scan, a\n"
                 "                  larger one by a kd-forest (4 trees, 128 checks: approximate, a\n"
                 "                  tenth of the scan's time at 1 000 000 templates); default 8192\n"
                 "  --proportions P canonical (default): in a store of the 16 default landmarks,\n"
                 "                  the angles of every frame, template or query, are taken on the\n"
                 "                  templates' mean segment lengths with the frame's own segment\n"
                 "                  directions, so that people of other proportions in one pose\n"
                 "                  answer alike (the class is still picked on the frame as it is);\n"
                 "                  body: each frame as it is (other landmark maps: always)\n"
                 "  --pose-map CSV  which poses of different datasets are one class: a CSV with the\n"
                 "                  columns dataset, pose, class. Without it, in a store of several\n"
                 "                  datasets (mimic ingest --dataset) every dataset's poses and\n"
                 "                  subjects are its own (\"faust/3\"); a class of one template is\n"
                 "                  reported, as cross-validation cannot learn it from others\n"
                 "  --json          one JSON object on stdout (schemas/index.schema.json)\n"
                 "  -h, --help      this help\n");
}

/* How the classes' k-NN searches: each class an exact scan or a kd-forest. */
static void print_knn(uint32_t exact, uint32_t n)
{
    uint32_t forests = n - exact;
    if (n == 1) printf("k-NN         one class, %s\n", exact ? "exact" : "a kd-forest");
    else if (!forests) printf("k-NN         all %u classes exact\n", n);
    else if (!exact) printf("k-NN         all %u classes kd-forests\n", n);
    else printf("k-NN         %u of %u classes exact, %u kd-forest%s\n", exact, n, forests, forests > 1 ? "s" : "");
}

int mim_cmd_index(int argc, char **argv)
{
    static const struct option longopts[] = {{"store", required_argument, 0, 's'},
                                              {"features", required_argument, 0, 'd'},
                                              {"noise", required_argument, 0, 'n'},
                                              {"augment", required_argument, 0, 'a'},
                                              {"discriminants", required_argument, 0, 'D'},
                                              {"shape-noise", required_argument, 0, 'S'},
                                              {"exact-max", required_argument, 0, 'x'},
                                              {"pose-map", required_argument, 0, 'P'},
                                              {"proportions", required_argument, 0, 'p'},
                                              {"json", no_argument, 0, 'j'},
                                              {"help", no_argument, 0, 'h'},
                                              {0, 0, 0, 0}};
    const char *store = NULL, *pose_map_path = NULL;
    int as_json = 0, c;
    mim_index_options_t o = {0};
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:d:n:a:D:S:x:p:jh", longopts, NULL)) != -1) {
        uint64_t v;
        if (c == 's') store = optarg;
        else if (c == 'd') {
            if (mim_cli_number("index", "features", optarg, 1, 100000, &v)) return 2;
            o.features = (uint32_t)v;
        } else if (c == 'n') {
            double f;
            if (mim_cli_real("index", "noise", optarg, 0, 1, 0, NULL, &f)) return 2;
            o.noise = f > 0 ? f : -1; /* 0: none (the library's 0 means its default) */
        } else if (c == 'D') {
            double f;
            if (mim_cli_real("index", "discriminants", optarg, 0, 1, 0, NULL, &f)) return 2;
            o.discriminant_noise = f > 0 ? f : -1;
        } else if (c == 'S') {
            double f;
            if (mim_cli_real("index", "shape-noise", optarg, 0, 1, 0, NULL, &f)) return 2;
            o.shape_noise = f > 0 ? f : -1;
        } else if (c == 'a') {
            if (mim_cli_number("index", "augment", optarg, 1, 64, &v)) return 2;
            o.augment = (uint32_t)v;
        } else if (c == 'x') {
            if (mim_cli_number("index", "exact-max", optarg, 1, UINT32_MAX, &v)) return 2;
            o.exact_max = (uint32_t)v;
        } else if (c == 'P') pose_map_path = optarg;
        else if (c == 'p') {
            if (strcmp(optarg, "canonical") && strcmp(optarg, "body")) {
                fprintf(stderr, "mimic index: --proportions '%s': use canonical or body\n", optarg);
                return 2;
            }
            o.proportions = strcmp(optarg, "body") ? MIM_INDEX_PROPORTIONS_CANONICAL : MIM_INDEX_PROPORTIONS_BODY;
        }
        else if (c == 'j') as_json = 1;
        else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic index: unknown or incomplete option '%s' (see mimic index --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!store) {
        fprintf(stderr, "mimic index: --store DIR is required (see mimic index --help)\n");
        return 2;
    }
    mim_error_t err = {0};
    mim_pose_map_t *pose_map = NULL;
    if (pose_map_path && mim_pose_map_load(&pose_map, pose_map_path, &err)) {
        fprintf(stderr, "mimic index: %s\n", mim_error_text(&err));
        return 2;
    }
    mim_db_t *db = NULL;
    mim_db_options_t ro = mim_cli_db_options(1), rw = mim_cli_db_options(0);
    /* open read-only first so that a wrong path is not made into a new store */
    int rc = mim_db_open(&db, store, &ro, &err);
    mim_db_close(&db);
    if (!rc) rc = mim_db_open(&db, store, &rw, &err);
    mim_progress_t pr = {.fn = mim_cli_progress};
    o.progress = &pr;
    mim_index_report_t rep;
    mim_query_status_t st;
    mim_query_labels_report_t lab;
    if (!rc) rc = mim_query_build_index_labelled(db, &o, pose_map ? pose_class : NULL, pose_map, &rep, &lab, &err);
    if (!rc) rc = mim_query_status(db, &st, &err);
    mim_pose_map_free(&pose_map);
    if (rc) {
        fprintf(stderr, "mimic index: %s\n", mim_error_text(&err));
        mim_db_close(&db);
        return 2;
    }
    if (lab.single && lab.classes > 1) {
        char ex[4 * sizeof lab.single_example[0]] = "";
        for (uint32_t i = 0; i < lab.single && i < MIM_QUERY_EXAMPLES; i++)
            snprintf(ex + strlen(ex), sizeof ex - strlen(ex), "%s%s", i ? ", " : "", lab.single_example[i]);
        fprintf(stderr,
                "mimic index: warning: %u of %u pose classes have one template (%s%s): they stay classes, but "
                "cross-validation has no other template to learn them from and counts them as misses%s\n",
                lab.single, lab.classes, ex, lab.single > MIM_QUERY_EXAMPLES ? ", ..." : "",
                lab.datasets > 1 ? "; map poses of different datasets onto one class with --pose-map CSV" : "");
    }
    const char *source = rep.class_source == MIM_CLASSES_KMEANS ? "kmeans" : "labels";
    if (as_json) {
        json_t *root = json_pack("{s:s, s:I, s:I, s:s, s:I, s:f, s:f, s:o, s:I, s:I, s:I, s:f, s:f, s:f, s:f, s:f}",
                                 "store", store,
                                 "templates",
                                 (json_int_t)st.templates, "classes", (json_int_t)rep.n_classes, "class_source", source,
                                 "features", (json_int_t)rep.d, "C", rep.C, "gamma", rep.gamma, "cv_accuracy",
                                 rep.cv_accuracy >= 0 ? json_real(rep.cv_accuracy) : json_null(), "support_vectors",
                                 (json_int_t)rep.support_vectors, "exact_classes", (json_int_t)rep.exact_classes,
                                 "augment", (json_int_t)rep.augment, "noise", rep.noise, "weight", rep.weight,
                                 "discriminant_noise", rep.discriminant_noise, "shape_noise",
                                 rep.shape_noise > 0 ? rep.shape_noise : 0.0, "seconds", rep.seconds);
        json_object_set_new(root, "proportions", json_string(rep.canonical ? "canonical" : "body"));
        json_object_set_new(root, "datasets", json_integer(lab.datasets));
        json_object_set_new(root, "mapped_templates", json_integer(lab.mapped));
        json_object_set_new(root, "single_template_classes", json_integer(lab.single));
        char *s = json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
        printf("%s\n", s ? s : "{}");
        free(s);
        json_decref(root);
    } else {
        printf("index        %s: %llu templates, %u classes (%s), %u angles\n", store,
               (unsigned long long)st.templates, rep.n_classes,
               rep.class_source == MIM_CLASSES_KMEANS ? "k-means, no pose labels" : "pose labels", rep.d);
        if (lab.datasets > 1)
            printf("datasets     %u: subjects and poses are each dataset's own%s\n", lab.datasets,
                   lab.mapped ? ", but for the poses the pose map places" : "");
        if (rep.n_classes < 2)
            printf("svm          one class: no SVM needed\n");
        else if (rep.cv_accuracy >= 0)
            printf("svm          C = %g, gamma = %.4g (cross-validation accuracy %.3f), %u support vectors\n", rep.C,
                   rep.gamma, rep.cv_accuracy, rep.support_vectors);
        else
            printf("svm          C = %g, gamma = %.4g (given), %u support vectors\n", rep.C, rep.gamma,
                   rep.support_vectors);
        if (rep.augment)
            printf("augmented    %u noisy copies per template, sigma %g of the landmark radius\n", rep.augment, rep.noise);
        else
            printf("augmented    no (templates only)\n");
        printf("proportions  %s\n", rep.canonical ? "canonical angles: segment directions on the templates' mean lengths"
                                                  : "each body's own");
        if (rep.shape_noise >= 0)
            printf("shape        discriminants over the landmarks, noise levels up to %g of the landmark radius\n",
                   rep.shape_noise);
        if (rep.discriminant_noise > 0)
            printf("angles       discriminants over all angles, trained with noise sigma %g of the landmark radius\n",
                   rep.discriminant_noise);
        if (rep.shape_noise < 0 && !(rep.discriminant_noise > 0))
            printf("discriminant none (frames go to the SVMs)\n");
        print_knn(rep.exact_classes, rep.n_classes);
        printf("built in     %.2f s\n", rep.seconds);
    }
    mim_db_close(&db);
    return 0;
}
