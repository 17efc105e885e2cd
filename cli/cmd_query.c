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
#include <string.h>

/* The answers of a batch, gathered as its frames are read (each frame is
 * queried as soon as the stream hands it over, and forgotten), so that a
 * batch at the 64 MiB cap takes a few bytes a frame, not its text. They
 * are printed once the whole file has proved valid: all or nothing. */
typedef struct answers {
    const mim_query_t *q;
    const mim_index_query_options_t *qo;
    const char *path;
    mim_index_hit_t *scratch; /* k */
    mim_index_answer_t *ans;
    uint32_t n, cap;
    mim_index_hit_t *hits; /* each answer's n_hits, one after the other */
    size_t n_hits, hits_cap;
} answers_t;

static int answer_frame(void *user, const mim_landmark_frame_t *f, mim_error_t *err)
{
    answers_t *a = user;
    mim_index_answer_t an;
    mim_error_t e = {0};
    int rc = mim_query_frame(a->q, f->positions, f->present, a->qo, &an, a->scratch, &e);
    if (rc)
        return mim_error_set(err, rc, "%s: frame %u: %s", a->path, f->index, mim_error_text(&e));
    if (a->n == a->cap) {
        uint32_t cap = a->cap ? 2 * a->cap : 1024;
        mim_index_answer_t *ans = cap > a->cap ? realloc(a->ans, cap * sizeof *ans) : NULL;
        if (!ans)
            return mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %u answers", a->path, a->n + 1);
        a->ans = ans, a->cap = cap;
    }
    if (a->n_hits + an.n_hits > a->hits_cap) {
        size_t cap = a->hits_cap ? 2 * a->hits_cap : 1024;
        while (cap < a->n_hits + an.n_hits)
            cap *= 2;
        mim_index_hit_t *hits = realloc(a->hits, cap * sizeof *hits);
        if (!hits)
            return mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %zu results", a->path, a->n_hits + an.n_hits);
        a->hits = hits, a->hits_cap = cap;
    }
    a->ans[a->n++] = an;
    memcpy(a->hits + a->n_hits, a->scratch, an.n_hits * sizeof *a->hits);
    a->n_hits += an.n_hits;
    return 0;
}

/* {"frames": [...]} as json_dumps(JSON_INDENT(2)) writes it, a frame at a
 * time: the frames' objects indented two levels. */
static int print_json(const answers_t *a)
{
    printf("{\n  \"frames\": [\n");
    const mim_index_hit_t *h = a->hits;
    for (uint32_t i = 0; i < a->n; h += a->ans[i].n_hits, i++) {
        json_t *j = mim_session_answer_json(a->q, &a->ans[i], h);
        char *s = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        json_decref(j);
        if (!s)
            return -1;
        for (const char *line = s, *nl; line; line = nl ? nl + 1 : NULL) {
            nl = strchr(line, '\n');
            printf("    %.*s%s", (int)(nl ? (size_t)(nl - line) : strlen(line)), line, nl ? "\n" : "");
        }
        fputs(i + 1 < a->n ? ",\n" : "\n", stdout);
        free(s);
    }
    printf("  ]\n}\n");
    return 0;
}

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
    answers_t a = {.q = q, .qo = &qo, .path = path, .scratch = calloc(qo.k, sizeof *a.scratch)};
    rc = a.scratch ? mim_landmark_frames_scan_file(path, mim_query_landmark_count(q), 3, answer_frame, &a, &err)
                   : mim_error_set(&err, MIM_ENOMEM, "out of memory for %u results", qo.k);
    if (!rc && as_json && print_json(&a))
        rc = mim_error_set(&err, MIM_ENOMEM, "out of memory for the JSON output");
    if (rc) {
        fprintf(stderr, "mimic query: %s\n", mim_error_text(&err));
        goto done;
    }
    const mim_index_t *ix = mim_query_index(q);
    const mim_index_hit_t *h = a.hits;
    for (uint32_t i = 0; !as_json && i < a.n; h += a.ans[i].n_hits, i++) {
        const mim_index_answer_t *an = &a.ans[i];
        printf("frame %u: class %s (probability %.3f)", i, mim_index_class_name(ix, an->cls), an->probability);
        if (an->missing) printf(", %u landmark%s missing", an->missing, an->missing > 1 ? "s" : "");
        printf("\n");
        for (uint32_t j = 0; j < an->n_hits; j++)
            printf("  %2u. template %-8llu subject %-10s pose %-10s distance %.4f\n", j + 1,
                   (unsigned long long)h[j].id, h[j].subject[0] ? h[j].subject : "-",
                   h[j].pose[0] ? h[j].pose : "-", (double)h[j].distance);
    }
done:
    free(a.scratch), free(a.ans), free(a.hits);
    mim_session_close(&s);
    return rc ? 1 : 0;
}
