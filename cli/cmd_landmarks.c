/* mimic landmarks: the 16 landmarks mimic would use for a mesh, and where
 * they came from (a file, the sidecar beside it, a built-in map of its
 * connectivity, or its rig: issue 28), so that a user can check them or
 * write their own; the built-in maps, listed and exported. JSON:
 * schemas/landmarks-show.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_ingest.h"
#include "mim_io.h"
#include "mim_register.h"
#include "mim_session.h"

#include <float.h>
#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic landmarks show MESH [--landmarks FILE] [--avatar-mesh NAME]... [--json] [--svg OUT.svg]\n"
            "       mimic landmarks maps [--json]\n"
            "       mimic landmarks export NAME [-o FILE]\n\n"
            "show: the 16 landmarks mimic would use for MESH (an avatar or a scan of any\n"
            "connectivity), from the first that exists of: the file given, NAME.landmarks.json\n"
            "beside it, a built-in map of its connectivity (SMPL's: FAUST and kin), its rig (a\n"
            "skinned glTF/GLB or VRM whose joint names mimic knows: the landmarks are placed from\n"
            "the joints by the rules in register/rig_landmarks.c). Each landmark is a vertex of MESH.\n"
            "  --landmarks FILE     a landmark map of its connectivity, or its positions\n"
            "  --avatar-mesh NAME   a glTF scene: only the meshes (or nodes) of that name (repeatable)\n"
            "  --json               one JSON object on stdout (schemas/landmarks-show.schema.json)\n"
            "  --svg OUT.svg        a picture: the mesh from the front and the side, each landmark\n"
            "                       a dot with its name\n"
            "maps: the landmark maps built into mimic. export: one of them as a landmark map\n"
            "file (schemas/landmarks.schema.json), on stdout or to -o FILE.\n"
            "  -h, --help           this help\n");
}

/* The default 16 names (what every store's map is matched against by name). */
static void default_map(mim_landmark_map_t *map)
{
    uint32_t v[MIM_LANDMARKS_DEFAULT_COUNT] = {0};
    mim_landmarks_default(map, v, 0);
}

/* The mesh's vertex nearest to p. */
static uint32_t nearest_vertex(const mim_mesh_t *m, const float *p, double *dist)
{
    uint32_t best = 0;
    double bd = DBL_MAX;
    for (uint32_t i = 0; i < m->n_vertices; i++) {
        double d = 0;
        for (int c = 0; c < 3; c++) d += pow((double)m->positions[3 * (size_t)i + c] - p[c], 2);
        if (d < bd) bd = d, best = i;
    }
    *dist = sqrt(bd);
    return best;
}

/* Front (x, y) and side (z, y) views, the mesh as dots, the landmarks named. */
static int write_svg(const char *path, const mim_mesh_t *m, const mim_landmark_map_t *map, const float *lm,
                     mim_error_t *err)
{
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (uint32_t i = 0; i < m->n_vertices; i++)
        for (int c = 0; c < 3; c++)
            lo[c] = fminf(lo[c], m->positions[3 * (size_t)i + c]), hi[c] = fmaxf(hi[c], m->positions[3 * (size_t)i + c]);
    const double H = 560, scale = H / fmax(1e-6, hi[1] - lo[1]), pad = 110;
    const double wf = (hi[0] - lo[0]) * scale, ws = (hi[2] - lo[2]) * scale, W = wf + ws + 4 * pad;
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (!f) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    fprintf(f, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" viewBox=\"0 0 %.0f %.0f\" "
               "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
            W, H + 60, W, H + 60);
    const uint32_t step = m->n_vertices > 3000 ? m->n_vertices / 3000 : 1;
    for (int view = 0; view < 2; view++) {
        /* front: the body's left (+X) on the picture's right, as a mirror; side: facing right (+Z) */
        const int ax = view == 0 ? 0 : 2;
        const double x0 = view == 0 ? pad : wf + 3 * pad;
        fprintf(f, "<text x=\"%.1f\" y=\"20\" font-weight=\"bold\">%s</text>\n", x0,
                view == 0 ? "front" : "side (facing right)");
        /* the vertices as round dots: zero-length strokes of one path */
        fprintf(f, "<path stroke=\"#b9c2cc\" stroke-width=\"2\" stroke-linecap=\"round\" d=\"");
        for (uint32_t i = 0; i < m->n_vertices; i += step) {
            const float *p = m->positions + 3 * (size_t)i;
            fprintf(f, "M%.0f %.0fh0", x0 + (p[ax] - lo[ax]) * scale, 40 + (hi[1] - p[1]) * scale);
        }
        fprintf(f, "\"/>\n");
        for (uint32_t l = 0; l < map->count; l++) {
            const float *p = lm + 3 * l;
            const double x = x0 + (p[ax] - lo[ax]) * scale, y = 40 + (hi[1] - p[1]) * scale;
            /* labels left of the body for its right side, right of it for its left */
            const int right_label = view == 1 || p[0] >= 0.5 * (lo[0] + hi[0]);
            fprintf(f, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"4.5\" fill=\"#e8692a\" stroke=\"#7a2e06\"/>\n", x, y);
            if (view == 1 && !strncmp(map->names[l], "r_", 2)) continue; /* behind its left twin, seen from the side */
            fprintf(f, "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"%s\">%s</text>\n", x + (right_label ? 8 : -8), y + 4,
                    right_label ? "start" : "end", map->names[l]);
        }
    }
    fprintf(f, "</svg>\n");
    if (fclose(f)) {
        free(buf);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    }
    mim_file_part_t part = {buf, len};
    int rc = mim_file_write_atomic(path, &part, 1, err);
    free(buf);
    return rc;
}

static int show(int argc, char **argv)
{
    static const struct option longopts[] = {{"landmarks", required_argument, 0, 'l'}, {"json", no_argument, 0, 'j'},
                                             {"svg", required_argument, 0, 's'},       {"help", no_argument, 0, 'h'},
                                             MIM_CLI_AVATAR_LONGOPTS,                  {0, 0, 0, 0}};
    const char *lm_file = NULL, *svg = NULL;
    mim_cli_avatar_t av = {0};
    int as_json = 0, c;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "l:js:h", longopts, NULL)) != -1) {
        if (c == 'l') lm_file = optarg;
        else if (c == 'j') as_json = 1;
        else if (c == 's') svg = optarg;
        else if (c == 'h') return help(stdout), 0;
        else if (c == MIM_CLI_OPT_AVATAR_MESH) {
            if (mim_cli_avatar_option("landmarks show", c, optarg, &av) < 0) return 2;
        } else {
            fprintf(stderr, "mimic landmarks show: unknown or incomplete option '%s' (see mimic landmarks --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (optind + 1 != argc) {
        fprintf(stderr, "mimic landmarks show: give one mesh file (see mimic landmarks --help)\n");
        return 2;
    }
    const char *path = argv[optind];
    mim_error_t err = {0};
    mim_io_scene_t scene;
    const mim_io_read_options_t ro = {.meshes = av.meshes, .n_meshes = av.n_meshes};
    if (mim_io_read_scene(path, &ro, &scene, &err)) {
        fprintf(stderr, "mimic landmarks show: %s\n", mim_error_text(&err));
        return 1;
    }
    mim_landmark_map_t map;
    default_map(&map);
    float lm[3 * MIM_LANDMARKS_MAX];
    char how[4200] = "";
    const char *source = "file";
    mim_ingest_landmark_sources_t src = {.landmarks_path = lm_file};
    int rc = mim_ingest_foreign_landmarks(path, &scene.mesh, &src, &map, lm, how, sizeof how, &err);
    char sidecar[4096];
    if (!rc && !lm_file) source = mim_io_landmarks_sidecar(path, sidecar, sizeof sidecar) == 1 ? "sidecar" : "built-in map";
    if (rc == MIM_ENOLANDMARKS && scene.skin_rc == 0) {
        mim_error_t rig_err = {0};
        if (!(rc = mim_session_rig_landmarks(&scene.mesh, &scene.skin, &map, lm, how, sizeof how, &rig_err)))
            source = "rig";
        else
            mim_error_set(&err, rc, "%s; nor from its rig: %s", mim_error_text(&err), mim_error_text(&rig_err));
    }
    if (rc) {
        fprintf(stderr, "mimic landmarks show: %s\n", mim_error_text(&err));
        mim_io_scene_free(&scene);
        return 1;
    }
    if (svg && (rc = write_svg(svg, &scene.mesh, &map, lm, &err))) {
        fprintf(stderr, "mimic landmarks show: %s\n", mim_error_text(&err));
        mim_io_scene_free(&scene);
        return 1;
    }
    json_t *arr = json_array();
    for (uint32_t l = 0; l < map.count; l++) {
        double d = 0;
        uint32_t v = nearest_vertex(&scene.mesh, lm + 3 * l, &d);
        json_array_append_new(arr, json_pack("{s:s, s:[f, f, f], s:i, s:f}", "name", map.names[l], "position",
                                             (double)lm[3 * l], (double)lm[3 * l + 1], (double)lm[3 * l + 2],
                                             "vertex", (int)v, "vertex_distance_m", d));
    }
    if (as_json) {
        json_t *j = json_pack("{s:s, s:s, s:s, s:i, s:i, s:o}", "mesh", path, "source", source, "from", how,
                              "vertices", (int)scene.mesh.n_vertices, "parts", (int)scene.n_parts, "landmarks", arr);
        char *txt = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (txt) printf("%s\n", txt);
        else rc = 1, fprintf(stderr, "mimic landmarks show: cannot make the JSON report (is the path valid UTF-8?)\n");
        free(txt);
        json_decref(j);
    } else {
        printf("%s: %u vertices in %u parts; landmarks from %s\n", path, scene.mesh.n_vertices, scene.n_parts, how);
        for (uint32_t l = 0; l < map.count; l++) {
            json_t *e = json_array_get(arr, l);
            printf("  %-11s %9.4f %9.4f %9.4f   vertex %lld\n", map.names[l], (double)lm[3 * l], (double)lm[3 * l + 1],
                   (double)lm[3 * l + 2], (long long)json_integer_value(json_object_get(e, "vertex")));
        }
        if (svg) printf("wrote %s\n", svg);
        json_decref(arr);
    }
    mim_io_scene_free(&scene);
    return rc ? 1 : 0;
}

static int maps(int argc, char **argv)
{
    int as_json = argc > 1 && !strcmp(argv[1], "--json");
    if (argc > 1 && !as_json) {
        if (!strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) return help(stdout), 0;
        fprintf(stderr, "mimic landmarks maps: unexpected argument '%s' (see mimic landmarks --help)\n", argv[1]);
        return 2;
    }
    json_t *arr = json_array();
    for (uint32_t i = 0; i < mim_reg_known_map_count(); i++) {
        mim_landmark_map_t m;
        mim_error_t e = {0};
        const char *text = mim_reg_known_map_text(i);
        uint32_t nv = mim_landmarks_parse(&m, text, strlen(text), mim_reg_known_map_name(i), &e) == 0 ? m.topology_vertices : 0;
        json_array_append_new(arr, json_pack("{s:s, s:i}", "name", mim_reg_known_map_name(i), "topology_vertices",
                                             (int)nv));
        if (!as_json) printf("%-24s %u vertices\n", mim_reg_known_map_name(i), nv);
    }
    if (as_json) {
        char *txt = json_dumps(arr, JSON_INDENT(2));
        if (txt) printf("%s\n", txt);
        free(txt);
    }
    json_decref(arr);
    return 0;
}

static int export_map(int argc, char **argv)
{
    const char *name = NULL, *out = NULL;
    for (int i = 1; i < argc; i++) {
        if ((!strcmp(argv[i], "-o") || !strcmp(argv[i], "--output")) && i + 1 < argc) out = argv[++i];
        else if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) return help(stdout), 0;
        else if (argv[i][0] != '-' && !name) name = argv[i];
        else {
            fprintf(stderr, "mimic landmarks export: unexpected argument '%s' (see mimic landmarks --help)\n", argv[i]);
            return 2;
        }
    }
    if (!name) {
        fprintf(stderr, "mimic landmarks export: give a built-in map's name (mimic landmarks maps lists them)\n");
        return 2;
    }
    for (uint32_t i = 0; i < mim_reg_known_map_count(); i++) {
        if (strcmp(mim_reg_known_map_name(i), name)) continue;
        const char *text = mim_reg_known_map_text(i);
        if (!out) return fputs(text, stdout) < 0 ? 1 : 0;
        mim_error_t err = {0};
        mim_file_part_t part = {text, strlen(text)};
        if (mim_file_write_atomic(out, &part, 1, &err)) {
            fprintf(stderr, "mimic landmarks export: %s\n", mim_error_text(&err));
            return 1;
        }
        return 0;
    }
    fprintf(stderr, "mimic landmarks export: no built-in map named '%s' (mimic landmarks maps lists them)\n", name);
    return 1;
}

int mim_cmd_landmarks(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) {
        help(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (!strcmp(argv[1], "show")) return show(argc - 1, argv + 1);
    if (!strcmp(argv[1], "maps")) return maps(argc - 1, argv + 1);
    if (!strcmp(argv[1], "export")) return export_map(argc - 1, argv + 1);
    fprintf(stderr, "mimic landmarks: unknown subcommand '%s' (show, maps or export; see mimic landmarks --help)\n",
            argv[1]);
    return 2;
}
