/* session/complete.c: the local Gaussian of the nearest templates, and a lost wrist or ankle whose elbow or knee and
 * shoulder or hip are seen turns with its seen parent bone. On the
 * imitation set (each subject takes each pose its own way, so the seen
 * upper arm or thigh is turned its own way), the session's answer from the
 * classes' Gaussians alone (gaussian 1) lands nearer the truth than those
 * Gaussians' answer (mim_index_complete) it starts from; the seen
 * landmarks come back as given. Hostile input: a NaN marked present, one
 * landmark seen.
 *
 * The local Gaussian: a store of 5 synth subjects (one rig) completes a
 * sixth subject's bodies, 3 landmarks lost, much nearer the truth than the
 * nearest template after its similarity (the bench: 3.5 against 10.1 mm;
 * retrieval's median and blend alone: 9.3). */
#include "test_support.h"

#include "mim_db.h"
#include "mim_index.h"
#include "mim_ingest.h"
#include "mim_register.h"
#include "mim_session.h"
#include "mim_synth.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static char *dir, *store;
static mim_session_t *s;

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("session-complete");
    char *bodies = ts_path(dir, "bodies");
    store = ts_path(dir, "store");
    const char *steps[][10] = {
        {"synth", "--out", bodies, "--subjects", "2", "--poses", "4", "--vertices", "1500", NULL},
        {"ingest", "--store", store, bodies, NULL},
    };
    int rc = 0;
    for (int i = 0; !rc && i < 2; i++) {
        char *o = NULL, *e = NULL;
        rc = ts_run_mimic(&o, &e, steps[i]);
        free(o), free(e);
    }
    free(bodies);
    mim_error_t err = {0};
    if (!rc) rc = mim_session_open(&s, store, NULL, &err);
    if (rc) fprintf(stderr, "setup: %s\n", mim_error_text(&err));
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    mim_session_close(&s);
    ts_rmtree(dir);
    free(dir), free(store);
    return 0;
}

static double dist(const float *a, const float *b)
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

static void test_ends_turn_with_their_parent_bone(void **state)
{
    (void)state;
    enum { SUBJECTS = 6, POSES = 12, TRAIN = 5 * POSES };
    mim_synth_options_t o = {.subjects = SUBJECTS, .poses = POSES, .vertices = 1500, .seed = 21,
                             .imitation_deg = 3.5, .tissue_mm = 4, .slide_mm = 22};
    mim_synth_t *syn;
    assert_int_equal(mim_synth_create(&syn, &o, NULL), 0);
    mim_landmark_map_t map;
    mim_synth_landmarks(syn, &map);
    assert_int_equal(map.count, mim_session_map(s)->count);
    const uint32_t L = map.count;
    float *scratch = malloc(12 * mim_synth_n_vertices(syn)), *lm = malloc(sizeof *lm * 3 * L * SUBJECTS * POSES);
    uint64_t ids[SUBJECTS * POSES];
    const char *sp[SUBJECTS * POSES], *pp[SUBJECTS * POSES];
    static const char *const sn[SUBJECTS] = {"s0", "s1", "s2", "s3", "s4", "s5"};
    char pn[POSES][8];
    for (uint32_t p = 0; p < POSES; p++) snprintf(pn[p], sizeof pn[p], "p%u", p);
    for (uint32_t t = 0; t < SUBJECTS * POSES; t++) {
        mim_synth_body(syn, t / POSES, t % POSES, scratch);
        for (uint32_t l = 0; l < L; l++) memcpy(lm + 3 * (L * t + l), scratch + 3 * (size_t)map.vertex[l], 12);
        ids[t] = t + 1, sp[t] = sn[t / POSES], pp[t] = pn[t % POSES];
    }
    mim_synth_destroy(&syn);
    free(scratch);
    /* the Gaussians of 5 subjects; the sixth's bodies lose both wrists and both ankles */
    int32_t parent[MIM_LANDMARKS_MAX]; /* as a store's index: canonical proportions */
    assert_int_equal(mim_index_skeleton(&map, parent), 0);
    mim_index_input_t in = {TRAIN, L, lm, ids, sp, pp, map.mirror, parent};
    mim_index_t *ix = NULL;
    assert_int_equal(mim_index_build(&ix, &in, NULL, NULL, NULL), 0);
    const int ends[4] = {mim_landmarks_find(&map, "l_wrist"), mim_landmarks_find(&map, "r_wrist"),
                         mim_landmarks_find(&map, "l_ankle"), mim_landmarks_find(&map, "r_ankle")};
    for (int e = 0; e < 4; e++) assert_true(ends[e] >= 0);
    double e_turned = 0, e_gauss = 0;
    mim_session_complete_options_t co = {.gaussian = 1, .index = ix};
    mim_error_t err = {0};
    for (uint32_t p = 0; p < POSES; p++) {
        const float *truth = lm + 3 * L * (TRAIN + p);
        float x[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX], g[3 * MIM_LANDMARKS_MAX];
        uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
        memcpy(x, truth, 12 * L);
        memset(present, 1, L);
        for (int e = 0; e < 4; e++) present[ends[e]] = 0, x[3 * ends[e]] = NAN;
        assert_int_equal(mim_session_complete(s, x, present, &co, out, done, &err), 0);
        assert_int_equal(mim_index_complete(ix, x, present, g, NULL, NULL), 0);
        for (uint32_t l = 0; l < L; l++) {
            assert_int_equal(done[l], !present[l]);
            if (present[l]) assert_memory_equal(out + 3 * l, truth + 3 * l, 12);
        }
        for (int e = 0; e < 4; e++) {
            e_turned += dist(out + 3 * ends[e], truth + 3 * ends[e]) / (4 * POSES);
            e_gauss += dist(g + 3 * ends[e], truth + 3 * ends[e]) / (4 * POSES);
        }
    }
    print_message("lost wrists and ankles: %.1f mm turned with their parent bone, %.1f mm the Gaussians' answer\n",
                  1000 * e_turned, 1000 * e_gauss);
    assert_true(e_turned < 0.9 * e_gauss);
    /* hostile input: a NaN marked present (the Gaussians refuse it: retrieval alone answers, finite),
     * one landmark seen */
    float x[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
    memcpy(x, lm + 3 * L * TRAIN, 12 * L);
    memset(present, 1, L);
    present[ends[0]] = 0, x[3 * ends[0]] = NAN;
    x[3 * mim_landmarks_find(&map, "l_elbow") + 1] = NAN;
    co.gaussian = 0;
    int rc = mim_session_complete(s, x, present, &co, out, done, &err);
    if (rc == 0)
        for (int c = 0; c < 3; c++) assert_true(isfinite(out[3 * ends[0] + c]));
    memset(present, 0, L);
    present[0] = 1;
    mim_error_clear(&err);
    assert_int_equal(mim_session_complete(s, x, present, &co, out, done, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "1 landmarks seen"));
    mim_index_close(&ix);
    free(lm);
}

static void test_local_gaussian_of_near_templates(void **state)
{
    (void)state;
    /* the store: subjects 0-4; the frames: subject 5 of the same seed (the first 5 are the same bodies) */
    mim_synth_options_t o = {.subjects = 5, .poses = 4, .vertices = 1500, .seed = 4};
    mim_synth_t *syn = NULL, *six = NULL;
    mim_error_t err = {0};
    char *bodies = ts_path(dir, "five"), *st = ts_path(dir, "five-store");
    assert_int_equal(mim_synth_create(&syn, &o, &err), 0);
    assert_int_equal(mim_synth_write_dataset(syn, bodies, &err), 0);
    o.subjects = 6;
    assert_int_equal(mim_synth_create(&six, &o, &err), 0);
    mim_db_t *db = NULL;
    mim_db_options_t dbo = {0};
    mim_ingest_report_t rep;
    char *paths[1] = {bodies};
    assert_int_equal(mim_db_open(&db, st, &dbo, &err), 0);
    assert_int_equal(mim_ingest_run(db, paths, 1, NULL, &rep, &err), 0);
    mim_db_close(&db);
    mim_session_t *fs = NULL;
    assert_int_equal(mim_session_open(&fs, st, NULL, &err), 0);
    mim_landmark_map_t map;
    mim_synth_landmarks(six, &map);
    const uint32_t L = map.count;
    float *v = malloc(12 * mim_synth_n_vertices(six)), *tl = malloc(sizeof *tl * 3 * L * 20);
    for (uint32_t t = 0; t < 20; t++) { /* the store's templates' landmarks, for the baseline */
        mim_synth_body(syn, t / 4, t % 4, v);
        for (uint32_t l = 0; l < L; l++) memcpy(tl + 3 * (L * t + l), v + 3 * (size_t)map.vertex[l], 12);
    }
    static const uint32_t lost_sets[3][3] = {{7, 5, 13}, {8, 0, 12}, {14, 9, 3}};
    double e_default = 0, e_nearest = 0;
    for (uint32_t p = 0; p < 4; p++)
        for (int q = 0; q < 3; q++) {
            float truth[3 * MIM_LANDMARKS_MAX], x[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX];
            uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
            mim_synth_body(six, 5, p, v);
            for (uint32_t l = 0; l < L; l++) memcpy(truth + 3 * l, v + 3 * (size_t)map.vertex[l], 12);
            memcpy(x, truth, 12 * L);
            memset(present, 1, L);
            for (int c = 0; c < 3; c++) present[lost_sets[q][c]] = 0, x[3 * lost_sets[q][c]] = NAN;
            assert_int_equal(mim_session_complete(fs, x, present, NULL, out, done, &err), 0);
            /* the baseline: the nearest template over the seen landmarks, after its best similarity */
            double best_d = INFINITY, best[3 * MIM_LANDMARKS_MAX] = {0};
            for (uint32_t t = 0; t < 20; t++) {
                float a[3 * MIM_LANDMARKS_MAX], b[3 * MIM_LANDMARKS_MAX], moved[3 * MIM_LANDMARKS_MAX];
                uint32_t m = 0;
                for (uint32_t l = 0; l < L; l++)
                    if (present[l]) memcpy(a + 3 * m, tl + 3 * (L * t + l), 12), memcpy(b + 3 * m, truth + 3 * l, 12), m++;
                mim_reg_similarity_t sim;
                assert_int_equal(mim_reg_similarity_fit(a, b, m, &sim, NULL), 0);
                mim_reg_similarity_apply(&sim, a, m, moved);
                double d = 0;
                for (uint32_t k = 0; k < 3 * m; k++) d += (moved[k] - b[k]) * (moved[k] - b[k]);
                if (d < best_d) {
                    best_d = d;
                    float whole[3 * MIM_LANDMARKS_MAX];
                    mim_reg_similarity_apply(&sim, tl + 3 * L * t, L, whole);
                    for (uint32_t k = 0; k < 3 * L; k++) best[k] = whole[k];
                }
            }
            for (int c = 0; c < 3; c++) {
                const uint32_t l = lost_sets[q][c];
                float bb[3] = {(float)best[3 * l], (float)best[3 * l + 1], (float)best[3 * l + 2]};
                e_default += dist(out + 3 * l, truth + 3 * l) / 36, e_nearest += dist(bb, truth + 3 * l) / 36;
            }
        }
    print_message("a sixth synth subject, 3 landmarks lost: %.1f mm completed, %.1f mm the nearest template\n",
                  1000 * e_default, 1000 * e_nearest);
    assert_true(e_default < 0.7 * e_nearest);
    mim_session_close(&fs);
    mim_synth_destroy(&syn), mim_synth_destroy(&six);
    free(v), free(tl), free(bodies), free(st);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_local_gaussian_of_near_templates),
        cmocka_unit_test(test_ends_turn_with_their_parent_bone),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
