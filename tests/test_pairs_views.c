/* The view of a 2D annotation (sample/view_estimate.c; seed 002, Section
 * 4.2): the mean torso, and the view (eq. 4) of synthetic pose-pairs seen
 * by random cameras (annotate.c) against the true camera's. */
#include "mim_sample.h"

#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { HEAD, CHEST, PELVIS, L_SHOULDER, R_SHOULDER, L_ELBOW, R_ELBOW, L_WRIST, R_WRIST, L_HIP, R_HIP, L_KNEE, R_KNEE,
       L_ANKLE, R_ANKLE, SPINE, NECK };

/* A person's rest torso (metres; x left, y up, z forward; the pelvis 0.95 m up).
 * Every joint is listed (arms and legs are placed by make_person): gcc
 * 12.2 at -O3 vectorises the copy of a table whose rows are mostly left
 * to zero-initialisation wrongly (L_HIP's x read as 0; a Release build of
 * this test failed), and a table written out whole is copied right. */
static const double rest[MIM_PAIR_PERSON_JOINTS][3] = {
    [HEAD] = {0, 1.63, 0.04},         [CHEST] = {0, 1.27, 0},          [PELVIS] = {0, 0.95, 0},
    [L_SHOULDER] = {0.18, 1.42, -0.01}, [R_SHOULDER] = {-0.18, 1.42, -0.01}, [L_ELBOW] = {0, 0, 0},
    [R_ELBOW] = {0, 0, 0},             [L_WRIST] = {0, 0, 0},          [R_WRIST] = {0, 0, 0},
    [L_HIP] = {0.09, 0.87, 0.04},      [R_HIP] = {-0.09, 0.87, 0.04},  [L_KNEE] = {0, 0, 0},
    [R_KNEE] = {0, 0, 0},              [L_ANKLE] = {0, 0, 0},          [R_ANKLE] = {0, 0, 0},
    [SPINE] = {0, 1.07, -0.03},        [NECK] = {0, 1.47, 0},
};

typedef struct person_opts {
    double height;     /* scale of the rest person */
    double lean, twist; /* radians: the upper body bent forward about the pelvis, turned about the spine */
    double jitter;     /* metres of noise on every joint */
} person_opts_t;

static mim_vec3 rnd_dir(mim_rng_t *r)
{
    mim_vec3 v = mim_v3(mim_rng_gauss(r), mim_rng_gauss(r), mim_rng_gauss(r));
    return mim_v3_normalize(v);
}

/* One person (17 joints) turned by yaw about the up axis and standing at (x, z). */
static void make_person(mim_rng_t *r, const person_opts_t *o, double yaw, double x, double z, double *out)
{
    mim_vec3 j[MIM_PAIR_PERSON_JOINTS];
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++) j[k] = mim_v3(rest[k][0], rest[k][1], rest[k][2]);
    /* the upper body (above the pelvis) bends and turns */
    mim_quat q = mim_quat_mul(mim_quat_axis_angle(mim_v3(1, 0, 0), o->lean), mim_quat_axis_angle(mim_v3(0, 1, 0), o->twist));
    const int upper[] = {HEAD, CHEST, L_SHOULDER, R_SHOULDER, SPINE, NECK};
    for (size_t k = 0; k < sizeof upper / sizeof *upper; k++)
        j[upper[k]] = mim_v3_add(j[PELVIS], mim_quat_rotate(q, mim_v3_sub(j[upper[k]], j[PELVIS])));
    /* arms at any angle; legs down, knees somewhat bent */
    for (int s = 0; s < 2; s++) {
        j[L_ELBOW + s] = mim_v3_add(j[L_SHOULDER + s], mim_v3_scale(rnd_dir(r), 0.29));
        j[L_WRIST + s] = mim_v3_add(j[L_ELBOW + s], mim_v3_scale(rnd_dir(r), 0.26));
        double a = -0.2 + 0.9 * mim_rng_unit(r), b = a - 0.6 * mim_rng_unit(r);
        j[L_KNEE + s] = mim_v3_add(j[L_HIP + s], mim_v3(0, -0.43 * cos(a), 0.43 * sin(a)));
        j[L_ANKLE + s] = mim_v3_add(j[L_KNEE + s], mim_v3(0, -0.42 * cos(b), 0.42 * sin(b)));
    }
    mim_quat turn = mim_quat_axis_angle(mim_v3(0, 1, 0), yaw);
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++) {
        mim_vec3 v = mim_quat_rotate(turn, mim_v3_scale(j[k], o->height));
        out[3 * k] = v.x + x + o->jitter * mim_rng_gauss(r);
        out[3 * k + 1] = v.y + o->jitter * mim_rng_gauss(r);
        out[3 * k + 2] = v.z + z + o->jitter * mim_rng_gauss(r);
    }
}

/* A pose-pair: B 0.5 to 2 m from A, both at random yaw; rigid = the rest torso exactly. */
static void make_pair(mim_rng_t *r, int rigid, double *pair)
{
    for (int p = 0; p < 2; p++) {
        person_opts_t o = {1.0, 0, 0, 0};
        if (!rigid) {
            o.height = 0.92 + 0.16 * mim_rng_unit(r);
            o.lean = -0.1 + 0.5 * mim_rng_unit(r);
            o.twist = 0.5 * (mim_rng_unit(r) - 0.5);
            o.jitter = 0.01;
        }
        double d = 0.5 + 1.5 * mim_rng_unit(r), a = 2 * M_PI * mim_rng_unit(r);
        make_person(r, &o, 2 * M_PI * mim_rng_unit(r), p ? d * cos(a) : 0, p ? d * sin(a) : 0,
                    pair + 3 * MIM_PAIR_PERSON_JOINTS * p);
    }
}

static double angle_between(double psi0, double phi0, double psi1, double phi1)
{
    static const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    double a[3], b[3];
    mim_pairs_view_direction(I, psi0, phi0, a);
    mim_pairs_view_direction(I, psi1, phi1, b);
    return acos(fmax(-1.0, fmin(1.0, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]))) * 180.0 / M_PI;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
static double quantile(double *v, int n, double q)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return v[(int)(q * (n - 1) + 0.5)];
}

static void learn_synthetic(mim_pairs_torso_t *torso, int rigid)
{
    enum { N = 200 };
    double *pairs = malloc(sizeof(double) * N * 3 * MIM_PAIR_JOINTS);
    mim_rng_t r;
    mim_rng_seed(&r, 99, 0);
    for (int n = 0; n < N; n++) make_pair(&r, rigid, pairs + n * 3 * MIM_PAIR_JOINTS);
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_torso_learn(pairs, N, torso, &err), 0);
    free(pairs);
}

typedef struct trial {
    double noise_px, focal_px; /* focal_px 0: the random camera's */
    int rigid, mirror;
} trial_t;

/* n annotations: the angle (degrees) between the estimated and true views, and (truth, estimate) angles. */
static void run_views(const mim_pairs_torso_t *torso, const trial_t *t, uint64_t seed, int n, double *err_deg,
                      double *truth, double *est)
{
    mim_rng_t r;
    mim_rng_seed(&r, seed, 1);
    double pair[3 * MIM_PAIR_JOINTS], uv[2 * MIM_PAIR_JOINTS], L[9];
    for (int k = 0; k < n; k++) {
        mim_pairs_camera_t cam;
        do make_pair(&r, t->rigid, pair);
        while (mim_pairs_local_frame(pair, L) || mim_pairs_camera_random(&r, pair, &cam));
        if (t->focal_px > 0) cam.focal_px = t->focal_px;
        mim_pairs_project(&cam, pair, uv);
        for (int i = 0; i < 2 * MIM_PAIR_JOINTS; i++) uv[i] += t->noise_px * mim_rng_gauss(&r);
        if (t->mirror)
            for (int i = 0; i < MIM_PAIR_JOINTS; i++) uv[2 * i] = cam.width - uv[2 * i];
        double tp, tf, ep, ef;
        mim_pairs_view_angles(L, cam.R + 6, &tp, &tf); /* the forward axis: R's third row */
        assert_int_equal(mim_pairs_annotation_view(torso, uv, cam.width, cam.height, &ep, &ef), 0);
        err_deg[k] = angle_between(tp, tf, ep, ef);
        if (truth) truth[2 * k] = tp, truth[2 * k + 1] = tf;
        if (est) est[2 * k] = ep, est[2 * k + 1] = ef;
    }
}

static void report(const char *what, double *e, int n, double *median, double *p95)
{
    *median = quantile(e, n, 0.5), *p95 = quantile(e, n, 0.95);
    print_message("view error, %s: median %.1f, 95th percentile %.1f degrees\n", what, *median, *p95);
}

/* The learned torso is the rest torso (chest above the pelvis: the frame is
 * the rest person's axes) whatever the people's yaw, place and arms; with
 * the hips on the pelvis (CMU-like skeletons) the shoulders give the frame;
 * a person with a NaN is skipped; nothing usable is MIM_EINVAL. */
static void test_torso_learn(void **state)
{
    (void)state;
    enum { N = 20 };
    static const int tj[MIM_PAIRS_TORSO_POINTS] = {PELVIS, L_HIP, R_HIP, SPINE, CHEST, NECK, L_SHOULDER, R_SHOULDER};
    double *pairs = malloc(sizeof(double) * N * 3 * MIM_PAIR_JOINTS);
    mim_rng_t r;
    mim_rng_seed(&r, 1, 0);
    for (int n = 0; n < N; n++) make_pair(&r, 1, pairs + n * 3 * MIM_PAIR_JOINTS);
    mim_pairs_torso_t t;
    mim_error_t err = {0};
    for (int hips_on_pelvis = 0; hips_on_pelvis < 2; hips_on_pelvis++) {
        if (hips_on_pelvis)
            for (int p = 0; p < 2 * N; p++) {
                double *J = pairs + 3 * MIM_PAIR_PERSON_JOINTS * p;
                memcpy(J + 3 * L_HIP, J + 3 * PELVIS, 3 * sizeof(double));
                memcpy(J + 3 * R_HIP, J + 3 * PELVIS, 3 * sizeof(double));
            }
        pairs[3 * (MIM_PAIR_JOINTS + CHEST)] = NAN; /* pair 1's person A: skipped */
        assert_int_equal(mim_pairs_torso_learn(pairs, N, &t, &err), 0);
        for (int k = 0; k < MIM_PAIRS_TORSO_POINTS; k++)
            for (int c = 0; c < 3; c++) {
                int hip = tj[k] == L_HIP || tj[k] == R_HIP;
                double want = hips_on_pelvis && hip ? 0.0 : rest[tj[k]][c] - rest[PELVIS][c];
                assert_true(fabs(t.point[k][c] - want) < 1e-9);
            }
    }
    assert_int_equal(mim_pairs_torso_learn(pairs, 0, &t, &err), MIM_EINVAL);
    for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) pairs[i] = 1.0; /* everyone at one place */
    mim_error_clear(&err);
    assert_int_equal(mim_pairs_torso_learn(pairs, 1, &t, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "no person"));
    free(pairs);
}

enum { N_VIEWS = 400 };

/* The best constant view chosen with hindsight (a 5 degree grid over the
 * sphere): the median error of an estimate that ignores the image. */
static double best_constant_median(const double *truth, int n)
{
    double *e = malloc(sizeof(double) * n), best = INFINITY;
    for (int a = 0; a < 72; a++)
        for (int b = 0; b <= 36; b++) {
            for (int k = 0; k < n; k++) e[k] = angle_between(-M_PI + a * M_PI / 36, b * M_PI / 36, truth[2 * k], truth[2 * k + 1]);
            best = fmin(best, quantile(e, n, 0.5));
        }
    free(e);
    return best;
}

/* 2 px of noise, people of other sizes and postures than the mean torso,
 * annotate.c's cameras: the error is measured against the true camera's
 * forward axis, and against the best constant guess. */
static void test_view_accuracy(void **state)
{
    (void)state;
    mim_pairs_torso_t torso;
    learn_synthetic(&torso, 0);
    double e[N_VIEWS], *truth = malloc(sizeof(double) * 2 * N_VIEWS), med, p95;
    trial_t t = {2, 0, 0, 0};
    run_views(&torso, &t, 5, N_VIEWS, e, truth, NULL);
    report("2 px", e, N_VIEWS, &med, &p95);
    double base = best_constant_median(truth, N_VIEWS);
    print_message("best constant view: median error %.1f degrees\n", base);
    /* measured 9.5 and 39 here, 9.2-10.9 and 41-53 over ten other seeds; the
     * depth sign flipped, no depth, the Necker choice reversed or the
     * backbone's depth flipped give 16-87 */
    assert_true(med < 13.0);
    assert_true(p95 < 60.0);
    assert_true(base > 60.0); /* measured 76: views come from every side */
    assert_true(med < base / 5);
    free(truth);
}

/* Conventions: rigid people exactly the mean torso, the assumed focal
 * length, no noise: only weak perspective is left (the local frame, the
 * camera axes and eq. 4's angles all agree with mim_pairs_local_frame and
 * mim_pairs_view_angles). */
static void test_view_exact(void **state)
{
    (void)state;
    mim_pairs_torso_t torso;
    learn_synthetic(&torso, 1);
    double e[N_VIEWS], med, p95;
    trial_t t = {0, 0.75 * 1920, 1, 0};
    run_views(&torso, &t, 6, N_VIEWS, e, NULL, NULL);
    report("rigid, f known, 0 px", e, N_VIEWS, &med, &p95);
    assert_true(med < 2.5); /* measured 1.5, 1.3-1.6 over ten other seeds; sabotaged: 7.7-178 */
    assert_true(p95 < 8.0); /* measured 5.1, 4.3-5.2 */
}

/* More pixel noise, more error (same pairs and cameras: the noise is drawn
 * after them). */
static void test_view_noise(void **state)
{
    (void)state;
    mim_pairs_torso_t torso;
    learn_synthetic(&torso, 0);
    double e[N_VIEWS], med[3], p95;
    const double noise[3] = {0, 2, 5};
    for (int k = 0; k < 3; k++) {
        trial_t t = {noise[k], 0, 0, 0};
        char name[32];
        snprintf(name, sizeof name, "%.0f px", noise[k]);
        run_views(&torso, &t, 7, N_VIEWS, e, NULL, NULL);
        report(name, e, N_VIEWS, &med[k], &p95);
    }
    assert_true(med[0] < med[2]);
    assert_true(med[1] < med[2]);
}

/* A mirror image is the view of the mirrored pair, whose true view is
 * (-psi, phi) (k = i x j turns over): the estimate must follow. */
static void test_view_mirror(void **state)
{
    (void)state;
    mim_pairs_torso_t torso;
    learn_synthetic(&torso, 0);
    double e[N_VIEWS], *est = malloc(sizeof(double) * 2 * N_VIEWS), *mir = malloc(sizeof(double) * 2 * N_VIEWS);
    double changed[N_VIEWS], follows[N_VIEWS];
    trial_t t = {2, 0, 0, 0}, m = {2, 0, 0, 1};
    run_views(&torso, &t, 8, N_VIEWS, e, NULL, est);
    run_views(&torso, &m, 8, N_VIEWS, e, NULL, mir);
    for (int k = 0; k < N_VIEWS; k++) {
        changed[k] = angle_between(est[2 * k], est[2 * k + 1], mir[2 * k], mir[2 * k + 1]);
        follows[k] = angle_between(-est[2 * k], est[2 * k + 1], mir[2 * k], mir[2 * k + 1]);
    }
    double c = quantile(changed, N_VIEWS, 0.5), f = quantile(follows, N_VIEWS, 0.5);
    print_message("mirror image: the estimate moves by %.1f degrees (median), %.1f from (-psi, phi)\n", c, f);
    assert_true(c > 60.0); /* measured 89 */
    assert_true(f < 15.0); /* measured 7.9: the mirrored person (left and right swapped) is no rotation of the torso */
    free(est), free(mir);
}

static void test_view_bad_input(void **state)
{
    (void)state;
    mim_pairs_torso_t torso;
    learn_synthetic(&torso, 0);
    mim_rng_t r;
    mim_rng_seed(&r, 9, 0);
    double pair[3 * MIM_PAIR_JOINTS], uv[2 * MIM_PAIR_JOINTS], bad[2 * MIM_PAIR_JOINTS], psi, phi;
    mim_pairs_camera_t cam;
    make_pair(&r, 0, pair);
    assert_int_equal(mim_pairs_camera_random(&r, pair, &cam), 0);
    mim_pairs_project(&cam, pair, uv);
    assert_int_equal(mim_pairs_annotation_view(&torso, uv, 1920, 1080, &psi, &phi), 0);
    assert_true(isfinite(psi) && isfinite(phi));
    memcpy(bad, uv, sizeof uv);
    bad[2 * (MIM_PAIR_PERSON_JOINTS + SPINE) + 1] = NAN; /* a torso pixel */
    assert_int_equal(mim_pairs_annotation_view(&torso, bad, 1920, 1080, &psi, &phi), MIM_EINVAL);
    memcpy(bad, uv, sizeof uv);
    bad[2 * L_WRIST] = NAN; /* not a torso joint: unused */
    assert_int_equal(mim_pairs_annotation_view(&torso, bad, 1920, 1080, &psi, &phi), 0);
    for (int i = 0; i < MIM_PAIR_PERSON_JOINTS; i++) bad[2 * i] = 500, bad[2 * i + 1] = 300; /* A at one pixel */
    assert_int_equal(mim_pairs_annotation_view(&torso, bad, 1920, 1080, &psi, &phi), MIM_EINVAL);
    assert_int_equal(mim_pairs_annotation_view(&torso, uv, 0, 1080, &psi, &phi), MIM_EINVAL);
    mim_pairs_torso_t flat = {{{0}}}; /* a torso at one place */
    assert_int_equal(mim_pairs_annotation_view(&flat, uv, 1920, 1080, &psi, &phi), MIM_EINVAL);
    torso.point[3][1] = NAN;
    assert_int_equal(mim_pairs_annotation_view(&torso, uv, 1920, 1080, &psi, &phi), MIM_EINVAL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_torso_learn), cmocka_unit_test(test_view_accuracy), cmocka_unit_test(test_view_exact),
        cmocka_unit_test(test_view_noise),  cmocka_unit_test(test_view_mirror),   cmocka_unit_test(test_view_bad_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
