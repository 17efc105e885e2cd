/* mimic register: one mesh of another connectivity onto the store's
 * connectivity (issue 13; register/ through ingest's registrar). */
#include "args.h"
#include "commands.h"
#include "mim_db.h"
#include "mim_ingest.h"
#include "mim_io.h"
#include "mim_query.h"

#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic register --store DIR [--landmarks FILE] MESH -o OUT.(ply|obj|off|stl|glb) [--json]\n"
            "                      [--max-distance-mm MM]\n\n"
            "Registers the store's connectivity onto MESH, a mesh of any connectivity (a scan, another\n"
            "dataset, an avatar), and writes the result: MESH's shape with the store's vertices and faces,\n"
            "vertex i where vertex i of a body belongs. It starts from the store's nearest template to\n"
            "MESH's landmarks (through the index), fits it to the landmarks, then closes the distance to\n"
            "the surface with non-rigid ICP.\n\n"
            "  --store DIR          the template store (read only; needs its index: mimic index)\n"
            "  --landmarks FILE     MESH's landmarks: its positions ({\"landmarks\": [[x, y, z], ...]}, the\n"
            "                       store map's order) or a landmark map of MESH's connectivity. Default:\n"
            "                       NAME.landmarks.json beside MESH, else a built-in map of a known\n"
            "                       connectivity (SMPL: FAUST and SMPL-family meshes)\n"
            "  -o, --output OUT     the registered mesh; the format follows the extension\n"
            "  --max-distance-mm MM refuse (write nothing, exit 1) when the surface distance p95 is over MM\n"
            "                       (default 15)\n"
            "  --json               the report on stdout (schemas/register.schema.json)\n"
            "  -h, --help           this help\n\n"
            "Exit status: 0 registered and written, 1 the mesh, its landmarks or the registration failed,\n"
            "2 bad usage, or the store cannot be opened or has no index.\n");
}

static json_t *report_json(const char *mesh, const char *outp, const mim_mesh_t *target, uint32_t n, const char *how,
                           uint64_t tid, const mim_template_view_t *tv, const mim_reg_report_t *r,
                           const mim_landmark_map_t *map)
{
    json_t *per = json_object(), *dist = json_object();
    for (uint32_t l = 0; l < r->n_landmarks; l++) json_object_set_new(per, map->names[l], json_real(r->landmark_mm[l]));
    for (int g = 0; g < MIM_REG_REGIONS; g++) json_object_set_new(dist, mim_reg_region_names[g], json_real(r->distortion_pct[g]));
    json_t *j = json_pack("{s:s, s:s, s:I, s:I, s:s, s:{s:I, s:s, s:s}, s:I, s:f, s:{s:f, s:f, s:f}, s:{s:f, s:f, s:o}, "
                     "s:{s:f, s:f, s:f}}",
                     "mesh", mesh, "output", outp, "vertices", (json_int_t)target->n_vertices, "store_vertices",
                     (json_int_t)n, "landmarks_from", how, "template", "id", (json_int_t)tid, "subject",
                     tv ? tv->subject : "", "pose", tv ? tv->pose : "", "iterations", (json_int_t)r->iterations,
                     "scale", r->scale, "surface_distance_mm", "mean", r->mean_mm, "p95", r->p95_mm, "max", r->max_mm,
                     "landmark_residuals_mm", "mean", r->landmark_mean_mm, "max", r->landmark_max_mm, "per_landmark",
                     per, "seconds", "initial", r->seconds_initial, "icp", r->seconds_icp, "total", r->seconds);
    if (j) {
        json_object_set_new(j, "distortion_percent", dist);
        json_object_set_new(j, "volume_ratio", isfinite(r->volume_ratio) ? json_real(r->volume_ratio) : json_null());
    } else {
        json_decref(dist);
    }
    return j;
}

int mim_cmd_register(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'},  {"landmarks", required_argument, 0, 'l'},
        {"output", required_argument, 0, 'o'}, {"max-distance-mm", required_argument, 0, 'D'},
        {"json", no_argument, 0, 'j'},         {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    const char *store = NULL, *outp = NULL;
    mim_ingest_landmark_sources_t src = {0};
    double max_mm = MIM_INGEST_DEFAULT_MAX_DISTANCE_MM;
    int as_json = 0, json_failed = 0, c;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:l:o:D:jh", longopts, NULL)) != -1) {
        switch (c) {
        case 's': store = optarg; break;
        case 'l': src.landmarks_path = optarg; break;
        case 'o': outp = optarg; break;
        case 'D':
            if (mim_cli_real("register", "max-distance-mm", optarg, 0.0, 1000.0, 1, "is not a distance in (0, 1000] mm",
                             &max_mm))
                return 2;
            break;
        case 'j': as_json = 1; break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic register: unknown or incomplete option '%s' (see mimic register --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (!store || !outp) {
        fprintf(stderr, "mimic register: --store DIR and -o OUT are required (see mimic register --help)\n");
        return 2;
    }
    if (optind != argc - 1) {
        fprintf(stderr, "mimic register: give exactly one MESH to register (%d given)\n", argc - optind);
        return 2;
    }
    if (!mim_io_format_known(outp)) {
        fprintf(stderr, "mimic register: %s: unknown output format (use .ply, .obj, .off, .stl or .glb)\n", outp);
        return 2;
    }
    const char *mesh_path = argv[optind];
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_options_t o = mim_cli_db_options(1);
    int rc = mim_db_open(&db, store, &o, &err);
    if (rc) {
        fprintf(stderr, "mimic register: %s\n", mim_error_text(&err));
        return 2;
    }
    mim_query_t *q = NULL;
    mim_ingest_registrar_t *r = NULL;
    if ((rc = mim_cli_registrar_open(db, "register", &q, &r))) {
        mim_db_close(&db);
        return rc;
    }
    const mim_landmark_map_t *map = mim_ingest_registrar_map(r);
    uint32_t nf, n = mim_xfer_topology_n_vertices(mim_ingest_registrar_topology(r));
    const uint32_t *faces = mim_ingest_registrar_faces(r, &nf);
    mim_mesh_t target = {0}, out = {0};
    float lm[3 * MIM_LANDMARKS_MAX];
    char how[4200] = "";
    mim_reg_report_t rep = {0};
    uint64_t tid = 0;
    int status = 1;
    if ((rc = mim_io_read_mesh(mesh_path, &target, &err)) ||
        (rc = mim_body_check(target.positions, target.n_vertices, mesh_path, &err)) ||
        (rc = mim_ingest_foreign_landmarks(mesh_path, &target, &src, map, lm, how, sizeof how, &err)))
        goto fail;
    if (mim_mesh_alloc(&out, n, nf)) {
        rc = mim_error_set(&err, MIM_ENOMEM, "out of memory");
        goto fail;
    }
    memcpy(out.faces, faces, (size_t)nf * 3 * sizeof *faces);
    if ((rc = mim_ingest_register_mesh(r, &target, lm, mesh_path, out.positions, &rep, &tid, &err))) goto fail;
    if (!(rep.p95_mm <= max_mm)) {
        rc = mim_error_set(&err, MIM_ETOPOLOGY,
                           "%s: registration too far from the surface: distance p95 %.1f mm over the %g mm limit "
                           "(mean %.1f mm, landmarks %.1f mm off): nothing written",
                           mesh_path, rep.p95_mm, max_mm, rep.mean_mm, rep.landmark_mean_mm);
        goto fail;
    }
    if ((rc = mim_io_write_mesh(outp, &out, &err))) goto fail;
    mim_db_txn_t *t = NULL;
    mim_template_view_t tv;
    int have_tv = !mim_db_begin(db, 0, &t, NULL) && !mim_db_template_get(t, tid, &tv, NULL);
    if (as_json) {
        json_t *j = report_json(mesh_path, outp, &target, n, how, tid, have_tv ? &tv : NULL, &rep, map);
        char *txt = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (txt) printf("%s\n", txt);
        else json_failed = 1, fprintf(stderr, "mimic register: cannot make the JSON report (is every path valid UTF-8?)\n");
        free(txt);
        json_decref(j);
    } else {
        printf("registered %s (%u vertices) onto the store's connectivity (%u vertices) in %.2f s, from template "
               "%llu%s%s%s%s%s: surface distance mean %.2f mm, p95 %.2f mm; landmarks %.1f mm off (mean); wrote %s\n",
               mesh_path, target.n_vertices, n, rep.seconds, (unsigned long long)tid, have_tv ? " (" : "",
               have_tv ? tv.subject : "", have_tv ? "/" : "", have_tv ? tv.pose : "", have_tv ? ")" : "", rep.mean_mm, rep.p95_mm,
               rep.landmark_mean_mm, outp);
    }
    mim_db_abort(&t);
    status = json_failed;
fail:
    if (status && err.code) fprintf(stderr, "mimic register: %s\n", mim_error_text(&err));
    mim_mesh_free(&target);
    mim_mesh_free(&out);
    mim_ingest_registrar_close(&r);
    mim_query_close(&q);
    mim_db_close(&db);
    return status;
}
