/* The compute slots the sessions' vest loops share (internal.h says why):
 * a queue in the order the loops came, so that a loop that waits is
 * served in its turn. A slot given back goes straight to the first loop
 * waiting, and only that loop is woken: with 24 loops on 2 slots, waking
 * every waiter at each change (a broadcast) cost 22 wake-ups a slot given
 * back, each taking a core from the slot holders for nothing. */
#include "internal.h"

void mim__gate_init(mim__gate_t *g, unsigned slots)
{
    pthread_mutex_init(&g->lock, NULL);
    g->slots = slots ? slots : 1;
    g->busy = 0;
    g->head = g->tail = NULL;
}

void mim__gate_destroy(mim__gate_t *g)
{
    pthread_mutex_destroy(&g->lock);
}

void mim__gate_enter(mim__gate_t *g)
{
    pthread_mutex_lock(&g->lock);
    if (!g->head && g->busy < g->slots) {
        g->busy++;
        pthread_mutex_unlock(&g->lock);
        return;
    }
    /* first come, first served: wait at the queue's end until a slot is
     * handed over (no loop overtakes another) */
    mim__gate_waiter_t w = {.next = NULL, .granted = 0};
    pthread_cond_init(&w.turn, NULL);
    if (g->tail)
        g->tail->next = &w;
    else
        g->head = &w;
    g->tail = &w;
    while (!w.granted)
        pthread_cond_wait(&w.turn, &g->lock);
    pthread_mutex_unlock(&g->lock);
    pthread_cond_destroy(&w.turn);
}

void mim__gate_leave(mim__gate_t *g)
{
    pthread_mutex_lock(&g->lock);
    mim__gate_waiter_t *w = g->head;
    if (w) { /* the slot passes to the first waiting (busy stays) */
        g->head = w->next;
        if (!g->head)
            g->tail = NULL;
        w->granted = 1;
        pthread_cond_signal(&w->turn);
    } else {
        g->busy--;
    }
    pthread_mutex_unlock(&g->lock);
}
