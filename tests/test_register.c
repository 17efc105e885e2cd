/* register/ (issue 13): registration of the store's connectivity onto a
 * mesh of another connectivity, the similarity fit, the target checks,
 * the binding of a foreign avatar; then mimic register and mimic ingest
 * --register end to end.
 *
 * Ground truth by re-triangulation (support/retriangulate.h): the target
 * is a synth body subdivided and renumbered, or decimated, so that it
 * shares no connectivity with the store while the true place of store
 * vertex i is the original body's vertex i. The registration starts from
 * another subject (library) or from the store's nearest template of a
 * store that does not hold the target's subject (CLI), so it has to move
 * every vertex to be right. */
#include "mim_db.h"
#include "mim_io.h"
#include "mim_register.h"
#include "mim_synth.h"
#include "mim_transfer.h"
#include "retriangulate.h"
#include "test_support.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h> /* memmem: _GNU_SOURCE comes from CMakeLists.txt */
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

/* The library cases: one synth dataset in memory. */
#define L_SUBJECTS 2
#define L_POSES 3
#define L_VERTICES 2000
static uint32_t n, nf;
static uint32_t *faces;
static mim_landmark_map_t map;
static mim_xfer_topology_t *topo;
static float *lib_body[L_SUBJECTS][L_POSES];

/* The CLI cases: mimic synth 4 subjects x 6 poses; the store holds
 * subjects 0..2, subject 3 is the foreign meshes' truth. */
#define C_SUBJECTS 4
#define C_POSES 6
#define C_STORED_SUBJECTS 3
static char *dir, *bodies, *store;
static uint32_t cli_n, cli_nf;
static uint32_t *cli_faces;

/* Targets of the surface and correspondence figures (mm). */
#define CORR_MEAN_MM 15.0
#define CORR_P95_MM 40.0
#define SURF_MEAN_MM 1.0

static int run_quiet(const char *const *args)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc) fprintf(stderr, "mimic %s exited %d: %s\n", args[0], rc, e ? e : "");
    free(o), free(e);
    return rc;
}

static char *body_path(int s, int p)
{
    char name[64];
    mim_synth_file_name((uint32_t)s, (uint32_t)p, name, sizeof name);
    return ts_path(bodies, name);
}

static int setup(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_synth_t *syn = NULL;
    mim_synth_options_t so = {.subjects = L_SUBJECTS, .poses = L_POSES, .vertices = L_VERTICES, .seed = 7};
    if (mim_synth_create(&syn, &so, &err)) return -1;
    n = mim_synth_n_vertices(syn), nf = mim_synth_n_faces(syn);
    faces = malloc((size_t)nf * 3 * sizeof *faces);
    memcpy(faces, mim_synth_faces(syn), (size_t)nf * 3 * sizeof *faces);
    mim_synth_landmarks(syn, &map);
    for (int s = 0; s < L_SUBJECTS; s++)
        for (int p = 0; p < L_POSES; p++) {
            lib_body[s][p] = malloc((size_t)3 * n * sizeof(float));
            if (mim_synth_body(syn, (uint32_t)s, (uint32_t)p, lib_body[s][p])) return -1;
        }
    mim_synth_destroy(&syn);
    if (mim_xfer_topology_open(&topo, n, faces, nf, &err)) return -1;

    /* the CLI store: subjects 0..2 ingested (file by file), indexed */
    dir = ts_tempdir("register");
    bodies = ts_path(dir, "bodies");
    store = ts_path(dir, "store");
    char sub[8], pos[8];
    snprintf(sub, sizeof sub, "%d", C_SUBJECTS), snprintf(pos, sizeof pos, "%d", C_POSES);
    const char *synth[] = {"synth", "--out", bodies, "--subjects", sub, "--poses", pos, "--vertices", "2000", NULL};
    if (run_quiet(synth)) return -1;
    char *lm = ts_path(bodies, "landmarks.json");
    const char *ingest[4 + C_STORED_SUBJECTS * C_POSES + 3] = {"ingest", "--store", store, "--landmarks", lm};
    int k = 5;
    char *paths[C_STORED_SUBJECTS * C_POSES];
    for (int s = 0; s < C_STORED_SUBJECTS; s++)
        for (int p = 0; p < C_POSES; p++) {
            paths[s * C_POSES + p] = body_path(s, p);
            ingest[k++] = paths[s * C_POSES + p];
        }
    ingest[k] = NULL;
    int rc = run_quiet(ingest);
    for (int i = 0; i < C_STORED_SUBJECTS * C_POSES; i++) free(paths[i]);
    free(lm);
    const char *index[] = {"index", "--store", store, NULL};
    if (rc || run_quiet(index)) return -1;
    char *first = body_path(0, 0);
    mim_mesh_t m = {0};
    rc = mim_io_read_mesh(first, &m, &err);
    free(first);
    if (rc) return -1;
    cli_n = m.n_vertices, cli_nf = m.n_faces, cli_faces = m.faces;
    m.faces = NULL;
    mim_mesh_free(&m);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    for (int s = 0; s < L_SUBJECTS; s++)
        for (int p = 0; p < L_POSES; p++) free(lib_body[s][p]);
    mim_xfer_topology_close(&topo);
    free(faces), free(cli_faces);
    ts_rmtree(dir);
    free(dir), free(bodies), free(store);
    return 0;
}

/* ---- figures ---- */
static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Per-vertex distance (mm) of a to b: mean and p95 (the report's quantile). */
static void correspondence(const float *a, const float *b, uint32_t count, double *mean_mm, double *p95_mm)
{
    double *d = malloc(count * sizeof *d), sum = 0;
    for (uint32_t i = 0; i < count; i++) {
        double s = 0;
        for (int c = 0; c < 3; c++) s += ((double)a[3 * i + c] - b[3 * i + c]) * ((double)a[3 * i + c] - b[3 * i + c]);
        d[i] = 1000.0 * sqrt(s), sum += d[i];
    }
    qsort(d, count, sizeof *d, cmp_d);
    *mean_mm = sum / count, *p95_mm = d[(size_t)floor(0.95 * (count - 1))];
    free(d);
}

static void landmarks_of(const float *body, const mim_landmark_map_t *m, float *out)
{
    for (uint32_t l = 0; l < m->count; l++) memcpy(out + 3 * l, body + 3 * (size_t)m->vertex[l], 3 * sizeof *out);
}

/* The target of a truth body: 0 subdivided 1->4 and renumbered, 1 decimated
 * to ~40 % and renumbered. */
static void retriangulate(const float *truth, uint32_t count, const uint32_t *f, uint32_t count_f, int how,
                          uint64_t seed, mim_mesh_t *target)
{
    mim_mesh_t body = {count, count_f, (float *)truth, (uint32_t *)f}, mid = {0};
    if (how == 0) assert_int_equal(rt_subdivide(&body, &mid), 0);
    else assert_int_equal(rt_decimate(&body, (uint32_t)(0.4 * count), &mid), 0);
    assert_int_equal(rt_shuffle(&mid, seed, target, NULL), 0);
    mim_mesh_free(&mid);
    assert_int_not_equal(target->n_vertices, count);
}

/* ---- registration, library ---- */

/* Subject 0 in pose 2, re-triangulated, registered from subject 1 in the
 * same pose: every vertex lands near its true place, on the surface, and
 * the report's figures are what mim_reg_surface_distance measures. */
static void test_round_trip(void **s)
{
    (void)s;
    mim_error_t err = {0};
    mim_reg_t *reg = NULL;
    assert_int_equal(mim_reg_open(&reg, topo, &map, NULL, &err), 0);
    const float *truth = lib_body[0][2], *tmpl = lib_body[1][2];
    float lm[3 * MIM_LANDMARKS_MAX], *out = malloc((size_t)3 * n * sizeof *out);
    double *dist = malloc(n * sizeof *dist);
    landmarks_of(truth, &map, lm);
    double start_mean, start_p95;
    correspondence(tmpl, truth, n, &start_mean, &start_p95);
    for (int how = 0; how < 2; how++) {
        mim_mesh_t target = {0};
        retriangulate(truth, n, faces, nf, how, 11 + how, &target);
        mim_reg_report_t rep;
        memset(&rep, 0xff, sizeof rep);
        int rc = mim_reg_run(reg, tmpl, &target, lm, "target.ply", out, &rep, &err);
        if (rc) fail_msg("%s", mim_error_text(&err));
        double cm, cp;
        correspondence(out, truth, n, &cm, &cp);
        assert_int_equal(mim_reg_surface_distance(&target, out, n, dist, &err), 0);
        double sum = 0, mx = 0;
        for (uint32_t i = 0; i < n; i++) sum += dist[i], mx = dist[i] > mx ? dist[i] : mx;
        double surf_mm = 1000.0 * sum / n;
        print_message("%s (%u vertices): correspondence mean %.1f mm, p95 %.1f mm (the template: %.1f, %.1f); "
                      "surface mean %.3f mm, p95 %.3f mm; %u ICP steps\n",
                      how ? "decimated" : "subdivided", target.n_vertices, cm, cp, start_mean, start_p95, surf_mm,
                      rep.p95_mm, rep.iterations);
        assert_true(cm <= CORR_MEAN_MM);
        assert_true(cp <= CORR_P95_MM);
        assert_true(surf_mm <= SURF_MEAN_MM);
        /* the report: its figures are the measured ones */
        assert_true(fabs(rep.mean_mm - surf_mm) <= 1e-3);
        assert_true(fabs(rep.max_mm - 1000.0 * mx) <= 1e-3);
        assert_true(rep.p95_mm >= 0 && rep.p95_mm <= rep.max_mm && rep.mean_mm <= rep.max_mm);
        assert_true(isfinite(rep.scale) && rep.scale > 0.8 && rep.scale < 1.25);
        assert_true(rep.iterations >= 1);
        assert_int_equal(rep.n_landmarks, map.count);
        double lsum = 0, lmax = 0;
        for (uint32_t l = 0; l < map.count; l++) {
            const float *a = out + 3 * (size_t)map.vertex[l], *b = lm + 3 * l;
            double d = 1000.0 * sqrt(((double)a[0] - b[0]) * (a[0] - b[0]) + ((double)a[1] - b[1]) * (a[1] - b[1]) +
                                     ((double)a[2] - b[2]) * (a[2] - b[2]));
            assert_true(fabs(rep.landmark_mm[l] - d) <= 1e-3);
            lsum += d, lmax = d > lmax ? d : lmax;
        }
        assert_true(fabs(rep.landmark_mean_mm - lsum / map.count) <= 1e-3);
        assert_true(fabs(rep.landmark_max_mm - lmax) <= 1e-3);
        assert_true(rep.landmark_max_mm < 30.0);
        assert_true(rep.rejected >= 0 && rep.rejected <= 1);
        assert_true(rep.seconds_initial >= 0 && rep.seconds_icp >= 0 && rep.seconds >= rep.seconds_icp);
        /* the same run again gives the same bytes (FLANN searched exactly, no randomness) */
        float *again = malloc((size_t)3 * n * sizeof *again);
        assert_int_equal(mim_reg_run(reg, tmpl, &target, lm, "target.ply", again, NULL, &err), 0);
        assert_memory_equal(again, out, (size_t)3 * n * sizeof *out);
        free(again);
        mim_mesh_free(&target);
    }
    free(out), free(dist);
    mim_reg_close(&reg);
    assert_null(reg);
    mim_reg_close(&reg); /* accepts NULL */
}

/* NaN or missing landmarks, and missing arguments: an error, never a run. */
static void test_run_bad_input(void **s)
{
    (void)s;
    mim_error_t err = {0};
    mim_reg_t *reg = NULL;
    assert_int_equal(mim_reg_open(&reg, topo, &map, NULL, &err), 0);
    const float *truth = lib_body[0][1];
    mim_mesh_t target = {0};
    retriangulate(truth, n, faces, nf, 0, 5, &target);
    float lm[3 * MIM_LANDMARKS_MAX], *out = malloc((size_t)3 * n * sizeof *out);
    landmarks_of(truth, &map, lm);
    lm[3 * 4 + 1] = NAN;
    memset(&err, 0, sizeof err);
    assert_int_equal(mim_reg_run(reg, lib_body[1][1], &target, lm, "scan.ply", out, NULL, &err), MIM_ENONFINITE);
    assert_non_null(strstr(err.msg, "scan.ply"));
    assert_non_null(strstr(err.msg, "landmark 4"));
    assert_null(strchr(err.msg, '\n'));
    lm[3 * 4 + 1] = INFINITY;
    assert_int_equal(mim_reg_run(reg, lib_body[1][1], &target, lm, "scan.ply", out, NULL, &err), MIM_ENONFINITE);
    landmarks_of(truth, &map, lm);
    /* all landmarks at one point: no similarity to fit */
    for (uint32_t l = 1; l < map.count; l++) memcpy(lm + 3 * l, lm, 3 * sizeof *lm);
    assert_true(mim_reg_run(reg, lib_body[1][1], &target, lm, "scan.ply", out, NULL, &err) < 0);
    assert_non_null(strstr(err.msg, "scan.ply"));
    landmarks_of(truth, &map, lm);
    assert_int_equal(mim_reg_run(reg, NULL, &target, lm, "scan.ply", out, NULL, &err), MIM_EINVAL);
    assert_int_equal(mim_reg_run(reg, lib_body[1][1], NULL, lm, "scan.ply", out, NULL, &err), MIM_EINVAL);
    assert_int_equal(mim_reg_run(reg, lib_body[1][1], &target, NULL, "scan.ply", out, NULL, &err), MIM_EINVAL);
    /* a bad target is the target check's error, named */
    target.positions[3 * 9 + 2] = NAN;
    memset(&err, 0, sizeof err);
    assert_int_equal(mim_reg_run(reg, lib_body[1][1], &target, lm, "scan.ply", out, NULL, &err), MIM_ENONFINITE);
    assert_non_null(strstr(err.msg, "scan.ply: vertex 9"));
    mim_mesh_free(&target);
    free(out);
    mim_reg_close(&reg);
    /* open: no map, or a map past the connectivity */
    assert_int_equal(mim_reg_open(&reg, topo, NULL, NULL, &err), MIM_EINVAL);
    assert_null(reg);
    mim_landmark_map_t bad = map;
    bad.vertex[3] = n;
    assert_true(mim_reg_open(&reg, topo, &bad, NULL, &err) < 0);
    assert_null(reg);
}

/* ---- the similarity fit ---- */
static void rotation(double axis_x, double axis_y, double axis_z, double angle, double R[9])
{
    mim_quat q = mim_quat_axis_angle(mim_v3_normalize(mim_v3(axis_x, axis_y, axis_z)), angle);
    mim_quat_to_matrix(q, R);
}

static double det3(const double m[9])
{
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[3] * (m[1] * m[8] - m[2] * m[7]) + m[6] * (m[1] * m[5] - m[2] * m[4]);
}

static void test_similarity(void **s)
{
    (void)s;
    mim_rng_t rng;
    mim_rng_seed(&rng, 42, 0);
    float src[3 * 16], dst[3 * 16], back[3 * 16];
    for (int i = 0; i < 3 * 16; i++) src[i] = (float)(mim_rng_unit(&rng) - 0.5);
    double R[9], scale = 1.37, t[3] = {0.25, -1.5, 3.0};
    rotation(0.3, -1.0, 0.6, 2.1, R);
    mim_reg_similarity_t known = {scale, {0}, {t[0], t[1], t[2]}};
    memcpy(known.R, R, sizeof R);
    mim_reg_similarity_apply(&known, src, 16, dst);
    mim_error_t err = {0};
    mim_reg_similarity_t fit;
    assert_int_equal(mim_reg_similarity_fit(src, dst, 16, &fit, &err), 0);
    assert_true(fabs(fit.scale - scale) < 1e-5);
    for (int k = 0; k < 9; k++) assert_true(fabs(fit.R[k] - R[k]) < 1e-5);
    for (int k = 0; k < 3; k++) assert_true(fabs(fit.t[k] - t[k]) < 1e-5);
    mim_reg_similarity_apply(&fit, src, 16, back);
    for (int i = 0; i < 3 * 16; i++) assert_true(fabsf(back[i] - dst[i]) < 1e-5f);

    /* a mirror image: the best rotation, never a reflection */
    float mirrored[3 * 16];
    for (int i = 0; i < 16; i++)
        mirrored[3 * i] = -src[3 * i], mirrored[3 * i + 1] = src[3 * i + 1], mirrored[3 * i + 2] = src[3 * i + 2];
    assert_int_equal(mim_reg_similarity_fit(src, mirrored, 16, &fit, &err), 0);
    assert_true(fabs(det3(fit.R) - 1.0) < 1e-9);
    assert_true(fit.scale > 0);
    /* R is orthonormal */
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double d = 0;
            for (int k = 0; k < 3; k++) d += fit.R[3 * a + k] * fit.R[3 * b + k];
            assert_true(fabs(d - (a == b)) < 1e-9);
        }

    /* too few, collinear, all at one point */
    memset(&err, 0, sizeof err);
    assert_int_equal(mim_reg_similarity_fit(src, dst, 2, &fit, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "3"));
    /* collinear as floats are: decimals rounded off the line, near the
     * origin and 500 m from it; as source and as destination */
    float line[3 * 16], far[3 * 16], same[3 * 16];
    for (int i = 0; i < 16; i++) {
        line[3 * i] = 0.1f * i, line[3 * i + 1] = 0.2f * i + 1, line[3 * i + 2] = -0.05f * i;
        far[3 * i] = 500.0f + 0.1f * i, far[3 * i + 1] = 0.2f * i + 1, far[3 * i + 2] = -0.05f * i;
        same[3 * i] = 1, same[3 * i + 1] = 2, same[3 * i + 2] = 3;
    }
    const float *lines[2] = {line, far};
    for (int k = 0; k < 2; k++) {
        memset(&err, 0, sizeof err);
        assert_int_equal(mim_reg_similarity_fit(lines[k], dst, 16, &fit, &err), MIM_EINVAL);
        assert_non_null(strstr(err.msg, "line"));
        assert_int_equal(mim_reg_similarity_fit(dst, lines[k], 16, &fit, &err), MIM_EINVAL);
    }
    assert_int_equal(mim_reg_similarity_fit(same, dst, 16, &fit, &err), MIM_EINVAL);
    assert_int_equal(mim_reg_similarity_fit(NULL, dst, 16, &fit, &err), MIM_EINVAL);
}

/* ---- the target check ---- */

/* A tetrahedron of body size (metres), outward faces, at offset x0. */
static void tetra(float *pos, uint32_t *f, uint32_t base, float x0)
{
    const float p[12] = {0, 0, 0, 0.5f, 0, 0, 0, 1.6f, 0, 0, 0, 0.3f};
    for (int i = 0; i < 12; i++) pos[i] = p[i] + (i % 3 == 0 ? x0 : 0);
    const uint32_t t[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    for (int i = 0; i < 12; i++) f[i] = t[i] + base;
}

static void expect_target(const mim_mesh_t *m, int code, const char *phrase)
{
    mim_error_t err = {0};
    int rc = mim_reg_target_check(m, "scan.obj", &err);
    if (rc != code || (phrase && !strstr(err.msg, phrase)))
        fprintf(stderr, "target check: %d (%s), message: %s\n", rc, mim_strerror(rc), err.msg);
    assert_int_equal(rc, code);
    if (code) {
        assert_non_null(strstr(err.msg, "scan.obj"));
        assert_non_null(strstr(err.msg, phrase));
        assert_null(strchr(err.msg, '\n'));
    }
}

static void test_target_check(void **s)
{
    (void)s;
    mim_mesh_t m = {0};
    /* a closed tetrahedron passes */
    assert_int_equal(mim_mesh_alloc(&m, 4, 4), 0);
    tetra(m.positions, m.faces, 0, 0);
    expect_target(&m, 0, NULL);
    mim_mesh_free(&m);
    /* a body passes */
    mim_mesh_t body = {n, nf, lib_body[0][0], faces};
    expect_target(&body, 0, NULL);

    /* an edge shared by three triangles: the tetrahedron and a fin on edge 0-2 */
    assert_int_equal(mim_mesh_alloc(&m, 5, 5), 0);
    tetra(m.positions, m.faces, 0, 0);
    float fin[3] = {-0.4f, 0.8f, -0.3f};
    memcpy(m.positions + 12, fin, sizeof fin);
    const uint32_t extra[3] = {0, 4, 2};
    memcpy(m.faces + 12, extra, sizeof extra);
    expect_target(&m, MIM_ETOPOLOGY, "non-manifold: edge 0-2 is shared by 3 triangles");
    mim_mesh_free(&m);

    /* two tetrahedra side by side */
    assert_int_equal(mim_mesh_alloc(&m, 8, 8), 0);
    tetra(m.positions, m.faces, 0, 0);
    tetra(m.positions + 12, m.faces + 12, 4, 1.0f);
    expect_target(&m, MIM_ETOPOLOGY, "disconnected: 2 pieces");
    mim_mesh_free(&m);

    /* a vertex on no triangle */
    assert_int_equal(mim_mesh_alloc(&m, 5, 4), 0);
    tetra(m.positions, m.faces, 0, 0);
    m.positions[12] = 0.2f, m.positions[13] = 0.2f, m.positions[14] = 0.2f;
    expect_target(&m, MIM_ETOPOLOGY, "vertex 4 is on no triangle");
    mim_mesh_free(&m);

    /* a NaN coordinate, an infinite one: the body check's MIM_ENONFINITE */
    assert_int_equal(mim_mesh_alloc(&m, 4, 4), 0);
    tetra(m.positions, m.faces, 0, 0);
    m.positions[3 * 2 + 1] = NAN;
    expect_target(&m, MIM_ENONFINITE, "vertex 2");
    m.positions[3 * 2 + 1] = -INFINITY;
    expect_target(&m, MIM_ENONFINITE, "vertex 2");
    /* millimetres (a 1.6 m body as 1600 units), and a body 1 km away: not a body */
    tetra(m.positions, m.faces, 0, 0);
    for (int i = 0; i < 12; i++) m.positions[i] *= 1000.0f;
    expect_target(&m, MIM_EFORMAT, "10 m box");
    tetra(m.positions, m.faces, 0, 0);
    for (int i = 0; i < 4; i++) m.positions[3 * i] += 2000.0f;
    expect_target(&m, MIM_EFORMAT, "from the origin");
    /* all at one point */
    for (int i = 0; i < 12; i++) m.positions[i] = 0.5f;
    expect_target(&m, MIM_EFORMAT, "not a body");
    /* a face past the vertices */
    tetra(m.positions, m.faces, 0, 0);
    m.faces[7] = 9;
    expect_target(&m, MIM_EINDEX, "vertex 9 past the 4 vertices");
    mim_mesh_free(&m);
    /* nothing */
    mim_mesh_t empty = {0};
    expect_target(&empty, MIM_EEMPTY, "no triangles");
    /* surface distance on a bad target: the same check */
    float p[3] = {0, 0, 0};
    double d;
    mim_error_t err = {0};
    assert_int_equal(mim_mesh_alloc(&m, 8, 8), 0);
    tetra(m.positions, m.faces, 0, 0);
    tetra(m.positions + 12, m.faces + 12, 4, 1.0f);
    assert_int_equal(mim_reg_surface_distance(&m, p, 1, &d, &err), MIM_ETOPOLOGY);
    mim_mesh_free(&m);
    /* and on a good one: a point above a face's middle is its height away */
    assert_int_equal(mim_mesh_alloc(&m, 4, 4), 0);
    tetra(m.positions, m.faces, 0, 0);
    float q[3] = {0.1f, 0.4f, -0.25f}; /* below face (0, 2, 1), the z = 0 plane */
    assert_int_equal(mim_reg_surface_distance(&m, q, 1, &d, &err), 0);
    assert_true(fabs(d - 0.25) < 1e-6);
    mim_mesh_free(&m);
}

/* ---- binding a foreign avatar ---- */
static void rotate_y90(const float *in, uint32_t count, float *out)
{
    for (uint32_t i = 0; i < count; i++) {
        float x = in[3 * i], y = in[3 * i + 1], z = in[3 * i + 2];
        out[3 * i] = z, out[3 * i + 1] = y, out[3 * i + 2] = -x;
    }
}

static double max_diff(const float *a, const float *b, size_t count)
{
    double m = 0;
    for (size_t i = 0; i < count; i++) m = fmax(m, fabs((double)a[i] - b[i]));
    return m;
}

static void expect_decode_error(const void *blob, size_t len, uint32_t np, uint32_t npf, const char *what)
{
    mim_reg_binding_t b;
    memset(&b, 0x5a, sizeof b);
    mim_error_t err = {0};
    int rc = mim_reg_binding_decode(blob, len, np, npf, &b, &err);
    if (rc != MIM_EFORMAT) fprintf(stderr, "decode of %s: %d (%s)\n", what, rc, err.msg);
    assert_int_equal(rc, MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "binding"));
    assert_int_equal(b.n_vertices, 0);
    assert_null(b.face);
    assert_null(b.offset);
    assert_null(b.proxy_rest);
}

static void test_binding(void **s)
{
    (void)s;
    mim_error_t err = {0};
    /* the avatar: subject 0 at rest, subdivided and renumbered; its proxy:
     * the store's connectivity registered onto it from subject 1 */
    const float *truth = lib_body[0][0];
    mim_mesh_t avatar = {0};
    retriangulate(truth, n, faces, nf, 0, 99, &avatar);
    float lm[3 * MIM_LANDMARKS_MAX];
    landmarks_of(truth, &map, lm);
    mim_reg_t *reg = NULL;
    assert_int_equal(mim_reg_open(&reg, topo, &map, NULL, &err), 0);
    mim_mesh_t proxy = {0};
    assert_int_equal(mim_mesh_alloc(&proxy, n, nf), 0);
    memcpy(proxy.faces, faces, (size_t)nf * 3 * sizeof *faces);
    assert_int_equal(mim_reg_run(reg, lib_body[1][0], &avatar, lm, "avatar", proxy.positions, NULL, &err), 0);
    mim_reg_close(&reg);

    mim_reg_binding_t b;
    assert_int_equal(mim_reg_bind(&proxy, &avatar, &b, &err), 0);
    assert_int_equal(b.n_vertices, avatar.n_vertices);
    assert_int_equal(b.n_proxy_vertices, n);
    assert_int_equal(b.n_proxy_faces, nf);
    assert_memory_equal(b.proxy_rest, proxy.positions, (size_t)3 * n * sizeof(float));
    double off = 0;
    for (uint32_t i = 0; i < b.n_vertices; i++) {
        assert_true(b.face[i] < nf);
        off = fmax(off, sqrt(b.offset[3 * i] * b.offset[3 * i] + b.offset[3 * i + 1] * b.offset[3 * i + 1] +
                             b.offset[3 * i + 2] * b.offset[3 * i + 2]));
    }
    float *work = malloc((size_t)3 * n * sizeof *work), *out = malloc((size_t)3 * avatar.n_vertices * sizeof *out);
    float *turned = malloc((size_t)3 * n * sizeof *turned);
    float *want = malloc((size_t)3 * avatar.n_vertices * sizeof *want);
    /* at rest: the avatar itself */
    mim_reg_binding_apply(&b, faces, proxy.positions, work, out);
    double rest = max_diff(out, avatar.positions, (size_t)3 * avatar.n_vertices);
    /* the proxy turned 90 degrees about +Y: the avatar turned the same way */
    rotate_y90(proxy.positions, n, turned);
    rotate_y90(avatar.positions, avatar.n_vertices, want);
    mim_reg_binding_apply(&b, faces, turned, work, out);
    double moved = max_diff(out, want, (size_t)3 * avatar.n_vertices);
    print_message("binding: largest offset %.2f mm; at rest off by %.2g m, turned %.2g m\n", 1000 * off, rest, moved);
    assert_true(rest <= 1e-4);
    assert_true(moved <= 1e-3);
    /* and it did move: the turned avatar is far from the one at rest */
    assert_true(max_diff(out, avatar.positions, (size_t)3 * avatar.n_vertices) > 0.1);

    /* the cached form: bytes back to the same binding, bit for bit */
    void *blob = NULL, *blob2 = NULL;
    size_t len = 0, len2 = 0;
    assert_int_equal(mim_reg_binding_encode(&b, &blob, &len, &err), 0);
    mim_reg_binding_t c;
    assert_int_equal(mim_reg_binding_decode(blob, len, n, nf, &c, &err), 0);
    assert_int_equal(c.n_vertices, b.n_vertices);
    assert_int_equal(c.n_proxy_vertices, n);
    assert_int_equal(c.n_proxy_faces, nf);
    assert_memory_equal(c.proxy_rest, b.proxy_rest, (size_t)3 * n * sizeof(float));
    assert_memory_equal(c.face, b.face, (size_t)b.n_vertices * sizeof(uint32_t));
    assert_memory_equal(c.bary, b.bary, (size_t)2 * b.n_vertices * sizeof(float));
    assert_memory_equal(c.offset, b.offset, (size_t)3 * b.n_vertices * sizeof(float));
    assert_int_equal(mim_reg_binding_encode(&c, &blob2, &len2, &err), 0);
    assert_int_equal(len2, len);
    assert_memory_equal(blob2, blob, len);
    free(blob2);
    mim_reg_binding_free(&c);

    /* damaged or foreign bytes: MIM_EFORMAT, nothing allocated, no crash.
     * The fields are found in the blob by their bytes (its layout is
     * bind.c's): a 16-byte header "MRB." n np nf, then the arrays. */
    const unsigned char *at_rest = memmem(blob, len, b.proxy_rest, (size_t)12 * n),
                        *at_face = memmem(blob, len, b.face, (size_t)4 * b.n_vertices),
                        *at_bary = memmem(blob, len, b.bary, (size_t)8 * b.n_vertices),
                        *at_offset = memmem(blob, len, b.offset, (size_t)12 * b.n_vertices);
    assert_true(at_rest && at_face && at_bary && at_offset);
    const unsigned char *b0 = blob;
    const size_t o_rest = (size_t)(at_rest - b0), o_face = (size_t)(at_face - b0), o_bary = (size_t)(at_bary - b0),
                 o_offset = (size_t)(at_offset - b0);
    assert_int_equal(o_rest, 16);
    unsigned char *bad = malloc(len);
    expect_decode_error(blob, len - 1, n, nf, "one byte short");
    expect_decode_error(blob, len / 2, n, nf, "half");
    expect_decode_error(blob, 15, n, nf, "a short header");
    expect_decode_error(blob, 0, n, nf, "nothing");
    expect_decode_error(NULL, len, n, nf, "NULL");
    expect_decode_error(blob, len, n + 1, nf, "a proxy of other vertices");
    expect_decode_error(blob, len, n, nf - 1, "a proxy of other faces");
    memcpy(bad, blob, len), bad[0] = 'X';
    expect_decode_error(bad, len, n, nf, "bad magic");
    memcpy(bad, blob, len), memset(bad + 4, 0, 4); /* no avatar vertices */
    expect_decode_error(bad, len, n, nf, "zero vertices");
    memcpy(bad, blob, len), memset(bad + 4, 0xff, 4); /* 2^32 - 1 avatar vertices in a small blob */
    expect_decode_error(bad, len, n, nf, "a huge vertex count");
    /* the last entry's triangle: one past the proxy's, and 2^32 - 1 */
    const size_t last_face = o_face + 4 * ((size_t)b.n_vertices - 1);
    uint32_t past = nf;
    memcpy(bad, blob, len), memcpy(bad + last_face, &past, 4);
    expect_decode_error(bad, len, n, nf, "a face past the proxy's");
    past = UINT32_MAX;
    memcpy(bad + last_face, &past, 4);
    expect_decode_error(bad, len, n, nf, "face 2^32 - 1");
    float nan = NAN, inf = INFINITY;
    memcpy(bad, blob, len), memcpy(bad + o_offset + 4 * 5, &nan, 4);
    expect_decode_error(bad, len, n, nf, "a NaN offset");
    memcpy(bad, blob, len), memcpy(bad + o_offset + 12 * ((size_t)b.n_vertices - 1) + 8, &inf, 4);
    expect_decode_error(bad, len, n, nf, "an infinite offset, last");
    memcpy(bad, blob, len), memcpy(bad + o_bary + 4 * 3, &inf, 4);
    expect_decode_error(bad, len, n, nf, "an infinite barycentric");
    memcpy(bad, blob, len), memcpy(bad + o_rest + 4 * 10, &nan, 4);
    expect_decode_error(bad, len, n, nf, "a NaN proxy position");
    /* the untouched copy still decodes (the cases above failed for their damage) */
    memcpy(bad, blob, len);
    assert_int_equal(mim_reg_binding_decode(bad, len, n, nf, &c, &err), 0);
    mim_reg_binding_free(&c);
    free(bad);
    free(blob);

    /* bind: a NaN avatar vertex, no avatar */
    avatar.positions[3 * 3] = NAN;
    mim_reg_binding_t e;
    assert_int_equal(mim_reg_bind(&proxy, &avatar, &e, &err), MIM_ENONFINITE);
    assert_null(e.face);
    assert_int_equal(mim_reg_bind(&proxy, NULL, &e, &err), MIM_EINVAL);
    mim_reg_binding_free(&b);
    assert_null(b.face);
    mim_reg_binding_free(&b); /* an empty one */
    free(work), free(out), free(turned), free(want);
    mim_mesh_free(&proxy);
    mim_mesh_free(&avatar);
}

/* ---- mimic register ---- */

/* Writes a foreign mesh: subject 3's body in pose `pose` re-triangulated
 * (how as retriangulate()), as NAME.ply in folder, with its landmark
 * positions as NAME.landmarks.json unless sidecar is 0. truth (may be
 * NULL) gets the body in the store's connectivity. Returns the path. */
static char *make_foreign(const char *folder, const char *name, int pose, int how, int sidecar, mim_mesh_t *truth)
{
    char *src = body_path(C_SUBJECTS - 1, pose), file[256];
    mim_mesh_t body = {0}, target = {0};
    mim_error_t err = {0};
    assert_int_equal(mim_io_read_mesh(src, &body, &err), 0);
    free(src);
    retriangulate(body.positions, body.n_vertices, body.faces, body.n_faces, how, 1000 + (uint64_t)pose, &target);
    snprintf(file, sizeof file, "%s.ply", name);
    char *path = ts_path(folder, file);
    if (mim_io_write_mesh(path, &target, &err)) fail_msg("%s", mim_error_text(&err));
    if (sidecar) {
        mim_landmark_map_t m;
        char *lm_path = ts_path(bodies, "landmarks.json"), side[4096];
        assert_int_equal(mim_landmarks_read(&m, lm_path, &err), 0);
        free(lm_path);
        json_t *arr = json_array();
        for (uint32_t l = 0; l < m.count; l++) {
            const float *p = body.positions + 3 * (size_t)m.vertex[l];
            json_array_append_new(arr, json_pack("[f, f, f]", (double)p[0], (double)p[1], (double)p[2]));
        }
        json_t *root = json_pack("{s:o}", "landmarks", arr);
        assert_int_equal(mim_io_landmarks_sidecar(path, side, sizeof side), 0); /* not there yet */
        assert_int_equal(json_dump_file(root, side, JSON_REAL_PRECISION(9)), 0);
        assert_int_equal(mim_io_landmarks_sidecar(path, side, sizeof side), 1);
        json_decref(root);
    }
    mim_mesh_free(&target);
    if (truth) *truth = body;
    else mim_mesh_free(&body);
    return path;
}

static int exists(const char *path) { return access(path, F_OK) == 0; }

/* One line on stderr, "mimic CMD: ...", holding each phrase (NULL: none). */
static void expect_one_line(const char *err, const char *cmd, const char *p1, const char *p2)
{
    char head[64];
    snprintf(head, sizeof head, "mimic %s: ", cmd);
    if (!err || strncmp(err, head, strlen(head)) || (p1 && !strstr(err, p1)) || (p2 && !strstr(err, p2)))
        fprintf(stderr, "stderr: %s", err ? err : "(none)\n");
    assert_non_null(err);
    assert_true(strncmp(err, head, strlen(head)) == 0);
    const char *nl = strchr(err, '\n');
    assert_non_null(nl);
    assert_int_equal(nl[1], '\0');
    if (p1) assert_non_null(strstr(err, p1));
    if (p2) assert_non_null(strstr(err, p2));
}

/* mimic register with args; expects exit `code`, one stderr line with the
 * phrases, and (unless code is 0) no output file. */
static void expect_register(const char *const *args, int code, const char *outp, const char *p1, const char *p2)
{
    char *o = NULL, *e = NULL;
    if (outp) unlink(outp);
    int rc = ts_run_mimic(&o, &e, args);
    if (rc != code) fprintf(stderr, "mimic register exited %d, not %d: %s", rc, code, e ? e : "");
    assert_int_equal(rc, code);
    if (code) {
        expect_one_line(e, "register", p1, p2);
        assert_true(o == NULL || o[0] == '\0');
        if (outp) assert_false(exists(outp));
    }
    free(o), free(e);
}

static void read_mesh(const char *path, mim_mesh_t *m)
{
    mim_error_t e = {0};
    if (mim_io_read_mesh(path, m, &e)) fail_msg("%s", mim_error_text(&e));
}

static void test_cli_register(void **s)
{
    (void)s;
    char *folder = ts_path(dir, "reg");
    assert_int_equal(mkdir(folder, 0755), 0);
    mim_mesh_t truth = {0};
    char *mesh = make_foreign(folder, "scan", 3, 0, 1, &truth);
    char *outp = ts_path(folder, "out.ply");
    const char *args[] = {"register", "--store", store, mesh, "-o", outp, "--json", NULL};
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc) fail_msg("mimic register: %s", e);
    json_error_t je;
    json_t *rep = json_loads(o, 0, &je);
    if (!rep) fail_msg("mimic register --json: %s: %s", je.text, o);
    mim_mesh_t target = {0}, out = {0};
    read_mesh(mesh, &target);
    read_mesh(outp, &out);
    /* the store's connectivity, in the truth's shape */
    assert_int_equal(out.n_vertices, cli_n);
    assert_int_equal(out.n_faces, cli_nf);
    assert_memory_equal(out.faces, cli_faces, (size_t)cli_nf * 12);
    double cm, cp;
    correspondence(out.positions, truth.positions, cli_n, &cm, &cp);
    double *dist = malloc(cli_n * sizeof *dist), sum = 0;
    mim_error_t err = {0};
    assert_int_equal(mim_reg_surface_distance(&target, out.positions, cli_n, dist, &err), 0);
    for (uint32_t i = 0; i < cli_n; i++) sum += dist[i];
    print_message("mimic register: correspondence mean %.1f mm, p95 %.1f mm; surface mean %.3f mm\n", cm, cp,
                  1000 * sum / cli_n);
    assert_true(cm <= CORR_MEAN_MM);
    assert_true(cp <= CORR_P95_MM);
    assert_true(1000 * sum / cli_n <= SURF_MEAN_MM);
    /* the report */
    assert_string_equal(json_string_value(json_object_get(rep, "mesh")), mesh);
    assert_string_equal(json_string_value(json_object_get(rep, "output")), outp);
    assert_int_equal(json_integer_value(json_object_get(rep, "vertices")), target.n_vertices);
    assert_int_equal(json_integer_value(json_object_get(rep, "store_vertices")), cli_n);
    char side[4096];
    assert_int_equal(mim_io_landmarks_sidecar(mesh, side, sizeof side), 1);
    assert_string_equal(json_string_value(json_object_get(rep, "landmarks_from")), side);
    json_t *tm = json_object_get(rep, "template");
    json_int_t tid = json_integer_value(json_object_get(tm, "id"));
    assert_true(tid >= 1 && tid <= C_STORED_SUBJECTS * C_POSES);
    /* the nearest pose of a stored subject: the same pose (ids in file order) */
    assert_int_equal((tid - 1) % C_POSES, 3);
    assert_string_equal(json_string_value(json_object_get(tm, "pose")), "3");
    json_t *sd = json_object_get(rep, "surface_distance_mm");
    double mean = json_real_value(json_object_get(sd, "mean")), p95 = json_real_value(json_object_get(sd, "p95")),
           mx = json_real_value(json_object_get(sd, "max"));
    assert_true(fabs(mean - 1000 * sum / cli_n) < 1e-2); /* the output went through a float file */
    assert_true(mean <= mx && p95 <= mx && p95 <= 15.0);
    json_t *lr = json_object_get(rep, "landmark_residuals_mm");
    assert_int_equal(json_object_size(json_object_get(lr, "per_landmark")), 16);
    assert_true(json_is_number(json_object_get(json_object_get(lr, "per_landmark"), "l_wrist")));
    assert_true(json_integer_value(json_object_get(rep, "iterations")) >= 1);
    assert_true(json_number_value(json_object_get(json_object_get(rep, "seconds"), "total")) > 0);
    json_decref(rep);
    free(o), free(e);
    free(dist);
    mim_mesh_t first = out; /* kept for the --landmarks run below */
    out = (mim_mesh_t){0};

    /* without --json: one summary line on stdout, the same mesh */
    char *out2 = ts_path(folder, "out2.obj");
    const char *plain[] = {"register", "--store", store, mesh, "--output", out2, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, plain), 0);
    assert_non_null(strstr(o, "registered"));
    assert_non_null(strstr(o, out2));
    assert_int_equal(strchr(o, '\n')[1], '\0');
    read_mesh(out2, &out);
    assert_int_equal(out.n_vertices, cli_n);
    mim_mesh_free(&out);
    free(o), free(e), free(out2);

    /* the landmarks given with --landmarks, the sidecar moved away: the same */
    char *given = ts_path(folder, "given.json");
    assert_int_equal(rename(side, given), 0);
    const char *with_lm[] = {"register", "--store", store, "--landmarks", given, mesh, "-o", outp, "--json", NULL};
    assert_int_equal(ts_run_mimic(&o, &e, with_lm), 0);
    rep = json_loads(o, 0, &je);
    assert_non_null(rep);
    assert_string_equal(json_string_value(json_object_get(rep, "landmarks_from")), given);
    json_decref(rep);
    free(o), free(e);
    read_mesh(outp, &out);
    assert_int_equal(out.n_vertices, cli_n);
    assert_memory_equal(out.positions, first.positions, (size_t)3 * cli_n * sizeof(float));
    mim_mesh_free(&out);
    mim_mesh_free(&first);

    /* ---- bad input: exit 1, one line, nothing written ---- */
    char *bad_out = ts_path(folder, "bad.ply");
    /* no landmarks anywhere: names the mesh and the ways to give them */
    const char *none[] = {"register", "--store", store, mesh, "-o", bad_out, NULL};
    expect_register(none, 1, bad_out, mesh, "--landmarks FILE");
    expect_register(none, 1, bad_out, "scan.landmarks.json", "no landmarks");
    /* the store's own landmark map: a map of another vertex count */
    char *store_map = ts_path(bodies, "landmarks.json");
    const char *wrong_map[] = {"register", "--store", store, "--landmarks", store_map, mesh, "-o", bad_out, NULL};
    char want[128];
    snprintf(want, sizeof want, "a landmark map of %u vertices, the mesh has %u", cli_n, target.n_vertices);
    expect_register(wrong_map, 1, bad_out, store_map, want);
    /* positions with a missing landmark; with 15 of 16; with a NaN and an overflow */
    char *text = ts_read_file(given, NULL);
    assert_non_null(text);
    json_t *pos = json_loads(text, 0, &je);
    json_array_set_new(json_object_get(pos, "landmarks"), 3, json_null());
    char *holes = ts_path(folder, "holes.json");
    assert_int_equal(json_dump_file(pos, holes, 0), 0);
    const char *with_holes[] = {"register", "--store", store, "--landmarks", holes, mesh, "-o", bad_out, NULL};
    expect_register(with_holes, 1, bad_out, holes, "landmark 3 (l_shoulder) is missing");
    json_array_remove(json_object_get(pos, "landmarks"), 3);
    char *short_lm = ts_path(folder, "short.json");
    assert_int_equal(json_dump_file(pos, short_lm, 0), 0);
    json_decref(pos);
    const char *with_short[] = {"register", "--store", store, "--landmarks", short_lm, mesh, "-o", bad_out, NULL};
    expect_register(with_short, 1, bad_out, short_lm, "has 15 landmarks");
    char *nan_lm = ts_path(folder, "nan.json"), *nan_text = strdup(text);
    char *first_num = strstr(nan_text, "[[");
    assert_non_null(first_num);
    memcpy(first_num + 2, "NaN", 3); /* over the first digits of the first coordinate */
    assert_int_equal(ts_write_file(nan_lm, nan_text, strlen(nan_text)), 0);
    const char *with_nan[] = {"register", "--store", store, "--landmarks", nan_lm, mesh, "-o", bad_out, NULL};
    expect_register(with_nan, 1, bad_out, nan_lm, "NaN");
    const char *huge = "{\"landmarks\": [[1e999, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1], "
                       "[1, 1, 1], [2, 0, 0], [0, 2, 0], [0, 0, 2], [2, 2, 0], [2, 0, 2], [0, 2, 2], [2, 2, 2], "
                       "[3, 0, 0], [0, 3, 0]]}";
    assert_int_equal(ts_write_file(nan_lm, huge, strlen(huge)), 0);
    expect_register(with_nan, 1, bad_out, nan_lm, "1e999");
    free(nan_text), free(text);
    /* a landmark file that is not there */
    char *missing = ts_path(folder, "missing.json");
    const char *with_missing[] = {"register", "--store", store, "--landmarks", missing, mesh, "-o", bad_out, NULL};
    expect_register(with_missing, 1, bad_out, missing, NULL);
    free(missing);

    /* a non-manifold target: a fin on an edge of the mesh */
    mim_mesh_t fin = {0};
    assert_int_equal(mim_mesh_alloc(&fin, target.n_vertices + 1, target.n_faces + 1), 0);
    memcpy(fin.positions, target.positions, (size_t)3 * target.n_vertices * sizeof(float));
    memcpy(fin.faces, target.faces, (size_t)3 * target.n_faces * sizeof(uint32_t));
    uint32_t a = target.faces[0], b2 = target.faces[1];
    float *np = fin.positions + 3 * (size_t)target.n_vertices;
    for (int c = 0; c < 3; c++) np[c] = 0.5f * (target.positions[3 * a + c] + target.positions[3 * b2 + c]) + 0.02f;
    fin.faces[3 * (size_t)target.n_faces] = a, fin.faces[3 * (size_t)target.n_faces + 1] = b2,
    fin.faces[3 * (size_t)target.n_faces + 2] = target.n_vertices;
    char *fin_path = ts_path(folder, "fin.ply");
    assert_int_equal(ts_write_mesh_ply(fin_path, &fin), 0);
    mim_mesh_free(&fin);
    const char *with_fin[] = {"register", "--store", store, "--landmarks", given, fin_path, "-o", bad_out, NULL};
    char edge[64];
    snprintf(edge, sizeof edge, "edge %u-%u", a < b2 ? a : b2, a < b2 ? b2 : a);
    expect_register(with_fin, 1, bad_out, fin_path, "non-manifold");
    expect_register(with_fin, 1, bad_out, edge, "shared by 3 triangles");

    /* a disconnected target: the mesh and a small tetrahedron beside it */
    mim_mesh_t two = {0};
    assert_int_equal(mim_mesh_alloc(&two, target.n_vertices + 4, target.n_faces + 4), 0);
    memcpy(two.positions, target.positions, (size_t)3 * target.n_vertices * sizeof(float));
    memcpy(two.faces, target.faces, (size_t)3 * target.n_faces * sizeof(uint32_t));
    tetra(two.positions + 3 * (size_t)target.n_vertices, two.faces + 3 * (size_t)target.n_faces, target.n_vertices,
          1.5f);
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 3; c++) two.positions[3 * ((size_t)target.n_vertices + i) + c] *= c == 0 ? 1.0f : 0.1f;
    char *two_path = ts_path(folder, "two.ply");
    assert_int_equal(ts_write_mesh_ply(two_path, &two), 0);
    mim_mesh_free(&two);
    const char *with_two[] = {"register", "--store", store, "--landmarks", given, two_path, "-o", bad_out, NULL};
    expect_register(with_two, 1, bad_out, two_path, "disconnected: 2 pieces");

    /* far from any template: a sphere around the body, the landmarks moved
     * out onto it: registered, but refused at the default 15 mm */
    ts_polymesh_t sp;
    ts_sphere(&sp, 24, 32, 1.0f);
    mim_mesh_t ball = {0};
    ts_triangulate(&sp, &ball);
    ts_polymesh_free(&sp);
    double c0[3] = {0, 0, 0};
    for (uint32_t i = 0; i < truth.n_vertices; i++)
        for (int c = 0; c < 3; c++) c0[c] += truth.positions[3 * i + c] / truth.n_vertices;
    for (uint32_t i = 0; i < ball.n_vertices; i++)
        for (int c = 0; c < 3; c++)
            ball.positions[3 * i + c] = (float)(c0[c] + ball.positions[3 * i + c] * (c == 1 ? 0.95 : 0.6));
    char *ball_path = ts_path(folder, "ball.ply");
    assert_int_equal(ts_write_mesh_ply(ball_path, &ball), 0);
    mim_landmark_map_t m;
    assert_int_equal(mim_landmarks_read(&m, store_map, &err), 0);
    json_t *arr = json_array();
    for (uint32_t l = 0; l < m.count; l++) {
        /* the landmark pushed radially out onto the ellipsoid */
        double d[3], r2 = 0;
        for (int c = 0; c < 3; c++) d[c] = truth.positions[3 * (size_t)m.vertex[l] + c] - c0[c];
        double sc[3] = {0.6, 0.95, 0.6};
        for (int c = 0; c < 3; c++) r2 += (d[c] / sc[c]) * (d[c] / sc[c]);
        double k = 1.0 / sqrt(r2);
        json_array_append_new(arr, json_pack("[f, f, f]", c0[0] + k * d[0], c0[1] + k * d[1], c0[2] + k * d[2]));
    }
    json_t *root = json_pack("{s:o}", "landmarks", arr);
    char *ball_lm = ts_path(folder, "ball.landmarks.json");
    assert_int_equal(json_dump_file(root, ball_lm, 0), 0);
    json_decref(root);
    mim_mesh_free(&ball);
    const char *with_ball[] = {"register", "--store", store, ball_path, "-o", bad_out, NULL};
    expect_register(with_ball, 1, bad_out, ball_path, "too far from the surface");
    expect_register(with_ball, 1, bad_out, "over the 15", "nothing written");
    /* a good mesh under a tiny limit: refused the same way, with its figures */
    const char *tiny[] = {"register", "--store", store, "--landmarks", given, mesh, "-o", bad_out,
                          "--max-distance-mm", "0.001", NULL};
    expect_register(tiny, 1, bad_out, "too far from the surface: distance p95", "nothing written");
    /* and a generous one lets the sphere through (it was the limit, not a failure) */
    const char *loose[] = {"register", "--store", store, ball_path, "-o", bad_out, "--max-distance-mm", "1000", NULL};
    expect_register(loose, 0, bad_out, NULL, NULL);
    assert_true(exists(bad_out));
    unlink(bad_out);

    /* a store without an index: exit 2, says to run mimic index */
    char *noindex = ts_path(dir, "noindex"), *b00 = body_path(0, 0), *b01 = body_path(0, 1);
    const char *ing[] = {"ingest", "--store", noindex, b00, b01, NULL};
    assert_int_equal(run_quiet(ing), 0);
    const char *no_ix[] = {"register", "--store", noindex, "--landmarks", given, mesh, "-o", bad_out, NULL};
    expect_register(no_ix, 2, bad_out, "mimic index", noindex);
    char *nothing = ts_path(dir, "nothing-here");
    const char *no_store[] = {"register", "--store", nothing, "--landmarks", given, mesh, "-o", bad_out, NULL};
    expect_register(no_store, 2, bad_out, NULL, NULL);
    free(nothing), free(noindex), free(b00), free(b01);

    /* usage: exit 2 */
    const char *u1[] = {"register", "--store", store, mesh, NULL};
    expect_register(u1, 2, NULL, "-o OUT", NULL);
    const char *u2[] = {"register", "--store", store, mesh, mesh, "-o", bad_out, NULL};
    expect_register(u2, 2, bad_out, "exactly one MESH", NULL);
    const char *u3[] = {"register", "--store", store, "-o", bad_out, NULL};
    expect_register(u3, 2, bad_out, "exactly one MESH", NULL);
    char *xyz = ts_path(folder, "out.xyz");
    const char *u4[] = {"register", "--store", store, mesh, "-o", xyz, NULL};
    expect_register(u4, 2, xyz, "unknown output format", NULL);
    free(xyz);
    const char *bad_mm[] = {"0", "-3", "abc", "1001", "nan", ""};
    for (size_t i = 0; i < sizeof bad_mm / sizeof *bad_mm; i++) {
        const char *u5[] = {"register", "--store", store, mesh, "-o", bad_out, "--max-distance-mm", bad_mm[i], NULL};
        expect_register(u5, 2, bad_out, "max-distance-mm", NULL);
    }
    const char *u6[] = {"register", "--store", store, mesh, "-o", bad_out, "--frobnicate", NULL};
    expect_register(u6, 2, bad_out, "--frobnicate", NULL);
    const char *u7[] = {"register", mesh, "-o", bad_out, NULL};
    expect_register(u7, 2, bad_out, "--store DIR", NULL);
    const char *help[] = {"register", "--help", NULL};
    assert_int_equal(ts_run_mimic(&o, &e, help), 0);
    assert_non_null(strstr(o, "usage: mimic register"));
    free(o), free(e);

    mim_mesh_free(&target);
    mim_mesh_free(&truth);
    free(mesh), free(outp), free(bad_out), free(given), free(store_map), free(holes), free(short_lm), free(nan_lm);
    free(fin_path), free(two_path), free(ball_path), free(ball_lm), free(folder);
}

/* ---- mimic ingest --register ---- */

static void copy_file(const char *from, const char *to)
{
    size_t len;
    char *b = ts_read_file(from, &len);
    assert_non_null(b);
    assert_int_equal(ts_write_file(to, b, len), 0);
    free(b);
}

static void test_cli_ingest_register(void **s)
{
    (void)s;
    /* a copy of the store, so that the other cases keep theirs */
    char *st = ts_path(dir, "ingest-store"), *from = ts_path(store, "data.mdb"), *to = ts_path(st, "data.mdb");
    assert_int_equal(mkdir(st, 0755), 0);
    copy_file(from, to);
    free(from), free(to);
    char *folder = ts_path(dir, "foreign");
    assert_int_equal(mkdir(folder, 0755), 0);
    mim_mesh_t truth1 = {0}, truth2 = {0};
    char *m1 = make_foreign(folder, "scan_s03_p01", 1, 0, 1, &truth1);
    char *m2 = make_foreign(folder, "scan_s03_p04", 4, 1, 1, &truth2);
    char *m3 = make_foreign(folder, "nolandmarks", 2, 0, 0, NULL);
    mim_mesh_t t1 = {0}, t2 = {0};
    read_mesh(m1, &t1);
    read_mesh(m2, &t2);

    const char *args[] = {"ingest", "--store", st, "--register", folder, NULL};
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc != 1) fprintf(stderr, "ingest --register: %d\n%s%s", rc, o, e);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(o, "ingested 3 files"));
    assert_non_null(strstr(o, "2 added (2 registered), 0 already stored, 1 failed"));
    assert_non_null(strstr(o, "store holds 20 templates"));
    /* the bad one, named, with the way to give landmarks */
    assert_non_null(strstr(e, m3));
    assert_non_null(strstr(e, "no landmarks"));
    assert_null(strstr(e, m1));
    assert_null(strstr(e, m2));
    free(o), free(e);

    /* list --json: the two registered templates with their figures */
    const char *list[] = {"list", "--store", st, "--json", NULL};
    assert_int_equal(ts_run_mimic(&o, &e, list), 0);
    json_error_t je;
    json_t *all = json_loads(o, 0, &je);
    assert_non_null(all);
    free(o), free(e);
    assert_int_equal(json_array_size(all), 20);
    int seen = 0;
    uint64_t ids[2] = {0, 0};
    size_t i;
    json_t *t;
    json_array_foreach(all, i, t)
    {
        json_t *r = json_object_get(t, "registration");
        const char *src = json_string_value(json_object_get(t, "source"));
        if (!r) {
            assert_null(strstr(src, "/foreign/"));
            continue;
        }
        json_int_t sv = json_integer_value(json_object_get(r, "source_vertices"));
        int which = strstr(src, "scan_s03_p01") ? 0 : strstr(src, "scan_s03_p04") ? 1 : -1;
        assert_true(which >= 0);
        assert_int_equal(sv, which ? t2.n_vertices : t1.n_vertices);
        double p95 = json_real_value(json_object_get(r, "p95_mm"));
        double mean = json_real_value(json_object_get(r, "mean_mm"));
        double mx = json_real_value(json_object_get(r, "max_mm"));
        assert_true(p95 > 0 && p95 <= 15.0 && mean > 0 && mean <= mx && p95 <= mx);
        assert_true(json_integer_value(json_object_get(r, "iterations")) >= 1);
        /* labels from the file name */
        assert_string_equal(json_string_value(json_object_get(t, "subject")), "3");
        ids[which] = (uint64_t)json_integer_value(json_object_get(t, "id"));
        seen |= 1 << which;
    }
    assert_int_equal(seen, 3);
    json_decref(all);

    /* what was stored is the registration: the truth's shape in the store's connectivity */
    mim_db_t *db = NULL;
    mim_db_options_t dbo = {.read_only = 1};
    mim_error_t err = {0};
    mim_db_txn_t *txn = NULL;
    assert_int_equal(mim_db_open(&db, st, &dbo, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &txn, &err), 0);
    for (int k = 0; k < 2; k++) {
        mim_template_view_t v;
        assert_int_equal(mim_db_template_get(txn, ids[k], &v, &err), 0);
        assert_int_equal(v.n_vertices, cli_n);
        double cm, cp;
        correspondence(v.positions, (k ? truth2 : truth1).positions, cli_n, &cm, &cp);
        print_message("ingest --register, %s: correspondence mean %.1f mm, p95 %.1f mm\n",
                      k ? "decimated" : "subdivided", cm, cp);
        assert_true(cm <= CORR_MEAN_MM);
        assert_true(cp <= CORR_P95_MM);
        mim_db_registration_t reg;
        assert_int_equal(mim_db_registration_get(txn, ids[k], &reg, &err), 0);
        assert_int_equal(reg.source_vertices, k ? t2.n_vertices : t1.n_vertices);
    }
    mim_db_abort(&txn);
    mim_db_close(&db);

    /* the same again: found by their hashes, nothing registered or added */
    rc = ts_run_mimic(&o, &e, args);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(o, "0 added, 2 already stored, 1 failed"));
    assert_null(strstr(o, "registered"));
    assert_non_null(strstr(o, "store holds 20 templates"));
    free(o), free(e);
    /* and not registered again (a registration would give the same bytes,
     * which the content hash would catch too): without their landmarks and
     * under a limit no registration meets, they are still found */
    char side1[4096], side2[4096];
    assert_int_equal(mim_io_landmarks_sidecar(m1, side1, sizeof side1), 1);
    assert_int_equal(mim_io_landmarks_sidecar(m2, side2, sizeof side2), 1);
    assert_int_equal(unlink(side1), 0);
    assert_int_equal(unlink(side2), 0);
    const char *again[] = {"ingest", "--store", st, "--register", "--max-distance-mm", "0.0001", folder, NULL};
    rc = ts_run_mimic(&o, &e, again);
    if (rc != 1) fprintf(stderr, "%s%s", o, e);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(o, "0 added, 2 already stored, 1 failed"));
    assert_null(strstr(e, m1));
    assert_null(strstr(e, m2));
    free(o), free(e);

    /* a new foreign mesh under a tiny limit: refused with its figures, store unchanged */
    char *m4 = make_foreign(dir, "scan_s03_p05", 5, 0, 1, NULL);
    const char *tight[] = {"ingest", "--store", st, "--register", "--max-distance-mm", "0.0001", m4, NULL};
    rc = ts_run_mimic(&o, &e, tight);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(o, "0 added, 0 already stored, 1 failed"));
    assert_non_null(strstr(o, "store holds 20 templates"));
    assert_non_null(strstr(e, m4));
    assert_non_null(strstr(e, "too far from the surface: distance p95"));
    assert_non_null(strstr(e, "not stored"));
    free(o), free(e);
    /* with the default limit it goes in */
    const char *normal[] = {"ingest", "--store", st, "--register", m4, NULL};
    rc = ts_run_mimic(&o, &e, normal);
    if (rc) fprintf(stderr, "%s%s", o, e);
    assert_int_equal(rc, 0);
    assert_non_null(strstr(o, "1 added (1 registered)"));
    assert_non_null(strstr(o, "store holds 21 templates"));
    free(o), free(e);

    /* without --register a foreign mesh is refused and says how */
    char *m5 = make_foreign(dir, "scan_s03_p00", 0, 0, 1, NULL);
    const char *plain[] = {"ingest", "--store", st, m5, NULL};
    rc = ts_run_mimic(&o, &e, plain);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(e, "--register"));
    assert_non_null(strstr(o, "store holds 21 templates"));
    free(o), free(e);

    /* (a): the dataset's landmark map of the mesh's own connectivity
     * (mimic synth at another vertex count; its landmarks.json beside) */
    char *other = ts_path(dir, "other");
    const char *synth[] = {"synth", "--out", other, "--subjects", "4", "--poses", "3", "--vertices", "1200", NULL};
    assert_int_equal(run_quiet(synth), 0);
    char name[64];
    mim_synth_file_name(3, 2, name, sizeof name);
    char *m6 = ts_path(other, name);
    const char *dataset[] = {"ingest", "--store", st, "--register", m6, NULL};
    rc = ts_run_mimic(&o, &e, dataset);
    if (rc) fprintf(stderr, "%s%s", o, e);
    assert_int_equal(rc, 0);
    assert_non_null(strstr(o, "1 added (1 registered)"));
    assert_non_null(strstr(o, "store holds 22 templates"));
    free(o), free(e);
    /* ... and given with --landmarks, for a mesh with none beside it */
    char *lonely = ts_path(dir, "lonely"), *m7 = ts_path(lonely, "alone_s03_p00.ply"), *src7 = NULL;
    assert_int_equal(mkdir(lonely, 0755), 0);
    mim_synth_file_name(3, 0, name, sizeof name);
    src7 = ts_path(other, name);
    copy_file(src7, m7);
    const char *alone[] = {"ingest", "--store", st, "--register", m7, NULL};
    rc = ts_run_mimic(&o, &e, alone);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(e, "no landmarks"));
    free(o), free(e);
    char *other_map = ts_path(other, "landmarks.json");
    const char *alone_map[] = {"ingest", "--store", st, "--register", "--landmarks", other_map, m7, NULL};
    rc = ts_run_mimic(&o, &e, alone_map);
    if (rc) fprintf(stderr, "%s%s", o, e);
    assert_int_equal(rc, 0);
    assert_non_null(strstr(o, "1 added (1 registered)"));
    assert_non_null(strstr(o, "store holds 23 templates"));
    free(o), free(e), free(other_map), free(src7), free(m7), free(lonely);

    /* --register on a store without an index: exit 2, says to index */
    char *noindex = ts_path(dir, "noindex2"), *b00 = body_path(0, 0);
    const char *ing[] = {"ingest", "--store", noindex, b00, NULL};
    assert_int_equal(run_quiet(ing), 0);
    const char *no_ix[] = {"ingest", "--store", noindex, "--register", m1, NULL};
    rc = ts_run_mimic(&o, &e, no_ix);
    assert_int_equal(rc, 2);
    expect_one_line(e, "ingest", "mimic index", NULL);
    free(o), free(e);
    const char *bad_mm[] = {"ingest", "--store", st, "--register", "--max-distance-mm", "0", m1, NULL};
    rc = ts_run_mimic(&o, &e, bad_mm);
    assert_int_equal(rc, 2);
    expect_one_line(e, "ingest", "max-distance-mm", NULL);
    free(o), free(e);

    free(noindex), free(b00), free(other), free(m6), free(m5), free(m4);
    mim_mesh_free(&t1), mim_mesh_free(&t2), mim_mesh_free(&truth1), mim_mesh_free(&truth2);
    free(m1), free(m2), free(m3), free(folder), free(st);
}

/* A foreign avatar's binding is cached under its landmarks too: the same
 * mesh with other landmarks (left and right swapped) is registered again,
 * not served from the first binding; each is then found in the cache. */
static void test_avatar_binding_key(void **s)
{
    (void)s;
    char *folder = ts_path(dir, "avatars");
    assert_int_equal(mkdir(folder, 0755), 0);
    char *av = make_foreign(folder, "av_s03_p00", 0, 0, 1, NULL), side[4096];
    assert_int_equal(mim_io_landmarks_sidecar(av, side, sizeof side), 1);
    /* the swapped landmarks: each l_ and r_ pair exchanged (the store's mirror table) */
    json_error_t je;
    json_t *root = json_load_file(side, 0, &je), *arr = json_object_get(root, "landmarks"), *sw = json_array();
    mim_landmark_map_t m;
    char *lm_path = ts_path(bodies, "landmarks.json");
    assert_int_equal(mim_landmarks_read(&m, lm_path, NULL), 0);
    for (uint32_t l = 0; l < m.count; l++) json_array_append(sw, json_array_get(arr, m.mirror[l]));
    json_t *sroot = json_pack("{s:o}", "landmarks", sw);
    char *swapped = ts_path(dir, "swapped.json"), *outp = ts_path(dir, "av_out.ply");
    assert_int_equal(json_dump_file(sroot, swapped, JSON_REAL_PRECISION(9)), 0);
    json_decref(root), json_decref(sroot);
    const char *plain[] = {"transfer", "--store", store, "--avatar", av, "--template", "2", "-o", outp, NULL};
    const char *other[] = {"transfer", "--store", store, "--avatar", av, "--avatar-landmarks", swapped,
                           "--template", "2", "-o", outp, NULL};
    const char *const *runs[4] = {plain, plain, other, plain};
    const int registers[4] = {1, 0, 1, 0};
    for (int k = 0; k < 4; k++) {
        char *o = NULL, *e = NULL;
        int rc = ts_run_mimic(&o, &e, runs[k]);
        if (rc) fail_msg("run %d: exit %d: %s", k, rc, e);
        if ((strstr(e, "registered onto") != NULL) != registers[k])
            fail_msg("run %d: %s registration, stderr: %s", k, registers[k] ? "wanted a" : "wanted no", e);
        free(o), free(e);
    }
    free(folder), free(av), free(lm_path), free(swapped), free(outp);
}

/* kill -9 during ingest --register: a registered template and its
 * registration go in one transaction, so the store holds both or neither
 * of each, intact; a re-run registers the rest and nothing twice. */
static uint64_t templates_in(const char *dir_path)
{
    mim_db_t *db = NULL;
    mim_db_txn_t *t = NULL;
    mim_db_meta_t meta = {0};
    mim_db_options_t ro = {.read_only = 1};
    if (mim_db_open(&db, dir_path, &ro, NULL) == 0 && mim_db_begin(db, 0, &t, NULL) == 0)
        mim_db_meta_get(t, &meta, NULL);
    mim_db_abort(&t);
    mim_db_close(&db);
    return meta.templates;
}

typedef struct {
    mim_db_txn_t *t;
    uint64_t foreign, registered, bad;
} kill_census_t;

static int census(const mim_template_view_t *v, void *user)
{
    kill_census_t *c = user;
    mim_db_registration_t r;
    int is_foreign = strstr(v->source, "/killed/") != NULL;
    int rc = mim_db_registration_get(c->t, v->id, &r, NULL);
    c->foreign += is_foreign;
    c->registered += rc == 0;
    if (is_foreign != (rc == 0) || (rc == 0 && (r.template_id != v->id || !(r.p95_mm <= 15.0)))) c->bad++;
    return 0;
}

static void test_kill_during_ingest_register(void **s)
{
    (void)s;
    enum { MESHES = 2 * C_POSES };
    char *st = ts_path(dir, "kill-store"), *from = ts_path(store, "data.mdb"), *to = ts_path(st, "data.mdb");
    assert_int_equal(mkdir(st, 0755), 0);
    copy_file(from, to);
    free(from), free(to);
    uint64_t before = templates_in(st);
    char *folder = ts_path(dir, "killed");
    assert_int_equal(mkdir(folder, 0755), 0);
    for (int p = 0; p < C_POSES; p++)
        for (int how = 0; how < 2; how++) {
            char name[64];
            snprintf(name, sizeof name, "k_p%02d_%d", p, how);
            free(make_foreign(folder, name, p, how, 1, NULL));
        }
    pid_t pid = fork();
    if (pid == 0) {
        int null = open("/dev/null", O_WRONLY);
        dup2(null, 1), dup2(null, 2);
        execl(ts_mimic_bin(), ts_mimic_bin(), "ingest", "--store", st, "--register", "--batch", "1", "--threads", "1",
              folder, (char *)NULL);
        _exit(127);
    }
    double t0 = mim_now();
    while (mim_now() - t0 < 120 && templates_in(st) < before + 2) usleep(500);
    kill(pid, SIGKILL);
    int status;
    waitpid(pid, &status, 0);
    assert_true(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);

    mim_db_t *db = NULL;
    mim_error_t err = {0};
    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(&db, st, &ro, &err), 0);
    kill_census_t c = {0};
    assert_int_equal(mim_db_begin(db, 0, &c.t, &err), 0);
    assert_int_equal(mim_db_template_each(c.t, census, &c, &err), 0);
    mim_db_abort(&c.t);
    mim_db_check_report_t cr;
    assert_int_equal(mim_db_check(db, NULL, &cr, &err), 0);
    mim_db_close(&db);
    print_message("killed after %llu of %d registered templates\n", (unsigned long long)c.registered, MESHES);
    assert_int_equal(cr.problems, 0);
    assert_int_equal(c.bad, 0);
    assert_int_equal(c.foreign, c.registered);
    assert_true(c.registered >= 2 && c.registered < MESHES); /* cut part-way */

    /* the re-run registers the rest and recognises what is stored */
    char *o = NULL, *e = NULL, want[96];
    const char *args[] = {"ingest", "--store", st, "--register", folder, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, args), 0);
    snprintf(want, sizeof want, "%llu added (%llu registered), %llu already stored",
             (unsigned long long)(MESHES - c.registered), (unsigned long long)(MESHES - c.registered),
             (unsigned long long)c.registered);
    if (!strstr(o, want)) fail_msg("re-run: wanted '%s' in: %s%s", want, o, e);
    assert_int_equal(templates_in(st), before + MESHES);
    free(o), free(e), free(st), free(folder);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_similarity),   cmocka_unit_test(test_target_check),
        cmocka_unit_test(test_round_trip),   cmocka_unit_test(test_run_bad_input),
        cmocka_unit_test(test_binding),      cmocka_unit_test(test_cli_register),
        cmocka_unit_test(test_cli_ingest_register),
        cmocka_unit_test(test_kill_during_ingest_register),
        cmocka_unit_test(test_avatar_binding_key),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
