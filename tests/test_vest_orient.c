/* Orientations in vest output (issue 17): a landmark line's segment
 * rotations through the one writer and both readers, and the simulator's
 * sensor error (--faults orient-noise, drift) end to end through
 * `mimic vest simulate` and `replay`. */
#include "vest_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void test_udp_orientations_round_trip(void **state)
{
    (void)state;
    vs_avatar_t a;
    vs_avatar_make(&a, MIM_VEST_POSE_REST);
    float xyz[3 * MIM_LANDMARKS_MAX], g[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX], pg[MIM_LANDMARKS_MAX];
    for (int round = 0; round < 50; round++) {
        mim_quat q[MIM_SEGMENTS], R[MIM_SEGMENTS], got[MIM_SEGMENTS];
        uint8_t have[MIM_SEGMENTS], hg[MIM_SEGMENTS];
        for (int s = 0; s < MIM_SEGMENTS; s++) {
            float f[4];
            vs_rand_quat(f);
            q[s] = (mim_quat){f[0], f[1], f[2], f[3]};
            have[s] = vs_rnd() % 5 != 0;
        }
        have[MIM_VEST_PELVIS] = 1; /* the landmarks must stay a body */
        mim_vest_fk_orient(&a.rig, q, NULL, xyz, present);
        mim_vest_segment_rotations(&a.rig, q, have, R);
        char *js = mim_vest_udp_format_orient(1000u * (uint64_t)round, xyz, present, a.rig.n_landmarks, R, have);
        assert_non_null(js);
        assert_non_null(strstr(js, "\"orientations\":{\"pelvis\":["));
        assert_true(strstr(js, "\"l_foot\":") < strstr(js, "\"r_foot\":"));
        uint64_t t;
        uint32_t n;
        int has = 0;
        mim_error_t err = {0};
        assert_int_equal(mim_vest_udp_parse_orient(js, strlen(js), &t, g, pg, MIM_LANDMARKS_MAX, &n, got, hg, &has, &err), 0);
        assert_true(has == 1 && n == a.rig.n_landmarks && t == 1000u * (uint64_t)round);
        for (int s = 0; s < MIM_SEGMENTS; s++) {
            assert_int_equal(hg[s], have[s]);
            if (!have[s]) {
                assert_true(got[s].w == 1 && got[s].x == 0);
                continue;
            }
            assert_true(fabs(got[s].x - R[s].x) < 1e-6 && fabs(got[s].y - R[s].y) < 1e-6 &&
                        fabs(got[s].z - R[s].z) < 1e-6 && fabs(got[s].w - R[s].w) < 1e-6);
        }
        mim_quat lf[MIM_SEGMENTS];
        uint8_t hl[MIM_SEGMENTS];
        assert_int_equal(vs_line_orientations(js, lf, hl), 1);
        assert_memory_equal(hl, have, sizeof hl);
        for (int s = 0; s < MIM_SEGMENTS; s++)
            if (have[s]) assert_true(vs_angle_deg(lf[s], R[s]) < 1e-4);
        free(js);
    }
    vs_avatar_free(&a);
}

/* mimic vest simulate --faults orient-noise / drift: the recording carries
 * the noisy orientations, replay gives them, --expected keeps the truth;
 * bad values get one line. */
static void test_cli_orient_faults(void **state)
{
    (void)state;
    char *dir = ts_tempdir("vest-orient");
    char *bvh = vs_write_bvh(dir, 31), *rec = ts_path(dir, "n.vest"), *exp = ts_path(dir, "n.jsonl");
    char *out = NULL, *err = NULL;
    /* mean angle between replay and --expected per segment, and per time */
    for (int kind = 0; kind < 3; kind++) {
        const char *faults = kind == 0 ? "orient-noise=5" : kind == 1 ? "drift=600" : "drop=0";
        const char *sargs[] = {"vest", "simulate", "--motion", bvh, "--rate", "50", "--out", rec, "--pose", "t",
                               "--expected", exp, "--faults", faults, "--seed", "7", NULL};
        int rc = ts_run_mimic(&out, &err, sargs);
        if (rc) fail_msg("simulate: %s", err);
        free(out), free(err);
        const char *rargs[] = {"vest", "replay", rec, "--avatar", "synth", "--pose", "t", NULL};
        assert_int_equal(ts_run_mimic(&out, &err, rargs), 0);
        char *want = ts_read_file(exp, NULL);
        double sum = 0, first = -1, last = 0, t_last = 0;
        size_t n = 0, lines = 0;
        for (char *line = out, *nl; line && *line; line = nl) {
            nl = strchr(line, '\n');
            if (nl) *nl++ = 0;
            unsigned long long t;
            char *wl = vs_expected_line(want, line, &t);
            mim_quat Rg[MIM_SEGMENTS], Re[MIM_SEGMENTS];
            uint8_t hg[MIM_SEGMENTS], he[MIM_SEGMENTS];
            assert_int_equal(vs_line_orientations(line, Rg, hg), 1);
            assert_int_equal(vs_line_orientations(wl, Re, he), 1);
            double frame = 0;
            int m = 0;
            for (int s = 0; s < MIM_SEGMENTS; s++)
                if (hg[s] && he[s]) frame += vs_angle_deg(Rg[s], Re[s]), m++;
            assert_true(m > 0);
            sum += frame, n += (size_t)m, frame /= m;
            if (first < 0) first = frame;
            last = frame, t_last = (double)t / 1e6;
            lines++;
            free(wl);
        }
        assert_true(lines > 25);
        double mean = sum / (double)n;
        if (kind == 0) {
            assert_true(mean > 2 && mean < 10);
        } else if (kind == 1) { /* 600 degrees a minute over the motion's 1 s: 0 to 10, 5 on average */
            assert_true(first < 0.01);
            assert_true(t_last > 0.9 && fabs(last - 10 * t_last) < 0.01);
            assert_true(mean > 4 && mean < 6);
        } else {
            assert_true(mean < 1e-3);
        }
        free(want), free(out), free(err);
    }
    const char *bad1[] = {"vest", "simulate", "--motion", bvh, "--out", rec, "--faults", "orient-noise=-2", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, bad1), 2);
    assert_non_null(strstr(err, "orient-noise '-2'"));
    free(out), free(err);
    const char *bad2[] = {"vest", "simulate", "--motion", bvh, "--out", rec, "--faults", "twist=3", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, bad2), 2);
    assert_non_null(strstr(err, "mimic vest simulate: --faults 'twist=3' is not a list of drop=P, corrupt=P, "
                                "disconnect=T, down=S, orient-noise=DEG, drift=DEG_PER_MIN"));
    free(out), free(err);
    const char *help[] = {"vest", "simulate", "--help", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, help), 0);
    assert_non_null(strstr(out, "orient-noise=DEG"));
    assert_non_null(strstr(out, "drift=DEG_PER_MIN"));
    free(out), free(err);
    ts_rmtree(dir);
    free(bvh), free(rec), free(exp), free(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_udp_orientations_round_trip),
        cmocka_unit_test(test_cli_orient_faults),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
