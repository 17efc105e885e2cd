/* register/ (issue 13), the library: registration of the store's
 * connectivity onto a mesh of another connectivity, the similarity fit,
 * the target checks, the binding of a foreign avatar. (mimic register and
 * ingest --register: test_register_cli.c.)
 *
 * Ground truth by re-triangulation (support/retriangulate.h): the target
 * is a synth body subdivided and renumbered, or decimated, so that it
 * shares no connectivity with the connectivity registered, while the true
 * place of vertex i is the original body's vertex i. The registration
 * starts from another subject, so it has to move every vertex to be right. */
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


/* One synth dataset in memory. */
#define L_SUBJECTS 2
#define L_POSES 3
#define L_VERTICES 2000
static uint32_t n, nf;
static uint32_t *faces;
static mim_landmark_map_t map;
static mim_xfer_topology_t *topo;
static float *lib_body[L_SUBJECTS][L_POSES];

#define CORR_MEAN_MM 15.0
#define CORR_P95_MM 40.0
#define SURF_MEAN_MM 1.0

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
    return mim_xfer_topology_open(&topo, n, faces, nf, &err) ? -1 : 0;
}

static int teardown(void **state)
{
    (void)state;
    for (int s = 0; s < L_SUBJECTS; s++)
        for (int p = 0; p < L_POSES; p++) free(lib_body[s][p]);
    mim_xfer_topology_close(&topo);
    free(faces);
    return 0;
}

static void landmarks_of(const float *body, const mim_landmark_map_t *m, float *out)
{
    for (uint32_t l = 0; l < m->count; l++) memcpy(out + 3 * l, body + 3 * (size_t)m->vertex[l], 3 * sizeof *out);
}

/* The target of a truth body (rt_target): how 0 subdivided, 1 decimated;
 * renumbered either way, never the truth's own connectivity. */
static void retriangulate(const float *truth, uint32_t count, const uint32_t *f, uint32_t count_f, int how,
                          uint64_t seed, mim_mesh_t *target)
{
    mim_mesh_t body = {count, count_f, (float *)truth, (uint32_t *)f};
    assert_int_equal(rt_target(&body, how, seed, target), 0);
    assert_int_not_equal(target->n_vertices, count);
}

static void correspondence(const float *a, const float *b, uint32_t count, double *mean_mm, double *p95_mm)
{
    assert_int_equal(rt_correspondence(a, b, count, mean_mm, p95_mm), 0);
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
    /* issue 29: a mirror image (left and right swapped: the landmarks and
     * the mesh with x negated) is refused before the solve, in one line */
    {
        mim_mesh_t mirror = {0};
        assert_int_equal(mim_mesh_alloc(&mirror, target.n_vertices, target.n_faces), 0);
        for (uint32_t v = 0; v < target.n_vertices; v++)
            mirror.positions[3 * v] = -target.positions[3 * v], mirror.positions[3 * v + 1] = target.positions[3 * v + 1],
            mirror.positions[3 * v + 2] = target.positions[3 * v + 2];
        for (uint32_t f = 0; f < target.n_faces; f++) /* wound outwards again */
            mirror.faces[3 * f] = target.faces[3 * f], mirror.faces[3 * f + 1] = target.faces[3 * f + 2],
            mirror.faces[3 * f + 2] = target.faces[3 * f + 1];
        float ml[3 * MIM_LANDMARKS_MAX];
        for (uint32_t l = 0; l < map.count; l++)
            ml[3 * l] = -lm[3 * l], ml[3 * l + 1] = lm[3 * l + 1], ml[3 * l + 2] = lm[3 * l + 2];
        memset(&err, 0, sizeof err);
        assert_int_equal(mim_reg_run(reg, lib_body[1][1], &mirror, ml, "mirror.ply", out, NULL, &err), MIM_EFORMAT);
        assert_non_null(strstr(err.msg, "mirror.ply"));
        assert_non_null(strstr(err.msg, "mirror image"));
        assert_null(strchr(err.msg, '\n'));
        /* the same mesh with its landmarks on their own sides (l_ at +x again): registered */
        float back[3 * MIM_LANDMARKS_MAX];
        for (uint32_t l = 0; l < map.count; l++) memcpy(back + 3 * l, ml + 3 * map.mirror[l], 3 * sizeof *back);
        mim_reg_report_t rep;
        assert_int_equal(mim_reg_run(reg, lib_body[1][1], &mirror, back, "mirror.ply", out, &rep, &err), 0);
        assert_true(rep.volume_ratio > 0.8 && rep.volume_ratio < 1.25);
        for (int g = 0; g < MIM_REG_REGIONS; g++) assert_true(rep.distortion_pct[g] >= 0 && rep.distortion_pct[g] < 50);
        mim_mesh_free(&mirror);
    }
    /* a bow: the spine landmark beside the chest, forward along up, so that
     * the landmark frame is nearly flat (mh-bodies' pose 10: -0.16 to 0.03
     * of a frame), is no mirror image: registered (refused at 1e-3 before) */
    {
        float bow[3 * MIM_LANDMARKS_MAX];
        memcpy(bow, lm, 3 * map.count * sizeof *bow);
        const int sp = mim_landmarks_find(&map, "spine"), ch = mim_landmarks_find(&map, "chest"),
                  pe = mim_landmarks_find(&map, "pelvis");
        assert_true(sp >= 0 && ch >= 0 && pe >= 0);
        /* spine = chest - 0.3 (chest - pelvis), nudged 2 mm to the front: forward from the
         * spine to the chest is then up, tipped a hair to the back (the other sign) */
        for (int c = 0; c < 3; c++) bow[3 * sp + c] = lm[3 * ch + c] - 0.3f * (lm[3 * ch + c] - lm[3 * pe + c]);
        bow[3 * sp + 2] += 0.002f;
        mim_reg_report_t rep;
        memset(&err, 0, sizeof err);
        int rc = mim_reg_run(reg, lib_body[1][1], &target, bow, "bow.ply", out, &rep, &err);
        if (rc) fail_msg("a nearly flat landmark frame: %s", err.msg);
    }
    /* a body flattened to 2 mm: the registration encloses almost nothing, refused */
    {
        mim_mesh_t flat = {0};
        assert_int_equal(mim_mesh_alloc(&flat, target.n_vertices, target.n_faces), 0);
        memcpy(flat.faces, target.faces, 3 * (size_t)target.n_faces * sizeof *flat.faces);
        float fl[3 * MIM_LANDMARKS_MAX];
        for (uint32_t v = 0; v < target.n_vertices; v++)
            for (int c = 0; c < 3; c++) flat.positions[3 * v + c] = target.positions[3 * v + c] * (c == 2 ? 0.01f : 1.0f);
        for (uint32_t l = 0; l < 3 * map.count; l++) fl[l] = lm[l] * (l % 3 == 2 ? 0.01f : 1.0f);
        memset(&err, 0, sizeof err);
        int rc = mim_reg_run(reg, lib_body[1][1], &flat, fl, "flat.ply", out, NULL, &err);
        print_message("a flattened body: %s\n", err.msg);
        assert_true(rc < 0);
        assert_non_null(strstr(err.msg, "flat.ply"));
        mim_mesh_free(&flat);
    }
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

/* mim_reg_likest: of candidate bodies, the one a similarity brings
 * nearest to the target, whatever its place, turn and size; candidates
 * that cannot be fitted are passed over; none at all is refused. */
static void test_likest(void **s)
{
    (void)s;
    mim_rng_t rng;
    mim_rng_seed(&rng, 7, 0);
    enum { NC = 4 };
    float cand[NC][3 * 16], target[3 * 16];
    for (int c = 0; c < NC; c++)
        for (int i = 0; i < 3 * 16; i++) cand[c][i] = (float)(mim_rng_unit(&rng) - 0.5);
    /* the target: candidate 2 turned, scaled and moved, 1 mm off */
    double R[9];
    rotation(0.2, 1.0, -0.4, 0.9, R);
    mim_reg_similarity_t known = {1.8, {0}, {2.0, 0.5, -1.0}};
    memcpy(known.R, R, sizeof R);
    mim_reg_similarity_apply(&known, cand[2], 16, target);
    for (int i = 0; i < 3 * 16; i++) target[i] += (float)(0.001 * (mim_rng_unit(&rng) - 0.5));
    uint32_t best = 99;
    mim_error_t err = {0};
    assert_int_equal(mim_reg_likest(target, 16, &cand[0][0], NC, &best, &err), 0);
    assert_int_equal(best, 2);
    /* candidate 2 collapsed to a point: passed over, another is the likest */
    for (int i = 0; i < 3 * 16; i++) cand[2][i] = 0.25f;
    best = 99;
    assert_int_equal(mim_reg_likest(target, 16, &cand[0][0], NC, &best, &err), 0);
    assert_true(best != 2 && best < NC);
    assert_int_equal(mim_reg_likest(target, 16, &cand[2][0], 1, &best, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "none of 1 candidate bodies fits the landmarks"));
    mim_error_clear(&err);
    assert_int_equal(mim_reg_likest(target, 16, &cand[0][0], 0, &best, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "none of 0 candidate bodies"));
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
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    expect_target(&m, 0, NULL);
    mim_mesh_free(&m);
    /* a body passes */
    mim_mesh_t body = {n, nf, lib_body[0][0], faces};
    expect_target(&body, 0, NULL);

    /* an edge shared by three triangles: the tetrahedron and a fin on edge 0-2 */
    assert_int_equal(mim_mesh_alloc(&m, 5, 5), 0);
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    float fin[3] = {-0.4f, 0.8f, -0.3f};
    memcpy(m.positions + 12, fin, sizeof fin);
    const uint32_t extra[3] = {0, 4, 2};
    memcpy(m.faces + 12, extra, sizeof extra);
    expect_target(&m, MIM_ETOPOLOGY, "non-manifold: edge 0-2 is shared by 3 triangles");
    mim_mesh_free(&m);

    /* two tetrahedra side by side */
    assert_int_equal(mim_mesh_alloc(&m, 8, 8), 0);
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    rt_tetrahedron(m.positions + 12, m.faces + 12, 4, 1.0f);
    expect_target(&m, MIM_ETOPOLOGY, "disconnected: 2 pieces");
    mim_mesh_free(&m);

    /* a vertex on no triangle */
    assert_int_equal(mim_mesh_alloc(&m, 5, 4), 0);
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    m.positions[12] = 0.2f, m.positions[13] = 0.2f, m.positions[14] = 0.2f;
    expect_target(&m, MIM_ETOPOLOGY, "vertex 4 is on no triangle");
    mim_mesh_free(&m);

    /* a NaN coordinate, an infinite one: the body check's MIM_ENONFINITE */
    assert_int_equal(mim_mesh_alloc(&m, 4, 4), 0);
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    m.positions[3 * 2 + 1] = NAN;
    expect_target(&m, MIM_ENONFINITE, "vertex 2");
    m.positions[3 * 2 + 1] = -INFINITY;
    expect_target(&m, MIM_ENONFINITE, "vertex 2");
    /* millimetres (a 1.6 m body as 1600 units), and a body 1 km away: not a body */
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    for (int i = 0; i < 12; i++) m.positions[i] *= 1000.0f;
    expect_target(&m, MIM_EFORMAT, "10 m box");
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    for (int i = 0; i < 4; i++) m.positions[3 * i] += 2000.0f;
    expect_target(&m, MIM_EFORMAT, "from the origin");
    /* all at one point */
    for (int i = 0; i < 12; i++) m.positions[i] = 0.5f;
    expect_target(&m, MIM_EFORMAT, "not a body");
    /* a face past the vertices */
    rt_tetrahedron(m.positions, m.faces, 0, 0);
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
    rt_tetrahedron(m.positions, m.faces, 0, 0);
    rt_tetrahedron(m.positions + 12, m.faces + 12, 4, 1.0f);
    assert_int_equal(mim_reg_surface_distance(&m, p, 1, &d, &err), MIM_ETOPOLOGY);
    mim_mesh_free(&m);
    /* and on a good one: a point above a face's middle is its height away */
    assert_int_equal(mim_mesh_alloc(&m, 4, 4), 0);
    rt_tetrahedron(m.positions, m.faces, 0, 0);
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_similarity), cmocka_unit_test(test_likest), cmocka_unit_test(test_target_check), cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_run_bad_input), cmocka_unit_test(test_binding),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
