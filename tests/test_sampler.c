/* The MCMC sampler of seed 002 (sample/mim_sample_mcmc.h): Metropolis-Hastings
 * with a state-dependent proposal against a known 2D density (chi-squared),
 * eq. 11's truncation, the pose model, the learned joint limits, eta's
 * allowances, the likelihood, and whole chains over synthetic pose-pairs. */
#include "mim_sample_mcmc.h"

#include "synthetic_pairs.h"
#include "test_support.h"

#include <ode/ode.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- a toy density for mh.c: two Gaussians in the plane ---- */
static double toy_log_f(const double *x)
{
    double a = (x[0] * x[0] + x[1] * x[1]) / (2 * 0.5 * 0.5);
    double b = ((x[0] - 1.5) * (x[0] - 1.5) + (x[1] - 0.5) * (x[1] - 0.5)) / (2 * 0.3 * 0.3);
    return log(exp(-a) + 0.5 * exp(-b));
}

typedef struct toy {
    double *out;
    uint32_t thin;
    int cap_check; /* count evaluations below the floor */
} toy_t;

static void toy_move(void *ctx, const void *from, const double *eps, void *to)
{
    (void)ctx;
    const double *a = from;
    double *b = to;
    b[0] = a[0] + eps[0], b[1] = a[1] + eps[1];
}

/* A proposal whose variance grows with |x0| (as eq. 12's does with the
 * motion near the state): without Q's asymmetry in eq. 10, the chain
 * would favour the wide side. */
static double toy_evaluate(void *ctx, const void *state, double floor, double *sig2)
{
    (void)ctx, (void)floor;
    const double *x = state;
    double s = 0.25 + 0.35 * fabs(x[0]);
    sig2[0] = s * s, sig2[1] = 0.3 * 0.3;
    return toy_log_f(x);
}

static void toy_emit(void *ctx, uint32_t i, const void *state, double log_f)
{
    toy_t *t = ctx;
    (void)log_f;
    if (i % t->thin == 0) memcpy(t->out + 2 * (i / t->thin), state, 2 * sizeof(double));
}

static const mim_mh_ops_t toy_ops = {2, 1, 2 * sizeof(double), toy_move, toy_evaluate, toy_emit};

/* The 0.999 quantile of chi-squared with k degrees of freedom
 * (Wilson-Hilferty). */
static double chi2_999(int k)
{
    double h = 2.0 / (9.0 * k);
    return k * pow(1 - h + 3.09 * sqrt(h), 3);
}

#define GX 12
#define GY 10
static void toy_cell_probabilities(double p[GX][GY], double x0, double x1, double y0, double y1)
{
    double total = 0;
    memset(p, 0, sizeof(double) * GX * GY);
    const int fine = 40;
    for (int i = 0; i < GX * fine; i++)
        for (int j = 0; j < GY * fine; j++) {
            double x[2] = {x0 + (i + 0.5) * (x1 - x0) / (GX * fine), y0 + (j + 0.5) * (y1 - y0) / (GY * fine)};
            double f = exp(toy_log_f(x));
            p[i / fine][j / fine] += f;
            total += f;
        }
    for (int i = 0; i < GX; i++)
        for (int j = 0; j < GY; j++) p[i][j] /= total;
}

/* Thinned draws match the density cell by cell (chi-squared at 0.1 %). */
static void test_mh_matches_toy_density(void **s)
{
    (void)s;
    const uint32_t steps = 400000, thin = 40, n = steps / thin;
    toy_t t = {calloc(2 * n, sizeof(double)), thin, 0};
    mim_rng_t rng;
    mim_rng_seed(&rng, 11, 0);
    mim_mh_stats_t st;
    mim_error_t err = {0};
    const double seed[2] = {0.2, 0.1};
    assert_int_equal(mim_mh_run(&toy_ops, &t, seed, 0 /* no truncation */, &rng, steps, &st, NULL, &err), 0);
    assert_int_equal(st.steps, steps);
    double accept = (double)st.accepted / st.steps;
    assert_true(accept > 0.2 && accept < 0.9);
    const double x0 = -2.5, x1 = 3.0, y0 = -2.0, y1 = 2.5;
    double p[GX][GY];
    toy_cell_probabilities(p, x0, x1, y0, y1);
    double counts[GX][GY] = {{0}};
    uint32_t inside = 0;
    for (uint32_t i = 0; i < n; i++) {
        int cx = (int)floor((t.out[2 * i] - x0) / (x1 - x0) * GX), cy = (int)floor((t.out[2 * i + 1] - y0) / (y1 - y0) * GY);
        if (cx < 0 || cx >= GX || cy < 0 || cy >= GY) continue;
        counts[cx][cy]++, inside++;
    }
    assert_true(inside > n * 0.99);
    double chi2 = 0;
    int cells = 0;
    for (int i = 0; i < GX; i++)
        for (int j = 0; j < GY; j++) {
            double e = p[i][j] * inside;
            if (e < 5) continue;
            chi2 += (counts[i][j] - e) * (counts[i][j] - e) / e;
            cells++;
        }
    print_message("toy density: chi-squared %.1f over %d cells (0.1%% bound %.1f), acceptance %.2f\n", chi2, cells,
                  chi2_999(cells - 1), accept);
    assert_true(cells > 25);
    assert_true(chi2 < chi2_999(cells - 1));
    /* the same seed, the same chain */
    toy_t again = {calloc(2 * n, sizeof(double)), thin, 0};
    mim_rng_seed(&rng, 11, 0);
    assert_int_equal(mim_mh_run(&toy_ops, &again, seed, 0, &rng, steps, &st, NULL, &err), 0);
    assert_memory_equal(t.out, again.out, 2 * n * sizeof(double));
    free(t.out), free(again.out);
}

/* eq. 11: nothing below f0 / c is ever visited, and above c f0 the density
 * is flat: two cells of equal area inside the flat top get equal counts. */
static void test_mh_truncation(void **s)
{
    (void)s;
    const uint32_t steps = 300000, thin = 30, n = steps / thin;
    toy_t t = {calloc(2 * n, sizeof(double)), thin, 0};
    mim_rng_t rng;
    mim_rng_seed(&rng, 5, 0);
    mim_mh_stats_t st;
    mim_error_t err = {0};
    /* the seed sits where f is e^-2 of the first peak: f0 / c = e^-3.4 and c f0 = e^-0.6 */
    const double seed[2] = {1.0, 0.0}, c = exp(1.4);
    double lf0 = toy_log_f(seed);
    assert_int_equal(mim_mh_run(&toy_ops, &t, seed, c, &rng, steps, &st, NULL, &err), 0);
    assert_true(st.zero > 0); /* proposals below the floor were refused */
    uint32_t near_a = 0, near_b = 0;
    for (uint32_t i = 0; i < n; i++) {
        double lf = toy_log_f(t.out + 2 * i);
        if (lf < lf0 - log(c) - 1e-12) fail_msg("sample %u below f0 / c: log f %g, floor %g", i, lf, lf0 - log(c));
        /* two discs of radius 0.12 about (+-0.15, 0), inside the flat top of the first peak */
        double ax = t.out[2 * i] - 0.15, ay = t.out[2 * i + 1], bx = t.out[2 * i] + 0.15, by = t.out[2 * i + 1];
        near_a += ax * ax + ay * ay < 0.12 * 0.12;
        near_b += bx * bx + by * by < 0.12 * 0.12;
    }
    double p_a = toy_log_f((double[]){0.15, 0}), p_b = toy_log_f((double[]){-0.15, 0});
    assert_true(p_a > lf0 + log(c) && p_b > lf0 + log(c)); /* both inside the cap */
    print_message("truncation: %u and %u samples in two equal discs of the flat top\n", near_a, near_b);
    assert_true(near_a > 100 && near_b > 100);
    double chi2 = (near_a - near_b) * (double)(near_a - near_b) / (near_a + near_b);
    assert_true(chi2 < 10.8); /* 0.1 % for one degree of freedom */
    /* a seed of density 0 under the model */
    const double far[2] = {1e6, 1e6};
    toy_t bad = {t.out, thin, 0};
    assert_int_equal(mim_mh_run(&toy_ops, &bad, far, c, &rng, 10, &st, NULL, &err), MIM_EINVAL);
    free(t.out);
}

static double dist3(const double *a, const double *b)
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* Forward kinematics: the rest gives the pair back; rotations keep every
 * bone's length; a knee's rotation moves its ankle only. */
static void test_pose_model(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 2, 0);
    double pair[3 * MIM_PAIR_JOINTS], back[3 * MIM_PAIR_JOINTS];
    sp_random_pair(&r, 0.5, pair);
    mim_pairs_pose_t pose;
    mim_pairs_pose_rest(pair, &pose);
    mim_pairs_pose_joints(&pose, back);
    for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) assert_true(fabs(back[i] - pair[i]) < 1e-12);
    for (int p = 0; p < 2; p++)
        for (int g = 0; g < MIM_PAIRS_ROT; g++)
            pose.rot[p][g] = mim_quat_axis_angle(mim_v3_normalize(mim_v3(1, 2, 3 - g)), 0.3 * g + p);
    mim_pairs_pose_joints(&pose, back);
    for (int k = 0; k < MIM_PAIR_JOINTS; k++) {
        int parent = mim_pairs_parent[k % MIM_PAIR_PERSON_JOINTS];
        if (parent < 0) continue;
        int pk = parent + (k >= MIM_PAIR_PERSON_JOINTS ? MIM_PAIR_PERSON_JOINTS : 0);
        assert_true(fabs(dist3(back + 3 * k, back + 3 * pk) - dist3(pair + 3 * k, pair + 3 * pk)) < 1e-12);
    }
    mim_pairs_pose_rest(pair, &pose);
    pose.rot[0][10] = mim_quat_axis_angle(mim_v3(1, 0, 0), 0.7); /* A's left knee */
    mim_pairs_pose_joints(&pose, back);
    for (int k = 0; k < MIM_PAIR_JOINTS; k++) {
        double d = dist3(back + 3 * k, pair + 3 * k);
        if (k == 13) assert_true(d > 0.1); /* l_ankle */
        else assert_true(d < 1e-12);
    }
    assert_false(mim_pairs_group_free(0));
    assert_false(mim_pairs_group_free(MIM_PAIRS_GROUP_TRANS(0)));
    assert_true(mim_pairs_group_free(MIM_PAIRS_GROUP_TRANS(1)));
    assert_true(mim_pairs_group_free(MIM_PAIRS_ROT)); /* B's root rotation */
}

/* A rough seed (--seed-jitter): bones keep their lengths, A's pelvis stays
 * (its root does not move), the joints move by about the turn asked for,
 * and no turn gives the pair back. */
static void test_seed_jitter(void **s)
{
    (void)s;
    mim_rng_t r, j;
    mim_rng_seed(&r, 3, 0);
    mim_rng_seed(&j, 4, 0);
    double pair[3 * MIM_PAIR_JOINTS], out[3 * MIM_PAIR_JOINTS];
    sp_random_pair(&r, 0.5, pair);
    mim_pairs_seed_jitter(pair, 0, 0, &j, out);
    for (int i = 0; i < 3 * MIM_PAIR_JOINTS; i++) assert_true(fabs(out[i] - pair[i]) < 1e-12);
    double moved = 0, moved_small = 0;
    for (int trial = 0; trial < 20; trial++) {
        mim_pairs_seed_jitter(pair, 15 * M_PI / 180, 0.2, &j, out);
        for (int k = 0; k < MIM_PAIR_JOINTS; k++) {
            int parent = mim_pairs_parent[k % MIM_PAIR_PERSON_JOINTS];
            if (parent < 0) continue;
            int pk = parent + (k >= MIM_PAIR_PERSON_JOINTS ? MIM_PAIR_PERSON_JOINTS : 0);
            assert_true(fabs(dist3(out + 3 * k, out + 3 * pk) - dist3(pair + 3 * k, pair + 3 * pk)) < 1e-12);
        }
        assert_true(dist3(out + 3 * 2, pair + 3 * 2) < 1e-12); /* A's pelvis */
        for (int k = 0; k < MIM_PAIR_JOINTS; k++) moved += dist3(out + 3 * k, pair + 3 * k) / MIM_PAIR_JOINTS / 20;
        mim_pairs_seed_jitter(pair, 2 * M_PI / 180, 0.02, &j, out);
        for (int k = 0; k < MIM_PAIR_JOINTS; k++) moved_small += dist3(out + 3 * k, pair + 3 * k) / MIM_PAIR_JOINTS / 20;
    }
    print_message("seed jitter 15 deg, 0.2 m: joints moved %.3f m on average; 2 deg, 0.02 m: %.3f m\n", moved, moved_small);
    assert_true(moved > 0.05 && moved < 1.0);
    assert_true(moved_small < 0.3 * moved);
}

/* Joint limits learned from poses: those poses are valid, a knee bent
 * the wrong way is not (by about the excess angle), the mirror image of
 * a valid pose is valid, and nothing learned is an error. */
static void test_validity(void **s)
{
    (void)s;
    mim_rng_t r;
    mim_rng_seed(&r, 3, 0);
    const uint32_t n = 200;
    double *pairs = malloc(n * 3 * MIM_PAIR_JOINTS * sizeof *pairs);
    for (uint32_t i = 0; i < n; i++) sp_random_pair(&r, 0.25, pairs + (size_t)i * 3 * MIM_PAIR_JOINTS);
    mim_pairs_validity_t *v = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_pairs_validity_learn(pairs, 0, &v, &err), MIM_EINVAL);
    assert_int_equal(mim_pairs_validity_learn(pairs, n, &v, &err), 0);
    uint32_t invalid;
    for (uint32_t i = 0; i < n; i += 17) {
        assert_true(mim_pairs_validity_excess(v, pairs + (size_t)i * 3 * MIM_PAIR_JOINTS, &invalid) == 0);
        assert_int_equal(invalid, 0);
    }
    /* A's left knee bent 100 degrees forwards (the shin ahead of the thigh) */
    mim_pairs_pose_t pose;
    mim_pairs_pose_rest(pairs, &pose);
    pose.rot[0][10] = mim_quat_axis_angle(mim_v3(1, 0, 0), -100 * M_PI / 180);
    double bent[3 * MIM_PAIR_JOINTS];
    mim_pairs_pose_joints(&pose, bent);
    double excess = mim_pairs_validity_excess(v, bent, &invalid);
    print_message("knee bent the wrong way: %u invalid checks, excess %.3f rad^2\n", invalid, excess);
    assert_int_equal(invalid, 1);
    assert_true(sqrt(excess) > 0.6 && sqrt(excess) < 100 * M_PI / 180);
    /* the mirror image (x -> -x, left and right swapped) of a learned pose */
    double mirror[3 * MIM_PAIR_JOINTS];
    static const int swap[MIM_PAIR_PERSON_JOINTS] = {0, 1, 2, 4, 3, 6, 5, 8, 7, 10, 9, 12, 11, 14, 13, 15, 16};
    for (int p = 0; p < 2; p++)
        for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++)
            for (int c = 0; c < 3; c++)
                mirror[3 * (p * MIM_PAIR_PERSON_JOINTS + swap[k]) + c] =
                    (c == 0 ? -1 : 1) * pairs[3 * (5 * MIM_PAIR_JOINTS + p * MIM_PAIR_PERSON_JOINTS + k) + c];
    assert_true(mim_pairs_validity_excess(v, mirror, &invalid) < 1e-3);
    /* a person with every joint at one place has no frame: every check fails */
    double flat[3 * MIM_PAIR_JOINTS];
    memcpy(flat, pairs, sizeof flat);
    for (int k = 0; k < 3 * MIM_PAIR_PERSON_JOINTS; k++) flat[k] = 1.0;
    mim_pairs_validity_excess(v, flat, &invalid);
    assert_int_equal(invalid, MIM_PAIRS_CHECKS);
    mim_pairs_validity_free(&v);
    assert_null(v);
    free(pairs);
}

/* eta's allowances: a prior pose's own penetration is allowed, deeper is
 * not; pairs the prior never shows overlapping have no allowance. */
static void test_penetration_allowance(void **s)
{
    (void)s;
    assert_true(dInitODE2(0));
    mim_penetration_t *p = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_penetration_open(&p, &err), 0);
    mim_rng_t r;
    mim_rng_seed(&r, 4, 0);
    double pair[3 * MIM_PAIR_JOINTS];
    sp_random_pair(&r, 0.0, pair);
    /* B steps into A: their torsos overlap by a few centimetres */
    for (int k = MIM_PAIR_PERSON_JOINTS; k < MIM_PAIR_JOINTS; k++) pair[3 * k + 2] -= 1.0;
    double eta = mim_penetration_pair(p, pair, NULL);
    assert_true(eta > 0.01);
    double *allowed = calloc(MIM_PENETRATION_ALLOWANCES, sizeof *allowed);
    mim_penetration_learn(p, pair, allowed);
    assert_true(mim_penetration_pair(p, pair, allowed) < 1e-9);
    for (int k = MIM_PAIR_PERSON_JOINTS; k < MIM_PAIR_JOINTS; k++) pair[3 * k + 2] -= 0.03;
    double deeper = mim_penetration_pair(p, pair, allowed);
    print_message("penetration %.3f m allowed; 3 cm deeper: %.3f m beyond\n", eta, deeper);
    assert_true(deeper > 0.01 && deeper < mim_penetration_pair(p, pair, NULL));
    free(allowed);
    mim_penetration_close(&p);
    dCloseODE();
}

/* ---- annotations of synthetic pairs, and chains ---- */
typedef struct world {
    uint32_t n_prior;
    double *prior;
    mim_pairs_annotations_t ann;
    mim_pairs_validity_t *validity;
    mim_pairs_evidence_t *evidence;
    double allowed[MIM_PENETRATION_ALLOWANCES];
    mim_pairs_target_t target;
} world_t;

/* A synthetic "take": pose-pairs that move smoothly (joint rotations on
 * slow sines), annotated by video cameras every frame, as pairs annotate
 * --video does. */
static void world_build(world_t *w, mim_pairs_density_t density)
{
    memset(w, 0, sizeof *w);
    const uint32_t frames = 60, views = 4;
    w->n_prior = frames;
    w->prior = malloc(frames * 3 * MIM_PAIR_JOINTS * sizeof *w->prior);
    double rest[3 * MIM_PAIR_JOINTS];
    mim_rng_t r;
    mim_rng_seed(&r, 9, 0);
    sp_random_pair(&r, 0.0, rest);
    for (uint32_t f = 0; f < frames; f++) {
        mim_pairs_pose_t pose;
        mim_pairs_pose_rest(rest, &pose);
        for (int p = 0; p < 2; p++)
            for (int g = 1; g < MIM_PAIRS_ROT; g++) {
                double ph = 0.37 * g + 1.3 * p;
                pose.rot[p][g] = mim_quat_axis_angle(mim_v3_normalize(mim_v3(1, 0.3 * sin(ph), 0.2)), 0.35 * sin(0.1 * f + ph));
            }
        pose.root[1][2] -= 0.2 * sin(0.05 * f);
        mim_pairs_pose_joints(&pose, w->prior + (size_t)f * 3 * MIM_PAIR_JOINTS);
    }
    mim_pairs_annotations_t *a = &w->ann;
    a->n = frames * views, a->width = 1920, a->height = 1080;
    a->take = calloc(a->n, sizeof *a->take), a->frame = calloc(a->n, sizeof *a->frame);
    a->view = calloc(a->n, sizeof *a->view), a->shot = calloc(a->n, sizeof *a->shot);
    a->points = calloc((size_t)a->n * 2 * MIM_PAIR_JOINTS, sizeof *a->points);
    mim_pairs_camera_t cam[4];
    for (uint32_t v = 0; v < views; v++) assert_int_equal(mim_pairs_camera_random(&r, w->prior, &cam[v]), 0);
    for (uint32_t f = 0; f < frames; f++)
        for (uint32_t v = 0; v < views; v++) {
            uint32_t i = f * views + v;
            const double *j = w->prior + (size_t)f * 3 * MIM_PAIR_JOINTS;
            assert_true(mim_pairs_camera_follow(&cam[v], j));
            mim_pairs_project(&cam[v], j, a->points + (size_t)i * 2 * MIM_PAIR_JOINTS);
            a->frame[i] = f, a->view[i] = v, a->shot[i] = v;
        }
    mim_error_t err = {0};
    mim_pairs_torso_t torso;
    uint32_t dropped;
    assert_int_equal(mim_pairs_validity_learn(w->prior, frames, &w->validity, &err), 0);
    assert_int_equal(mim_pairs_torso_learn(w->prior, frames, &torso, &err), 0);
    assert_int_equal(mim_pairs_evidence_build(&w->ann, &torso, density, &w->evidence, &dropped, NULL, &err), 0);
    assert_int_equal(mim_pairs_evidence_count(w->evidence), a->n - dropped);
    assert_true(dropped < a->n / 10);
    mim_pairs_sampler_defaults(&w->target.opt);
    w->target.opt.density = density;
    w->target.validity = w->validity, w->target.evidence = w->evidence, w->target.allowed = w->allowed;
}

static void world_free(world_t *w)
{
    free(w->prior);
    mim_pairs_annotations_free(&w->ann);
    mim_pairs_validity_free(&w->validity);
    mim_pairs_evidence_free(&w->evidence);
}

/* eq. 9's likelihood prefers the pose-pairs that were annotated: a prior
 * frame against the same frame with its arms and B moved. */
static void test_likelihood(void **s)
{
    (void)s;
    world_t w;
    world_build(&w, MIM_DENSITY_IC);
    mim_rng_t r;
    mim_rng_seed(&r, 1, 0);
    double views[16];
    const double *ev = mim_pairs_evidence_views(w.evidence);
    for (int v = 0; v < 8; v++) mim_pairs_view_draw(ev, mim_pairs_evidence_count(w.evidence), 0.5, &r, &views[2 * v], &views[2 * v + 1]);
    int better = 0;
    for (uint32_t f = 0; f < w.n_prior; f += 6) {
        const double *truth = w.prior + (size_t)f * 3 * MIM_PAIR_JOINTS;
        uint32_t nearest[8];
        double lt = mim_pairs_log_likelihood(w.evidence, MIM_DENSITY_IC, 0.05, 0.5, truth, views, 8, nearest);
        for (int v = 0; v < 8; v++) assert_true(nearest[v] < mim_pairs_evidence_count(w.evidence));
        mim_pairs_pose_t pose;
        mim_pairs_pose_rest(truth, &pose);
        pose.rot[0][4] = mim_quat_axis_angle(mim_v3(0, 0, 1), 1.2); /* A's left arm raised */
        pose.rot[1][5] = mim_quat_axis_angle(mim_v3(1, 0, 0), -1.0); /* B's right arm forward */
        pose.root[1][0] += 0.5;
        double moved[3 * MIM_PAIR_JOINTS];
        mim_pairs_pose_joints(&pose, moved);
        double lm = mim_pairs_log_likelihood(w.evidence, MIM_DENSITY_IC, 0.05, 0.5, moved, views, 8, NULL);
        better += lt > lm;
        assert_true(isfinite(lt) && isfinite(lm) && lt <= 0);
    }
    assert_int_equal(better, 10);
    /* the prior density has no likelihood */
    assert_true(mim_pairs_log_likelihood(w.evidence, MIM_DENSITY_PRIOR, 0.05, 0.5, w.prior, views, 8, NULL) == 0);
    /* two people at one place have no local frame */
    double same[3 * MIM_PAIR_JOINTS];
    memcpy(same, w.prior, 3 * MIM_PAIR_PERSON_JOINTS * sizeof(double));
    memcpy(same + 3 * MIM_PAIR_PERSON_JOINTS, w.prior, 3 * MIM_PAIR_PERSON_JOINTS * sizeof(double));
    assert_true(mim_pairs_log_likelihood(w.evidence, MIM_DENSITY_IC, 0.05, 0.5, same, views, 8, NULL) == -INFINITY);
    world_free(&w);
}

/* Whole chains over each density: they move, keep bones and A's root,
 * never visit below f0 / c, and give the same bytes from the same seed. */
static void test_chains(void **s)
{
    (void)s;
    assert_true(dInitODE2(0));
    mim_penetration_t *pen = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_penetration_open(&pen, &err), 0);
    for (int d = 0; d < 4; d++) {
        world_t w;
        world_build(&w, (mim_pairs_density_t)d);
        for (uint32_t i = 0; i < w.n_prior; i++) mim_penetration_learn(pen, w.prior + (size_t)i * 3 * MIM_PAIR_JOINTS, w.allowed);
        const uint32_t n = 300;
        double *j1 = malloc(n * 3 * MIM_PAIR_JOINTS * sizeof *j1), *j2 = malloc(n * 3 * MIM_PAIR_JOINTS * sizeof *j2);
        double *l1 = malloc(n * sizeof *l1), *l2 = malloc(n * sizeof *l2);
        const double *seed = w.prior + 20 * 3 * MIM_PAIR_JOINTS;
        mim_rng_t r;
        mim_rng_seed(&r, 8, 0);
        mim_mh_stats_t st;
        assert_int_equal(mim_pairs_chain_run(&w.target, seed, &r, pen, n, j1, l1, &st, NULL, &err), 0);
        double accept = (double)st.accepted / st.steps;
        print_message("%s: acceptance %.2f, %.0f%% of proposals of density 0, log f0 %.2f\n", mim_pairs_density_names[d],
                      accept, 100.0 * st.zero / st.steps, st.seed_log_density);
        assert_true(accept > 0.02);
        double moved = 0;
        for (uint32_t i = 0; i < n; i++) {
            const double *x = j1 + (size_t)i * 3 * MIM_PAIR_JOINTS;
            assert_true(l1[i] >= st.seed_log_density - log(w.target.opt.c) - 1e-9);
            assert_true(dist3(x + 3 * 2, seed + 3 * 2) < 1e-12); /* A's pelvis holds */
            for (int k = 0; k < MIM_PAIR_JOINTS; k++) {
                int parent = mim_pairs_parent[k % MIM_PAIR_PERSON_JOINTS];
                if (parent < 0) continue;
                int pk = parent + (k >= MIM_PAIR_PERSON_JOINTS ? MIM_PAIR_PERSON_JOINTS : 0);
                assert_true(fabs(dist3(x + 3 * k, x + 3 * pk) - dist3(seed + 3 * k, seed + 3 * pk)) < 1e-9);
            }
            moved = fmax(moved, dist3(x + 3 * 7, seed + 3 * 7)); /* A's left wrist */
        }
        assert_true(moved > 0.02);
        mim_rng_seed(&r, 8, 0);
        assert_int_equal(mim_pairs_chain_run(&w.target, seed, &r, pen, n, j2, l2, &st, NULL, &err), 0);
        assert_memory_equal(j1, j2, n * 3 * MIM_PAIR_JOINTS * sizeof *j1);
        assert_memory_equal(l1, l2, n * sizeof *l1);
        /* an invalid seed (a knee bent the wrong way, and more) has density 0 */
        mim_pairs_pose_t pose;
        mim_pairs_pose_rest(seed, &pose);
        for (int g = 1; g < MIM_PAIRS_ROT; g++) pose.rot[0][g] = mim_quat_axis_angle(mim_v3(1, 0, 0), 2.5);
        double broken[3 * MIM_PAIR_JOINTS];
        mim_pairs_pose_joints(&pose, broken);
        assert_int_equal(mim_pairs_chain_run(&w.target, broken, &r, pen, 10, j2, l2, &st, NULL, &err), MIM_EINVAL);
        free(j1), free(j2), free(l1), free(l2);
        world_free(&w);
    }
    mim_penetration_close(&pen);
    dCloseODE();
}

/* Seeds lifted from annotations (lift.c): pose-pairs of another motion
 * than the prior frames', seen by a camera of the focal length and centre
 * the lifting assumes, lift to pairs with the prior's bone lengths whose
 * joints lie on their pixels' rays (the annotation seen again: every
 * joint but those of a bone laid at its length where its ray passes too
 * far), within the joint limits (a finite prior density); 2 px of noise
 * still gives a valid lifting; the same generator gives the same bytes. */
static void test_lift(void **s)
{
    (void)s;
    world_t w;
    world_build(&w, MIM_DENSITY_PRIOR);
    double len[MIM_PAIR_PERSON_JOINTS];
    mim_pairs_bone_lengths(w.prior, w.n_prior, len);
    double rest[3 * MIM_PAIR_JOINTS], shown[3 * MIM_PAIR_JOINTS], uv[2 * MIM_PAIR_JOINTS], out[3 * MIM_PAIR_JOINTS],
        again[3 * MIM_PAIR_JOINTS];
    mim_rng_t r, cams;
    mim_rng_seed(&r, 9, 0);
    sp_random_pair(&r, 0.0, rest); /* the world's rest pair: its bone lengths */
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++) {
        int parent = mim_pairs_parent[k];
        assert_true(fabs(len[k] - (parent < 0 ? 0.0 : dist3(rest + 3 * k, rest + 3 * parent))) < 1e-9);
    }
    mim_rng_seed(&cams, 4, 0);
    int on_ray = 0, joints = 0, valid = 0, noisy = 0;
    for (uint32_t f = 0; f < 40; f++) {
        /* another motion: other axes, larger turns, B nearer */
        mim_pairs_pose_t pose;
        mim_pairs_pose_rest(rest, &pose);
        for (int p = 0; p < 2; p++)
            for (int g = 1; g < MIM_PAIRS_ROT; g++) {
                double ph = 0.91 * g + 0.4 * p + 0.5 * f;
                pose.rot[p][g] = mim_quat_axis_angle(mim_v3_normalize(mim_v3(1, 0.6 * cos(ph), 0.4 * sin(ph))), 0.5 * sin(ph));
            }
        pose.root[1][2] += 0.3;
        mim_pairs_pose_joints(&pose, shown);
        mim_pairs_camera_t cam;
        assert_int_equal(mim_pairs_camera_random(&cams, shown, &cam), 0);
        cam.focal_px = 0.75 * cam.width; /* what the lifting assumes (cx, cy: the image's centre) */
        if (!mim_pairs_project(&cam, shown, uv)) continue;
        mim_rng_t lr;
        mim_rng_seed(&lr, 3, f);
        if (mim_pairs_lift(&w.target, uv, cam.width, cam.height, len, &lr, out)) continue;
        valid++;
        mim_rng_seed(&lr, 3, f);
        assert_int_equal(mim_pairs_lift(&w.target, uv, cam.width, cam.height, len, &lr, again), 0);
        assert_memory_equal(out, again, sizeof out);
        uint32_t invalid;
        mim_pairs_validity_excess(w.validity, out, &invalid);
        assert_true(invalid <= w.target.opt.max_invalid);
        for (int k = 0; k < MIM_PAIR_JOINTS; k++) {
            int parent = mim_pairs_parent[k % MIM_PAIR_PERSON_JOINTS];
            if (parent >= 0) {
                int pk = parent + (k >= MIM_PAIR_PERSON_JOINTS ? MIM_PAIR_PERSON_JOINTS : 0);
                assert_true(fabs(dist3(out + 3 * k, out + 3 * pk) - len[k % MIM_PAIR_PERSON_JOINTS]) < 1e-9);
            }
            /* mimic's frame back to the camera's: a half turn about x */
            const double *j = out + 3 * k;
            double u = cam.focal_px * j[0] / -j[2] + cam.cx, v = cam.focal_px * -j[1] / -j[2] + cam.cy;
            on_ray += hypot(u - uv[2 * k], v - uv[2 * k + 1]) < 1e-6;
            joints++;
        }
        for (int k = 0; k < 2 * MIM_PAIR_JOINTS; k++) uv[k] += 2.0 * mim_rng_gauss(&cams);
        mim_rng_seed(&lr, 3, f);
        noisy += !mim_pairs_lift(&w.target, uv, cam.width, cam.height, len, &lr, again);
    }
    print_message("%d of 40 lifted, %d of %d joints on their rays, %d with 2 px noise\n", valid, on_ray, joints, noisy);
    assert_true(valid >= 30 && noisy >= valid - 5);
    assert_true(on_ray >= 0.9 * joints);
    world_free(&w);
}

/* Bone lengths from one take's annotations: a take whose arms are 1.3
 * times the prior's (another skeleton) shows them so, a take of the
 * prior's own bones shows those, the legs keep the prior's metres, and a
 * take with too few annotations keeps the prior's lengths. */
static void test_lengths_2d(void **s)
{
    (void)s;
    mim_rng_t r, cams;
    mim_rng_seed(&r, 9, 0);
    double rest[3 * MIM_PAIR_JOINTS], longer[3 * MIM_PAIR_JOINTS], len[MIM_PAIR_PERSON_JOINTS];
    sp_random_pair(&r, 0.0, rest);
    mim_pairs_bone_lengths(rest, 1, len);
    memcpy(longer, rest, sizeof rest);
    static const char *const arms[2][3] = {{"l_shoulder", "l_elbow", "l_wrist"}, {"r_shoulder", "r_elbow", "r_wrist"}};
    for (int p = 0; p < 2; p++)
        for (int side = 0; side < 2; side++) {
            double *j[3];
            for (int k = 0; k < 3; k++) j[k] = longer + 3 * (MIM_PAIR_PERSON_JOINTS * p + mim_sample_joint_index(arms[side][k]));
            double fore[3];
            for (int c = 0; c < 3; c++) fore[c] = j[2][c] - j[1][c];
            for (int c = 0; c < 3; c++) j[1][c] = j[0][c] + 1.3 * (j[1][c] - j[0][c]);
            for (int c = 0; c < 3; c++) j[2][c] = j[1][c] + 1.3 * fore[c];
        }
    enum { FRAMES = 60 };
    mim_pairs_annotations_t a = {.width = 1920, .height = 1080};
    a.take = calloc(2 * FRAMES + 3, sizeof *a.take);
    a.points = malloc((2 * FRAMES + 3) * 2 * MIM_PAIR_JOINTS * sizeof *a.points);
    mim_rng_seed(&cams, 4, 0);
    for (uint32_t take = 0; take < 3; take++)
        for (uint32_t f = 0; f < (take == 2 ? 3u : FRAMES); f++) {
            mim_pairs_pose_t pose;
            mim_pairs_pose_rest(take == 0 ? longer : rest, &pose);
            for (int p = 0; p < 2; p++)
                for (int g = 1; g < MIM_PAIRS_ROT; g++) {
                    double ph = 0.91 * g + 0.4 * p + 0.5 * f;
                    pose.rot[p][g] = mim_quat_axis_angle(mim_v3_normalize(mim_v3(1, 0.6 * cos(ph), 0.4 * sin(ph))), 0.6 * sin(ph));
                }
            pose.root[1][2] += 0.3;
            double shown[3 * MIM_PAIR_JOINTS];
            mim_pairs_pose_joints(&pose, shown);
            mim_pairs_camera_t cam;
            assert_int_equal(mim_pairs_camera_random(&cams, shown, &cam), 0);
            if (!mim_pairs_project(&cam, shown, a.points + (size_t)a.n * 2 * MIM_PAIR_JOINTS)) continue;
            a.take[a.n++] = take;
        }
    double est[3][MIM_PAIR_PERSON_JOINTS];
    for (uint32_t take = 0; take < 3; take++) mim_pairs_bone_lengths_2d(&a, take, len, est[take]);
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++) {
        const char *name = mim_sample_joint_names[k];
        const int arm = strstr(name, "elbow") || strstr(name, "wrist");
        if (len[k] < 0.15) continue; /* short bones: the 2D noise of a pixel is a large share */
        print_message("%-10s prior %.3f  take 0 %.3f  take 1 %.3f\n", name, len[k], est[0][k], est[1][k]);
        assert_true(fabs(est[1][k] / len[k] - 1) < 0.1);
        assert_true(fabs(est[0][k] / len[k] - (arm ? 1.3 : 1.0)) < 0.1);
    }
    assert_memory_equal(est[2], len, sizeof len); /* 3 annotations: too few */
    free(a.take), free(a.points);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mh_matches_toy_density), cmocka_unit_test(test_mh_truncation),
        cmocka_unit_test(test_pose_model),             cmocka_unit_test(test_seed_jitter),
        cmocka_unit_test(test_validity),
        cmocka_unit_test(test_penetration_allowance),  cmocka_unit_test(test_likelihood),
        cmocka_unit_test(test_chains),                 cmocka_unit_test(test_lift),
        cmocka_unit_test(test_lengths_2d),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
