/* session/: the skeleton drive (the avatar's own rest frames turned as its
 * landmark skeleton turns onto the landmarks, one solve), on a store of
 * bodies that take each pose their own way (synth's imitation, soft tissue
 * and a registered store's slide) and an avatar the store does not hold:
 * the auto drive takes it on the plain path and comes closer to the truth
 * than the templates' frames; exact at rest and under a rigid turn; the
 * template drive kept where asked; bad requests. */
#include "test_support.h"

#include "mim_session.h"
#include "mim_synth.h"

#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum { SUBJECTS = 4, POSES = 12 };
static char *dir, *store, *avatar;
static mim_session_t *sess;
static mim_synth_t *syn;

static int run(const char *const *args)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc) fprintf(stderr, "mimic %s: %s", args[0], e ? e : "");
    free(o), free(e);
    return rc;
}

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("session-skeleton");
    char *bodies = ts_path(dir, "bodies"), *held = ts_path(dir, "held");
    store = ts_path(dir, "store");
    avatar = ts_path(held, "synth_s00_p00.ply");
    /* at the imitation set's resolution (bench/RESULTS.md): a coarser mesh's frames feel the slide less */
    mim_synth_options_t o = {.subjects = SUBJECTS, .poses = POSES, .vertices = 7000, .seed = 5,
                             .imitation_deg = 3.5, .tissue_mm = 4, .slide_mm = 22};
    mim_error_t err = {0};
    int rc = mim_synth_create(&syn, &o, &err) || mim_synth_write_dataset(syn, bodies, &err);
    /* subject 0 is the wearer: out of the store, labels from the file names */
    char *manifest = ts_path(bodies, "manifest.csv");
    rc = rc || remove(manifest) || mkdir(held, 0755);
    for (uint32_t p = 0; !rc && p < POSES; p++) {
        char name[64];
        snprintf(name, sizeof name, "synth_s00_p%02u.ply", p);
        char *from = ts_path(bodies, name), *to = ts_path(held, name);
        rc = rename(from, to);
        free(from), free(to);
    }
    const char *ingest[] = {"ingest", "--store", store, bodies, NULL};
    const char *index[] = {"index", "--store", store, NULL};
    rc = rc || run(ingest) || run(index);
    if (!rc) rc = mim_session_open(&sess, store, NULL, &err);
    if (!rc) rc = mim_session_load_avatar(sess, avatar, &err);
    if (rc) fprintf(stderr, "setup: %s\n", mim_error_text(&err));
    free(bodies), free(held), free(manifest);
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    mim_session_close(&sess);
    mim_synth_destroy(&syn);
    ts_rmtree(dir);
    free(dir), free(store), free(avatar);
    return 0;
}

static float *alloc_pose(void) { return malloc(3 * sizeof(float) * mim_session_mesh(sess)->n_vertices); }

/* The wearer (subject 0) in pose p into x; its landmarks into u. */
static void wearer(uint32_t p, float *x, float *u)
{
    const mim_landmark_map_t *map = mim_session_map(sess);
    assert_int_equal(mim_synth_body(syn, 0, p, x), 0);
    for (uint32_t l = 0; l < map->count; l++) memcpy(u + 3 * l, x + 3 * (size_t)map->vertex[l], 3 * sizeof *u);
}

static double mean_distance(const float *a, const float *b)
{
    const uint32_t n = mim_session_mesh(sess)->n_vertices;
    double sum = 0;
    for (uint32_t i = 0; i < n; i++) {
        const double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
        sum += sqrt(dx * dx + dy * dy + dz * dz);
    }
    return sum / n;
}

static void transfer(const mim_session_request_t *req, float *x, mim_session_report_t *rep)
{
    mim_error_t err = {0};
    int rc = mim_session_transfer(sess, req, x, rep, &err);
    if (rc) fprintf(stderr, "transfer: %s\n", mim_error_text(&err));
    assert_int_equal(rc, 0);
}

/* Every pose but the rest, on the plain path (relative transfer off: it is
 * the gate's to open, MIM_SESSION_RELATIVE_GATE_DEG): auto takes the
 * skeleton drive, one solve, the pose's template named; and it lies closer
 * to the wearer's truth than the templates' frames, blended and corrected
 * as the template drive does. */
static void test_auto_takes_skeleton(void **state)
{
    (void)state;
    float *truth = alloc_pose(), *x = alloc_pose(), u[3 * MIM_LANDMARKS_MAX];
    double e_auto = 0, e_template = 0;
    for (uint32_t p = 1; p < POSES; p++) {
        wearer(p, truth, u);
        mim_session_report_t rep;
        mim_session_request_t req = {.landmarks = u, .relative = -1};
        transfer(&req, x, &rep);
        assert_int_equal(rep.drive, MIM_DRIVE_SKELETON);
        assert_int_equal(rep.relative, 0);
        assert_int_equal(rep.n_templates, 1);
        assert_int_equal(rep.xfer.iterations, 1);
        assert_int_equal(rep.queried, 1);
        assert_true(rep.label[0] != 0 && rep.template_id != 0);
        e_auto += mean_distance(x, truth);
        req.drive = MIM_DRIVE_TEMPLATE;
        transfer(&req, x, &rep);
        assert_int_equal(rep.drive, MIM_DRIVE_TEMPLATE);
        assert_int_equal(rep.corrected, 1);
        assert_true(rep.n_templates > 1);
        e_template += mean_distance(x, truth);
    }
    e_auto /= POSES - 1, e_template /= POSES - 1;
    fprintf(stderr, "mean error: skeleton drive %.1f mm, template drive %.1f mm\n", 1e3 * e_auto, 1e3 * e_template);
    assert_true(e_auto < 0.9 * e_template);
    free(truth), free(x);
}

/* With the defaults (relative transfer on): the store's subjects take a
 * pose their own way (their spread passes MIM_SESSION_RELATIVE_SPREAD_DEG),
 * so the relative path is not taken, whatever the references' gate says,
 * and auto takes the skeleton drive. */
static void test_store_gate(void **state)
{
    (void)state;
    float *truth = alloc_pose(), *x = alloc_pose(), u[3 * MIM_LANDMARKS_MAX];
    for (uint32_t p = 1; p < POSES; p++) {
        wearer(p, truth, u);
        mim_session_report_t rep;
        mim_session_request_t req = {.landmarks = u};
        transfer(&req, x, &rep);
        assert_int_equal(rep.relative, 0);
        assert_int_equal(rep.drive, MIM_DRIVE_SKELETON);
        req.drive = MIM_DRIVE_TEMPLATE; /* the template drive too keeps to the plain path */
        transfer(&req, x, &rep);
        assert_int_equal(rep.relative, 0);
        assert_int_equal(rep.drive, MIM_DRIVE_TEMPLATE);
    }
    free(truth), free(x);
}

/* The spread itself: subjects that share each pose's landmarks exactly
 * (one turned and moved as a whole, one scaled) spread 0; a subject whose
 * elbow bends otherwise spreads more; a subject's repeat of a pose, an
 * empty label and poses no two subjects share are not pairs. */
static void test_pose_spread(void **state)
{
    (void)state;
    const mim_landmark_map_t *map = mim_session_map(sess);
    const uint32_t L = map->count;
    enum { N = 7 };
    float *lm = malloc(sizeof *lm * 3 * L * N), body[3 * MIM_LANDMARKS_MAX];
    const char *subjects[N] = {"a", "b", "c", "a", "b", "", "d"};
    const char *poses[N] = {"p1", "p1", "p1", "p1", "p2", "p1", "p3"};
    float *rest = alloc_pose();
    assert_int_equal(mim_synth_body(syn, 1, 3, rest), 0);
    for (uint32_t l = 0; l < L; l++) memcpy(body + 3 * l, rest + 3 * (size_t)map->vertex[l], 3 * sizeof *body);
    for (uint32_t t = 0; t < N; t++)
        for (uint32_t l = 0; l < L; l++) {
            const float *v = body + 3 * l;
            float *o = lm + 3 * ((size_t)t * L + l);
            if (t == 1) /* turned about y and moved */
                o[0] = 0.6f * v[0] + 0.8f * v[2] + 1, o[1] = v[1] - 2, o[2] = -0.8f * v[0] + 0.6f * v[2];
            else /* scaled */
                for (int k = 0; k < 3; k++) o[k] = (t == 2 ? 1.2f : 1.0f) * v[k];
        }
    assert_true(fabs(mim_session_pose_spread(N, L, lm, subjects, poses)) < 1e-3);
    /* c's left elbow elsewhere: a pose taken its own way */
    const int elbow = mim_landmarks_find(map, "l_elbow");
    assert_true(elbow >= 0);
    lm[3 * ((size_t)2 * L + elbow) + 2] += 0.15f;
    const double one = mim_session_pose_spread(N, L, lm, subjects, poses);
    assert_true(one > 0.5);
    /* a's repeat (template 3) moved: not another subject, no change */
    lm[3 * ((size_t)3 * L + elbow) + 2] += 0.3f;
    assert_true(fabs(mim_session_pose_spread(N, L, lm, subjects, poses) - one) < 1e-9);
    /* no pose shared by two subjects: unknown */
    const char *alone[N] = {"p1", "p2", "p3", "p1", "p4", "p5", "p6"};
    assert_true(isnan(mim_session_pose_spread(N, L, lm, subjects, alone)));
    assert_true(isnan(mim_session_pose_spread(N, L, NULL, subjects, poses)));
    free(lm), free(rest);
}

/* The avatar's own rest landmarks give its rest mesh back, and the same
 * landmarks turned and moved give it turned and moved: every segment
 * takes the one rotation, and the solve is exact for it. */
static void test_exact_rigid(void **state)
{
    (void)state;
    const mim_mesh_t *rest = mim_session_mesh(sess);
    const mim_landmark_map_t *map = mim_session_map(sess);
    const uint32_t n = rest->n_vertices;
    float *x = alloc_pose(), *want = alloc_pose(), u[3 * MIM_LANDMARKS_MAX];
    const double a = 100.0 * M_PI / 180.0, c = cos(a), s = sin(a), t[3] = {0.4, -0.2, 1.5};
    for (uint32_t i = 0; i < n; i++) {
        const float *v = rest->positions + 3 * (size_t)i;
        want[3 * i] = (float)(c * v[0] + s * v[2] + t[0]);
        want[3 * i + 1] = (float)(v[1] + t[1]);
        want[3 * i + 2] = (float)(-s * v[0] + c * v[2] + t[2]);
    }
    mim_session_report_t rep;
    for (int turned = 0; turned < 2; turned++) {
        const float *src = turned ? want : rest->positions;
        for (uint32_t l = 0; l < map->count; l++) memcpy(u + 3 * l, src + 3 * (size_t)map->vertex[l], 3 * sizeof *u);
        mim_session_request_t req = {.landmarks = u, .drive = MIM_DRIVE_SKELETON};
        transfer(&req, x, &rep);
        assert_int_equal(rep.drive, MIM_DRIVE_SKELETON);
        assert_true(mean_distance(x, src) < 1e-4);
    }
    free(x), free(want);
}

/* What keeps the templates' frames: the template drive, the segment
 * correction asked for, templates given by id; the skeleton drive asked
 * for with a template alone takes its landmarks on the avatar's
 * proportions. */
static void test_choices(void **state)
{
    (void)state;
    float *truth = alloc_pose(), *x = alloc_pose(), u[3 * MIM_LANDMARKS_MAX];
    wearer(3, truth, u);
    mim_session_report_t rep;
    mim_session_request_t corrected = {.landmarks = u, .segment_correction = 1, .relative = -1};
    transfer(&corrected, x, &rep);
    assert_int_equal(rep.drive, MIM_DRIVE_TEMPLATE);
    assert_int_equal(rep.corrected, 1);
    mim_session_request_t off = {.landmarks = u, .segment_correction = -1, .relative = -1};
    transfer(&off, x, &rep);
    assert_int_equal(rep.drive, MIM_DRIVE_SKELETON);
    const uint64_t id = rep.template_id;
    mim_session_request_t given = {.landmarks = u, .template_id = id};
    transfer(&given, x, &rep);
    assert_int_equal(rep.drive, MIM_DRIVE_TEMPLATE);
    assert_int_equal(rep.queried, 0);
    mim_session_request_t mode_a = {.template_id = id, .drive = MIM_DRIVE_SKELETON};
    transfer(&mode_a, x, &rep);
    assert_int_equal(rep.drive, MIM_DRIVE_SKELETON);
    assert_int_equal(rep.template_id, id);
    assert_true(rep.label[0] != 0);
    /* the retargeted landmarks are held exactly */
    const mim_landmark_map_t *map = mim_session_map(sess);
    for (uint32_t l = 0; l < map->count; l++)
        for (int k = 0; k < 3; k++)
            assert_true(fabsf(x[3 * (size_t)map->vertex[l] + k] - rep.landmarks[3 * l + k]) < 1e-4f);
    free(truth), free(x);
}

static void test_bad_requests(void **state)
{
    (void)state;
    float *truth = alloc_pose(), *x = alloc_pose(), u[3 * MIM_LANDMARKS_MAX];
    wearer(2, truth, u);
    u[4] = NAN;
    mim_session_report_t rep;
    mim_error_t err = {0};
    mim_session_request_t req = {.landmarks = u, .drive = MIM_DRIVE_SKELETON};
    assert_int_equal(mim_session_transfer(sess, &req, x, &rep, &err), MIM_ENONFINITE);
    assert_non_null(strstr(mim_error_text(&err), "finite"));
    wearer(2, truth, u);
    err = (mim_error_t){0};
    req.drive = (mim_session_drive_t)(MIM_DRIVE_SKELETON + 1);
    assert_int_equal(mim_session_transfer(sess, &req, x, &rep, &err), MIM_EINVAL);
    assert_non_null(strstr(mim_error_text(&err), "unknown drive"));
    assert_int_equal(mim_session_drive_parse("skeleton"), MIM_DRIVE_SKELETON);
    assert_int_equal(mim_session_drive_parse("skeletons"), -1);
    free(truth), free(x);
}

/* mimic transfer says which drive it took (auto on the plain path: the
 * skeleton), and takes --drive skeleton. */
static void test_cli(void **state)
{
    (void)state;
    float *truth = alloc_pose(), u[3 * MIM_LANDMARKS_MAX];
    wearer(4, truth, u);
    const uint32_t L = mim_session_map(sess)->count;
    char text[4096] = "{\"landmarks\": [";
    for (uint32_t l = 0; l < L; l++)
        snprintf(text + strlen(text), sizeof text - strlen(text), "%s[%.6f, %.6f, %.6f]", l ? ", " : "", u[3 * l],
                 u[3 * l + 1], u[3 * l + 2]);
    strcat(text, "]}");
    char *lm = ts_path(dir, "frame.json"), *out = ts_path(dir, "out.ply");
    assert_int_equal(ts_write_file(lm, text, strlen(text)), 0);
    static const char *const drives[2] = {"auto", "skeleton"};
    for (int d = 0; d < 2; d++) {
        const char *args[] = {"transfer", "--store", store, "--avatar", avatar, "--landmarks", lm, "--drive",
                              drives[d], "--relative", "off", "-o", out, "--json", NULL};
        char *o = ts_mimic_expect(0, NULL, args);
        json_t *rep = json_loads(o, 0, NULL);
        assert_non_null(rep);
        assert_string_equal(json_string_value(json_object_get(rep, "drive")), "skeleton");
        json_decref(rep), free(o);
    }
    const char *bad[] = {"transfer", "--store", store, "--avatar", avatar, "--landmarks", lm, "--drive", "bones",
                         "-o", out, NULL};
    char *e = NULL;
    free(ts_mimic_expect(2, &e, bad));
    assert_non_null(strstr(e, "--drive 'bones' is not auto, template, orientation or skeleton"));
    free(e), free(lm), free(out), free(truth);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_auto_takes_skeleton), cmocka_unit_test(test_store_gate),
        cmocka_unit_test(test_pose_spread),         cmocka_unit_test(test_exact_rigid),
        cmocka_unit_test(test_choices),             cmocka_unit_test(test_bad_requests),
        cmocka_unit_test(test_cli),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
