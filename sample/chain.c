/* A chain over pose-pairs (seed 002 Sections 3-5): the posterior of eq. 1
 * (the physical prior of eq. 2 times the likelihood of eqs. 6 and 9), the
 * velocity-biased proposal of eq. 12 over the pose model's 24 free groups,
 * run by mh.c with eq. 11's truncation around the seed. */
#include "mim_sample_mcmc.h"

#include <math.h>
#include <string.h>

const char *const mim_pairs_density_names[4] = {"ic", "cartesian", "shape", "prior"};

int mim_pairs_density_parse(const char *name)
{
    for (int d = 0; d < 4; d++)
        if (name && !strcmp(name, mim_pairs_density_names[d])) return d;
    return -1;
}

void mim_pairs_sampler_defaults(mim_pairs_sampler_options_t *o)
{
    memset(o, 0, sizeof *o);
    o->density = MIM_DENSITY_IC;
    o->views = 8;
    o->sigma_l = MIM_PAIRS_DEFAULT_SIGMA_L;
    o->cone = MIM_VIEW_DEFAULT_SIGMA;
    o->sigma_p = 0.05, o->alpha = 10, o->max_invalid = 8, o->c = 100; /* the paper's defaults */
    /* measured on cmu-pairs (bench/RESULTS.md): the paper's units are not
     * given, and in mimic's (2D pairs at unit RMS radius) sigma_l = 0.01
     * makes a change of 0.01 in d_I cost 50 in log f, so no chain moves;
     * the steps give 20-40 % acceptance */
    o->sigma0_rot = 0.02, o->sigma0_trans = 0.01;
    o->velocity_scale = 0.05;
}

/* eq. 2 in logs: -INFINITY when isvalid = 0. */
static double log_prior(const mim_pairs_target_t *t, mim_penetration_t *pen, const double *joints)
{
    uint32_t invalid;
    double excess = mim_pairs_validity_excess(t->validity, joints, &invalid);
    if (invalid > t->opt.max_invalid) return -INFINITY;
    double eta = pen ? mim_penetration_pair(pen, joints, t->allowed) : 0.0;
    return -(excess + t->opt.alpha * eta * eta) / (2 * t->opt.sigma_p * t->opt.sigma_p);
}

double mim_pairs_log_density(const mim_pairs_target_t *t, mim_penetration_t *pen, const double *joints,
                             const double *views, uint32_t m, uint32_t *nearest)
{
    double lp = log_prior(t, pen, joints);
    if (lp == -INFINITY || !t->evidence || t->opt.density == MIM_DENSITY_PRIOR) return lp;
    return lp + mim_pairs_log_likelihood(t->evidence, t->opt.density, t->opt.sigma_l, t->opt.cone, joints, views, m, nearest);
}

typedef struct chain {
    const mim_pairs_target_t *t;
    mim_penetration_t *pen;
    double views[2 * MIM_PAIRS_MAX_VIEWS];
    uint32_t m;
    double *out_joints, *out_log_density;
} chain_t;

static void move(void *ctx, const void *from, const double *eps, void *to)
{
    (void)ctx;
    const mim_pairs_pose_t *a = from;
    mim_pairs_pose_t *b = to;
    memcpy(b, a, sizeof *b);
    for (int g = 0; g < MIM_PAIRS_GROUPS; g++) {
        const double *e = eps + 3 * g;
        if (g >= MIM_PAIRS_GROUP_TRANS(0)) {
            for (int c = 0; c < 3; c++) b->root[g - MIM_PAIRS_GROUP_TRANS(0)][c] += e[c];
            continue;
        }
        double angle = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
        if (angle == 0) continue;
        /* exp(eps) on the left: undone by exp(-eps), so eps -> -eps reverses the move */
        mim_quat q = mim_quat_axis_angle(mim_v3(e[0] / angle, e[1] / angle, e[2] / angle), angle);
        mim_quat *r = &b->rot[g / MIM_PAIRS_ROT][g % MIM_PAIRS_ROT];
        *r = mim_quat_normalize(mim_quat_mul(q, *r));
    }
}

void mim_pairs_seed_jitter(const double *pair, double rot_sd, double trans_sd, mim_rng_t *rng, double *out)
{
    mim_pairs_pose_t rest, edited;
    mim_pairs_pose_rest(pair, &rest);
    double eps[3 * MIM_PAIRS_GROUPS];
    for (int g = 0; g < MIM_PAIRS_GROUPS; g++) {
        double sd = !mim_pairs_group_free(g) ? 0.0 : g >= MIM_PAIRS_GROUP_TRANS(0) ? trans_sd : rot_sd;
        for (int c = 0; c < 3; c++) eps[3 * g + c] = sd * mim_rng_gauss(rng);
    }
    move(NULL, &rest, eps, &edited);
    mim_pairs_pose_joints(&edited, out);
}

static double rms_radius(const double *joints)
{
    double c[3] = {0, 0, 0}, s = 0;
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int k = 0; k < 3; k++) c[k] += joints[3 * i + k] / MIM_PAIR_JOINTS;
    for (int i = 0; i < MIM_PAIR_JOINTS; i++)
        for (int k = 0; k < 3; k++) s += (joints[3 * i + k] - c[k]) * (joints[3 * i + k] - c[k]);
    return sqrt(s / MIM_PAIR_JOINTS);
}

static double evaluate(void *ctx, const void *state, double floor, double *sig2)
{
    chain_t *ch = ctx;
    const mim_pairs_target_t *t = ch->t;
    const mim_pairs_sampler_options_t *o = &t->opt;
    double joints[3 * MIM_PAIR_JOINTS];
    mim_pairs_pose_joints(state, joints);
    double lp = log_prior(t, ch->pen, joints);
    /* the likelihood is at most 1 (eq. 9's kernel): a prior below the floor decides */
    if (lp < floor) return -INFINITY;
    uint32_t nearest[MIM_PAIRS_MAX_VIEWS];
    double vel[MIM_PAIRS_GROUPS] = {0}, lf = lp;
    int biased = t->evidence && o->density != MIM_DENSITY_PRIOR;
    if (biased) {
        lf += mim_pairs_log_likelihood(t->evidence, o->density, o->sigma_l, o->cone, joints, ch->views, ch->m, nearest);
        if (lf > -INFINITY) mim_pairs_velocity(t->evidence, nearest, ch->m, rms_radius(joints), vel);
    }
    /* eq. 12 (the prior alone: the unbiased proposal, as the paper samples it) */
    for (int g = 0; g < MIM_PAIRS_GROUPS; g++) {
        double s0 = g >= MIM_PAIRS_GROUP_TRANS(0) ? o->sigma0_trans : o->sigma0_rot;
        sig2[g] = mim_pairs_group_free(g) ? s0 * s0 + o->velocity_scale * o->velocity_scale * vel[g] : 0.0;
    }
    return lf;
}

static void emit(void *ctx, uint32_t i, const void *state, double log_f)
{
    chain_t *ch = ctx;
    mim_pairs_pose_joints(state, ch->out_joints + (size_t)i * 3 * MIM_PAIR_JOINTS);
    ch->out_log_density[i] = log_f;
}

int mim_pairs_chain_run(const mim_pairs_target_t *t, const double *seed, mim_rng_t *rng, mim_penetration_t *pen,
                        uint32_t n, double *out_joints, double *out_log_density, mim_mh_stats_t *stats,
                        _Atomic uint64_t *done, mim_error_t *err)
{
    chain_t ch = {.t = t, .pen = pen, .out_joints = out_joints, .out_log_density = out_log_density};
    /* eq. 6's views, drawn from eq. 5's KDE once for the chain */
    if (t->evidence && t->opt.density != MIM_DENSITY_PRIOR) {
        ch.m = t->opt.views < MIM_PAIRS_MAX_VIEWS ? t->opt.views : MIM_PAIRS_MAX_VIEWS;
        for (uint32_t v = 0; v < ch.m; v++)
            mim_pairs_view_draw(mim_pairs_evidence_views(t->evidence), mim_pairs_evidence_count(t->evidence),
                                MIM_VIEW_DEFAULT_SIGMA, rng, &ch.views[2 * v], &ch.views[2 * v + 1]);
    }
    mim_pairs_pose_t start;
    mim_pairs_pose_rest(seed, &start);
    const mim_mh_ops_t ops = {MIM_PAIRS_GROUPS, 3, sizeof(mim_pairs_pose_t), move, evaluate, emit};
    return mim_mh_run(&ops, &ch, &start, t->opt.c, rng, n, stats, done, err);
}
