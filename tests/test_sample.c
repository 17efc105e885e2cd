/* sample/ (seed 002): interaction coordinates, d_I (eq. 8),
 * the rigid alignment, D_I / D_C / D_S and coverage (eq. 13). */
#include "internal.h"
#include "mim_sample.h"

#include "test_support.h"

#include <ode/ode.h>

#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void random_pair(mim_rng_t *r, int dim, double *p)
{
    for (int i = 0; i < MIM_PAIR_JOINTS * dim; i++) p[i] = mim_rng_unit(r) * 1.8 - 0.9;
}

static void rotate(const double *in, double ax, double ay, double az, double ang, const double t[3], double *out)
{
    mim_quat q = mim_quat_axis_angle(mim_v3_normalize(mim_v3(ax, ay, az)), ang);
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
        mim_vec3 v = mim_quat_rotate(q, mim_v3(in[3 * i], in[3 * i + 1], in[3 * i + 2]));
        out[3 * i] = v.x + t[0], out[3 * i + 1] = v.y + t[1], out[3 * i + 2] = v.z + t[2];
    }
}

static int has_edge(const mim_ic_t *t, int a, int b)
{
    for (uint32_t k = 0; k < t->n_edges; k++)
        if (t->edge[k][0] == a && t->edge[k][1] == b) return 1;
    return 0;
}

/* A ladder of 2 x 17 points: every rung and rail, one diagonal per square
 * (Qt triangulates the cocircular squares), nothing else: 65 edges. */
static void test_delaunay_ladder(void **s)
{
    (void)s;
    double p[2 * MIM_PAIR_JOINTS];
    for (int i = 0; i < MIM_PAIR_PERSON_JOINTS; i++) {
        p[2 * i] = 0.1 * i, p[2 * i + 1] = 0.0;                                     /* person A: lower rail */
        p[2 * (i + MIM_PAIR_PERSON_JOINTS)] = 0.1 * i, p[2 * (i + MIM_PAIR_PERSON_JOINTS) + 1] = 0.1; /* B: upper */
    }
    mim_ic_t t;
    mim_error_t err = {0};
    assert_int_equal(mim_ic_build(p, 2, &t, &err), 0);
    assert_int_equal(t.n_edges, 65);
    for (int i = 0; i < MIM_PAIR_PERSON_JOINTS; i++) {
        assert_true(has_edge(&t, i, i + MIM_PAIR_PERSON_JOINTS)); /* rungs */
        if (i + 1 < MIM_PAIR_PERSON_JOINTS) {
            assert_true(has_edge(&t, i, i + 1));                                           /* rails */
            assert_true(has_edge(&t, i + MIM_PAIR_PERSON_JOINTS, i + 1 + MIM_PAIR_PERSON_JOINTS));
            assert_true(has_edge(&t, i, i + 1 + MIM_PAIR_PERSON_JOINTS) ^
                        has_edge(&t, i + 1, i + MIM_PAIR_PERSON_JOINTS)); /* one diagonal */
        }
    }
    /* sorted, i < j, unique */
    for (uint32_t k = 0; k < t.n_edges; k++) {
        assert_true(t.edge[k][0] < t.edge[k][1]);
        if (k) assert_true(t.edge[k - 1][0] < t.edge[k][0] || (t.edge[k - 1][0] == t.edge[k][0] && t.edge[k - 1][1] < t.edge[k][1]));
    }
}

/* 3D: a random cloud's tetrahedralisation joins each point to its nearest
 * neighbour (every Delaunay graph contains the nearest-neighbour graph),
 * has at least 3n - 6 edges, and a duplicated joint takes its twin's
 * edges and one to it. */
static void test_delaunay_3d(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 7, 1);
    double p[3 * MIM_PAIR_JOINTS];
    random_pair(&r, 3, p);
    mim_ic_t t;
    mim_error_t err = {0};
    assert_int_equal(mim_ic_build(p, 3, &t, &err), 0);
    assert_true(t.n_edges >= 3 * MIM_PAIR_JOINTS - 6 && t.n_edges <= MIM_IC_MAX_EDGES);
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
        int nn = -1;
        double best = INFINITY;
        for (int j = 0; j < MIM_PAIR_JOINTS; j++) {
            if (j == i) continue;
            double d = 0;
            for (int c = 0; c < 3; c++) d += (p[3 * i + c] - p[3 * j + c]) * (p[3 * i + c] - p[3 * j + c]);
            if (d < best) best = d, nn = j;
        }
        assert_true(has_edge(&t, i < nn ? i : nn, i < nn ? nn : i));
    }
    /* joint 20 moved onto joint 3: an edge 3-20, and 20 shares 3's others */
    memcpy(p + 3 * 20, p + 3 * 3, 3 * sizeof(double));
    assert_int_equal(mim_ic_build(p, 3, &t, &err), 0);
    assert_true(has_edge(&t, 3, 20));
    for (int j = 0; j < MIM_PAIR_JOINTS; j++)
        if (j != 3 && j != 20) assert_int_equal(has_edge(&t, j < 3 ? j : 3, j < 3 ? 3 : j), has_edge(&t, j < 20 ? j : 20, j < 20 ? 20 : j));
}

static void test_ic_bad_input(void **s)
{
    (void)s;
    double p[3 * MIM_PAIR_JOINTS];
    mim_rng_t r;
    mim_rng_seed(&r, 3, 0);
    random_pair(&r, 3, p);
    mim_ic_t t;
    mim_error_t err = {0};
    p[3 * 18 + 1] = NAN;
    assert_int_equal(mim_ic_build(p, 3, &t, &err), MIM_ENONFINITE);
    assert_non_null(strstr(err.msg, "joint 18 (chest of person B)"));
    /* every joint on one line: no triangle; qhull's reason in the message, nothing on stderr */
    double line[2 * MIM_PAIR_JOINTS];
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) line[2 * i] = 0.01 * i, line[2 * i + 1] = 0.02 * i;
    fflush(stderr);
    int saved = dup(2), devnull_pipe[2];
    assert_int_equal(pipe(devnull_pipe), 0);
    dup2(devnull_pipe[1], 2);
    mim_error_clear(&err);
    int rc = mim_ic_build(line, 2, &t, &err);
    fflush(stderr);
    dup2(saved, 2), close(saved), close(devnull_pipe[1]);
    fcntl(devnull_pipe[0], F_SETFL, O_NONBLOCK);
    char buf[64];
    ssize_t got = read(devnull_pipe[0], buf, sizeof buf);
    close(devnull_pipe[0]);
    assert_int_equal(rc, MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "span no triangle (qhull:"));
    assert_true(got <= 0); /* qhull wrote nothing to stderr */
    assert_int_equal(mim_ic_build(line, 4, &t, &err), MIM_EINVAL);
}

/* eq. 8: zero for a pair against itself, symmetric, and each edge weighed
 * by 1 / max(beta, |u|) over the sum of the weights: with every edge
 * shorter than beta (the cap) the weights are equal, and each half is the
 * plain mean of |du| over its triangulation's edges. */
static void test_dI(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 11, 0);
    double a[3 * MIM_PAIR_JOINTS], b[3 * MIM_PAIR_JOINTS];
    random_pair(&r, 3, a);
    random_pair(&r, 3, b);
    mim_ic_t ta, tb;
    mim_error_t err = {0};
    assert_int_equal(mim_ic_build(a, 3, &ta, &err), 0);
    assert_int_equal(mim_ic_build(b, 3, &tb, &err), 0);
    assert_true(mim_ic_distance(a, &ta, a, &ta, 0) == 0.0);
    double ab = mim_ic_distance(a, &ta, b, &tb, 0), ba = mim_ic_distance(b, &tb, a, &ta, 0);
    assert_true(ab > 0);
    assert_true(fabs(ab - ba) < 1e-12);
    /* shrink both so that every edge is under beta: d_I = mean |du| over ta + over tb */
    double sa[3 * MIM_PAIR_JOINTS], sb[3 * MIM_PAIR_JOINTS];
    for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) sa[i] = a[i] * 0.001, sb[i] = b[i] * 0.001;
    double want = 0;
    const mim_ic_t *ts[2] = {&ta, &tb};
    for (int h = 0; h < 2; h++) {
        double sum = 0;
        for (uint32_t k = 0; k < ts[h]->n_edges; k++) {
            int i = ts[h]->edge[k][0], j = ts[h]->edge[k][1];
            double d2 = 0;
            for (int c = 0; c < 3; c++) {
                double du = (sa[3 * j + c] - sa[3 * i + c]) - (sb[3 * j + c] - sb[3 * i + c]);
                d2 += du * du;
            }
            sum += sqrt(d2);
        }
        want += sum / ts[h]->n_edges;
    }
    assert_true(fabs(mim_ic_distance(sa, &ta, sb, &tb, 0.05) - want) < 1e-12);
    /* and a longer beta changes nothing there; a beta below the edges does */
    assert_true(fabs(mim_ic_distance(sa, &ta, sb, &tb, 0.5) - want) < 1e-12);
    assert_true(fabs(mim_ic_distance(sa, &ta, sb, &tb, 1e-6) - want) > 1e-9);
}

/* D_I, D_C, D_S: 0 for a pair against itself turned and moved; > 0
 * otherwise; the alignment is a rotation (no mirror image). */
static void test_rigid_invariance(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 5, 0);
    double a[3 * MIM_PAIR_JOINTS], b[3 * MIM_PAIR_JOINTS], moved[3 * MIM_PAIR_JOINTS], mirror[3 * MIM_PAIR_JOINTS];
    random_pair(&r, 3, a);
    random_pair(&r, 3, b);
    const double t[3] = {3.0, -1.0, 0.5};
    rotate(a, 0.3, 1.0, -0.2, 2.1, t, moved);
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        mirror[3 * i] = -a[3 * i], mirror[3 * i + 1] = a[3 * i + 1], mirror[3 * i + 2] = a[3 * i + 2];
    mim_pair_prep_t *pa = malloc(sizeof *pa), *pm = malloc(sizeof *pm), *pb = malloc(sizeof *pb), *px = malloc(sizeof *px);
    mim_error_t err = {0};
    assert_int_equal(mim_pair_prepare(a, pa, &err), 0);
    assert_int_equal(mim_pair_prepare(moved, pm, &err), 0);
    assert_int_equal(mim_pair_prepare(b, pb, &err), 0);
    assert_int_equal(mim_pair_prepare(mirror, px, &err), 0);
    for (int m = 0; m < 3; m++) {
        assert_true(mim_sample_distance(pa, pm, (mim_sample_metric_t)m) < 1e-9);
        assert_true(mim_sample_distance(pm, pa, (mim_sample_metric_t)m) < 1e-9);
        assert_true(mim_sample_distance(pa, pb, (mim_sample_metric_t)m) > 1e-3);
        assert_true(mim_sample_distance(pa, px, (mim_sample_metric_t)m) > 1e-3); /* a mirror image is another pair */
    }
    double back[3 * MIM_PAIR_JOINTS];
    mim_sample_align(a, moved, 3, back);
    for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) assert_true(fabs(back[i] - a[i]) < 1e-9);
    free(pa), free(pm), free(pb), free(px);
}

/* The sum of squared residuals of a_i ~ R b_i + t (R row-major). */
static double residual(const double *a, const double *b, const double R[9], const double t[3])
{
    double e = 0;
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int r = 0; r < 3; r++) {
            double v = t[r] - a[3 * i + r];
            for (int c = 0; c < 3; c++) v += R[3 * r + c] * b[3 * i + c];
            e += v * v;
        }
    return e;
}

/* mim_sample_rigid_fit is the least-squares rotation: a rotation (det +1,
 * also for a mirror image), exact for a turned copy at any angle (half
 * turns, where the quaternion's scalar part is 0, among them), and no
 * small turn of it (the translation fitted again) fits better; planar and
 * collinear sets, whose rotation is not unique, still fit exactly; in 2D
 * a turned copy is exact too. */
static void test_rigid_fit(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 8, 2);
    const double axes[][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 2, -3}, {-0.3, 0.1, 0.9}};
    const double angles[] = {0, 1e-9, 0.7, M_PI / 2, 3.0, M_PI};
    for (int shape = 0; shape < 3; shape++)
        for (size_t x = 0; x < sizeof axes / sizeof axes[0]; x++)
            for (size_t y = 0; y < sizeof angles / sizeof angles[0]; y++) {
                double a[3 * MIM_PAIR_JOINTS], b[3 * MIM_PAIR_JOINTS], R[9], t[3];
                random_pair(&r, 3, b);
                for (int i = 0; i < MIM_PAIR_JOINTS && shape; i++) /* 1: a plane; 2: a line */
                    b[3 * i + 2] = 0.5 * b[3 * i], b[3 * i + 1] = shape == 2 ? -b[3 * i] : b[3 * i + 1];
                const double shift[3] = {0.4, -2.0, 7.0};
                rotate(b, axes[x][0], axes[x][1], axes[x][2], angles[y], shift, a);
                mim_sample_rigid_fit(a, b, NULL, R, t);
                const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) +
                                   R[2] * (R[3] * R[7] - R[4] * R[6]);
                assert_true(fabs(det - 1) < 1e-12);
                if (residual(a, b, R, t) > 1e-20)
                    fail_msg("shape %d, axis %zu, angle %g: residual %g", shape, x, angles[y], residual(a, b, R, t));
            }
    /* 2D: the closed-form angle, at every quadrant and a half turn */
    const double turns[] = {0, 1.0, 2.5, M_PI, -2.5, -0.4};
    for (size_t y = 0; y < sizeof turns / sizeof turns[0]; y++) {
        double a[2 * MIM_PAIR_JOINTS], b[2 * MIM_PAIR_JOINTS], back[2 * MIM_PAIR_JOINTS];
        random_pair(&r, 2, b);
        const double c = cos(turns[y]), sn = sin(turns[y]);
        for (int i = 0; i < MIM_PAIR_JOINTS; i++)
            a[2 * i] = c * b[2 * i] - sn * b[2 * i + 1] + 0.7, a[2 * i + 1] = sn * b[2 * i] + c * b[2 * i + 1] - 3.0;
        mim_sample_align(a, b, 2, back);
        for (int i = 0; i < 2 * MIM_PAIR_JOINTS; i++)
            if (fabs(back[i] - a[i]) > 1e-12) fail_msg("2D, angle %g: coordinate %d off by %g", turns[y], i, back[i] - a[i]);
    }
    for (int trial = 0; trial < 50; trial++) {
        double a[3 * MIM_PAIR_JOINTS], b[3 * MIM_PAIR_JOINTS], R[9], t[3];
        random_pair(&r, 3, a), random_pair(&r, 3, b);
        if (trial % 5 == 0) /* b a mirror image of a, noisy */
            for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) b[i] = (i % 3 ? a[i] : -a[i]) + 0.05 * mim_rng_gauss(&r);
        mim_sample_rigid_fit(a, b, NULL, R, t);
        const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) + R[2] * (R[3] * R[7] - R[4] * R[6]);
        assert_true(fabs(det - 1) < 1e-12);
        const double best = residual(a, b, R, t);
        for (int k = 0; k < 20; k++) {
            /* R turned a little about a random axis; t fitted again (centroids matched) */
            mim_quat q = mim_quat_axis_angle(mim_v3_normalize(mim_v3(mim_rng_gauss(&r), mim_rng_gauss(&r), mim_rng_gauss(&r))), 1e-3);
            double R2[9], t2[3], ca[3] = {0, 0, 0}, cb[3] = {0, 0, 0};
            for (int c = 0; c < 3; c++) {
                const mim_vec3 col = mim_quat_rotate(q, mim_v3(R[c], R[3 + c], R[6 + c]));
                R2[c] = col.x, R2[3 + c] = col.y, R2[6 + c] = col.z;
            }
            for (int i = 0; i < MIM_PAIR_JOINTS; i++)
                for (int c = 0; c < 3; c++) ca[c] += a[3 * i + c] / MIM_PAIR_JOINTS, cb[c] += b[3 * i + c] / MIM_PAIR_JOINTS;
            for (int c = 0; c < 3; c++) t2[c] = ca[c] - (R2[3 * c] * cb[0] + R2[3 * c + 1] * cb[1] + R2[3 * c + 2] * cb[2]);
            if (residual(a, b, R2, t2) < best * (1 - 1e-12)) fail_msg("trial %d: a turned fit is better: %.17g < %.17g", trial, residual(a, b, R2, t2), best);
        }
    }
}

/* eq. 13: C(G, G) = 0; adding samples never raises C; errors. */
static void test_coverage(void **s)
{
    (void)s;
    enum { M = 12, K = 20 };
    mim_rng_t r;
    mim_rng_seed(&r, 9, 0);
    mim_pair_prep_t *g = malloc(M * sizeof *g), *smp = malloc(K * sizeof *smp);
    mim_error_t err = {0};
    double p[3 * MIM_PAIR_JOINTS];
    for (int i = 0; i < M; i++) random_pair(&r, 3, p), assert_int_equal(mim_pair_prepare(p, &g[i], &err), 0);
    for (int i = 0; i < K; i++) random_pair(&r, 3, p), assert_int_equal(mim_pair_prepare(p, &smp[i], &err), 0);
    for (int m = 0; m < 3; m++) {
        double prev = INFINITY;
        mim_sample_coverage_t c = {0};
        assert_int_equal(mim_sample_coverage(g, M, g, M, (mim_sample_metric_t)m, NULL, &c, &err), 0);
        assert_true(c.coverage < 1e-9);
        for (uint32_t k = 1; k <= K; k++) {
            assert_int_equal(mim_sample_coverage(g, M, smp, k, (mim_sample_metric_t)m, NULL, &c, &err), 0);
            assert_true(c.coverage > 0 && c.coverage <= prev + 1e-15);
            prev = c.coverage;
        }
    }
    mim_sample_coverage_t c = {0};
    assert_int_equal(mim_sample_coverage(g, M, smp, 0, MIM_METRIC_IC, NULL, &c, &err), MIM_EINVAL);
    free(g), free(smp);
}

/* Joint names of known schemes (as the files spell them) and a user's map. */
static int load_names(const char *list, char (*names)[64])
{
    int n = 0;
    char buf[2048];
    snprintf(buf, sizeof buf, "%s", list);
    for (char *save = NULL, *t = strtok_r(buf, " ", &save); t; t = strtok_r(NULL, " ", &save))
        snprintf(names[n++], 64, "%s", t);
    return n;
}

static void test_joint_map(void **s)
{
    (void)s;
    char names[64][64];
    int32_t idx[MIM_PAIR_PERSON_JOINTS];
    const char *scheme = NULL;
    mim_error_t err = {0};
    /* CMU's BVH conversion (cmu-pairs) */
    int n = load_names("Hips LHipJoint LeftUpLeg LeftLeg LeftFoot LeftToeBase RHipJoint RightUpLeg RightLeg RightFoot "
                       "RightToeBase LowerBack Spine Spine1 Neck Neck1 Head LeftShoulder LeftArm LeftForeArm LeftHand "
                       "RightShoulder RightArm RightForeArm RightHand",
                       names);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, NULL, "a.bvh", idx, &scheme, &err), 0);
    assert_string_equal(scheme, "CMU/Biovision");
    assert_string_equal(names[idx[0]], "Head");
    assert_string_equal(names[idx[3]], "LeftArm");     /* l_shoulder: where the upper arm starts */
    assert_string_equal(names[idx[14]], "RightFoot");  /* r_ankle */
    assert_string_equal(names[idx[16]], "Neck");       /* neck */
    /* ASF (CMU's skeletons) */
    n = load_names("root lhipjoint lfemur ltibia lfoot ltoes rhipjoint rfemur rtibia rfoot rtoes lowerback upperback "
                   "thorax lowerneck upperneck head lclavicle lhumerus lradius lwrist lhand rclavicle rhumerus rradius "
                   "rwrist rhand",
                   names);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, NULL, "a.asf", idx, &scheme, &err), 0);
    assert_string_equal(scheme, "ASF");
    assert_string_equal(names[idx[9]], "lfemur");
    /* MakeHuman, in another case */
    n = load_names("ROOT spine05 spine04 spine03 spine02 spine01 neck01 head upperleg01.L lowerleg01.L foot.L "
                   "upperleg01.R lowerleg01.R foot.R upperarm01.L lowerarm01.L wrist.L upperarm01.R lowerarm01.R wrist.R",
                   names);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, NULL, "m.bvh", idx, &scheme, &err), 0);
    assert_string_equal(scheme, "MakeHuman");
    assert_string_equal(names[idx[2]], "ROOT");
    /* the short lower-case scheme */
    n = load_names("root lhip lknee lankle rhip rknee rankle spine chest lowerneck head lshoulder lelbow lwrist "
                   "rshoulder relbow rwrist",
                   names);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, NULL, "s.bvh", idx, &scheme, &err), 0);
    assert_string_equal(scheme, "short lower-case");
    /* one missing: the nearest scheme and the joint, in one line */
    n = load_names("Hips LeftUpLeg LeftLeg LeftFoot RightUpLeg RightLeg RightFoot Spine Spine1 Neck Head LeftArm "
                   "LeftForeArm RightArm RightForeArm RightHand",
                   names);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, NULL, "b.bvh", idx, &scheme, &err),
                     MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "b.bvh: joints not recognised: closest to the CMU/Biovision scheme, but no LeftHand joint (l_wrist)"));
    assert_non_null(strstr(err.msg, "--joint-map"));
    /* a user's map for any naming */
    n = load_names("J0 J1 J2 J3 J4 J5 J6 J7 J8 J9 J10 J11 J12 J13 J14 J15 J16 J17", names);
    char map[1024] = "{";
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++)
        snprintf(map + strlen(map), sizeof map - strlen(map), "%s\"%s\": \"j%d\"", k ? ", " : "", mim_sample_joint_names[k],
                 16 - k);
    strcat(map, "}");
    mim_error_clear(&err);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, map, "c.bvh", idx, &scheme, &err), 0);
    assert_string_equal(scheme, "joint map");
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++) assert_int_equal(idx[k], 16 - k);
    mim_error_clear(&err);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, "{\"head\": \"J0\",\n  oops}", "c.bvh", idx,
                                        &scheme, &err),
                     MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "joint map:2:"));
    mim_error_clear(&err);
    assert_int_equal(mim_pair_joint_map((const char(*)[64])names, (uint32_t)n, "{\"head\": \"J0\"}", "c.bvh", idx,
                                        &scheme, &err),
                     MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "no \"chest\""));
}

static void test_unit_guess(void **s)
{
    (void)s;
    double m;
    const char *name;
    assert_int_equal(mim_pair_unit_guess(1.45, &m, &name), 0);
    assert_true(m == 1.0);
    assert_int_equal(mim_pair_unit_guess(25.7, &m, &name), 0); /* a CMU subject in its BVH */
    assert_true(fabs(m - 0.0254 / 0.45) < 1e-12);
    assert_non_null(strstr(name, "CMU"));
    assert_int_equal(mim_pair_unit_guess(145.0, &m, &name), 0);
    assert_true(m == 0.01);
    assert_int_equal(mim_pair_unit_guess(1450.0, &m, &name), 0);
    assert_true(m == 0.001);
    assert_int_equal(mim_pair_unit_guess(57.0, &m, &name), 0);
    assert_true(m == 0.0254);
    assert_int_equal(mim_pair_unit_guess(5.0, &m, &name), MIM_ENOTFOUND);
    assert_int_equal(mim_pair_unit_guess(NAN, &m, &name), MIM_ENOTFOUND);
}

/* Samples as JSON lines: a round trip, and each malformed file refused in
 * one line naming the line. */
static void test_samples_file(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 4, 0);
    double p[2][3 * MIM_PAIR_JOINTS];
    random_pair(&r, 3, p[0]);
    random_pair(&r, 3, p[1]);
    char *h = mim_pairs_jsonl_header(), *l0 = mim_pairs_jsonl_line(p[0], -12.5), *l1 = mim_pairs_jsonl_line(p[1], NAN);
    assert_non_null(h), assert_non_null(l0), assert_non_null(l1);
    assert_null(strchr(l0, '\n'));
    size_t cap = strlen(h) + strlen(l0) + strlen(l1) + 16;
    char *text = malloc(cap);
    snprintf(text, cap, "%s\r\n%s\n\n%s\n", h, l0, l1);
    mim_pairs_samples_t smp;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_samples_parse(text, strlen(text), "s.jsonl", &smp, &err), 0);
    assert_int_equal(smp.n, 2);
    for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) {
        assert_true(fabs(smp.joints[i] - p[0][i]) < 1e-8);
        assert_true(fabs(smp.joints[3 * MIM_PAIR_JOINTS + i] - p[1][i]) < 1e-8);
    }
    assert_true(smp.log_density[0] == -12.5);
    assert_true(isnan(smp.log_density[1]));
    mim_pairs_samples_free(&smp);
    struct { const char *text; int code; const char *phrase; } bad[] = {
        {"", MIM_EEMPTY, "s.jsonl: empty"},
        {"{\"format\": \"something else\"}\n", MIM_EFORMAT, "s.jsonl:1: not a mimic pair-samples file"},
        {"not json\n", MIM_EFORMAT, "s.jsonl:1:"},
        {NULL, MIM_EEMPTY, "no samples after the header"},                 /* header alone */
        {"L{\"joints\": [[0, 0, 0]]}", MIM_EFORMAT, "s.jsonl:2: \"joints\" must hold 34"},
        {"L{\"joints\": [[0, 0, NaN]]}", MIM_EFORMAT, "s.jsonl:2:"},
        {"X1e999", MIM_EFORMAT, "s.jsonl:2:"},
        {"X5000", MIM_ENONFINITE, "s.jsonl:2: joint 0: coordinate 5000 is not within 1000 m"},
        {"X\"a\"", MIM_EFORMAT, "joint 0: a coordinate is not a number"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof *bad; k++) {
        char buf[8192];
        if (!bad[k].text) snprintf(buf, sizeof buf, "%s\n", h);
        else if (bad[k].text[0] == 'L') snprintf(buf, sizeof buf, "%s\n%s\n", h, bad[k].text + 1);
        else if (bad[k].text[0] == 'X') { /* a full line with the first coordinate replaced */
            const char *rest = strchr(l0 + 12, ',');
            snprintf(buf, sizeof buf, "%s\n{\"joints\":[[%s%s\n", h, bad[k].text + 1, rest);
        } else snprintf(buf, sizeof buf, "%s", bad[k].text);
        mim_error_clear(&err);
        int rc = mim_pairs_samples_parse(buf, strlen(buf), "s.jsonl", &smp, &err);
        if (rc != bad[k].code || !strstr(err.msg, bad[k].phrase))
            fail_msg("case %zu: %d '%s' (wanted %d '%s')", k, rc, err.msg, bad[k].code, bad[k].phrase);
        assert_int_equal(smp.n, 0);
        assert_null(strchr(err.msg, '\n'));
    }
    free(h), free(l0), free(l1), free(text);
}

/* A samples line: joint 0's three coordinates as given, the others
 * fixed; pre/post wrap "joints": [...] (keys, spaces). */
static void samples_line(char *buf, size_t cap, const char *pre, const char *xyz, const char *post)
{
    int n = snprintf(buf, cap, "%s[[%s]", pre, xyz);
    for (int i = 1; i < MIM_PAIR_JOINTS; i++) n += snprintf(buf + n, cap - (size_t)n, ", [%d.25, -0.5, 1e-1]", i % 7);
    snprintf(buf + n, cap - (size_t)n, "]%s", post);
}

/* jansson's reading of a line (what the fast path must match): joints and
 * log density, or -1 when it refuses it. */
static int jansson_line(const char *line, double *joints, double *ld)
{
    json_error_t je;
    json_t *o = json_loads(line, JSON_REJECT_DUPLICATES, &je), *arr = json_object_get(o, "joints");
    if (!o || json_array_size(arr) != MIM_PAIR_JOINTS) return json_decref(o), -1;
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int k = 0; k < 3; k++) joints[3 * i + k] = json_number_value(json_array_get(json_array_get(arr, (size_t)i), (size_t)k));
    json_t *l = json_object_get(o, "log_density");
    *ld = json_is_number(l) ? json_number_value(l) : NAN;
    json_decref(o);
    return 0;
}

/* The samples reader's fast path (no JSON tree) takes mimic's own lines
 * and their JSON variants (spaces, keys in either order, integers, -0,
 * exponents, null or no log density), each value bit for bit jansson's;
 * it hands anything else to jansson (another key, an escaped key, a
 * repeated key, a leading zero, a bare point, a 16-digit integer, an
 * overflowing number, trailing bytes, a NUL), which reads it or names
 * what is wrong as before. */
static void test_samples_fast_lines(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 8, 0);
    double p[3 * MIM_PAIR_JOINTS];
    random_pair(&r, 3, p);
    char *own = mim_pairs_jsonl_line(p, -3.75);
    /* refused: the phrase of the reader's one-line message after "s.jsonl:2" */
    struct { const char *pre, *xyz, *post; int fast; const char *refused; } cases[] = {
        {"{\"joints\":", "0.1,0.2,0.3", ",\"log_density\":-1.5}", 1, NULL},
        {" { \"log_density\" : null , \"joints\" :\t", " 1 , -0 , 2E2 ", " }\r", 1, NULL},
        {"{\"joints\": ", "-0.0, 1.5e-3, 0", "}", 1, NULL},
        {"{\"log_density\": 12, \"joints\": ", "999.999999999, -1000, 3", "}", 1, NULL},
        {"{\"joints\": ", "0.1, 0.2, 0.3", ", \"extra\": [1, {}]}", 0, NULL},
        {"{\"\\u006aoints\": ", "0.1, 0.2, 0.3", "}", 0, NULL},
        {"{\"joints\": ", "0.1, 0.2, 0.3", ", \"log_density\": 1e999}", 0, "real number overflow"},
        {"{\"joints\": ", "01, 0.2, 0.3", "}", 0, "invalid token near '0'"},
        {"{\"joints\": ", "1., 0.2, 0.3", "}", 0, "invalid token near '1.'"},
        {"{\"joints\": ", "1234567890123456, 0.2, 0.3", "}", 0, "joint 0: coordinate 1.23457e+15 is not within 1000 m"},
        {"{\"joints\": ", "0.1, 0.2, 0.3", "} x", 0, "end of file expected"},
        {"{\"joints\": [[0,0,0]], \"joints\": ", "0.1, 0.2, 0.3", "}", 0, "duplicate object key"},
    };
    char line[4096];
    double got[3 * MIM_PAIR_JOINTS], want[3 * MIM_PAIR_JOINTS], ld_got, ld_want;
    assert_int_equal(mim__pairs_line_fast(own, strlen(own), got, &ld_got), 1);
    assert_int_equal(jansson_line(own, want, &ld_want), 0);
    assert_memory_equal(got, want, sizeof got);
    assert_true(ld_got == ld_want);
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        samples_line(line, sizeof line, cases[k].pre, cases[k].xyz, cases[k].post);
        const int fast = mim__pairs_line_fast(line, strlen(line), got, &ld_got);
        if (fast != cases[k].fast) fail_msg("case %zu: fast path %d, wanted %d: %.80s", k, fast, cases[k].fast, line);
        /* through the reader: as jansson reads it, or refused */
        char *h = mim_pairs_jsonl_header(), text[8192];
        snprintf(text, sizeof text, "%s\n%s\n", h, line);
        free(h);
        mim_pairs_samples_t smp;
        mim_error_t err = {0};
        const int rc = mim_pairs_samples_parse(text, strlen(text), "s.jsonl", &smp, &err);
        const int ok = jansson_line(line, want, &ld_want) == 0 && fabs(want[0]) <= MIM_PLAUSIBLE_REACH_M;
        if (ok != (rc == 0)) fail_msg("case %zu: reader %d '%s', jansson %s", k, rc, err.msg, ok ? "reads it" : "refuses");
        if (ok != !cases[k].refused) fail_msg("case %zu: jansson %s it, the case says otherwise", k, ok ? "reads" : "refuses");
        if (!rc) {
            assert_memory_equal(smp.joints, want, sizeof want); /* bits: -0 read as jansson's integer 0 */
            assert_true(smp.log_density[0] == ld_want || (isnan(smp.log_density[0]) && isnan(ld_want)));
            if (fast) assert_memory_equal(got, want, sizeof want);
            mim_pairs_samples_free(&smp);
        } else if (strncmp(err.msg, "s.jsonl:2", 9) || !strstr(err.msg, cases[k].refused) || strchr(err.msg, '\n')) {
            fail_msg("case %zu: '%s' (wanted s.jsonl:2 ... %s)", k, err.msg, cases[k].refused);
        }
    }
    /* a NUL inside the line: jansson's to refuse */
    samples_line(line, sizeof line, "{\"joints\": ", "0.1, 0.2, 0.3", "}");
    const size_t len = strlen(line);
    line[5] = '\0';
    assert_int_equal(mim__pairs_line_fast(line, len, got, &ld_got), 0);
    free(own);
}

/* ODE's capsule depth: two crossing capsules overlap by the sum of their
 * radii less the distance between their axes; a pose-pair standing apart
 * has none; closer, more. */
static void person_t_pose(double *p, double dx, double dz)
{
    static const double j[MIM_PAIR_PERSON_JOINTS][3] = {
        {0, 1.7, 0},     {0, 1.4, 0},     {0, 1.0, 0},    {0.2, 1.45, 0},  {-0.2, 1.45, 0}, {0.5, 1.45, 0},
        {-0.5, 1.45, 0}, {0.75, 1.45, 0}, {-0.75, 1.45, 0}, {0.1, 0.95, 0}, {-0.1, 0.95, 0}, {0.1, 0.5, 0},
        {-0.1, 0.5, 0},  {0.1, 0.08, 0},  {-0.1, 0.08, 0}, {0, 1.2, 0},     {0, 1.55, 0}};
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++)
        p[3 * k] = j[k][0] + dx, p[3 * k + 1] = j[k][1], p[3 * k + 2] = j[k][2] + dz;
}

static void test_penetration(void **s)
{
    (void)s;
    assert_true(dInitODE2(0));
    mim_penetration_t *p = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_penetration_open(&p, &err), 0);
    const double a0[3] = {-1, 0, 0}, a1[3] = {1, 0, 0};
    for (int k = 0; k < 5; k++) {
        double d = 0.05 * k, b0[3] = {0, d, -1}, b1[3] = {0, d, 1};
        double got = mim_penetration_capsules(p, a0, a1, 0.1, b0, b1, 0.08);
        double want = 0.18 - d > 0 ? 0.18 - d : 0.0;
        if (fabs(got - want) > 1e-6) fail_msg("axes %.2f apart: depth %g, want %g", d, got, want);
    }
    double pair[3 * MIM_PAIR_JOINTS];
    person_t_pose(pair, 0, 0);
    person_t_pose(pair + 3 * MIM_PAIR_PERSON_JOINTS, 2.5, 0);
    assert_true(mim_penetration_pair(p, pair, NULL) < 1e-9); /* apart, and no bone of one person in another of his */
    double prev = 0;
    for (int k = 3; k >= 0; k--) { /* B steps in front of A: 0.3, 0.2, 0.1, 0 m */
        person_t_pose(pair + 3 * MIM_PAIR_PERSON_JOINTS, 0, 0.1 * k);
        double eta = mim_penetration_pair(p, pair, NULL);
        if (k == 3) assert_true(eta < 1e-9); /* 0.3 m: the torsos (0.12 + 0.12) clear */
        else assert_true(eta > prev);
        prev = eta;
    }
    mim_penetration_close(&p);
    assert_null(p);
    dCloseODE();
}

/* eqs. 3-5: the local frame of two people side by side, views as angles
 * and back, invariant under a rigid motion of pair and camera together,
 * and draws from the view density that match it (chi-squared). */
static void test_views(void **s)
{
    (void)s;
    double pair[3 * MIM_PAIR_JOINTS], R[9];
    person_t_pose(pair, 0, 0);
    person_t_pose(pair + 3 * MIM_PAIR_PERSON_JOINTS, 2.0, 0);
    assert_int_equal(mim_pairs_local_frame(pair, R), 0);
    const double want[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}; /* i = +x (A to B), j = +y (backbones), k = +z */
    for (int k = 0; k < 9; k++) assert_true(fabs(R[k] - want[k]) < 1e-12);
    double psi, phi;
    const double front[3] = {0, 0, 1}, side[3] = {1, 0, 0}, up[3] = {0, 1, 0};
    mim_pairs_view_angles(R, front, &psi, &phi);
    assert_true(fabs(psi - M_PI / 2) < 1e-12 && fabs(phi - M_PI / 2) < 1e-12);
    mim_pairs_view_angles(R, side, &psi, &phi);
    assert_true(fabs(psi) < 1e-12 && fabs(phi - M_PI / 2) < 1e-12);
    mim_pairs_view_angles(R, up, &psi, &phi);
    assert_true(fabs(phi) < 1e-12);
    /* turn pair and camera together: the same view */
    double moved[3 * MIM_PAIR_JOINTS], R2[9], dir[3], dir2[3];
    const double t[3] = {1, 2, 3};
    rotate(pair, 0.2, 1, 0.1, 1.1, t, moved);
    assert_int_equal(mim_pairs_local_frame(moved, R2), 0);
    mim_rng_t r;
    mim_rng_seed(&r, 21, 0);
    mim_quat q = mim_quat_axis_angle(mim_v3_normalize(mim_v3(0.2, 1, 0.1)), 1.1);
    for (int n = 0; n < 100; n++) {
        double p0 = (mim_rng_unit(&r) * 2 - 1) * M_PI * 0.999, f0 = 0.01 + mim_rng_unit(&r) * (M_PI - 0.02), p1, f1;
        mim_pairs_view_direction(R, p0, f0, dir);
        mim_pairs_view_angles(R, dir, &p1, &f1);
        assert_true(fabs(p1 - p0) < 1e-9 && fabs(f1 - f0) < 1e-9); /* round trip */
        mim_vec3 d2 = mim_quat_rotate(q, mim_v3(dir[0], dir[1], dir[2]));
        dir2[0] = d2.x, dir2[1] = d2.y, dir2[2] = d2.z;
        mim_pairs_view_angles(R2, dir2, &p1, &f1);
        assert_true(fabs(p1 - p0) < 1e-9 && fabs(f1 - f0) < 1e-9); /* rigid invariance */
    }
    /* no frame when the roots coincide */
    double same[3 * MIM_PAIR_JOINTS];
    person_t_pose(same, 0, 0);
    person_t_pose(same + 3 * MIM_PAIR_PERSON_JOINTS, 0, 0);
    assert_int_equal(mim_pairs_local_frame(same, R), MIM_EINVAL);
    /* draws against the density: 8 x 8 cells around two views, chi-squared */
    const double views[4] = {0.4, 1.4, -0.6, 1.8};
    const double sg = 0.25;
    enum { N = 40000, C = 8 };
    double counts[C][C] = {{0}};
    double p0 = -1.6, p1 = 1.4, f0 = 0.6, f1 = 2.6; /* the cells cover most of the mass */
    int inside = 0;
    for (int n = 0; n < N; n++) {
        mim_pairs_view_draw(views, 2, sg, &r, &psi, &phi);
        int a = (int)floor((psi - p0) / (p1 - p0) * C), b = (int)floor((phi - f0) / (f1 - f0) * C);
        if (a >= 0 && a < C && b >= 0 && b < C) counts[a][b]++, inside++;
    }
    double chi2 = 0;
    int cells = 0;
    for (int a = 0; a < C; a++)
        for (int b = 0; b < C; b++) {
            /* expected: the density integrated over the cell (midpoint rule on a 6 x 6 grid) */
            double e = 0, ca = (p1 - p0) / C, cb = (f1 - f0) / C;
            for (int u = 0; u < 6; u++)
                for (int v = 0; v < 6; v++)
                    e += mim_pairs_view_density(views, 2, sg, p0 + ca * (a + (u + 0.5) / 6), f0 + cb * (b + (v + 0.5) / 6)) *
                         ca * cb / 36;
            e *= N;
            if (e < 20) continue;
            chi2 += (counts[a][b] - e) * (counts[a][b] - e) / e;
            cells++;
        }
    print_message("view KDE: chi-squared %.1f over %d cells (%d of %d draws inside)\n", chi2, cells, inside, N);
    assert_true(cells > 20);
    assert_true(chi2 < 2.0 * cells); /* a wrong bandwidth or mean is far above */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_delaunay_ladder), cmocka_unit_test(test_delaunay_3d), cmocka_unit_test(test_ic_bad_input),
        cmocka_unit_test(test_dI),              cmocka_unit_test(test_rigid_invariance), cmocka_unit_test(test_rigid_fit),
        cmocka_unit_test(test_coverage),
        cmocka_unit_test(test_joint_map), cmocka_unit_test(test_unit_guess),
        cmocka_unit_test(test_samples_file), cmocka_unit_test(test_samples_fast_lines), cmocka_unit_test(test_penetration),
        cmocka_unit_test(test_views),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
