/* Work on the caller's number of threads (coverage, preparing many
 * pose-pairs): the library never asks the machine how many cores it has,
 * nor sets process-wide thread attributes. */
#include "internal.h"

#include <pthread.h>
#include <stdlib.h>

typedef struct worker {
    void (*fn)(void *ctx, uint32_t worker);
    void *ctx;
    uint32_t id;
} worker_t;

static void *run(void *arg)
{
    worker_t *w = arg;
    w->fn(w->ctx, w->id);
    return NULL;
}

void mim__parallel(uint32_t threads, void (*fn)(void *ctx, uint32_t worker), void *ctx)
{
    uint32_t extra = threads > 1 ? threads - 1 : 0, started = 0;
    pthread_t *tid = extra ? malloc(extra * sizeof *tid) : NULL;
    worker_t *w = extra ? malloc(extra * sizeof *w) : NULL;
    if (tid && w)
        for (; started < extra; started++) {
            w[started] = (worker_t){fn, ctx, started + 1};
            if (pthread_create(&tid[started], NULL, run, &w[started])) break;
        }
    fn(ctx, 0);
    for (uint32_t t = 0; t < started; t++) pthread_join(tid[t], NULL);
    free(tid), free(w);
}
