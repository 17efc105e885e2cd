/* Progress on long work: count, rate and ETA on stderr, on a terminal only
 * (MIMIC_PROGRESS=1 forces it, =0 silences it), at most ~8 updates a second. */
#include "mim_core.h"

#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

double mim_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

void mim_progress_begin(mim_progress_t *p, const char *label, uint64_t total)
{
    const char *force = getenv("MIMIC_PROGRESS");
    p->label = label;
    p->total = total;
    p->done = 0;
    p->t_start = p->t_last = mim_now();
    if (force && *force) p->enabled = atoi(force) != 0;
    else p->enabled = isatty(STDERR_FILENO);
}

static void progress_print(mim_progress_t *p, double now, int final)
{
    double dt = now - p->t_start;
    double rate = dt > 0 ? (double)p->done / dt : 0;
    if (p->total) {
        double eta = rate > 0 ? (double)(p->total - (p->done < p->total ? p->done : p->total)) / rate : 0;
        fprintf(stderr, "\r%s: %llu/%llu (%3.0f%%) %.1f/s ETA %.0fs   ", p->label,
                (unsigned long long)p->done, (unsigned long long)p->total,
                100.0 * (double)p->done / (double)p->total, rate, eta);
    } else {
        fprintf(stderr, "\r%s: %llu %.1f/s   ", p->label, (unsigned long long)p->done, rate);
    }
    if (final) fputc('\n', stderr);
    fflush(stderr);
}

void mim_progress_update(mim_progress_t *p, uint64_t done)
{
    p->done = done;
    if (!p->enabled) return;
    double now = mim_now();
    if (now - p->t_last < 0.125 && done != p->total) return;
    p->t_last = now;
    progress_print(p, now, 0);
}

void mim_progress_end(mim_progress_t *p)
{
    if (p->enabled) progress_print(p, mim_now(), 1);
    p->enabled = 0;
}
