/* The real-time loop of mimic serve: a thread reads the vest, turns each
 * whole vest frame into the avatar's landmarks (calibrated rig, forward
 * kinematics) and publishes one avatar frame for it:
 *
 *  - a key frame (seed 000, Fig. 1): the nearest template of the landmarks
 *    (query/), then the transfer with the cached factor (transfer/). When
 *    the template is the one of the previous key frame, the iteration can
 *    be warm-started from that key frame's solution: about 0.6x the time
 *    for about 13 % more error (bench/warm_start.c), so by default (auto)
 *    the loop warm-starts only when cold key frames no longer fit its
 *    budget, before it lowers the key rate;
 *  - between key frames, morphs (Section 3.5): with key interval k, the k
 *    frames after key i show the frames-method morph from key i-1 to key i
 *    at t = 1/k ... 1 (one solve each with the same factor), so the last
 *    of them is key i itself.
 *
 * The paper fixed k by hand and left an adaptive k as future work. Here k
 * follows the loop's own measured costs: with vest period P, key-frame
 * cost c_k and morph cost c_m (moving averages of the CPU time the
 * compute took on this thread, so that waiting for a core or for the gate
 * does not count), k = 1 while c_k fits in 80 % of P, else the smallest k
 * with c_k + (k - 1) c_m <= 0.8 k P (c_k is then the warm-started cost if
 * auto has switched to it). When frames morphs cost too much for any k up
 * to 30 (at this size a morph's solve costs about what a warm key frame
 * does), the morphs become the paper's linear ones, which cost next to
 * nothing. With many sessions, the loop uses the larger of its own k and
 * the one all sessions share (fair.c: what the whole process's demand
 * fits in the cores), and counts k in vest frames, skipped ones too, so
 * that every session keys at the same rate; and when even that is not
 * enough, the loop skips to the newest vest frame instead of falling
 * behind (flush_frames). A fixed key rate (--key-rate) overrides the
 * choice of k. A lost landmark is held at its last position for up to
 * HOLD_US of vest time, then filled in from the store's templates
 * (mim_session_complete: seed 002's completion by retrieval) while at least
 * 4 are seen, else held, so a dropout does not stop the stream. Holding
 * first: in a vest replay the last position beats retrieval for losses up
 * to about a second, and retrieval wins beyond (bench/RESULTS.md).
 *
 * A vest that goes away is waited for: a device unplugged (serial, HID),
 * or any vest silent for SILENCE_S (or 5 vest periods, if longer), e.g. a
 * UDP sender that stopped. Status then says "reconnecting", with an
 * error that tells the time since (it grows: "unplugged for 3.2 s", "no
 * data for 3.2 s"), and that error goes once frames come again: it
 * describes the outage, not a frame. */
#include "internal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define HOLD_US 1000000 /* a lost landmark is held this long before it is completed */

#define BUDGET_FRACTION MIM__FAIR_BUDGET /* of the vest period, for one frame's compute */
#define K_MAX MIM__FAIR_K_MAX /* never fewer key frames than one every 30 vest frames */
#define PERIOD_SAMPLES 15 /* vest intervals the period is the median of */
#define EWMA 0.2            /* weight of a new cost sample */
#define SILENCE_S 1.0       /* a vest silent this long has gone away */

typedef struct key {
    int valid, morph_ready;
    float *pos;     /* 3 * n: the transferred avatar */
    double *quats;  /* 4 * n and */
    double *W;      /* 3 * n: its frames and encoding, made when a morph needs them */
    float u[3 * MIM_LANDMARKS_MAX];
    uint64_t template_id;
    char label[MIM_SESSION_LABEL_MAX]; /* the class name */
    int oriented;   /* made by the orientation drive, from these segment rotations: */
    mim_quat R[MIM_VEST_SEGMENTS];
    uint8_t have_R[MIM_VEST_SEGMENTS];
    uint64_t frame;  /* the complete vest frame it was made from (recent[]) */
} key_pose_t;

/* The latest complete vest frames' landmarks: an in-between shown after
 * key b stands for a vest frame between keys a and b, which arrived, so
 * its own landmarks pin it (issue 29), not ones interpolated between the
 * keys'. More than K_MAX, the longest key interval. */
#define RECENT_FRAMES 32
_Static_assert(RECENT_FRAMES > K_MAX, "the frames between two keys are all kept");

struct mim__loop {
    mim__vs_t *vs;      /* the session whose vest this is */
    mim_serve_options_t opt;
    mim_vest_rig_t rig;
    mim_vest_transport_t *t;
    mim_vest_decoder_t *dec;
    mim_vest_state_t st;
    mim_vest_assembler_t as;
    pthread_t thread;
    int started;
    atomic_int stop;
    char spec[1024];
    float *out;        /* a morphed frame (3 * n) */
    float *own;        /* a foreign avatar's frame on its own vertices (mim_session_output), or NULL */
    mim_session_report_t report; /* the latest key frame's */
    double *F;         /* 9 * n: scratch for a key's frames */
    key_pose_t keys[2];
    int cur;           /* keys[cur] is the latest key, keys[!cur] the one before */
    uint32_t k;        /* key interval chosen at the latest key */
    uint32_t since_key; /* vest frames since the latest key (skipped ones too) */
    uint32_t skipped;   /* vest frames skipped since the latest one made */
    int fair_id;        /* its entry in the service's fair.c (-1: none) */
    mim__fair_choice_t common; /* the interval all sessions share, as of the latest frame */
    double frame_cpu, frame_wall; /* the frame being made: its compute's CPU and wall seconds in a slot, */
    uint32_t frame_skipped;       /* and the vest frames skipped before it */
    double w_key, w_morph; /* wall seconds of a key frame and a morph (moving averages, for status) */
    float last_u[3 * MIM_LANDMARKS_MAX];
    uint8_t have_u[MIM_LANDMARKS_MAX];
    uint64_t seen_us[MIM_LANDMARKS_MAX]; /* vest time a landmark was last seen */
    double period, c_key, c_cold, c_warm, c_morph, c_linear; /* seconds: vest period, costs (moving averages) */
    int linear;        /* morphs between the latest keys are linear (frames ones do not fit) */
    uint64_t t_prev_vest;
    double dt[PERIOD_SAMPLES]; /* the latest intervals between vest frames, seconds */
    uint32_t n_dt, i_dt;
    double arrival;    /* mim_now() when the chunk being decoded arrived */
    double t_data;     /* mim_now() when the latest bytes came (at first: when the vest was opened) */
    int pending;       /* a vest frame completed in this chunk: at pending_t, */
    uint64_t pending_t;
    float pending_xyz[3 * MIM_LANDMARKS_MAX]; /* with these landmarks */
    uint8_t pending_present[MIM_LANDMARKS_MAX];
    mim_quat pending_R[MIM_VEST_SEGMENTS];    /* and these segment rotations */
    uint8_t pending_have[MIM_VEST_SEGMENTS];
    uint64_t number;
    double window_start;
    uint32_t window_frames, window_keys;
    pthread_mutex_t lock; /* guards what /api/status reads: */
    const char *state; /* a string literal: streaming, reconnecting, ended, failed, stopped */
    char error[512];
    int outage;        /* error tells of the vest being away (cleared when it is back) */
    uint64_t last_template, warm_starts, iterations, key_frames;
    uint64_t oriented_keys; /* key frames made by the orientation drive */
    uint64_t skeleton_keys; /* and by the skeleton drive */
    uint64_t completed; /* lost landmarks filled in by retrieval */
    uint64_t frames_complete;                        /* complete vest frames so far */
    uint64_t recent_no[RECENT_FRAMES];               /* which frame each slot holds (frames_complete then) */
    float recent_u[RECENT_FRAMES][3 * MIM_LANDMARKS_MAX];
    char last_label[MIM_SESSION_LABEL_MAX];
    char degraded[512]; /* the last key frame's mim_session_report_t.degraded: damage that changed it */
    double key_rate_hz, frame_rate_hz;
};

static void set_state(mim__loop_t *l, const char *state, const char *error)
{
    pthread_mutex_lock(&l->lock);
    l->state = state;
    if (error)
        snprintf(l->error, sizeof l->error, "%s", error);
    pthread_mutex_unlock(&l->lock);
}

static void set_error(mim__loop_t *l, const char *error)
{
    pthread_mutex_lock(&l->lock);
    snprintf(l->error, sizeof l->error, "%s", error);
    l->outage = 0;
    pthread_mutex_unlock(&l->lock);
}

/* The outage's message, renewed at every timeout while the vest is away. */
static void set_outage(mim__loop_t *l, const char *error)
{
    pthread_mutex_lock(&l->lock);
    snprintf(l->error, sizeof l->error, "%.500s", error);
    l->outage = 1;
    pthread_mutex_unlock(&l->lock);
}

static void ewma(double *avg, double sample)
{
    *avg = *avg > 0.0 ? (1.0 - EWMA) * *avg + EWMA * sample : sample;
}

static double budget(const mim__loop_t *l)
{
    return BUDGET_FRACTION * (l->period > 0.0 ? l->period : 1.0 / 60.0);
}

/* This thread's CPU time, seconds: the cost of compute, whatever the wait
 * for a core. */
static double cpu_now(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts))
        return mim_now();
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A compute slot (gate.c), taken and given back: the CPU and wall time in
 * between count in the frame's (for fair.c); slot_leave returns the CPU
 * time, the compute's cost. */
typedef struct slot {
    double wall, cpu;
} slot_t;

static slot_t slot_enter(mim__loop_t *l)
{
    mim__gate_enter(&l->vs->sv->gate); /* the wait costs no CPU: it is not in the cost */
    return (slot_t){mim_now(), cpu_now()};
}

static double slot_leave(mim__loop_t *l, slot_t s)
{
    double cpu = cpu_now() - s.cpu, wall = mim_now() - s.wall;
    mim__gate_leave(&l->vs->sv->gate);
    l->frame_cpu += cpu, l->frame_wall += wall;
    return cpu;
}

/* Whether the next key frame warm-starts (when its template allows). */
static int want_warm(const mim__loop_t *l)
{
    if (l->opt.warm_start)
        return l->opt.warm_start > 0;
    /* auto: only when cold key frames do not fit, its own or the sessions' together */
    return l->c_cold > budget(l) || (l->opt.key_rate <= 0.0 && l->common.warm);
}

/* The smallest k with ck + (k - 1) cm <= k B, or 0 if none up to K_MAX. */
static uint32_t interval_for(double ck, double cm, double B)
{
    if (ck <= B)
        return 1;
    if (cm >= B || cm >= ck)
        return 0;
    double k = ceil((ck - cm) / (B - cm));
    return k > K_MAX ? 0 : (uint32_t)k;
}

/* The key interval and the morph method for the costs measured so far (see
 * the top of the file): frames morphs while they fit, else linear ones
 * (next to free, the paper's); past K_MAX the loop skips vest frames. */
static void choose_interval(mim__loop_t *l)
{
    l->linear = 0;
    if (l->opt.key_rate > 0.0) {
        double k = round(1.0 / (l->opt.key_rate * (l->period > 0.0 ? l->period : 1.0 / 60.0)));
        l->k = k < 1.0 ? 1u : k > K_MAX ? K_MAX : (uint32_t)k;
        return;
    }
    const double B = budget(l);
    double ck = l->c_cold;
    if (want_warm(l))
        ck = l->c_warm > 0.0 ? l->c_warm : 0.6 * l->c_cold;
    uint32_t k = interval_for(ck, l->c_morph > 0.0 ? l->c_morph : 0.5 * ck, B);
    if (!k) {
        l->linear = 1;
        k = interval_for(ck, l->c_linear, B);
    }
    l->k = k ? k : K_MAX;
    if (l->common.k > l->k) /* the sessions' common interval (fair.c) */
        l->k = l->common.k;
    if (l->common.linear && l->k > 1)
        l->linear = 1;
}

/* A key's frames (as quaternions) and encoding, which the frames morph needs. */
static void morph_ready(mim__loop_t *l, key_pose_t *k)
{
    if (k->morph_ready)
        return;
    const mim_xfer_topology_t *t = mim_session_topology(l->vs->s);
    mim_xfer_frames(t, k->pos, l->F);
    mim_xfer_frames_to_quats(l->vs->mesh->n_vertices, l->F, k->quats);
    mim_xfer_encode(t, k->pos, l->F, k->W);
    k->morph_ready = 1;
}

/* A new key frame from complete landmarks u (and the segment rotations R,
 * have, when the vest gives them) into keys[!cur]: the session's pipeline
 * (nearest template; its frames, or the avatar's own turned by R; the
 * solve with the cached factor). */
static int make_key(mim__loop_t *l, const float *u, const mim_quat *R, const uint8_t *have, mim_error_t *err)
{
    mim__vs_t *vs = l->vs;
    const uint32_t L = vs->map->count;
    double t0 = mim_now();
    key_pose_t *prev = &l->keys[l->cur], *k = &l->keys[!l->cur];
    mim_session_request_t req = {.landmarks = u, .orientations = R, .orient_present = have,
                                 .drive = (mim_session_drive_t)l->opt.drive, .blend = l->opt.blend,
                                 .segment_correction = l->opt.segment_correction, .relative = l->opt.relative};
    if (prev->valid && want_warm(l)) /* warm start: the same template as the last key frame */
        req.xfer.start = prev->pos, req.start_template = prev->template_id;
    mim_session_report_t *rep = &l->report;
    slot_t slot = slot_enter(l);
    int rc = mim_session_transfer(vs->s, &req, k->pos, rep, err);
    double cpu = slot_leave(l, slot);
    if (rep->queried)
        mim__metrics_add(&vs->m, MIM__C_QUERIES, 1);
    if (rc)
        return rc;
    k->valid = 1, k->morph_ready = 0;
    k->template_id = rep->template_id;
    if ((k->oriented = rep->drive == MIM_DRIVE_ORIENTATION))
        memcpy(k->R, R, sizeof k->R), memcpy(k->have_R, have, sizeof k->have_R);
    snprintf(k->label, sizeof k->label, "%s", rep->class_name);
    memcpy(k->u, u, 3 * (size_t)L * sizeof *u);
    k->frame = l->frames_complete;
    l->cur = !l->cur;
    double c = mim_now() - t0;
    ewma(&l->w_key, c);
    ewma(&l->c_key, cpu);
    ewma(rep->warm_started ? &l->c_warm : &l->c_cold, cpu);
    mim__metrics_add(&vs->m, MIM__C_TRANSFERS, 1);
    mim__metrics_add(&vs->m, MIM__C_KEY_FRAMES, 1);
    mim__metrics_observe(&vs->m, MIM__H_KEY_FRAME, c);
    pthread_mutex_lock(&l->lock);
    l->last_template = rep->template_id;
    snprintf(l->last_label, sizeof l->last_label, "%s", k->label);
    snprintf(l->degraded, sizeof l->degraded, "%s", rep->degraded);
    l->warm_starts += rep->warm_started;
    l->oriented_keys += rep->drive == MIM_DRIVE_ORIENTATION;
    l->skeleton_keys += rep->drive == MIM_DRIVE_SKELETON;
    l->iterations += rep->xfer.iterations;
    l->key_frames++;
    pthread_mutex_unlock(&l->lock);
    return 0;
}

/* The frame between keys a and b at t in (0, 1), into l->out: pinned by
 * the landmarks of the vest frame it stands for when that frame is still
 * in recent[], else by the keys' along the skeleton. */
static int make_morph(mim__loop_t *l, key_pose_t *a, key_pose_t *b, double t, mim_error_t *err)
{
    mim__vs_t *vs = l->vs;
    double t0 = mim_now();
    const float *real = NULL;
    if (b->frame > a->frame) {
        const uint64_t at = a->frame + (uint64_t)llround(t * (double)(b->frame - a->frame));
        if (at > a->frame && at < b->frame && l->recent_no[at % RECENT_FRAMES] == at)
            real = l->recent_u[at % RECENT_FRAMES];
    }
    if (a->oriented && b->oriented && !l->linear) {
        mim_session_oriented_key_t ka = {a->R, a->have_R, a->u, a->template_id}, kb = {b->R, b->have_R, b->u, b->template_id};
        slot_t slot = slot_enter(l);
        int rc = mim_session_morph_oriented(vs->s, &ka, &kb, t, real, l->out, err);
        double cpu = slot_leave(l, slot);
        if (!rc) {
            ewma(&l->c_morph, cpu);
            ewma(&l->w_morph, mim_now() - t0);
            mim__metrics_add(&vs->m, MIM__C_MORPH_FRAMES, 1);
            mim__metrics_observe(&vs->m, MIM__H_MORPH_FRAME, mim_now() - t0);
        }
        return rc;
    }
    slot_t slot = slot_enter(l);
    if (!l->linear)
        morph_ready(l, a), morph_ready(l, b);
    mim_xfer_key_t ka = {a->pos, a->quats, a->W, a->u, NULL}, kb = {b->pos, b->quats, b->W, b->u, NULL};
    int rc = mim_session_morph(vs->s, l->linear ? MIM_XFER_MORPH_LINEAR : MIM_XFER_MORPH_FRAMES, &ka, &kb, t, real,
                               l->out, err);
    double cpu = slot_leave(l, slot);
    if (!rc) {
        double c = mim_now() - t0;
        ewma(l->linear ? &l->c_linear : &l->c_morph, cpu);
        if (!l->linear)
            ewma(&l->w_morph, c);
        mim__metrics_add(&vs->m, MIM__C_MORPH_FRAMES, 1);
        mim__metrics_observe(&vs->m, MIM__H_MORPH_FRAME, c);
    }
    return rc;
}

/* The loop's costs and its latest frame to fair.c, and the common
 * interval back, for its next key frame. */
static void share_costs(mim__loop_t *l, double now)
{
    if (l->fair_id < 0)
        return;
    mim__fair_demand_t d = {.key_cold = l->c_cold, .key_warm = l->c_warm, .morph = l->c_morph,
                            .linear = l->c_linear, .period = l->period,
                            .fixed_k = l->opt.key_rate > 0.0 ? l->k : 0, .warm_ok = !l->opt.warm_start};
    mim__fair_choice_t c =
        mim__fair_frame(&l->vs->sv->fair, l->fair_id, &d, l->frame_cpu, l->frame_wall, l->frame_skipped, now);
    pthread_mutex_lock(&l->lock);
    l->common = c;
    pthread_mutex_unlock(&l->lock);
}

/* Key and frame rates over the last second, for status and metrics. */
static void count_rates(mim__loop_t *l, int key)
{
    double now = mim_now();
    if (l->window_start == 0.0)
        l->window_start = now;
    l->window_frames++, l->window_keys += key != 0;
    double dt = now - l->window_start;
    if (dt < 1.0)
        return;
    pthread_mutex_lock(&l->lock);
    l->key_rate_hz = l->window_keys / dt, l->frame_rate_hz = l->window_frames / dt;
    pthread_mutex_unlock(&l->lock);
    mim__metrics_set(&l->vs->m, MIM__G_KEY_RATE, l->window_keys / dt);
    mim__metrics_set(&l->vs->m, MIM__G_FRAME_RATE, l->window_frames / dt);
    l->window_start = now, l->window_frames = l->window_keys = 0;
}

/* Whether lost landmark i is still held at its last position at vest time
 * t (seen, and lost for under HOLD_US). */
static int held(const mim__loop_t *l, uint32_t i, uint64_t t)
{
    return l->have_u[i] && t >= l->seen_us[i] && t - l->seen_us[i] < HOLD_US;
}

/* One vest frame's landmarks (present[i] = 0 for a lost one) and segment
 * rotations (R and have; NULL from a landmark source): a key frame or a
 * morph, published. */
static void landmarks_frame(mim__loop_t *l, const float *xyz, const uint8_t *present, const mim_quat *R,
                            const uint8_t *have, uint64_t t_vest)
{
    mim__vs_t *vs = l->vs;
    const uint32_t L = vs->map->count;
    mim__metrics_add(&vs->m, MIM__C_VEST_FRAMES, 1);
    float u[3 * MIM_LANDMARKS_MAX], shown[3 * MIM_LANDMARKS_MAX];
    int complete = 1, lost = 0;
    for (uint32_t i = 0; i < L; i++) {
        if (present[i]) {
            memcpy(l->last_u + 3 * i, xyz + 3 * i, 3 * sizeof *xyz);
            l->have_u[i] = 1, l->seen_us[i] = t_vest;
        }
        lost |= !present[i];
        complete &= l->have_u[i];
        for (int c = 0; c < 3; c++) {
            u[3 * i + c] = l->last_u[3 * i + c];
            shown[3 * i + c] = present[i] ? xyz[3 * i + c] : NAN;
        }
    }
    int to_complete = 0; /* lost landmarks not held any more (or never seen) */
    for (uint32_t i = 0; i < L; i++)
        to_complete |= !present[i] && !held(l, i, t_vest);
    if (lost)
        mim__metrics_add(&vs->m, MIM__C_INCOMPLETE, 1);
    if (to_complete) {
        /* Lost landmarks are completed from the store's templates (seed
         * 002's completion by retrieval) when enough are seen; else held.
         * Held first, for HOLD_US: over short losses the last position is
         * nearer than retrieval (bench/complete.c's vest replay). */
        float filled[3 * MIM_LANDMARKS_MAX];
        uint8_t done[MIM_LANDMARKS_MAX];
        mim_error_t cerr = {0};
        if (mim_session_complete(vs->s, xyz, present, NULL, filled, done, &cerr) == 0) {
            uint32_t n_done = 0;
            for (uint32_t i = 0; i < L; i++)
                if (done[i] && !held(l, i, t_vest)) memcpy(u + 3 * i, filled + 3 * i, 3 * sizeof *u), n_done++;
            complete = 1;
            mim__metrics_add(&vs->m, MIM__C_COMPLETED, n_done);
            pthread_mutex_lock(&l->lock);
            l->completed += n_done;
            pthread_mutex_unlock(&l->lock);
        }
    }
    if (!complete || !vs->sv->q)
        return; /* the transfer holds every landmark: it needs them all, and an index */
    l->frames_complete++;
    l->recent_no[l->frames_complete % RECENT_FRAMES] = l->frames_complete;
    memcpy(l->recent_u[l->frames_complete % RECENT_FRAMES], u, 3 * (size_t)L * sizeof *u);

    mim_error_t err = {0};
    int key = 0, rc = 0;
    const uint32_t skipped = l->skipped;
    /* the interval counts vest frames, skipped ones too: a loop that fell
     * behind keys as often as the others (fair.c) */
    l->since_key = skipped > UINT32_MAX - l->since_key ? UINT32_MAX : l->since_key + skipped;
    l->skipped = 0;
    l->frame_cpu = l->frame_wall = 0.0, l->frame_skipped = skipped;
    if (!l->keys[l->cur].valid || l->since_key >= l->k) {
        rc = make_key(l, u, R, have, &err);
        if (!rc)
            choose_interval(l), l->since_key = 0, key = 1;
    }
    if (rc) {
        mim__metrics_add(&vs->m, MIM__C_VEST_ERRORS, 1);
        set_error(l, mim_error_text(&err));
        return;
    }
    key_pose_t *b = &l->keys[l->cur], *a = &l->keys[!l->cur];
    const float *pos = b->pos;
    double t = (double)(l->since_key + 1) / l->k;
    if (a->valid && t < 1.0) {
        if ((rc = make_morph(l, a, b, t, &err))) {
            mim__metrics_add(&vs->m, MIM__C_VEST_ERRORS, 1);
            set_error(l, mim_error_text(&err));
            return;
        }
        pos = l->out;
    }
    l->since_key++;
    const int shows_key = pos == b->pos;
    if (l->own) { /* a foreign avatar: the pose on its own vertices */
        mim_session_output(vs->s, pos, l->own);
        pos = l->own;
    }
    double now = mim_now();
    mim_serve_frame_t f = {.number = ++l->number,
                           .t_vest_us = t_vest,
                           .arrival_us = (uint64_t)(l->arrival * 1e6),
                           .template_id = b->template_id,
                           .compute_us = (uint32_t)((now - l->arrival) * 1e6),
                           .key_interval = l->k,
                           .key = shows_key,
                           .n_vertices = vs->out_mesh->n_vertices,
                           .n_landmarks = L,
                           .positions = pos,
                           .landmarks = shown,
                           .session = vs->name};
    /* the stream's header holds 31 bytes of label (schemas/serve-ws-frame.md) */
    snprintf(f.label, sizeof f.label, "%.*s", (int)sizeof f.label - 1, b->label);
    mim__ws_publish(vs->sv->ws, vs, &f);
    if (l->opt.on_frame)
        l->opt.on_frame(l->opt.user, &f);
    mim__metrics_add(&vs->m, MIM__C_FRAMES, 1);
    mim__metrics_observe(&vs->m, MIM__H_FRAME, mim_now() - l->arrival);
    mim__metrics_set(&vs->m, MIM__G_KEY_INTERVAL, l->k);
    count_rates(l, key);
    share_costs(l, now);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The vest's period: the median of the intervals between its latest
 * completed frames, every one of them (also those flush_frames skips), so
 * that skipped or lost frames do not read as a slower vest (which would
 * change a fixed key rate's interval, and widen the auto budget just when
 * the loop is behind). */
static void vest_period(mim__loop_t *l, uint64_t t_vest)
{
    if (l->t_prev_vest && t_vest > l->t_prev_vest && t_vest - l->t_prev_vest < 1000000) {
        l->dt[l->i_dt] = (double)(t_vest - l->t_prev_vest) * 1e-6;
        l->i_dt = (l->i_dt + 1) % PERIOD_SAMPLES;
        l->n_dt += l->n_dt < PERIOD_SAMPLES;
        double s[PERIOD_SAMPLES];
        memcpy(s, l->dt, l->n_dt * sizeof *s);
        qsort(s, l->n_dt, sizeof *s, cmp_double);
        l->period = s[l->n_dt / 2];
    }
    l->t_prev_vest = t_vest;
}

/* A completed vest frame: its landmarks now (forward kinematics of the
 * sensor state as it is, before a later frame's packets change it), its
 * avatar frame after the chunk (flush_frames). */
static void frame_done(mim__loop_t *l, uint64_t t)
{
    vest_period(l, t);
    if (l->pending)
        mim__metrics_add(&l->vs->m, MIM__C_SKIPPED, 1), l->skipped++;
    mim_vest_fk(&l->rig, &l->st, t, 0, l->pending_xyz, l->pending_present);
    mim_vest_fresh(&l->st, t, 0, l->pending_have);
    mim_vest_segment_rotations(&l->rig, l->st.q, l->pending_have, l->pending_R); /* the decoder took unit readings only */
    l->pending = 1, l->pending_t = t;
}

/* Vest frames completed while one chunk is decoded are not made at once:
 * only the newest of them is, after the chunk. A loop that keeps up reads
 * about one frame a chunk; one that fell behind (a slow solve, a busy
 * machine) finds several queued in the next read and skips to the newest
 * instead of working through a backlog it cannot catch up. */
static void on_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    mim__loop_t *l = user;
    uint64_t t[2], m[2];
    int done = mim_vest_assembler_push(&l->as, info, t, m), k = 0;
    /* a frame closed by this packet's later timestamp is taken before the
     * packet's orientations enter the state (as mimic vest replay does) */
    if (done > 0 && t[0] < info->t_us)
        frame_done(l, t[0]), k = 1;
    for (uint32_t i = 0; i < n; i++)
        mim_vest_state_update(&l->st, &f[i]);
    for (; k < done; k++)
        frame_done(l, t[k]);
}

static void flush_frames(mim__loop_t *l)
{
    if (l->pending)
        landmarks_frame(l, l->pending_xyz, l->pending_present, l->pending_R, l->pending_have, l->pending_t);
    l->pending = 0;
}

/* The vest's link state, told once per change (status, metrics, log). */
static void link_state(mim__loop_t *l, int up, const char *why)
{
    pthread_mutex_lock(&l->lock);
    int was_up = !strcmp(l->state, "streaming");
    pthread_mutex_unlock(&l->lock);
    if (up == was_up)
        return;
    set_state(l, up ? "streaming" : "reconnecting", why);
    if (up) { /* the outage is over: its message no longer says how things are */
        pthread_mutex_lock(&l->lock);
        if (l->outage)
            l->error[0] = 0, l->outage = 0;
        pthread_mutex_unlock(&l->lock);
    }
    mim__metrics_add(&l->vs->m, up ? MIM__C_VEST_RECONNECTS : MIM__C_VEST_DISCONNECTS, 1);
    mim__metrics_set(&l->vs->m, MIM__G_VEST_UP, up);
    if (!up) { /* no frames while it is away: the rates say so, not their last values */
        mim__fair_idle(&l->vs->sv->fair, l->fair_id); /* nor is it demand */
        pthread_mutex_lock(&l->lock);
        l->key_rate_hz = l->frame_rate_hz = 0.0;
        pthread_mutex_unlock(&l->lock);
        mim__metrics_set(&l->vs->m, MIM__G_KEY_RATE, 0.0);
        mim__metrics_set(&l->vs->m, MIM__G_FRAME_RATE, 0.0);
        l->window_start = 0.0, l->window_frames = l->window_keys = 0;
    }
    mim_log_emit(l->opt.log, l->opt.log_ctx, up ? MIM_LOG_INFO : MIM_LOG_WARN, "vest %s: %s", l->spec,
                 up ? "streaming again" : "lost; waiting for it to come back");
}

static void *run(void *arg)
{
    mim__loop_t *l = arg;
    mim__vs_t *vs = l->vs;
    while (!atomic_load(&l->stop)) {
        mim_vest_chunk_t ch;
        mim_error_t err = {0};
        int r = mim_vest_transport_read(l->t, &ch, &err);
        l->arrival = mim_now();
        if (r == -ETIMEDOUT) {
            double silent = l->arrival - l->t_data, limit = fmax(SILENCE_S, 5.0 * l->period);
            char msg[512];
            if (!mim_vest_transport_connected(l->t)) /* unplugged: the transport says for how long */
                snprintf(msg, sizeof msg, "%.500s", mim_error_text(&err));
            else if (silent > limit) /* there, but silent (a UDP sender that stopped) */
                snprintf(msg, sizeof msg, "vest %.400s: no data for %.1f s", l->spec, silent);
            else
                continue;
            link_state(l, 0, msg);
            set_outage(l, msg);
            continue;
        }
        if (r == 0) {
            uint64_t tl, ml;
            if (mim_vest_assembler_flush(&l->as, &tl, &ml)) {
                frame_done(l, tl);
                flush_frames(l);
            }
            set_state(l, "ended", NULL);
            mim__fair_idle(&vs->sv->fair, l->fair_id);
            mim__metrics_set(&vs->m, MIM__G_VEST_UP, 0);
            return NULL;
        }
        if (r < 0) {
            mim__metrics_add(&vs->m, MIM__C_VEST_ERRORS, 1);
            mim__metrics_set(&vs->m, MIM__G_VEST_UP, 0);
            set_state(l, "failed", mim_error_text(&err));
            mim__fair_idle(&vs->sv->fair, l->fair_id);
            return NULL;
        }
        l->t_data = l->arrival;
        link_state(l, 1, NULL); /* (nothing to do unless it was away) */
        if (ch.kind == MIM_VEST_CHUNK_STREAM) {
            if (ch.restart) {
                mim_vest_decoder_reset(l->dec);
                memset(&l->as, 0, sizeof l->as);
            }
            mim_vest_decoder_feed(l->dec, ch.data, ch.len, ch.t_us);
            flush_frames(l);
            continue;
        }
        /* a UDP landmark datagram: landmarks already */
        uint64_t tu;
        float xyz[3 * MIM_LANDMARKS_MAX];
        uint8_t present[MIM_LANDMARKS_MAX];
        uint32_t n = 0;
        mim_quat R[MIM_VEST_SEGMENTS];
        uint8_t have[MIM_VEST_SEGMENTS];
        int oriented = 0;
        if (mim_vest_udp_parse_orient((const char *)ch.data, ch.len, &tu, xyz, present, MIM_LANDMARKS_MAX, &n, R, have,
                                      &oriented, &err) ||
            n != vs->map->count) {
            if (!err.code)
                mim_error_set(&err, MIM_EFORMAT, "udp frame: %u landmarks, the avatar has %u", n, vs->map->count);
            mim__metrics_add(&vs->m, MIM__C_VEST_ERRORS, 1);
            set_error(l, mim_error_text(&err));
            continue;
        }
        vest_period(l, tu);
        landmarks_frame(l, xyz, present, oriented ? R : NULL, oriented ? have : NULL, tu);
    }
    set_state(l, "stopped", NULL);
    return NULL;
}

int mim__loop_open(mim__loop_t **out, mim__vs_t *vs, const mim_serve_options_t *opt, mim_error_t *err)
{
    *out = NULL;
    mim__loop_t *l = calloc(1, sizeof *l);
    mim_vest_skeleton_t *sk = malloc(sizeof *sk);
    const size_t n = vs->mesh->n_vertices;
    int rc = 0, ok = l && sk;
    if (l) {
        l->out = malloc(3 * n * sizeof *l->out);
        if (mim_session_maps_output(vs->s))
            ok = ok && (l->own = malloc(3 * (size_t)vs->out_mesh->n_vertices * sizeof *l->own));
        l->F = malloc(9 * n * sizeof *l->F);
        ok = ok && l->out && l->F;
        for (int i = 0; i < 2; i++) {
            key_pose_t *k = &l->keys[i];
            k->pos = malloc(3 * n * sizeof *k->pos);
            k->quats = malloc(4 * n * sizeof *k->quats);
            k->W = malloc(3 * n * sizeof *k->W);
            ok = ok && k->pos && k->quats && k->W;
        }
    }
    if (!ok)
        rc = mim_error_set(err, MIM_ENOMEM, "out of memory for the vest loop");
    const mim_error_t *why = NULL;
    if (!rc && (opt->relative < -1 || opt->relative > 1))
        rc = mim_error_set(err, MIM_EINVAL, "serve: relative %d (0 default, 1 on, -1 off)", opt->relative);
    if (!rc && opt->drive == MIM_DRIVE_ORIENTATION && !mim_session_skin(vs->s, &why, NULL))
        rc = mim_error_set(err, why->code, "--drive orientation: %s", mim_error_text(why));
    if (l) {
        l->vs = vs;
        l->opt = *opt;
        l->k = 1;
        l->fair_id = -1;
        l->common = (mim__fair_choice_t){1, 0, 0};
        pthread_mutex_init(&l->lock, NULL);
        snprintf(l->spec, sizeof l->spec, "%s", opt->vest);
        l->state = "streaming";
    }
    if (!rc) {
        mim_vest_state_reset(&l->st);
        mim_vest_calib_options_t co = {opt->vest_pose};
        rc = mim_vest_skeleton_estimate(sk, vs->mesh, vs->map, err);
        if (!rc)
            rc = mim_vest_calibrate(&l->rig, sk, &co, NULL, err);
        /* a service waits for its vest to come back, however long it is away */
        mim_vest_transport_options_t to = {.timeout_ms = 200, .realtime = 1, .reconnect_limit_ms = INT_MAX,
                                           .log = opt->log, .log_ctx = opt->log_ctx};
        if (!rc)
            rc = mim_vest_transport_open(&l->t, opt->vest, &to, err);
        mim_vest_decoder_options_t dopt = {.header_flags = l->t ? mim_vest_transport_header_flags(l->t) : 0};
        if (!rc && mim_vest_decoder_open(&l->dec, &dopt, on_packet, l))
            rc = mim_error_set(err, MIM_ENOMEM, "out of memory for the vest decoder");
    }
    if (!rc) {
        mim__metrics_set(&vs->m, MIM__G_VEST_UP, 1);
        l->t_data = mim_now();
    }
    if (!rc)
        l->fair_id = mim__fair_join(&vs->sv->fair); /* -1 (out of memory): its own k only */
    if (!rc && (rc = -pthread_create(&l->thread, NULL, run, l)) != 0)
        rc = mim_error_set(err, rc, "cannot start the vest thread: %s", strerror(-rc));
    if (l)
        l->started = !rc;
    free(sk);
    if (rc) {
        mim__loop_close(&l);
        return rc;
    }
    *out = l;
    return 0;
}

void mim__loop_close(mim__loop_t **pl)
{
    mim__loop_t *l = pl ? *pl : NULL;
    if (!l)
        return;
    if (l->started) {
        atomic_store(&l->stop, 1);
        pthread_join(l->thread, NULL);
    }
    if (l->vs)
        mim__fair_leave(&l->vs->sv->fair, l->fair_id);
    mim_vest_decoder_close(&l->dec);
    mim_vest_transport_close(&l->t);
    if (l->vs)
        pthread_mutex_destroy(&l->lock);
    free(l->out), free(l->F), free(l->own);
    for (int i = 0; i < 2; i++)
        free(l->keys[i].pos), free(l->keys[i].quats), free(l->keys[i].W);
    free(l);
    *pl = NULL;
}

const char *mim__loop_state(mim__loop_t *l)
{
    if (!l)
        return "none";
    pthread_mutex_lock(&l->lock);
    const char *state = l->state;
    pthread_mutex_unlock(&l->lock);
    return state;
}

json_t *mim__loop_status(mim__loop_t *l)
{
    if (!l)
        return json_null();
    pthread_mutex_lock(&l->lock);
    json_t *j = json_pack(
        "{s:s, s:s, s:o, s:o, s:o, s:I, s:s, s:i, s:i, s:s, s:f, s:f, s:f, s:f, s:f, s:s, s:I, s:f, s:I, s:s, s:I, s:I}", "spec", l->spec, "state", l->state,
        "error", l->error[0] ? json_string(l->error) : json_null(), "last_template",
        l->last_template ? json_integer((json_int_t)l->last_template) : json_null(), "last_label",
        l->last_label[0] ? json_string(l->last_label) : json_null(), "reconnects",
        (json_int_t)mim_vest_transport_reconnects(l->t), "key_rate_mode", l->opt.key_rate > 0.0 ? "fixed" : "auto",
        "key_interval", (int)l->k, "shared_key_interval", (int)l->common.k, "morph", l->linear ? "linear" : "frames",
        "key_rate_hz", l->key_rate_hz, "frame_rate_hz", l->frame_rate_hz, "key_ms", l->w_key * 1e3, "key_cpu_ms",
        l->c_key * 1e3, "morph_ms", l->w_morph * 1e3, "warm_start",
        l->opt.warm_start ? (l->opt.warm_start > 0 ? "on" : "off") : "auto", "warm_starts", (json_int_t)l->warm_starts,
        "iterations_per_key", l->key_frames ? (double)l->iterations / (double)l->key_frames : 0.0,
        "completed_landmarks", (json_int_t)l->completed, "drive", mim_session_drive_names[l->opt.drive],
        "oriented_keys", (json_int_t)l->oriented_keys, "skeleton_keys", (json_int_t)l->skeleton_keys);
    if (j)
        json_object_set_new(j, "degraded", l->degraded[0] ? json_string(l->degraded) : json_null());
    pthread_mutex_unlock(&l->lock);
    return j;
}
