/* Coverage (seed 002, eq. 13) without computing every distance: the lower
 * bounds of D_C, D_I, D_S and LIMBS (sample/coverage_bounds.c) never exceed the
 * distance, and the pruned, threaded search gives the exhaustive scan's
 * answers to the bit (each truth's nearest distance and sample, and C) on
 * random sets with repeats, ties and degenerate pairs. */
#include "internal.h"

#include "synthetic_pairs.h"
#include "test_support.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define J MIM_PAIR_JOINTS

/* p turned about its centroid by angle about axis (x, y, z), scaled by s,
 * then moved by t. */
static void move(double *p, double x, double y, double z, double angle, double s, const double t[3])
{
    double c[3] = {0, 0, 0};
    for (int i = 0; i < J; i++)
        for (int k = 0; k < 3; k++) c[k] += p[3 * i + k] / J;
    mim_quat q = mim_quat_axis_angle(mim_v3_normalize(mim_v3(x, y, z)), angle);
    for (int i = 0; i < J; i++) {
        mim_vec3 v = mim_quat_rotate(q, mim_v3(p[3 * i] - c[0], p[3 * i + 1] - c[1], p[3 * i + 2] - c[2]));
        p[3 * i] = c[0] + s * v.x + t[0], p[3 * i + 1] = c[1] + s * v.y + t[1], p[3 * i + 2] = c[2] + s * v.z + t[2];
    }
}

/* m truths and k samples. Truths: random pairs, every third a small step
 * from the one before (as a take's frames), some far from the origin or
 * small. Samples by index mod 10: 0 a repeat of an earlier sample, 1 a
 * truth itself (several copies of one truth tie at 0), 2 a truth moved
 * rigidly, 3 a truth scaled (D_S nearly 0, D_C not), 4 two joints at one
 * place (merged by the triangulation, as CMU's hips), 5 a flat pair (qhull
 * joggles it), 6 a pair 500 m away, else random. */
static void make_sets(uint64_t seed, uint32_t m, uint32_t k, mim_pair_prep_t **g, mim_pair_prep_t **s)
{
    mim_rng_t r;
    mim_rng_seed(&r, seed, 31);
    double *tj = malloc((size_t)m * 3 * J * sizeof *tj), *sj = malloc((size_t)k * 3 * J * sizeof *sj);
    assert_non_null(tj), assert_non_null(sj);
    for (uint32_t i = 0; i < m; i++) {
        double *p = tj + (size_t)i * 3 * J;
        if (i % 3 == 1) {
            memcpy(p, p - 3 * J, 3 * J * sizeof *p);
            const double t[3] = {0.01, 0, -0.02};
            move(p, mim_rng_gauss(&r), mim_rng_gauss(&r), mim_rng_gauss(&r), 0.05, 1.0, t);
            continue;
        }
        sp_random_pair(&r, 0.8, p);
        const double far[3] = {-200, 3, 700}, none[3] = {0, 0, 0};
        if (i % 11 == 5) move(p, 0, 1, 0, 2.0, 1.0, far);
        if (i % 13 == 7) move(p, 1, 0, 0, 0.3, 0.01, none);
    }
    for (uint32_t j = 0; j < k; j++) {
        double *p = sj + (size_t)j * 3 * J;
        const double *truth = tj + (size_t)mim_rng_below(&r, m) * 3 * J;
        const double shift[3] = {mim_rng_gauss(&r), mim_rng_gauss(&r), mim_rng_gauss(&r)}, none[3] = {0, 0, 0};
        switch (j % 10) {
        case 0:
            if (j) {
                memcpy(p, sj + (size_t)mim_rng_below(&r, j) * 3 * J, 3 * J * sizeof *p);
                break;
            }
            /* fall through */
        case 1: memcpy(p, truth, 3 * J * sizeof *p); break;
        case 2: memcpy(p, truth, 3 * J * sizeof *p), move(p, shift[0], shift[1], shift[2], 1.0, 1.0, shift); break;
        case 3: memcpy(p, truth, 3 * J * sizeof *p), move(p, 0, 1, 0, 0.0, 1.3, none); break;
        case 4: { /* two joints at one place, two 3e-25 m apart (their squares not floats) */
            const double near[6] = {1e-24, 2e-24, -1e-24, 1.1e-24, 1.7e-24, -1e-24};
            sp_random_pair(&r, 0.8, p), memcpy(p + 3 * 20, p + 3 * 3, 3 * sizeof *p);
            memcpy(p + 3 * 4, near, 3 * sizeof *p), memcpy(p + 3 * 21, near + 3, 3 * sizeof *p);
            break;
        }
        case 5:
            sp_random_pair(&r, 0.8, p);
            for (int i = 0; i < J; i++) p[3 * i + 2] = 0.3;
            break;
        case 6: {
            const double far[3] = {500, -20, 300};
            sp_random_pair(&r, 0.8, p), move(p, 0, 1, 0, 1.0, 1.0, far);
            break;
        }
        default: sp_random_pair(&r, 0.8, p);
        }
    }
    *g = malloc((size_t)m * sizeof **g), *s = malloc((size_t)k * sizeof **s);
    assert_non_null(*g), assert_non_null(*s);
    mim_error_t err = {0};
    assert_int_equal(mim_pair_prepare_many(tj, m, 2, MIM_PREP_ALL, *g, NULL, &err), 0);
    assert_int_equal(mim_pair_prepare_many(sj, k, 2, MIM_PREP_ALL, *s, NULL, &err), 0);
    free(tj), free(sj);
}

/* Samples the first bounds cannot tell apart: for each of m truths, 40
 * mirror images turned at random (every joint distance the truth's: first
 * bounds near 0, distances far), then one copy with each joint moved by a
 * centimetre or so (its nearest), found past the seeds, in index order. */
static mim_pair_prep_t *mirrored_samples(uint64_t seed, const mim_pair_prep_t *g, uint32_t m, uint32_t *k)
{
    enum { MIRRORS = 40 };
    mim_rng_t r;
    mim_rng_seed(&r, seed, 37);
    *k = m * (MIRRORS + 1);
    double *sj = malloc((size_t)*k * 3 * J * sizeof *sj);
    assert_non_null(sj);
    for (uint32_t i = 0; i < m; i++) {
        double *p = sj + (size_t)i * (MIRRORS + 1) * 3 * J;
        for (int c = 0; c < MIRRORS; c++, p += 3 * J) {
            memcpy(p, g[i].joints, 3 * J * sizeof *p);
            for (int j = 0; j < J; j++) p[3 * j] = -p[3 * j];
            const double none[3] = {0, 0, 0};
            move(p, mim_rng_gauss(&r), mim_rng_gauss(&r), mim_rng_gauss(&r), 3.0 * mim_rng_unit(&r), 1.0, none);
        }
        memcpy(p, g[i].joints, 3 * J * sizeof *p);
        for (int j = 0; j < 3 * J; j++) p[j] += 0.01 * mim_rng_gauss(&r);
    }
    mim_pair_prep_t *s = malloc((size_t)*k * sizeof *s);
    assert_non_null(s);
    mim_error_t err = {0};
    assert_int_equal(mim_pair_prepare_many(sj, *k, 2, MIM_PREP_ALL, s, NULL, &err), 0);
    free(sj);
    return s;
}

/* The histograms' sums made directly from the joints are the sums of the
 * histograms, to their float rounding (the first bound's premise). */
static void test_marginals(void **state)
{
    (void)state;
    enum { M = 10, K = 60 };
    mim_pair_prep_t *g, *s;
    make_sets(5, M, K, &g, &s);
    for (uint32_t j = 0; j < K; j++) {
        float fr[MIM__JOINT_PAIRS];
        double rad_h[J * MIM__SC_R], rad[J * MIM__SC_R];
        mim__sc_histogram_marginals(s[j].sc, rad_h);
        mim__sc_pair_radii(s[j].joints, fr);
        mim__sc_radial(fr, rad);
        for (int b = 0; b < J * MIM__SC_R; b++)
            if (fabs(rad[b] - rad_h[b]) > 1e-5) fail_msg("sample %u, radial bin %d: %.9g, histogram %.9g", j, b, rad[b], rad_h[b]);
    }
    free(g), free(s);
}

/* Every bound at or below the distance it bounds, for every pair of a set
 * (the degenerate ones among them). */
static void test_bounds_below_distances(void **state)
{
    (void)state;
    enum { M = 40, K = 300 };
    mim_pair_prep_t *g, *s;
    make_sets(1, M, K, &g, &s);
    for (int metric = 0; metric < 4; metric++) {
        const mim_sample_metric_t mt = (mim_sample_metric_t)metric;
        const uint32_t stride = mim__bound_stride(mt);
        const uint32_t dim = mim__bound_dim(mt), T = MIM__BOUND_TRUTHS;
        float *fb = malloc((size_t)K * stride * sizeof *fb), *fa = malloc(T * stride * sizeof *fa);
        float *lbs = malloc((size_t)T * K * sizeof *lbs);
        assert_non_null(fb), assert_non_null(fa), assert_non_null(lbs);
        double slack_b = 0;
        mim__shape_truth_t ta;
        for (uint32_t j = 0; j < K; j++) {
            mim__bound_features(mt, &s[j], 0, fb + (size_t)j * stride);
            slack_b = fmax(slack_b, mim__bound_slack(mt, &s[j]));
        }
        double ratio = 0, ratio2 = 0, slacks[MIM__BOUND_TRUTHS];
        for (uint32_t i = 0; i < M; i++) {
            /* the first bounds of T truths at once, as coverage makes them */
            if (i % T == 0) {
                for (uint32_t t = 0; t < T && i + t < M; t++) {
                    slacks[t] = mim__bound_slack(mt, &g[i + t]) + slack_b;
                    mim__bound_features(mt, &g[i + t], 1, fa + (size_t)t * dim);
                }
                mim__bound_lower(mt, fa, M - i < T ? M - i : T, fb, K, slacks, lbs);
            }
            const double slack = slacks[i % T];
            const float *lb = lbs + (size_t)(i % T) * K;
            mim__shape_truth(&g[i], &ta);
            mim__centred_t ga;
            mim__align_centre(g[i].joints, &ga);
            for (uint32_t j = 0; j < K; j++) {
                const double d = mim_sample_distance(&g[i], &s[j], mt);
                if (!(lb[j] <= d)) fail_msg("metric %d, truth %u, sample %u: bound %.17g above %.17g", metric, i, j, lb[j], d);
                ratio += d > 0 ? fmax(lb[j], 0) / d / (M * K) : 0;
                if (mt != MIM_METRIC_SHAPE) continue;
                /* the aligned bound after one joint (any best below it
                 * returns it), bounds part-way (best just below d) and the
                 * distance itself */
                const float *f = fb + (size_t)j * stride;
                mim__centred_t sb;
                mim__align_centre(s[j].joints, &sb);
                double bb[3 * MIM_PAIR_JOINTS];
                mim__align_centred(&ga, sb.p, bb);
                int exact;
                const double lb2 = mim__shape_distance_aligned(&g[i], &ta, bb, f, slack, -1.0, &exact);
                if (exact || !(lb2 <= d)) fail_msg("D_S, truth %u, sample %u: aligned bound %.17g above %.17g", i, j, lb2, d);
                ratio2 += d > 0 ? fmax(lb2, 0) / d / (M * K) : 0;
                const double part =
                    mim__shape_distance_aligned(&g[i], &ta, bb, f, slack, lb2 + 0.9 * (d - lb2), &exact);
                if (!(part <= d)) fail_msg("D_S, truth %u, sample %u: bound part-way %.17g above %.17g", i, j, part, d);
                const double whole = mim__shape_distance_aligned(&g[i], &ta, bb, f, slack, INFINITY, &exact);
                if (!exact || memcmp(&whole, &d, sizeof d)) fail_msg("D_S, truth %u, sample %u: %.17g, not %.17g", i, j, whole, d);
            }
        }
        /* and they bound something */
        print_message("metric %d: bound / distance %.3f on average (D_S's aligned, one joint made, %.3f)\n", metric, ratio, ratio2);
        assert_true(ratio > 0.1);
        if (mt == MIM_METRIC_SHAPE) assert_true(ratio2 > ratio);
        free(fb), free(fa), free(lbs);
    }
    free(g), free(s);
}

/* The pruned search on 1 and 2 threads against the exhaustive scan. */
static void compare(const mim_pair_prep_t *g, uint32_t m, const mim_pair_prep_t *s, uint32_t k, mim_sample_metric_t metric,
                    int pruned)
{
    double *near0 = malloc(m * sizeof *near0), *near1 = malloc(m * sizeof *near1);
    uint32_t *which0 = malloc(m * sizeof *which0), *which1 = malloc(m * sizeof *which1);
    assert_non_null(near0), assert_non_null(near1), assert_non_null(which0), assert_non_null(which1);
    mim_error_t err = {0};
    const mim_sample_coverage_options_t scan = {.threads = 2, .exhaustive = 1};
    mim_sample_coverage_t ref = {.nearest = near0, .which = which0};
    assert_int_equal(mim_sample_coverage(g, m, s, k, metric, &scan, &ref, &err), 0);
    assert_true(ref.distances == (uint64_t)m * k);
    uint64_t distances = 0;
    for (uint32_t threads = 1; threads <= 2; threads++) {
        const mim_sample_coverage_options_t o = {.threads = threads};
        mim_sample_coverage_t res = {.nearest = near1, .which = which1};
        assert_int_equal(mim_sample_coverage(g, m, s, k, metric, &o, &res, &err), 0);
        for (uint32_t i = 0; i < m; i++)
            if (memcmp(&near0[i], &near1[i], sizeof near0[i]) || which0[i] != which1[i])
                fail_msg("metric %d, %u threads, truth %u: %.17g (sample %u) against the scan's %.17g (sample %u)", metric,
                         threads, i, near1[i], which1[i], near0[i], which0[i]);
        assert_memory_equal(&res.coverage, &ref.coverage, sizeof res.coverage);
        /* fewer distances, and the same work whatever the threads */
        if (pruned) assert_true(res.distances < ref.distances);
        if (threads == 1) distances = res.distances;
        assert_true(res.distances == distances);
    }
    free(near0), free(near1), free(which0), free(which1);
}

static void test_pruned_equals_scan(void **state)
{
    (void)state;
    for (uint64_t seed = 1; seed <= 3; seed++) {
        mim_pair_prep_t *g, *s;
        /* 203 truths: chunks of 8 bounded at once, the last of 3 */
        make_sets(seed, 203, 2000, &g, &s);
        compare(g, 203, s, 2000, MIM_METRIC_CARTESIAN, 1);
        compare(g, 203, s, 2000, MIM_METRIC_IC, 1);
        compare(g, 203, s, 2000, MIM_METRIC_LIMBS, 1);
        /* D_S costs 20 times more a distance: fewer of both (62 truths: chunks of 3, the last of 2) */
        compare(g, 62, s, 600, MIM_METRIC_SHAPE, 1);
        free(g), free(s);
    }
}

/* Each measure's answers, alone and with the others in one pass, in any
 * order, on 1 and 2 threads, against the scan's. */
static void many_against_scan(const mim_pair_prep_t *g, uint32_t m, const mim_pair_prep_t *s, uint32_t k)
{
    mim_error_t err = {0};
    double *scan_near = malloc(4 * (size_t)m * sizeof *scan_near), *near = malloc(4 * (size_t)m * sizeof *near);
    uint32_t *scan_which = malloc(4 * (size_t)m * sizeof *scan_which), *which = malloc(4 * (size_t)m * sizeof *which);
    assert_non_null(scan_near), assert_non_null(near), assert_non_null(scan_which), assert_non_null(which);
    double scan_cov[4];
    const mim_sample_coverage_options_t scan = {.threads = 2, .exhaustive = 1};
    for (int q = 0; q < 4; q++) {
        mim_sample_coverage_t ref = {.nearest = scan_near + (size_t)q * m, .which = scan_which + (size_t)q * m};
        assert_int_equal(mim_sample_coverage(g, m, s, k, (mim_sample_metric_t)q, &scan, &ref, &err), 0);
        scan_cov[q] = ref.coverage;
    }
    const mim_sample_metric_t all[4] = {MIM_METRIC_LIMBS, MIM_METRIC_SHAPE, MIM_METRIC_CARTESIAN, MIM_METRIC_IC};
    const mim_sample_metric_t two[2] = {MIM_METRIC_SHAPE, MIM_METRIC_IC};
    const struct {
        const mim_sample_metric_t *metrics;
        uint32_t n;
    } asks[] = {{all, 4}, {two, 2}, {all + 1, 3}, {all + 3, 1}, {all + 1, 1}};
    for (size_t a = 0; a < sizeof asks / sizeof asks[0]; a++)
        for (uint32_t threads = 1; threads <= 2; threads++) {
            mim_sample_coverage_t res[4];
            for (uint32_t q = 0; q < asks[a].n; q++)
                res[q] = (mim_sample_coverage_t){.nearest = near + (size_t)q * m, .which = which + (size_t)q * m};
            const mim_sample_coverage_options_t o = {.threads = threads};
            assert_int_equal(mim_sample_coverage_many(g, m, s, k, asks[a].metrics, asks[a].n, &o, res, &err), 0);
            for (uint32_t q = 0; q < asks[a].n; q++) {
                const int mt = (int)asks[a].metrics[q];
                const double *n0 = scan_near + (size_t)mt * m, *n1 = near + (size_t)q * m;
                const uint32_t *w0 = scan_which + (size_t)mt * m, *w1 = which + (size_t)q * m;
                for (uint32_t i = 0; i < m; i++)
                    if (memcmp(&n1[i], &n0[i], sizeof n0[i]) || w1[i] != w0[i])
                        fail_msg("ask %zu, metric %d, %u threads, truth %u: %.17g (sample %u) against the scan's %.17g (sample %u)", a,
                                 mt, threads, i, n1[i], w1[i], n0[i], w0[i]);
                assert_memory_equal(&res[q].coverage, &scan_cov[mt], sizeof res[q].coverage);
                assert_true(res[q].distances < (uint64_t)m * k);
            }
        }
    free(scan_near), free(near), free(scan_which), free(which);
}

/* Several measures in one pass (D_I and D_S sharing their alignments):
 * each answer the scan's, on the random sets and on mirror images that
 * the first bounds cannot tell from their truths; and the measures asked
 * for checked. */
static void test_many_equals_scan(void **state)
{
    (void)state;
    mim_pair_prep_t *g, *s;
    make_sets(5, 62, 600, &g, &s);
    many_against_scan(g, 62, s, 600);
    free(s);
    uint32_t k;
    s = mirrored_samples(6, g, 16, &k);
    many_against_scan(g, 16, s, k);
    /* the measures asked for: none, too many, one twice, one of none, no list */
    mim_sample_coverage_t res[5] = {{0}};
    const mim_sample_metric_t five[5] = {MIM_METRIC_IC, MIM_METRIC_CARTESIAN, MIM_METRIC_SHAPE, MIM_METRIC_LIMBS, MIM_METRIC_IC};
    const mim_sample_metric_t twice[2] = {MIM_METRIC_SHAPE, MIM_METRIC_SHAPE}, none[1] = {(mim_sample_metric_t)7};
    const struct {
        const mim_sample_metric_t *metrics;
        uint32_t n;
        const char *says;
    } bad[] = {{five, 0, "0 measures asked for (1 to 4)"},
               {five, 5, "5 measures asked for (1 to 4)"},
               {twice, 2, "measure 2 asked for twice"},
               {none, 1, "measure 7 is none of the four"},
               {NULL, 1, "0 measures asked for (1 to 4)"}};
    for (size_t b = 0; b < sizeof bad / sizeof bad[0]; b++) {
        mim_error_t err = {0};
        assert_int_equal(mim_sample_coverage_many(g, 62, s, k, bad[b].metrics, bad[b].n, NULL, res, &err), MIM_EINVAL);
        if (!strstr(mim_error_text(&err), bad[b].says)) fail_msg("case %zu: '%s'", b, mim_error_text(&err));
    }
    free(g), free(s);
}

/* Samples all alike: the lowest index, as the scan keeps; one sample. */
static void test_ties_and_one_sample(void **state)
{
    (void)state;
    mim_pair_prep_t *g, *s;
    make_sets(4, 30, 200, &g, &s);
    /* every sample a copy of truth 0: all tie at 0 for it */
    mim_pair_prep_t *same = malloc(50 * sizeof *same);
    assert_non_null(same);
    for (int j = 0; j < 50; j++) same[j] = g[0];
    for (int metric = 0; metric < 4; metric++) {
        double near[30];
        uint32_t which[30];
        mim_sample_coverage_t res = {.nearest = near, .which = which};
        const mim_sample_coverage_options_t o = {.threads = 2};
        mim_error_t err = {0};
        assert_int_equal(mim_sample_coverage(g, 30, same, 50, (mim_sample_metric_t)metric, &o, &res, &err), 0);
        assert_true(near[0] < 1e-9);
        for (int i = 0; i < 30; i++) assert_int_equal(which[i], 0);
        compare(g, 30, s, 1, (mim_sample_metric_t)metric, 0);
    }
    free(same), free(g), free(s);
}

/* The LIMBS distance computed another way: Horn's quaternion fit (the
 * largest eigenvector of his 4 x 4 matrix, by Jacobi rotations) over the
 * 24 limb joints, both orders of b's people. */
static void jacobi4(double a[4][4], double v[4][4])
{
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) v[i][j] = i == j;
    for (int sweep = 0; sweep < 50; sweep++)
        for (int p = 0; p < 3; p++)
            for (int q = p + 1; q < 4; q++) {
                if (fabs(a[p][q]) < 1e-300) continue;
                double th = (a[q][q] - a[p][p]) / (2 * a[p][q]);
                double t = (th >= 0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1)), c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 4; k++) {
                    double x = a[k][p], y = a[k][q];
                    a[k][p] = c * x - s * y, a[k][q] = s * x + c * y;
                }
                for (int k = 0; k < 4; k++) {
                    double x = a[p][k], y = a[q][k];
                    a[p][k] = c * x - s * y, a[q][k] = s * x + c * y;
                }
                for (int k = 0; k < 4; k++) {
                    double x = v[k][p], y = v[k][q];
                    v[k][p] = c * x - s * y, v[k][q] = s * x + c * y;
                }
            }
}

static double horn_limbs(const double *a, const double *b)
{
    enum { L = 2 * MIM_LIMB_COUNT };
    double best = INFINITY;
    for (int swap = 0; swap < 2; swap++) {
        double pa[L][3], pb[L][3], ca[3] = {0}, cb[3] = {0};
        for (int i = 0; i < L; i++) {
            const int person = i / MIM_LIMB_COUNT, k = MIM_LIMB_FIRST + i % MIM_LIMB_COUNT;
            for (int c = 0; c < 3; c++) {
                pa[i][c] = a[3 * (MIM_PAIR_PERSON_JOINTS * person + k) + c];
                pb[i][c] = b[3 * (MIM_PAIR_PERSON_JOINTS * (person ^ swap) + k) + c];
                ca[c] += pa[i][c] / L, cb[c] += pb[i][c] / L;
            }
        }
        double S[3][3] = {{0}};
        for (int i = 0; i < L; i++)
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++) S[r][c] += (pb[i][r] - cb[r]) * (pa[i][c] - ca[c]);
        double Nm[4][4] = {
            {S[0][0] + S[1][1] + S[2][2], S[1][2] - S[2][1], S[2][0] - S[0][2], S[0][1] - S[1][0]},
            {S[1][2] - S[2][1], S[0][0] - S[1][1] - S[2][2], S[0][1] + S[1][0], S[2][0] + S[0][2]},
            {S[2][0] - S[0][2], S[0][1] + S[1][0], -S[0][0] + S[1][1] - S[2][2], S[1][2] + S[2][1]},
            {S[0][1] - S[1][0], S[2][0] + S[0][2], S[1][2] + S[2][1], -S[0][0] - S[1][1] + S[2][2]}};
        double V[4][4];
        jacobi4(Nm, V);
        int top = 0;
        for (int k = 1; k < 4; k++)
            if (Nm[k][k] > Nm[top][top]) top = k;
        mim_quat q = mim_quat_normalize((mim_quat){V[1][top], V[2][top], V[3][top], V[0][top]}); /* Horn: (w, x, y, z) */
        double sum = 0;
        for (int i = 0; i < L; i++) {
            mim_vec3 r = mim_quat_rotate(q, mim_v3(pb[i][0] - cb[0], pb[i][1] - cb[1], pb[i][2] - cb[2]));
            sum += sqrt(pow(ca[0] + r.x - pa[i][0], 2) + pow(ca[1] + r.y - pa[i][1], 2) + pow(ca[2] + r.z - pa[i][2], 2));
        }
        best = fmin(best, sum / L);
    }
    return best;
}

/* LIMBS against the brute force: every distance as Horn's fit gives it,
 * and coverage as the minimum over every sample; a truth with its people
 * swapped, moved rigidly and its head, spine and neck moved covers it at
 * 0, where D_C does not. */
static void test_limbs_brute_force(void **state)
{
    (void)state;
    enum { M = 40, K = 400 };
    mim_pair_prep_t *g, *s;
    make_sets(5, M, K, &g, &s);
    double cov = 0;
    for (uint32_t i = 0; i < M; i++) {
        double near = INFINITY;
        for (uint32_t j = 0; j < K; j++) {
            const double d = mim_sample_distance(&g[i], &s[j], MIM_METRIC_LIMBS), h = horn_limbs(g[i].joints, s[j].joints);
            if (!(fabs(d - h) <= 1e-9 * (1 + h))) fail_msg("truth %u, sample %u: limbs %.17g, Horn's %.17g", i, j, d, h);
            near = fmin(near, d);
        }
        cov += near / M;
    }
    mim_sample_coverage_t res = {0};
    const mim_sample_coverage_options_t o = {.threads = 2};
    mim_error_t err = {0};
    assert_int_equal(mim_sample_coverage(g, M, s, K, MIM_METRIC_LIMBS, &o, &res, &err), 0);
    assert_true(fabs(res.coverage - cov) <= 1e-12 * (1 + cov));
    assert_true(res.distances < (uint64_t)M * K);
    /* swapped, moved, the unfitted joints changed */
    double p[3 * J];
    for (int person = 0; person < 2; person++)
        memcpy(p + 3 * MIM_PAIR_PERSON_JOINTS * person, g[0].joints + 3 * MIM_PAIR_PERSON_JOINTS * (1 - person),
               3 * MIM_PAIR_PERSON_JOINTS * sizeof *p);
    const double t[3] = {1.0, -2.0, 0.5};
    move(p, 0.3, 1, -0.2, 2.2, 1.0, t);
    for (int person = 0; person < 2; person++)
        for (int k = 0; k < 3; k++) p[3 * (MIM_PAIR_PERSON_JOINTS * person + 0) + k] += 0.3; /* the heads */
    mim_pair_prep_t q;
    assert_int_equal(mim_pair_prepare(p, &q, &err), 0);
    assert_true(mim_sample_distance(&g[0], &q, MIM_METRIC_LIMBS) < 1e-9);
    assert_true(mim_sample_distance(&g[0], &q, MIM_METRIC_CARTESIAN) > 0.02);
    free(g), free(s);
}

/* Samples prepared with only what a distance reads of them (no shape
 * contexts; no triangulation but for D_I) give the same answers, to the
 * bit; a pose-pair without a part its distance reads is refused, and so
 * are joints that are not finite, whatever the parts. */
static void test_prepared_parts(void **state)
{
    (void)state;
    enum { M = 40, K = 400 };
    mim_pair_prep_t *g, *s;
    make_sets(6, M, K, &g, &s);
    double *sj = malloc((size_t)K * 3 * J * sizeof *sj);
    mim_pair_prep_t *tri = malloc(K * sizeof *tri), *bare = malloc(K * sizeof *bare);
    assert_non_null(sj), assert_non_null(tri), assert_non_null(bare);
    for (uint32_t j = 0; j < K; j++) memcpy(sj + (size_t)j * 3 * J, s[j].joints, 3 * J * sizeof *sj);
    mim_error_t err = {0};
    assert_int_equal(mim_pair_prepare_many(sj, K, 2, MIM_PREP_TRIANGULATION, tri, NULL, &err), 0);
    assert_int_equal(mim_pair_prepare_many(sj, K, 2, 0, bare, NULL, &err), 0);
    /* each pose-pair twice in a row: the repeat takes the parts of the one
     * before it, which are what preparing it alone makes */
    double *twice = malloc((size_t)2 * K * 3 * J * sizeof *twice);
    mim_pair_prep_t *both = malloc(2 * K * sizeof *both), alone;
    assert_non_null(twice), assert_non_null(both);
    for (uint32_t j = 0; j < 2 * K; j++) memcpy(twice + (size_t)j * 3 * J, s[j / 2].joints, 3 * J * sizeof *twice);
    assert_int_equal(mim_pair_prepare_many(twice, 2 * K, 2, MIM_PREP_ALL, both, NULL, &err), 0);
    for (uint32_t j = 0; j < 2 * K; j++) {
        assert_int_equal(mim_pair_prepare(twice + (size_t)j * 3 * J, &alone, &err), 0);
        assert_int_equal(both[j].parts, MIM_PREP_ALL);
        assert_memory_equal(both[j].joints, alone.joints, sizeof alone.joints);
        assert_int_equal(both[j].ic.n_edges, alone.ic.n_edges);
        assert_memory_equal(both[j].ic.edge, alone.ic.edge, alone.ic.n_edges * sizeof alone.ic.edge[0]);
        assert_memory_equal(both[j].sc, alone.sc, sizeof alone.sc);
    }
    free(twice), free(both);
    for (int metric = 0; metric < 4; metric++) {
        const mim_sample_metric_t mt = (mim_sample_metric_t)metric;
        double near0[M], near1[M];
        uint32_t which0[M], which1[M];
        const mim_sample_coverage_options_t o = {.threads = 2};
        mim_sample_coverage_t full = {.nearest = near0, .which = which0}, part = {.nearest = near1, .which = which1};
        assert_int_equal(mim_sample_coverage(g, M, s, K, mt, &o, &full, &err), 0);
        const mim_pair_prep_t *fewer = mim_sample_metric_parts(mt, 1) ? tri : bare;
        assert_int_equal(mim_sample_coverage(g, M, fewer, K, mt, &o, &part, &err), 0);
        assert_memory_equal(near0, near1, sizeof near0);
        assert_memory_equal(which0, which1, sizeof which0);
        if (mt == MIM_METRIC_IC) {
            mim_error_t e2 = {0};
            assert_int_equal(mim_sample_coverage(g, M, bare, K, mt, &o, &part, &e2), MIM_EINVAL);
            assert_non_null(strstr(mim_error_text(&e2), "sample 1 was prepared without the triangulation"));
        }
        /* one distance: the parts it reads give the full answer, a part missing none */
        assert_true(mim_sample_distance(&g[0], fewer, mt) == mim_sample_distance(&g[0], &s[0], mt));
        assert_true(isnan(mim_sample_distance(&g[0], &bare[0], mt)) == (mt == MIM_METRIC_IC));
        assert_true(isnan(mim_sample_distance(&bare[0], &s[0], mt)) == (mt == MIM_METRIC_IC || mt == MIM_METRIC_SHAPE));
    }
    /* truths need their shape contexts for D_S */
    mim_pair_prep_t *gt = malloc(M * sizeof *gt);
    assert_non_null(gt);
    assert_int_equal(mim_pair_prepare_many(sj, M, 1, MIM_PREP_TRIANGULATION, gt, NULL, &err), 0);
    mim_sample_coverage_t res = {0};
    mim_error_t e3 = {0};
    assert_int_equal(mim_sample_coverage(gt, M, tri, K, MIM_METRIC_SHAPE, NULL, &res, &e3), MIM_EINVAL);
    assert_non_null(strstr(mim_error_text(&e3), "truth 1 was prepared without the shape contexts"));
    /* a joint not finite, with no part made: refused, and found */
    sj[3 * J * 7 + 5] = NAN;
    uint32_t bad = 0;
    mim_error_t e4 = {0};
    assert_int_equal(mim_pair_prepare_many(sj, K, 2, 0, bare, &bad, &e4), MIM_ENONFINITE);
    assert_int_equal(bad, 7);
    free(g), free(s), free(sj), free(tri), free(bare), free(gt);
}

/* The rows' elevation coordinates and cosines (mim__sc_row's, as the
 * processor runs them) are within MIM__BOUND_EL_COORD_ERR and
 * MIM__BOUND_COS_ERR of the histograms' (libm's asin(up / r), in bin
 * units, both as binning clamps them; and its cos), and their azimuth
 * coordinates within MIM__BOUND_AZ_COORD_ERR of atan2's: over every elevation in steps of
 * 1e-6 of its sine and over vectors of every size and tilt, those near
 * the vertical, below a picometre and huge among them. Joint 0 sits at
 * the origin, the others at the vectors. */
static double clamped(double f) { return f < 0 ? 0 : f > MIM__SC_EL - 1 ? MIM__SC_EL - 1 : f; }
static void row_worst(mim__sc_coords_t *c, double *worst, double *worst_cos, double *worst_az)
{
    static const float fr[MIM__JOINT_PAIRS] = {0};
    mim__sc_row_t row;
    mim__sc_row(c, fr, 0, &row);
    for (int j = 1; j < J; j++) {
        const double x = c->x[j], y = c->y[j], z = c->z[j], r = sqrt(x * x + y * y + z * z);
        const double el = r > 0 ? asin(y / r) : 0.0, exact = (el + M_PI / 2) / M_PI * MIM__SC_EL - 0.5;
        *worst = fmax(*worst, fabs((double)row.fe[j] - clamped(exact)));
        *worst_cos = fmax(*worst_cos, fabs((double)row.cosel[j] - cos(el)));
        const double az = (atan2(z, x) + M_PI) / (2 * M_PI) * MIM__SC_AZ - 0.5, d = fabs(row.fa[j] - az);
        *worst_az = fmax(*worst_az, fmin(d, MIM__SC_AZ - d));
    }
}
static void test_bound_elevation(void **state)
{
    (void)state;
    mim__sc_coords_t c;
    double worst = 0, worst_cos = 0, worst_az = 0;
    mim_rng_t rng;
    mim_rng_seed(&rng, 42, 7);
    memset(&c, 0, sizeof c);
    for (int step = 0, j = 1; step <= 3000000; step++) {
        double v[3];
        if (step <= 2000000) { /* the sweep, at two lengths */
            const double sine = -1.0 + step * 1e-6, r = step % 2 ? 3.0 : 1.0;
            v[0] = sqrt(fmax(0, 1 - sine * sine)) * r, v[1] = sine * r, v[2] = 0;
        } else { /* random vectors: size 1e-4 to 10 (a few 1e-20 and 1e20), the horizontal part down to 1e-12 of the vertical */
            for (int k = 0; k < 3; k++) v[k] = 2 * mim_rng_unit(&rng) - 1;
            const double size = step % 101 == 0 ? 1e-20 : step % 103 == 0 ? 1e20 : pow(10, -4 + 5 * mim_rng_unit(&rng));
            const double flat = pow(10, -12 * mim_rng_unit(&rng));
            v[0] *= size * flat, v[2] *= size * flat, v[1] *= size;
        }
        c.x[j] = v[0], c.y[j] = v[1], c.z[j] = v[2];
        if (++j == J) row_worst(&c, &worst, &worst_cos, &worst_az), j = 1;
    }
    print_message("the rows' elevation coordinates: at most %.3g bins from asin's, cosines %.3g from cos, azimuths %.3g from atan2's\n",
                  worst, worst_cos, worst_az);
    assert_true(worst <= MIM__BOUND_EL_COORD_ERR);
    assert_true(worst_cos <= MIM__BOUND_COS_ERR);
    assert_true(worst_az <= MIM__BOUND_AZ_COORD_ERR);
    /* the poles and the horizontal exactly; a joint on joint 0 gives elevation 0 */
    const double up[4] = {1, -2, 0, 0}, side[4] = {0, 0, 1, 0}, want[4] = {3, 0, 1.5, 1.5};
    static const float fr[MIM__JOINT_PAIRS] = {0};
    mim__sc_row_t row;
    memset(&c, 0, sizeof c);
    for (int k = 0; k < 4; k++) c.y[k + 1] = up[k], c.z[k + 1] = side[k];
    mim__sc_row(&c, fr, 0, &row);
    for (int k = 0; k < 4; k++) assert_true(row.fe[k + 1] == want[k]);
}

/* The aligned bound's azimuths within MIM__BOUND_AZ_COORD_ERR bins of
 * atan2's (circularly), over every direction in steps of 1e-6 turns and
 * vectors of every size, nearly vertical ones (tiny x and z) among them;
 * and its histograms near the scan's for the pose-pairs of a set. */
static void test_bound_azimuth(void **state)
{
    (void)state;
    double worst = 0;
    mim_rng_t rng;
    mim_rng_seed(&rng, 43, 7);
    for (int step = 0; step <= 3000000; step++) {
        double x, z;
        if (step <= 1000000) {
            const double ang = 2 * M_PI * step * 1e-6 - M_PI;
            x = cos(ang), z = sin(ang);
        } else {
            const double size = pow(10, -12 + 13 * mim_rng_unit(&rng));
            x = (2 * mim_rng_unit(&rng) - 1) * size, z = (2 * mim_rng_unit(&rng) - 1) * size;
            if (step % 7 == 0) x = 0;
            if (step % 11 == 0) z = step % 2 ? 0.0 : -0.0;
        }
        const double exact = (atan2(z, x) + M_PI) / (2 * M_PI) * MIM__SC_AZ - 0.5;
        const double d = fabs(mim__sc_bound_azimuth((float)x, (float)z) - exact);
        worst = fmax(worst, fmin(d, MIM__SC_AZ - d));
    }
    print_message("the bound's azimuth coordinates: at most %.3g bins from atan2's\n", worst);
    assert_true(worst <= MIM__BOUND_AZ_COORD_ERR);
    enum { K = 60 };
    mim_pair_prep_t *g, *s;
    make_sets(6, 10, K, &g, &s);
    double far = 0;
    for (uint32_t j = 0; j < K; j++) {
        float fr[MIM__JOINT_PAIRS], h[MIM_SC_BINS];
        mim__sc_coords_t c;
        mim__sc_pair_radii(s[j].joints, fr);
        mim__sc_coords(s[j].joints, &c);
        for (int i = 0; i < J; i++) {
            mim__sc_row_t row;
            mim__sc_row(&c, fr, i, &row);
            mim__sc_row_histogram(&row, h);
            double l1 = 0;
            for (int r = 0; r < MIM__SC_R; r++)
                for (int a = 0; a < MIM__SC_AZ; a++)
                    for (int e = 0; e < MIM__SC_EL; e++)
                        l1 += fabs((double)h[MIM__SC_WORK(r, e, a)] - s[j].sc[i][(r * MIM__SC_AZ + a) * MIM__SC_EL + e]);
            far = fmax(far, l1);
        }
    }
    print_message("the aligned bound's histograms: at most %.3g (L1) from the scan's\n", far);
    assert_true(far < 1e-4);
    free(g), free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_marginals),
        cmocka_unit_test(test_bounds_below_distances),
        cmocka_unit_test(test_pruned_equals_scan),
        cmocka_unit_test(test_many_equals_scan),
        cmocka_unit_test(test_ties_and_one_sample),
        cmocka_unit_test(test_limbs_brute_force),
        cmocka_unit_test(test_prepared_parts),
        cmocka_unit_test(test_bound_elevation),
        cmocka_unit_test(test_bound_azimuth),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
