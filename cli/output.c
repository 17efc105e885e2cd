/* The cli's log lines and progress line on stderr (output.h). Libraries
 * only call the callbacks; the environment and the terminal are read here,
 * at the top, where DESIGN.md "Layering" puts them. */
#include "output.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

/* stderr is one per process, so is its progress line; a log line may come
 * from a library's thread (serve's vest loop) while the main thread draws */
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static struct {
    int enabled;          /* drawing this run */
    int open;             /* a line is drawn and not yet ended by a newline */
    double t_start, t_last;
} bar;

static int progress_wanted(void)
{
    const char *force = getenv("MIMIC_PROGRESS");
    if (force && *force)
        return atoi(force) != 0;
    return isatty(STDERR_FILENO);
}

static void draw(const char *label, uint64_t done, uint64_t total, double now, int final)
{
    double dt = now - bar.t_start;
    double rate = dt > 0 ? (double)done / dt : 0;
    if (total) {
        double left = (double)(total - (done < total ? done : total));
        fprintf(stderr, "\r%s: %llu/%llu (%3.0f%%) %.1f/s ETA %.0fs   ", label, (unsigned long long)done,
                (unsigned long long)total, 100.0 * (double)done / (double)total, rate, rate > 0 ? left / rate : 0);
    } else {
        fprintf(stderr, "\r%s: %llu %.1f/s   ", label, (unsigned long long)done, rate);
    }
    if (final)
        fputc('\n', stderr);
    bar.open = !final;
    fflush(stderr);
}

void mim_cli_progress(void *ctx, int phase, const char *label, uint64_t done, uint64_t total)
{
    (void)ctx;
    pthread_mutex_lock(&lock);
    if (phase == MIM_PROGRESS_BEGIN) {
        bar.enabled = progress_wanted();
        bar.t_start = bar.t_last = mim_now();
    } else if (bar.enabled && phase == MIM_PROGRESS_STEP) {
        double now = mim_now();
        /* rate-limited, but the last step is always shown */
        if (now - bar.t_last >= 0.125 || done == total) {
            bar.t_last = now;
            draw(label, done, total, now, 0);
        }
    } else if (bar.enabled && phase == MIM_PROGRESS_END) {
        draw(label, done, total, mim_now(), 1);
        bar.enabled = 0;
    }
    pthread_mutex_unlock(&lock);
}

void mim_cli_log(void *ctx, int level, const char *msg)
{
    (void)ctx, (void)level;
    pthread_mutex_lock(&lock);
    if (bar.open) { /* the message gets a line of its own; the bar redraws below it */
        fputc('\n', stderr);
        bar.open = 0;
    }
    fprintf(stderr, "mimic: %s\n", msg);
    pthread_mutex_unlock(&lock);
}

void mim_cli_logf(const char *fmt, ...)
{
    char line[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    mim_cli_log(NULL, MIM_LOG_INFO, line);
}
