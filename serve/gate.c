/* The compute slots the sessions' vest loops share (internal.h says why):
 * a ticket queue, so that a loop that waits is served in its turn. */
#include "internal.h"

void mim__gate_init(mim__gate_t *g, unsigned slots)
{
    pthread_mutex_init(&g->lock, NULL);
    pthread_cond_init(&g->turn, NULL);
    g->slots = slots ? slots : 1;
    g->busy = 0;
    g->next_ticket = g->serving = 0;
}

void mim__gate_destroy(mim__gate_t *g)
{
    pthread_cond_destroy(&g->turn);
    pthread_mutex_destroy(&g->lock);
}

void mim__gate_enter(mim__gate_t *g)
{
    pthread_mutex_lock(&g->lock);
    uint64_t ticket = g->next_ticket++;
    /* first come, first served: a ticket waits for the ones before it to
     * have a slot, so no loop overtakes another forever */
    while (ticket != g->serving || g->busy >= g->slots)
        pthread_cond_wait(&g->turn, &g->lock);
    g->serving++;
    g->busy++;
    pthread_cond_broadcast(&g->turn); /* the next ticket may fit a free slot too */
    pthread_mutex_unlock(&g->lock);
}

void mim__gate_leave(mim__gate_t *g)
{
    pthread_mutex_lock(&g->lock);
    g->busy--;
    pthread_cond_broadcast(&g->turn);
    pthread_mutex_unlock(&g->lock);
}
