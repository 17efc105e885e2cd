/* The common key interval of the sessions (issue 16): when the cores
 * cannot make a key frame for every vest frame of every session, every
 * session's key rate drops alike.
 *
 * Why not each loop on its own: each loop used to choose its key interval
 * k from its own wall-clock costs (loop.c). At 24 vests on 2 cores a key
 * frame's wall time was 14-24 ms (0.7-0.9 ms alone): the loops waited for
 * a core, and that wait counted as cost, so each loop flipped between
 * k = 1 and k = 30 on its own, and the loops that fell behind skipped to
 * the newest vest frame at different moments. Achieved key rates across
 * sessions: 18.7-45.2 Hz, min/max 0.50-0.63 (bench/RESULTS.md, "Many
 * vests in one process"). Sharing wall-clock costs between loops did not
 * help either (0.50 and 0.62, ibid.): wall time measures the machine's
 * load, not a session's demand.
 *
 * What this file does instead:
 *  - each loop measures the CPU time of its compute (its thread's
 *    CLOCK_THREAD_CPUTIME_ID), which waiting for a core or the gate does
 *    not inflate, and publishes it here: the CPU cost of a cold and a warm
 *    key frame, a frames morph and a linear morph, and its vest period;
 *  - from these, one rule for the whole process (mim__fair_choose, pure):
 *    the smallest common k (and, as loop.c's rule for one session: warm
 *    starts before a lower key rate, frames morphs while they fit, else
 *    linear ones; a cost not measured yet is the mean of the measured
 *    ones, else a warm key frame as a cold one and a morph as a key frame,
 *    as the orientation drive's morphs cost) whose total demand, sum over
 *    sessions of
 *    (c_key + (k - 1) c_morph) / (k P) cores, fits the compute capacity.
 *    A session with a fixed key rate (--key-rate) keeps its own k; its
 *    demand is counted first, and the auto sessions share what is left.
 *    Sessions with equal costs get equal k; each loop uses the larger of
 *    its own k and the common one. A session counts from its first frame
 *    until its vest goes away, ends or fails (mim__fair_idle);
 *  - the capacity (cores the compute may take) is what the compute can get
 *    on the cores the process may run on (cpu.c: its affinity mask), the
 *    larger of two measures over each window of WINDOW_S, smoothed:
 *    (1) what it got plus what nobody used: the compute's CPU per second
 *    plus the cores' idle time (/proc/stat); (2) what the compute slots
 *    yield when kept busy: slots x the share of a core a slot holder runs
 *    (its CPU over its wall time in the slot; other work on the machine
 *    preempts it) x the fraction of the vest frames the loops made (a loop
 *    thread starved of a core skips frames before it asks for a slot).
 *    (1) tells that idle cores are there to take; (2) that the compute
 *    gets a core when it asks, whoever else runs, which (1) misses when
 *    other processes soak up every idle moment. Neither is what the
 *    compute got at the current interval alone, so neither falls because
 *    the interval rose. It is at most the cores less what the rest of the
 *    process uses (its CPU, CLOCK_PROCESS_CPUTIME_ID, less the compute's:
 *    the fan-out, the vests' decoding), --compute-cores (default: the
 *    cores) and the slots. So the interval rises above 1 only when the CPU
 *    is spent: no idle time left, and the compute preempted or the loops
 *    starved. A cheaper choice is taken only when the current one's demand
 *    exceeds the capacity by TOL_UP while the loops make their vest frames
 *    (a compute that meets its demand on a busy machine gets that demand,
 *    no more), or at all while they skip them; a dearer one only when it
 *    fits in HYSTERESIS of it.
 *    Before (through the runs of "Fair key rates" and "On an idle
 *    machine"): the capacity was (2) x 0.8, and dropped to 0.9 x the
 *    compute's CPU per second while loops waited over a vest period for a
 *    slot. Both estimated down what the compute could get: the share falls
 *    whenever 24 loop threads, the fan-out and the bench's processes share
 *    2 cores though idle time is left, and the drop took what the compute
 *    got (at a higher k, less) as all it could get. At 24 vests with one
 *    client each the interval stayed 2 while serve used 85 % of one core
 *    (bench/RESULTS.md, "24 vests on two cores"). Also tried here, not
 *    kept (one run each at 24 vests, one client each, other users'
 *    benchmarks on the machine): the cores less the rest of the process
 *    alone read 1.8 cores, kept k = 1, and serve got 95 % of one core: 37 %
 *    of the vest frames skipped, p99 60 ms (load average 3.4-6.5); (1)
 *    alone went down to 0.48 cores and k = 3 (load average 5.5-5.9) where
 *    the old rule held k = 2 with no frame skipped: others soaked up the
 *    idle time, and what the compute got at k = 3 was all it saw; (2)
 *    without the frames made, with the tolerance whether or not frames
 *    were skipped: at 32 vests (load average 10-20) slots x share read
 *    1.2 cores while the starved loops made 700-1000 of 1920 vest frames
 *    a second (54 % skipped), and at 24 vests k stayed 1 with 28 % skipped
 *    where the old rule held k = 2 with 12 (load average 6.7-8.0).
 *    Tried before that, not kept: (a) the share alone, without the drop:
 *    at 24 vests (10 clients each) it kept k = 1
 *    (cold key frames, 24 x 60/s at 0.7-0.9 ms: 1.0-1.3 cores, fit the
 *    capacity): 45 % of the vest frames skipped, 32.7-33.4 Hz a session,
 *    p99 169 ms (one run); (b) dropping the capacity when frames were late (vest frames
 *    skipped, or published over a period after their bytes came), not
 *    when loops waited for a slot: at 24 vests it went down to 8.7 Hz a
 *    session with frames still 6-16 % late (the fan-out's and the
 *    machine's lateness, not the key frames'); guarded (only while the
 *    compute was half the process's CPU) it held 22 Hz at 24 vests, but at
 *    12 vests on the loaded machine it keyed 48-49 Hz with 5.5 % skipped
 *    where the old loops keyed 56.8-58.8 Hz with 2.4 % (one run each,
 *    load average 5.4-6.9): fewer key frames did not put late frames on
 *    time; (c) dropping when loops waited over half a vest period for a
 *    slot: 12 vests keyed 39-54 Hz (2.3-5.7 % skipped). Late frames alone
 *    are no sign the CPU is spent;
 *  - loop.c counts the interval in vest frames (skipped ones too), not in
 *    frames it published, so a loop that skipped a frame makes its next
 *    key on time: with one k, every session keys at the vest rate / k.
 *
 * Measured with bench/serve --vests 12,24 (bench/RESULTS.md, "Fair key
 * rates", "24 vests on two cores"). */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define WINDOW_S 0.5    /* the compute's and the process's CPU and the cores' idle time are summed over this */
#define EWMA 0.3        /* weight of a window's figures in the smoothed ones */
#define WALL_MIN 0.002  /* seconds of compute a window needs to tell a share */
#define CAP_MIN 0.01    /* cores: the capacity never goes below this (unless given lower) */
#define HYSTERESIS 0.9  /* a dearer choice than the current one must fit in this much of the capacity */
#define TOL_UP 1.05     /* a cheaper one is taken when the current one needs over this much of it, */
#define MADE_OK 0.98    /* ... or any more than it while the loops make fewer of the vest frames than this */

static int known(double c)
{
    return isfinite(c) && c > 0.0;
}

/* A session's cores at interval k: (ck + (k - 1) cm) / (k P). */
static double demand_at(double ck, double cm, double P, uint32_t k)
{
    return (ck + (double)(k - 1) * cm) / ((double)k * P);
}

static double period_of(const mim__fair_demand_t *d)
{
    return known(d->period) ? d->period : 1.0 / 60.0;
}

mim__fair_choice_t mim__fair_choose(const mim__fair_demand_t *d, size_t n, double capacity)
{
    mim__fair_choice_t c = {1, 0, 0};
    /* an unmeasured cost (a session just added) is taken as the mean of
     * the measured ones, not as free */
    double sum[4] = {0}, cnt[4] = {0};
    for (size_t i = 0; i < n; i++) {
        const double v[4] = {d[i].key_cold, d[i].key_warm, d[i].morph, d[i].linear};
        for (int j = 0; j < 4; j++)
            if (known(v[j]))
                sum[j] += v[j], cnt[j]++;
    }
    double mean[4];
    for (int j = 0; j < 4; j++)
        mean[j] = cnt[j] ? sum[j] / cnt[j] : 0.0;
    if (!cnt[0]) /* nothing measured yet: nothing to share */
        return c;
    double fixed = 0.0; /* the fixed-rate sessions' cores, at their own k */
    size_t n_auto = 0;
    for (size_t i = 0; i < n; i++) {
        double ck = known(d[i].key_cold) ? d[i].key_cold : mean[0];
        double cm = known(d[i].morph) ? d[i].morph : cnt[2] ? mean[2] : ck;
        if (d[i].fixed_k)
            fixed += demand_at(ck, fmin(cm, ck), period_of(&d[i]), d[i].fixed_k);
        else
            n_auto++;
    }
    if (!n_auto)
        return c;
    const double left = (isfinite(capacity) ? capacity : 0.0) - fixed;
    /* the auto sessions' cores at k, with warm key frames or not, frames
     * or linear morphs */
    for (int pass = 0; pass < 3; pass++) { /* cold k = 1; warm, frames morphs; warm, linear morphs */
        const int warm = pass > 0, linear = pass == 2;
        for (uint32_t k = 1; k <= MIM__FAIR_K_MAX; k++) {
            double total = 0.0;
            for (size_t i = 0; i < n; i++) {
                if (d[i].fixed_k)
                    continue;
                double cold = known(d[i].key_cold) ? d[i].key_cold : mean[0];
                double ck = cold;
                if (warm && d[i].warm_ok)
                    ck = known(d[i].key_warm) ? d[i].key_warm : cnt[1] ? mean[1] : cold;
                double cm = linear ? (known(d[i].linear) ? d[i].linear : mean[3])
                                   : (known(d[i].morph) ? d[i].morph : cnt[2] ? mean[2] : ck);
                total += demand_at(ck, cm, period_of(&d[i]), k);
            }
            if (total <= left) {
                c.k = k, c.warm = warm, c.linear = linear && k > 1;
                return c;
            }
            if (pass == 0)
                break; /* cold key frames only at k = 1 (then warm ones first, as loop.c) */
        }
    }
    c.k = MIM__FAIR_K_MAX, c.warm = 1, c.linear = 1;
    return c;
}

void mim__fair_init(mim__fair_t *f, unsigned cores, unsigned slots, double given, mim__fair_sampler_t sample,
                    void *sample_user)
{
    memset(f, 0, sizeof *f);
    pthread_mutex_init(&f->lock, NULL);
    f->cores = cores ? cores : 1;
    /* each slot computes on one core at most */
    f->capacity_max = fmin(isfinite(given) && given > 0.0 ? given : f->cores, slots ? slots : 1);
    f->capacity = f->capacity_max;
    f->sample = sample, f->sample_user = sample_user;
    f->s0 = (mim__fair_sample_t){NAN, NAN, NAN};
    f->rest = f->got = f->share = f->made = -1.0;
    f->slots = slots ? slots : 1;
    f->choice = (mim__fair_choice_t){1, 0, 0};
}

void mim__fair_destroy(mim__fair_t *f)
{
    free(f->d);
    free(f->packed);
    free(f->used);
    free(f->active);
    pthread_mutex_destroy(&f->lock);
}

/* How cheap a choice is: linear morphs, then warm key frames, then k. */
static uint32_t cheapness(mim__fair_choice_t c)
{
    return (uint32_t)c.linear * 4 * MIM__FAIR_K_MAX + (uint32_t)c.warm * 2 * MIM__FAIR_K_MAX + c.k;
}

/* The active entries packed (under the lock) and the choice for them: a
 * dearer one than now only when it fits with room (HYSTERESIS), a cheaper
 * one only when the current one is short by more than TOL_UP (by any
 * amount while the loops skip vest frames), so that the interval does not
 * flip at each window where demand and capacity meet. */
static void rechoose(mim__fair_t *f)
{
    size_t m = 0;
    for (size_t i = 0; i < f->n; i++)
        if (f->used[i] && f->active[i])
            f->packed[m++] = f->d[i];
    mim__fair_choice_t c = mim__fair_choose(f->packed, m, f->capacity);
    if (m && cheapness(c) < cheapness(f->choice)) {
        c = mim__fair_choose(f->packed, m, HYSTERESIS * f->capacity);
        if (cheapness(c) > cheapness(f->choice))
            c = f->choice;
    } else if (m && cheapness(c) > cheapness(f->choice) && f->made >= MADE_OK &&
               cheapness(mim__fair_choose(f->packed, m, TOL_UP * f->capacity)) <= cheapness(f->choice))
        c = f->choice; /* its demand is met: the compute gets what it needs */
    f->choice = c;
}

int mim__fair_join(mim__fair_t *f)
{
    pthread_mutex_lock(&f->lock);
    int id = -1;
    for (size_t i = 0; i < f->n; i++)
        if (!f->used[i]) {
            id = (int)i;
            break;
        }
    if (id < 0) {
        size_t n = f->n + 1;
        mim__fair_demand_t *d = realloc(f->d, n * sizeof *d);
        if (d)
            f->d = d;
        mim__fair_demand_t *p = realloc(f->packed, n * sizeof *p);
        if (p)
            f->packed = p;
        unsigned char *u = realloc(f->used, n);
        if (u)
            f->used = u;
        unsigned char *t = realloc(f->active, n);
        if (t)
            f->active = t;
        if (d && p && u && t)
            id = (int)f->n, f->n = n;
    }
    if (id >= 0) {
        memset(&f->d[id], 0, sizeof f->d[id]);
        f->used[id] = 1;
        f->active[id] = 0; /* counted from its first frame */
        rechoose(f);
    }
    pthread_mutex_unlock(&f->lock);
    return id;
}

void mim__fair_idle(mim__fair_t *f, int id)
{
    if (id < 0)
        return;
    pthread_mutex_lock(&f->lock);
    if ((size_t)id < f->n && f->used[id] && f->active[id]) {
        f->active[id] = 0;
        rechoose(f);
    }
    pthread_mutex_unlock(&f->lock);
}

void mim__fair_leave(mim__fair_t *f, int id)
{
    if (id < 0)
        return;
    pthread_mutex_lock(&f->lock);
    if ((size_t)id < f->n)
        f->used[id] = 0;
    rechoose(f);
    pthread_mutex_unlock(&f->lock);
}

static void smooth(double *avg, double x)
{
    *avg = *avg >= 0.0 ? (1.0 - EWMA) * *avg + EWMA * x : x;
}

/* A window's end (under the lock): the compute's CPU per second plus the
 * cores' idle time, the slots' share of a core, the process's CPU less
 * the compute's, and the capacity from them. */
static void window_end(mim__fair_t *f, double dt)
{
    mim__fair_sample_t s = {NAN, NAN, NAN};
    if (f->sample)
        f->sample(f->sample_user, &s);
    const double W = s.wall - f->s0.wall, compute = f->w_cpu / dt;
    const double used = (s.process - f->s0.process) / W, idle = (s.idle - f->s0.idle) / W;
    if (known(W) && isfinite(used))
        smooth(&f->rest, fmin(fmax(used - compute, 0.0), f->cores));
    if (known(W) && isfinite(idle))
        smooth(&f->got, compute + fmin(fmax(idle, 0.0), f->cores));
    if (f->w_wall >= WALL_MIN)
        smooth(&f->share, fmin(1.0, f->w_cpu / f->w_wall));
    if (f->w_vest > 0.0)
        smooth(&f->made, f->w_made / f->w_vest);
    double can = -1.0; /* the larger of (1) and (2), as measured */
    if (f->got >= 0.0)
        can = f->got;
    if (f->share >= 0.0)
        can = fmax(can, f->slots * f->share * (f->made >= 0.0 ? f->made : 1.0));
    double cap = f->capacity_max;
    if (f->rest >= 0.0)
        cap = fmin(cap, f->cores - f->rest);
    if (can >= 0.0)
        cap = fmin(cap, can);
    f->capacity = fmax(fmin(CAP_MIN, f->capacity_max), cap);
    f->s0 = s;
}

mim__fair_choice_t mim__fair_frame(mim__fair_t *f, int id, const mim__fair_demand_t *d, double cpu, double wall,
                                   uint32_t skipped, double now)
{
    pthread_mutex_lock(&f->lock);
    if (id >= 0 && (size_t)id < f->n && f->used[id])
        f->d[id] = *d, f->active[id] = 1;
    if (f->window_start == 0.0 || now < f->window_start)
        f->window_start = now, f->w_cpu = f->w_wall = f->w_made = f->w_vest = 0.0;
    if (known(cpu) && known(wall))
        f->w_cpu += cpu, f->w_wall += wall;
    f->w_made += 1.0, f->w_vest += 1.0 + (double)skipped;
    const double dt = now - f->window_start;
    if (dt >= WINDOW_S) {
        window_end(f, dt);
        f->window_start = now, f->w_cpu = f->w_wall = f->w_made = f->w_vest = 0.0;
        rechoose(f); /* costs change slowly: once a window is enough */
    }
    mim__fair_choice_t c = f->choice;
    pthread_mutex_unlock(&f->lock);
    return c;
}

void mim__fair_state(mim__fair_t *f, mim__fair_choice_t *choice, double *capacity)
{
    pthread_mutex_lock(&f->lock);
    *choice = f->choice;
    *capacity = f->capacity;
    pthread_mutex_unlock(&f->lock);
}
