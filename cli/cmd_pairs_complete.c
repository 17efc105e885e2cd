/* mimic pairs complete: the joints of pose-pairs that were not seen filled
 * in from samples of the interaction (seed 002's Fig. 12;
 * sample/pair_complete.c). JSON report: schemas/pairs-complete.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_sample.h"
#include "pairs_input.h"

#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CMD "pairs complete"
#define N MIM_PAIR_JOINTS

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic pairs complete --pairs IN.jsonl --missing JOINT[,JOINT...] --samples SAMPLES.jsonl\n"
            "                            -o OUT.jsonl [--k K] [--match pair|person] [--json]\n\n"
            "The joints of each pose-pair of IN that were not seen (--missing: A.head ... B.neck, as the\n"
            "samples format names them) filled in from SAMPLES (seed 002's Fig. 12). Each sample is\n"
            "fitted rigidly onto the seen joints; the K that fit best each place a missing joint by its\n"
            "offsets from the seen joints around it (interaction coordinates: the joints nearest it, of\n"
            "either person, decide), and their answers are blended. IN is in the samples format\n"
            "(schemas/pair-samples.md); the values it gives for the missing joints are not used. OUT:\n"
            "IN with those joints filled, line for line.\n\n"
            "  --missing LIST  the joints to fill, comma-separated (e.g. B.l_elbow,B.l_wrist)\n"
            "  --k K           samples blended (default %d, 1..%d)\n"
            "  --match M       pair (default): match on every seen joint of both people; person: only\n"
            "                  on the missing joints' own person (single-person completion)\n"
            "  --json          a report on stdout (schemas/pairs-complete.schema.json): with IN the true\n"
            "                  pose-pairs (pairs export of motion capture), \"moved_m\" is the error\n\n"
            "Exit status: 0 done, 1 an input failed (files, too few seen joints), 2 bad usage.\n",
            MIM_PAIRS_COMPLETE_DEFAULT_K, MIM_PAIRS_COMPLETE_MAX_K);
}

/* --missing's names into missing[34]: 0, or -1 after printing. */
static int parse_missing(const char *list, uint8_t *missing)
{
    memset(missing, 0, N);
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", list);
    int any = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        /* "A.head" ... "B.neck" */
        const int person = tok[0] == 'A' ? 0 : tok[0] == 'B' ? 1 : -1;
        const int j = person >= 0 && tok[1] == '.' ? mim_sample_joint_index(tok + 2) : -1;
        const int found = person >= 0 && j >= 0 ? person * MIM_PAIR_PERSON_JOINTS + j : -1;
        if (found < 0) {
            fprintf(stderr, "mimic " CMD ": --missing: '%s' is no joint (A.head ... B.neck: mimic pairs complete "
                            "--help)\n", tok);
            return -1;
        }
        missing[found] = 1, any = 1;
    }
    if (!any) {
        fprintf(stderr, "mimic " CMD ": --missing names no joint\n");
        return -1;
    }
    return 0;
}

int mim_cmd_pairs_complete(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"pairs", required_argument, 0, 'i'},   {"missing", required_argument, 0, 'x'},
        {"samples", required_argument, 0, 's'}, {"output", required_argument, 0, 'o'},
        {"k", required_argument, 0, 'k'},       {"match", required_argument, 0, 'M'},
        {"json", no_argument, 0, 'j'},          {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    const char *in_path = NULL, *missing_list = NULL, *samples_path = NULL, *out_path = NULL;
    uint64_t k = MIM_PAIRS_COMPLETE_DEFAULT_K;
    mim_pairs_complete_options_t o = {0};
    int as_json = 0, c;
    optind = 0, opterr = 0;
    while ((c = getopt_long(argc, argv, "i:x:s:o:k:M:jh", longopts, NULL)) != -1) {
        switch (c) {
        case 'i': in_path = optarg; break;
        case 'x': missing_list = optarg; break;
        case 's': samples_path = optarg; break;
        case 'o': out_path = optarg; break;
        case 'j': as_json = 1; break;
        case 'k':
            if (mim_cli_number(CMD, "k", optarg, 1, MIM_PAIRS_COMPLETE_MAX_K, &k)) return 2;
            break;
        case 'M':
            if (strcmp(optarg, "pair") && strcmp(optarg, "person")) {
                fprintf(stderr, "mimic " CMD ": --match '%s': give pair or person\n", optarg);
                return 2;
            }
            o.person_only = !strcmp(optarg, "person");
            break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic " CMD ": unknown or incomplete option '%s' (see mimic " CMD " --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!in_path || !missing_list || !samples_path || !out_path) {
        fprintf(stderr, "mimic " CMD ": --pairs, --missing, --samples and -o are required (see mimic " CMD
                        " --help)\n");
        return 2;
    }
    if (optind < argc) {
        fprintf(stderr, "mimic " CMD ": unexpected argument '%s'\n", argv[optind]);
        return 2;
    }
    uint8_t missing[N];
    if (parse_missing(missing_list, missing)) return 2;
    o.k = (uint32_t)k;
    mim_pairs_samples_t in = {0}, smp = {0};
    double *out = NULL;
    int status = 1;
    if (mim_cli_samples_read(CMD, in_path, &in) || mim_cli_samples_read(CMD, samples_path, &smp)) goto done;
    out = malloc((size_t)in.n * 3 * N * sizeof *out);
    if (!out) {
        fprintf(stderr, "mimic " CMD ": out of memory for %u pose-pairs\n", in.n);
        goto done;
    }
    double moved = 0;
    uint32_t filled = 0;
    for (uint32_t p = 0; p < in.n; p++) {
        const double *q = in.joints + (size_t)p * 3 * N;
        double *r = out + (size_t)p * 3 * N;
        int rc = mim_pairs_complete(smp.joints, smp.n, q, missing, &o, r);
        if (rc) {
            fprintf(stderr, "mimic " CMD ": %s:%ld: %s\n", in_path, in.line ? in.line[p] : (long)p + 2,
                    rc == MIM_EEMPTY      ? "fewer than 3 seen joints to match on"
                    : rc == MIM_ENOTFOUND ? "no sample fits its seen joints"
                                          : "cannot complete it");
            goto done;
        }
        for (int j = 0; j < N; j++)
            if (missing[j]) {
                double d2 = 0;
                for (int a = 0; a < 3; a++) d2 += (r[3 * j + a] - q[3 * j + a]) * (r[3 * j + a] - q[3 * j + a]);
                moved += sqrt(d2), filled++;
            }
    }
    if (mim_cli_pairs_write_samples(CMD, out_path, out, in.log_density, in.n)) goto done;
    const double mean = filled ? moved / filled : 0;
    if (as_json) {
        json_t *j = json_pack("{s:I, s:I, s:I, s:s, s:I, s:f}", "pairs", (json_int_t)in.n, "joints",
                              (json_int_t)(filled / (in.n ? in.n : 1)), "samples", (json_int_t)smp.n, "match",
                              o.person_only ? "person" : "pair", "k", (json_int_t)o.k, "moved_m", mean);
        char *s = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (s) printf("%s\n", s);
        else fprintf(stderr, "mimic " CMD ": cannot make the JSON report\n");
        free(s);
        json_decref(j);
    } else {
        printf("%u pose-pairs, %u joints each filled from %u samples to %s (mean %.3f m from the input's values)\n",
               in.n, filled / (in.n ? in.n : 1), smp.n, out_path, mean);
    }
    status = 0;
done:
    free(out);
    mim_pairs_samples_free(&in);
    mim_pairs_samples_free(&smp);
    return status;
}
