/* index/: the angle descriptor (counts, indexing, invariance, mirroring,
 * missing landmarks) and decision-tree feature selection. */
#include "mim_index.h"
#include "mim_synth.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void test_counts_and_indexing(void **s)
{
    (void)s;
    assert_int_equal(mim_index_angle_count(16), 1680);
    assert_int_equal(mim_index_angle_count(4), 12);
    assert_int_equal(mim_index_angle_count(2), 0);
    uint32_t ns[] = {4, 5, 16};
    for (int t = 0; t < 3; t++) {
        uint32_t n = ns[t], count = mim_index_angle_count(n);
        for (uint32_t a = 0; a < count; a++) {
            uint32_t i, j, k;
            mim_index_angle_triple(n, a, &i, &j, &k);
            assert_true(i < k && i != j && k != j && k < n && j < n);
            assert_int_equal(mim_index_angle_of(n, i, j, k), a);
            assert_int_equal(mim_index_angle_of(n, k, j, i), a);
        }
    }
}

/* The 16 landmark positions of a synth body. */
static void synth_landmarks(const mim_synth_t *syn, uint32_t subject, uint32_t pose, float *lm, float *scratch)
{
    mim_landmark_map_t map;
    mim_synth_landmarks(syn, &map);
    mim_synth_body(syn, subject, pose, scratch);
    for (uint32_t l = 0; l < map.count; l++) memcpy(lm + 3 * l, scratch + 3 * map.vertex[l], 12);
}

static void test_invariance_and_mirror(void **s)
{
    (void)s;
    mim_synth_options_t o = {.subjects = 2, .poses = 4, .vertices = 1500, .seed = 3};
    mim_synth_t *syn;
    assert_int_equal(mim_synth_create(&syn, &o, NULL), 0);
    float *scratch = malloc(12 * mim_synth_n_vertices(syn)), lm[48], moved[48], mirrored[48];
    float a[1680], b[1680];
    synth_landmarks(syn, 1, 3, lm, scratch);
    mim_index_angles(lm, NULL, 16, a);
    /* rotated, translated and scaled: the same angles */
    mim_quat q = mim_quat_axis_angle(mim_v3(0.3, -1, 0.5), 2.1);
    for (int l = 0; l < 16; l++) {
        mim_vec3 p = mim_quat_rotate(q, mim_v3(lm[3 * l], lm[3 * l + 1], lm[3 * l + 2]));
        moved[3 * l] = (float)(1.7 * p.x + 4), moved[3 * l + 1] = (float)(1.7 * p.y - 2), moved[3 * l + 2] = (float)(1.7 * p.z + 9);
    }
    mim_index_angles(moved, NULL, 16, b);
    for (int i = 0; i < 1680; i++) {
        assert_false(isnan(a[i]));
        assert_true(fabsf(a[i] - b[i]) < 2e-4f);
    }
    /* the body mirrored (x -> -x, left <-> right): angle a is the original's map[a] */
    mim_landmark_map_t map;
    mim_synth_landmarks(syn, &map);
    uint32_t mmap[1680];
    mim_index_angle_mirror(16, map.mirror, mmap);
    for (int l = 0; l < 16; l++) {
        const float *src = lm + 3 * map.mirror[l];
        mirrored[3 * l] = -src[0], mirrored[3 * l + 1] = src[1], mirrored[3 * l + 2] = src[2];
    }
    mim_index_angles(mirrored, NULL, 16, b);
    int differs = 0;
    for (int i = 0; i < 1680; i++) {
        assert_int_equal(mmap[mmap[i]], (uint32_t)i); /* an involution */
        assert_true(fabsf(b[i] - a[mmap[i]]) < 1e-5f);
        differs += fabsf(b[i] - a[i]) > 1e-3f; /* an asymmetric pose does change */
    }
    assert_true(differs > 100);
    /* a missing landmark: exactly the angles that involve it are NaN */
    uint8_t present[16];
    memset(present, 1, sizeof present);
    present[5] = 0;
    mim_index_angles(lm, present, 16, b);
    int nans = 0;
    for (int i = 0; i < 1680; i++) {
        uint32_t x, y, z;
        mim_index_angle_triple(16, (uint32_t)i, &x, &y, &z);
        int involved = x == 5 || y == 5 || z == 5;
        nans += isnan(b[i]);
        assert_int_equal(isnan(b[i]) != 0, involved);
        if (!involved) assert_true(b[i] == a[i]);
    }
    assert_int_equal(nans, 105 + 15 * 14);
    /* the selected descriptor is the same numbers */
    uint32_t sel[3] = {7, 900, 1679};
    float dsc[3];
    mim_index_descriptor(lm, NULL, 16, sel, 3, dsc);
    for (int i = 0; i < 3; i++) assert_true(dsc[i] == a[sel[i]]);
    free(scratch);
    mim_synth_destroy(&syn);
}

static void test_selection(void **s)
{
    (void)s;
    enum { S = 4, P = 12, N = S * P, D = 1680 };
    mim_synth_options_t o = {.subjects = S, .poses = P, .vertices = 1500, .seed = 7};
    mim_synth_t *syn;
    assert_int_equal(mim_synth_create(&syn, &o, NULL), 0);
    float *scratch = malloc(12 * mim_synth_n_vertices(syn)), *x = malloc(sizeof(float) * N * D), lm[48];
    uint32_t labels[N], subject[N];
    for (uint32_t sub = 0; sub < S; sub++)
        for (uint32_t p = 0; p < P; p++) {
            synth_landmarks(syn, sub, p, lm, scratch);
            mim_index_angles(lm, NULL, 16, x + (size_t)(sub * P + p) * D);
            labels[sub * P + p] = p;
            subject[sub * P + p] = sub;
        }
    mim_landmark_map_t map;
    mim_synth_landmarks(syn, &map);
    uint32_t mmap[D], sel[20];
    mim_index_angle_mirror(16, map.mirror, mmap);
    mim_select_options_t so = {.features = 20};
    mim_select_report_t rep;
    assert_int_equal(mim_index_select(x, labels, N, D, P, mmap, &so, sel, &rep, NULL), 0);
    assert_true(rep.tree_features >= 1 && rep.tree_features <= 20);
    assert_true(rep.training_accuracy == 1.0);
    for (int i = 0; i < 20; i++)
        for (int j = 0; j < i; j++) assert_int_not_equal(sel[i], sel[j]);
    /* leave one subject out, 1-NN on the 20 selected angles */
    int hits = 0;
    for (int q = 0; q < N; q++) {
        double best = INFINITY;
        int arg = -1;
        for (int r = 0; r < N; r++) {
            if (subject[r] == subject[q]) continue;
            double d2 = 0;
            for (int f = 0; f < 20; f++) {
                double dd = x[(size_t)q * D + sel[f]] - x[(size_t)r * D + sel[f]];
                d2 += dd * dd;
            }
            if (d2 < best) best = d2, arg = r;
        }
        hits += labels[arg] == labels[q];
    }
    fprintf(stderr, "leave-one-subject-out 1-NN on 20 selected angles: %d/%d (tree: %u nodes, %u angles)\n", hits, N,
            rep.tree_nodes, rep.tree_features);
    assert_true(hits >= (int)(0.9 * N));
    /* bad labels */
    mim_error_t err = {0};
    labels[3] = P;
    assert_int_equal(mim_index_select(x, labels, N, D, P, mmap, &so, sel, &rep, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "sample 3 has class 12"));
    free(scratch), free(x);
    mim_synth_destroy(&syn);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_counts_and_indexing),
        cmocka_unit_test(test_invariance_and_mirror),
        cmocka_unit_test(test_selection),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
