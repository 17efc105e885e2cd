/* sample/bvh_write.c: pose-pairs as BVH. Pairs made here by forward
 * kinematics (fixed bone lengths, random joint rotations) are written,
 * read back by vest/'s joint-position reader, mapped to the 17 joints by
 * name, and must come back to 1e-6 m; the same for extreme rotations
 * (a bone turned 180 degrees, gimbal lock) and a zero-length bone. */
#include "mim_sample.h"

#include "test_support.h"

#include "mim_vest_motion.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NJ MIM_PAIR_PERSON_JOINTS
#define PAIR (3 * MIM_PAIR_JOINTS)

/* Parent of each joint (mim_sample_joint_names order), its bone from the
 * parent at rest (metres, y up), and an order with parents first. */
static const int parent[NJ] = {16, 15, -1, 1, 1, 3, 4, 5, 6, 2, 2, 9, 10, 11, 12, 2, 1};
static const double rest_bone[NJ][3] = {
    {0, 0.12, 0.02}, {0, 0.22, 0.01}, {0, 0, 0},      {0.17, 0.1, 0},  {-0.17, 0.1, 0}, {0.28, 0, 0},
    {-0.28, 0, 0},   {0.25, 0, 0},    {-0.25, 0, 0},  {0.1, -0.06, 0}, {-0.1, -0.06, 0}, {0, -0.42, 0.01},
    {0, -0.42, 0.01}, {0, -0.4, -0.02}, {0, -0.4, -0.02}, {0, 0.12, -0.01}, {0, 0.2, 0},
};
static const int fk_order[NJ] = {2, 15, 1, 16, 0, 3, 5, 7, 4, 6, 8, 9, 11, 13, 10, 12, 14};

static mim_quat random_rot(mim_rng_t *r, double max_rad)
{
    mim_vec3 a = mim_v3_normalize(mim_v3(mim_rng_gauss(r), mim_rng_gauss(r), mim_rng_gauss(r)));
    return mim_quat_axis_angle(a, (2 * mim_rng_unit(r) - 1) * max_rad);
}

/* One person's 17 joints (out: 17 x 3) from local rotations, a root place
 * and bones (rest_bone unless given). */
static void fk(const mim_quat *local, mim_vec3 root, const double (*bone)[3], double *out)
{
    mim_quat G[NJ];
    if (!bone) bone = rest_bone;
    for (int i = 0; i < NJ; i++) {
        int j = fk_order[i], p = parent[j];
        mim_vec3 at = root;
        if (p >= 0) {
            at = mim_quat_rotate(G[p], mim_v3(bone[j][0], bone[j][1], bone[j][2]));
            at = mim_v3_add(at, mim_v3(out[3 * p], out[3 * p + 1], out[3 * p + 2]));
        }
        G[j] = p >= 0 ? mim_quat_mul(G[p], local[j]) : local[j];
        out[3 * j] = at.x, out[3 * j + 1] = at.y, out[3 * j + 2] = at.z;
    }
}

static void random_person(mim_rng_t *r, mim_vec3 root, const double (*bone)[3], double *out)
{
    mim_quat local[NJ];
    for (int j = 0; j < NJ; j++) local[j] = random_rot(r, M_PI);
    fk(local, root, bone, out);
}

/* Writes person `who` of n pairs, reads it back and returns the largest
 * distance between a joint read and the input (metres). */
static double round_trip(const double *pairs, uint32_t n, int who, double frame_time)
{
    char *text = mim_pairs_bvh_text(pairs, n, who, frame_time);
    assert_non_null(text);
    char *lower = strdup(text);
    assert_non_null(lower);
    for (char *c = lower; *c; c++) *c = (char)tolower((unsigned char)*c);
    assert_null(strstr(lower, "nan"));
    assert_null(strstr(lower, "inf"));
    free(lower);
    char want[64];
    snprintf(want, sizeof want, "\nFrames: %u\nFrame Time: ", (unsigned)n);
    assert_non_null(strstr(text, want));
    mim_vest_joint_motion_t m;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_joint_motion_parse_bvh(&m, text, strlen(text), "test", &err), 0);
    assert_int_equal(m.n_frames, n);
    assert_true(fabs(m.frame_time - frame_time) < 1e-9 * frame_time);
    int32_t map[NJ];
    const char *scheme = NULL;
    assert_int_equal(mim_pair_joint_map((const char(*)[64])m.name, m.n_joints, NULL, "test", map, &scheme, &err), 0);
    assert_string_equal(scheme, "CMU/Biovision");
    double worst = 0;
    for (uint32_t f = 0; f < n; f++)
        for (int j = 0; j < NJ; j++)
            for (int c = 0; c < 3; c++) {
                double got = m.positions[3 * ((size_t)f * m.n_joints + (size_t)map[j]) + c];
                double e = fabs(got - pairs[(size_t)f * PAIR + 3 * NJ * who + 3 * j + c]);
                if (!(e <= worst)) worst = e; /* a NaN is the worst */
            }
    mim_vest_joint_motion_free(&m);
    free(text);
    return worst;
}

static void test_round_trip(void **s)
{
    (void)s;
    enum { N = 40 };
    double *pairs = malloc(sizeof *pairs * PAIR * N);
    assert_non_null(pairs);
    mim_rng_t r;
    mim_rng_seed(&r, 2, 11);
    for (int f = 0; f < N; f++) {
        random_person(&r, mim_v3(mim_rng_unit(&r) - 0.5, 0.9 + 0.1 * mim_rng_unit(&r), mim_rng_unit(&r)), NULL,
                      pairs + f * PAIR);
        random_person(&r, mim_v3(1.2 + mim_rng_unit(&r), 0.9, -0.4 - mim_rng_unit(&r)), NULL,
                      pairs + f * PAIR + 3 * NJ);
    }
    double ea = round_trip(pairs, N, 0, 1.0 / 30), eb = round_trip(pairs, N, 1, 1.0 / 30);
    print_message("round trip: largest error A %.3g m, B %.3g m\n", ea, eb);
    assert_true(ea < 1e-6 && eb < 1e-6);
    free(pairs);
}

/* Rest; a forearm turned 180 degrees; the root and the chest at X = +-90
 * (gimbal lock, Z and Y about one axis); the root turned 180 degrees about
 * y and about x; everything at once with random other joints. */
static void test_extreme_rotations(void **s)
{
    (void)s;
    enum { N = 8 };
    double pairs[PAIR * N];
    mim_quat local[N][NJ];
    mim_vec3 X = mim_v3(1, 0, 0), Y = mim_v3(0, 1, 0), Z = mim_v3(0, 0, 1);
    mim_rng_t r;
    mim_rng_seed(&r, 2, 12);
    for (int f = 0; f < N; f++)
        for (int j = 0; j < NJ; j++) local[f][j] = f == N - 1 ? random_rot(&r, M_PI) : mim_quat_identity();
    local[1][5] = mim_quat_axis_angle(Z, M_PI);                                        /* l_elbow: forearm flipped */
    local[2][2] = mim_quat_axis_angle(X, M_PI / 2);                                    /* root X = 90 */
    local[3][2] = mim_quat_mul(mim_quat_mul(mim_quat_axis_angle(Z, 0.7), mim_quat_axis_angle(X, -M_PI / 2)),
                               mim_quat_axis_angle(Y, 0.5));                          /* X = -90, Z and Y too */
    local[4][1] = mim_quat_axis_angle(X, -M_PI / 2), local[4][6] = mim_quat_axis_angle(Y, M_PI); /* chest, r_elbow */
    local[5][2] = mim_quat_axis_angle(Y, M_PI);
    local[6][2] = mim_quat_axis_angle(X, M_PI), local[6][11] = mim_quat_axis_angle(X, M_PI); /* upside down, knee */
    local[N - 1][2] = local[3][2], local[N - 1][5] = local[1][5], local[N - 1][1] = local[4][1];
    for (int f = 0; f < N; f++) {
        fk(local[f], mim_v3(0, 1, 0), NULL, pairs + f * PAIR);
        fk(local[f], mim_v3(-0.7, 1, 2), NULL, pairs + f * PAIR + 3 * NJ);
    }
    double ea = round_trip(pairs, N, 0, 0.025), eb = round_trip(pairs, N, 1, 0.025);
    assert_true(ea < 1e-6 && eb < 1e-6);
    char *text = mim_pairs_bvh_text(pairs, N, 1, 0.025);
    assert_non_null(strstr(text, "\nMOTION\nFrames: 8\nFrame Time: 0.025\n"));
    assert_non_null(strstr(text, "ROOT Hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition "
                                 "Zrotation Xrotation Yrotation\n"));
    /* frame 0 is the rest pose: B's root place and 51 zero rotations */
    const char *f0 = strstr(text, "Frame Time: 0.025\n") + strlen("Frame Time: 0.025\n");
    const char *rest = "-0.7 1 2 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 "
                       "0 0 0 0 0 0 0 0 0 0\n";
    assert_memory_equal(f0, rest, strlen(rest));
    free(text);
}

static void test_empty_and_bad(void **s)
{
    (void)s;
    double pair[PAIR] = {0};
    assert_null(mim_pairs_bvh_text(pair, 0, 0, 1.0 / 30));
    assert_null(mim_pairs_bvh_text(NULL, 1, 0, 1.0 / 30));
    assert_null(mim_pairs_bvh_text(pair, 1, 2, 1.0 / 30));
    /* all joints at one place and no frame time: still a file a reader takes, at 30 fps */
    char *text = mim_pairs_bvh_text(pair, 1, 0, 0);
    assert_non_null(text);
    mim_vest_joint_motion_t m;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_joint_motion_parse_bvh(&m, text, strlen(text), "test", &err), 0);
    assert_true(fabs(m.frame_time - 1.0 / 30) < 1e-9);
    mim_vest_joint_motion_free(&m);
    free(text);
    /* a NaN joint (the pelvis: every bone and the root place) writes no NaN */
    pair[6] = NAN;
    text = mim_pairs_bvh_text(pair, 1, 0, 1.0 / 30);
    assert_non_null(text);
    assert_null(strstr(text, "nan"));
    assert_int_equal(mim_vest_joint_motion_parse_bvh(&m, text, strlen(text), "test", &err), 0);
    mim_vest_joint_motion_free(&m);
    free(text);
}

/* CMU data has a hip at its parent's place: l_hip's bone of length 0 (and
 * then both hips', and the neck's too, leaving the pelvis one direction). */
static void test_zero_length_bone(void **s)
{
    (void)s;
    enum { N = 12 };
    double pairs[PAIR * N], bone[NJ][3];
    mim_rng_t r;
    mim_rng_seed(&r, 2, 13);
    for (int variant = 0; variant < 3; variant++) {
        memcpy(bone, rest_bone, sizeof bone);
        bone[9][0] = bone[9][1] = bone[9][2] = 0;
        if (variant >= 1) bone[10][0] = bone[10][1] = bone[10][2] = 0;
        if (variant >= 2) bone[16][0] = bone[16][1] = bone[16][2] = 0;
        for (int f = 0; f < N; f++) {
            random_person(&r, mim_v3(0, 1, 0), (const double(*)[3])bone, pairs + f * PAIR);
            random_person(&r, mim_v3(1, 1, 0), (const double(*)[3])bone, pairs + f * PAIR + 3 * NJ);
        }
        assert_true(round_trip(pairs, N, 0, 0.01) < 1e-6);
        assert_true(round_trip(pairs, N, 1, 0.01) < 1e-6);
    }
}

/* Motion capture whose bones stretch: a forearm twice as long in frame 1
 * comes back at frame 0's length, pointing the same way. */
static void test_stretched_bone_keeps_length(void **s)
{
    (void)s;
    double pairs[2 * PAIR], bone[NJ][3];
    mim_rng_t r;
    mim_rng_seed(&r, 2, 14);
    memcpy(bone, rest_bone, sizeof bone);
    random_person(&r, mim_v3(0, 1, 0), NULL, pairs);
    random_person(&r, mim_v3(1, 1, 0), NULL, pairs + 3 * NJ);
    for (int c = 0; c < 3; c++) bone[7][c] *= 2; /* l_wrist from l_elbow */
    random_person(&r, mim_v3(0, 1, 0), (const double(*)[3])bone, pairs + PAIR);
    random_person(&r, mim_v3(1, 1, 0), NULL, pairs + PAIR + 3 * NJ);
    char *text = mim_pairs_bvh_text(pairs, 2, 0, 0.01);
    assert_non_null(text);
    mim_vest_joint_motion_t m;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_joint_motion_parse_bvh(&m, text, strlen(text), "test", &err), 0);
    int32_t map[NJ];
    assert_int_equal(mim_pair_joint_map((const char(*)[64])m.name, m.n_joints, NULL, "test", map, NULL, &err), 0);
    const float *e = m.positions + 3 * ((size_t)m.n_joints + (size_t)map[5]);
    const float *w = m.positions + 3 * ((size_t)m.n_joints + (size_t)map[7]);
    mim_vec3 got = mim_v3(w[0] - e[0], w[1] - e[1], w[2] - e[2]);
    mim_vec3 in = mim_v3(pairs[PAIR + 21] - pairs[PAIR + 15], pairs[PAIR + 22] - pairs[PAIR + 16],
                         pairs[PAIR + 23] - pairs[PAIR + 17]);
    assert_true(fabs(mim_v3_norm(got) - mim_v3_norm(mim_v3(0.25, 0, 0))) < 1e-6);
    assert_true(mim_v3_norm(mim_v3_sub(mim_v3_normalize(got), mim_v3_normalize(in))) < 1e-6);
    /* the elbow, before the stretched bone, is where the input has it */
    for (int c = 0; c < 3; c++) assert_true(fabs(e[c] - pairs[PAIR + 15 + c]) < 1e-6);
    mim_vest_joint_motion_free(&m);
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_extreme_rotations),
        cmocka_unit_test(test_empty_and_bad),
        cmocka_unit_test(test_zero_length_bone),
        cmocka_unit_test(test_stretched_bone_keeps_length),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
