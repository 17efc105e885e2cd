/* Progress on long work: the state of one run (label, total, done) and the
 * calls to the caller's callback. Drawing it (a terminal line with rate
 * and ETA) is cli/'s business; libraries only report. */
#include "mim_core.h"

#include <time.h>

double mim_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

void mim_progress_begin(mim_progress_t *p, const char *label, uint64_t total)
{
    p->label = label;
    p->total = total;
    p->done = 0;
    p->active = 1;
    if (p->fn)
        p->fn(p->ctx, MIM_PROGRESS_BEGIN, label, 0, total);
}

void mim_progress_update(mim_progress_t *p, uint64_t done)
{
    p->done = done;
    if (p->fn && p->active)
        p->fn(p->ctx, MIM_PROGRESS_STEP, p->label, done, p->total);
}

void mim_progress_end(mim_progress_t *p)
{
    /* once: a failure path may end what the normal path already ended */
    if (p->fn && p->active)
        p->fn(p->ctx, MIM_PROGRESS_END, p->label, p->done, p->total);
    p->active = 0;
}
