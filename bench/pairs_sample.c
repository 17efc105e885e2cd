/* The seed 002 sampler's speed (issue 14, sample/mim_sample_mcmc.h):
 * samples per second of one chain on one thread for each density, a
 * profile of a step's pieces, and the likelihood the paper describes
 * without its speed-up as a reference measured in the same run (the
 * machine is shared: the ratios are what holds). Prints figures; never
 * passes or fails. The paper reports about 10 samples a second on a
 * 4-core i7 (Section 6, "Implementation Details"); the target is
 * 100 a second per core.
 *
 * Data: both takes of ../shared/data/cmu-pairs (20_11 + 21_11, 20_03 +
 * 21_03; vest/'s joint motion reader, sample/'s joint map and unit guess,
 * as `mimic pairs` reads them), or with --synthetic (or without the data)
 * two synthetic takes of as many frames, posed by forward kinematics with
 * joint rotations on slow sines. Annotations as `mimic pairs annotate
 * --video --every 1 --views 6` makes them: every frame of both takes seen
 * by 6 video cameras (a random camera that follows the pair, a new shot
 * when it loses it), 2 px Gaussian noise. Prior (joint limits, torso,
 * eta's allowances, the chains' seeds): every 10th frame of the takes.
 *
 * Speed: for each density, mim_pairs_chain_run (defaults: 8 views) on one
 * thread, --runs runs of --samples samples from different generator
 * streams (each a prior frame as seed, as `mimic pairs sample` picks it);
 * the median of the runs' samples per second, the pooled acceptance.
 *
 * A proposal whose prior already lies below eq. 11's floor skips the
 * likelihood, so a chain that refuses its proposals runs faster than one
 * that moves; hence also a modelled step that always evaluates it: the
 * prior density's measured step (proposal, kinematics, validity,
 * penetration, acceptance, output) plus the likelihood's and eq. 12's
 * median times per call.
 *
 * Profile: the median time per call over states (every prior frame and
 * every 10th state of the prior density's chains, which move; a
 * likelihood density's chain that refuses everything would only give its
 * seed again), each with its own 8 views drawn from the annotations' view
 * density (eq. 5): forward kinematics, joint-angle validity, penetration
 * (ODE), the likelihood of each density, eq. 12's variances, and inside
 * the IC likelihood what can be called from outside: the 2D Delaunay
 * triangulation of a view's projection (mim_ic_build, qhull) and d_I of
 * eq. 8 (mim_ic_distance), with an estimate of the short list's
 * alignments (mim_pairs2d_align). Calls per step: 2 kinematics (the
 * proposal's, and the chain's output), 1 validity, 1 penetration, 1
 * likelihood; inside it, per view, one triangulation and 8 d_I
 * (likelihood.c's short list of 8).
 *
 * Reference: eq. 9 as the paper writes it before "in practice": for each
 * view, the max over ALL annotations of d_I against each annotation's own
 * triangulation, after eq. 9's M (no cone of similar views, no short
 * list). Built here from public functions, the likelihood's own 2D
 * projection, normalisation and rotation (mim_pairs2d_*) among them, so
 * that both likelihoods compare the same projections.
 *
 * usage: bench_pairs_sample [--data DIR | --synthetic] [--runs R] [--samples N]
 *                           [--naive-states K]
 * DIR: the shared data folder that holds cmu-pairs/ (default
 * $MIMIC_SHARED_DATA, else ../shared/data beside the source tree). */
#include "bench_data.h"
#include "synthetic_pairs.h"
#include "mim_core.h"
#include "mim_sample_mcmc.h"
#include "mim_vest_motion.h"

#include <math.h>
#include <ode/ode.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define J MIM_PAIR_JOINTS
#define PJ MIM_PAIR_PERSON_JOINTS
#define ANN_VIEWS 6     /* cameras per take, as annotate --views 6 */
#define NOISE_PX 2.0    /* annotate's default */
#define PRIOR_EVERY 10  /* annotate's and sample's default --every */
#define CHAIN_VIEWS 8   /* the sampler's default m */
#define SHORTLIST 8     /* likelihood.c's d_I calls per view */
#define SEED_TRIES 32   /* prior frames a chain tries for a seed, as pairs sample */
#define STATE_EVERY 10  /* chain states profiled: every 10th (at most about 300) */

typedef struct take {
    char name[32];
    double *frames; /* n * 34 * 3, metres */
    uint32_t n;
} take_t;

/* ---- reading a take, as cli/pairs_input.c does ---- */
static const float *joint_at(const mim_vest_joint_motion_t *m, uint32_t f, int32_t j)
{
    return m->positions + 3 * ((size_t)f * m->n_joints + (size_t)j);
}

static int read_person(const char *path, mim_vest_joint_motion_t *m, int32_t map[PJ], double *scale)
{
    mim_error_t err = {0};
    if (mim_vest_joint_motion_read_bvh(m, path, &err) ||
        mim_pair_joint_map((const char(*)[64])m->name, m->n_joints, NULL, path, map, NULL, &err)) {
        fprintf(stderr, "bench_pairs_sample: %s\n", mim_error_text(&err));
        return -1;
    }
    /* the person's size in the first frame: head to the middle of the ankles */
    const float *h = joint_at(m, 0, map[0]), *la = joint_at(m, 0, map[13]), *ra = joint_at(m, 0, map[14]);
    double d2 = 0;
    for (int c = 0; c < 3; c++) d2 += (h[c] - 0.5 * (la[c] + ra[c])) * (h[c] - 0.5 * (la[c] + ra[c]));
    if (mim_pair_unit_guess(sqrt(d2), scale, NULL)) {
        fprintf(stderr, "bench_pairs_sample: %s: no unit fits a person of %.3g units\n", path, sqrt(d2));
        return -1;
    }
    return 0;
}

static int read_take(const char *dir, const char *fa, const char *fb, take_t *t)
{
    char pa[4200], pb[4200];
    snprintf(pa, sizeof pa, "%s/%s", dir, fa);
    snprintf(pb, sizeof pb, "%s/%s", dir, fb);
    mim_vest_joint_motion_t ma = {0}, mb = {0};
    int32_t map_a[PJ], map_b[PJ];
    double sa, sb;
    int rc = -1;
    if (read_person(pa, &ma, map_a, &sa) || read_person(pb, &mb, map_b, &sb)) goto done;
    if (ma.n_frames != mb.n_frames || !ma.n_frames) {
        fprintf(stderr, "bench_pairs_sample: %s and %s: %u and %u frames\n", pa, pb, ma.n_frames, mb.n_frames);
        goto done;
    }
    t->n = ma.n_frames;
    if (!(t->frames = malloc((size_t)t->n * 3 * J * sizeof *t->frames))) goto done;
    for (uint32_t f = 0; f < t->n; f++)
        for (int j = 0; j < PJ; j++) {
            const float *a = joint_at(&ma, f, map_a[j]), *b = joint_at(&mb, f, map_b[j]);
            for (int c = 0; c < 3; c++)
                t->frames[(size_t)f * 3 * J + 3 * j + c] = a[c] * sa,
                t->frames[(size_t)f * 3 * J + 3 * (j + PJ) + c] = b[c] * sb;
        }
    snprintf(t->name, sizeof t->name, "%.*s", (int)(strcspn(fa, ".")), fa);
    rc = 0;
done:
    mim_vest_joint_motion_free(&ma);
    mim_vest_joint_motion_free(&mb);
    return rc;
}

/* ---- a synthetic take: forward kinematics on slow sines ---- */
static int synthetic_take(uint32_t n, int which, take_t *t)
{
    double rest[3 * J];
    sp_rest_pair(rest);
    if (!(t->frames = malloc((size_t)n * 3 * J * sizeof *t->frames))) return -1;
    t->n = n;
    snprintf(t->name, sizeof t->name, "synthetic %d", which + 1);
    for (uint32_t f = 0; f < n; f++) {
        mim_pairs_pose_t pose;
        mim_pairs_pose_rest(rest, &pose);
        for (int p = 0; p < 2; p++)
            for (int g = 1; g < MIM_PAIRS_ROT; g++) {
                double ph = 0.37 * g + 1.3 * p + 2.1 * which;
                mim_vec3 axis = mim_v3_normalize(mim_v3(1, 0.3 * sin(ph), 0.2 * cos(ph)));
                pose.rot[p][g] = mim_quat_axis_angle(axis, 0.4 * sin(0.03 * f + ph));
            }
        pose.rot[1][0] = mim_quat_axis_angle(mim_v3(0, 1, 0), 0.3 * sin(0.01 * f + which));
        pose.root[1][2] -= 0.25 * sin(0.015 * f + which);
        pose.root[1][0] += 0.15 * sin(0.011 * f);
        mim_pairs_pose_joints(&pose, t->frames + (size_t)f * 3 * J);
    }
    return 0;
}

/* ---- annotations, as `mimic pairs annotate --video` makes them ---- */
static int annotate(const take_t *takes, int n_takes, uint32_t views, uint64_t seed, mim_pairs_annotations_t *a,
                    uint32_t *shots)
{
    const mim_pairs_annotate_options_t opt = {views, 1, NOISE_PX, seed};
    memset(a, 0, sizeof *a);
    *shots = 0;
    for (int t = 0; t < n_takes; t++) {
        uint32_t bad = 0;
        if (mim_pairs_annotate_take(takes[t].frames, takes[t].n, 0, 1, (uint32_t)t, &opt, a, NULL, shots, &bad)) {
            fprintf(stderr, "bench_pairs_sample: %s frame %u: no annotation (no camera sees both people?)\n", takes[t].name, bad);
            return -1;
        }
    }
    return 0;
}

/* eq. 9's M applied: b turned onto a (normalised 2D pose-pairs). */
static void align_rotate(const double *a, const double *b, double *out)
{
    double c, sn;
    mim_pairs2d_align(a, b, &c, &sn);
    mim_pairs2d_rotate(b, c, sn, out);
}

/* The annotations for the reference: each normalised and triangulated. */
typedef struct naive {
    uint32_t n;
    double (*pts)[2 * J];
    mim_ic_t *ic;
} naive_t;

static int naive_build(const mim_pairs_annotations_t *a, naive_t *nv)
{
    nv->n = 0;
    nv->pts = malloc((size_t)a->n * sizeof *nv->pts), nv->ic = malloc((size_t)a->n * sizeof *nv->ic);
    if (!nv->pts || !nv->ic) return -1;
    for (uint32_t i = 0; i < a->n; i++) {
        mim_error_t err = {0};
        if (mim_pairs2d_normalise(a->points + (size_t)i * 2 * J, nv->pts[nv->n]) && !mim_ic_build(nv->pts[nv->n], 2, &nv->ic[nv->n], &err))
            nv->n++;
    }
    return 0;
}

/* The view's projection of joints, normalised into q; 0 when degenerate. */
static int view_projection(const double R[9], const double *joints, double psi, double phi, double *q)
{
    double dir[3], uv[2 * J];
    mim_pairs_view_direction(R, psi, phi, dir);
    mim_pairs2d_project(joints, dir, uv);
    return mim_pairs2d_normalise(uv, q) > 0;
}

/* eq. 6 with eq. 9 over every annotation (the paper's likelihood before
 * its speed-up); best (m entries, may be NULL) gets each view's d_I. */
static double naive_log_likelihood(const naive_t *nv, double sigma_l, const double *joints, const double *views, uint32_t m,
                                   double *best)
{
    double R[9], terms[MIM_PAIRS_MAX_VIEWS], top = -INFINITY;
    if (mim_pairs_local_frame(joints, R)) return -INFINITY;
    for (uint32_t v = 0; v < m; v++) {
        double q[2 * J], r[2 * J], d = INFINITY;
        mim_ic_t tq;
        mim_error_t err = {0};
        if (view_projection(R, joints, views[2 * v], views[2 * v + 1], q) && !mim_ic_build(q, 2, &tq, &err))
            for (uint32_t i = 0; i < nv->n; i++) {
                align_rotate(nv->pts[i], q, r);
                double di = mim_ic_distance(nv->pts[i], &nv->ic[i], r, &tq, MIM_IC_DEFAULT_BETA);
                if (di < d) d = di;
            }
        if (best) best[v] = d;
        terms[v] = -d / (2 * sigma_l * sigma_l);
        if (terms[v] > top) top = terms[v];
    }
    if (top == -INFINITY) return -INFINITY;
    double s = 0;
    for (uint32_t v = 0; v < m; v++) s += exp(terms[v] - top);
    return top + log(s / m);
}

/* ---- the profile ---- */
typedef struct state {
    double joints[3 * J];
    mim_pairs_pose_t pose;
    double views[2 * CHAIN_VIEWS];
    double q[CHAIN_VIEWS][2 * J]; /* the views' normalised projections */
    mim_ic_t tq[CHAIN_VIEWS];     /* and their triangulations */
    int ok[CHAIN_VIEWS];          /* 0: a degenerate projection */
    uint32_t ann[CHAIN_VIEWS];    /* an annotation (of the reference's list) to measure d_I against */
    double r[CHAIN_VIEWS][2 * J]; /* q[v] turned onto it by eq. 9's M */
    uint32_t cone[CHAIN_VIEWS]; /* annotations whose view is within sigma_v of the view's */
} state_t;

enum { P_FK, P_VALIDITY, P_PENETRATION, P_L_IC, P_L_CART, P_L_SHAPE, P_DELAUNAY, P_DI, P_ALIGN, P_VELOCITY, P_NAIVE, PIECES };

typedef struct prof {
    const mim_pairs_validity_t *validity;
    const mim_pairs_evidence_t *ev_ic, *ev_shape;
    const double *allowed;
    mim_penetration_t *pen;
    const naive_t *nv;
    double sigma_l, cone; /* the sampler's defaults: eq. 9's bandwidth, its cone of similar views */
} prof_t;

static volatile double sink;

/* One piece at state s, reps times: the calls made. */
static int piece_run(const prof_t *p, int piece, state_t *s, int reps)
{
    double acc = 0, joints[3 * J];
    uint32_t invalid, nearest[CHAIN_VIEWS];
    int calls = 0;
    for (int k = 0; k < reps; k++) switch (piece) {
        case P_FK: mim_pairs_pose_joints(&s->pose, joints), acc += joints[0], calls++; break;
        case P_VALIDITY: acc += mim_pairs_validity_excess(p->validity, s->joints, &invalid), calls++; break;
        case P_PENETRATION: acc += mim_penetration_pair(p->pen, s->joints, p->allowed), calls++; break;
        case P_L_IC:
        case P_L_CART:
            acc += mim_pairs_log_likelihood(p->ev_ic, piece == P_L_IC ? MIM_DENSITY_IC : MIM_DENSITY_CARTESIAN, p->sigma_l, p->cone,
                                            s->joints, s->views, CHAIN_VIEWS, nearest);
            calls++;
            break;
        case P_L_SHAPE:
            acc += mim_pairs_log_likelihood(p->ev_shape, MIM_DENSITY_SHAPE, p->sigma_l, p->cone, s->joints, s->views, CHAIN_VIEWS,
                                            nearest);
            calls++;
            break;
        case P_DELAUNAY:
            for (int v = 0; v < CHAIN_VIEWS; v++) {
                mim_error_t err = {0};
                mim_ic_t t;
                if (!s->ok[v]) continue;
                acc += mim_ic_build(s->q[v], 2, &t, &err) + t.n_edges, calls++;
            }
            break;
        case P_DI:
            for (int v = 0; v < CHAIN_VIEWS; v++) {
                if (!s->ok[v]) continue;
                acc += mim_ic_distance(p->nv->pts[s->ann[v]], &p->nv->ic[s->ann[v]], s->r[v], &s->tq[v], MIM_IC_DEFAULT_BETA);
                calls++;
            }
            break;
        case P_ALIGN:
            for (int v = 0; v < CHAIN_VIEWS; v++) {
                if (!s->ok[v]) continue;
                for (uint32_t i = 0; i < 8; i++)
                    {
                        double c, sn;
                        acc += mim_pairs2d_align(p->nv->pts[(s->ann[v] + 379 * i) % p->nv->n], s->q[v], &c, &sn), calls++;
                    }
            }
            break;
        case P_VELOCITY: {
            double out[MIM_PAIRS_GROUPS];
            /* annotations at random: the cost does not depend on which */
            for (int v = 0; v < CHAIN_VIEWS; v++) nearest[v] = s->ann[v] % mim_pairs_evidence_count(p->ev_ic);
            mim_pairs_velocity(p->ev_ic, nearest, CHAIN_VIEWS, 0.5, out);
            acc += out[1], calls++;
            break;
        }
        case P_NAIVE: acc += naive_log_likelihood(p->nv, p->sigma_l, s->joints, s->views, CHAIN_VIEWS, NULL), calls++; break;
        }
    sink = acc;
    return calls;
}

/* The median over states[0..n) of each piece's time per call (seconds),
 * reps[piece] calls a timing; the reference (P_NAIVE) at every
 * `stride`-th state only. The pieces take turns state by state, so that a
 * change of the machine's load falls on all of them alike; each is called
 * once untimed first, as a chain's caches hold what the previous step used. */
static int profile(const prof_t *p, state_t *st, uint32_t n, uint32_t stride, const int reps[PIECES], double out[PIECES])
{
    double *t = malloc((size_t)PIECES * n * sizeof *t);
    int k[PIECES] = {0};
    if (!t) return -1;
    for (uint32_t i = 0; i < n; i++)
        for (int piece = 0; piece < PIECES; piece++) {
            if (piece == P_NAIVE && i % stride) continue;
            /* one call first, untimed: a chain calls each piece step after
             * step, with the same views (the reference scans everything anyway) */
            if (piece != P_NAIVE) piece_run(p, piece, &st[i], 1);
            double t0 = mim_now();
            int calls = piece_run(p, piece, &st[i], reps[piece]);
            double dt = mim_now() - t0;
            if (calls) t[(size_t)piece * n + k[piece]++] = dt / calls;
        }
    for (int piece = 0; piece < PIECES; piece++) out[piece] = k[piece] ? bench_median(t + (size_t)piece * n, k[piece]) : NAN;
    free(t);
    return 0;
}

/* ---- the chains ---- */
typedef struct speed {
    double per_s;             /* median over the runs */
    double lo, hi;            /* slowest and fastest run */
    double accept, zero;      /* pooled */
    uint32_t runs;
} speed_t;

/* runs chains of n samples each from the generator streams 0..runs-1;
 * keep (may be NULL) gets every run's states (runs * n * 34 * 3). */
static int chains(const mim_pairs_target_t *t, const double *prior, uint32_t n_prior, mim_penetration_t *pen,
                  uint32_t runs, uint32_t n, double *keep, speed_t *out)
{
    double *joints = malloc((size_t)n * 3 * J * sizeof *joints), *logd = malloc(n * sizeof *logd);
    double *rate = malloc(runs * sizeof *rate);
    uint64_t steps = 0, accepted = 0, zero = 0;
    int rc = -1;
    memset(out, 0, sizeof *out);
    if (!joints || !logd || !rate) goto done;
    for (uint32_t r = 0; r < runs; r++) {
        mim_rng_t rng;
        mim_rng_seed(&rng, 1, r);
        mim_mh_stats_t st;
        mim_error_t err = {0};
        int ok = -1;
        for (int attempt = 0; attempt < SEED_TRIES && ok; attempt++) {
            const double *seed = prior + (size_t)3 * J * mim_rng_below(&rng, n_prior);
            double t0 = mim_now();
            ok = mim_pairs_chain_run(t, seed, &rng, pen, n, joints, logd, &st, NULL, &err);
            rate[r] = n / (mim_now() - t0);
            if (ok && ok != MIM_EINVAL) break;
        }
        if (ok) {
            fprintf(stderr, "bench_pairs_sample: %s chain %u: %s\n", mim_pairs_density_names[t->opt.density], r,
                    mim_error_text(&err));
            goto done;
        }
        steps += st.steps, accepted += st.accepted, zero += st.zero;
        if (keep) memcpy(keep + (size_t)r * n * 3 * J, joints, (size_t)n * 3 * J * sizeof *joints);
    }
    out->runs = runs;
    out->accept = steps ? (double)accepted / steps : 0, out->zero = steps ? (double)zero / steps : 0;
    out->lo = out->hi = rate[0];
    for (uint32_t r = 0; r < runs; r++) out->lo = fmin(out->lo, rate[r]), out->hi = fmax(out->hi, rate[r]);
    out->per_s = bench_median(rate, (int)runs);
    rc = 0;
done:
    free(joints), free(logd), free(rate);
    return rc;
}

static void print_machine(void)
{
    char line[512], model[256] = "unknown";
    FILE *f = fopen("/proc/cpuinfo", "r");
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "model name", 10) && strchr(line, ':')) {
            snprintf(model, sizeof model, "%s", strchr(line, ':') + 2);
            model[strcspn(model, "\n")] = 0;
            break;
        }
    if (f) fclose(f);
    printf("machine: %s, load average %.2f (one chain, one thread)\n", model, bench_load_average());
}

static const char *data_dir(char *buf, size_t size)
{
    const char *env = getenv("MIMIC_SHARED_DATA");
    if (env) {
        snprintf(buf, size, "%s", env);
    } else {
        snprintf(buf, size, "%s", __FILE__);
        char *slash = strrchr(buf, '/');
        if (slash) *slash = 0;
        strncat(buf, "/../../shared/data", size - strlen(buf) - 1);
    }
    return buf;
}

int main(int argc, char **argv)
{
    char dbuf[4096], pdir[4200];
    const char *dir = NULL;
    int synthetic = 0;
    uint32_t runs = 7, samples = 400, naive_states = 24;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--data") && i + 1 < argc) dir = argv[++i];
        else if (!strcmp(argv[i], "--synthetic")) synthetic = 1;
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) runs = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--samples") && i + 1 < argc) samples = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--naive-states") && i + 1 < argc) naive_states = (uint32_t)strtoul(argv[++i], NULL, 10);
        else {
            fprintf(stderr, "usage: bench_pairs_sample [--data DIR | --synthetic] [--runs R] [--samples N] "
                            "[--naive-states K]\n");
            return 2;
        }
    }
    if (!runs || runs > 1000 || samples < 10 || samples > 1000000 || !naive_states) {
        fprintf(stderr, "bench_pairs_sample: runs 1..1000, samples 10..1000000, naive-states >= 1\n");
        return 2;
    }
    if (!dir) dir = data_dir(dbuf, sizeof dbuf);
    snprintf(pdir, sizeof pdir, "%s/cmu-pairs", dir);

    /* ---- motions ---- */
    take_t takes[2] = {{{0}, NULL, 0}, {{0}, NULL, 0}};
    const char *source = "cmu-pairs";
    char probe[4300];
    snprintf(probe, sizeof probe, "%s/20_11.bvh", pdir);
    FILE *pf = synthetic ? NULL : fopen(probe, "rb");
    if (pf) {
        fclose(pf);
        if (read_take(pdir, "20_11.bvh", "21_11.bvh", &takes[0]) || read_take(pdir, "20_03.bvh", "21_03.bvh", &takes[1]))
            return 1;
    } else {
        if (!synthetic) printf("(no %s: synthetic takes)\n", probe);
        source = "synthetic (forward kinematics, slow sines)";
        /* as many frames as the CMU takes */
        if (synthetic_take(233, 0, &takes[0]) || synthetic_take(275, 1, &takes[1])) return 1;
    }
    uint32_t n_prior = 0;
    for (int t = 0; t < 2; t++) n_prior += (takes[t].n + PRIOR_EVERY - 1) / PRIOR_EVERY;
    double *prior = malloc((size_t)n_prior * 3 * J * sizeof *prior);
    if (!prior) return 1;
    n_prior = 0;
    for (int t = 0; t < 2; t++)
        for (uint32_t f = 0; f < takes[t].n; f += PRIOR_EVERY)
            memcpy(prior + (size_t)n_prior++ * 3 * J, takes[t].frames + (size_t)f * 3 * J, 3 * J * sizeof *prior);

    /* ---- annotations, prior, evidence ---- */
    double t_setup = mim_now();
    mim_pairs_annotations_t ann;
    uint32_t shots = 0;
    if (annotate(takes, 2, ANN_VIEWS, 1, &ann, &shots)) return 1;
    mim_error_t err = {0};
    mim_pairs_validity_t *validity = NULL;
    mim_pairs_torso_t torso;
    mim_pairs_evidence_t *ev_ic = NULL, *ev_shape = NULL;
    uint32_t dropped = 0, dropped_s = 0;
    double t_ev = 0;
    if (mim_pairs_validity_learn(prior, n_prior, &validity, &err) || mim_pairs_torso_learn(prior, n_prior, &torso, &err)) {
        fprintf(stderr, "bench_pairs_sample: %s\n", mim_error_text(&err));
        return 1;
    }
    t_ev = mim_now();
    if (mim_pairs_evidence_build(&ann, &torso, MIM_DENSITY_IC, &ev_ic, &dropped, NULL, &err)) {
        fprintf(stderr, "bench_pairs_sample: %s\n", mim_error_text(&err));
        return 1;
    }
    t_ev = mim_now() - t_ev;
    if (mim_pairs_evidence_build(&ann, &torso, MIM_DENSITY_SHAPE, &ev_shape, &dropped_s, NULL, &err)) {
        fprintf(stderr, "bench_pairs_sample: %s\n", mim_error_text(&err));
        return 1;
    }
    naive_t nv;
    if (naive_build(&ann, &nv)) return 1;
    /* ODE's process-wide state: the program owns it; one context (this thread) */
    if (!dInitODE2(0)) {
        fprintf(stderr, "bench_pairs_sample: ODE does not initialise\n");
        return 1;
    }
    mim_penetration_t *pen = NULL;
    double *allowed = calloc(MIM_PENETRATION_ALLOWANCES, sizeof *allowed);
    if (!allowed || mim_penetration_open(&pen, &err)) {
        fprintf(stderr, "bench_pairs_sample: %s\n", allowed ? mim_error_text(&err) : "out of memory");
        return 1;
    }
    for (uint32_t i = 0; i < n_prior; i++) mim_penetration_learn(pen, prior + (size_t)i * 3 * J, allowed);
    t_setup = mim_now() - t_setup;

    print_machine();
    printf("data: %s: %s (%u frames), %s (%u frames)\n", source, takes[0].name, takes[0].n, takes[1].name, takes[1].n);
    printf("annotations: %u (every frame x %d video cameras, %u shots, %.0f px noise), %u in the evidence (%u without a "
           "view); reference list %u\n",
           ann.n, ANN_VIEWS, shots, NOISE_PX, mim_pairs_evidence_count(ev_ic), dropped, nv.n);
    printf("prior: %u frames (every %dth); chain: %d views per likelihood, sampler defaults; setup %.2f s (IC evidence "
           "%.2f s)\n\n",
           n_prior, PRIOR_EVERY, CHAIN_VIEWS, t_setup, t_ev);

    /* ---- chains ---- */
    mim_pairs_target_t target[4];
    speed_t sp[4];
    double *kept = malloc((size_t)runs * samples * 3 * J * sizeof *kept);
    if (!kept) return 1;
    for (int d = 0; d < 4; d++) {
        mim_pairs_sampler_defaults(&target[d].opt);
        target[d].opt.density = (mim_pairs_density_t)d;
        target[d].validity = validity, target[d].allowed = allowed;
        target[d].evidence = d == MIM_DENSITY_PRIOR ? NULL : d == MIM_DENSITY_SHAPE ? ev_shape : ev_ic;
        if (chains(&target[d], prior, n_prior, pen, runs, samples, d == MIM_DENSITY_PRIOR ? kept : NULL, &sp[d])) return 1;
    }
    printf("Speed: one chain, one thread, defaults, %u runs x %u samples (the median run; target 100 samples/s a core)\n\n",
           runs, samples);
    printf("| density | samples/s | runs (slowest - fastest) | ms / sample | acceptance | density-0 proposals |\n");
    printf("|---|---:|---|---:|---:|---:|\n");
    for (int d = 0; d < 4; d++)
        printf("| %s | %s%.0f%s | %.0f - %.0f | %.3f | %.3f | %.0f %% |\n", mim_pairs_density_names[d], d ? "" : "**",
               sp[d].per_s, d ? "" : "**", sp[d].lo, sp[d].hi, 1e3 / sp[d].per_s, sp[d].accept, 100 * sp[d].zero);
    printf("| paper (not measured here): about 10 samples/s on a 4-core i7 | | | | | |\n\n");
    printf("A proposal whose prior already lies below eq. 11's floor skips the likelihood: a chain that refuses most "
           "proposals (density-0 column) runs faster than one that moves; the step modelled below always evaluates it.\n\n");

    /* ---- profile states: the prior frames, then every 10th state of the
     * prior density's chains (they walk under the physical prior every
     * density shares; a likelihood density's chain that refuses its
     * proposals would only give its seed again) ---- */
    uint32_t every = runs * samples / 300 > STATE_EVERY ? runs * samples / 300 : STATE_EVERY;
    uint32_t n_chain_states = runs * samples / every, n_states = n_prior + n_chain_states;
    state_t *st = malloc((size_t)n_states * sizeof *st);
    if (!st) return 1;
    mim_pairs_sampler_options_t defaults;
    mim_pairs_sampler_defaults(&defaults);
    mim_rng_t rng;
    mim_rng_seed(&rng, 2, 0);
    const double *ev_views = mim_pairs_evidence_views(ev_ic);
    for (uint32_t i = 0; i < n_states; i++) {
        state_t *s = &st[i];
        const double *src = i < n_prior ? prior + (size_t)i * 3 * J : kept + (size_t)(i - n_prior) * every * 3 * J;
        memcpy(s->joints, src, sizeof s->joints);
        mim_pairs_pose_rest(s->joints, &s->pose);
        double R[9];
        int frame = !mim_pairs_local_frame(s->joints, R);
        for (int v = 0; v < CHAIN_VIEWS; v++) {
            mim_pairs_view_draw(ev_views, mim_pairs_evidence_count(ev_ic), MIM_VIEW_DEFAULT_SIGMA, &rng, &s->views[2 * v],
                                &s->views[2 * v + 1]);
            mim_error_t e2 = {0};
            s->ok[v] = frame && view_projection(R, s->joints, s->views[2 * v], s->views[2 * v + 1], s->q[v]) &&
                       !mim_ic_build(s->q[v], 2, &s->tq[v], &e2);
            s->ann[v] = (uint32_t)mim_rng_below(&rng, nv.n);
            if (s->ok[v]) align_rotate(nv.pts[s->ann[v]], s->q[v], s->r[v]);
            /* likelihood.c's cone: the annotations' views (eq. 4) within sigma_v */
            double psi = s->views[2 * v], phi = s->views[2 * v + 1], cone = cos(defaults.cone);
            double l[3] = {sin(phi) * cos(psi), cos(phi), sin(phi) * sin(psi)};
            s->cone[v] = 0;
            for (uint32_t i = 0; i < mim_pairs_evidence_count(ev_ic); i++) {
                double ap = ev_views[2 * i], aph = ev_views[2 * i + 1];
                s->cone[v] += sin(aph) * cos(ap) * l[0] + cos(aph) * l[1] + sin(aph) * sin(ap) * l[2] >= cone;
            }
        }
    }
    prof_t pr = {validity, ev_ic, ev_shape, allowed, pen, &nv, defaults.sigma_l, defaults.cone};
    uint32_t stride = n_states / naive_states ? n_states / naive_states : 1, n_naive = (n_states + stride - 1) / stride;
    double us[PIECES];
    static const int reps[PIECES] = {[P_FK] = 64, [P_VALIDITY] = 8, [P_PENETRATION] = 8, [P_L_IC] = 1, [P_L_CART] = 1,
                                     [P_L_SHAPE] = 1, [P_DELAUNAY] = 1, [P_DI] = 8, [P_ALIGN] = 1, [P_VELOCITY] = 64,
                                     [P_NAIVE] = 1};
    if (profile(&pr, st, n_states, stride, reps, us)) return 1;
    for (int piece = 0; piece < PIECES; piece++) us[piece] *= 1e6;
    double *cones = malloc((size_t)n_states * CHAIN_VIEWS * sizeof *cones);
    if (!cones) return 1;
    for (uint32_t i = 0; i < n_states * CHAIN_VIEWS; i++) cones[i] = st[i / CHAIN_VIEWS].cone[i % CHAIN_VIEWS];
    const double cone_med = bench_median(cones, (int)(n_states * CHAIN_VIEWS));
    free(cones);

    /* ---- a step that evaluates everything: the prior chain's measured
     * step (proposal, kinematics, validity, penetration, acceptance,
     * output) plus a likelihood and eq. 12's variances ---- */
    const double prior_step = 1e6 / sp[MIM_DENSITY_PRIOR].per_s;
    const double step_of[3] = {prior_step + us[P_L_IC] + us[P_VELOCITY], prior_step + us[P_L_CART] + us[P_VELOCITY],
                               prior_step + us[P_L_SHAPE] + us[P_VELOCITY]};
    const double step_naive = prior_step + us[P_NAIVE] + us[P_VELOCITY];
    printf("Profile: median time per call over %u states (the %u prior frames and %u states of the prior chains), "
           "each with its own %d views drawn from the annotations' view density\n\n",
           n_states, n_prior, n_chain_states, CHAIN_VIEWS);
    printf("A step that evaluates the likelihood (the prior chain's measured step %.1f us + the likelihood + eq. 12):\n\n",
           prior_step);
    printf("| likelihood (%d views) | us / likelihood | us / step | samples/s | x mimic's IC likelihood |\n"
           "|---|---:|---:|---:|---:|\n", CHAIN_VIEWS);
    static const int lpiece[3] = {P_L_IC, P_L_CART, P_L_SHAPE};
    for (int d = 0; d < 3; d++)
        printf("| %s%s%s | %.1f | %.1f | %s%.0f%s | %.2f |\n", d ? "" : "**", mim_pairs_density_names[d], d ? "" : "**",
               us[lpiece[d]], step_of[d], d ? "" : "**", 1e6 / step_of[d], d ? "" : "**", us[lpiece[d]] / us[P_L_IC]);
    printf("| reference: eq. 9 over all %u annotations, d_I each (IC; median over %u states) | %.0f | %.0f | %.1f | %.1f |\n\n",
           nv.n, n_naive, us[P_NAIVE], step_naive, 1e6 / step_naive, us[P_NAIVE] / us[P_L_IC]);

    /* ---- the breakdown of that IC step ---- */
    const double step = step_of[0];
    const double tri = CHAIN_VIEWS * us[P_DELAUNAY], dist = CHAIN_VIEWS * SHORTLIST * us[P_DI];
    const double rest_l = us[P_L_IC] - tri - dist;
    const double mh = prior_step - 2 * us[P_FK] - us[P_VALIDITY] - us[P_PENETRATION];
    printf("Breakdown of that IC step (%.0f us):\n\n", step);
    printf("| piece | calls / step | us / call | us / step | share of a step |\n|---|---:|---:|---:|---:|\n");
    printf("| forward kinematics (mim_pairs_pose_joints) | 2 | %.2f | %.1f | %.1f %% |\n", us[P_FK], 2 * us[P_FK],
           100 * 2 * us[P_FK] / step);
    printf("| joint-angle validity (mim_pairs_validity_excess) | 1 | %.2f | %.1f | %.1f %% |\n", us[P_VALIDITY],
           us[P_VALIDITY], 100 * us[P_VALIDITY] / step);
    printf("| penetration, ODE (mim_penetration_pair) | 1 | %.2f | %.1f | %.1f %% |\n", us[P_PENETRATION],
           us[P_PENETRATION], 100 * us[P_PENETRATION] / step);
    printf("| proposal, acceptance, output (the prior step's rest) | 1 | | %.1f | %.1f %% |\n", mh, 100 * mh / step);
    printf("| **likelihood, IC (mim_pairs_log_likelihood)** | 1 | %.1f | %.1f | **%.1f %%** |\n", us[P_L_IC], us[P_L_IC],
           100 * us[P_L_IC] / step);
    printf("| - 2D Delaunay of a view's projection (mim_ic_build, qhull) | %d | %.2f | %.1f | %.1f %% |\n", CHAIN_VIEWS,
           us[P_DELAUNAY], tri, 100 * tri / step);
    printf("| - d_I of eq. 8 (mim_ic_distance, 2D) | %d | %.2f | %.1f | %.1f %% |\n", CHAIN_VIEWS * SHORTLIST, us[P_DI],
           dist, 100 * dist / step);
    printf("| - the rest: projections, the views of %u annotations scanned, alignments | 1 | | %.1f | %.1f %% |\n",
           mim_pairs_evidence_count(ev_ic), rest_l, 100 * rest_l / step);
    const double aligns = CHAIN_VIEWS * fmax(cone_med, SHORTLIST) * us[P_ALIGN];
    printf("| -- of it, estimated: the aligned RMS of the %.0f annotations in a view's cone (median; "
           "mim_pairs2d_align) | %.0f | %.3f | %.1f | %.1f %% |\n",
           cone_med, CHAIN_VIEWS * fmax(cone_med, SHORTLIST), us[P_ALIGN], aligns, 100 * aligns / step);
    printf("| eq. 12 variances (mim_pairs_velocity) | 1 | %.2f | %.2f | %.2f %% |\n\n", us[P_VELOCITY], us[P_VELOCITY],
           100 * us[P_VELOCITY] / step);

    /* ---- what the speed-up costs: the same views, both likelihoods ---- */
    uint32_t same = 0, views_cmp = 0, n_cmp = 0;
    double *ratio = malloc((size_t)n_naive * CHAIN_VIEWS * sizeof *ratio), *dlog = malloc(n_naive * sizeof *dlog);
    if (!ratio || !dlog) return 1;
    for (uint32_t i = 0; i < n_states; i += stride) {
        double best[CHAIN_VIEWS];
        double ln = naive_log_likelihood(&nv, pr.sigma_l, st[i].joints, st[i].views, CHAIN_VIEWS, best);
        double lm = mim_pairs_log_likelihood(ev_ic, MIM_DENSITY_IC, pr.sigma_l, pr.cone, st[i].joints, st[i].views, CHAIN_VIEWS,
                                             NULL);
        if (isfinite(ln) && isfinite(lm)) dlog[n_cmp++] = ln - lm;
        for (int v = 0; v < CHAIN_VIEWS; v++) {
            /* mimic's d_I of this view alone: eq. 9's term is -d / (2 sigma_l^2) */
            double l1 = mim_pairs_log_likelihood(ev_ic, MIM_DENSITY_IC, pr.sigma_l, pr.cone, st[i].joints, st[i].views + 2 * v, 1,
                                                 NULL);
            double dm = -l1 * 2 * pr.sigma_l * pr.sigma_l;
            if (!isfinite(dm) || !isfinite(best[v]) || !(best[v] > 0)) continue;
            same += fabs(dm - best[v]) <= 1e-9 * best[v];
            ratio[views_cmp++] = dm / best[v];
        }
    }
    if (views_cmp && n_cmp)
        printf("What the speed-up costs (the reference's %u states): mimic's likelihood finds the best d_I of all "
               "annotations in %u of %u views (%.0f %%); its best d_I is %.2fx the best of all (median over views; %.2fx at "
               "the 90th percentile); its log L (eq. 6, sigma_l %.2g) is lower by %.2f (median over states; %.1f at the 90th "
               "percentile)\n",
               n_naive, same, views_cmp, 100.0 * same / views_cmp, bench_quantile(ratio, (int)views_cmp, 0.5),
               bench_quantile(ratio, (int)views_cmp, 0.9), pr.sigma_l, bench_quantile(dlog, (int)n_cmp, 0.5),
               bench_quantile(dlog, (int)n_cmp, 0.9));

    free(ratio), free(dlog), free(st), free(kept), free(prior), free(allowed);
    free(nv.pts), free(nv.ic);
    mim_penetration_close(&pen);
    dCloseODE();
    mim_pairs_evidence_free(&ev_ic);
    mim_pairs_evidence_free(&ev_shape);
    mim_pairs_validity_free(&validity);
    mim_pairs_annotations_free(&ann);
    for (int t = 0; t < 2; t++) free(takes[t].frames);
    return 0;
}
