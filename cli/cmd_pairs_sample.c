/* mimic pairs sample: seed 002's lifting by sampling (Sections 3-5). The
 * prior motions teach the joint limits, the torso for the annotations'
 * views and the chains' seeds; the annotations are the likelihood's
 * evidence; C chains run on C threads, each with its own generator stream
 * (the same seed and chain count give the same bytes), and their samples
 * are written chain after chain. */
#include "args.h"
#include "commands.h"
#include "mim_sample_mcmc.h"
#include "output.h"
#include "pairs_input.h"

#include <errno.h>
#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <ode/ode.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define MAX_CHAINS 256
#define SEED_TRIES 32 /* prior frames a chain tries before it gives up on a seed */

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic pairs sample --prior A.bvh,B.bvh [--prior ...] [--every N] [--offset K]\n"
            "                          [--annotations ANN.json] --samples N [--chains C]\n"
            "                          [--density ic|cartesian|shape|prior] [--views M] [--sigma-l S]\n"
            "                          [--seed S] [--restart-every N] [--velocity-scale V]\n"
            "                          [--start SAMPLES.jsonl[:LINE[,LINE...]]] [--seed-jitter DEG,M]\n"
            "                          [--bvh DIR]\n"
            "                          [--joint-map FILE.json] [--unit M] [--up AXIS] [--json] -o SAMPLES.jsonl\n\n"
            "3D pose-pairs sampled by Metropolis-Hastings from the posterior of seed 002 (Yin et al.):\n"
            "the physical prior (joint limits learned from the --prior motions' frames, offset,\n"
            "offset + every, ...; bone penetration through ODE) times the likelihood of the 2D\n"
            "annotations (pairs annotate's format) seen along M views drawn from their view density.\n"
            "Each chain starts from an annotation drawn at random and lifted to 3D (without annotations:\n"
            "a prior frame drawn at random; or from --start's sample) and walks with the velocity-biased\n"
            "proposal, the density truncated around the seed's; every --restart-every steps it starts\n"
            "again from a new seed (the paper's restart).\n\n"
            "  --density D      ic (eqs. 8-9, default), cartesian (aligned 2D distance), shape (2D shape\n"
            "                   contexts), or prior (no annotations, unbiased proposal)\n"
            "  --samples N      samples in all (1..10000000), split over the chains\n"
            "  --chains C       chains, one thread each (default 2)\n"
            "  --views M        views per likelihood (eq. 6; default 8, at most 64)\n"
            "  --sigma-l S      eq. 9's bandwidth (default 0.1, in units of the 2D pair's RMS radius)\n"
            "  --restart-every N  steps of a chain between restarts (default 5; 0: never)\n"
            "  --velocity-scale V eq. 12: the annotations' motion is scaled by V in the proposal (default 0.05)\n"
            "  --seed S         the generator's seed (default 1)\n"
            "  --seeds lifted|prior  where a chain (re)starts: an annotation drawn at random and lifted to\n"
            "                   3D (each bone's depth from its 2D length and its length as the take's\n"
            "                   annotations show it, in the prior's metres; its sign chosen by the\n"
            "                   prior; default with --annotations), or a prior\n"
            "                   frame drawn at random (default without)\n"
            "  --start F[:L[,L...]] the chains (and their restarts) start from those lines of samples\n"
            "                   file F, chain k from the k-th line mod their count (the paper's K\n"
            "                   seeds; default: line 1)\n"
            "  --seed-jitter DEG,M every seed edited before its chain starts: each joint turned by a\n"
            "                   random rotation of DEG degrees a component, B moved by M metres a\n"
            "                   component (a rough lifting, as the paper's hand-edited seed; redrawn\n"
            "                   while the prior forbids it; default 0,0)\n"
            "  --bvh DIR        also DIR/chainK_A.bvh and chainK_B.bvh, a frame per sample (y up)\n"
            "  --up AXIS        the --prior files' up axis, x, y, z, -x, -y or -z (default: found per\n"
            "                   take and said; mimic pairs --help)\n"
            "  --json           a report: samples, seconds, samples_per_second, acceptance and the log\n"
            "                   density's rise from a seed over its run per chain,\n"
            "                   parameters\n"
            "  -o FILE          the samples (schemas/pair-samples.md), chain after chain\n\n"
            "Exit status: 0 done, 1 an input failed (motions, annotations, no seed of finite density),\n"
            "2 bad usage.\n");
}

typedef struct chain_job {
    const mim_pairs_target_t *target;
    const double *prior;
    uint32_t n_prior;
    const double *start; /* NULL: a prior frame, or a lifted annotation */
    const mim_pairs_annotations_t *lift; /* non-NULL: seeds lifted from these annotations (--seeds lifted) */
    const double *lengths;               /* each annotated take's bone lengths (17 a take), for lifting */
    uint64_t seed;
    uint32_t index, n, restart_every, restarts;
    double jitter_rot, jitter_trans; /* --seed-jitter: radians, metres (0: the seeds as they are) */
    double *joints, *log_density;
    double rise; /* summed over the runs: log f at a run's last step minus at its seed */
    mim_mh_stats_t stats;
    _Atomic uint64_t done;
    _Atomic int finished;
    int rc;
    mim_error_t err;
} chain_job_t;

static void *chain_thread(void *arg)
{
    chain_job_t *j = arg;
    mim_penetration_t *pen = NULL;
    if ((j->rc = mim_penetration_open(&pen, &j->err))) {
        atomic_store(&j->finished, 1);
        return NULL;
    }
    /* the seeds come from a stream of their own, so that every density
     * starts its chains from the same prior frames (a paired comparison) */
    mim_rng_t rng, seeds;
    mim_rng_seed(&rng, j->seed, j->index);
    mim_rng_seed(&seeds, j->seed, (uint64_t)MAX_CHAINS + j->index);
    /* runs of restart_every steps, each from a new seed with new views
     * (Section 5.3's restart, with the sample drawn rather than chosen):
     * a chain that stays near its seed then still visits many */
    for (uint32_t at = 0; at < j->n && !j->rc; j->restarts++) {
        uint32_t len = j->restart_every && j->n - at > j->restart_every ? j->restart_every : j->n - at;
        mim_mh_stats_t st;
        /* a prior frame of finite density (the paper's seed is one good pose-pair) */
        int jitter = j->jitter_rot > 0 || j->jitter_trans > 0;
        for (int attempt = 0; attempt < SEED_TRIES; attempt++) {
            double edited[3 * MIM_PAIR_JOINTS], lifted[3 * MIM_PAIR_JOINTS];
            const double *seed = j->start ? j->start : j->prior + 3 * MIM_PAIR_JOINTS * mim_rng_below(&seeds, j->n_prior);
            if (!j->start && j->lift) {
                /* an annotation at random, lifted to 3D (a seed's choice: no proposal density to keep) */
                const mim_pairs_annotations_t *a = j->lift;
                const double *uv = a->points + (size_t)2 * MIM_PAIR_JOINTS * mim_rng_below(&seeds, a->n);
                const uint32_t i = (uint32_t)((uv - a->points) / (2 * MIM_PAIR_JOINTS));
                if (mim_pairs_lift(j->target, uv, a->width, a->height, j->lengths + (size_t)MIM_PAIR_PERSON_JOINTS * a->take[i],
                                   &seeds, lifted))
                    continue;
                seed = lifted;
            }
            if (jitter) {
                /* drawn from the seeds' stream too: every density gets the same edits */
                mim_pairs_seed_jitter(seed, j->jitter_rot, j->jitter_trans, &seeds, edited);
                seed = edited;
            }
            j->rc = mim_pairs_chain_run(j->target, seed, &rng, pen, len, j->joints + (size_t)at * 3 * MIM_PAIR_JOINTS,
                                        j->log_density + at, &st, &j->done, &j->err);
            if (j->rc != MIM_EINVAL || (j->start && !jitter)) break;
        }
        if (!at) j->stats.seed_log_density = st.seed_log_density;
        if (!j->rc) j->rise += j->log_density[at + len - 1] - st.seed_log_density;
        j->stats.steps += st.steps, j->stats.accepted += st.accepted, j->stats.zero += st.zero;
        at += len;
    }
    mim_penetration_close(&pen);
    dCleanupODEAllDataForThread();
    atomic_store(&j->finished, 1);
    return NULL;
}

/* --start F[:L[,L...]]: the pose-pairs on those lines of a samples file
 * (1 = the first sample; default 1), in *starts (n_starts of them): the
 * paper's K seeds, chain k starting from seed k mod K. */
static int read_start(const char *spec, double **starts, uint32_t *n_starts)
{
    char path[4096];
    snprintf(path, sizeof path, "%s", spec);
    uint64_t lines[MAX_CHAINS] = {1};
    uint32_t n = 1;
    char *colon = strrchr(path, ':');
    if (colon && colon[1] && strspn(colon + 1, "0123456789,") == strlen(colon + 1)) {
        *colon = 0;
        n = 0;
        for (char *tok = colon + 1, *next; tok; tok = next) {
            next = strchr(tok, ',');
            if (next) *next++ = 0;
            if (n == MAX_CHAINS) {
                fprintf(stderr, "mimic pairs sample: --start: more than %d lines\n", MAX_CHAINS);
                return 2;
            }
            if (mim_cli_number("pairs sample", "start's line", tok, 1, UINT32_MAX, &lines[n++])) return 2;
        }
    }
    mim_pairs_samples_t s = {0};
    int rc = 0;
    if (mim_cli_samples_read("pairs sample: --start", path, &s)) {
        rc = 1;
    } else if (!(*starts = malloc((size_t)n * 3 * MIM_PAIR_JOINTS * sizeof **starts))) {
        fprintf(stderr, "mimic pairs sample: --start: out of memory\n");
        rc = 1;
    } else {
        *n_starts = n;
        for (uint32_t i = 0; i < n && !rc; i++) {
            if (lines[i] > s.n) {
                fprintf(stderr, "mimic pairs sample: --start: %s has %u samples, not %llu\n", path, s.n,
                        (unsigned long long)lines[i]);
                rc = 1;
            } else {
                memcpy(*starts + (size_t)i * 3 * MIM_PAIR_JOINTS, s.joints + (size_t)(lines[i] - 1) * 3 * MIM_PAIR_JOINTS,
                       3 * MIM_PAIR_JOINTS * sizeof **starts);
            }
        }
    }
    mim_pairs_samples_free(&s);
    return rc;
}

static int read_annotations(const char *path, char **text, mim_pairs_annotations_t *ann, mim_error_t *err)
{
    size_t len;
    return mim_file_read(path, 0, text, &len, err) || mim_pairs_annotations_parse(*text, len, path, ann, err) ? -1 : 0;
}

static int write_bvh(const char *dir, const chain_job_t *jobs, uint32_t chains)
{
    if (mkdir(dir, 0777) && errno != EEXIST) {
        fprintf(stderr, "mimic pairs sample: --bvh %s: %s\n", dir, strerror(errno));
        return -1;
    }
    for (uint32_t c = 0; c < chains; c++)
        for (int person = 0; person < 2; person++) {
            if (!jobs[c].n) continue;
            char path[4200];
            snprintf(path, sizeof path, "%s/chain%u_%c.bvh", dir, c, person ? 'B' : 'A');
            /* a sample a frame, at 30 frames a second to play them */
            char *text = mim_pairs_bvh_text(jobs[c].joints, jobs[c].n, person, 1.0 / 30);
            int rc = text ? mim_cli_pairs_write("pairs sample", path, text, strlen(text)) : -1;
            if (!text) fprintf(stderr, "mimic pairs sample: out of memory for %s\n", path);
            free(text);
            if (rc) return -1;
        }
    return 0;
}

static json_t *report(const mim_pairs_target_t *t, const chain_job_t *jobs, uint32_t chains, uint64_t total,
                      double seconds, uint32_t n_prior, uint32_t n_ann, uint32_t dropped, uint64_t seed)
{
    json_t *acc = json_array(), *f0 = json_array(), *rs = json_array(), *rise = json_array();
    for (uint32_t c = 0; c < chains; c++) {
        const mim_mh_stats_t *s = &jobs[c].stats;
        json_array_append_new(rs, json_integer(jobs[c].restarts > 0 ? jobs[c].restarts - 1 : 0));
        json_array_append_new(acc, json_real(s->steps ? (double)s->accepted / (double)s->steps : 0.0));
        json_array_append_new(f0, json_real(s->seed_log_density));
        json_array_append_new(rise, json_real(jobs[c].restarts ? jobs[c].rise / jobs[c].restarts : 0.0));
    }
    const mim_pairs_sampler_options_t *o = &t->opt;
    json_t *params = json_pack("{s:s, s:I, s:f, s:f, s:f, s:f, s:I, s:f, s:f, s:f, s:f, s:f, s:f}", "density",
                               mim_pairs_density_names[o->density], "views", (json_int_t)o->views, "sigma_l", o->sigma_l,
                               "sigma_v", MIM_VIEW_DEFAULT_SIGMA, "sigma_p", o->sigma_p, "alpha", o->alpha,
                               "max_invalid", (json_int_t)o->max_invalid, "c", o->c, "sigma0_rot", o->sigma0_rot,
                               "sigma0_trans", o->sigma0_trans, "velocity_scale", o->velocity_scale, "beta",
                               MIM_IC_DEFAULT_BETA, "joint_tolerance", MIM_PAIRS_VALID_TOL);
    json_object_set_new(params, "restart_every", json_integer(jobs[0].restart_every));
    json_object_set_new(params, "cone", json_real(o->cone));
    json_object_set_new(params, "seeds", json_string(jobs[0].start ? "start" : jobs[0].lift ? "lifted" : "prior"));
    json_object_set_new(params, "seed_jitter_deg", json_real(jobs[0].jitter_rot * 180 / M_PI));
    json_object_set_new(params, "seed_jitter_m", json_real(jobs[0].jitter_trans));
    return json_pack("{s:I, s:I, s:f, s:f, s:f, s:o, s:o, s:o, s:o, s:I, s:I, s:I, s:I, s:o}", "samples", (json_int_t)total,
                     "chains", (json_int_t)chains, "seconds", seconds, "samples_per_second",
                     seconds > 0 ? total / seconds : 0.0, "samples_per_second_per_chain",
                     seconds > 0 ? total / seconds / chains : 0.0, "acceptance", acc, "seed_log_density", f0, "restarts", rs,
                     "log_density_rise", rise, "prior_frames", (json_int_t)n_prior, "annotations", (json_int_t)n_ann, "annotations_dropped",
                     (json_int_t)dropped, "seed", (json_int_t)seed, "parameters", params);
}

int mim_cmd_pairs_sample(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"prior", required_argument, 0, 'p'},     {"every", required_argument, 0, 'e'},
        {"offset", required_argument, 0, 'k'},    {"joint-map", required_argument, 0, 'm'},
        {"unit", required_argument, 0, 'u'}, {"up", required_argument, 0, MIM_CLI_OPT_UP},      {"annotations", required_argument, 0, 'a'},
        {"samples", required_argument, 0, 'n'},   {"chains", required_argument, 0, 'C'},
        {"density", required_argument, 0, 'd'},   {"views", required_argument, 0, 'v'},
        {"sigma-l", required_argument, 0, 'l'},   {"seed", required_argument, 0, 'S'},
        {"start", required_argument, 0, 's'},     {"bvh", required_argument, 0, 'B'},
        {"output", required_argument, 0, 'o'},    {"json", no_argument, 0, 'j'},
        {"restart-every", required_argument, 0, 'R'}, {"velocity-scale", required_argument, 0, 'V'},
        {"seed-jitter", required_argument, 0, 'J'}, {"seeds", required_argument, 0, 'L'},
        {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    mim_cli_takes_t tk = {.cmd = "pairs sample", .every = 1};
    mim_pairs_target_t target = {0};
    mim_pairs_sampler_defaults(&target.opt);
    const char *ann_path = NULL, *start_spec = NULL, *bvh_dir = NULL, *outp = NULL;
    uint64_t samples = 0, chains = 2, views = target.opt.views, seed = 1, restart_every = 5; /* measured: more lifted seeds cover more (bench/RESULTS.md) */
    double jitter_deg = 0, jitter_m = 0;
    int as_json = 0, c, taken, seeds_lifted = -1;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "p:e:k:m:u:a:n:C:d:v:l:S:s:B:o:R:V:J:L:jh", longopts, NULL)) != -1) {
        if ((taken = mim_cli_takes_option(&tk, c, optarg))) {
            if (taken < 0) return 2;
            continue;
        }
        switch (c) {
        case 'a': ann_path = optarg; break;
        case 'n':
            if (mim_cli_number("pairs sample", "samples", optarg, 1, MIM_PAIRS_SAMPLES_MAX, &samples)) return 2;
            break;
        case 'C':
            if (mim_cli_number("pairs sample", "chains", optarg, 1, MAX_CHAINS, &chains)) return 2;
            break;
        case 'd': {
            int d = mim_pairs_density_parse(optarg);
            if (d < 0) {
                fprintf(stderr, "mimic pairs sample: --density '%s' is not ic, cartesian, shape or prior\n", optarg);
                return 2;
            }
            target.opt.density = (mim_pairs_density_t)d;
            break;
        }
        case 'v':
            if (mim_cli_number("pairs sample", "views", optarg, 1, MIM_PAIRS_MAX_VIEWS, &views)) return 2;
            break;
        case 'l':
            if (mim_cli_real("pairs sample", "sigma-l", optarg, 0.0, 100.0, 1, "is not a bandwidth in (0, 100]",
                             &target.opt.sigma_l))
                return 2;
            break;
        case 'S':
            if (mim_cli_number("pairs sample", "seed", optarg, 0, UINT64_MAX, &seed)) return 2;
            break;
        case 's': start_spec = optarg; break;
        case 'V':
            if (mim_cli_real("pairs sample", "velocity-scale", optarg, 0.0, 100.0, 0, "is not a scale in 0..100",
                             &target.opt.velocity_scale))
                return 2;
            break;
        case 'R':
            if (mim_cli_number("pairs sample", "restart-every", optarg, 0, MIM_PAIRS_SAMPLES_MAX, &restart_every)) return 2;
            break;
        case 'J': {
            char deg[64];
            const char *comma = strchr(optarg, ',');
            if (!comma || (size_t)(comma - optarg) >= sizeof deg) {
                fprintf(stderr, "mimic pairs sample: --seed-jitter '%s' is not DEG,M (degrees, metres)\n", optarg);
                return 2;
            }
            memcpy(deg, optarg, (size_t)(comma - optarg));
            deg[comma - optarg] = 0;
            if (mim_cli_real("pairs sample", "seed-jitter", deg, 0.0, 90.0, 0, "does not start with degrees in 0..90",
                             &jitter_deg) ||
                mim_cli_real("pairs sample", "seed-jitter", comma + 1, 0.0, 10.0, 0, "does not end with metres in 0..10",
                             &jitter_m))
                return 2;
            break;
        }
        case 'L':
            if (strcmp(optarg, "lifted") && strcmp(optarg, "prior")) {
                fprintf(stderr, "mimic pairs sample: --seeds '%s' is not lifted or prior\n", optarg);
                return 2;
            }
            seeds_lifted = !strcmp(optarg, "lifted");
            break;
        case 'B': bvh_dir = optarg; break;
        case 'o': outp = optarg; break;
        case 'j': as_json = 1; break;
        case 'h': help(stdout); return 0;
        default:
            fprintf(stderr, "mimic pairs sample: unknown or incomplete option '%s' (see mimic pairs sample --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    target.opt.views = (uint32_t)views;
    if (!tk.n || !samples || !outp || optind < argc) {
        fprintf(stderr, "mimic pairs sample: --prior A,B, --samples N and -o FILE are required, and nothing else (see "
                        "mimic pairs sample --help)\n");
        return 2;
    }
    if (target.opt.density != MIM_DENSITY_PRIOR && !ann_path) {
        fprintf(stderr, "mimic pairs sample: --density %s needs --annotations (or --density prior)\n",
                mim_pairs_density_names[target.opt.density]);
        return 2;
    }
    if (seeds_lifted < 0) seeds_lifted = ann_path != NULL;
    if (seeds_lifted && !ann_path) {
        fprintf(stderr, "mimic pairs sample: --seeds lifted needs --annotations\n");
        return 2;
    }
    if (chains > samples) chains = samples;
    if (mim_cli_takes_begin(&tk)) return 1;

    int status = 1;
    double *prior = NULL, *starts = NULL;
    uint32_t n_starts = 0;
    uint32_t n_prior = 0, dropped = 0, n_ann = 0;
    char *text = NULL;
    mim_pairs_annotations_t ann = {0};
    mim_pairs_validity_t *validity = NULL;
    mim_pairs_evidence_t *evidence = NULL;
    chain_job_t *jobs = NULL;
    pthread_t *threads = NULL;
    double *joints = NULL, *logd = NULL, *allowed = NULL, *lengths = NULL;
    mim_error_t err = {0};
    int ode = 0;
    if (mim_cli_takes_read_all(&tk, &prior, &n_prior)) goto done;
    if (!n_prior) {
        fprintf(stderr, "mimic pairs sample: the --prior takes have no frames from %llu on\n", (unsigned long long)tk.offset);
        goto done;
    }
    if (start_spec && (status = read_start(start_spec, &starts, &n_starts))) goto done;
    if (n_starts > chains) {
        fprintf(stderr, "mimic pairs sample: --start gives %u lines for %llu chains: one a chain at most\n", n_starts,
                (unsigned long long)chains);
        status = 2;
        goto done;
    }
    status = 1;
    if (mim_pairs_validity_learn(prior, n_prior, &validity, &err)) {
        fprintf(stderr, "mimic pairs sample: %s\n", mim_error_text(&err));
        goto done;
    }
    target.validity = validity;
    if (seeds_lifted) {
        if (read_annotations(ann_path, &text, &ann, &err)) {
            fprintf(stderr, "mimic pairs sample: %s\n", mim_error_text(&err));
            goto done;
        }
        /* each take lifts with its own skeleton's bones, from its annotations; the prior's scale */
        double len_prior[MIM_PAIR_PERSON_JOINTS];
        mim_pairs_bone_lengths(prior, n_prior, len_prior);
        uint32_t takes = 0;
        for (uint32_t i = 0; i < ann.n; i++) takes = ann.take[i] >= takes ? ann.take[i] + 1 : takes;
        if (!(lengths = malloc((size_t)takes * MIM_PAIR_PERSON_JOINTS * sizeof *lengths))) {
            fprintf(stderr, "mimic pairs sample: out of memory for %u takes' bone lengths\n", takes);
            goto done;
        }
        for (uint32_t t = 0; t < takes; t++)
            mim_pairs_bone_lengths_2d(&ann, t, len_prior, lengths + (size_t)t * MIM_PAIR_PERSON_JOINTS);
    }
    if (target.opt.density != MIM_DENSITY_PRIOR) {
        mim_pairs_torso_t torso;
        mim_progress_t pr = {.fn = mim_cli_progress};
        if (mim_pairs_torso_learn(prior, n_prior, &torso, &err) || (!ann.n && read_annotations(ann_path, &text, &ann, &err)) ||
            mim_pairs_evidence_build(&ann, &torso, target.opt.density, &evidence, &dropped, &pr, &err)) {
            fprintf(stderr, "mimic pairs sample: %s\n", mim_error_text(&err));
            goto done;
        }
        n_ann = mim_pairs_evidence_count(evidence);
        target.evidence = evidence;
        if (dropped) mim_cli_logf("pairs sample: %u of %u annotations have no view that can be estimated; left out", dropped, ann.n);
    }
    jobs = calloc(chains, sizeof *jobs), threads = calloc(chains, sizeof *threads);
    joints = malloc((size_t)samples * 3 * MIM_PAIR_JOINTS * sizeof *joints), logd = malloc((size_t)samples * sizeof *logd);
    if (!jobs || !threads || !joints || !logd) {
        fprintf(stderr, "mimic pairs sample: out of memory for %llu samples\n", (unsigned long long)samples);
        goto done;
    }
    /* ODE's process-wide state: the program owns it (penetration.c) */
    if (!dInitODE2(0)) {
        fprintf(stderr, "mimic pairs sample: the Open Dynamics Engine does not initialise\n");
        goto done;
    }
    ode = 1;
    /* eta's allowances: what each pair of bones shows in the prior motions */
    mim_penetration_t *pen = NULL;
    if (!(allowed = calloc(MIM_PENETRATION_ALLOWANCES, sizeof *allowed)) || mim_penetration_open(&pen, &err)) {
        fprintf(stderr, "mimic pairs sample: %s\n", allowed ? mim_error_text(&err) : "out of memory");
        goto done;
    }
    for (uint32_t i = 0; i < n_prior; i++) mim_penetration_learn(pen, prior + (size_t)i * 3 * MIM_PAIR_JOINTS, allowed);
    mim_penetration_close(&pen);
    target.allowed = allowed;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    uint64_t at = 0;
    uint32_t started = 0;
    for (uint32_t k = 0; k < chains; k++) {
        chain_job_t *j = &jobs[k];
        j->target = &target, j->prior = prior, j->n_prior = n_prior, j->start = starts ? starts + (size_t)(k % n_starts) * 3 * MIM_PAIR_JOINTS : NULL;
        j->seed = seed, j->index = k, j->restart_every = (uint32_t)restart_every;
        j->jitter_rot = jitter_deg * M_PI / 180, j->jitter_trans = jitter_m;
        j->lift = seeds_lifted ? &ann : NULL, j->lengths = lengths;
        j->n = (uint32_t)(samples / chains + (k < samples % chains));
        j->joints = joints + at * 3 * MIM_PAIR_JOINTS, j->log_density = logd + at;
        at += j->n;
        if (pthread_create(&threads[k], NULL, chain_thread, j)) {
            fprintf(stderr, "mimic pairs sample: cannot start chain %u's thread\n", k);
            break;
        }
        started++;
    }
    /* progress from this thread: the chains only count */
    mim_progress_t pr = {.fn = mim_cli_progress};
    mim_progress_begin(&pr, "samples", samples);
    for (int running = started > 0; running;) {
        uint64_t done_steps = 0;
        for (uint32_t k = 0; k < started; k++) done_steps += atomic_load(&jobs[k].done);
        mim_progress_update(&pr, done_steps);
        if (done_steps >= samples) break;
        int alive = 0;
        for (uint32_t k = 0; k < started; k++) alive |= !atomic_load(&jobs[k].finished);
        if (!alive) break;
        usleep(100000);
    }
    for (uint32_t k = 0; k < started; k++) pthread_join(threads[k], NULL);
    mim_progress_end(&pr);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    if (started < chains) goto done;
    for (uint32_t k = 0; k < chains; k++)
        if (jobs[k].rc) {
            fprintf(stderr, "mimic pairs sample: chain %u: %s%s\n", k, mim_error_text(&jobs[k].err),
                    jobs[k].rc != MIM_EINVAL                  ? ""
                    : jitter_deg > 0 || jitter_m > 0 ? " (for every edit of a seed it tried: a smaller --seed-jitter?)"
                    : !start_spec                    ? " (for every prior frame it tried)"
                                                     : "");
            goto done;
        }
    if (mim_cli_pairs_write_samples("pairs sample", outp, joints, logd, (uint32_t)samples)) goto done;
    if (bvh_dir && write_bvh(bvh_dir, jobs, (uint32_t)chains)) goto done;
    if (as_json) {
        json_t *j = report(&target, jobs, (uint32_t)chains, samples, seconds, n_prior, n_ann, dropped, seed);
        char *out = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        json_decref(j);
        if (!out) {
            fprintf(stderr, "mimic pairs sample: cannot make the JSON report\n");
            goto done;
        }
        printf("%s\n", out);
        free(out);
    }
    uint64_t acc = 0, steps = 0;
    for (uint32_t k = 0; k < chains; k++) acc += jobs[k].stats.accepted, steps += jobs[k].stats.steps;
    fprintf(stderr, "mimic pairs sample: %llu samples from %llu chains in %.1f s (%.0f/s), %.1f%% accepted, to %s\n",
            (unsigned long long)samples, (unsigned long long)chains, seconds, seconds > 0 ? samples / seconds : 0.0,
            steps ? 100.0 * acc / steps : 0.0, outp);
    status = 0;
done:
    if (ode) dCloseODE();
    free(jobs), free(threads), free(joints), free(logd), free(allowed), free(prior), free(starts), free(text), free(tk.map_text);
    free(lengths);
    mim_pairs_evidence_free(&evidence);
    mim_pairs_validity_free(&validity);
    mim_pairs_annotations_free(&ann);
    return status;
}
