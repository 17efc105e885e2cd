/* mimic synth: write a dataset of synthetic human bodies (mim_synth.h). */
#include "args.h"
#include "commands.h"
#include "mim_synth.h"
#include "output.h"

#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic synth --out DIR [--subjects S] [--poses P] [--vertices N] [--seed K]\n\n"
            "Generates synthetic human bodies with exact ground truth: S subjects (height\n"
            "1.52..1.93 m, limb lengths and girths, shoulder and hip width vary) x P poses, all\n"
            "on one connectivity (a closed triangle surface). Pose 0 is the rest pose (A-pose),\n"
            "1..11 are designed poses (tpose, arms_up, walk, squat, sit, kick, wave, reach, lunge,\n"
            "bow, guard), later ones random within joint limits. Writes one binary PLY per body\n"
            "(synth_sSS_pPP.ply; metres, +Y up, facing +Z), manifest.csv and landmarks.json\n"
            "(16 landmark vertices) into DIR. The same options give byte-identical files.\n\n"
            "  --out DIR       output folder, created if missing (required)\n"
            "  --subjects S    number of subjects, 1..1000 (default 4)\n"
            "  --poses P       number of poses per subject, 1..1000 (default 12)\n"
            "  --vertices N    approximate vertices per body, 500..200000 (default 7000)\n"
            "  --seed K        seed of subject shapes and random poses, 0..2^64-1 (default 1)\n"
            "  -h, --help      this help\n");
}

int mim_cmd_synth(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"out", required_argument, 0, 'o'},      {"subjects", required_argument, 0, 's'},
        {"poses", required_argument, 0, 'p'},    {"vertices", required_argument, 0, 'n'},
        {"seed", required_argument, 0, 'k'},     {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0}};
    const char *out = NULL;
    mim_synth_options_t opt = {MIM_SYNTH_DEFAULT_SUBJECTS, MIM_SYNTH_DEFAULT_POSES, MIM_SYNTH_DEFAULT_VERTICES, 1, 0, 0, 0};
    int c;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":h", longopts, NULL)) != -1) {
        uint64_t v;
        switch (c) {
        case 'o':
            out = optarg;
            break;
        case 's':
            if (mim_cli_number("synth", "subjects", optarg, 1, 1000, &v)) return 2;
            opt.subjects = (uint32_t)v;
            break;
        case 'p':
            if (mim_cli_number("synth", "poses", optarg, 1, 1000, &v)) return 2;
            opt.poses = (uint32_t)v;
            break;
        case 'n':
            if (mim_cli_number("synth", "vertices", optarg, MIM_SYNTH_MIN_VERTICES, MIM_SYNTH_MAX_VERTICES, &v)) return 2;
            opt.vertices = (uint32_t)v;
            break;
        case 'k':
            if (mim_cli_number("synth", "seed", optarg, 0, UINT64_MAX, &v)) return 2;
            opt.seed = v;
            break;
        case 'h':
            help(stdout);
            return 0;
        case ':':
            fprintf(stderr, "mimic synth: option '%s' needs a value (see mimic synth --help)\n", argv[optind - 1]);
            return 2;
        default:
            fprintf(stderr, "mimic synth: unknown option '%s' (see mimic synth --help)\n", argv[optind - 1]);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "mimic synth: unexpected argument '%s' (see mimic synth --help)\n", argv[optind]);
        return 2;
    }
    if (!out || !*out) {
        fprintf(stderr, "mimic synth: --out DIR is required (see mimic synth --help)\n");
        return 2;
    }
    mim_error_t err = {0};
    mim_synth_t *s = NULL;
    int rc = mim_synth_create(&s, &opt, &err);
    mim_synth_set_progress(s, mim_cli_progress, NULL);
    if (!rc) rc = mim_synth_write_dataset(s, out, &err);
    if (rc) {
        fprintf(stderr, "mimic synth: %s\n", mim_error_text(&err));
        mim_synth_destroy(&s);
        return rc == MIM_EINVAL ? 2 : 1;
    }
    printf("mimic synth: wrote %u bodies (%u subjects x %u poses), %u vertices and %u triangles each, to %s\n",
           opt.subjects * opt.poses, opt.subjects, opt.poses, mim_synth_n_vertices(s), mim_synth_n_faces(s), out);
    mim_synth_destroy(&s);
    return 0;
}
