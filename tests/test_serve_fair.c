/* The sessions' common key interval (serve/fair.c, issue 16 item 1): the
 * rule alone, on given CPU costs, and the registry the loops share, driven
 * by hand with given times and a given machine (its process's CPU, its
 * cores' idle time). No thread, no socket, no clock: these assert the
 * rule, not anyone's speed. */
#include "internal.h"

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#define P (1.0 / 60.0)

/* A session keyed at 60 Hz: a key frame of key ms CPU, frames morphs of
 * morph ms, linear ones of 0.02 ms. */
static mim__fair_demand_t sess(double key_ms, double morph_ms)
{
    return (mim__fair_demand_t){.key_cold = key_ms * 1e-3, .key_warm = 0.6 * key_ms * 1e-3, .morph = morph_ms * 1e-3,
                                .linear = 0.02e-3, .period = P, .warm_ok = 1};
}

/* The total cores of d at choice c, as the rule counts them (auto sessions). */
static double cores(const mim__fair_demand_t *d, size_t n, mim__fair_choice_t c)
{
    double t = 0.0;
    for (size_t i = 0; i < n; i++) {
        uint32_t k = d[i].fixed_k ? d[i].fixed_k : c.k;
        double ck = c.warm && !d[i].fixed_k ? d[i].key_warm : d[i].key_cold;
        double cm = c.linear && !d[i].fixed_k ? d[i].linear : d[i].morph;
        t += (ck + (k - 1) * cm) / (k * d[i].period);
    }
    return t;
}

/* Light load: a key frame for every vest frame, cold, whoever asks. */
static void test_light_load_keys_every_frame(void **state)
{
    (void)state;
    mim__fair_demand_t d[12];
    for (int i = 0; i < 12; i++)
        d[i] = sess(0.9, 0.5);
    /* 12 x 0.9 ms x 60 Hz = 0.65 cores, in 2 x 0.8 */
    mim__fair_choice_t c = mim__fair_choose(d, 12, 1.6);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    assert_false(c.linear);
    /* one session */
    c = mim__fair_choose(d, 1, 1.6);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* none */
    c = mim__fair_choose(d, 0, 1.6);
    assert_int_equal(c.k, 1);
}

/* Overload: warm key frames first, then the smallest k that fits, then
 * linear morphs; the choice always fits, and one k less would not. */
static void test_overload_smallest_fitting_interval(void **state)
{
    (void)state;
    mim__fair_demand_t d[24];
    for (int i = 0; i < 24; i++)
        d[i] = sess(0.9, 0.5);
    /* cold at k = 1: 1.30 cores; warm: 0.78 */
    mim__fair_choice_t c = mim__fair_choose(d, 24, 1.0);
    assert_int_equal(c.k, 1);
    assert_true(c.warm);
    assert_false(c.linear);
    assert_true(cores(d, 24, c) <= 1.0);
    /* frames morphs: 24 x (0.54 + (k-1) 0.5) / k ms x 60 -> 0.72 cores at
     * best, above 0.6: linear morphs, k = 2 (0.40 cores), as k = 1 (0.78)
     * does not fit */
    c = mim__fair_choose(d, 24, 0.6);
    assert_true(c.warm);
    assert_true(c.linear);
    assert_int_equal(c.k, 2);
    assert_true(cores(d, 24, c) <= 0.6);
    /* frames morphs that are cheap fit before linear ones do */
    for (int i = 0; i < 24; i++)
        d[i].morph = 0.1e-3;
    c = mim__fair_choose(d, 24, 0.6);
    assert_false(c.linear);
    assert_true(c.k > 1);
    assert_true(cores(d, 24, c) <= 0.6);
    mim__fair_choice_t less = c;
    less.k--;
    assert_true(cores(d, 24, less) > 0.6);
    /* nothing fits: one key frame in K_MAX, linear */
    c = mim__fair_choose(d, 24, 0.001);
    assert_int_equal(c.k, MIM__FAIR_K_MAX);
    assert_true(c.linear);
    c = mim__fair_choose(d, 24, 0.0);
    assert_int_equal(c.k, MIM__FAIR_K_MAX);
    c = mim__fair_choose(d, 24, -1.0);
    assert_int_equal(c.k, MIM__FAIR_K_MAX);
}

/* More sessions, a larger common interval (never a smaller one). */
static void test_interval_grows_with_sessions(void **state)
{
    (void)state;
    mim__fair_demand_t d[64];
    for (int i = 0; i < 64; i++)
        d[i] = sess(0.9, 0.5);
    uint32_t prev = 1;
    int prev_linear = 0;
    for (size_t n = 1; n <= 64; n++) {
        mim__fair_choice_t c = mim__fair_choose(d, n, 0.8);
        /* as sessions are added, the choice only gets cheaper: linear
         * once, k never back down within a morph method */
        assert_true(c.linear >= prev_linear);
        if (c.linear == prev_linear)
            assert_true(c.k >= prev);
        assert_true(cores(d, n, c) <= 0.8 || c.k == MIM__FAIR_K_MAX);
        prev = c.k, prev_linear = c.linear;
    }
    assert_true(prev > 1);
    /* and removed again (the registry packs the live ones): back to 1 */
    assert_int_equal(mim__fair_choose(d, 2, 0.8).k, 1);
}

/* Costs not measured yet (0, NaN, infinite) are the mean of the measured
 * ones, never free; when none is measured, there is nothing to share. */
static void test_unmeasured_costs(void **state)
{
    (void)state;
    mim__fair_demand_t d[24];
    for (int i = 0; i < 24; i++)
        d[i] = sess(0.9, 0.5);
    mim__fair_choice_t ref = mim__fair_choose(d, 24, 0.6);
    d[3].key_cold = 0.0, d[3].key_warm = NAN, d[3].morph = 0.0, d[3].linear = NAN;
    d[7].key_cold = NAN, d[7].key_warm = INFINITY, d[7].period = 0.0; /* 0: 1/60 */
    d[9].key_cold = -1.0, d[9].period = NAN;
    mim__fair_choice_t c = mim__fair_choose(d, 24, 0.6);
    assert_int_equal(c.k, ref.k);
    assert_int_equal(c.linear, ref.linear);
    for (int i = 0; i < 24; i++)
        d[i].key_cold = d[i].key_warm = d[i].morph = d[i].linear = NAN;
    c = mim__fair_choose(d, 24, 0.6);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* a NaN capacity fits nothing */
    for (int i = 0; i < 24; i++)
        d[i] = sess(0.9, 0.5);
    c = mim__fair_choose(d, 24, NAN);
    assert_int_equal(c.k, MIM__FAIR_K_MAX);
}

/* A fixed key rate keeps its own interval; its demand comes first, and the
 * auto sessions share the rest. */
static void test_fixed_rate_sessions(void **state)
{
    (void)state;
    mim__fair_demand_t d[13];
    for (int i = 0; i < 13; i++)
        d[i] = sess(0.9, 0.5);
    /* 12 auto: 0.65 cores cold; with 1 more at a fixed 60 Hz (0.054
     * cores) in 0.7: still every frame */
    d[12].fixed_k = 1;
    assert_int_equal(mim__fair_choose(d, 13, 0.7).k, 1);
    /* in 0.66 not: the fixed one's share is taken first */
    mim__fair_choice_t c = mim__fair_choose(d, 13, 0.66);
    assert_true(c.warm || c.k > 1);
    assert_true(cores(d, 13, c) <= 0.66);
    /* only fixed sessions: nothing to choose */
    for (int i = 0; i < 13; i++)
        d[i].fixed_k = 4;
    c = mim__fair_choose(d, 13, 0.01);
    assert_int_equal(c.k, 1);
    assert_false(c.linear);
}

/* A session whose warm start is not auto keeps cold key frames in the sum. */
static void test_warm_only_where_auto(void **state)
{
    (void)state;
    mim__fair_demand_t d[24];
    for (int i = 0; i < 24; i++)
        d[i] = sess(0.9, 0.5), d[i].warm_ok = 0;
    /* 1.30 cores cold, warm (0.78) not allowed: k = 1 does not fit 1.0 */
    mim__fair_choice_t c = mim__fair_choose(d, 24, 1.0);
    assert_true(c.k > 1);
}

/* Equal costs, equal intervals: the rule has no per-session answer. And
 * unequal ones still one k: a dearer avatar does not key less often. */
static void test_one_interval_for_all(void **state)
{
    (void)state;
    mim__fair_demand_t d[24];
    for (int i = 0; i < 24; i++)
        d[i] = sess(i % 2 ? 0.9 : 2.7, 0.5);
    mim__fair_choice_t c = mim__fair_choose(d, 24, 0.8);
    assert_true(c.k > 1);
    assert_true(cores(d, 24, c) <= 0.8);
}

/* The machine a registry reads (its sampler): the process's CPU and the
 * idle time of its cores so far, as the test sets them. */
typedef struct machine {
    double wall, process, idle;
} machine_t;

static void read_machine(void *user, mim__fair_sample_t *s)
{
    const machine_t *m = user;
    s->wall = m->wall, s->process = m->process, s->idle = m->idle;
}

/* n loops' frames at 60 Hz each for seconds, one in every `every` vest
 * periods made (the others skipped), each frame's compute taking cpu CPU
 * seconds in wall seconds of a compute slot, while the rest of the process
 * takes rest cores and idle cores lie idle (NaN: idle time unknown); *t
 * advances. */
typedef struct load {
    int n, every;
    double cpu, wall, rest, idle;
} load_t;

static mim__fair_choice_t run(mim__fair_t *f, machine_t *m, const int *id, const mim__fair_demand_t *d, load_t L,
                              double seconds, double *t)
{
    mim__fair_choice_t c = {0, 0, 0};
    long step = 0;
    for (double end = *t + seconds; *t < end; *t += P, step++) {
        m->wall = *t;
        m->idle += L.idle * P;
        m->process += L.rest * P;
        for (int i = 0; i < L.n; i++) {
            if (step % L.every) /* skipped: the next frame made tells */
                continue;
            m->process += L.cpu;
            c = mim__fair_frame(f, id[i], d, L.cpu, L.wall, step ? (uint32_t)L.every - 1 : 0, *t);
        }
    }
    return c;
}

/* The registry: entries join and leave, and count from their first frame
 * until they idle. The capacity is what the compute can get on the cores:
 * the larger of what it got plus the cores' idle time and slots x the
 * share of a core a slot holder runs, at most the cores less the rest of
 * the process (and --compute-cores, and the slots). Times, CPU and idle
 * time are given, not read. */
static void test_registry_capacity(void **state)
{
    (void)state;
    machine_t m = {100.0, 0.0, 0.0};
    mim__fair_t f;
    mim__fair_init(&f, 2, 2, 0.0, read_machine, &m);
    double cap, t = 100.0;
    mim__fair_choice_t c;
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 2.0) < 1e-9); /* the cores, until measured */
    assert_int_equal(c.k, 1);
    int id[24];
    for (int i = 0; i < 24; i++)
        assert_true((id[i] = mim__fair_join(&f)) >= 0);
    mim__fair_demand_t d = sess(0.9, 0.5); /* 24 x 0.9 ms x 60 = 1.30 cores at every frame */
    /* idle cores, a slot a whole core: the cores less the rest, 1.8 */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 0.2, 0.5}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.8) < 0.01);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* a slot holder preempted (0.6 of a core: the other loops, the
     * fan-out) with idle time left: the compute could take it; the old
     * rule's slots x 0.8 x 0.6 = 0.96 cores would have halved the key rate */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 1.5e-3, 0.2, 0.3}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.6) < 0.01); /* 1.3 + 0.3 */
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* another process soaks up every idle moment, yet a slot holder runs
     * 0.8 of the time: slots x 0.8 = 1.6 cores to take */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 1.125e-3, 0.2, 0.0}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.6) < 0.01);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* the demand met on a busy machine: what it got is its demand; a slot
     * holder runs half the time (1.0 core): the interval stays 1 */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 1.8e-3, 0.2, 0.0}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.3) < 0.01);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* the CPU spent: no idle time, the loops make one vest frame in 2
     * (the compute got 0.65 cores), a slot holder runs 0.4 of the time
     * (2 x 0.4 x 0.5 = 0.4): the demand fits 0.65 cores */
    c = run(&f, &m, id, &d, (load_t){24, 2, 0.9e-3, 2.25e-3, 0.2, 0.0}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.65) < 0.01);
    assert_true(c.warm);
    assert_true(c.k > 1);
    assert_true(cores(&d, 1, c) * 24 <= cap);
    /* the loop threads starved (one vest frame in 2 made) though a slot
     * holder runs 0.8 of the time: 2 x 0.8 x 0.5 = 0.8 cores; and while
     * they stay starved at the cheaper interval it stays (the share and
     * the frames made do not fall because the interval rose) */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 0.2, 0.5}, 10.0, &t);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    c = run(&f, &m, id, &d, (load_t){24, 2, 0.9e-3, 1.125e-3, 0.2, 0.0}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.8) < 0.01);
    assert_true(c.warm);
    assert_true(cores(&d, 1, c) * 24 <= cap);
    mim__fair_choice_t starved = c;
    c = run(&f, &m, id, &d, (load_t){24, 2, 0.5e-3, 0.625e-3, 0.2, 0.0}, 20.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.8) < 0.01);
    assert_int_equal(c.k, starved.k);
    /* cores idle again: back to cold key frames at every vest frame */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 0.2, 0.5}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.8) < 0.01);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* the rest of the process takes 1.2 cores: 0.8 left, whatever lies idle */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 1.2, 0.5}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.8) < 0.01);
    assert_true(c.warm || c.k > 1);
    assert_true(cores(&d, 1, c) * 24 <= cap);
    /* a share near 0, nothing idle, the process's CPU unknown: the
     * capacity's floor (0.01 cores), which nothing fits: linear morphs and
     * a key frame in 30 */
    c = run(&f, &m, id, &d, (load_t){24, 1, 1e-6, 1e-3, 0.2, 0.0}, 1.0, &t);
    m.process = NAN;
    c = run(&f, &m, id, &d, (load_t){24, 1, 1e-6, 1e-3, 0.2, 0.0}, 20.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.01) < 1e-9);
    assert_int_equal(c.k, MIM__FAIR_K_MAX);
    assert_true(c.linear);
    /* windows with too little compute to tell keep the share */
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.0, 0.0, 0.2, 0.0}, 2.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.01) < 1e-9);
    /* 20 leave; an entry is reused */
    for (int i = 4; i < 24; i++)
        mim__fair_leave(&f, id[i]);
    mim__fair_leave(&f, -1);
    int again = mim__fair_join(&f);
    assert_true(again >= 4 && again < 24);
    mim__fair_leave(&f, again);
    /* and a whole core again: every vest frame keyed */
    m.process = 0.0;
    c = run(&f, &m, id, &d, (load_t){4, 1, 0.9e-3, 0.9e-3, 0.1, 1.5}, 10.0, &t);
    assert_int_equal(c.k, 1);
    assert_false(c.warm);
    /* a frame from an entry that left (a loop closing) is harmless */
    c = mim__fair_frame(&f, id[5], &d, 0.9e-3, 0.9e-3, 0, t);
    mim__fair_destroy(&f);
}

/* Without idle time (no /proc/stat): slots x share, at most the cores
 * less the rest. One slot: one core at most, however many cores. */
static void test_registry_without_idle_time(void **state)
{
    (void)state;
    machine_t m = {100.0, 0.0, NAN};
    mim__fair_t f;
    double cap, t = 100.0;
    mim__fair_choice_t c;
    int id[24];
    mim__fair_demand_t d = sess(0.9, 0.5);
    mim__fair_init(&f, 2, 2, 0.0, read_machine, &m);
    for (int i = 0; i < 24; i++)
        id[i] = mim__fair_join(&f);
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 0.3, NAN}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.7) < 0.01);
    assert_int_equal(c.k, 1);
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 1.5e-3, 0.3, NAN}, 10.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.2) < 0.01); /* 2 x 0.6 */
    assert_true(c.warm || c.k > 1);
    mim__fair_destroy(&f);

    mim__fair_init(&f, 4, 1, 0.0, read_machine, &m);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 1.0) < 1e-9);
    mim__fair_destroy(&f);

    /* no sampler at all: the capacity stays at its most */
    mim__fair_init(&f, 2, 2, 0.0, NULL, NULL);
    for (int i = 0; i < 24; i++)
        id[i] = mim__fair_join(&f);
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 0.3, NAN}, 2.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 2.0) < 0.01);
    mim__fair_destroy(&f);
}

/* --compute-cores: a cap whatever lies idle; sessions whose vest went
 * away do not count. */
static void test_registry_given_cores(void **state)
{
    (void)state;
    machine_t m = {100.0, 0.0, 0.0};
    mim__fair_t f;
    double cap, t = 100.0;
    mim__fair_choice_t c;
    int id[24];
    mim__fair_demand_t d = sess(0.9, 0.5);
    mim__fair_init(&f, 2, 2, 0.5, read_machine, &m);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.5) < 1e-9);
    for (int i = 0; i < 24; i++)
        id[i] = mim__fair_join(&f);
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 0.1, 1.5}, 2.0, &t);
    mim__fair_state(&f, &c, &cap);
    assert_true(fabs(cap - 0.5) < 1e-9);
    assert_true(c.k > 1);
    /* 20 of them idle (their vests away) without leaving: not counted,
     * and the 4 left fit at every frame; a frame makes one count again */
    for (int i = 4; i < 24; i++)
        mim__fair_idle(&f, id[i]);
    mim__fair_idle(&f, -1);
    c = run(&f, &m, id, &d, (load_t){4, 1, 0.9e-3, 0.9e-3, 0.1, 1.5}, 1.0, &t);
    assert_int_equal(c.k, 1);
    c = run(&f, &m, id, &d, (load_t){24, 1, 0.9e-3, 0.9e-3, 0.1, 1.5}, 1.0, &t);
    assert_true(c.k > 1);
    mim__fair_destroy(&f);
}

/* /proc/stat's idle and iowait ticks of the process's CPUs only; the real
 * machine's figures are sane. */
static void test_cpu_idle(void **state)
{
    (void)state;
    const char *stat = "cpu  100 0 50 9000 30 0 0 0 0 0\n"
                       "cpu0 50 0 25 4000 10 0 0 0 0 0\n"
                       "cpu1 40 0 20 3000 15 0 0 0 0 0\n"
                       "cpu2 10 0 5 2000 5 0 0 0 0 0\n"
                       "intr 1 2 3\n";
    unsigned char mine[MIM__CPU_MAX] = {0};
    mine[0] = mine[2] = 1;
    assert_true(fabs(mim__cpu_idle_ticks(stat, mine) - (4010.0 + 2005.0)) < 1e-9);
    mine[0] = mine[2] = 0;
    assert_true(isnan(mim__cpu_idle_ticks(stat, mine)));
    assert_true(isnan(mim__cpu_idle_ticks("intr 1 2 3\n", mine)));
    assert_true(isnan(mim__cpu_idle_ticks("", mine)));

    mim__cpu_t cpu;
    mim__cpu_init(&cpu);
    assert_true(cpu.cores >= 1);
    unsigned marked = 0;
    for (int i = 0; i < MIM__CPU_MAX; i++)
        marked += cpu.mine[i];
    assert_true(marked >= cpu.cores);
    mim__fair_sample_t a, b;
    mim__cpu_sample(&cpu, &a);
    mim__cpu_sample(&cpu, &b);
    assert_true(b.wall >= a.wall);
    assert_true(a.process >= 0.0 && b.process >= a.process);
    if (isfinite(a.idle)) /* Linux: /proc/stat */
        assert_true(a.idle >= 0.0 && b.idle >= a.idle);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_light_load_keys_every_frame),
        cmocka_unit_test(test_overload_smallest_fitting_interval),
        cmocka_unit_test(test_interval_grows_with_sessions),
        cmocka_unit_test(test_unmeasured_costs),
        cmocka_unit_test(test_fixed_rate_sessions),
        cmocka_unit_test(test_warm_only_where_auto),
        cmocka_unit_test(test_one_interval_for_all),
        cmocka_unit_test(test_registry_capacity),
        cmocka_unit_test(test_registry_without_idle_time),
        cmocka_unit_test(test_registry_given_cores),
        cmocka_unit_test(test_cpu_idle),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
