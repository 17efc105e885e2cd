/* mimic pairs templates: sampled pose-pairs become templates (issue 14).
 * The work is session/'s (mim_session_pairs.h: each person's landmarks,
 * its transfer, the store and the index); here the options, the inputs
 * opened, the steps called in order, and what they say printed. JSON
 * report: schemas/pairs-templates.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_sample.h"
#include "mim_session.h"
#include "mim_index.h"
#include "mim_query.h"
#include "mim_session_pairs.h"
#include "output.h"
#include "pairs_input.h"

#include <getopt.h>
#include <jansson.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CMD "pairs templates"

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic pairs templates --store DIR --samples SAMPLES.jsonl --avatar ID [--max N]\n"
            "                             [--person a|b|both] [--proportions avatar|sample]\n"
            "                             [--pose-label class|sample [--label-prefix P]] [--json]\n\n"
            "Sampled pose-pairs become templates of the store. For each sample of SAMPLES\n"
            "(schemas/pair-samples.md; metres, +Y up) and each person in it, the person's joints\n"
            "give the store's landmarks (matched by name: head, chest, ..., spine, neck), which\n"
            "pose the avatar as mimic transfer --landmarks does (its default drive: the nearest\n"
            "templates' frames where relative transfer holds, else the avatar's own turned by its\n"
            "landmark skeleton; the landmarks held). Each result is stored as a new template:\n"
            "subject the avatar's, source sampled:SAMPLES:LINE:PERSON (e.g. sampled:/data/s.jsonl:12:a:\n"
            "line 12, person a),\n"
            "pose label the pose class the index gives the person (see --pose-label). All of them\n"
            "are committed in one transaction, then the recognition index is rebuilt (with the same\n"
            "number of angles), so that mimic query recognises the new poses.\n\n"
            "Before the transfer each person is turned about +Y to face the avatar's way (its\n"
            "hips and shoulders) and moved onto the avatar (the centres of their landmarks\n"
            "coincide); with --proportions avatar (default) each segment of the landmark skeleton\n"
            "keeps the sample's direction and takes the avatar's length (joints of a motion\n"
            "capture skeleton are not the avatar's surface landmarks; as mimic transfer --template\n"
            "does); sample holds the sample's joints as they are.\n\n"
            "  --store DIR           the template store; it needs its index (mimic index)\n"
            "  --samples FILE        pose-pair samples, JSON lines (mimic pairs sample, pairs export)\n"
            "  --avatar ID           the template (mimic list) that takes each sampled pose\n"
            "  --max N               the first N samples (default: all)\n"
            "  --person a|b|both     which person of each sample (default both)\n"
            "  --proportions WHICH   avatar (default) or sample (above)\n"
            "  --pose-label WHICH    class (default): the pose class the index gives the person's\n"
            "                        own joints (its nearest template's pose label; none in a store\n"
            "                        whose index clusters by k-means), so that a sampled pose joins\n"
            "                        the class it resembles; sample: P LINE-PERSON (sampled-12-a),\n"
            "                        one pose class per person: the index then trains an SVM for\n"
            "                        each, which is slow and recognises such one-template classes\n"
            "                        poorly (a query often lands in an old class)\n"
            "  --label-prefix P      P for --pose-label sample (default \"sampled-\"; up to %d\n"
            "                        printable characters, no space or '/'); implies it\n"
            "  --json                {\"templates\": n, \"ids\": [...], \"duplicates\": d, \"seconds\": s}\n"
            "                        on stdout (schemas/pairs-templates.schema.json)\n"
            "  -h, --help            this help\n\n"
            "A result equal to a stored template is not stored twice (counted as a duplicate).\n"
            "With --pose-label class, a person whose own joints the rebuilt index puts in another\n"
            "class than its label takes that class, and the index is built again (up to 6 times).\n"
            "Afterwards each new template is looked for again with its sample's own joints: a warning\n"
            "(and --json's not_found_again) names those mimic query answers with another template, and\n"
            "why. The index of a store of the 16 default landmarks sees every body on canonical\n"
            "proportions, so the avatar's bone lengths do not hide a person; the rebuilt index can\n"
            "still put one in another pose class than the one it gave it before it joined (over\n"
            "another landmark map, --proportions avatar can also make it miss among like samples).\n"
            "Nothing is stored unless every selected person is transferred.\n"
            "Exit status: 0 done, 1 an input failed (the samples file, a sample's landmarks, an\n"
            "unknown avatar id, a transfer), 2 bad usage or the command could not run (the store,\n"
            "its index).\n",
            MIM_SESSION_PAIRS_PREFIX_MAX);
}

/* Whether name (an index class, "dataset/label" in a store of several
 * datasets) is label. */
static int class_is(const char *name, const char *label)
{
    const size_t n = strlen(name), l = strlen(label);
    return n >= l && !strcmp(name + n - l, label) && (n == l || name[n - l - 1] == '/');
}

/* Whether each stored person is found again by its own joints: the
 * rebuilt index's nearest template to the sample's joints (as they are,
 * the sample's proportions) should be the one stored from them. The index
 * sees canonical proportions (a store of the 16 default landmarks), so the
 * avatar's bone lengths do not move the person away from its sample; what
 * can is the class: the person's pose label is the class the index gave
 * its joints before it joined, and the index rebuilt with it may put the
 * same joints in another class (its discriminants are learnt from every
 * template, the new ones too), whose nearest template is then another.
 * Counts the people found into *found and lists the others in miss (JSON
 * objects, why: "class" or "nearer", another template of its own class
 * nearer; *other_class counts the first) and whether the index sees
 * canonical proportions into *canonical; -1 when the store cannot be read
 * back (not an error of the command). */
static int check_found(const char *store, const mim_pairs_samples_t *smp, const mim_session_pairs_t *p,
                       const char *prefix, uint32_t *found, uint32_t *other_class, int *canonical, json_t *miss)
{
    mim_error_t err = {0};
    mim_session_t *s = NULL;
    mim_session_options_t so;
    mim_cli_session_options(&so, NULL);
    const mim_query_t *q = mim_session_open(&s, store, &so, &err) ? NULL : mim_session_query(s);
    const mim_landmark_map_t *map = s ? mim_session_map(s) : NULL;
    int rc = q && map ? 0 : -1;
    *found = *other_class = 0;
    mim_index_info_t info = {0};
    if (q) mim_index_get_info(mim_query_index(q), &info);
    *canonical = (int)info.canonical;
    const uint32_t n = mim_session_pairs_count(p, NULL);
    for (uint32_t i = 0; i < n && !rc; i++) {
        mim_session_pairs_person_t pp;
        if (mim_session_pairs_person(p, i, &pp)) {
            rc = -1;
            break;
        }
        if (!pp.id) continue; /* a duplicate: stored before, under another source */
        /* the person's joints by the map's names, as the sample holds them */
        const double *joints = smp->joints + (size_t)pp.sample * 3 * MIM_PAIR_JOINTS +
                               (pp.person == 'b' ? 3 * MIM_PAIR_PERSON_JOINTS : 0);
        float lm[3 * MIM_LANDMARKS_MAX];
        for (uint32_t l = 0; l < map->count && !rc; l++) {
            const int j = mim_sample_joint_index(map->names[l]);
            if (j < 0) rc = -1;
            for (int c = 0; c < 3 && !rc; c++) lm[3 * l + c] = (float)joints[3 * j + c];
        }
        mim_index_query_options_t qo = {.k = 1};
        mim_index_answer_t ans;
        mim_index_hit_t hit;
        if (rc || mim_index_query(mim_query_index(q), lm, NULL, &qo, &ans, &hit, &err) || !ans.n_hits) {
            rc = -1;
            break;
        }
        if (hit.id == pp.id) {
            (*found)++;
        } else {
            char who[2] = {pp.person, 0}, label[MIM_SESSION_PAIRS_PREFIX_MAX + 32];
            if (prefix) snprintf(label, sizeof label, "%s%ld-%c", prefix, pp.line, pp.person);
            const char *answered = mim_index_class_name(mim_query_index(q), ans.cls);
            const int same = class_is(answered, prefix ? label : pp.pose_class);
            *other_class += !same;
            json_array_append_new(miss, json_pack("{s:I, s:I, s:s, s:I, s:f, s:s, s:s}", "id", (json_int_t)pp.id,
                                                  "line", (json_int_t)pp.line, "person", who, "nearest",
                                                  (json_int_t)hit.id, "distance", (double)hit.distance, "why",
                                                  same ? "nearer" : "class", "class", answered));
        }
    }
    mim_session_close(&s);
    return rc;
}

/* The store, read-only, with its index, and landmarks that pose-pair
 * samples give (all but the store's own failures are the command's:
 * checked before the samples are read). Returns an exit status. */
static int open_store(const char *store, mim_session_t **s)
{
    mim_error_t err = {0};
    mim_session_options_t so;
    mim_cli_session_options(&so, NULL);
    int rc = mim_session_open(s, store, &so, &err);
    if (!rc) rc = mim_session_pairs_check(*s, &err);
    if (rc) { /* the command cannot run (docs/reference.md: exit statuses) */
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
        mim_session_close(s);
        return 2;
    }
    return 0;
}

int mim_cmd_pairs_templates(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'},        {"samples", required_argument, 0, 'S'},
        {"avatar", required_argument, 0, 'a'},       {"max", required_argument, 0, 'n'},
        {"person", required_argument, 0, 'p'},       {"proportions", required_argument, 0, 'P'},
        {"pose-label", required_argument, 0, 'L'},   {"label-prefix", required_argument, 0, 'l'},
        {"json", no_argument, 0, 'j'},               {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    const char *store = NULL, *samples_path = NULL, *avatar = NULL, *prefix = NULL; /* NULL: the class */
    int by_sample = -1; /* --pose-label: -1 not given, 0 class, 1 sample */
    uint64_t max = 0, avatar_id = 0; /* max 0: all */
    unsigned persons = 0;            /* 0: both */
    int as_json = 0, retarget = 1, c;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:S:a:n:p:P:L:l:jh", longopts, NULL)) != -1) {
        switch (c) {
        case 's': store = optarg; break;
        case 'S': samples_path = optarg; break;
        case 'a': avatar = optarg; break;
        case 'n':
            if (mim_cli_number(CMD, "max", optarg, 1, MIM_PAIRS_SAMPLES_MAX, &max)) return 2;
            break;
        case 'p':
            if (!strcmp(optarg, "a")) persons = MIM_SESSION_PAIRS_PERSON_A;
            else if (!strcmp(optarg, "b")) persons = MIM_SESSION_PAIRS_PERSON_B;
            else if (!strcmp(optarg, "both")) persons = 0;
            else {
                fprintf(stderr, "mimic " CMD ": --person '%s': use a, b or both\n", optarg);
                return 2;
            }
            break;
        case 'P':
            if (!strcmp(optarg, "avatar")) retarget = 1;
            else if (!strcmp(optarg, "sample")) retarget = 0;
            else {
                fprintf(stderr, "mimic " CMD ": --proportions '%s': use avatar or sample\n", optarg);
                return 2;
            }
            break;
        case 'L':
            if (!strcmp(optarg, "class")) by_sample = 0;
            else if (!strcmp(optarg, "sample")) by_sample = 1;
            else {
                fprintf(stderr, "mimic " CMD ": --pose-label '%s': use class or sample\n", optarg);
                return 2;
            }
            break;
        case 'l':
            if (!mim_session_pairs_prefix_ok(optarg)) {
                fprintf(stderr, "mimic " CMD ": --label-prefix '%s': at most %d printable characters, no space or "
                                "'/'\n", optarg, MIM_SESSION_PAIRS_PREFIX_MAX);
                return 2;
            }
            prefix = optarg;
            break;
        case 'j': as_json = 1; break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic " CMD ": unknown or incomplete option '%s' (see mimic " CMD " --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "mimic " CMD ": unexpected argument '%s' (see mimic " CMD " --help)\n", argv[optind]);
        return 2;
    }
    if (!store || !samples_path || !avatar) {
        fprintf(stderr, "mimic " CMD ": --store, --samples and --avatar are required (see mimic " CMD " --help)\n");
        return 2;
    }
    if (prefix && !by_sample) {
        fprintf(stderr, "mimic " CMD ": --label-prefix is for --pose-label sample, not class\n");
        return 2;
    }
    if (by_sample == 1 && !prefix) prefix = "sampled-";
    if (mim_cli_template_id(CMD, "avatar", avatar, &avatar_id)) return 2;

    const double t0 = mim_now();
    mim_session_t *s = NULL;
    if (open_store(store, &s)) return 2;
    mim_error_t err = {0};
    char real[PATH_MAX];
    mim_pairs_samples_t smp = {0};
    if (mim_cli_samples_read(CMD, samples_path, &smp)) {
        mim_session_close(&s);
        return 1;
    }
    const char *samples_real = realpath(samples_path, real) ? real : samples_path;
    mim_progress_t pr = {.fn = mim_cli_progress};
    const mim_session_pairs_options_t po = {.max = (uint32_t)max, .persons = persons, .sample_proportions = !retarget,
                                            .origin = samples_path, .progress = &pr};
    mim_session_pairs_t *p = NULL;
    int status = 1, rc;
    if ((rc = mim_session_load_avatar(s, avatar, &err))) {
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
    } else if ((rc = mim_session_pairs_prepare(s, &smp, &po, &p, &err)) ||
               (rc = mim_session_pairs_transfer(s, p, &err))) {
        fprintf(stderr, "mimic " CMD ": %s%s\n", mim_error_text(&err),
                rc == MIM_EUNSUPPORTED && !p ? " (use --proportions sample)" : ""); /* retargeting needs the 16 */
        status = rc == MIM_EIO || rc == MIM_ENOMEM ? 2 : 1; /* the system's, or an input's */
    }
    mim_session_close(&s); /* before the store is opened for writing: one environment at a time */
    if (rc) goto done;

    /* the store's failures and the system's: 2 */
    const mim_db_options_t rw = mim_cli_db_options(0);
    const mim_session_pairs_store_options_t sto = {.avatar_id = avatar_id, .source = samples_real,
                                                   .label_prefix = prefix, .db = &rw};
    mim_session_pairs_report_t rep;
    if ((rc = mim_session_pairs_store(p, store, &sto, &rep, &err))) {
        fprintf(stderr, "mimic " CMD ": %s\n", mim_error_text(&err));
        status = 2;
        goto done;
    }
    status = 0;
    const double seconds = mim_now() - t0;
    const uint32_t added = rep.added, dup = rep.duplicates;
    /* each stored person found again by its own joints? (duplicates were stored before: not theirs to find) */
    json_t *miss = json_array();
    uint32_t found = 0, other_class = 0;
    int canonical = 0;
    const int checked = miss && check_found(store, &smp, p, prefix, &found, &other_class, &canonical, miss) == 0;
    if (checked && found < added) {
        fprintf(stderr,
                "mimic " CMD ": warning: %u of %u sampled people are not found again by their own joints (mimic "
                "query answers another template; --json lists them)",
                added - found, added);
        if (other_class)
            fprintf(stderr, "; %u in another pose class than the one the index gave them before they joined it",
                    other_class);
        if (retarget && !canonical) /* an index of another landmark map sees the avatar's bone lengths */
            fprintf(stderr, "; their templates hold the avatar's proportions, not the sample's; --proportions sample "
                            "keeps the sample's");
        fprintf(stderr, "\n");
    }
    if (as_json) {
        json_t *arr = json_array();
        for (uint32_t i = 0; arr && i < added; i++) json_array_append_new(arr, json_integer((json_int_t)rep.ids[i]));
        json_t *j = arr ? json_pack("{s:I, s:o, s:I, s:f}", "templates", (json_int_t)added, "ids", arr, "duplicates",
                                    (json_int_t)dup, "seconds", seconds)
                        : NULL;
        if (j) json_object_set_new(j, "relabelled", json_integer((json_int_t)rep.relabelled));
        if (j && checked) {
            json_object_set_new(j, "found_again", json_integer((json_int_t)found));
            json_object_set(j, "not_found_again", miss);
        }
        char *txt = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (txt) printf("%s\n", txt);
        else fprintf(stderr, "mimic " CMD ": cannot make the JSON report (out of memory)\n"), status = 1;
        free(txt);
        json_decref(j);
    } else {
        uint32_t n_samples;
        mim_session_pairs_count(p, &n_samples);
        printf("pairs templates: %u template%s from %u sample%s of %s", added, added == 1 ? "" : "s", n_samples,
               n_samples == 1 ? "" : "s", samples_path);
        if (added) printf(" (ids %llu..%llu)", (unsigned long long)rep.ids[0], (unsigned long long)rep.ids[added - 1]);
        if (dup) printf(", %u already stored", dup);
        printf(" in %.2f s; index rebuilt: %u classes, %u angles", seconds, rep.index.n_classes, rep.index.d);
        if (rep.relabelled) printf(" (%u labels moved to the class it gives their joints)", rep.relabelled);
        printf("\n");
    }
    json_decref(miss);
done:
    mim_session_close(&s);
    mim_session_pairs_free(&p);
    mim_pairs_samples_free(&smp);
    return status;
}
