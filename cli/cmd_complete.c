/* mimic complete: lost landmarks filled in from the store's templates
 * (issue 14; seed 002's completion by retrieval) and the index's pose
 * classes (issue 29; session/complete.c). */
#include "args.h"
#include "commands.h"
#include "mim_session.h"

#include <getopt.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic complete --store DIR --landmarks FRAMES.json [--classes W] [--exclude-subject S]\n"
            "                      [--no-local] [--json]\n\n"
            "Fills the null landmarks of each frame (schemas/landmark-frames.schema.json; up to all but %d\n"
            "may be null) from the store's templates: the templates nearest to the landmarks still seen\n"
            "(after each one's best similarity onto them), their median, blended onto the seen landmarks\n"
            "with Gaussian weights (seed 002, Section 6); mixed with the index's pose classes' answer\n"
            "(each class a Gaussian over the landmarks: its conditional mean given the seen ones). Where a\n"
            "template matches the seen landmarks within about 1.5 cm, the nearest templates' own Gaussian\n"
            "is weighted in over either answer.\n\n"
            "  --store DIR           the template store\n"
            "  --landmarks FILE      one frame or a batch, null where a landmark is lost\n"
            "  --classes W           the pose classes' share in 0..1 (default %.1f; 0: the templates\n"
            "                        alone; 1: the classes alone); a store without an index uses the\n"
            "                        templates alone\n"
            "  --no-local            no Gaussian of the nearest templates (with --classes 1: no scan\n"
            "                        of the templates)\n"
            "  --exclude-subject S   leave that subject's templates out (the classes stay as the index\n"
            "                        was built: for a strict leave-one-out add --classes 0)\n"
            "  --json                {\"frames\": [{\"landmarks\": [...], \"completed\": [i, ...]}, ...]}\n"
            "                        (schemas/complete.schema.json); without it, one line per frame\n"
            "  -h, --help            this help\n\n"
            "Exit status: 0 done, 1 a frame could not be completed or the file is bad, 2 bad usage or the\n"
            "store cannot be opened.\n",
            MIM_COMPLETE_MIN_SEEN, MIM_COMPLETE_DEFAULT_GAUSSIAN);
}

int mim_cmd_complete(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'}, {"landmarks", required_argument, 0, 'l'},
        {"exclude-subject", required_argument, 0, 'x'}, {"json", no_argument, 0, 'j'},
        {"classes", required_argument, 0, 'c'}, {"no-local", no_argument, 0, 'n'},
        {"help", no_argument, 0, 'h'},           {0, 0, 0, 0},
    };
    const char *store = NULL, *lm_path = NULL, *exclude = NULL;
    int as_json = 0, no_local = 0, c;
    double classes = MIM_COMPLETE_DEFAULT_GAUSSIAN;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:l:x:c:njh", longopts, NULL)) != -1) {
        switch (c) {
        case 's': store = optarg; break;
        case 'l': lm_path = optarg; break;
        case 'x': exclude = optarg; break;
        case 'c':
            if (mim_cli_real("complete", "classes", optarg, 0.0, 1.0, 0, "is not a share in 0..1", &classes)) return 2;
            break;
        case 'n': no_local = 1; break;
        case 'j': as_json = 1; break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic complete: unknown or incomplete option '%s' (see mimic complete --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!store || !lm_path || optind < argc) {
        fprintf(stderr, "mimic complete: --store DIR and --landmarks FILE are required, and nothing else (see mimic "
                        "complete --help)\n");
        return 2;
    }
    mim_error_t err = {0};
    mim_session_t *s = NULL;
    mim_session_options_t so;
    mim_cli_session_options(&so, NULL);
    if (mim_session_open(&s, store, &so, &err)) {
        fprintf(stderr, "mimic complete: %s\n", mim_error_text(&err));
        return 2;
    }
    const mim_landmark_map_t *map = mim_session_map(s);
    const uint32_t L = map->count;
    mim_landmark_frames_t fr = {0};
    int status = 1;
    json_t *frames = json_array();
    float out[3 * MIM_LANDMARKS_MAX];
    uint8_t done[MIM_LANDMARKS_MAX];
    if (mim_landmark_frames_read(lm_path, L, L - MIM_COMPLETE_MIN_SEEN, &fr, &err)) {
        fprintf(stderr, "mimic complete: %s\n", mim_error_text(&err));
        goto end;
    }
    for (uint32_t f = 0; f < fr.n_frames; f++) {
        mim_session_complete_options_t co = {.exclude_subject = exclude, .gaussian = classes > 0 ? classes : -1,
                                             .no_local = no_local};
        if (mim_session_complete(s, fr.positions + (size_t)f * L * 3, fr.present + (size_t)f * L, &co, out, done,
                                 &err)) {
            fprintf(stderr, "mimic complete: %s: frame %u: %s\n", lm_path, f, mim_error_text(&err));
            goto end;
        }
        json_t *lms = json_array(), *which = json_array();
        char names[1024] = "";
        for (uint32_t l = 0; l < L; l++) {
            json_array_append_new(lms, json_pack("[f, f, f]", (double)out[3 * l], (double)out[3 * l + 1], (double)out[3 * l + 2]));
            if (done[l]) {
                json_array_append_new(which, json_integer(l));
                snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", names[0] ? ", " : "", map->names[l]);
            }
        }
        json_array_append_new(frames, json_pack("{s:o, s:o}", "landmarks", lms, "completed", which));
        if (!as_json) printf("frame %u: %s\n", f, names[0] ? names : "nothing lost");
    }
    if (as_json) {
        json_t *root = json_pack("{s:O}", "frames", frames);
        char *txt = root ? json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        json_decref(root);
        if (!txt) {
            fprintf(stderr, "mimic complete: cannot make the JSON report\n");
            goto end;
        }
        printf("%s\n", txt);
        free(txt);
    }
    status = 0;
end:
    json_decref(frames);
    mim_landmark_frames_free(&fr);
    mim_session_close(&s);
    return status;
}
