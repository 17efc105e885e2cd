/* The handler pool of mimic serve: the requests that take milliseconds
 * (POST /api/query, POST /api/transfer, GET /api/avatar) run here, not on
 * the lws service thread, which must stay free to write the stream: a
 * 5 ms transfer there would hold every client's next frame for 5 ms.
 *
 * Two threads (created with default attributes) share one FIFO of jobs.
 * A finished job goes on the done list and the service thread is woken
 * (lws_cancel_service, thread-safe); there, on
 * LWS_CALLBACK_EVENT_WAIT_CANCELLED, http.c takes the done jobs and asks
 * for a writable callback on each one's connection. A connection that
 * closes first either takes its job back from the queue or marks it
 * orphaned, and the service thread frees it when it comes back. The
 * queue is bounded (QUEUE_MAX jobs): past it a request gets 503 at once
 * instead of waiting behind others' transfers. */
#include "internal.h"

#include <libwebsockets.h>
#include <stdlib.h>
#include <string.h>

#define QUEUE_MAX 64u

struct mim__workers {
    mim_serve_t *sv;
    pthread_mutex_t lock;
    pthread_cond_t more;       /* a job or stop */
    mim__job_t *head, *tail;   /* waiting, oldest first */
    mim__job_t *done, *done_tail;
    unsigned waiting, running;
    struct lws_context *ctx;   /* woken when a job is done (NULL: nobody to wake) */
    int stop;
    unsigned n;
    pthread_t threads[];
};

void mim__job_free(mim__job_t *job)
{
    if (!job)
        return;
    mim__reply_free(&job->rp);
    free(job->body);
    free(job);
}

static void *work(void *arg)
{
    mim__workers_t *w = arg;
    pthread_mutex_lock(&w->lock);
    for (;;) {
        while (!w->stop && !w->head)
            pthread_cond_wait(&w->more, &w->lock);
        if (w->stop)
            break;
        mim__job_t *job = w->head;
        w->head = job->next;
        if (!w->head)
            w->tail = NULL;
        job->next = NULL;
        w->waiting--, w->running++;
        pthread_mutex_unlock(&w->lock);

        job->status = job->fn(w->sv, &job->rq, &job->rp);

        pthread_mutex_lock(&w->lock);
        w->running--;
        if (w->done_tail)
            w->done_tail->next = job;
        else
            w->done = job;
        w->done_tail = job;
        /* under the lock: close detaches the context before destroying it */
        if (w->ctx)
            lws_cancel_service(w->ctx); /* the service thread sends the reply */
    }
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

int mim__workers_open(mim__workers_t **out, mim_serve_t *sv, unsigned threads, mim_error_t *err)
{
    *out = NULL;
    mim__workers_t *w = calloc(1, sizeof *w + threads * sizeof(pthread_t));
    if (!w)
        return mim_error_set(err, MIM_ENOMEM, "out of memory for the request workers");
    w->sv = sv;
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->more, NULL);
    int rc = 0;
    for (; w->n < threads; w->n++)
        if ((rc = pthread_create(&w->threads[w->n], NULL, work, w)) != 0)
            break;
    if (rc) {
        mim__workers_close(&w);
        return mim_error_set(err, -rc, "cannot start the request workers: %s", strerror(rc));
    }
    *out = w;
    return 0;
}

void mim__workers_attach(mim__workers_t *w, struct lws_context *ctx)
{
    pthread_mutex_lock(&w->lock);
    w->ctx = ctx;
    pthread_mutex_unlock(&w->lock);
}

int mim__workers_submit(mim__workers_t *w, mim__job_t *job)
{
    pthread_mutex_lock(&w->lock);
    int full = w->waiting + w->running >= QUEUE_MAX;
    if (!full) {
        job->next = NULL;
        if (w->tail)
            w->tail->next = job;
        else
            w->head = job;
        w->tail = job;
        w->waiting++;
        pthread_cond_signal(&w->more);
    }
    pthread_mutex_unlock(&w->lock);
    return full ? -1 : 0;
}

unsigned mim__workers_pending(mim__workers_t *w)
{
    pthread_mutex_lock(&w->lock);
    unsigned n = w->waiting + w->running;
    pthread_mutex_unlock(&w->lock);
    return n;
}

mim__job_t *mim__workers_done(mim__workers_t *w)
{
    if (!w)
        return NULL;
    pthread_mutex_lock(&w->lock);
    mim__job_t *d = w->done;
    w->done = w->done_tail = NULL;
    pthread_mutex_unlock(&w->lock);
    return d;
}

int mim__workers_cancel(mim__workers_t *w, mim__job_t *job)
{
    int taken = 0;
    pthread_mutex_lock(&w->lock);
    for (mim__job_t **p = &w->head, *prev = NULL; *p; prev = *p, p = &(*p)->next)
        if (*p == job) {
            *p = job->next;
            if (w->tail == job)
                w->tail = prev;
            w->waiting--;
            taken = 1;
            break;
        }
    pthread_mutex_unlock(&w->lock);
    return taken;
}

void mim__workers_close(mim__workers_t **pw)
{
    mim__workers_t *w = pw ? *pw : NULL;
    if (!w)
        return;
    pthread_mutex_lock(&w->lock);
    w->stop = 1;
    pthread_cond_broadcast(&w->more);
    pthread_mutex_unlock(&w->lock);
    for (unsigned i = 0; i < w->n; i++)
        pthread_join(w->threads[i], NULL); /* a running handler finishes first */
    /* Called after the context is destroyed: every connection has closed,
     * taking its waiting job back or leaving it orphaned; what is left
     * (done, or finished just now) is freed here. */
    for (mim__job_t *j = w->head, *next; j; j = next)
        next = j->next, mim__job_free(j);
    for (mim__job_t *j = w->done, *next; j; j = next)
        next = j->next, mim__job_free(j);
    pthread_cond_destroy(&w->more);
    pthread_mutex_destroy(&w->lock);
    free(w);
    *pw = NULL;
}
