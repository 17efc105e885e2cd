/* transfer/skin.c: the avatar's segmentation over the vest's 17 segments
 * and the orientation drive's frames (issue 17), on a synth body made here. */
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

static struct {
    mim_synth_t *synth;
    mim_xfer_topology_t *topo;
    mim_landmark_map_t map;
    uint32_t n;
    float *rest;
    double bones[MIM_VEST_SEGMENTS * 6];
    mim_vest_skeleton_t sk;
} fx;

static int setup(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_synth_options_t o = {.subjects = 1, .poses = 2, .vertices = 3000, .seed = 11};
    if (mim_synth_create(&fx.synth, &o, &err)) return -1;
    fx.n = mim_synth_n_vertices(fx.synth);
    mim_synth_landmarks(fx.synth, &fx.map);
    fx.rest = malloc(3 * (size_t)fx.n * sizeof *fx.rest);
    if (!fx.rest || mim_synth_body(fx.synth, 0, 0, fx.rest)) return -1;
    mim_mesh_t m = {fx.n, mim_synth_n_faces(fx.synth), fx.rest, (uint32_t *)mim_synth_faces(fx.synth)};
    if (mim_vest_skeleton_estimate(&fx.sk, &m, &fx.map, &err)) return -1;
    mim_vest_skeleton_bones(&fx.sk, fx.bones);
    return mim_xfer_topology_open(&fx.topo, fx.n, mim_synth_faces(fx.synth), mim_synth_n_faces(fx.synth), &err);
}

static int teardown(void **state)
{
    (void)state;
    mim_xfer_topology_close(&fx.topo);
    mim_synth_destroy(&fx.synth);
    free(fx.rest);
    return 0;
}

static mim_xfer_skin_t *skin_of(uint32_t smoothing)
{
    mim_xfer_skin_t *skin = malloc(fx.n * sizeof *skin);
    assert_non_null(skin);
    mim_error_t err = {0};
    assert_int_equal(mim_xfer_skin_from_bones(fx.topo, fx.rest, fx.bones, MIM_VEST_SEGMENTS, smoothing, skin, &err), 0);
    return skin;
}

static float weight_of(const mim_xfer_skin_t *s, uint32_t bone)
{
    for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES; k++)
        if (s->weight[k] > 0 && s->bone[k] == bone) return s->weight[k];
    return 0;
}

/* the vertex nearest to point p */
static uint32_t nearest_vertex(mim_vec3 p)
{
    uint32_t best = 0;
    double bd = INFINITY;
    for (uint32_t i = 0; i < fx.n; i++) {
        mim_vec3 v = mim_v3(fx.rest[3 * i], fx.rest[3 * i + 1], fx.rest[3 * i + 2]);
        double d = mim_v3_norm(mim_v3_sub(v, p));
        if (d < bd) bd = d, best = i;
    }
    return best;
}

static void test_weights(void **state)
{
    (void)state;
    mim_xfer_skin_t *hard = skin_of(0), *soft = skin_of(MIM_XFER_DEFAULT_SKIN_SMOOTHING);
    uint32_t blended = 0;
    for (uint32_t i = 0; i < fx.n; i++) {
        /* without smoothing: one segment per vertex */
        assert_true(hard[i].weight[0] == 1.0f && hard[i].weight[1] == 0.0f);
        float sum = 0;
        for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES; k++) {
            sum += soft[i].weight[k];
            if (k) assert_true(soft[i].weight[k] <= soft[i].weight[k - 1]);
        }
        assert_float_equal(sum, 1.0f, 1e-5f);
        blended += soft[i].weight[1] > 0.1f;
        /* diffusion follows the surface: an arm's vertex takes nothing from the legs */
        if (soft[i].bone[0] == MIM_VEST_L_FOREARM || soft[i].bone[0] == MIM_VEST_L_HAND) {
            assert_true(weight_of(&soft[i], MIM_VEST_L_THIGH) == 0.0f);
            assert_true(weight_of(&soft[i], MIM_VEST_R_FOREARM) == 0.0f);
        }
    }
    assert_true(blended > fx.n / 20); /* the joints blend */
    /* mid-bone: that bone alone; at the elbow: both bones */
    mim_vec3 mid = mim_v3_lerp(fx.sk.pivot[MIM_VEST_L_UPPERARM], fx.sk.end[MIM_VEST_L_UPPERARM], 0.5);
    const mim_xfer_skin_t *m = &soft[nearest_vertex(mid)];
    assert_int_equal(m->bone[0], MIM_VEST_L_UPPERARM);
    assert_true(m->weight[0] > 0.9f);
    const mim_xfer_skin_t *e = &soft[nearest_vertex(fx.sk.pivot[MIM_VEST_L_FOREARM])];
    assert_true(weight_of(e, MIM_VEST_L_UPPERARM) > 0.15f && weight_of(e, MIM_VEST_L_FOREARM) > 0.15f);
    free(hard), free(soft);
}

/* The wide band (mim_xfer_skin_from_bones_wide, the session's skin): the
 * shoulder blends over more of the upper arm than the narrow skin does,
 * while a vertex whose heaviest bone is outside the mask (the forearm, the
 * hand) keeps exactly the narrow weights; no wider steps, no change. */
static void test_wide_band(void **state)
{
    (void)state;
    mim_error_t err = {0};
    const uint32_t n = fx.n;
    mim_xfer_skin_t *narrow = skin_of(MIM_XFER_DEFAULT_SKIN_SMOOTHING), *wide = malloc(n * sizeof *wide),
                    *same = malloc(n * sizeof *same);
    assert_non_null(wide), assert_non_null(same);
    assert_int_equal(mim_xfer_skin_from_bones_wide(fx.topo, fx.rest, fx.bones, MIM_VEST_SEGMENTS,
                                                   MIM_XFER_DEFAULT_SKIN_SMOOTHING, MIM_XFER_SKIN_WIDE_SEGMENTS,
                                                   MIM_XFER_DEFAULT_SKIN_SMOOTHING_WIDE, wide, &err),
                     0);
    assert_int_equal(mim_xfer_skin_from_bones_wide(fx.topo, fx.rest, fx.bones, MIM_VEST_SEGMENTS,
                                                   MIM_XFER_DEFAULT_SKIN_SMOOTHING, MIM_XFER_SKIN_WIDE_SEGMENTS,
                                                   MIM_XFER_DEFAULT_SKIN_SMOOTHING, same, &err),
                     0);
    assert_memory_equal(same, narrow, n * sizeof *same);
    uint32_t kept = 0, changed = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t b = narrow[i].bone[0];
        if (b < 64 && (MIM_XFER_SKIN_WIDE_SEGMENTS >> b & 1)) {
            changed += memcmp(&wide[i], &narrow[i], sizeof wide[i]) != 0;
        } else {
            assert_memory_equal(&wide[i], &narrow[i], sizeof wide[i]);
            kept++;
        }
    }
    assert_true(kept > n / 4 && changed > n / 10);
    /* a quarter down the upper arm: narrow, the arm's alone; wide, the shoulder still pulls */
    mim_vec3 q = mim_v3_lerp(fx.sk.pivot[MIM_VEST_L_UPPERARM], fx.sk.end[MIM_VEST_L_UPPERARM], 0.25);
    uint32_t v = nearest_vertex(q);
    float parent_narrow = weight_of(&narrow[v], MIM_VEST_L_SHOULDER) + weight_of(&narrow[v], MIM_VEST_CHEST);
    float parent_wide = weight_of(&wide[v], MIM_VEST_L_SHOULDER) + weight_of(&wide[v], MIM_VEST_CHEST);
    assert_true(parent_wide > parent_narrow + 0.05f);
    free(narrow), free(wide), free(same);
}

static void test_identity_and_rigid(void **state)
{
    (void)state;
    mim_xfer_skin_t *skin = skin_of(MIM_XFER_DEFAULT_SKIN_SMOOTHING);
    const uint32_t n = fx.n;
    double *F = malloc(9 * (size_t)n * sizeof *F), *G = malloc(9 * (size_t)n * sizeof *G), *W = malloc(3 * (size_t)n * sizeof *W);
    float *out = malloc(3 * (size_t)n * sizeof *out);
    mim_xfer_frames(fx.topo, fx.rest, F);
    mim_xfer_encode(fx.topo, fx.rest, F, W);
    mim_quat R[MIM_VEST_SEGMENTS];
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) R[g] = mim_quat_identity();
    mim_xfer_skin_frames(n, skin, F, R, G);
    for (size_t i = 0; i < 9 * (size_t)n; i++) assert_true(fabs(G[i] - F[i]) < 1e-12);
    /* the whole body turned: one solve gives the turned body; q and -q mix freely */
    mim_quat q = mim_quat_axis_angle(mim_v3_normalize(mim_v3(1, 2, 3)), 0.7);
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) R[g] = g % 2 ? q : (mim_quat){-q.x, -q.y, -q.z, -q.w};
    mim_xfer_skin_frames(n, skin, F, R, G);
    float u[3 * MIM_LANDMARKS_MAX], *turned = malloc(3 * (size_t)n * sizeof *turned);
    for (uint32_t i = 0; i < n; i++) {
        mim_vec3 v = mim_quat_rotate(q, mim_v3(fx.rest[3 * i], fx.rest[3 * i + 1], fx.rest[3 * i + 2]));
        turned[3 * i] = (float)v.x, turned[3 * i + 1] = (float)v.y, turned[3 * i + 2] = (float)v.z;
    }
    for (uint32_t k = 0; k < fx.map.count; k++) memcpy(u + 3 * k, turned + 3 * (size_t)fx.map.vertex[k], 3 * sizeof *u);
    mim_xfer_solver_t *s = NULL;
    assert_int_equal(mim_xfer_solver_open(&s, fx.topo, fx.map.vertex, fx.map.count, NULL, NULL), 0);
    mim_xfer_options_t o = {.max_iterations = 1};
    assert_int_equal(mim_xfer_transfer(s, W, n, G, u, fx.map.count, &o, out, NULL, NULL), 0);
    for (size_t i = 0; i < 3 * (size_t)n; i++) assert_true(fabs(out[i] - turned[i]) < 1e-4);
    mim_xfer_solver_close(&s);
    free(skin), free(F), free(G), free(W), free(out), free(turned);
}

/* A forearm twist moves almost no landmark (seed 000's landmarks cannot see
 * it); the orientation drive gets the hand right where the landmark-only
 * solve from the rest frames cannot. The truth twists the left forearm and
 * hand 70 degrees about the forearm's axis, blended by the skin's weights. */
static void test_twist(void **state)
{
    (void)state;
    mim_xfer_skin_t *skin = skin_of(MIM_XFER_DEFAULT_SKIN_SMOOTHING);
    const uint32_t n = fx.n;
    mim_vec3 pivot = fx.sk.pivot[MIM_VEST_L_FOREARM];
    mim_vec3 axis = mim_v3_normalize(mim_v3_sub(fx.sk.end[MIM_VEST_L_FOREARM], pivot));
    mim_quat tw = mim_quat_axis_angle(axis, 70.0 * M_PI / 180.0), R[MIM_VEST_SEGMENTS];
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) R[g] = mim_quat_identity();
    R[MIM_VEST_L_FOREARM] = R[MIM_VEST_L_HAND] = tw;
    float *truth = malloc(3 * (size_t)n * sizeof *truth), *out = malloc(3 * (size_t)n * sizeof *out);
    for (uint32_t i = 0; i < n; i++) {
        mim_vec3 x = mim_v3(fx.rest[3 * i], fx.rest[3 * i + 1], fx.rest[3 * i + 2]), y = mim_v3(0, 0, 0);
        for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES; k++) { /* linear blend skinning about the elbow */
            mim_quat r = R[skin[i].bone[k]];
            y = mim_v3_add(y, mim_v3_scale(mim_v3_add(mim_quat_rotate(r, mim_v3_sub(x, pivot)), pivot), skin[i].weight[k]));
        }
        truth[3 * i] = (float)y.x, truth[3 * i + 1] = (float)y.y, truth[3 * i + 2] = (float)y.z;
    }
    double *F = malloc(9 * (size_t)n * sizeof *F), *G = malloc(9 * (size_t)n * sizeof *G), *W = malloc(3 * (size_t)n * sizeof *W);
    mim_xfer_frames(fx.topo, fx.rest, F);
    mim_xfer_encode(fx.topo, fx.rest, F, W);
    float u[3 * MIM_LANDMARKS_MAX];
    for (uint32_t k = 0; k < fx.map.count; k++) memcpy(u + 3 * k, truth + 3 * (size_t)fx.map.vertex[k], 3 * sizeof *u);
    mim_xfer_solver_t *s = NULL;
    assert_int_equal(mim_xfer_solver_open(&s, fx.topo, fx.map.vertex, fx.map.count, NULL, NULL), 0);
    double err_hand[2] = {0, 0};
    uint32_t hand = 0;
    for (int drive = 0; drive < 2; drive++) {
        mim_xfer_options_t o = {0};
        if (drive) mim_xfer_skin_frames(n, skin, F, R, G), o.max_iterations = 1;
        assert_int_equal(mim_xfer_transfer(s, W, n, drive ? G : F, u, fx.map.count, &o, out, NULL, NULL), 0);
        for (uint32_t i = 0; i < n; i++) {
            if (skin[i].bone[0] != MIM_VEST_L_HAND) continue;
            double d2 = 0;
            for (int c = 0; c < 3; c++) d2 += (out[3 * i + c] - truth[3 * i + c]) * (out[3 * i + c] - truth[3 * i + c]);
            err_hand[drive] += sqrt(d2);
            hand += !drive;
        }
    }
    assert_true(hand > 20);
    err_hand[0] /= hand, err_hand[1] /= hand;
    print_message("hand error: landmarks alone %.1f mm, orientation drive %.1f mm\n", 1e3 * err_hand[0], 1e3 * err_hand[1]);
    assert_true(err_hand[1] < 0.5 * err_hand[0]);
    mim_xfer_solver_close(&s);
    free(skin), free(truth), free(out), free(F), free(G), free(W);
}

/* Dense per-segment weights (a rig's, summed per segment): the heaviest
 * four kept and normalised, a vertex without weight takes the fallback. */
static void test_from_dense(void **state)
{
    (void)state;
    enum { B = 6 };
    const float dense[3 * B] = {0.1f, 0.4f, 0.2f, 0.05f, 0.3f, 0.15f, /**/ 0, 0, 0, 2, 0, 0, /**/ 0, 0, 0, 0, 0, 0};
    mim_xfer_skin_t fallback[3] = {{{0}, {1}}, {{0}, {1}}, {{MIM_VEST_HEAD}, {1}}}, skin[3];
    assert_int_equal(mim_xfer_skin_from_dense(3, dense, B, fallback, skin), 1);
    const uint8_t order[4] = {1, 4, 2, 5}; /* 0.4 0.3 0.2 0.15; 0.1 and 0.05 dropped */
    for (int k = 0; k < 4; k++) {
        assert_int_equal(skin[0].bone[k], order[k]);
        assert_float_equal(skin[0].weight[k], dense[order[k]] / 1.05f, 1e-6f);
    }
    assert_int_equal(skin[1].bone[0], 3);
    assert_float_equal(skin[1].weight[0], 1.0f, 1e-6f);
    assert_true(skin[1].weight[1] == 0.0f);
    assert_int_equal(skin[2].bone[0], MIM_VEST_HEAD); /* the fallback's */
    assert_int_equal(mim_xfer_skin_from_dense(1, dense + 2 * B, B, NULL, skin), 1);
    assert_int_equal(skin[0].bone[0], 0);
    assert_true(skin[0].weight[0] == 1.0f);
}

static void test_bad_inputs(void **state)
{
    (void)state;
    mim_xfer_skin_t *skin = malloc(fx.n * sizeof *skin);
    mim_error_t err = {0};
    assert_int_equal(mim_xfer_skin_from_bones(fx.topo, fx.rest, fx.bones, 0, 4, skin, &err), MIM_EINVAL);
    assert_int_equal(mim_xfer_skin_from_bones(fx.topo, fx.rest, fx.bones, MIM_XFER_SKIN_MAX_BONES + 1, 4, skin, &err),
                     MIM_EINVAL);
    assert_int_equal(mim_xfer_skin_from_bones(NULL, fx.rest, fx.bones, 17, 4, skin, &err), MIM_EINVAL);
    double bad[MIM_VEST_SEGMENTS * 6];
    memcpy(bad, fx.bones, sizeof bad);
    bad[6 * 9 + 4] = NAN;
    err = (mim_error_t){0};
    assert_int_equal(mim_xfer_skin_from_bones(fx.topo, fx.rest, bad, 17, 4, skin, &err), MIM_ENONFINITE);
    assert_non_null(strstr(err.msg, "bone 9"));
    /* opposite rotations cancelling in the blend: the heaviest one decides, no NaN */
    mim_xfer_skin_t half = {{0, 1, 0, 0}, {0.5f, 0.5f, 0, 0}};
    mim_quat r[2] = {mim_quat_axis_angle(mim_v3(0, 0, 1), M_PI / 2), mim_quat_axis_angle(mim_v3(0, 0, 1), -M_PI / 2)};
    mim_quat q = mim_xfer_skin_rotation(&half, r);
    assert_true(isfinite(q.x) && isfinite(q.w));
    free(skin);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_weights),
        cmocka_unit_test(test_wide_band),
        cmocka_unit_test(test_identity_and_rigid),
        cmocka_unit_test(test_twist),
        cmocka_unit_test(test_from_dense),
        cmocka_unit_test(test_bad_inputs),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
