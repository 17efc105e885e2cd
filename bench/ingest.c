/* bench/ingest: ingest throughput and store size.
 *
 * Makes a synthetic dataset (bodies of about 7000 vertices on one
 * connectivity), then ingests it into fresh stores: on one reader thread (the
 * issue's "one core" figure: parse + hash + commit) and on all cores. Each
 * figure is the median of several runs. A reference measured in the same run
 * (reading the same files' bytes with fread) gives a ratio that does not
 * depend on how busy this shared machine is. Also reports store bytes per
 * template against the raw float32 positions. mh-bodies is measured too when
 * it is beside the project.
 *
 * usage: bench_ingest [--meshes N] [--runs R] [--vertices V] [--shared DIR] */
#include "bench_data.h"
#include "mim_db.h"
#include "mim_ingest.h"
#include "mim_synth.h"

#include <ftw.h>
#include <sched.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int rm_one(const char *p, const struct stat *st, int f, struct FTW *w)
{
    (void)st, (void)f, (void)w;
    return remove(p);
}
static void rmtree(const char *p) { nftw(p, rm_one, 16, FTW_DEPTH | FTW_PHYS); }

/* Reference: read every file's bytes, nothing else. */
static double read_bytes_seconds(const mim_file_list_t *files)
{
    static char buf[1 << 20];
    double t0 = mim_now();
    for (size_t i = 0; i < files->count; i++) {
        FILE *f = fopen(files->paths[i], "rb");
        if (!f) continue;
        while (fread(buf, 1, sizeof buf, f) == sizeof buf) {
        }
        fclose(f);
    }
    return mim_now() - t0;
}

typedef struct {
    double rate_1core, rate_all, ref_rate, bytes_per_template, disk_per_template;
    uint32_t n_vertices;
    size_t meshes;
} result_t;

static int measure(const char *label, const char *data, const char *manifest, int runs, result_t *r)
{
    char *paths[] = {(char *)data};
    mim_file_list_t files;
    mim_error_t err = {0};
    if (mim_discover(paths, 1, &files, &err)) return fprintf(stderr, "%s\n", err.msg), 1;
    r->meshes = files.count;
    double one[32], all[32], ref[32];
    char store[4096];
    snprintf(store, sizeof store, "%s.store", data);
    for (int k = 0; k < runs; k++) {
        ref[k] = (double)files.count / read_bytes_seconds(&files);
        for (int threads = 1; threads <= 2; threads++) {
            rmtree(store);
            mim_db_t *db;
            if (mim_db_open(&db, store, NULL, &err)) return fprintf(stderr, "%s\n", err.msg), 1;
            mim_ingest_options_t opt = {.threads = (uint32_t)threads, .quiet = 1, .manifest_path = manifest};
            mim_ingest_report_t rep;
            /* "one core": the whole process pinned to one CPU, reader and writer alike */
            cpu_set_t saved, one_cpu;
            sched_getaffinity(0, sizeof saved, &saved);
            CPU_ZERO(&one_cpu);
            for (int cpu = 0; cpu < CPU_SETSIZE; cpu++)
                if (CPU_ISSET(cpu, &saved)) {
                    CPU_SET(cpu, &one_cpu);
                    break;
                }
            if (threads == 1) sched_setaffinity(0, sizeof one_cpu, &one_cpu);
            int failed = mim_ingest_run(db, paths, 1, &opt, &rep, &err) || rep.failed;
            sched_setaffinity(0, sizeof saved, &saved);
            if (failed) return fprintf(stderr, "ingest failed: %s\n", err.msg), 1;
            (threads == 1 ? one : all)[k] = (double)rep.added / rep.seconds;
            if (k == runs - 1 && threads == 1) {
                mim_db_stat_t st;
                mim_db_stat(db, &st, &err);
                mim_db_txn_t *t;
                mim_db_begin(db, 0, &t, &err);
                mim_db_topology_t topo;
                mim_db_topology_get(t, &topo, &err);
                r->n_vertices = topo.n_vertices;
                mim_db_abort(&t);
                r->bytes_per_template = (double)st.template_bytes / (double)rep.templates;
                r->disk_per_template = (double)st.disk_bytes / (double)rep.templates;
            }
            mim_db_close(&db);
        }
    }
    rmtree(store);
    r->rate_1core = bench_median(one, runs);
    r->rate_all = bench_median(all, runs);
    r->ref_rate = bench_median(ref, runs);
    double raw = 12.0 * r->n_vertices;
    printf("%-22s %6zu meshes  %6u verts  1 core: %7.1f meshes/s  all cores: %7.1f meshes/s  "
           "(fread-only reference %8.1f files/s: ingest at %.3f of it)  store: %.0f B/template = %.2f%% over raw %.0f B "
           "(disk %.0f B/template)\n",
           label, r->meshes, r->n_vertices, r->rate_1core, r->rate_all, r->ref_rate, r->rate_1core / r->ref_rate,
           r->bytes_per_template, 100.0 * (r->bytes_per_template / raw - 1), raw, r->disk_per_template);
    mim_file_list_free(&files);
    return 0;
}

int main(int argc, char **argv)
{
    int meshes = 200, runs = 5;
    uint32_t vertices = 7000;
    const char *shared = getenv("MIMIC_SHARED_DATA");
    static const struct option lo[] = {{"meshes", 1, 0, 'n'}, {"runs", 1, 0, 'r'}, {"vertices", 1, 0, 'v'},
                                       {"shared", 1, 0, 's'}, {"help", 0, 0, 'h'},   {0, 0, 0, 0}};
    int c;
    while ((c = getopt_long(argc, argv, "n:r:v:s:h", lo, NULL)) != -1) {
        if (c == 'n') meshes = atoi(optarg);
        else if (c == 'r') runs = atoi(optarg);
        else if (c == 'v') vertices = (uint32_t)atoi(optarg);
        else if (c == 's') shared = optarg;
        else {
            printf("usage: bench_ingest [--meshes N] [--runs R (<=32)] [--vertices V] [--shared DIR]\n");
            return c == 'h' ? 0 : 2;
        }
    }
    if (runs < 1 || runs > 32 || meshes < 1) return fprintf(stderr, "bench_ingest: bad --runs or --meshes\n"), 2;
    char tmpl[] = "/tmp/mimic-bench-XXXXXX";
    char *dir = mkdtemp(tmpl);
    char data[4200];
    snprintf(data, sizeof data, "%s/synth", dir);

    /* subjects x poses >= meshes */
    uint32_t subjects = 10, poses = (uint32_t)((meshes + 9) / 10);
    mim_synth_options_t so = {.subjects = subjects, .poses = poses, .vertices = vertices, .seed = 1};
    mim_synth_t *syn;
    mim_error_t err = {0};
    if (mim_synth_create(&syn, &so, &err) || mim_synth_write_dataset(syn, data, &err))
        return fprintf(stderr, "bench_ingest: %s\n", mim_error_text(&err)), 1;
    mim_synth_destroy(&syn);
    printf("bench_ingest: median of %d runs; one store per run; %ld cores\n", runs, sysconf(_SC_NPROCESSORS_ONLN));
    result_t r;
    int rc = measure("synth", data, NULL, runs, &r);
    if (!rc && shared) {
        char mh[4200], man[4300];
        snprintf(mh, sizeof mh, "%s/mh-bodies", shared);
        snprintf(man, sizeof man, "%s/manifest.csv", mh);
        if (access(mh, R_OK) == 0) {
            /* copy nothing: the store goes beside a temp symlink to the data */
            char link[4300];
            snprintf(link, sizeof link, "%s/mh-bodies", dir);
            if (symlink(mh, link) == 0) rc = measure("mh-bodies", link, man, runs, &r);
        }
    }
    rmtree(dir);
    return rc;
}
