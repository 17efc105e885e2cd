/* The compute slots the sessions' loops share (serve/gate.c): never more
 * holders than slots, and a slot given back goes to the loop that has
 * waited longest. Real threads; what is asserted does not depend on their
 * timing (the queue is read under the gate's lock). */
#include "internal.h"

#include <pthread.h>
#include <sched.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

typedef struct shared {
    mim__gate_t gate;
    atomic_int inside, most, done;
    int order[16], n_order; /* who entered, in turn (written in a slot of 1) */
} shared_t;

typedef struct worker {
    shared_t *s;
    int index, rounds;
} worker_t;

static void *hold_and_count(void *arg)
{
    worker_t *w = arg;
    for (int r = 0; r < w->rounds; r++) {
        mim__gate_enter(&w->s->gate);
        int now = atomic_fetch_add(&w->s->inside, 1) + 1;
        for (int most = atomic_load(&w->s->most); now > most && !atomic_compare_exchange_weak(&w->s->most, &most, now);)
            ;
        sched_yield(); /* let the others try while this one holds it */
        atomic_fetch_sub(&w->s->inside, 1);
        atomic_fetch_add(&w->s->done, 1);
        mim__gate_leave(&w->s->gate);
    }
    return NULL;
}

/* 8 threads on 2 slots, 300 rounds each: never 3 holders, every round done. */
static void test_slots_never_exceeded(void **state)
{
    (void)state;
    static shared_t s;
    mim__gate_init(&s.gate, 2);
    pthread_t t[8];
    worker_t w[8];
    for (int i = 0; i < 8; i++) {
        w[i] = (worker_t){&s, i, 300};
        assert_int_equal(pthread_create(&t[i], NULL, hold_and_count, &w[i]), 0);
    }
    for (int i = 0; i < 8; i++)
        pthread_join(t[i], NULL);
    assert_true(atomic_load(&s.most) >= 1 && atomic_load(&s.most) <= 2);
    assert_int_equal(atomic_load(&s.done), 8 * 300);
    assert_int_equal(s.gate.busy, 0);
    assert_null(s.gate.head);
    mim__gate_destroy(&s.gate);
}

static void *enter_once(void *arg)
{
    worker_t *w = arg;
    mim__gate_enter(&w->s->gate);
    w->s->order[w->s->n_order++] = w->index; /* alone in the slot */
    mim__gate_leave(&w->s->gate);
    return NULL;
}

static int waiting(mim__gate_t *g)
{
    pthread_mutex_lock(&g->lock);
    int n = 0;
    for (const mim__gate_waiter_t *w = g->head; w; w = w->next)
        n++;
    pthread_mutex_unlock(&g->lock);
    return n;
}

/* One slot, held; 6 loops queue one after the other: they get it in the
 * order they came. */
static void test_first_come_first_served(void **state)
{
    (void)state;
    static shared_t s;
    mim__gate_init(&s.gate, 1);
    mim__gate_enter(&s.gate);
    pthread_t t[6];
    worker_t w[6];
    for (int i = 0; i < 6; i++) {
        w[i] = (worker_t){&s, i, 1};
        assert_int_equal(pthread_create(&t[i], NULL, enter_once, &w[i]), 0);
        while (waiting(&s.gate) < i + 1) /* it is in the queue before the next one starts */
            sched_yield();
    }
    assert_int_equal(s.gate.busy, 1);
    mim__gate_leave(&s.gate);
    for (int i = 0; i < 6; i++)
        pthread_join(t[i], NULL);
    assert_int_equal(s.n_order, 6);
    for (int i = 0; i < 6; i++)
        assert_int_equal(s.order[i], i);
    assert_int_equal(s.gate.busy, 0);
    mim__gate_destroy(&s.gate);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_slots_never_exceeded),
        cmocka_unit_test(test_first_come_first_served),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
