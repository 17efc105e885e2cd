/* mimic pairs: seed 002's pose-pairs (issue 14): coverage (eq. 13) of true
 * pose-pairs by samples, the export of a take's pose-pairs in the samples
 * format, and 2D annotations; sample (cmd_pairs_sample.c) and templates
 * (cmd_pairs_templates.c) have files of their own. */
#include "args.h"
#include "commands.h"
#include "mim_sample.h"
#include "output.h"
#include "pairs_input.h"

#include <getopt.h>
#include <math.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic pairs coverage --truth A.bvh,B.bvh [--truth ...] [--every N] [--offset K]\n"
            "                            --samples SAMPLES.jsonl [--measures LIST] [--threads N]\n"
            "                            [--joint-map FILE.json] [--unit M] [--up AXIS] [--json]\n"
            "       mimic pairs export --pair A.bvh,B.bvh [--pair ...] [--every N] [--offset K]\n"
            "                          [--joint-map FILE.json] [--unit M] [--up AXIS] -o FRAMES.jsonl\n"
            "       mimic pairs annotate --pair A.bvh,B.bvh [--pair ...] [--every N] [--offset K] [--views V]\n"
            "                            [--video] [--noise-px P] [--seed S] [--joint-map FILE.json] [--unit M]\n"
            "                            [--up AXIS] -o ANN.json [--cameras CAMS.json]\n"
            "       mimic pairs sample --prior A.bvh,B.bvh ... -o SAMPLES.jsonl   (mimic pairs sample --help)\n"
            "       mimic pairs templates --store DIR --samples SAMPLES.jsonl --avatar ID ...\n"
            "                                                            (mimic pairs templates --help)\n"
            "       mimic pairs retrieve --annotations ANN.json --samples SAMPLES.jsonl -o LIFTED.jsonl ...\n"
            "                                                            (mimic pairs retrieve --help)\n"
            "       mimic pairs complete --pairs IN.jsonl --missing JOINTS --samples SAMPLES.jsonl -o OUT.jsonl\n"
            "                                                            (mimic pairs complete --help)\n\n"
            "Two-person pose-pairs (seed 002, Yin et al.). A pose-pair is two people's 17 joints each\n"
            "(the 16 landmarks and the neck) in one world frame, read from the two motion files of one\n"
            "take with the root translation kept; joints are found by their names (CMU/Biovision,\n"
            "MakeHuman, ASF, short lower-case) or by --joint-map, a JSON object from mimic's joint names\n"
            "(head, chest, pelvis, l_shoulder, ..., neck) to the file's.\n\n"
            "  coverage   C(G, S) of eq. 13: the mean over the true pose-pairs G (frames offset,\n"
            "             offset + every, ... of each --truth take) of the distance to the nearest\n"
            "             sample of S (schemas/pair-samples.md), in D_I (interaction coordinates, eq. 8,\n"
            "             3D), D_C (joint RMS) and D_S (3D shape contexts), each after a rigid alignment\n"
            "             (metres for D_I and D_C), and limbs: the mean distance of each person's 12\n"
            "             limb joints (shoulders, elbows, wrists, hips, knees, ankles) after a rigid\n"
            "             fit over those joints, the better of the two orders of the people (metres).\n"
            "             Exact: a distance is skipped only where a lower bound proves that sample\n"
            "             cannot be the nearest.\n\n"
            "  export     the pose-pairs of takes (frames offset, offset + every, ...) in the samples\n"
            "             format, log density null: motion capture to compare samples with, or to\n"
            "             measure what the capture itself covers.\n\n"
            "  annotate   2D annotations the way a person clicks them on photos: every N-th frame\n"
            "             (default 10) from K on, seen by V random perspective cameras each (default 1;\n"
            "             3 to 8 m away, any side, -10 to 35 degrees up, 1920 x 1080 pixels, focal\n"
            "             length 1000 to 1800 pixels, the whole pair in view), with Gaussian pixel\n"
            "             noise of P pixels (default 2) on every joint\n"
            "             (schemas/pair-annotations.schema.json); the true cameras go to --cameras\n"
            "             (schemas/pair-cameras.schema.json). --video: each view is one camera's video\n"
            "             of the take instead, which follows the pair at its distance and direction (a\n"
            "             frame it cannot see whole starts a new shot with a new camera); the sampler\n"
            "             takes its proposal's motion (eq. 12) from consecutive frames of a shot.\n"
            "             The same --seed gives the same bytes.\n\n"
            "  sample     3D pose-pairs lifted from annotations by MCMC sampling (Sections 3-5).\n\n"
            "  templates  sampled people as templates of a store, so that mimic query knows their poses.\n\n"
            "  retrieve   a 3D pose-pair for each 2D annotation: the sample that projects onto it best.\n\n"
            "  complete   the joints of pose-pairs that were not seen, filled in from the samples.\n\n"
            "  --every N          every N-th frame (default 1; annotate: 10)\n"
            "  --offset K         from frame K (default 0)\n"
            "  --unit M           metres per file unit (default: guessed from the people's size)\n"
            "  --up AXIS          the files' up axis, x, y, z, -x, -y or -z (default: found per take, the\n"
            "                     head above the feet in the rest pose, else over the frames, and said);\n"
            "                     pose-pairs are turned to mimic's y up as they are read\n"
            "  --threads N        coverage: threads (default: one per core)\n"
            "  --measures LIST    coverage: some of D_I,D_C,D_S,limbs, comma-separated (default: all four)\n"
            "  --json             {\"truth\": m, \"samples\": n, \"D_I\": ..., \"D_C\": ..., \"D_S\": ...,\n"
            "                     \"limbs\": ...}: the measures asked for\n"
            "  -h, --help         this help\n\n"
            "Exit status: 0 done, 1 an input failed (a motion file, joints, samples), 2 bad usage.\n");
}

/* --measures D_I,limbs,...: which of label[] to compute */
static int measures(const char *list, const char *const label[4], int want[4])
{
    memset(want, 0, 4 * sizeof *want);
    for (const char *p = list;;) {
        size_t n = strcspn(p, ",");
        int k = 0;
        while (k < 4 && !(strlen(label[k]) == n && !strncmp(p, label[k], n))) k++;
        if (k == 4) {
            fprintf(stderr, "mimic pairs coverage: --measures '%s': '%.*s' is not D_I, D_C, D_S or limbs\n", list, (int)n, p);
            return -1;
        }
        want[k] = 1;
        if (!p[n]) return 0;
        p += n + 1;
    }
}

static int coverage(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"truth", required_argument, 0, 'p'},     {"every", required_argument, 0, 'e'},
        {"offset", required_argument, 0, 'k'},    {"samples", required_argument, 0, 's'},
        {"joint-map", required_argument, 0, 'm'}, {"unit", required_argument, 0, 'u'}, {"up", required_argument, 0, MIM_CLI_OPT_UP},
        {"json", no_argument, 0, 'j'},            {"threads", required_argument, 0, 't'},
        {"measures", required_argument, 0, 'M'},  {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    static const char *const label[4] = {"D_I", "D_C", "D_S", "limbs"};
    int want[4] = {1, 1, 1, 1};
    const char *samples_path = NULL;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    uint64_t threads = cores > 0 ? (uint64_t)cores : 1;
    mim_cli_takes_t tk = {.cmd = "pairs coverage", .every = 1};
    int as_json = 0, c, taken;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "p:e:k:s:m:u:jt:M:h", longopts, NULL)) != -1) {
        if ((taken = mim_cli_takes_option(&tk, c, optarg))) {
            if (taken < 0) return 2;
            continue;
        }
        switch (c) {
        case 's': samples_path = optarg; break;
        case 'j': as_json = 1; break;
        case 'M':
            if (measures(optarg, label, want)) return 2;
            break;
        case 't':
            if (mim_cli_number("pairs coverage", "threads", optarg, 1, 256, &threads)) return 2;
            break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic pairs coverage: unknown or incomplete option '%s' (see mimic pairs --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!tk.n || !samples_path) {
        fprintf(stderr, "mimic pairs coverage: --truth A,B and --samples FILE are required (see mimic pairs --help)\n");
        return 2;
    }
    if (optind < argc) {
        fprintf(stderr, "mimic pairs coverage: unexpected argument '%s'\n", argv[optind]);
        return 2;
    }
    if (mim_cli_takes_begin(&tk)) return 1;
    mim_error_t err = {0};
    /* the true pose-pairs and the samples, prepared with what the measures read of each */
    unsigned parts_a = 0, parts_b = 0;
    for (int k = 0; k < 4; k++)
        if (want[k])
            parts_a |= mim_sample_metric_parts((mim_sample_metric_t)k, 0), parts_b |= mim_sample_metric_parts((mim_sample_metric_t)k, 1);
    mim_pair_prep_t *g = NULL, *sp = NULL;
    uint32_t m = 0;
    int status = 1;
    mim_pairs_samples_t smp = {0};
    for (int t = 0; t < tk.n; t++) {
        double *fr = NULL;
        uint32_t nf = 0;
        if (mim_cli_takes_read(&tk, t, &fr, &nf)) goto done;
        mim_pair_prep_t *grown = realloc(g, (size_t)(m + nf) * sizeof *g);
        if (!grown) {
            free(fr);
            fprintf(stderr, "mimic pairs coverage: out of memory\n");
            goto done;
        }
        g = grown;
        uint32_t bad = 0;
        if (mim_pair_prepare_many(fr, nf, (uint32_t)threads, parts_a, g + m, &bad, &err)) {
            fprintf(stderr, "mimic pairs coverage: %s: frame %u: %s\n", tk.spec[t], (unsigned)(tk.offset + bad * tk.every),
                    mim_error_text(&err));
            free(fr);
            goto done;
        }
        m += nf;
        free(fr);
    }
    if (mim_cli_samples_read("pairs coverage", samples_path, &smp)) goto done;
    sp = malloc((size_t)smp.n * sizeof *sp);
    if (!sp) {
        fprintf(stderr, "mimic pairs coverage: out of memory for %u samples\n", smp.n);
        goto done;
    }
    uint32_t bad = 0;
    if (mim_pair_prepare_many(smp.joints, smp.n, (uint32_t)threads, parts_b, sp, &bad, &err)) {
        fprintf(stderr, "mimic pairs coverage: %s: sample %u: %s\n", samples_path, bad + 1, mim_error_text(&err));
        goto done;
    }
    /* the measures in one pass: D_I and D_S share the samples they align */
    double cov[4];
    mim_sample_metric_t asked[4];
    mim_sample_coverage_t res[4] = {{0}};
    uint32_t n_asked = 0;
    for (int k = 0; k < 4; k++)
        if (want[k]) asked[n_asked++] = (mim_sample_metric_t)k;
    mim_progress_t pr = {.fn = mim_cli_progress};
    const mim_sample_coverage_options_t o = {.threads = (uint32_t)threads, .progress = &pr};
    if (mim_sample_coverage_many(g, m, sp, smp.n, asked, n_asked, &o, res, &err)) {
        fprintf(stderr, "mimic pairs coverage: %s\n", mim_error_text(&err));
        goto done;
    }
    for (uint32_t q = 0; q < n_asked; q++) cov[asked[q]] = res[q].coverage;
    if (as_json) {
        json_t *j = json_pack("{s:I, s:I}", "truth", (json_int_t)m, "samples", (json_int_t)smp.n);
        for (int k = 0; k < 4 && j; k++)
            if (want[k]) json_object_set_new(j, label[k], json_real(cov[k]));
        char *out = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (!out) {
            fprintf(stderr, "mimic pairs coverage: cannot make the JSON report\n");
            json_decref(j);
            goto done;
        }
        printf("%s\n", out);
        free(out);
        json_decref(j);
    } else {
        printf("coverage of %u true pose-pairs by %u samples:", m, smp.n);
        for (int k = 0; k < 4; k++)
            if (want[k]) printf(" %s %.4f%s", label[k], cov[k], k == 2 ? "" : " m");
        printf("\n");
    }
    status = 0;
done:
    free(g), free(sp), free(tk.map_text);
    mim_pairs_samples_free(&smp);
    return status;
}

static int export_pairs(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"pair", required_argument, 0, 'p'},      {"every", required_argument, 0, 'e'},
        {"offset", required_argument, 0, 'k'},    {"output", required_argument, 0, 'o'},
        {"joint-map", required_argument, 0, 'm'}, {"unit", required_argument, 0, 'u'}, {"up", required_argument, 0, MIM_CLI_OPT_UP},
        {"help", no_argument, 0, 'h'},            {0, 0, 0, 0},
    };
    const char *outp = NULL;
    mim_cli_takes_t tk = {.cmd = "pairs export", .every = 1};
    int c, taken;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "p:e:k:o:m:u:h", longopts, NULL)) != -1) {
        if ((taken = mim_cli_takes_option(&tk, c, optarg))) {
            if (taken < 0) return 2;
            continue;
        }
        switch (c) {
        case 'o': outp = optarg; break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic pairs export: unknown or incomplete option '%s' (see mimic pairs --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!tk.n || !outp || optind < argc) {
        fprintf(stderr, "mimic pairs export: --pair A,B and -o FILE are required, and nothing else (see mimic pairs --help)\n");
        return 2;
    }
    if (mim_cli_takes_begin(&tk)) return 1;
    double *frames = NULL;
    uint32_t total = 0;
    int status = 1;
    if (mim_cli_takes_read_all(&tk, &frames, &total) ||
        mim_cli_pairs_write_samples("pairs export", outp, frames, NULL, total))
        goto done;
    fprintf(stderr, "mimic pairs export: %u pose-pairs to %s\n", total, outp);
    status = 0;
done:
    free(frames), free(tk.map_text);
    return status;
}

static int annotate(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"pair", required_argument, 0, 'p'},      {"every", required_argument, 0, 'e'},
        {"offset", required_argument, 0, 'k'},    {"views", required_argument, 0, 'v'},
        {"noise-px", required_argument, 0, 'n'},  {"seed", required_argument, 0, 'S'},
        {"output", required_argument, 0, 'o'},    {"cameras", required_argument, 0, 'c'},
        {"joint-map", required_argument, 0, 'm'}, {"unit", required_argument, 0, 'u'}, {"up", required_argument, 0, MIM_CLI_OPT_UP},
        {"video", no_argument, 0, 'V'},           {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    const char *outp = NULL, *cams_path = NULL;
    int video = 0;
    mim_cli_takes_t tk = {.cmd = "pairs annotate", .every = 10};
    int c, taken;
    uint64_t views = 1, seed = 1;
    double noise = 2.0;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "p:e:k:v:n:S:o:c:m:u:Vh", longopts, NULL)) != -1) {
        if ((taken = mim_cli_takes_option(&tk, c, optarg))) {
            if (taken < 0) return 2;
            continue;
        }
        switch (c) {
        case 'v':
            if (mim_cli_number("pairs annotate", "views", optarg, 1, MIM_PAIRS_ANNOTATE_MAX_VIEWS, &views)) return 2;
            break;
        case 'n':
            if (mim_cli_real("pairs annotate", "noise-px", optarg, 0.0, 1000.0, 0, "is not a number of pixels in 0..1000", &noise))
                return 2;
            break;
        case 'S':
            if (mim_cli_number("pairs annotate", "seed", optarg, 0, UINT64_MAX, &seed)) return 2;
            break;
        case 'o': outp = optarg; break;
        case 'c': cams_path = optarg; break;
        case 'V': video = 1; break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic pairs annotate: unknown or incomplete option '%s' (see mimic pairs --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!tk.n || !outp || optind < argc) {
        fprintf(stderr, "mimic pairs annotate: --pair A,B and -o FILE are required, and nothing else (see mimic pairs --help)\n");
        return 2;
    }
    if (mim_cli_takes_begin(&tk)) return 1;
    char *ann_text = NULL, *cam_text = NULL;
    mim_pairs_annotations_t a = {0};
    mim_pairs_camera_t *cams = NULL;
    const mim_pairs_annotate_options_t opt = {(uint32_t)views, video, noise, seed};
    uint32_t shots = 0;
    int status = 1;
    for (int t = 0; t < tk.n; t++) {
        double *fr = NULL;
        uint32_t nf = 0, bad = 0;
        if (mim_cli_takes_read(&tk, t, &fr, &nf)) goto done;
        int rc = mim_pairs_annotate_take(fr, nf, (uint32_t)tk.offset, (uint32_t)tk.every, (uint32_t)t, &opt, &a, &cams,
                                         &shots, &bad);
        free(fr);
        if (rc == MIM_ENOTFOUND)
            fprintf(stderr, "mimic pairs annotate: %s: frame %u: no camera sees both people whole\n", tk.spec[t], bad);
        else if (rc)
            fprintf(stderr, "mimic pairs annotate: %s at %u annotations\n",
                    rc == MIM_ENOMEM ? "out of memory" : "too many annotations", a.n);
        if (rc) goto done;
    }
    ann_text = mim_pairs_annotations_json(&a, tk.spec, (uint32_t)tk.n);
    cam_text = cams_path ? mim_pairs_cameras_json(&a, cams) : NULL;
    if (!ann_text || (cams_path && !cam_text)) {
        fprintf(stderr, "mimic pairs annotate: cannot make the JSON (out of memory, or a path that is not UTF-8)\n");
        goto done;
    }
    /* the cameras first: a failure then leaves the annotations as they were */
    if ((cams_path && mim_cli_pairs_write("pairs annotate", cams_path, cam_text, strlen(cam_text))) ||
        mim_cli_pairs_write("pairs annotate", outp, ann_text, strlen(ann_text)))
        goto done;
    fprintf(stderr, "mimic pairs annotate: %u annotations (%llu views of %u frames) to %s\n", a.n,
            (unsigned long long)views, (unsigned)(a.n / views), outp);
    status = 0;
done:
    mim_pairs_annotations_free(&a);
    free(cams), free(ann_text), free(cam_text), free(tk.map_text);
    return status;
}

int mim_cmd_pairs(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) {
        help(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (!strcmp(argv[1], "coverage")) return coverage(argc - 1, argv + 1);
    if (!strcmp(argv[1], "export")) return export_pairs(argc - 1, argv + 1);
    if (!strcmp(argv[1], "annotate")) return annotate(argc - 1, argv + 1);
    if (!strcmp(argv[1], "sample")) return mim_cmd_pairs_sample(argc - 1, argv + 1);
    if (!strcmp(argv[1], "templates")) return mim_cmd_pairs_templates(argc - 1, argv + 1);
    if (!strcmp(argv[1], "retrieve")) return mim_cmd_pairs_retrieve(argc - 1, argv + 1);
    if (!strcmp(argv[1], "complete")) return mim_cmd_pairs_complete(argc - 1, argv + 1);
    fprintf(stderr, "mimic pairs: unknown subcommand '%s' (see mimic pairs --help)\n", argv[1]);
    return 2;
}
