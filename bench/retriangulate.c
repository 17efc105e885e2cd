/* bench/retriangulate: a mesh file re-triangulated into ground truth for
 * register/ (tests/support/retriangulate.h): quadric decimation to about N
 * vertices or 1->4 midpoint subdivision, then optionally a random vertex
 * and face order. Every vertex of the output that was a vertex of the input
 * is exactly where it was; --map says which one it was.
 *
 * usage: bench_retriangulate IN OUT (--decimate N | --subdivide)
 *                            [--shuffle SEED] [--map FILE]
 *   IN, OUT  any mesh format io/ reads and writes (.ply, .obj, .off, .glb)
 *   --map    writes one line per output vertex: its index in IN, or -1 for
 *            a vertex that is new (a subdivision midpoint)
 * Prints the vertex and face counts and the time each step took. */
#include "mim_core.h"
#include "mim_io.h"
#include "retriangulate.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NO_VERTEX UINT32_MAX

static int usage(void)
{
    fprintf(stderr, "usage: bench_retriangulate IN OUT (--decimate N | --subdivide) [--shuffle SEED] [--map FILE]\n");
    return 2;
}

static int parse_u64(const char *s, uint64_t *v)
{
    char *end;
    errno = 0;
    unsigned long long x = strtoull(s, &end, 10);
    if (errno || end == s || *end || *s == '-')
        return -1;
    *v = x;
    return 0;
}

int main(int argc, char **argv)
{
    const char *in_path = NULL, *out_path = NULL, *map_path = NULL;
    uint64_t target = 0, seed = 0;
    int subdivide = 0, decimate = 0, shuffle = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--subdivide")) {
            subdivide = 1;
        } else if (!strcmp(a, "--decimate") || !strcmp(a, "--shuffle") || !strcmp(a, "--map")) {
            if (i + 1 >= argc) {
                fprintf(stderr, "bench_retriangulate: %s needs a value\n", a);
                return usage();
            }
            const char *v = argv[++i];
            if (!strcmp(a, "--map")) {
                map_path = v;
            } else if (parse_u64(v, !strcmp(a, "--decimate") ? &target : &seed)) {
                fprintf(stderr, "bench_retriangulate: %s %s: not a non-negative integer\n", a, v);
                return usage();
            } else if (!strcmp(a, "--decimate")) {
                decimate = 1;
            } else {
                shuffle = 1;
            }
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "bench_retriangulate: unknown option %s\n", a);
            return usage();
        } else if (!in_path) {
            in_path = a;
        } else if (!out_path) {
            out_path = a;
        } else {
            return usage();
        }
    }
    if (!in_path || !out_path || subdivide + decimate != 1)
        return usage();
    if (decimate && (target < 4 || target > UINT32_MAX)) {
        fprintf(stderr, "bench_retriangulate: --decimate %" PRIu64 ": at least 4 vertices\n", target);
        return 2;
    }

    mim_error_t err = {0};
    mim_mesh_t in = {0}, mid = {0}, out = {0};
    uint32_t *orig = NULL, *nofo = NULL; /* orig[v]: the input vertex of v, or NO_VERTEX */
    int rc, status = 1;
    double t0 = mim_now();
    if ((rc = mim_io_read_mesh(in_path, &in, &err))) {
        fprintf(stderr, "bench_retriangulate: %s\n", mim_error_text(&err));
        return 1;
    }
    double t_read = mim_now() - t0;
    printf("%s: %" PRIu32 " vertices, %" PRIu32 " faces (read %.3f s)\n", in_path, in.n_vertices, in.n_faces, t_read);

    t0 = mim_now();
    if (decimate) {
        rc = rt_decimate_map(&in, (uint32_t)target, &mid, &orig);
    } else {
        rc = rt_subdivide(&in, &mid);
        if (!rc && !(orig = malloc((size_t)mid.n_vertices * sizeof *orig)))
            rc = MIM_ENOMEM;
        for (uint32_t v = 0; !rc && v < mid.n_vertices; v++)
            orig[v] = v < in.n_vertices ? v : NO_VERTEX;
    }
    double t_step = mim_now() - t0;
    if (rc) {
        fprintf(stderr, "bench_retriangulate: %s: %s %s\n", in_path, decimate ? "decimate" : "subdivide",
                mim_strerror(rc));
        goto done;
    }
    printf("%s: %" PRIu32 " vertices, %" PRIu32 " faces (%.3f s)\n", decimate ? "decimate" : "subdivide",
           mid.n_vertices, mid.n_faces, t_step);

    if (shuffle) {
        t0 = mim_now();
        uint32_t *o2 = malloc((size_t)mid.n_vertices * sizeof *o2);
        nofo = malloc((size_t)mid.n_vertices * sizeof *nofo);
        rc = o2 && nofo ? rt_shuffle(&mid, seed, &out, nofo) : MIM_ENOMEM;
        if (rc) {
            free(o2);
            fprintf(stderr, "bench_retriangulate: shuffle: %s\n", mim_strerror(rc));
            goto done;
        }
        for (uint32_t v = 0; v < mid.n_vertices; v++)
            o2[nofo[v]] = orig[v];
        free(orig);
        orig = o2;
        printf("shuffle: seed %" PRIu64 " (%.3f s)\n", seed, mim_now() - t0);
    } else {
        out = mid;
        memset(&mid, 0, sizeof mid);
    }

    t0 = mim_now();
    if ((rc = mim_io_write_mesh(out_path, &out, &err))) {
        fprintf(stderr, "bench_retriangulate: %s\n", mim_error_text(&err));
        goto done;
    }
    printf("%s: %" PRIu32 " vertices, %" PRIu32 " faces (write %.3f s)\n", out_path, out.n_vertices, out.n_faces,
           mim_now() - t0);

    if (map_path) {
        FILE *f = fopen(map_path, "w");
        if (!f) {
            fprintf(stderr, "bench_retriangulate: %s: %s\n", map_path, strerror(errno));
            goto done;
        }
        for (uint32_t v = 0; v < out.n_vertices; v++)
            if (orig[v] == NO_VERTEX)
                fputs("-1\n", f);
            else
                fprintf(f, "%" PRIu32 "\n", orig[v]);
        if (fclose(f)) {
            fprintf(stderr, "bench_retriangulate: %s: %s\n", map_path, strerror(errno));
            goto done;
        }
    }
    status = 0;
done:
    free(orig), free(nofo);
    mim_mesh_free(&in), mim_mesh_free(&mid), mim_mesh_free(&out);
    return status;
}
