/* transfer/: a key frame's right-hand side as Laplacian offsets (issue 31):
 * the orientation drive's turned rest offsets and a blend's offsets from
 * kept quaternions give what the frames' way gives, within rounding, and
 * so does the transfer from them; on a synth body made here. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "mim_core.h"
#include "mim_synth.h"
#include "mim_transfer.h"
#include "mim_vest_kinematics.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define POSES 3

static struct {
    mim_synth_t *synth;
    mim_xfer_topology_t *topo;
    mim_xfer_solver_t *solver;
    mim_landmark_map_t map;
    uint32_t n;
    float *rest, *pose[POSES];     /* subject 0 at rest (the avatar); subject 1's poses */
    double *F, *W, *D, *T[POSES];  /* the avatar's frames, W, rest offsets; subject 1's frames */
    mim_xfer_skin_t *skin;
} fx;

static int setup(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_synth_options_t o = {.subjects = 2, .poses = POSES, .vertices = 3000, .seed = 5};
    if (mim_synth_create(&fx.synth, &o, &err)) return -1;
    const uint32_t n = fx.n = mim_synth_n_vertices(fx.synth);
    mim_synth_landmarks(fx.synth, &fx.map);
    fx.rest = malloc(3 * (size_t)n * sizeof *fx.rest);
    fx.F = malloc(9 * (size_t)n * sizeof *fx.F);
    fx.W = malloc(3 * (size_t)n * sizeof *fx.W);
    fx.D = malloc(3 * (size_t)n * sizeof *fx.D);
    fx.skin = malloc(n * sizeof *fx.skin);
    if (!fx.rest || !fx.F || !fx.W || !fx.D || !fx.skin || mim_synth_body(fx.synth, 0, 0, fx.rest)) return -1;
    for (int p = 0; p < POSES; p++) {
        fx.pose[p] = malloc(3 * (size_t)n * sizeof *fx.pose[p]);
        fx.T[p] = malloc(9 * (size_t)n * sizeof *fx.T[p]);
        if (!fx.pose[p] || !fx.T[p] || mim_synth_body(fx.synth, 1, (uint32_t)p, fx.pose[p])) return -1;
    }
    const uint32_t *faces = mim_synth_faces(fx.synth);
    if (mim_xfer_topology_open(&fx.topo, n, faces, mim_synth_n_faces(fx.synth), &err)) return -1;
    mim_xfer_frames(fx.topo, fx.rest, fx.F);
    mim_xfer_encode(fx.topo, fx.rest, fx.F, fx.W);
    mim_xfer_decode(n, fx.F, fx.W, fx.D);
    for (int p = 0; p < POSES; p++) mim_xfer_frames(fx.topo, fx.pose[p], fx.T[p]);
    mim_mesh_t m = {n, mim_synth_n_faces(fx.synth), fx.rest, (uint32_t *)faces};
    mim_vest_skeleton_t sk;
    double bones[MIM_VEST_SEGMENTS * 6];
    if (mim_vest_skeleton_estimate(&sk, &m, &fx.map, &err)) return -1;
    mim_vest_skeleton_bones(&sk, bones);
    if (mim_xfer_skin_from_bones_wide(fx.topo, fx.rest, bones, MIM_VEST_SEGMENTS, MIM_XFER_DEFAULT_SKIN_SMOOTHING,
                                      MIM_XFER_SKIN_WIDE_SEGMENTS, MIM_XFER_DEFAULT_SKIN_SMOOTHING_WIDE, fx.skin, &err))
        return -1;
    return mim_xfer_solver_open(&fx.solver, fx.topo, fx.map.vertex, fx.map.count, NULL, &err);
}

static int teardown(void **state)
{
    (void)state;
    mim_xfer_solver_close(&fx.solver);
    mim_xfer_topology_close(&fx.topo);
    mim_synth_destroy(&fx.synth);
    for (int p = 0; p < POSES; p++) free(fx.pose[p]), free(fx.T[p]);
    free(fx.rest), free(fx.F), free(fx.W), free(fx.D), free(fx.skin);
    return 0;
}

/* The largest difference of two arrays relative to the largest entry of a. */
static double rel_diff(const double *a, const double *b, size_t count)
{
    double d = 0, m = 0;
    for (size_t i = 0; i < count; i++) d = fmax(d, fabs(a[i] - b[i])), m = fmax(m, fabs(a[i]));
    return d / m;
}

/* Segment rotations of every kind the drive meets: identity, large turns
 * about varied axes, and some given as -q (the same rotation). */
static void rotations(mim_quat R[MIM_VEST_SEGMENTS])
{
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) {
        R[g] = g % 5 == 0 ? mim_quat_identity()
                          : mim_quat_axis_angle(mim_v3_normalize(mim_v3(1 + g, 2 - g, 0.5 * g)), 0.3 * g);
        if (g % 3 == 1) R[g] = (mim_quat){-R[g].x, -R[g].y, -R[g].z, -R[g].w};
    }
}

static void test_skin_offsets(void **state)
{
    (void)state;
    const uint32_t n = fx.n;
    mim_quat R[MIM_VEST_SEGMENTS];
    rotations(R);
    double *G = malloc(9 * (size_t)n * sizeof *G), *want = malloc(3 * (size_t)n * sizeof *want),
           *got = malloc(3 * (size_t)n * sizeof *got);
    mim_xfer_skin_frames(n, fx.skin, fx.F, R, G);
    mim_xfer_decode(n, G, fx.W, want);
    mim_xfer_skin_offsets(n, fx.skin, fx.D, R, got);
    assert_true(rel_diff(want, got, 3 * (size_t)n) < 1e-12);
    /* the orientation drive's solve from them: the frames' result */
    float u[3 * MIM_LANDMARKS_MAX], *a = malloc(3 * (size_t)n * sizeof *a), *b = malloc(3 * (size_t)n * sizeof *b);
    for (uint32_t k = 0; k < fx.map.count; k++)
        memcpy(u + 3 * k, fx.pose[1] + 3 * (size_t)fx.map.vertex[k], 3 * sizeof *u);
    mim_xfer_options_t one = {.max_iterations = 1};
    assert_int_equal(mim_xfer_transfer(fx.solver, fx.W, n, G, u, fx.map.count, &one, a, NULL, NULL), 0);
    assert_int_equal(mim_xfer_transfer_offsets(fx.solver, fx.W, n, got, u, fx.map.count, &one, b, NULL, NULL), 0);
    for (size_t i = 0; i < 3 * (size_t)n; i++) assert_true(fabsf(a[i] - b[i]) < 1e-6f);
    free(G), free(want), free(got), free(a), free(b);
}

static void test_offsets_blend(void **state)
{
    (void)state;
    const uint32_t n = fx.n;
    double *Q[POSES], *B = malloc(9 * (size_t)n * sizeof *B), *want = malloc(3 * (size_t)n * sizeof *want),
           *got = malloc(3 * (size_t)n * sizeof *got);
    const double *frames[POSES], *quats[POSES];
    for (int p = 0; p < POSES; p++) {
        Q[p] = malloc(4 * (size_t)n * sizeof *Q[p]);
        mim_xfer_frames_to_quats(n, fx.T[p], Q[p]);
        frames[p] = fx.T[p], quats[p] = Q[p];
    }
    /* unequal, equal (NULL), one left out, none weighing (the first alone) */
    const double w3[POSES] = {1, 0.5, 2}, w0[POSES] = {0, 1, 1}, none[POSES] = {0, -1, NAN};
    const double *weights[] = {w3, NULL, w0, none};
    for (size_t c = 0; c < sizeof weights / sizeof weights[0]; c++)
        for (uint32_t k = 1; k <= POSES; k++) {
            mim_xfer_frames_blend(n, k, frames, weights[c], B);
            mim_xfer_decode(n, B, fx.W, want);
            mim_xfer_offsets_blend(n, k, quats, weights[c], fx.W, got);
            assert_true(rel_diff(want, got, 3 * (size_t)n) < 1e-12);
        }
    for (int p = 0; p < POSES; p++) free(Q[p]);
    free(B), free(want), free(got);
}

/* The iterated transfer from the offsets of its first frames is the one
 * from the frames: the same solves, the same stop, the same result. */
static void test_transfer_offsets(void **state)
{
    (void)state;
    const uint32_t n = fx.n;
    double *D0 = malloc(3 * (size_t)n * sizeof *D0);
    float u[3 * MIM_LANDMARKS_MAX], *a = malloc(3 * (size_t)n * sizeof *a), *b = malloc(3 * (size_t)n * sizeof *b);
    for (int p = 1; p < POSES; p++) {
        for (uint32_t k = 0; k < fx.map.count; k++)
            memcpy(u + 3 * k, fx.pose[p] + 3 * (size_t)fx.map.vertex[k], 3 * sizeof *u);
        mim_xfer_decode(n, fx.T[p], fx.W, D0);
        mim_xfer_report_t ra, rb;
        assert_int_equal(mim_xfer_transfer(fx.solver, fx.W, n, fx.T[p], u, fx.map.count, NULL, a, &ra, NULL), 0);
        assert_int_equal(mim_xfer_transfer_offsets(fx.solver, fx.W, n, D0, u, fx.map.count, NULL, b, &rb, NULL), 0);
        assert_true(ra.iterations > 1);
        assert_int_equal(ra.iterations, rb.iterations);
        assert_int_equal(ra.early_stopped, rb.early_stopped);
        for (size_t i = 0; i < 3 * (size_t)n; i++) assert_true(fabsf(a[i] - b[i]) < 1e-6f);
    }
    mim_error_t err = {0};
    assert_int_equal(mim_xfer_transfer_offsets(fx.solver, fx.W, n, NULL, u, fx.map.count, NULL, b, NULL, &err),
                     MIM_EINVAL);
    free(D0), free(a), free(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_skin_offsets),
        cmocka_unit_test(test_offsets_blend),
        cmocka_unit_test(test_transfer_offsets),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
