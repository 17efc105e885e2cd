/* mimic ingest: mesh files and folders into a template store. */
#include "args.h"
#include "commands.h"
#include "mim_db.h"
#include "mim_ingest.h"
#include "mim_query.h"
#include "output.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic ingest --store DIR [--landmarks FILE] [--manifest CSV] [--batch N] [--threads N]\n"
            "                    [--dataset NAME] [--register [--max-distance-mm MM]] PATH...\n\n"
            "Reads every mesh under each PATH (a file, or a folder walked recursively for\n"
            ".off .ply .obj .stl .gltf .glb), checks it, and stores it as a template.\n\n"
            "  --store DIR       the template store (created if missing)\n"
            "  --landmarks FILE  landmark map for a new store (default: landmarks.json beside the meshes,\n"
            "                    else the built-in map of the first mesh's connectivity: mimic landmarks maps);\n"
            "                    with --register, a landmark map of the meshes' own connectivity\n"
            "  --manifest CSV    labels: a CSV with columns file,subject,pose (default: labels from\n"
            "                    file names: FAUST tr_reg_NNN, SCAPE meshNNN, NAME_sSS_pPP)\n"
            "  --dataset NAME    the dataset the templates belong to (default: the folder each was\n"
            "                    ingested from, the PATH's own name for a folder). Subjects and poses are\n"
            "                    a dataset's own: two datasets' subject \"0\" are two people, and their\n"
            "                    poses form one class only when mimic index --pose-map maps them so\n"
            "                    (NAME: letters, digits, '.', '_', '-')\n"
            "  --batch N         templates per committed transaction (default 64)\n"
            "  --threads N       reader threads (default: one per core)\n"
            "  --register        register meshes of another connectivity onto the store's (landmarks from\n"
            "                    NAME.landmarks.json beside each, --landmarks or landmarks.json beside the\n"
            "                    dataset as a map of their connectivity, or a built-in map such as SMPL's);\n"
            "                    needs the store's index (mimic index); into an empty store the meshes go\n"
            "                    in as they are and make its connectivity\n"
            "  --max-distance-mm MM  refuse a registration whose surface distance p95 is over MM\n"
            "                    (default 15)\n"
            "  -q, --quiet       no per-file error lines\n"
            "  -h, --help        this help\n\n"
            "The first ingest into an empty store fixes its connectivity; later meshes must share it.\n"
            "The same content is stored once. Bad files are reported and skipped.\n"
            "Exit status: 0 all files went in (or were already there), 1 some file failed, 2 bad usage or\n"
            "the ingest could not run.\n");
}

/* Whether the store holds no connectivity yet (nothing ingested). */
static int store_is_empty(mim_db_t *db)
{
    mim_db_txn_t *t = NULL;
    mim_db_topology_t topo;
    if (mim_db_begin(db, 0, &t, NULL)) return 0;
    int empty = mim_db_topology_get(t, &topo, NULL) == MIM_ENOTFOUND;
    mim_db_abort(&t);
    return empty;
}

int mim_cmd_ingest(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"store", required_argument, 0, 's'},   {"landmarks", required_argument, 0, 'l'},
        {"manifest", required_argument, 0, 'm'}, {"batch", required_argument, 0, 'b'},
        {"threads", required_argument, 0, 't'}, {"quiet", no_argument, 0, 'q'},
        {"register", no_argument, 0, 'r'},      {"max-distance-mm", required_argument, 0, 'D'},
        {"dataset", required_argument, 0, 'd'}, {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    int do_register = 0;
    const char *store = NULL;
    mim_ingest_options_t opt = {.log = mim_cli_log, .progress = mim_cli_progress};
    optind = 0;
    opterr = 0;
    int c;
    uint64_t v;
    while ((c = getopt_long(argc, argv, "s:l:m:b:t:qh", longopts, NULL)) != -1) {
        switch (c) {
        case 's': store = optarg; break;
        case 'l': opt.landmarks_path = optarg; break;
        case 'm': opt.manifest_path = optarg; break;
        case 'b':
            if (mim_cli_number("ingest", "batch", optarg, 1, 1000000, &v)) return 2;
            opt.batch = (uint32_t)v;
            break;
        case 't':
            if (mim_cli_number("ingest", "threads", optarg, 1, 256, &v)) return 2;
            opt.threads = (uint32_t)v;
            break;
        case 'q': opt.quiet = 1; break;
        case 'r': do_register = 1; break;
        case 'd':
            if (!mim_ingest_dataset_valid(optarg)) {
                fprintf(stderr,
                        "mimic ingest: --dataset '%s': a name is 1 to %d of the letters, digits, '.', '_' and '-' "
                        "(not . or ..)\n",
                        optarg, MIM_INGEST_DATASET_MAX);
                return 2;
            }
            opt.dataset = optarg;
            break;
        case 'D':
            if (mim_cli_real("ingest", "max-distance-mm", optarg, 0.0, 1000.0, 1, "is not a distance in (0, 1000] mm",
                             &opt.max_distance_mm))
                return 2;
            break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic ingest: unknown or incomplete option '%s' (see mimic ingest --help)\n", argv[optind - 1]);
            return 2;
        }
    }
    if (!store) {
        fprintf(stderr, "mimic ingest: --store DIR is required (see mimic ingest --help)\n");
        return 2;
    }
    if (optind >= argc) {
        fprintf(stderr, "mimic ingest: no PATH given: name mesh files or folders to ingest\n");
        return 2;
    }
    mim_error_t err = {0};
    mim_db_t *db = NULL;
    mim_db_options_t o = mim_cli_db_options(0);
    int rc = mim_db_open(&db, store, &o, &err);
    if (rc) {
        fprintf(stderr, "mimic ingest: %s\n", mim_error_text(&err));
        return 2;
    }
    mim_query_t *q = NULL;
    if (do_register && store_is_empty(db)) {
        /* nothing to register onto yet: the first meshes make the store's
         * connectivity (never "run mimic index" on a store with nothing to index) */
        fprintf(stderr, "mimic ingest: note: %s is empty: the meshes are ingested as they are and their "
                        "connectivity becomes the store's; later ones of another connectivity are registered onto it\n",
                mim_db_path(db));
        do_register = 0;
    }
    if (do_register && (rc = mim_cli_registrar_open(db, "ingest", &q, &opt.registrar))) {
        mim_db_close(&db);
        return rc;
    }
    mim_ingest_report_t rep;
    rc = mim_ingest_run(db, argv + optind, (size_t)(argc - optind), &opt, &rep, &err);
    mim_ingest_registrar_close(&opt.registrar);
    mim_query_close(&q);
    mim_db_close(&db);
    if (rc) {
        fprintf(stderr, "mimic ingest: %s\n", mim_error_text(&err));
        return 2;
    }
    char skipped[64] = "", registered[64] = "";
    if (rep.registered)
        snprintf(registered, sizeof registered, " (%llu registered)", (unsigned long long)rep.registered);
    if (rep.skipped) /* symlink loops, each reported above */
        snprintf(skipped, sizeof skipped, ", %llu skipped", (unsigned long long)rep.skipped);
    printf("ingested %llu files in %.2f s (%.1f files/s): %llu added%s, %llu already stored, %llu failed%s; store holds "
           "%llu templates\n",
           (unsigned long long)rep.files, rep.seconds, rep.seconds > 0 ? (double)rep.files / rep.seconds : 0.0,
           (unsigned long long)rep.added, registered, (unsigned long long)rep.duplicates, (unsigned long long)rep.failed, skipped,
           (unsigned long long)rep.templates);
    return rep.failed ? 1 : 0;
}
