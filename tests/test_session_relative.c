/* session/: relative transfer (issue 15), the template drive's default:
 * the avatar's W plus the template's change from its subject's reference
 * (that subject's template nearest the avatar's rest), and the template's
 * turn on the avatar's own rest frames within the 8 degree gate. On a
 * synth store: closer to the avatar's true pose than the plain path by a
 * clear margin; --relative off is the plain path bit for bit; the report;
 * references per fork; a store without a subject's rest pose (gate off)
 * and a template without a subject (plain path); bad values. */
#include "test_support.h"

#include "mim_session.h"
#include "mim_transfer.h"

#include <jansson.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* synth: subject s pose p is template 1 + s * POSES + p; pose 0 is rest */
#define SUBJECTS 3
#define POSES 6
#define ID(s, p) ((uint64_t)(1 + (s) * POSES + (p)))

static char *dir, *bodies, *store, *bodies2, *store2;
static mim_session_t *base; /* avatar: subject 0 at rest */
static uint32_t n, L;

static int run(const char *const *args)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc) fprintf(stderr, "mimic %s: %s\n", args[0], e ? e : "");
    free(o), free(e);
    return rc;
}

static int copy_file(const char *from_dir, const char *name, const char *to_dir, const char *as)
{
    char *a = ts_path(from_dir, name), *b = ts_path(to_dir, as ? as : name);
    size_t len = 0;
    char *data = ts_read_file(a, &len);
    int rc = data ? ts_write_file(b, data, len) : -1;
    free(data), free(a), free(b);
    return rc;
}

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("session-relative");
    bodies = ts_path(dir, "bodies"), store = ts_path(dir, "store");
    bodies2 = ts_path(dir, "bodies2"), store2 = ts_path(dir, "store2");
    const char *synth[] = {"synth", "--out", bodies, "--subjects", "3", "--poses", "6", "--vertices", "1500", NULL};
    const char *ingest[] = {"ingest", "--store", store, bodies, NULL};
    const char *index[] = {"index", "--store", store, NULL};
    int rc = run(synth) || run(ingest) || run(index);
    /* store2: subject 1 without its rest pose; subject 2's pose 3 alone and
     * without a subject label (a name mimic does not parse) */
    if (!rc) rc = mkdir(bodies2, 0755) || copy_file(bodies, "landmarks.json", bodies2, NULL);
    for (int s = 0; !rc && s < 2; s++)
        for (int p = s; !rc && p < POSES; p++) {
            char name[64];
            snprintf(name, sizeof name, "synth_s%02d_p%02d.ply", s, p);
            rc = copy_file(bodies, name, bodies2, NULL);
        }
    if (!rc) rc = copy_file(bodies, "synth_s02_p03.ply", bodies2, "loose.ply");
    const char *ingest2[] = {"ingest", "--store", store2, bodies2, NULL};
    if (!rc) rc = run(ingest2);
    mim_error_t err = {0};
    if (!rc) rc = mim_session_open(&base, store, NULL, &err);
    if (!rc) rc = mim_session_load_avatar(base, "1", &err);
    if (rc) fprintf(stderr, "setup: %s\n", mim_error_text(&err));
    if (!rc) n = mim_session_mesh(base)->n_vertices, L = mim_session_map(base)->count;
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    mim_session_close(&base);
    ts_rmtree(dir);
    free(dir), free(bodies), free(store), free(bodies2), free(store2);
    return 0;
}

static float *alloc_pose(void) { return malloc(3 * (size_t)n * sizeof(float)); }

/* Template id's positions, and its landmarks into u. */
static float *truth_of(mim_session_t *s, uint64_t id, float *u)
{
    float *x = alloc_pose();
    mim_error_t err = {0};
    if (mim_session_template(s, id, x, NULL, NULL, 0, &err)) fail_msg("%s", mim_error_text(&err));
    const mim_landmark_map_t *m = mim_session_map(s);
    for (uint32_t l = 0; u && l < m->count; l++)
        memcpy(u + 3 * l, x + 3 * (size_t)m->vertex[l], 3 * sizeof *u);
    return x;
}

static double mean_mm(const float *a, const float *b)
{
    double d = 0;
    for (uint32_t i = 0; i < n; i++) {
        double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
        d += sqrt(dx * dx + dy * dy + dz * dz);
    }
    return 1e3 * d / n;
}

static void transfer(mim_session_t *s, const mim_session_request_t *req, float *out, mim_session_report_t *rep)
{
    mim_error_t err = {0};
    if (mim_session_transfer(s, req, out, rep, &err)) fail_msg("%s", mim_error_text(&err));
}

/* The avatar (subject 0 at rest) into pose p by subject 1's template, the
 * targets subject 0's true landmarks in p: relative lands far closer. */
static void test_closer_than_plain(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], *on = alloc_pose(), *off = alloc_pose(), *dflt = alloc_pose();
    double sum_on = 0, sum_off = 0;
    for (uint32_t p = 1; p < POSES; p++) {
        float *truth = truth_of(base, ID(0, p), u);
        mim_session_report_t r_on, r_off, r_dflt;
        mim_session_request_t req = {.template_id = ID(1, p), .landmarks = u, .relative = 1};
        transfer(base, &req, on, &r_on);
        req.relative = -1;
        transfer(base, &req, off, &r_off);
        req.relative = 0; /* the default is on */
        transfer(base, &req, dflt, &r_dflt);
        assert_memory_equal(on, dflt, 3 * (size_t)n * sizeof *on);
        double e_on = mean_mm(on, truth), e_off = mean_mm(off, truth);
        print_message("pose %u: relative %.2f mm, plain %.2f mm\n", p, e_on, e_off);
        assert_true(e_on < 0.5 * e_off);
        sum_on += e_on, sum_off += e_off;
        /* the report: subject 1's reference is its rest template, within the gate */
        assert_int_equal(r_on.relative, 1);
        assert_int_equal(r_dflt.relative, 1);
        assert_int_equal(r_on.frames_turned, 1);
        assert_int_equal(r_on.reference_id, ID(1, 0));
        assert_int_equal(r_on.references[0], ID(1, 0));
        assert_int_equal(r_off.relative, 0);
        assert_int_equal(r_off.frames_turned, 0);
        assert_int_equal(r_off.reference_id, 0);
        assert_int_equal(r_on.template_id, ID(1, p));
        free(truth);
    }
    print_message("mean over poses: relative %.2f mm, plain %.2f mm\n", sum_on / (POSES - 1), sum_off / (POSES - 1));
    assert_true(sum_on < 0.25 * sum_off);
    free(on), free(off), free(dflt);
}

/* The avatar's own subject's template: its reference is the avatar itself,
 * so relative transfer solves with the pose's own W and frames: the truth. */
static void test_own_subject_is_exact(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], *on = alloc_pose(), *off = alloc_pose();
    float *truth = truth_of(base, ID(0, 3), u);
    mim_session_report_t r;
    mim_session_request_t req = {.template_id = ID(0, 3), .landmarks = u};
    transfer(base, &req, on, &r);
    req.relative = -1;
    transfer(base, &req, off, NULL);
    print_message("own subject: relative %.4f mm, plain %.3f mm\n", mean_mm(on, truth), mean_mm(off, truth));
    assert_int_equal(r.reference_id, ID(0, 0));
    assert_true(mean_mm(on, truth) < 0.05);
    assert_true(mean_mm(off, truth) > 0.5);
    free(on), free(off), free(truth);
}

/* Off is the plain path: the avatar's rest W and the template's frames
 * through an own solver give the same floats. */
static void test_off_is_plain(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], *got = alloc_pose(), *want = alloc_pose();
    float *truth = truth_of(base, ID(2, 4), u);
    double *F = malloc(9 * (size_t)n * sizeof *F);
    mim_error_t err = {0};
    assert_int_equal(mim_session_template(base, ID(1, 4), NULL, F, NULL, 0, &err), 0);
    mim_xfer_solver_t *solver = NULL;
    mim_xfer_solver_options_t so = {0};
    assert_int_equal(mim_xfer_solver_open(&solver, mim_session_topology(base), mim_session_map(base)->vertex, L, &so, &err), 0);
    mim_xfer_options_t xo = {0};
    assert_int_equal(mim_xfer_transfer(solver, mim_session_encoding(base), n, F, u, L, &xo, want, NULL, &err), 0);
    mim_session_request_t req = {.template_id = ID(1, 4), .landmarks = u, .relative = -1, .segment_correction = -1};
    transfer(base, &req, got, NULL);
    assert_memory_equal(got, want, 3 * (size_t)n * sizeof *got);
    /* relative on differs, and a held pose (the slot's cached change) repeats itself */
    req.relative = 1, req.segment_correction = 0;
    transfer(base, &req, got, NULL);
    assert_true(mean_mm(got, want) > 0.1);
    transfer(base, &req, want, NULL);
    assert_memory_equal(got, want, 3 * (size_t)n * sizeof *got);
    mim_xfer_solver_close(&solver);
    free(got), free(want), free(truth), free(F);
}

/* The segment correction's default: on where the transfer is plain (the
 * imitation set's gain), off where it is relative (another body's landmark
 * skeleton would turn the avatar's own frames); on and off as asked. */
static void test_correction_default(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], *dflt = alloc_pose(), *on = alloc_pose(), *off = alloc_pose();
    float *truth = truth_of(base, ID(2, 4), u);
    mim_session_report_t r;
    mim_session_request_t req = {.template_id = ID(1, 4), .landmarks = u, .relative = -1};
    transfer(base, &req, dflt, &r);
    assert_int_equal(r.relative, 0);
    assert_int_equal(r.corrected, 1);
    req.segment_correction = 1;
    transfer(base, &req, on, &r);
    assert_int_equal(r.corrected, 1);
    assert_memory_equal(dflt, on, 3 * (size_t)n * sizeof *on);
    req.segment_correction = -1;
    transfer(base, &req, off, &r);
    assert_int_equal(r.corrected, 0);
    assert_true(mean_mm(dflt, off) > 0.01);
    /* relative: the default leaves the frames as they are */
    req = (mim_session_request_t){.template_id = ID(1, 4), .landmarks = u};
    transfer(base, &req, dflt, &r);
    assert_int_equal(r.relative, 1);
    assert_int_equal(r.corrected, 0);
    req.segment_correction = -1;
    transfer(base, &req, off, &r);
    assert_memory_equal(dflt, off, 3 * (size_t)n * sizeof *off);
    free(dflt), free(on), free(off), free(truth);
}

/* Two templates blended: each with its own subject's reference. */
static void test_blend(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], *on = alloc_pose(), *off = alloc_pose();
    float *truth = truth_of(base, ID(0, 2), u);
    uint64_t ids[2] = {ID(1, 2), ID(2, 2)};
    mim_session_report_t r;
    mim_session_request_t req = {.template_ids = ids, .n_templates = 2, .landmarks = u};
    transfer(base, &req, on, &r);
    req.relative = -1;
    transfer(base, &req, off, NULL);
    print_message("blend of two: relative %.2f mm, plain %.2f mm\n", mean_mm(on, truth), mean_mm(off, truth));
    assert_int_equal(r.n_templates, 2);
    assert_int_equal(r.relative, 1);
    assert_int_equal(r.frames_turned, 2);
    assert_int_equal(r.references[0], ID(1, 0));
    assert_int_equal(r.references[1], ID(2, 0));
    assert_true(mean_mm(on, truth) < 0.5 * mean_mm(off, truth));
    free(on), free(off), free(truth);
}

/* The index's nearest (mimic transfer --landmarks): relative too. */
static void test_queried(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], *x = alloc_pose();
    float *truth = truth_of(base, ID(2, 5), u);
    mim_session_report_t r;
    mim_session_request_t req = {.landmarks = u};
    transfer(base, &req, x, &r);
    assert_int_equal(r.queried, 1);
    assert_int_equal(r.relative, 1);
    assert_int_equal(r.reference_id, ID((r.template_id - 1) / POSES, 0));
    free(x), free(truth);
}

typedef struct job {
    mim_session_t *s;
    const float *u;
    float *out;
    int rc;
} job_t;

static void *job_run(void *arg)
{
    job_t *j = arg;
    mim_session_request_t req = {.template_id = ID(1, 1), .landmarks = j->u};
    mim_error_t err = {0};
    for (int i = 0; i < 3 && !j->rc; i++)
        j->rc = mim_session_transfer(j->s, &req, j->out, NULL, &err);
    return NULL;
}

/* A fork has its own avatar, so its own references and scales: it gives
 * what a session of its own gives, the base keeps what it gave, and both
 * find their references at once on two threads. */
static void test_fork_own_references(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_session_t *f = NULL, *alone = NULL;
    assert_int_equal(mim_session_fork(&f, base, NULL, &err), 0);
    assert_int_equal(mim_session_load_avatar(f, "13", &err), 0); /* subject 2 at rest */
    assert_int_equal(mim_session_open(&alone, store, NULL, &err), 0);
    assert_int_equal(mim_session_load_avatar(alone, "13", &err), 0);
    float u0[3 * MIM_LANDMARKS_MAX], u2[3 * MIM_LANDMARKS_MAX];
    float *t0 = truth_of(base, ID(0, 1), u0), *t2 = truth_of(base, ID(2, 1), u2);
    float *b_before = alloc_pose(), *b_after = alloc_pose(), *f_out = alloc_pose(), *a_out = alloc_pose();
    job_t jb = {base, u0, b_before, 0};
    job_run(&jb);
    assert_int_equal(jb.rc, 0);
    job_t tb = {base, u0, b_after, 0}, tf = {f, u2, f_out, 0};
    pthread_t p1, p2;
    assert_int_equal(pthread_create(&p1, NULL, job_run, &tb), 0);
    assert_int_equal(pthread_create(&p2, NULL, job_run, &tf), 0);
    pthread_join(p1, NULL), pthread_join(p2, NULL);
    assert_int_equal(tb.rc, 0);
    assert_int_equal(tf.rc, 0);
    job_t ja = {alone, u2, a_out, 0};
    job_run(&ja);
    assert_int_equal(ja.rc, 0);
    assert_memory_equal(b_before, b_after, 3 * (size_t)n * sizeof(float));
    assert_memory_equal(f_out, a_out, 3 * (size_t)n * sizeof(float));
    print_message("fork (subject 2): %.2f mm from its truth; base (subject 0): %.2f mm\n", mean_mm(f_out, t2),
                  mean_mm(b_before, t0));
    assert_true(mean_mm(f_out, t2) < 2.0);
    /* subject 0's template: the fork's reference is subject 0's rest, as the base's */
    mim_session_report_t r;
    mim_session_request_t req = {.template_id = ID(0, 1), .landmarks = u2};
    transfer(f, &req, f_out, &r);
    assert_int_equal(r.reference_id, ID(0, 0));
    mim_session_close(&f);
    mim_session_close(&alone);
    free(t0), free(t2), free(b_before), free(b_after), free(f_out), free(a_out);
}

/* store2: subject 1 has no rest pose, so its reference stands in another
 * pose than the avatar's rest: no evidence that it moves as the avatar
 * would, so the plain path (issue 29: its change of encoding alone made
 * bodies of one rig 25 % better, and real people's 20 % worse); and an
 * unlabelled template takes the plain path too. */
static void test_no_rest_reference(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_session_t *s = NULL;
    assert_int_equal(mim_session_open(&s, store2, NULL, &err), 0);
    /* the ids by label */
    uint64_t a_rest = 0, a_pose = 0, b_pose = 0, loose = 0;
    char label[MIM_SESSION_LABEL_MAX];
    for (uint64_t id = 1; mim_session_template(s, id, NULL, NULL, label, sizeof label, &err) == 0; id++) {
        if (!strcmp(label, "0/0")) a_rest = id;
        else if (!strcmp(label, "0/3")) a_pose = id;
        else if (!strcmp(label, "1/3")) b_pose = id;
        else if (!strcmp(label, "-/-")) loose = id;
    }
    assert_true(a_rest && a_pose && b_pose && loose);
    char avatar[32];
    snprintf(avatar, sizeof avatar, "%llu", (unsigned long long)a_rest);
    assert_int_equal(mim_session_load_avatar(s, avatar, &err), 0);
    float u[3 * MIM_LANDMARKS_MAX], *on = alloc_pose(), *off = alloc_pose();
    float *truth = truth_of(s, a_pose, u);
    mim_session_report_t r;
    mim_session_request_t req = {.template_id = b_pose, .landmarks = u};
    transfer(s, &req, on, &r);
    req.relative = -1;
    transfer(s, &req, off, NULL);
    print_message("no rest reference: relative %.2f mm, plain %.2f mm (reference %llu)\n", mean_mm(on, truth),
                  mean_mm(off, truth), (unsigned long long)r.reference_id);
    assert_int_equal(r.relative, 0);
    assert_int_equal(r.frames_turned, 0);
    assert_int_equal(r.reference_id, 0);
    assert_memory_equal(on, off, 3 * (size_t)mim_session_mesh(s)->n_vertices * sizeof *on); /* bit for bit */
    /* no subject: the plain path, bit for bit */
    req = (mim_session_request_t){.template_id = loose, .landmarks = u};
    transfer(s, &req, on, &r);
    assert_int_equal(r.relative, 0);
    assert_int_equal(r.reference_id, 0);
    req.relative = -1;
    transfer(s, &req, off, NULL);
    assert_memory_equal(on, off, 3 * (size_t)n * sizeof *on);
    /* a blend with it: all or none */
    uint64_t ids[2] = {b_pose, loose};
    req = (mim_session_request_t){.template_ids = ids, .n_templates = 2, .landmarks = u};
    transfer(s, &req, on, &r);
    assert_int_equal(r.relative, 0);
    mim_session_close(&s);
    free(on), free(off), free(truth);
}

/* The index's blend, relative: each template weighs (1 / (d + floor))^2
 * times (1 / (build distance of its reference from the avatar's rest +
 * floor))^2; the plain path's weights are 1 / (d + floor), so the shares
 * of one query's templates relate as the square of the plain ones' times
 * the builds' factor. And the shares sum to 1. */
static void test_relative_weights(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], u2[3 * MIM_LANDMARKS_MAX], rest[3 * MIM_LANDMARKS_MAX], *x = alloc_pose();
    free(truth_of(base, ID(1, 4), u));
    free(truth_of(base, ID(2, 4), u2));
    free(truth_of(base, ID(0, 0), rest)); /* the avatar */
    for (uint32_t k = 0; k < 3 * L; k++) /* between two subjects: no template is the query */
        u[k] = 0.5f * (u[k] + u2[k]);
    mim_session_report_t on, off;
    /* the template drive: off, auto would take the skeleton drive (the plain path) */
    mim_session_request_t req = {.landmarks = u, .blend = 3, .drive = MIM_DRIVE_TEMPLATE};
    transfer(base, &req, x, &on);
    req.relative = -1;
    transfer(base, &req, x, &off);
    assert_int_equal(on.relative, 1);
    assert_int_equal(on.n_templates, 3);
    assert_int_equal(off.n_templates, 3);
    double sum = 0, build[3];
    for (uint32_t j = 0; j < 3; j++) {
        assert_int_equal(on.templates[j], off.templates[j]);
        float lm[3 * MIM_LANDMARKS_MAX];
        free(truth_of(base, on.references[j], lm));
        build[j] = mim_xfer_build_distance(rest, lm, L);
        sum += on.weights[j];
    }
    assert_true(fabs(sum - 1) < 1e-12);
    assert_true(build[0] > 0 || build[1] > 0 || build[2] > 0); /* other builds than the avatar's among them */
    for (uint32_t j = 1; j < 3; j++) {
        const double plain = off.weights[j] / off.weights[0];
        const double bf = (build[0] + MIM_SESSION_BUILD_DISTANCE_FLOOR) / (build[j] + MIM_SESSION_BUILD_DISTANCE_FLOOR);
        const double want = pow(plain, MIM_SESSION_RELATIVE_DISTANCE_POWER) * pow(bf, MIM_SESSION_RELATIVE_BUILD_POWER);
        print_message("template %llu: share %.4f (plain %.4f), build %.5f\n", (unsigned long long)on.templates[j],
                      on.weights[j], off.weights[j], build[j]);
        assert_true(fabs(on.weights[j] / on.weights[0] - want) < 1e-9 * want);
    }
    /* templates given by id: equal shares, relative or not */
    uint64_t ids[2] = {ID(1, 4), ID(2, 4)};
    req = (mim_session_request_t){.template_ids = ids, .n_templates = 2, .landmarks = u};
    transfer(base, &req, x, &on);
    assert_int_equal(on.relative, 1);
    assert_true(fabs(on.weights[0] - 0.5) < 1e-12 && fabs(on.weights[1] - 0.5) < 1e-12);
    free(x);
}

/* Relative transfer solves at most MIM_SESSION_RELATIVE_ITERATIONS times
 * unless the request caps the solves itself; the plain path keeps
 * iterating (here: told never to converge nor stop early). */
static void test_relative_iterations(void **state)
{
    (void)state;
    float u[3 * MIM_LANDMARKS_MAX], *x = alloc_pose();
    free(truth_of(base, ID(0, 2), u));
    mim_session_report_t r;
    mim_session_request_t req = {.template_id = ID(1, 2), .landmarks = u, .xfer = {.tol = -1, .no_early_stop = 1}};
    transfer(base, &req, x, &r);
    assert_int_equal(r.relative, 1);
    assert_int_equal(r.xfer.iterations, MIM_SESSION_RELATIVE_ITERATIONS);
    req.relative = -1;
    transfer(base, &req, x, &r);
    assert_int_equal(r.relative, 0);
    assert_true(r.xfer.iterations > MIM_SESSION_RELATIVE_ITERATIONS);
    req.relative = 0, req.xfer.max_iterations = MIM_SESSION_RELATIVE_ITERATIONS + 3; /* the request's own cap */
    transfer(base, &req, x, &r);
    assert_int_equal(r.relative, 1);
    assert_int_equal(r.xfer.iterations, MIM_SESSION_RELATIVE_ITERATIONS + 3);
    free(x);
}

static void test_bad_values(void **state)
{
    (void)state;
    float *x = alloc_pose();
    const int bad[] = {2, -2, 7};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        mim_error_t err = {0};
        mim_session_request_t req = {.template_id = ID(1, 1), .relative = bad[k]};
        assert_int_equal(mim_session_transfer(base, &req, x, NULL, &err), MIM_EINVAL);
        assert_non_null(strstr(mim_error_text(&err), "relative"));
    }
    free(x);
}

static json_t *run_json(const char *const *args)
{
    char *o = NULL, *e = NULL;
    if (ts_run_mimic(&o, &e, args)) fail_msg("mimic %s: %s", args[0], e);
    json_error_t je;
    json_t *j = json_loads(o, 0, &je);
    if (!j) fail_msg("not JSON: %s", o);
    free(o), free(e);
    return j;
}

/* The commands: --relative on|off, the reports, and bad values. */
static void test_cli(void **state)
{
    (void)state;
    char *outp = ts_path(dir, "out.ply"), *glb = ts_path(dir, "out.glb");
    const char *mode[] = {NULL, "on", "off"};
    for (int k = 0; k < 3; k++) {
        const char *args[] = {"transfer", "--store", store, "--avatar", "1", "--template", "10", "-o", outp, "--json",
                              mode[k] ? "--relative" : NULL, mode[k], NULL};
        json_t *j = run_json(args);
        int on = k < 2;
        assert_int_equal(json_is_true(json_object_get(j, "relative")), on);
        assert_int_equal(json_integer_value(json_object_get(j, "frames_turned")), on);
        json_t *ref = json_object_get(j, "reference"), *refs = json_object_get(j, "references");
        if (on) {
            assert_int_equal(json_integer_value(ref), ID(1, 0));
            assert_int_equal(json_array_size(refs), 1);
            assert_int_equal(json_integer_value(json_array_get(refs, 0)), ID(1, 0));
        } else {
            assert_true(json_is_null(ref));
            assert_int_equal(json_array_size(refs), 0);
        }
        json_decref(j);
        const char *morph[] = {"morph", "--store", store, "--avatar", "1", "--keys", "8,9,10", "--frames-between", "1",
                               "-o", glb, "--json", mode[k] ? "--relative" : NULL, mode[k], NULL};
        j = run_json(morph);
        assert_int_equal(json_integer_value(json_object_get(j, "relative_keys")), on ? 3 : 0);
        json_decref(j);
    }
    const char *cmds[][2] = {{"transfer", "maybe"}, {"morph", "1"}, {"serve", "yes"}, {"transfer", ""}};
    for (size_t k = 0; k < sizeof cmds / sizeof cmds[0]; k++) {
        char *o = NULL, *e = NULL, *badout = ts_path(dir, "bad.ply");
        const char *args[] = {cmds[k][0], "--store", store, "--avatar", "1", "--relative", cmds[k][1], NULL};
        const char *xfer[] = {cmds[k][0], "--store", store, "--avatar", "1", "--template", "10", "-o", badout,
                              "--relative", cmds[k][1], NULL};
        assert_int_equal(ts_run_mimic(&o, &e, strcmp(cmds[k][0], "transfer") ? args : xfer), 2);
        if (!strstr(e, "--relative") || !strstr(e, "use on or off")) fail_msg("%s: %s", cmds[k][0], e);
        assert_int_equal(access(badout, F_OK), -1);
        free(o), free(e), free(badout);
    }
    free(outp), free(glb);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_closer_than_plain),  cmocka_unit_test(test_own_subject_is_exact),
        cmocka_unit_test(test_off_is_plain),       cmocka_unit_test(test_correction_default),
        cmocka_unit_test(test_blend),
        cmocka_unit_test(test_queried),            cmocka_unit_test(test_fork_own_references),
        cmocka_unit_test(test_no_rest_reference),  cmocka_unit_test(test_bad_values),
        cmocka_unit_test(test_relative_weights),   cmocka_unit_test(test_relative_iterations),
        cmocka_unit_test(test_cli),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
