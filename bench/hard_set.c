/* The hard recognition set (issue 15): see hard_set.h. The public synth API
 * poses bodies only by pose number; nearby poses need joint angles of
 * their own, so this uses synth's internal skinning (synth_internal.h):
 * the subject's rest body and weights, forward kinematics, linear blend
 * skinning of the landmark vertices only. */
#include "hard_set.h"
#include "mim_index.h"
#include "synth_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const uint32_t bases[] = {0, 3, 7, 8, 11}; /* rest, walk, wave, reach, guard */

typedef struct {
    int j, k;
    double deg;
} turn_t;
/* Variant v turns these (up to two) joint axes; a turn goes the other way
 * when the base is already bent past 60 degrees on that axis (stays in the
 * joint's range). */
static const turn_t variants[BENCH_HARD_VARIANTS][2] = {
    {{-1, 0, 0}, {-1, 0, 0}},
    {{MIM__J_LFARM, 0, 20}, {-1, 0, 0}},              /* left elbow */
    {{MIM__J_RUARM, 1, 15}, {-1, 0, 0}},              /* right arm raised sideways */
    {{MIM__J_SPINE, 0, 15}, {-1, 0, 0}},              /* bend forward */
    {{MIM__J_NECK, 0, 20}, {-1, 0, 0}},               /* head down */
    {{MIM__J_LTHIGH, 0, 15}, {MIM__J_LSHIN, 0, 15}},  /* left hip and knee */
    {{MIM__J_LUARM, 0, 12}, {MIM__J_RUARM, 0, 12}},   /* both arms forward */
    {{MIM__J_RSHIN, 0, 20}, {MIM__J_RTHIGH, 0, 10}},  /* right knee and hip */
};

/* Axes without a range (hinge joints, clavicle and foot twist): no jitter. */
static int locked(int j, int k)
{
    if (j == MIM__J_LFARM || j == MIM__J_RFARM || j == MIM__J_LSHIN || j == MIM__J_RSHIN) return k != 0;
    if (j == MIM__J_LCLAV || j == MIM__J_RCLAV || j == MIM__J_LFOOT || j == MIM__J_RFOOT) return k == 2;
    return 0;
}

void bench_hard_free(bench_hard_t *h)
{
    free(h->landmarks), free(h->pose_name), free(h->redrawn);
    memset(h, 0, sizeof *h);
}

int bench_hard_make(bench_hard_t *h, uint32_t subjects, uint32_t poses, uint32_t vertices, uint64_t seed,
                    double spread, mim_error_t *err)
{
    return bench_hard_make_draws(h, subjects, poses, vertices, seed, spread, 0, err);
}

int bench_hard_make_draws(bench_hard_t *h, uint32_t subjects, uint32_t poses, uint32_t vertices, uint64_t seed,
                          double spread, uint32_t draws, mim_error_t *err)
{
    memset(h, 0, sizeof *h);
    mim_synth_options_t o = {.subjects = subjects, .poses = 1, .vertices = vertices, .seed = seed};
    mim_synth_t *s = NULL;
    int rc = mim_synth_create(&s, &o, err);
    if (rc) return rc;
    mim_landmark_map_t map;
    mim_synth_landmarks(s, &map);
    uint32_t L = map.count;
    h->subjects = subjects, h->poses = poses, h->n_landmarks = L, h->draws = draws;
    memcpy(h->mirror, map.mirror, sizeof(uint32_t) * L);
    if (mim_index_skeleton(&map, h->parent)) {
        mim_synth_destroy(&s);
        return mim_error_set(err, MIM_EUNSUPPORTED, "hard set: synth's landmarks are not the 16 default ones");
    }
    h->landmarks = malloc(sizeof(float) * 3 * L * subjects * poses);
    h->redrawn = draws ? malloc(sizeof(float) * 3 * L * subjects * poses * draws) : NULL;
    h->pose_name = calloc(poses ? poses : 1, sizeof *h->pose_name);
    if (!h->landmarks || !h->pose_name || (draws && !h->redrawn)) {
        rc = mim_error_set(err, MIM_ENOMEM, "hard set: out of memory");
        goto out;
    }
    uint32_t nb = sizeof bases / sizeof *bases;
    for (uint32_t p = 0; p < poses; p++)
        snprintf(h->pose_name[p], sizeof h->pose_name[p], "%s+%u", mim__pose_table_name(bases[p / BENCH_HARD_VARIANTS % nb]),
                 p % BENCH_HARD_VARIANTS);
    for (uint32_t sj = 0; sj < subjects && !rc; sj++) {
        mim__subject_t sub;
        mim__subject_make(&sub, seed, sj);
        mim__body_t b;
        if ((rc = mim__body_eval(s, &sub, &b))) {
            mim_error_set(err, rc, "hard set: subject %u failed", sj);
            break;
        }
        for (uint32_t p = 0; p < poses; p++)
            for (uint32_t d = 0; d <= draws; d++) { /* d = 0: the set's own jitter; 1..draws: others */
                double deg[MIM__NJ][3];
                mim__pose_angles(bases[p / BENCH_HARD_VARIANTS % nb], seed, deg);
                for (int t = 0; t < 2; t++) {
                    const turn_t *v = &variants[p % BENCH_HARD_VARIANTS][t];
                    if (v->j < 0) continue;
                    deg[v->j][v->k] += (deg[v->j][v->k] > 60 ? -v->deg : v->deg) * spread;
                }
                mim_rng_t r;
                uint64_t stream = (uint64_t)sj * 100003 + p;
                mim_rng_seed(&r, seed, d ? 0x6a6974746572ULL + ((uint64_t)d << 40) + stream : 0x68617264ULL + stream);
                for (int j = 0; j < MIM__NJ; j++)
                    for (int k = 0; k < 3; k++)
                        if (!locked(j, k)) deg[j][k] += 6 * mim_rng_unit(&r) - 3;
                mim_quat q[MIM__NJ], G[MIM__NJ];
                mim_vec3 P[MIM__NJ];
                mim__pose_quats((const double(*)[3])deg, q);
                mim__fk(&b.sk, q, G, P);
                size_t t = (size_t)sj * poses + p;
                float *out = d ? h->redrawn + (t * draws + d - 1) * L * 3 : h->landmarks + t * L * 3;
                for (uint32_t l = 0; l < L; l++) {
                    uint32_t v = map.vertex[l];
                    double x[3];
                    mim__lbs(&b.sk, q, G, P, 1, b.rest + 3 * (size_t)v, b.wj + (size_t)MIM__NW * v,
                             b.ww + (size_t)MIM__NW * v, x);
                    for (int c = 0; c < 3; c++) out[3 * l + c] = (float)x[c];
                }
            }
        mim__body_free(&b);
    }
out:
    mim_synth_destroy(&s);
    if (rc) bench_hard_free(h);
    return rc;
}
