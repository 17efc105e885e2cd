/* mimic transfer: one avatar into one pose (seed 000, Section 3.4), written
 * as PLY, OBJ, OFF or GLB. JSON report: schemas/transfer.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_query.h"
#include "session.h"

#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic transfer --store DIR --avatar (MESH|ID) (--template ID | --landmarks FILE.json | both)\n"
            "                      [--iterations N] [--tol T] [--formulation least-squares|square] [--json]\n"
            "                      -o OUT.(ply|obj|off|glb)\n\n"
            "Deforms the avatar into a pose, keeping its own shape: the template gives the pose\n"
            "through its local frames, the landmarks (if given) fix 16 points exactly.\n\n"
            "  --store DIR          the template store\n"
            "  --avatar MESH|ID     a mesh file with the store's connectivity, or a template id (mimic list)\n"
            "  --template ID        the template whose pose to take; with no --landmarks, mimic\n"
            "                       retargets its landmarks onto the avatar's proportions\n"
            "  --landmarks FILE     one landmark frame, {\"landmarks\": [[x,y,z], ...]} in the order of\n"
            "                       the store's landmark map (schemas/landmark-frames.schema.json);\n"
            "                       alone, the template is the nearest pose from mimic query\n"
            "  --iterations N       at most N solves (default %u)\n"
            "  --tol T              stop when no vertex moves more than T metres (default %g)\n"
            "  --formulation F      least-squares (default: the landmark rows stay in the objective)\n"
            "                       or square (the paper's system (3))\n"
            "  -o, --output OUT     .ply .obj .off or .glb\n"
            "  --json               a JSON report on stdout (schemas/transfer.schema.json)\n"
            "  -h, --help           this help\n",
            MIM_XFER_DEFAULT_MAX_ITERATIONS, MIM_XFER_DEFAULT_TOL);
}

/* The nearest template of a landmark frame, through the store's index. */
static int nearest_template(mim_db_t *db, const float *u, uint64_t *id, mim_error_t *err)
{
    mim_query_t *q = NULL;
    int rc = mim_query_open(&q, db, err); /* without an index: "...: store has no index (run mimic index)" */
    if (rc)
        return rc;
    mim_index_query_options_t o = {.k = 1};
    mim_index_answer_t ans;
    mim_index_hit_t hit;
    rc = mim_query_frame(q, u, NULL, &o, &ans, &hit, err);
    if (!rc && ans.n_hits == 0)
        rc = mim_error_set(err, MIM_ENOTFOUND, "%s: the index returned no template", mim_db_path(db));
    if (!rc)
        *id = hit.id;
    mim_query_close(&q);
    return rc;
}

int mim_cmd_transfer(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'},      {"avatar", required_argument, 0, 'a'},
        {"template", required_argument, 0, 't'},   {"landmarks", required_argument, 0, 'l'},
        {"iterations", required_argument, 0, 'i'}, {"tol", required_argument, 0, 'T'},
        {"formulation", required_argument, 0, 'f'}, {"output", required_argument, 0, 'o'},
        {"json", no_argument, 0, 'j'},             {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0}};
    const char *store = NULL, *avatar = NULL, *tmpl_arg = NULL, *lm_path = NULL, *outp = NULL;
    uint64_t iterations = 0, tmpl_id = 0;
    double tol = 0.0;
    int as_json = 0, c;
    mim_xfer_formulation_t form = MIM_XFER_LEAST_SQUARES;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:a:t:l:i:T:f:o:jh", longopts, NULL)) != -1) {
        if (c == 's') store = optarg;
        else if (c == 'a') avatar = optarg;
        else if (c == 't') tmpl_arg = optarg;
        else if (c == 'l') lm_path = optarg;
        else if (c == 'o') outp = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 'i') {
            if (mim_cli_number("transfer", "iterations", optarg, 1, 1000, &iterations)) return 2;
        } else if (c == 'T') {
            char *end = NULL;
            tol = strtod(optarg, &end);
            if (!*optarg || *end || !(tol > 0.0) || !isfinite(tol)) {
                fprintf(stderr, "mimic transfer: --tol '%s' is not a positive number of metres\n", optarg);
                return 2;
            }
        } else if (c == 'f') {
            if (!strcmp(optarg, "least-squares")) form = MIM_XFER_LEAST_SQUARES;
            else if (!strcmp(optarg, "square")) form = MIM_XFER_SQUARE;
            else {
                fprintf(stderr, "mimic transfer: --formulation '%s': use least-squares or square\n", optarg);
                return 2;
            }
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
    if (tmpl_arg && mim_serve_template_id("transfer", tmpl_arg, &tmpl_id)) return 2;

    mim_error_t err = {0};
    mim_serve_session_t s;
    double t0 = mim_now();
    int rc = mim_serve_session_open(&s, store, avatar, &err);
    const uint32_t n = s.mesh.n_vertices, nl = s.map.count;
    float u[3 * MIM_LANDMARKS_MAX];
    mim_landmark_frames_t frames = {0};
    if (!rc && lm_path) {
        rc = mim_landmark_frames_read(lm_path, nl, 0, &frames, &err);
        if (!rc && frames.n_frames != 1)
            rc = mim_error_set(&err, MIM_EFORMAT, "%s: has %u frames; transfer takes one", lm_path, frames.n_frames);
        if (!rc)
            memcpy(u, frames.positions, 3 * (size_t)nl * sizeof(float));
        if (!rc && !tmpl_arg)
            rc = nearest_template(s.db, u, &tmpl_id, &err);
    }
    float *tpos = malloc(3 * (size_t)(n ? n : 1) * sizeof *tpos), *out = malloc(3 * (size_t)(n ? n : 1) * sizeof *out);
    double *F = malloc(9 * (size_t)(n ? n : 1) * sizeof *F);
    char label[256] = "";
    if (!rc && (!tpos || !out || !F)) rc = mim_error_set(&err, MIM_ENOMEM, "out of memory for %u vertices", n);
    if (!rc) rc = mim_serve_session_template(&s, tmpl_id, tpos, F, label, sizeof label, &err);
    /* mode (a): no landmarks given, so they come from the template */
    if (!rc && !lm_path) rc = mim_xfer_retarget_landmarks(&s.map, s.mesh.positions, tpos, u, &err);
    double t_load = mim_now() - t0;
    mim_xfer_solver_t *solver = NULL;
    mim_xfer_solver_options_t so = {.formulation = form};
    mim_xfer_report_t rep = {0};
    double t1 = mim_now(), t_open = 0.0, t_solve = 0.0;
    if (!rc) rc = mim_xfer_solver_open(&solver, s.topo, s.map.vertex, nl, &so, &err);
    t_open = mim_now() - t1;
    if (!rc) {
        mim_xfer_options_t o = {.max_iterations = (uint32_t)iterations, .tol = tol};
        t1 = mim_now();
        rc = mim_xfer_transfer(solver, s.W, n, F, u, nl, &o, out, &rep, &err);
        t_solve = mim_now() - t1;
    }
    if (!rc) {
        mim_mesh_t m = {n, s.mesh.n_faces, out, s.mesh.faces};
        rc = mim_xfer_write_mesh(outp, &m, &err);
    }
    if (rc) {
        fprintf(stderr, "mimic transfer: %s\n", mim_error_text(&err));
    } else if (as_json) {
        json_t *j = json_pack("{s:s, s:s, s:I, s:s, s:s, s:s, s:i, s:o, s:b, s:b, s:{s:f, s:f, s:f}}", "output", outp,
                              "avatar", s.avatar, "template", (json_int_t)tmpl_id, "template_label", label, "mode",
                              lm_path ? (tmpl_arg ? "template+landmarks" : "landmarks") : "template", "formulation",
                              form == MIM_XFER_SQUARE ? "square" : "least-squares", "iterations", (int)rep.iterations,
                              "last_move_m", isfinite(rep.last_move) ? json_real(rep.last_move) : json_null(), "converged",
                              rep.converged, "early_stopped", rep.early_stopped, "seconds", "load", t_load,
                              "factor", t_open, "transfer", t_solve);
        char *txt = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        printf("%s\n", txt ? txt : "{}");
        free(txt);
        json_decref(j);
    } else {
        fprintf(stderr, "mimic transfer: %s -> %s in the pose of template %llu (%s): %u iterations (%s), %.2f ms\n",
                s.avatar, outp, (unsigned long long)tmpl_id, label, rep.iterations,
                rep.converged ? "converged" : rep.early_stopped ? "stopped when the moves stopped shrinking"
                                                               : "iteration cap",
                1e3 * t_solve);
    }
    mim_xfer_solver_close(&solver);
    mim_landmark_frames_free(&frames);
    free(tpos), free(out), free(F);
    mim_serve_session_close(&s);
    return rc ? 1 : 0;
}
