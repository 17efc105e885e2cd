/* The interaction coordinates' own Delaunay tetrahedralisation
 * (sample/delaunay.c) against qhull's: the same edges wherever it answers,
 * an answer for most pose-pairs, and no answer where none is proven (five
 * points on a sphere, four on a plane), where qhull decides. */
#include "internal.h"
#include "synthetic_pairs.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static int same_edges(const mim_ic_t *a, const mim_ic_t *b)
{
    return a->n_edges == b->n_edges && !memcmp(a->edge, b->edge, a->n_edges * sizeof a->edge[0]);
}

/* mim_ic_build's edges are qhull's; returns whether delaunay.c answered. */
static int check_against_qhull(const double *p, const char *what, int i)
{
    mim_ic_t fast, slow;
    mim_error_t e1 = {0}, e2 = {0};
    const int r1 = mim_ic_build(p, 3, &fast, &e1), r2 = mim__ic_build_qhull(p, 3, &slow, &e2);
    if (r1 != r2 || (!r1 && !same_edges(&fast, &slow)))
        fail_msg("%s %d: %u edges (rc %d), qhull %u (rc %d)", what, i, fast.n_edges, r1, slow.n_edges, r2);
    uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS] = {{0}};
    return mim__delaunay3_edges(p, MIM_PAIR_JOINTS, have) == 0;
}

/* Pose-pairs (two people posed at random, joints turned by up to 0.2 to
 * 1.5 rad), as they are and with a capture's noise (up to 2 mm a
 * coordinate), and clouds of 34 uniform points: qhull's edges every time.
 * The pose-pairs as they are hold ties (the people mirror each other and
 * stand on one floor): there delaunay.c declines and qhull decides. With
 * noise, as real captures, and in the clouds (0.2 mm to 2 km across,
 * as far from the origin as they are wide), delaunay.c answers nearly
 * every time itself. */
static void test_agrees_with_qhull(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 31, 2);
    double p[3 * MIM_PAIR_JOINTS];
    int answered = 0, total = 0;
    for (int i = 0; i < 1000; i++) {
        sp_random_pair(&r, 0.2 + 1.3 * mim_rng_unit(&r), p);
        check_against_qhull(p, "pose-pair", i);
        for (int k = 0; k < 3 * MIM_PAIR_JOINTS; k++) p[k] += 0.004 * (mim_rng_unit(&r) - 0.5);
        answered += check_against_qhull(p, "pose-pair with noise", i), total++;
    }
    for (int i = 0; i < 500; i++, total++) {
        const double scale = pow(10, -4 + 7 * mim_rng_unit(&r)), shift = 4 * scale * (mim_rng_unit(&r) - 0.5);
        for (int k = 0; k < 3 * MIM_PAIR_JOINTS; k++) p[k] = scale * (2 * mim_rng_unit(&r) - 1) + shift;
        answered += check_against_qhull(p, "cloud", i);
    }
    if (answered < total * 98 / 100) fail_msg("delaunay.c answered %d of %d", answered, total);
}

/* Ties, where the Delaunay tetrahedralisation is not one: 34 points on a
 * sphere (every five on it), a 3 x 3 x 4 grid less two (cubes' corners
 * on spheres), every point in one plane (no tetrahedron: qhull joggles),
 * and a cloud turned 1e-12 off such a grid. delaunay.c declines each;
 * mim_ic_build gives qhull's answer. */
static void test_declines_ties(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 5, 9);
    double p[3 * MIM_PAIR_JOINTS];
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
        double v[3], n = 0;
        for (int k = 0; k < 3; k++) v[k] = mim_rng_unit(&r) - 0.5, n += v[k] * v[k];
        for (int k = 0; k < 3; k++) p[3 * i + k] = 0.8 * v[k] / sqrt(n) + 0.1;
    }
    assert_false(check_against_qhull(p, "sphere", 0));
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) p[3 * i] = 0.3 * (i % 3), p[3 * i + 1] = 0.3 * (i / 3 % 3), p[3 * i + 2] = 0.3 * (i / 9);
    assert_false(check_against_qhull(p, "grid", 0));
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) p[3 * i + 2] += 1e-12 * mim_rng_unit(&r);
    assert_false(check_against_qhull(p, "grid, 1e-12 off", 0));
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
        const double a = mim_rng_unit(&r), b = mim_rng_unit(&r);
        p[3 * i] = a + b, p[3 * i + 1] = 2 * a - b, p[3 * i + 2] = 0.5 * a + 0.25 * b; /* in one plane */
    }
    assert_false(check_against_qhull(p, "plane", 0));
}

/* Far from the origin, qhull's lifting (each point's squared distance
 * from the origin) loses the digits that decide, and its answer can be
 * another's: a cloud 2 mm across 400 m away gave qhull an edge that no
 * empty sphere holds (checked in exact arithmetic). delaunay.c's
 * predicates take differences of the points, exact here: the same cloud
 * moved 512 m (every coordinate a multiple of 2^-30, so that the move
 * is exact) gets the edges it gets at the origin, which are qhull's
 * there; for clouds 2 mm and 2 m across. */
static void test_far_from_origin(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 12, 3);
    double p[3 * MIM_PAIR_JOINTS], moved[3 * MIM_PAIR_JOINTS];
    for (int size = 0; size < 2; size++)
        for (int i = 0; i < 20; i++) {
            for (int k = 0; k < 3 * MIM_PAIR_JOINTS; k++) {
                const double step = size ? 0x1p-20 : 0x1p-30; /* 2 m or 2 mm across */
                p[k] = step * floor((2 * mim_rng_unit(&r) - 1) * 0x1p20);
                moved[k] = p[k] + 512;
            }
            mim_ic_t here, there, qhull;
            mim_error_t err = {0};
            assert_int_equal(mim_ic_build(p, 3, &here, &err), 0);
            assert_int_equal(mim_ic_build(moved, 3, &there, &err), 0);
            assert_int_equal(mim__ic_build_qhull(p, 3, &qhull, &err), 0);
            uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS] = {{0}};
            assert_int_equal(mim__delaunay3_edges(moved, MIM_PAIR_JOINTS, have), 0);
            if (!same_edges(&here, &there) || !same_edges(&here, &qhull))
                fail_msg("cloud %d (%s): %u edges at the origin, %u at 512 m, qhull %u at the origin", i, size ? "2 m" : "2 mm",
                         here.n_edges, there.n_edges, qhull.n_edges);
        }
}

/* The smallest answers: four points are one tetrahedron (six edges), and
 * a fifth inside joins all four; fewer than four, or 35, are not asked. */
static void test_small(void **s)
{
    (void)s;
    const double tet[5][3] = {{0, 0, 0}, {1, 0.1, 0.2}, {0.3, 1.1, -0.1}, {0.2, 0.4, 0.9}, {0.35, 0.38, 0.25}};
    uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS] = {{0}};
    assert_int_equal(mim__delaunay3_edges(tet[0], 4, have), 0);
    int edges = 0, below = 0;
    for (int a = 0; a < MIM_PAIR_JOINTS; a++)
        for (int b = 0; b < MIM_PAIR_JOINTS; b++) {
            if (have[a][b] && a < b) edges++;
            if (have[a][b] && a >= b) below++;
        }
    assert_int_equal(edges, 6);
    assert_int_equal(below, 0);
    memset(have, 0, sizeof have);
    assert_int_equal(mim__delaunay3_edges(tet[0], 5, have), 0);
    for (int a = 0; a < 4; a++) assert_true(have[a][4]);
    assert_int_equal(mim__delaunay3_edges(tet[0], 3, have), -1);
    assert_int_equal(mim__delaunay3_edges(tet[0], MIM_PAIR_JOINTS + 1, have), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_agrees_with_qhull),
        cmocka_unit_test(test_declines_ties),
        cmocka_unit_test(test_far_from_origin),
        cmocka_unit_test(test_small),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
