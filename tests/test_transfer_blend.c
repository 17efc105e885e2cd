/* transfer/blend.c (issue 15): the per-vertex average of several
 * templates' frames and the segment correction, on rotations and landmark
 * skeletons whose answers are known; and core's shortest arc. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "mim_core.h"
#include "mim_transfer.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define NV 5

static double angle_between(mim_quat a, mim_quat b)
{
    double d = fabs(a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w);
    return 2 * acos(d > 1 ? 1 : d);
}

static void frames_of(mim_quat q, double *F)
{
    for (int i = 0; i < NV; i++) mim_quat_to_matrix(q, F + 9 * i);
}

static void test_quat_between(void **state)
{
    (void)state;
    const mim_vec3 pairs[][2] = {{{1, 0, 0}, {0, 1, 0}}, {{0, 0, 2}, {0, 3, 3}}, {{1, 2, 3}, {1, 2, 3}},
                                 {{1, 0, 0}, {-1, 0, 0}}, {{0, 1, 0}, {0, -5, 0}}};
    for (size_t k = 0; k < sizeof pairs / sizeof pairs[0]; k++) {
        mim_quat q = mim_quat_between(pairs[k][0], pairs[k][1]);
        mim_vec3 r = mim_v3_normalize(mim_quat_rotate(q, pairs[k][0])), b = mim_v3_normalize(pairs[k][1]);
        assert_true(mim_v3_norm(mim_v3_sub(r, b)) < 1e-9);
        /* the shortest arc: its angle is the angle between the directions */
        double want = acos(fmax(-1, fmin(1, mim_v3_dot(mim_v3_normalize(pairs[k][0]), b))));
        assert_true(fabs(angle_between(q, mim_quat_identity()) - want) < 1e-9);
    }
    mim_quat z = mim_quat_between(mim_v3(0, 0, 0), mim_v3(1, 0, 0));
    assert_true(angle_between(z, mim_quat_identity()) < 1e-12);
}

static void test_blend_rotations(void **state)
{
    (void)state;
    double A[9 * NV], B[9 * NV], C[9 * NV], out[9 * NV];
    mim_vec3 axis = mim_v3(0.3, 1, -0.2);
    frames_of(mim_quat_axis_angle(axis, 0.2), A);
    frames_of(mim_quat_axis_angle(axis, 0.8), B);
    /* the same rotation stored as -q must not cancel */
    mim_quat c = mim_quat_axis_angle(axis, 0.8);
    c.x = -c.x, c.y = -c.y, c.z = -c.z, c.w = -c.w;
    frames_of(c, C);
    const double *two[2] = {A, B}, *neg[2] = {A, C};
    mim_xfer_frames_blend(NV, 2, two, NULL, out);
    for (int i = 0; i < NV; i++)
        assert_true(angle_between(mim_quat_from_matrix(out + 9 * i), mim_quat_axis_angle(axis, 0.5)) < 1e-9);
    mim_xfer_frames_blend(NV, 2, neg, NULL, out);
    assert_true(angle_between(mim_quat_from_matrix(out), mim_quat_axis_angle(axis, 0.5)) < 1e-9);
    /* weights pull towards the heavier: 3:1 lies between the middle and B */
    const double w31[2] = {1, 3};
    mim_xfer_frames_blend(NV, 2, two, w31, out);
    double to_b = angle_between(mim_quat_from_matrix(out), mim_quat_axis_angle(axis, 0.8));
    assert_true(to_b < 0.2 && to_b > 0.1);
    /* a zero or NaN weight counts nothing; none positive gives the first */
    const double w0[2] = {0, 2}, wnan[2] = {NAN, 1}, wnone[2] = {0, -1};
    mim_xfer_frames_blend(NV, 2, two, w0, out);
    assert_true(angle_between(mim_quat_from_matrix(out), mim_quat_axis_angle(axis, 0.8)) < 1e-9);
    mim_xfer_frames_blend(NV, 2, two, wnan, out);
    assert_true(angle_between(mim_quat_from_matrix(out), mim_quat_axis_angle(axis, 0.8)) < 1e-9);
    mim_xfer_frames_blend(NV, 2, two, wnone, out);
    assert_memory_equal(out, A, sizeof A);
    /* in place over the first */
    memcpy(C, A, sizeof A);
    const double *inplace[2] = {C, B};
    mim_xfer_frames_blend(NV, 2, inplace, NULL, C);
    assert_true(angle_between(mim_quat_from_matrix(C + 9 * (NV - 1)), mim_quat_axis_angle(axis, 0.5)) < 1e-9);
}

static void frame_of_quat(mim_quat q, double *F) { mim_quat_to_matrix(q, F); }

/* out_i = P_i R_i^T A_i: a template turned by G_i from its reference turns
 * the avatar's frames by G_i, whatever the three bodies' own frames are.
 * Angles to 1e-6: acos near 1 turns 1e-16 of rounding into 3e-8 rad. */
static void test_frames_relative(void **state)
{
    (void)state;
    double P[9 * NV], R[9 * NV], A[9 * NV], out[9 * NV];
    mim_quat G[NV], a[NV];
    for (int i = 0; i < NV; i++) {
        mim_quat r = mim_quat_axis_angle(mim_v3(1, i, 0.5), 0.3 + 0.4 * i);
        G[i] = mim_quat_axis_angle(mim_v3(-0.2, 1, i), 0.2 * (i + 1));
        a[i] = mim_quat_axis_angle(mim_v3(0, 0.3, 1), -0.7 + 0.1 * i);
        frame_of_quat(r, R + 9 * i);
        frame_of_quat(mim_quat_mul(G[i], r), P + 9 * i);
        frame_of_quat(a[i], A + 9 * i);
    }
    mim_xfer_frames_relative(NV, P, R, A, out);
    for (int i = 0; i < NV; i++)
        assert_true(angle_between(mim_quat_from_matrix(out + 9 * i), mim_quat_mul(G[i], a[i])) < 1e-6);
    /* not turned (pose = reference): the avatar's own frames */
    mim_xfer_frames_relative(NV, R, R, A, out);
    for (int i = 0; i < 9 * NV; i++) assert_true(fabs(out[i] - A[i]) < 1e-12);
    /* in place over the avatar's */
    mim_xfer_frames_relative(NV, P, R, A, A);
    for (int i = 0; i < NV; i++)
        assert_true(angle_between(mim_quat_from_matrix(A + 9 * i), mim_quat_mul(G[i], a[i])) < 1e-6);
}

/* An octahedron: the frames of a mesh turned rigidly are its frames turned,
 * and its encoding W does not change, so the relative frames of a turned
 * template carry the turn to another body and its encoding change is 0. */
static void test_relative_on_meshes(void **state)
{
    (void)state;
    static const uint32_t faces[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
    static const float X[18] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
    float Y[18], GX[18];
    mim_quat g = mim_quat_axis_angle(mim_v3(0.3, 1, 0.2), 0.9);
    for (int i = 0; i < 6; i++) {
        mim_vec3 r = mim_quat_rotate(g, mim_v3(X[3 * i], X[3 * i + 1], X[3 * i + 2]));
        GX[3 * i] = (float)r.x, GX[3 * i + 1] = (float)r.y, GX[3 * i + 2] = (float)r.z;
        Y[3 * i] = 1.3f * X[3 * i], Y[3 * i + 1] = 0.8f * X[3 * i + 1], Y[3 * i + 2] = X[3 * i + 2] + 0.1f * (float)i;
    }
    mim_xfer_topology_t *t = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_xfer_topology_open(&t, 6, faces, 8, &err), 0);
    double FX[54], FGX[54], FY[54], out[54], WX[18], WGX[18], WY[18], Wout[18];
    mim_xfer_frames(t, X, FX);
    mim_xfer_frames(t, GX, FGX);
    mim_xfer_frames(t, Y, FY);
    mim_xfer_frames_relative(6, FGX, FX, FY, out);
    for (int i = 0; i < 6; i++) {
        mim_quat want = mim_quat_mul(g, mim_quat_from_matrix(FY + 9 * i));
        assert_true(angle_between(mim_quat_from_matrix(out + 9 * i), want) < 1e-6);
    }
    mim_xfer_encode(t, X, FX, WX);
    mim_xfer_encode(t, GX, FGX, WGX);
    mim_xfer_encode(t, Y, FY, WY);
    const double *wp[1] = {WGX}, *wr[1] = {WX};
    mim_xfer_encoding_relative(6, 1, wp, wr, NULL, NULL, WY, Wout);
    for (int i = 0; i < 18; i++) assert_true(fabs(Wout[i] - WY[i]) < 1e-6);
    mim_xfer_topology_close(&t);
}

static void test_encoding_relative(void **state)
{
    (void)state;
    enum { N = 4 };
    double Wa[3 * N], P1[3 * N], R1[3 * N], P2[3 * N], R2[3 * N], out[3 * N];
    for (int i = 0; i < 3 * N; i++) {
        Wa[i] = 0.1 * i, R1[i] = -0.5 * i, P1[i] = R1[i] + 1, R2[i] = 2.0 + i, P2[i] = R2[i] + 3;
    }
    const double *wp[2] = {P1, P2}, *wr[2] = {R1, R2};
    /* equal weights: the mean change, 2 */
    mim_xfer_encoding_relative(N, 2, wp, wr, NULL, NULL, Wa, out);
    for (int i = 0; i < 3 * N; i++) assert_true(fabs(out[i] - (Wa[i] + 2)) < 1e-12);
    /* weights 1:3: 2.5 */
    const double w13[2] = {1, 3};
    mim_xfer_encoding_relative(N, 2, wp, wr, w13, NULL, Wa, out);
    for (int i = 0; i < 3 * N; i++) assert_true(fabs(out[i] - (Wa[i] + 2.5)) < 1e-12);
    /* scales: (2 * 1 + 3) / 2, a NaN scale counting 1 */
    const double sc[2] = {2, NAN};
    mim_xfer_encoding_relative(N, 2, wp, wr, NULL, sc, Wa, out);
    for (int i = 0; i < 3 * N; i++) assert_true(fabs(out[i] - (Wa[i] + 2.5)) < 1e-12);
    /* a zero or NaN weight counts nothing; none positive, or k = 0: W_avatar */
    const double w0[2] = {0, 1}, wbad[2] = {NAN, -1};
    mim_xfer_encoding_relative(N, 2, wp, wr, w0, NULL, Wa, out);
    for (int i = 0; i < 3 * N; i++) assert_true(fabs(out[i] - (Wa[i] + 3)) < 1e-12);
    memset(out, 0, sizeof out);
    mim_xfer_encoding_relative(N, 2, wp, wr, wbad, NULL, Wa, out);
    assert_memory_equal(out, Wa, sizeof Wa);
    memset(out, 0, sizeof out);
    mim_xfer_encoding_relative(N, 0, wp, wr, NULL, NULL, Wa, out);
    assert_memory_equal(out, Wa, sizeof Wa);
    /* in place over the avatar's */
    double Wb[3 * N];
    memcpy(Wb, Wa, sizeof Wa);
    mim_xfer_encoding_relative(N, 1, wp, wr, NULL, NULL, Wb, Wb);
    for (int i = 0; i < 3 * N; i++) assert_true(fabs(Wb[i] - (Wa[i] + 1)) < 1e-12);
    /* the scale: rms ratio; NaN when it cannot tell */
    double half[3 * N], zero[3 * N] = {0};
    for (int i = 0; i < 3 * N; i++) half[i] = -0.5 * Wa[i];
    assert_true(fabs(mim_xfer_encoding_scale(N, Wa, half) - 2) < 1e-12);
    assert_true(fabs(mim_xfer_encoding_scale(N, half, Wa) - 0.5) < 1e-12);
    assert_true(isnan(mim_xfer_encoding_scale(N, Wa, zero)));
    half[5] = INFINITY;
    assert_true(isnan(mim_xfer_encoding_scale(N, Wa, half)));
    half[5] = 0, Wb[0] = NAN;
    assert_true(isnan(mim_xfer_encoding_scale(N, Wb, half)));
}

/* A landmark skeleton (the 16 default names, default order) standing in
 * an A-pose: x is the body's left, y up. */
static void skeleton(float *lm)
{
    static const float p[16][3] = {
        {0, 1.70f, 0},      {0, 1.40f, 0},     {0, 1.00f, 0},      {0.18f, 1.45f, 0}, {-0.18f, 1.45f, 0},
        {0.30f, 1.20f, 0},  {-0.30f, 1.20f, 0}, {0.40f, 0.95f, 0.05f}, {-0.40f, 0.95f, 0.05f}, {0.10f, 0.95f, 0},
        {-0.10f, 0.95f, 0}, {0.11f, 0.50f, 0.02f}, {-0.11f, 0.50f, 0.02f}, {0.12f, 0.08f, 0}, {-0.12f, 0.08f, 0},
        {0, 1.20f, 0}};
    memcpy(lm, p, sizeof p);
}

static mim_vec3 lm_at(const float *lm, int l) { return mim_v3(lm[3 * l], lm[3 * l + 1], lm[3 * l + 2]); }

static void test_segment_correction(void **state)
{
    (void)state;
    mim_landmark_map_t map;
    uint32_t v[16];
    for (int i = 0; i < 16; i++) v[i] = (uint32_t)i;
    mim_landmarks_default(&map, v, 0);
    float from[48], to[48];
    skeleton(from);
    mim_quat R[MIM_SEGMENTS];
    mim_error_t err = {0};
    /* the same skeleton: no turn anywhere */
    assert_int_equal(mim_xfer_segment_correction(&map, from, from, R, &err), 0);
    for (int s = 0; s < MIM_SEGMENTS; s++) assert_true(angle_between(R[s], mim_quat_identity()) < 1e-6);
    /* the whole body turned 30 degrees about +Y: every segment turns so */
    mim_quat turn = mim_quat_axis_angle(mim_v3(0, 1, 0), M_PI / 6);
    for (int l = 0; l < 16; l++) {
        mim_vec3 r = mim_quat_rotate(turn, lm_at(from, l));
        to[3 * l] = (float)r.x, to[3 * l + 1] = (float)r.y, to[3 * l + 2] = (float)r.z;
    }
    assert_int_equal(mim_xfer_segment_correction(&map, from, to, R, &err), 0);
    for (int s = 0; s < MIM_SEGMENTS; s++) assert_true(angle_between(R[s], turn) < 1e-5);
    /* the left forearm alone bent 60 degrees at the elbow (about +Z):
     * the forearm and the hand turn, the upper arm and the rest do not */
    skeleton(to);
    mim_quat bend = mim_quat_axis_angle(mim_v3(0, 0, 1), M_PI / 3);
    mim_vec3 e = lm_at(from, 5), w = mim_v3_add(e, mim_quat_rotate(bend, mim_v3_sub(lm_at(from, 7), e)));
    to[21] = (float)w.x, to[22] = (float)w.y, to[23] = (float)w.z;
    assert_int_equal(mim_xfer_segment_correction(&map, from, to, R, &err), 0);
    mim_vec3 d0 = mim_v3_sub(lm_at(from, 7), e), d1 = mim_v3_sub(lm_at(to, 7), e);
    mim_quat arc = mim_quat_between(d0, d1);
    assert_true(angle_between(R[7], arc) < 1e-5);  /* l_forearm */
    assert_true(angle_between(R[9], arc) < 1e-5);  /* l_hand follows it */
    assert_true(angle_between(R[5], mim_quat_identity()) < 1e-6); /* l_upperarm */
    assert_true(angle_between(R[8], mim_quat_identity()) < 1e-6); /* r_forearm */
    assert_true(angle_between(R[0], mim_quat_identity()) < 1e-6); /* pelvis */
    /* bad input */
    to[0] = NAN;
    assert_int_equal(mim_xfer_segment_correction(&map, from, to, R, &err), MIM_ENONFINITE);
    assert_non_null(strstr(mim_error_text(&err), "head"));
    snprintf(map.names[15], sizeof map.names[15], "waist");
    skeleton(to);
    mim_error_t err2 = {0}; /* the first error of an error object stays */
    assert_int_equal(mim_xfer_segment_correction(&map, from, to, R, &err2), MIM_EUNSUPPORTED);
    assert_non_null(strstr(mim_error_text(&err2), "spine"));
}

/* The build distance: none between one body at any size, place and turn
 * (pair distances over their sum); some when one limb grows, more when it
 * grows more; symmetric; NaN for a landmark that is not finite. */
static void test_build_distance(void **state)
{
    (void)state;
    enum { L = 16 };
    float a[3 * L], b[3 * L], c[3 * L], d[3 * L];
    for (int l = 0; l < L; l++) /* a spread of points, none on another */
        for (int k = 0; k < 3; k++)
            a[3 * l + k] = (float)(0.1 * l * (k + 1) + 0.3 * sin(1.7 * l + k));
    mim_quat q = mim_quat_axis_angle(mim_v3(1, 2, 3), 0.9);
    for (int l = 0; l < L; l++) {
        mim_vec3 v = mim_quat_rotate(q, mim_v3(a[3 * l], a[3 * l + 1], a[3 * l + 2]));
        b[3 * l] = (float)(1.7 * v.x + 0.5), b[3 * l + 1] = (float)(1.7 * v.y - 2), b[3 * l + 2] = (float)(1.7 * v.z);
    }
    memcpy(c, a, sizeof a), memcpy(d, a, sizeof a);
    for (int k = 0; k < 3; k++) /* the last landmark further out: once, then twice as far */
        c[3 * (L - 1) + k] += 0.05f * (float)(k + 1), d[3 * (L - 1) + k] += 0.10f * (float)(k + 1);
    assert_true(mim_xfer_build_distance(a, a, L) == 0);
    assert_true(mim_xfer_build_distance(a, b, L) < 1e-6);
    double ac = mim_xfer_build_distance(a, c, L), ad = mim_xfer_build_distance(a, d, L);
    assert_true(ac > 1e-4);
    assert_true(ad > 1.5 * ac);
    assert_true(fabs(mim_xfer_build_distance(c, a, L) - ac) < 1e-12);
    c[4] = NAN;
    assert_true(isnan(mim_xfer_build_distance(a, c, L)));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_quat_between),
        cmocka_unit_test(test_blend_rotations),
        cmocka_unit_test(test_segment_correction),
        cmocka_unit_test(test_frames_relative),
        cmocka_unit_test(test_relative_on_meshes),
        cmocka_unit_test(test_encoding_relative),
        cmocka_unit_test(test_build_distance),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
