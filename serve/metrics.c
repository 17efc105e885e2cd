/* Counters and latency histograms, exposed in the Prometheus text format
 * (https://prometheus.io/docs/instrumenting/exposition_formats/). One mutex:
 * a handful of increments per request costs nothing next to a solve. */
#include "internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* seconds; sub-millisecond buckets because a key frame must fit in ~16 ms */
static const double bounds[MIM__BUCKETS] = {0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.0075, 0.01,
                                            0.025,   0.05,   0.1,   0.25,   0.5,   1.0,    2.5};
static const int statuses[MIM__STATUSES - 1] = {200, 400, 404, 405, 413, 500, 503};
static const char *const route_names[MIM__R_COUNT] = {"status",   "avatar", "query", "transfer", "metrics",
                                                      "sessions", "viewer", "other"};
static const struct {
    const char *name, *help;
} counter_info[MIM__C_COUNT] = {
    {"mimic_queries_total", "Landmark frames answered by the recognition index."},
    {"mimic_transfers_total", "Avatar transfers computed."},
    {"mimic_vest_frames_total", "Vest frames turned into landmarks."},
    {"mimic_vest_frames_skipped_total", "Vest frames skipped because a newer one had arrived before the loop was free."},
    {"mimic_frames_total", "Avatar frames published to the stream."},
    {"mimic_key_frames_total", "Key frames made (nearest template, then transfer)."},
    {"mimic_morph_frames_total", "Frames morphed between two key frames."},
    {"mimic_vest_incomplete_frames_total", "Vest frames with lost landmarks."},
    {"mimic_landmarks_completed_total", "Lost landmarks filled in from the store's templates (else held at their last position)."},
    {"mimic_frames_dropped_total", "Frames dropped for WebSocket clients that did not keep up."},
    {"mimic_vest_errors_total", "Vest read or decode errors."},
    {"mimic_vest_disconnects_total", "Times the vest went away."},
    {"mimic_vest_reconnects_total", "Times the vest came back."},
    {"mimic_ws_joined_total", "WebSocket clients that joined."},
    {"mimic_ws_left_total", "WebSocket clients that left."},
    {"mimic_ws_frames_sent_total", "Binary avatar frames sent to WebSocket clients."},
    {"mimic_ws_messages_total", "Messages received from WebSocket clients."},
    {"mimic_ws_bad_messages_total", "Client messages that were malformed (answered with an error)."},
    {"mimic_ws_evicted_total", "WebSocket clients closed for not reading (stalled too long, or their place taken by a new viewer)."},
};
static const struct {
    const char *name, *help;
} gauge_info[MIM__G_COUNT] = {
    {"mimic_key_interval", "Vest frames per key frame now (1: every vest frame is a key frame)."},
    {"mimic_key_rate_hz", "Key frames per second over the last second."},
    {"mimic_frame_rate_hz", "Frames published per second over the last second."},
    {"mimic_vest_up", "1 while the vest streams, 0 while it is away or without one."},
    {"mimic_ws_clients", "WebSocket clients connected now."},
};
static const struct {
    const char *name, *help;
} hist_info[MIM__H_COUNT] = {
    {"mimic_query_seconds", "Time to answer one landmark frame."},
    {"mimic_transfer_seconds", "Time of one transfer (solves only)."},
    {"mimic_key_frame_seconds", "Compute time of one key frame (query + transfer)."},
    {"mimic_morph_frame_seconds", "Compute time of one morphed frame."},
    {"mimic_frame_latency_seconds", "From the arrival of a vest frame's last bytes to its avatar frame being published."},
};

void mim__metrics_init(mim__metrics_t *m)
{
    memset(m, 0, sizeof *m);
    pthread_mutex_init(&m->lock, NULL);
}

void mim__metrics_destroy(mim__metrics_t *m)
{
    pthread_mutex_destroy(&m->lock);
}

void mim__metrics_add(mim__metrics_t *m, mim__counter_t c, uint64_t n)
{
    pthread_mutex_lock(&m->lock);
    m->counters[c] += n;
    pthread_mutex_unlock(&m->lock);
}

uint64_t mim__metrics_get(mim__metrics_t *m, mim__counter_t c)
{
    pthread_mutex_lock(&m->lock);
    uint64_t v = m->counters[c];
    pthread_mutex_unlock(&m->lock);
    return v;
}

static void observe(mim__histogram_t *h, double s)
{
    int b = 0;
    while (b < MIM__BUCKETS && s > bounds[b])
        b++;
    h->counts[b]++;
    h->n++;
    h->sum += s;
}

void mim__metrics_observe(mim__metrics_t *m, mim__hist_t h, double seconds)
{
    pthread_mutex_lock(&m->lock);
    observe(&m->hist[h], seconds);
    pthread_mutex_unlock(&m->lock);
}

void mim__metrics_set(mim__metrics_t *m, mim__gauge_t g, double v)
{
    pthread_mutex_lock(&m->lock);
    m->gauges[g] = v;
    pthread_mutex_unlock(&m->lock);
}

void mim__metrics_request(mim__metrics_t *m, mim__route_t r, int status, double seconds)
{
    int k = 0;
    while (k < MIM__STATUSES - 1 && statuses[k] != status)
        k++;
    pthread_mutex_lock(&m->lock);
    m->requests[r][k]++;
    observe(&m->request_seconds[r], seconds);
    pthread_mutex_unlock(&m->lock);
}

/* A growing text buffer; on out of memory it stays failed and text() is NULL. */
typedef struct buf {
    char *p;
    size_t len, cap;
    int failed;
} buf_t;

static void put(buf_t *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(buf_t *b, const char *fmt, ...)
{
    if (b->failed)
        return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(b->p ? b->p + b->len : NULL, b->p ? b->cap - b->len : 0, fmt, ap);
        va_end(ap);
        if (n < 0) {
            b->failed = 1;
            return;
        }
        if (b->p && b->len + (size_t)n < b->cap) {
            b->len += (size_t)n;
            return;
        }
        size_t cap = (b->cap ? 2 * b->cap : 4096) + (size_t)n;
        char *p = realloc(b->p, cap);
        if (!p) {
            b->failed = 1;
            return;
        }
        b->p = p, b->cap = cap;
    }
}

static void put_hist(buf_t *b, const char *name, const char *labels, const mim__histogram_t *h)
{
    uint64_t cum = 0;
    const char *sep = labels[0] ? "," : "";
    for (int i = 0; i < MIM__BUCKETS; i++) {
        cum += h->counts[i];
        put(b, "%s_bucket{%s%sle=\"%g\"} %llu\n", name, labels, sep, bounds[i], (unsigned long long)cum);
    }
    cum += h->counts[MIM__BUCKETS];
    put(b, "%s_bucket{%s%sle=\"+Inf\"} %llu\n", name, labels, sep, (unsigned long long)cum);
    put(b, "%s_sum%s%s%s %.9g\n", name, labels[0] ? "{" : "", labels, labels[0] ? "}" : "", h->sum);
    put(b, "%s_count%s%s%s %llu\n", name, labels[0] ? "{" : "", labels, labels[0] ? "}" : "",
        (unsigned long long)h->n);
}

/* A consistent snapshot of m; the copied mutex is never used. */
static void snapshot(mim__metrics_t *m, mim__metrics_t *out)
{
    pthread_mutex_lock(&m->lock);
    memcpy(out, m, sizeof *out);
    pthread_mutex_unlock(&m->lock);
}

static void merge_hist(mim__histogram_t *into, const mim__histogram_t *h)
{
    for (int i = 0; i <= MIM__BUCKETS; i++)
        into->counts[i] += h->counts[i];
    into->n += h->n;
    into->sum += h->sum;
}

char *mim__metrics_text(mim__metrics_t *m, mim__metrics_t *const *sessions, const char *const *names, size_t n)
{
    mim__metrics_t c, *each = n ? malloc(n * sizeof *each) : NULL;
    if (n && !each)
        return NULL;
    snapshot(m, &c);
    for (size_t k = 0; k < n; k++)
        snapshot(sessions[k], &each[k]);
    /* the process's totals: the service's own plus every session's */
    mim__metrics_t total = c;
    for (size_t k = 0; k < n; k++) {
        for (int i = 0; i < MIM__C_COUNT; i++)
            total.counters[i] += each[k].counters[i];
        for (int h = 0; h < MIM__H_COUNT; h++)
            merge_hist(&total.hist[h], &each[k].hist[h]);
        for (int g = 0; g < MIM__G_COUNT; g++)
            total.gauges[g] = g == MIM__G_KEY_INTERVAL ? (each[k].gauges[g] > total.gauges[g] ? each[k].gauges[g]
                                                                                              : total.gauges[g])
                                                       : total.gauges[g] + each[k].gauges[g];
    }

    buf_t b = {0};
    for (int i = 0; i < MIM__C_COUNT; i++) {
        put(&b, "# HELP %s %s\n# TYPE %s counter\n%s %llu\n", counter_info[i].name, counter_info[i].help,
            counter_info[i].name, counter_info[i].name, (unsigned long long)total.counters[i]);
        for (size_t k = 0; k < n; k++)
            put(&b, "%s{session=\"%s\"} %llu\n", counter_info[i].name, names[k],
                (unsigned long long)each[k].counters[i]);
    }
    for (int i = 0; i < MIM__G_COUNT; i++) {
        put(&b, "# HELP %s %s\n# TYPE %s gauge\n%s %.6g\n", gauge_info[i].name, gauge_info[i].help,
            gauge_info[i].name, gauge_info[i].name, total.gauges[i]);
        for (size_t k = 0; k < n; k++)
            put(&b, "%s{session=\"%s\"} %.6g\n", gauge_info[i].name, names[k], each[k].gauges[i]);
    }
    put(&b, "# HELP mimic_http_requests_total HTTP requests by route and status.\n"
            "# TYPE mimic_http_requests_total counter\n");
    for (int r = 0; r < MIM__R_COUNT; r++)
        for (int k = 0; k < MIM__STATUSES; k++)
            if (c.requests[r][k]) {
                char code[16] = "other";
                if (k < MIM__STATUSES - 1)
                    snprintf(code, sizeof code, "%d", statuses[k]);
                put(&b, "mimic_http_requests_total{route=\"%s\",code=\"%s\"} %llu\n", route_names[r], code,
                    (unsigned long long)c.requests[r][k]);
            }
    put(&b, "# HELP mimic_http_request_seconds Time from a request's start to its last byte sent.\n"
            "# TYPE mimic_http_request_seconds histogram\n");
    for (int r = 0; r < MIM__R_COUNT; r++) {
        char labels[64];
        snprintf(labels, sizeof labels, "route=\"%s\"", route_names[r]);
        put_hist(&b, "mimic_http_request_seconds", labels, &c.request_seconds[r]);
    }
    for (int h = 0; h < MIM__H_COUNT; h++) {
        put(&b, "# HELP %s %s\n# TYPE %s histogram\n", hist_info[h].name, hist_info[h].help, hist_info[h].name);
        put_hist(&b, hist_info[h].name, "", &total.hist[h]);
        for (size_t k = 0; k < n; k++) {
            char labels[64];
            snprintf(labels, sizeof labels, "session=\"%s\"", names[k]);
            put_hist(&b, hist_info[h].name, labels, &each[k].hist[h]);
        }
    }
    free(each);
    if (b.failed) {
        free(b.p);
        return NULL;
    }
    return b.p;
}
