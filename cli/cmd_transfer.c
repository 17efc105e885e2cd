/* mimic transfer: one avatar into one pose (seed 000, Section 3.4), written
 * as PLY, OBJ, OFF or GLB. JSON report: schemas/transfer.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_io.h"
#include "mim_session.h"

#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic transfer --store DIR --avatar (MESH|ID) (--template ID[,ID...] | --landmarks FILE.json | both)\n"
            "                      [--drive auto|template|orientation|skeleton] [--blend K] [--segment-correction on|off]\n"
            "                      [--relative on|off]\n"
            "                      [--iterations N] [--tol T]\n"
            "                      [--formulation least-squares|square] [--json]\n"
            "                      -o OUT.(ply|obj|off|glb)\n\n"
            "Deforms the avatar into a pose, keeping its own shape: the template gives the pose\n"
            "through its local frames, the landmarks (if given) fix 16 points exactly.\n\n"
            "  --store DIR          the template store\n"
            "  --avatar MESH|ID     a mesh file, or a template id (mimic list); a mesh of another connectivity\n"
            "                       is registered onto the store's once and bound (kept in the store)\n"
            "  --avatar-landmarks FILE  that mesh's landmarks (default: NAME.landmarks.json beside it,\n"
            "                       or a built-in map of its connectivity)\n"
            MIM_CLI_AVATAR_HELP
            "  --template ID[,ID...] the template whose pose to take; with no --landmarks, mimic\n"
            "                       retargets its landmarks onto the avatar's proportions; several\n"
            "                       (at most %d): their frames blended with equal weights\n"
            "  --landmarks FILE     one landmark frame, {\"landmarks\": [[x,y,z], ...]} in the order of\n"
            "                       the store's landmark map (schemas/landmark-frames.schema.json);\n"
            "                       alone, the template is the nearest pose from mimic query\n"
            "                       the frame's optional \"orientations\" (the 17 vest segments' rotations\n"
            "                       from the avatar's rest mesh) drive the avatar's own frames\n"
            "  --drive D            auto (default: orientations when the frame has them; else the\n"
            "                       templates' frames where --relative holds (one rig's bodies); else,\n"
            "                       with --landmarks from the index, skeleton), template (the templates'\n"
            "                       frames, iterated), orientation (one solve; needs orientations) or\n"
            "                       skeleton (the avatar's own frames turned as its landmark skeleton\n"
            "                       turns onto the landmarks, one solve)\n"
            "  --blend K            with --landmarks alone: blend the frames of the K nearest templates,\n"
            "                       weighted by query distance (default %d; 1: the nearest alone)\n"
            "  --segment-correction on|off  turn each template's frames so that its landmark skeleton\n"
            "                       lies along the landmarks' before the solve (default: on where\n"
            "                       the transfer is not relative, off where it is)\n"
            "  --relative on|off    the template drive: the avatar's W plus the template's change from its\n"
            "                       subject's template nearest the avatar's rest, and its turn on the\n"
            "                       avatar's own frames, where that reference stands as the avatar does\n"
            "                       (within %g degrees: one rig's bodies; real people's do not) (default\n"
            "                       on; off: the template's frames, rest W)\n"
            "  --iterations N       at most N solves (default %u; %u on the relative path)\n"
            "  --tol T              stop when no vertex moves more than T metres (default: %g of the\n"
            "                       landmarks' extent, at least %g)\n"
            "  --formulation F      least-squares (default: the landmark rows stay in the objective)\n"
            "                       or square (the paper's system (3))\n"
            "  -o, --output OUT     .ply .obj .off or .glb\n"
            "  --json               a JSON report on stdout (schemas/transfer.schema.json)\n"
            "  -h, --help           this help\n",
            MIM_XFER_BLEND_MAX, MIM_SESSION_DEFAULT_BLEND, MIM_SESSION_RELATIVE_GATE_DEG, MIM_XFER_DEFAULT_MAX_ITERATIONS,
            MIM_SESSION_RELATIVE_ITERATIONS,
            MIM_XFER_DEFAULT_SETTLE, MIM_XFER_DEFAULT_TOL);
}

int mim_cmd_transfer(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'},      {"avatar", required_argument, 0, 'a'}, {"avatar-landmarks", required_argument, 0, 'A'}, MIM_CLI_AVATAR_LONGOPTS,
        {"template", required_argument, 0, 't'},   {"landmarks", required_argument, 0, 'l'},
        {"iterations", required_argument, 0, 'i'}, {"tol", required_argument, 0, 'T'},
        {"formulation", required_argument, 0, 'f'}, {"output", required_argument, 0, 'o'},
        {"json", no_argument, 0, 'j'},             {"help", no_argument, 0, 'h'}, {"drive", required_argument, 0, 'd'},
        {"blend", required_argument, 0, 'b'},      {"segment-correction", required_argument, 0, 'C'},
        {"relative", required_argument, 0, 'R'},
        {0, 0, 0, 0}};
    const char *store = NULL, *avatar = NULL, *tmpl_arg = NULL, *lm_path = NULL, *outp = NULL;
    mim_cli_avatar_t av = {0};
    uint64_t iterations = 0, blend = 0, tmpl_ids[MIM_XFER_BLEND_MAX];
    uint32_t n_tmpl = 0;
    int correction = 0, relative = 1;
    double tol = 0.0;
    int as_json = 0, c, look_kept = 0;
    mim_xfer_formulation_t form = MIM_XFER_LEAST_SQUARES;
    optind = 0;
    opterr = 0;
    int drive = MIM_DRIVE_AUTO;
    while ((c = getopt_long(argc, argv, "s:a:t:l:i:T:f:o:jhd:b:C:R:", longopts, NULL)) != -1) {
        if (c == 's') store = optarg;
        else if (c == 'a') avatar = optarg;
        else if (c == 'A') av.landmarks = optarg;
        else if (c == MIM_CLI_OPT_AVATAR_MESH || c == MIM_CLI_OPT_MAX_DISTANCE) {
            if (mim_cli_avatar_option("transfer", c, optarg, &av) < 0) return 2;
        }
        else if (c == 't') tmpl_arg = optarg;
        else if (c == 'l') lm_path = optarg;
        else if (c == 'o') outp = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 'b') {
            if (mim_cli_number("transfer", "blend", optarg, 1, MIM_XFER_BLEND_MAX, &blend)) return 2;
        } else if (c == 'C') {
            if (mim_cli_on_off("transfer", "segment-correction", optarg, &correction)) return 2;
            correction = correction ? 1 : -1;
        } else if (c == 'R') {
            if (mim_cli_on_off("transfer", "relative", optarg, &relative)) return 2;
        } else if (c == 'i') {
            if (mim_cli_number("transfer", "iterations", optarg, 1, 1000, &iterations)) return 2;
        } else if (c == 'T') {
            if (mim_cli_real("transfer", "tol", optarg, 0.0, HUGE_VAL, 1, "is not a positive number of metres", &tol))
                return 2;
        } else if (c == 'f') {
            if (!strcmp(optarg, "least-squares")) form = MIM_XFER_LEAST_SQUARES;
            else if (!strcmp(optarg, "square")) form = MIM_XFER_SQUARE;
            else {
                fprintf(stderr, "mimic transfer: --formulation '%s': use least-squares or square\n", optarg);
                return 2;
            }
        } else if (c == 'd') {
            if (mim_cli_drive("transfer", optarg, &drive)) return 2;
        } else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic transfer: unknown or incomplete option '%s' (see mimic transfer --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "mimic transfer: unexpected argument '%s' (see mimic transfer --help)\n", argv[optind]);
        return 2;
    }
    if (!store || !avatar || !outp || (!tmpl_arg && !lm_path)) {
        fprintf(stderr, "mimic transfer: --store, --avatar, -o and --template and/or --landmarks are required "
                        "(see mimic transfer --help)\n");
        return 2;
    }
    if (tmpl_arg && mim_cli_template_ids("transfer", "template", tmpl_arg, tmpl_ids, MIM_XFER_BLEND_MAX, &n_tmpl))
        return 2;
    if (blend && tmpl_arg) {
        fprintf(stderr, "mimic transfer: --blend K takes the K nearest templates; --template names them (use one)\n");
        return 2;
    }
    if (drive == MIM_DRIVE_ORIENTATION && !lm_path) {
        fprintf(stderr, "mimic transfer: --drive orientation needs --landmarks (a frame with orientations)\n");
        return 2;
    }

    mim_error_t err = {0};
    mim_session_t *s = NULL;
    double t0 = mim_now();
    mim_session_options_t so;
    mim_cli_session_options(&so, &av);
    so.formulation = form;
    int rc = mim_session_open(&s, store, &so, &err);
    if (!rc && !tmpl_arg && !mim_session_query(s))
        rc = mim_error_set(&err, MIM_ENOTFOUND, "%s: store has no index (run mimic index)", store);
    if (rc) { /* the command cannot run (docs/reference.md: exit statuses) */
        mim_session_close(&s);
        fprintf(stderr, "mimic transfer: %s\n", mim_error_text(&err));
        return 2;
    }
    rc = mim_session_load_avatar(s, avatar, &err);
    const double t_open = mim_now() - t0, t_factor = mim_session_factor_seconds(s);
    const uint32_t n = mim_session_mesh(s)->n_vertices, nl = mim_session_map(s)->count;
    mim_landmark_frames_t frames = {0};
    if (!rc && lm_path) {
        rc = mim_landmark_frames_read(lm_path, nl, 0, &frames, &err);
        if (!rc && frames.n_frames != 1)
            rc = mim_error_set(&err, MIM_EFORMAT, "%s: has %u frames; transfer takes one", lm_path, frames.n_frames);
        if (!rc && drive == MIM_DRIVE_ORIENTATION && !frames.orientations)
            rc = mim_error_set(&err, MIM_EFORMAT, "%s: --drive orientation, but the frame has no \"orientations\"", lm_path);
    }
    float *out = malloc(3 * (size_t)n * sizeof *out);
    if (!rc && !out) rc = mim_error_set(&err, MIM_ENOMEM, "out of memory for %u vertices", n);
    mim_session_report_t rep = {0};
    if (!rc) {
        mim_session_request_t req = {.template_ids = tmpl_ids, .n_templates = n_tmpl, .blend = (uint32_t)blend,
                                     .segment_correction = correction, .relative = relative ? 1 : -1,
                                     .landmarks = lm_path ? frames.positions : NULL,
                                     .xfer = {.max_iterations = (uint32_t)iterations, .tol = tol},
                                     .orientations = (const mim_quat *)frames.orientations,
                                     .orient_present = frames.orient_present, .drive = (mim_session_drive_t)drive};
        rc = mim_session_transfer(s, &req, out, &rep, &err);
    }
    if (!rc) { /* in the avatar's own connectivity */
        const mim_mesh_t *om = mim_session_output_mesh(s);
        float *own = mim_session_maps_output(s) ? malloc(3 * (size_t)om->n_vertices * sizeof *own) : out;
        if (!own) rc = mim_error_set(&err, MIM_ENOMEM, "out of memory for %u vertices", om->n_vertices);
        if (!rc) {
            mim_session_output(s, out, own);
            mim_mesh_t m = {om->n_vertices, om->n_faces, own, om->faces};
            size_t ol = strlen(outp);
            if (ol >= 4 && !strcasecmp(outp + ol - 4, ".glb")) { /* the avatar's parts and look (issue 28) */
                mim_io_sequence_t sq = {.mesh = &m, .n_frames = 1, .positions = own, .look_kept = &look_kept};
                mim_session_output_look(s, &sq);
                rc = mim_io_write_sequence_glb(outp, &sq, &err);
            } else {
                rc = mim_io_write_mesh(outp, &m, &err);
            }
        }
        if (own != out) free(own);
    }
    uint32_t n_parts = 0;
    if (!rc) mim_session_output_parts(s, &n_parts);
    /* load: the store, the avatar and the template; factor: the avatar's Cholesky factor */
    const double t_load = t_open - t_factor + rep.seconds_query + rep.seconds_template, t_solve = rep.seconds_solve;
    if (!rc && rep.degraded[0]) /* damage elsewhere in the store changed the output: never silently */
        fprintf(stderr, "mimic transfer: warning: %s\n", rep.degraded);
    if (rc) {
        fprintf(stderr, "mimic transfer: %s\n", mim_error_text(&err));
    } else if (as_json) {
        json_t *j = json_pack("{s:s, s:s, s:I, s:s, s:s, s:s, s:s, s:i, s:i, s:i, s:o, s:b, s:b, s:{s:f, s:f, s:f}}", "output", outp,
                              "avatar", mim_session_avatar(s), "template", (json_int_t)rep.template_id, "template_label", rep.label, "mode",
                              lm_path ? (tmpl_arg ? "template+landmarks" : "landmarks") : "template", "formulation",
                              form == MIM_XFER_SQUARE ? "square" : "least-squares", "drive",
                              mim_session_drive_names[rep.drive], "orientations_filled", (int)rep.orient_filled,
                              "vertices_from_template", (int)rep.orient_from_template, "iterations", (int)rep.xfer.iterations,
                              "last_move_m", isfinite(rep.xfer.last_move) ? json_real(rep.xfer.last_move) : json_null(),
                              "converged", rep.xfer.converged, "early_stopped", rep.xfer.early_stopped, "seconds",
                              "load", t_load, "factor", t_factor, "transfer", t_solve);
        json_t *ids = json_array();
        for (uint32_t k = 0; k < rep.n_templates; k++)
            json_array_append_new(ids, json_integer((json_int_t)rep.templates[k]));
        if (j) {
            json_object_set_new(j, "templates", ids);
            json_object_set_new(j, "segment_correction", json_boolean(rep.corrected));
            json_t *refs = json_array();
            for (uint32_t k = 0; rep.relative && k < rep.n_templates; k++)
                json_array_append_new(refs, json_integer((json_int_t)rep.references[k]));
            json_object_set_new(j, "relative", json_boolean(rep.relative));
            json_object_set_new(j, "parts", json_integer(n_parts));
            json_object_set_new(j, "look", json_boolean(look_kept));
            json_object_set_new(j, "frames_turned", json_integer(rep.frames_turned));
            json_object_set_new(j, "reference",
                                rep.relative ? json_integer((json_int_t)rep.reference_id) : json_null());
            json_object_set_new(j, "references", refs);
            json_object_set_new(j, "degraded", rep.degraded[0] ? json_string(rep.degraded) : json_null());
        } else {
            json_decref(ids);
        }
        char *txt = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (txt) printf("%s\n", txt);
        else rc = MIM_EINVAL, fprintf(stderr, "mimic transfer: cannot make the JSON report (is every path valid UTF-8?)\n");
        free(txt);
        json_decref(j);
    } else {
        char more[48] = "";
        if (rep.n_templates > 1)
            snprintf(more, sizeof more, " and %u more, blended", rep.n_templates - 1);
        char rel[96] = "";
        if (rep.relative)
            snprintf(rel, sizeof rel, ", relative to template %llu (frames %s)", (unsigned long long)rep.reference_id,
                     rep.frames_turned == rep.n_templates ? "turned" : rep.frames_turned ? "partly turned" : "the template's");
        fprintf(stderr, "mimic transfer: %s -> %s in the pose of template %llu (%s)%s%s: %s drive, %u iterations (%s), %.2f ms\n",
                mim_session_avatar(s), outp, (unsigned long long)rep.template_id, rep.label,
                more, rel,
                mim_session_drive_names[rep.drive], rep.xfer.iterations,
                rep.drive != MIM_DRIVE_TEMPLATE ? "one solve"
                : rep.xfer.converged     ? "converged"
                : rep.xfer.early_stopped ? "stopped when the moves stopped shrinking"
                                         : "iteration cap",
                1e3 * t_solve);
    }
    mim_landmark_frames_free(&frames);
    free(out);
    mim_session_close(&s);
    return rc == MIM_ENOINDEX ? 2 : rc ? 1 : 0; /* no index: the command could not run */
}
