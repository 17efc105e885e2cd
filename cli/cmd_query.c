/* mimic query: the nearest-pose templates of landmark frames (seed 000,
 * §3.3). Input: schemas/landmark-frames.schema.json; JSON output:
 * schemas/query.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_session.h"

#include <getopt.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>

static void help(FILE *out)
{
    fprintf(out, "usage: mimic query --store DIR --landmarks FILE.json [-k K] [--exclude-subject S] [--json]\n\n"
                 "Recognises the pose of each landmark frame in FILE (one frame, or a batch:\n"
                 "schemas/landmark-frames.schema.json, in the order of the store's landmark map)\n"
                 "and prints its class, the class probability and the K nearest templates of\n"
                 "that class (id, subject, pose, distance: L2 over the descriptor angles, radians).\n"
                 "A frame may mark up to 3 landmarks null (lost): the angles that involve them are\n"
                 "left out. Needs the index built by mimic index; warns when it is stale.\n\n"
                 "  --store DIR            the template store\n"
                 "  --landmarks FILE       the landmark frames (JSON)\n"
                 "  -k K                   templates per frame (default 1)\n"
                 "  --exclude-subject S    leave subject S's templates out of the answers (leave-one-subject-out\n"
                 "                         tests); the index's classifier was built with them and still knows\n"
                 "                         S: for a strict test, index a store without S\n"
                 "  --json                 one JSON object on stdout (schemas/query.schema.json)\n"
                 "  -h, --help             this help\n");
}

int mim_cmd_query(int argc, char **argv)
{
    static const struct option longopts[] = {{"store", required_argument, 0, 's'},
                                              {"landmarks", required_argument, 0, 'l'},
                                              {"exclude-subject", required_argument, 0, 'x'},
                                              {"json", no_argument, 0, 'j'},
                                              {"help", no_argument, 0, 'h'},
                                              {0, 0, 0, 0}};
    const char *store = NULL, *path = NULL;
    int as_json = 0, c;
    mim_index_query_options_t qo = {.k = 1};
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:l:k:x:jh", longopts, NULL)) != -1) {
        uint64_t v;
        if (c == 's') store = optarg;
        else if (c == 'l') path = optarg;
        else if (c == 'k') {
            if (mim_cli_number("query", "k", optarg, 1, 10000, &v)) return 2;
            qo.k = (uint32_t)v;
        } else if (c == 'x') qo.exclude_subject = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic query: unknown or incomplete option '%s' (see mimic query --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!store || !path) {
        fprintf(stderr, "mimic query: --store DIR and --landmarks FILE are required (see mimic query --help)\n");
        return 2;
    }
    mim_error_t err = {0};
    mim_session_t *s = NULL;
    mim_session_options_t so;
    mim_cli_session_options(&so, NULL);
    int rc = mim_session_open(&s, store, &so, &err);
    const mim_query_t *q = rc ? NULL : mim_session_query(s);
    if (!rc && !q)
        rc = mim_error_set(&err, MIM_ENOTFOUND, "%s: store has no index (run mimic index)", store);
    if (rc) { /* the command cannot run (docs/reference.md: exit statuses) */
        fprintf(stderr, "mimic query: %s\n", mim_error_text(&err));
        mim_session_close(&s);
        return 2;
    }
    const mim_query_status_t *st = mim_query_get_status(q);
    if (st->stale)
        fprintf(stderr,
                "mimic query: warning: %s: the index is stale (built over %llu templates, the store has %llu; run "
                "mimic index)\n",
                store, (unsigned long long)st->built.templates, (unsigned long long)st->templates);
    mim_landmark_frames_t f = {0};
    rc = mim_landmark_frames_read(path, mim_query_landmark_count(q), 3, &f, &err);
    mim_index_answer_t *ans = NULL;
    mim_index_hit_t *hits = NULL;
    if (!rc) {
        ans = calloc(f.n_frames, sizeof *ans);
        hits = calloc((size_t)f.n_frames * qo.k, sizeof *hits);
        rc = ans && hits ? mim_query_batch(q, &f, &qo, ans, hits, &err) : MIM_ENOMEM;
    }
    if (rc) {
        fprintf(stderr, "mimic query: %s\n", mim_error_text(&err));
        goto done;
    }
    const mim_index_t *ix = mim_query_index(q);
    json_t *frames = as_json ? json_array() : NULL;
    for (uint32_t i = 0; i < f.n_frames; i++) {
        const mim_index_answer_t *a = &ans[i];
        const mim_index_hit_t *h = hits + (size_t)i * qo.k;
        const char *cls = mim_index_class_name(ix, a->cls);
        if (as_json) {
            json_array_append_new(frames, mim_session_answer_json(q, a, h));
        } else {
            printf("frame %u: class %s (probability %.3f)", i, cls, a->probability);
            if (a->missing) printf(", %u landmark%s missing", a->missing, a->missing > 1 ? "s" : "");
            printf("\n");
            for (uint32_t j = 0; j < a->n_hits; j++)
                printf("  %2u. template %-8llu subject %-10s pose %-10s distance %.4f\n", j + 1,
                       (unsigned long long)h[j].id, h[j].subject[0] ? h[j].subject : "-",
                       h[j].pose[0] ? h[j].pose : "-", (double)h[j].distance);
        }
    }
    if (as_json) {
        json_t *root = json_pack("{s:o}", "frames", frames);
        char *s = json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
        printf("%s\n", s ? s : "{}");
        free(s);
        json_decref(root);
    }
done:
    free(ans), free(hits);
    mim_landmark_frames_free(&f);
    mim_session_close(&s);
    return rc ? 1 : 0;
}
