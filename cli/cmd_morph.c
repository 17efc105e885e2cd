/* mimic morph: key poses and the poses between them (seed 000, Section
 * 3.5) as one GLB with a morph-target animation. */
#include "args.h"
#include "commands.h"
#include "mim_io.h"
#include "mim_session.h"

#include <getopt.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define KEYS_MAX 256

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic morph --store DIR --avatar (MESH|ID) --keys K1,K2,... --frames-between N\n"
            "                   [--method linear|frames] [--landmarks FILE.json] [--drive auto|template|orientation|skeleton]\n"
            "                   [--relative on|off] [--fps F] [--json] -o OUT.glb\n\n"
            "Transfers the avatar into the pose of each key template, fills N poses between\n"
            "consecutive keys, and writes the sequence as a GLB animation (morph targets).\n\n"
            "  --store DIR          the template store\n"
            "  --avatar MESH|ID     a mesh file, or a template id; a mesh of another connectivity\n"
            "                       is registered onto the store's once and bound (kept in the store)\n"
            "  --avatar-landmarks FILE  that mesh's landmarks (default: NAME.landmarks.json beside it,\n"
            "                       or a built-in map of its connectivity)\n"
            MIM_CLI_AVATAR_HELP
            "  --keys K1,K2,...     template ids of the key poses, in order (2..%d)\n"
            "  --frames-between N   in-between poses per pair of keys (0..1000)\n"
            "  --method M           frames (default: per-vertex frames slerped, the landmarks along\n"
            "                       the skeleton, one solve each: no limb shrinks) or linear (positions,\n"
            "                       the paper's)\n"
            "  --landmarks FILE     one landmark frame per key ({\"frames\": [...]}); without it each\n"
            "                       key's landmarks are retargeted from its template\n"
            "  --drive D            auto (default: where the landmark frames carry \"orientations\",\n"
            "                       keys are the avatar's own frames turned per segment, one solve,\n"
            "                       and in-betweens slerp the rotations and solve again), template,\n"
            "                       orientation (every frame needs orientations) or skeleton (keys\n"
            "                       are the avatar's own frames turned by its landmark skeleton)\n"
            "  --relative on|off    template-driven keys by relative transfer (the template's change from\n"
            "                       its subject's template nearest the avatar's rest, where it stands as\n"
            "                       the avatar does; default on)\n"
            "  --fps F              playback rate of the animation (default 30)\n"
            "  -o, --output OUT     a .glb file\n"
            "  --json               a JSON report on stdout (schemas/morph.schema.json)\n"
            "  -h, --help           this help\n",
            KEYS_MAX);
}

static int parse_keys(const char *text, uint64_t *keys, uint32_t *count)
{
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", text);
    *count = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        if (*count == KEYS_MAX) {
            fprintf(stderr, "mimic morph: --keys: more than %d keys\n", KEYS_MAX);
            return -1;
        }
        if (mim_cli_template_id("morph", "keys", tok, &keys[*count])) return -1;
        (*count)++;
    }
    if (*count < 2) {
        fprintf(stderr, "mimic morph: --keys '%s': give at least two template ids, comma-separated\n", text);
        return -1;
    }
    return 0;
}

int mim_cmd_morph(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'},  {"avatar", required_argument, 0, 'a'}, {"avatar-landmarks", required_argument, 0, 'A'}, MIM_CLI_AVATAR_LONGOPTS,
        {"keys", required_argument, 0, 'k'},   {"frames-between", required_argument, 0, 'n'},
        {"method", required_argument, 0, 'm'}, {"landmarks", required_argument, 0, 'l'},
        {"fps", required_argument, 0, 'r'},    {"output", required_argument, 0, 'o'},
        {"json", no_argument, 0, 'j'},         {"help", no_argument, 0, 'h'}, {"drive", required_argument, 0, 'd'},
        {"relative", required_argument, 0, 'R'}, {0, 0, 0, 0}};
    const char *store = NULL, *avatar = NULL, *keys_arg = NULL, *lm_path = NULL, *outp = NULL;
    mim_cli_avatar_t av = {0};
    uint64_t between = 0, fps = 30, keys[KEYS_MAX];
    uint32_t n_keys = 0;
    int have_between = 0, as_json = 0, c, drive = MIM_DRIVE_AUTO, relative = 1, look_kept = 0;
    mim_xfer_morph_method_t method = MIM_XFER_MORPH_FRAMES;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:a:k:n:m:l:r:o:jhd:R:", longopts, NULL)) != -1) {
        if (c == 's') store = optarg;
        else if (c == 'a') avatar = optarg;
        else if (c == 'A') av.landmarks = optarg;
        else if (c == MIM_CLI_OPT_AVATAR_MESH || c == MIM_CLI_OPT_MAX_DISTANCE) {
            if (mim_cli_avatar_option("morph", c, optarg, &av) < 0) return 2;
        }
        else if (c == 'k') keys_arg = optarg;
        else if (c == 'l') lm_path = optarg;
        else if (c == 'o') outp = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 'n') {
            if (mim_cli_number("morph", "frames-between", optarg, 0, 1000, &between)) return 2;
            have_between = 1;
        } else if (c == 'r') {
            if (mim_cli_number("morph", "fps", optarg, 1, 1000, &fps)) return 2;
        } else if (c == 'm') {
            if (!strcmp(optarg, "linear")) method = MIM_XFER_MORPH_LINEAR;
            else if (!strcmp(optarg, "frames")) method = MIM_XFER_MORPH_FRAMES;
            else {
                fprintf(stderr, "mimic morph: --method '%s': use linear or frames\n", optarg);
                return 2;
            }
        } else if (c == 'd') {
            if (mim_cli_drive("morph", optarg, &drive)) return 2;
        } else if (c == 'R') {
            if (mim_cli_on_off("morph", "relative", optarg, &relative)) return 2;
        } else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic morph: unknown or incomplete option '%s' (see mimic morph --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "mimic morph: unexpected argument '%s' (see mimic morph --help)\n", argv[optind]);
        return 2;
    }
    if (!store || !avatar || !keys_arg || !have_between || !outp) {
        fprintf(stderr, "mimic morph: --store, --avatar, --keys, --frames-between and -o are required "
                        "(see mimic morph --help)\n");
        return 2;
    }
    if (parse_keys(keys_arg, keys, &n_keys)) return 2;
    if (drive == MIM_DRIVE_ORIENTATION && !lm_path) {
        fprintf(stderr, "mimic morph: --drive orientation needs --landmarks (frames with orientations)\n");
        return 2;
    }
    size_t olen = strlen(outp);
    if (olen < 4 || strcasecmp(outp + olen - 4, ".glb")) {
        fprintf(stderr, "mimic morph: -o '%s': the sequence is written as a .glb file\n", outp);
        return 2;
    }

    mim_error_t err = {0};
    mim_session_t *s = NULL;
    mim_session_options_t so;
    mim_cli_session_options(&so, &av);
    int rc = mim_session_open(&s, store, &so, &err);
    if (rc) { /* the command cannot run (docs/reference.md: exit statuses) */
        fprintf(stderr, "mimic morph: %s\n", mim_error_text(&err));
        return 2;
    }
    rc = mim_session_load_avatar(s, avatar, &err);
    const mim_xfer_topology_t *topo = mim_session_topology(s);
    const uint32_t n = mim_session_mesh(s)->n_vertices, nl = mim_session_map(s)->count;
    const size_t n_frames = (size_t)(n_keys - 1) * (between + 1) + 1;
    mim_landmark_frames_t lmf = {0};
    if (!rc && lm_path) {
        rc = mim_landmark_frames_read(lm_path, nl, 0, &lmf, &err);
        if (!rc && lmf.n_frames != n_keys)
            rc = mim_error_set(&err, MIM_EFORMAT, "%s: has %u frames for %u keys", lm_path, lmf.n_frames, n_keys);
        if (!rc && drive == MIM_DRIVE_ORIENTATION && !lmf.orientations)
            rc = mim_error_set(&err, MIM_EFORMAT, "%s: --drive orientation, but no frame has \"orientations\"", lm_path);
    }
    /* per key: positions, frames as quaternions, own W, landmarks */
    float *kpos = NULL, *klm = NULL, *seq = NULL;
    double *kq = NULL, *kW = NULL, *F = NULL;
    if (!rc) {
        kpos = malloc((size_t)n_keys * 3 * n * sizeof *kpos);
        klm = malloc((size_t)n_keys * 3 * nl * sizeof *klm);
        kq = malloc((size_t)n_keys * 4 * n * sizeof *kq);
        kW = malloc((size_t)n_keys * 3 * n * sizeof *kW);
        F = malloc(9 * (size_t)n * sizeof *F);
        seq = malloc(n_frames * 3 * n * sizeof *seq);
        if (!kpos || !klm || !kq || !kW || !F || !seq)
            rc = mim_error_set(&err, MIM_ENOMEM, "out of memory for %zu frames of %u vertices", n_frames, n);
    }
    double t0 = mim_now();
    uint32_t iterations = 0, oriented_keys = 0, relative_keys = 0;
    uint8_t *oriented = calloc(n_keys, 1);
    if (!rc && !oriented) rc = mim_error_set(&err, MIM_ENOMEM, "out of memory");
    for (uint32_t k = 0; k < n_keys && !rc; k++) {
        float *u = klm + (size_t)k * 3 * nl, *x = kpos + (size_t)k * 3 * n;
        mim_session_request_t req = {.template_id = keys[k],
                                     .landmarks = lm_path ? lmf.positions + (size_t)k * 3 * nl : NULL,
                                     .drive = (mim_session_drive_t)drive, .relative = relative ? 1 : -1};
        if (lmf.orientations) { /* a frame without any: none present, the template drive (auto) */
            req.orientations = (const mim_quat *)lmf.orientations + (size_t)k * MIM_SEGMENTS;
            req.orient_present = lmf.orient_present + (size_t)k * MIM_SEGMENTS;
        }
        mim_session_report_t rep;
        mim_error_t kerr = {0};
        if ((rc = mim_session_transfer(s, &req, x, &rep, &kerr)))
            mim_error_set(&err, rc, "key %u (template %llu): %s", k, (unsigned long long)keys[k], mim_error_text(&kerr));
        if (!rc) {
            iterations += rep.xfer.iterations;
            oriented[k] = rep.drive == MIM_DRIVE_ORIENTATION;
            oriented_keys += oriented[k];
            relative_keys += rep.relative;
            /* the key pose's landmarks, own frames and W, for the frames method */
            memcpy(u, rep.landmarks, 3 * (size_t)nl * sizeof *u);
            mim_xfer_frames(topo, x, F);
            mim_xfer_frames_to_quats(n, F, kq + (size_t)k * 4 * n);
            mim_xfer_encode(topo, x, F, kW + (size_t)k * 3 * n);
        }
    }
    for (uint32_t k = 0; k + 1 < n_keys && !rc; k++) {
        mim_xfer_key_t a = {kpos + (size_t)k * 3 * n, kq + (size_t)k * 4 * n, kW + (size_t)k * 3 * n,
                            klm + (size_t)k * 3 * nl, NULL};
        mim_xfer_key_t b = {kpos + (size_t)(k + 1) * 3 * n, kq + (size_t)(k + 1) * 4 * n,
                            kW + (size_t)(k + 1) * 3 * n, klm + (size_t)(k + 1) * 3 * nl, NULL};
        size_t f0 = (size_t)k * (between + 1);
        memcpy(seq + f0 * 3 * n, a.positions, 3 * (size_t)n * sizeof *seq);
        /* between two keys of the orientation drive: their rotations slerped, one solve each */
        mim_session_oriented_key_t oa = {0}, ob = {0};
        if (oriented[k] && oriented[k + 1]) {
            const size_t qa = (size_t)k * MIM_SEGMENTS, qb = (size_t)(k + 1) * MIM_SEGMENTS;
            oa = (mim_session_oriented_key_t){(const mim_quat *)lmf.orientations + qa, lmf.orient_present + qa, a.landmarks,
                                              keys[k]};
            ob = (mim_session_oriented_key_t){(const mim_quat *)lmf.orientations + qb, lmf.orient_present + qb, b.landmarks,
                                              keys[k + 1]};
        }
        for (uint64_t j = 1; j <= between && !rc; j++) {
            double t = (double)j / (double)(between + 1);
            float *o = seq + (f0 + j) * 3 * n;
            rc = oa.R && method == MIM_XFER_MORPH_FRAMES ? mim_session_morph_oriented(s, &oa, &ob, t, NULL, o, &err)
                                                        : mim_session_morph(s, method, &a, &b, t, NULL, o, &err);
        }
    }
    if (!rc) memcpy(seq + (n_frames - 1) * 3 * n, kpos + (size_t)(n_keys - 1) * 3 * n, 3 * (size_t)n * sizeof *seq);
    double t_compute = mim_now() - t0;
    if (!rc) { /* in the avatar's own connectivity */
        const mim_mesh_t *om = mim_session_output_mesh(s);
        float *own = seq;
        if (mim_session_maps_output(s) && !(own = malloc(n_frames * 3 * (size_t)om->n_vertices * sizeof *own)))
            rc = mim_error_set(&err, MIM_ENOMEM, "out of memory for %zu frames of %u vertices", n_frames, om->n_vertices);
        for (size_t f = 0; !rc && own != seq && f < n_frames; f++)
            mim_session_output(s, seq + f * 3 * n, own + f * 3 * (size_t)om->n_vertices);
        mim_io_sequence_t sq = {.mesh = om, .n_frames = (uint32_t)n_frames, .positions = own, .fps = (double)fps,
                                .look_kept = &look_kept};
        mim_session_output_look(s, &sq); /* the avatar's parts and look (issue 28) */
        if (!rc) rc = mim_io_write_sequence_glb(outp, &sq, &err);
        if (own != seq) free(own);
    }
    if (rc) {
        fprintf(stderr, "mimic morph: %s\n", mim_error_text(&err));
    } else if (as_json) {
        json_t *j = json_pack("{s:s, s:s, s:s, s:i, s:i, s:i, s:i, s:i, s:i, s:f}", "output", outp, "avatar", mim_session_avatar(s), "method",
                              method == MIM_XFER_MORPH_LINEAR ? "linear" : "frames", "keys", (int)n_keys,
                              "oriented_keys", (int)oriented_keys, "relative_keys", (int)relative_keys,
                              "frames_between", (int)between, "frames", (int)n_frames, "key_iterations",
                              (int)iterations, "seconds", t_compute);
        uint32_t n_parts = 0;
        mim_session_output_parts(s, &n_parts);
        if (j) json_object_set_new(j, "parts", json_integer(n_parts)), json_object_set_new(j, "look", json_boolean(look_kept));
        char *txt = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (txt) printf("%s\n", txt);
        else rc = MIM_EINVAL, fprintf(stderr, "mimic morph: cannot make the JSON report (is every path valid UTF-8?)\n");
        free(txt);
        json_decref(j);
    } else {
        fprintf(stderr, "mimic morph: %s -> %s: %u keys, %zu frames (%s), %.1f ms\n", mim_session_avatar(s), outp, n_keys, n_frames,
                method == MIM_XFER_MORPH_LINEAR ? "linear" : "frames", 1e3 * t_compute);
    }
    mim_landmark_frames_free(&lmf);
    free(kpos), free(klm), free(kq), free(kW), free(F), free(seq), free(oriented);
    mim_session_close(&s);
    return rc == MIM_ENOINDEX ? 2 : rc ? 1 : 0; /* no index: the command could not run */
}
