/* session/: the orientation drive (issue 17) through the one pipeline, on a
 * synth store made here: a forearm twist that no landmark shows, lost
 * sensors and their fallbacks, and the bad requests. */
#include "foreign_avatar.h"
#include "test_support.h"

#include "mim_session.h"
#include "mim_vest_kinematics.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static char *dir, *store;
static mim_session_t *sess;
static mim_vest_skeleton_t sk;

static int run(const char *const *args)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    free(o), free(e);
    return rc;
}

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("session-orient");
    char *bodies = ts_path(dir, "bodies");
    store = ts_path(dir, "store");
    const char *synth[] = {"synth", "--out", bodies, "--subjects", "3", "--poses", "12", "--vertices", "3000", NULL};
    const char *ingest[] = {"ingest", "--store", store, bodies, NULL};
    const char *index[] = {"index", "--store", store, NULL};
    int rc = run(synth) || run(ingest) || run(index);
    free(bodies);
    mim_error_t err = {0};
    if (!rc) rc = mim_session_open(&sess, store, NULL, &err);
    if (!rc) rc = mim_session_load_avatar(sess, "1", &err); /* a subject at rest */
    if (!rc) rc = mim_vest_skeleton_estimate(&sk, mim_session_mesh(sess), mim_session_map(sess), &err);
    if (rc) fprintf(stderr, "setup: %s\n", mim_error_text(&err));
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    mim_session_close(&sess);
    ts_rmtree(dir);
    free(dir), free(store);
    return 0;
}

/* The pose: the left forearm and hand twisted 80 degrees about the
 * forearm's axis; the landmarks by the vest's own forward kinematics. */
static void twisted_pose(mim_quat R[MIM_VEST_SEGMENTS], float *u)
{
    mim_vec3 axis = mim_v3_normalize(mim_v3_sub(sk.end[MIM_VEST_L_FOREARM], sk.pivot[MIM_VEST_L_FOREARM]));
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) R[g] = mim_quat_identity();
    R[MIM_VEST_L_FOREARM] = R[MIM_VEST_L_HAND] = mim_quat_axis_angle(axis, 80.0 * M_PI / 180.0);
    mim_vest_rig_t rig;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_calibrate(&rig, &sk, NULL, NULL, &err), 0); /* rest pose, tared: R_s = reading */
    assert_int_equal(mim_vest_fk_orient(&rig, R, NULL, u, NULL), mim_session_map(sess)->count);
}

/* Mean angle (degrees) between R_hand and each left-hand vertex's frame
 * turn from the rest mesh to pose x. */
static double hand_angle(const float *x, mim_quat R_hand)
{
    const mim_mesh_t *rest = mim_session_mesh(sess);
    const uint32_t n = rest->n_vertices;
    const mim_xfer_skin_t *skin = mim_session_skin(sess, NULL, NULL);
    double *F0 = malloc(9 * (size_t)n * sizeof *F0), *F1 = malloc(9 * (size_t)n * sizeof *F1), Rm[9];
    mim_xfer_frames(mim_session_topology(sess), rest->positions, F0);
    mim_xfer_frames(mim_session_topology(sess), x, F1);
    mim_quat_to_matrix(R_hand, Rm);
    double sum = 0;
    uint32_t count = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (skin[i].bone[0] != MIM_VEST_L_HAND || skin[i].weight[0] < 0.9f) continue;
        /* tr(R^T M) with M = F1 F0^T: sum over axes k of (R f0_k) . f1_k */
        double tr = 0;
        for (int k = 0; k < 3; k++) {
            const double *a = F0 + 9 * (size_t)i + 3 * k, *b = F1 + 9 * (size_t)i + 3 * k;
            for (int r = 0; r < 3; r++) tr += (Rm[r] * a[0] + Rm[3 + r] * a[1] + Rm[6 + r] * a[2]) * b[r];
        }
        double c = (tr - 1) / 2;
        sum += acos(c > 1 ? 1 : c < -1 ? -1 : c) * 180.0 / M_PI;
        count++;
    }
    free(F0), free(F1);
    assert_true(count > 10);
    return sum / count;
}

static void test_twist(void **state)
{
    (void)state;
    const uint32_t n = mim_session_mesh(sess)->n_vertices;
    mim_quat R[MIM_VEST_SEGMENTS];
    float u[3 * MIM_LANDMARKS_MAX], *x = malloc(3 * (size_t)n * sizeof *x);
    twisted_pose(R, u);
    mim_error_t err = {0};
    double angle[2];
    for (int d = 0; d < 2; d++) {
        mim_session_request_t req = {.landmarks = u, .orientations = R,
                                     .drive = d ? MIM_DRIVE_AUTO : MIM_DRIVE_TEMPLATE};
        mim_session_report_t rep;
        assert_int_equal(mim_session_transfer(sess, &req, x, &rep, &err), 0);
        assert_int_equal(rep.drive, d ? MIM_DRIVE_ORIENTATION : MIM_DRIVE_TEMPLATE);
        assert_true(rep.queried && rep.template_id >= 1 && rep.label[0]); /* recognition still runs */
        if (d) assert_int_equal(rep.xfer.iterations, 1);
        angle[d] = hand_angle(x, R[MIM_VEST_L_HAND]);
    }
    print_message("hand turned by 80 degrees: off by %.1f (template drive), %.1f (orientation drive)\n", angle[0],
                  angle[1]);
    assert_true(angle[1] < 15.0);
    assert_true(angle[0] > 2 * angle[1]);
    free(x);
}

static void test_lost_sensors(void **state)
{
    (void)state;
    const uint32_t n = mim_session_mesh(sess)->n_vertices;
    mim_quat R[MIM_VEST_SEGMENTS];
    float u[3 * MIM_LANDMARKS_MAX], *x = malloc(3 * (size_t)n * sizeof *x);
    twisted_pose(R, u);
    mim_error_t err = {0};
    /* the hand's sensor lost: it takes the forearm's rotation, the same here */
    uint8_t have[MIM_VEST_SEGMENTS];
    memset(have, 1, sizeof have);
    have[MIM_VEST_L_HAND] = 0;
    mim_quat junk[MIM_VEST_SEGMENTS];
    memcpy(junk, R, sizeof junk);
    junk[MIM_VEST_L_HAND] = mim_quat_axis_angle(mim_v3(0, 0, 1), 2.0); /* what a lost sensor held: not read */
    mim_session_request_t req = {.landmarks = u, .orientations = junk, .orient_present = have};
    mim_session_report_t rep;
    assert_int_equal(mim_session_transfer(sess, &req, x, &rep, &err), 0);
    assert_int_equal(rep.drive, MIM_DRIVE_ORIENTATION);
    assert_int_equal(rep.orient_filled, 1);
    assert_int_equal(rep.orient_from_template, 0);
    assert_true(hand_angle(x, R[MIM_VEST_L_HAND]) < 15.0);
    /* pelvis and chest lost: no neighbour has a rotation for them, the
     * template's frames drive their vertices */
    memset(have, 1, sizeof have);
    have[MIM_VEST_PELVIS] = have[MIM_VEST_CHEST] = 0;
    assert_int_equal(mim_session_transfer(sess, &req, x, &rep, &err), 0);
    assert_int_equal(rep.orient_filled, 0);
    assert_true(rep.orient_from_template > n / 20);
    for (size_t i = 0; i < 3 * (size_t)n; i++) assert_true(isfinite(x[i]));
    free(x);
}

static void test_bad_requests(void **state)
{
    (void)state;
    const uint32_t n = mim_session_mesh(sess)->n_vertices;
    mim_quat R[MIM_VEST_SEGMENTS];
    float u[3 * MIM_LANDMARKS_MAX], *x = malloc(3 * (size_t)n * sizeof *x);
    twisted_pose(R, u);
    mim_error_t err = {0};
    mim_session_request_t no_lm = {.template_id = 1, .orientations = R};
    assert_int_equal(mim_session_transfer(sess, &no_lm, x, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "orientations need landmarks"));
    err = (mim_error_t){0};
    mim_session_request_t no_or = {.landmarks = u, .drive = MIM_DRIVE_ORIENTATION};
    assert_int_equal(mim_session_transfer(sess, &no_or, x, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "needs orientations"));
    /* an orientation that is no rotation, named */
    mim_quat Rb[MIM_VEST_SEGMENTS];
    memcpy(Rb, R, sizeof Rb);
    Rb[MIM_VEST_L_SHIN] = (mim_quat){0, 0, 0, 0};
    mim_session_request_t zero = {.landmarks = u, .orientations = Rb};
    err = (mim_error_t){0};
    assert_int_equal(mim_session_transfer(sess, &zero, x, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "orientation 'l_shin' is not a unit quaternion (norm 0)"));
    Rb[MIM_VEST_L_SHIN].w = NAN;
    err = (mim_error_t){0};
    assert_int_equal(mim_session_transfer(sess, &zero, x, NULL, &err), MIM_ENONFINITE);
    uint8_t have[MIM_VEST_SEGMENTS];
    memset(have, 1, sizeof have);
    have[MIM_VEST_L_SHIN] = 0; /* lost: what it holds is not read */
    zero.orient_present = have;
    assert_int_equal(mim_session_transfer(sess, &zero, x, NULL, &err), 0);
    /* the template drive ignores orientations: the same as none */
    float *y = malloc(3 * (size_t)n * sizeof *y);
    mim_session_request_t a = {.landmarks = u, .orientations = R, .drive = MIM_DRIVE_TEMPLATE}, b = {.landmarks = u};
    assert_int_equal(mim_session_transfer(sess, &a, x, NULL, &err), 0);
    assert_int_equal(mim_session_transfer(sess, &b, y, NULL, &err), 0);
    assert_memory_equal(x, y, 3 * (size_t)n * sizeof *x);
    /* templates to blend (issue 15): too many, a zero id, a count without ids */
    uint64_t ids[MIM_XFER_BLEND_MAX + 1];
    for (int k = 0; k <= MIM_XFER_BLEND_MAX; k++) ids[k] = 1;
    mim_session_request_t many = {.landmarks = u, .template_ids = ids, .n_templates = MIM_XFER_BLEND_MAX + 1};
    err = (mim_error_t){0};
    assert_int_equal(mim_session_transfer(sess, &many, x, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "17 templates to blend (at most 16)"));
    mim_session_request_t wide = {.landmarks = u, .blend = MIM_XFER_BLEND_MAX + 1};
    err = (mim_error_t){0};
    assert_int_equal(mim_session_transfer(sess, &wide, x, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "17 templates to blend (at most 16)"));
    ids[1] = 0;
    mim_session_request_t zero_id = {.landmarks = u, .template_ids = ids, .n_templates = 2};
    err = (mim_error_t){0};
    assert_int_equal(mim_session_transfer(sess, &zero_id, x, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "template id 0 in the list to blend"));
    mim_session_request_t no_ids = {.landmarks = u, .n_templates = 2};
    err = (mim_error_t){0};
    assert_int_equal(mim_session_transfer(sess, &no_ids, x, NULL, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "2 templates to blend, but no ids"));
    free(x), free(y);
}

/* In-betweens of two oriented keys: the rotations slerped, one solve; at
 * t = 0 and 1 they are the keys. */
static void test_morph(void **state)
{
    (void)state;
    const uint32_t n = mim_session_mesh(sess)->n_vertices;
    mim_quat R[MIM_VEST_SEGMENTS], I[MIM_VEST_SEGMENTS];
    float u[3 * MIM_LANDMARKS_MAX], u0[3 * MIM_LANDMARKS_MAX];
    twisted_pose(R, u);
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) I[g] = mim_quat_identity();
    memcpy(u0, u, sizeof u0);
    const mim_mesh_t *rest = mim_session_mesh(sess);
    for (uint32_t k = 0; k < mim_session_map(sess)->count; k++)
        memcpy(u0 + 3 * k, rest->positions + 3 * (size_t)mim_session_map(sess)->vertex[k], 3 * sizeof *u0);
    float *x = malloc(3 * (size_t)n * sizeof *x), *key = malloc(3 * (size_t)n * sizeof *key);
    mim_error_t err = {0};
    mim_session_oriented_key_t a = {I, NULL, u0, 1}, b = {R, NULL, u, 1};
    mim_session_request_t rb = {.template_id = 1, .landmarks = u, .orientations = R};
    assert_int_equal(mim_session_transfer(sess, &rb, key, NULL, &err), 0);
    assert_int_equal(mim_session_morph_oriented(sess, &a, &b, 1.0, NULL, x, &err), 0);
    for (size_t i = 0; i < 3 * (size_t)n; i++) assert_true(fabs(x[i] - key[i]) < 1e-5);
    assert_int_equal(mim_session_morph_oriented(sess, &a, &b, 0.5, NULL, x, &err), 0);
    double half = hand_angle(x, mim_quat_slerp(I[0], R[MIM_VEST_L_HAND], 0.5));
    print_message("half-way in-between: the hand off the half turn by %.1f degrees\n", half);
    assert_true(half < 15.0);
    free(x), free(key);
}

/* A skinned glTF avatar: its own rig's weights drive the segments where
 * the joint names map (here its left hand rides the forearm bone, unlike
 * the geometry's segmentation), the geometry where a vertex hangs on an
 * unmapped joint (a "Hair" bone). */
static void test_gltf_skin(void **state)
{
    (void)state;
    const mim_mesh_t *m = mim_session_mesh(sess);
    const uint32_t n = m->n_vertices;
    const mim_xfer_skin_t *geo = mim_session_skin(sess, NULL, NULL);
    static const char *const names[MIM_VEST_SEGMENTS + 1] = {
        "mixamorig:Hips", "mixamorig:Spine2", "mixamorig:Head", "mixamorig:LeftShoulder", "mixamorig:RightShoulder",
        "mixamorig:LeftArm", "mixamorig:RightArm", "mixamorig:LeftForeArm", "mixamorig:RightForeArm",
        "mixamorig:LeftHand", "mixamorig:RightHand", "mixamorig:LeftUpLeg", "mixamorig:RightUpLeg", "mixamorig:LeftLeg",
        "mixamorig:RightLeg", "mixamorig:LeftFoot", "mixamorig:RightFoot", "Hair"};
    uint16_t *joints = calloc(4 * (size_t)n, sizeof *joints);
    float *weights = calloc(4 * (size_t)n, sizeof *weights);
    uint32_t hair = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint16_t j = geo[i].bone[0];
        if (j == MIM_VEST_L_HAND) j = MIM_VEST_L_FOREARM; /* the rig's own choice */
        if (geo[i].bone[0] == MIM_VEST_HEAD && i % 3 == 0) j = MIM_VEST_SEGMENTS, hair++;
        joints[4 * (size_t)i] = j, weights[4 * (size_t)i] = 1;
    }
    char *glb = ts_path(dir, "skinned.glb");
    assert_int_equal(ts_write_skinned_glb(glb, m, names, MIM_VEST_SEGMENTS + 1, joints, weights, 0), 0);
    mim_session_t *s2 = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_session_open(&s2, store, NULL, &err), 0);
    assert_int_equal(mim_session_load_avatar(s2, glb, &err), 0);
    int from_rig = 0;
    const mim_xfer_skin_t *rig = mim_session_skin(s2, NULL, &from_rig);
    assert_non_null(rig);
    assert_int_equal(from_rig, 1);
    uint32_t hands = 0, kept = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (geo[i].bone[0] == MIM_VEST_L_HAND) {
            assert_int_equal(rig[i].bone[0], MIM_VEST_L_FOREARM);
            assert_true(rig[i].weight[0] == 1.0f);
            hands++;
        } else if (joints[4 * (size_t)i] == MIM_VEST_SEGMENTS) { /* the hair: the geometry's weights */
            assert_memory_equal(&rig[i], &geo[i], sizeof rig[i]);
            kept++;
        }
    }
    assert_true(hands > 10 && kept == hair && hair > 10);
    /* the drive then turns the left hand with the forearm's rotation */
    mim_quat R[MIM_VEST_SEGMENTS];
    float u[3 * MIM_LANDMARKS_MAX], *x = malloc(3 * (size_t)n * sizeof *x);
    twisted_pose(R, u);
    const mim_quat twist = R[MIM_VEST_L_HAND];
    R[MIM_VEST_L_HAND] = mim_quat_identity(); /* the hand's own sensor says: not turned; this rig does not listen */
    mim_session_request_t req = {.landmarks = u, .orientations = R};
    assert_int_equal(mim_session_transfer(s2, &req, x, NULL, &err), 0);
    assert_true(hand_angle(x, twist) < 15.0);
    mim_session_close(&s2);
    /* a rig whose names map to too few segments: the geometry alone */
    static const char *const few[2] = {"bone_a", "LeftHand"};
    for (uint32_t i = 0; i < n; i++) joints[4 * (size_t)i] = i % 2;
    assert_int_equal(ts_write_skinned_glb(glb, m, few, 2, joints, weights, 0), 0);
    assert_int_equal(mim_session_open(&s2, store, NULL, &err), 0);
    assert_int_equal(mim_session_load_avatar(s2, glb, &err), 0);
    rig = mim_session_skin(s2, NULL, &from_rig);
    assert_int_equal(from_rig, 0);
    assert_memory_equal(rig, geo, n * sizeof *rig);
    mim_session_close(&s2);
    free(joints), free(weights), free(glb), free(x);
}

/* A skinned glTF avatar of another connectivity: its rig's weights reach
 * the proxy through the binding (each proxy vertex takes the bound avatar
 * vertices' weights by their barycentric share). The rig here puts the
 * body's left side on the left forearm and the rest on the hips, which no
 * geometry would. */
static void test_foreign_gltf_skin(void **state)
{
    (void)state;
    fa_options_t fo = {.vertices = 3000, .seed = 7, .subdivisions = 1, .shuffle_seed = 5};
    fa_avatar_t fa;
    char why[256];
    assert_int_equal(fa_make(&fo, &fa, why, sizeof why), 0);
    char *ply = ts_path(dir, "foreign.ply"), *side = ts_path(dir, "foreign.landmarks.json"), *glb = ts_path(dir, "foreign.glb");
    assert_int_equal(fa_write(&fa, ply, side, -1, why, sizeof why), 0);
    static const char *const names[MIM_VEST_SEGMENTS] = {
        "mixamorig:Hips", "mixamorig:Spine2", "mixamorig:Head", "mixamorig:LeftShoulder", "mixamorig:RightShoulder",
        "mixamorig:LeftArm", "mixamorig:RightArm", "mixamorig:LeftForeArm", "mixamorig:RightForeArm",
        "mixamorig:LeftHand", "mixamorig:RightHand", "mixamorig:LeftUpLeg", "mixamorig:RightUpLeg", "mixamorig:LeftLeg",
        "mixamorig:RightLeg", "mixamorig:LeftFoot", "mixamorig:RightFoot"};
    const uint32_t na = fa.mesh.n_vertices;
    uint16_t *joints = calloc(4 * (size_t)na, sizeof *joints);
    float *weights = calloc(4 * (size_t)na, sizeof *weights);
    for (uint32_t i = 0; i < na; i++)
        joints[4 * (size_t)i] = fa.mesh.positions[3 * (size_t)i] > 0 ? MIM_VEST_L_FOREARM : MIM_VEST_PELVIS,
                       weights[4 * (size_t)i] = 1;
    assert_int_equal(ts_write_skinned_glb(glb, &fa.mesh, names, MIM_VEST_SEGMENTS, joints, weights, 0), 0);
    mim_session_t *s2 = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_session_open(&s2, store, NULL, &err), 0);
    if (mim_session_load_avatar(s2, glb, &err)) fail_msg("%s", err.msg);
    assert_true(mim_session_maps_output(s2));
    int from_rig = 0;
    const mim_xfer_skin_t *skin = mim_session_skin(s2, NULL, &from_rig);
    assert_non_null(skin);
    assert_int_equal(from_rig, 1);
    const mim_mesh_t *proxy = mim_session_mesh(s2);
    uint32_t left = 0, right = 0;
    for (uint32_t i = 0; i < proxy->n_vertices; i++) {
        float x = proxy->positions[3 * (size_t)i];
        if (x > 0.02f) assert_int_equal(skin[i].bone[0], MIM_VEST_L_FOREARM), left++;
        if (x < -0.02f) assert_int_equal(skin[i].bone[0], MIM_VEST_PELVIS), right++;
    }
    assert_true(left > 100 && right > 100);
    mim_session_close(&s2);
    fa_free(&fa);
    free(joints), free(weights), free(ply), free(side), free(glb);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_twist),
        cmocka_unit_test(test_lost_sensors),
        cmocka_unit_test(test_bad_requests),
        cmocka_unit_test(test_morph),
        cmocka_unit_test(test_gltf_skin),
        cmocka_unit_test(test_foreign_gltf_skin),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
