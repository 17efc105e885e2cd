/* The cost of driving an avatar of its own connectivity (issue 13, point
 * 5): per frame, the transfer runs on the store's connectivity (the
 * proxy) and the binding maps the result onto the avatar's vertices
 * (mim_reg_binding_apply). Prints figures; never passes or fails.
 *
 * Avatar: a body of the data set subdivided 1->4 once or twice until it
 * has at least --avatar-vertices vertices (default 50,000), in a random
 * vertex order (tests/support/retriangulate.h); proxy: the body itself
 * (what registration gives back for it, to within its error), posed by a
 * full transfer (the template's frames, the landmarks of another pose).
 * Both are timed in the same run, median of --runs (default 200); the
 * ratio is apply / transfer.
 *
 * usage: bench_bind [--vertices N] [--mh DIR | --no-mh] [--avatar-vertices N] [--runs R] */
#include "bench_data.h"
#include "mim_core.h"
#include "mim_register.h"
#include "mim_transfer.h"
#include "retriangulate.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct args {
    uint32_t avatar_vertices;
    int runs;
} args_t;

static int run_set(const bench_dataset_t *d, void *user)
{
    const args_t *a = user;
    const uint32_t n = d->n, c = d->map.count;
    mim_error_t err = {0};
    mim_mesh_t body = {n, d->n_faces, d->pos[0], d->faces}, sub = {0}, avatar = {0};
    mim_mesh_t cur = body;
    while (cur.n_vertices < a->avatar_vertices) {
        mim_mesh_t next = {0};
        if (rt_subdivide(&cur, &next)) return 1;
        if (cur.positions != body.positions) mim_mesh_free(&cur);
        cur = next;
    }
    sub = cur;
    if (rt_shuffle(&sub, 7, &avatar, NULL)) return 1;
    if (sub.positions != body.positions) mim_mesh_free(&sub);

    mim_reg_binding_t b;
    double t0 = mim_now();
    if (mim_reg_bind(&body, &avatar, &b, &err)) {
        fprintf(stderr, "%s: %s\n", d->name, mim_error_text(&err));
        return 1;
    }
    double t_bind = mim_now() - t0;

    /* the proxy's pose: subject 0's W, subject 1's frames in pose 3, subject 0's landmarks in pose 3 */
    mim_xfer_topology_t *topo = NULL;
    mim_xfer_solver_t *s = NULL;
    mim_xfer_solver_options_t so = {0};
    if (mim_xfer_topology_open(&topo, n, d->faces, d->n_faces, &err) ||
        mim_xfer_solver_open(&s, topo, d->map.vertex, c, &so, &err)) {
        fprintf(stderr, "%s: %s\n", d->name, mim_error_text(&err));
        return 1;
    }
    double *W = malloc(3 * (size_t)n * sizeof *W), *F = malloc(9 * (size_t)n * sizeof *F);
    float *targets = malloc(3 * (size_t)c * sizeof *targets), *pose = malloc(3 * (size_t)n * sizeof *pose);
    float *work = malloc(3 * (size_t)n * sizeof *work), *out = malloc(3 * (size_t)avatar.n_vertices * sizeof *out);
    double *vt = malloc(a->runs * sizeof *vt), *va = malloc(a->runs * sizeof *va);
    mim_xfer_frames(topo, d->pos[0], F);
    mim_xfer_encode(topo, d->pos[0], F, W);
    mim_xfer_frames(topo, d->pos[1 * d->poses + 3], F);
    for (uint32_t k = 0; k < c; k++) memcpy(targets + 3 * k, d->pos[3] + 3 * (size_t)d->map.vertex[k], 12);
    /* at rest the binding gives the avatar back */
    mim_reg_binding_apply(&b, d->faces, d->pos[0], work, out);
    double rest_err = 0;
    for (size_t i = 0; i < 3 * (size_t)avatar.n_vertices; i++) {
        double e = out[i] - avatar.positions[i];
        if (e < 0) e = -e;
        if (e > rest_err) rest_err = e;
    }
    for (int k = 0; k < a->runs; k++) {
        t0 = mim_now();
        mim_xfer_transfer(s, W, n, F, targets, c, NULL, pose, NULL, &err);
        double t1 = mim_now();
        mim_reg_binding_apply(&b, d->faces, pose, work, out);
        vt[k] = t1 - t0, va[k] = mim_now() - t1;
    }
    double mt = bench_median(vt, a->runs), ma = bench_median(va, a->runs);
    printf("| %s | %u | %u | %.3f | %.3f | %.2f | %.1f | %.1e |\n", d->name, n, avatar.n_vertices, 1e3 * mt, 1e3 * ma,
           ma / mt, t_bind, rest_err);
    mim_reg_binding_free(&b);
    mim_xfer_solver_close(&s);
    mim_xfer_topology_close(&topo);
    mim_mesh_free(&avatar);
    free(W), free(F), free(targets), free(pose), free(work), free(out), free(vt), free(va);
    return 0;
}

int main(int argc, char **argv)
{
    bench_sets_t sets;
    bench_sets_init(&sets);
    args_t a = {50000, 200};
    for (int i = 1; i < argc; i++) {
        if (bench_sets_arg(&sets, argc, argv, &i)) continue;
        if (!strcmp(argv[i], "--avatar-vertices") && i + 1 < argc) a.avatar_vertices = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) a.runs = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--vertices N] [--mh DIR | --no-mh] [--avatar-vertices N] [--runs R]\n", argv[0]);
            return 2;
        }
    }
    if (a.runs < 1) a.runs = 1;
    printf("| set | proxy vertices | avatar vertices | transfer (ms, median) | binding apply (ms, median) | apply / "
           "transfer | bind once (s) | largest rest error (m) |\n|---|---|---|---|---|---|---|---|\n");
    return bench_sets_run(&sets, 2, 4, run_set, &a);
}
