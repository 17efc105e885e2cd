/* bench/serve: `mimic serve` under load (issue 6).
 *
 * One simulated vest at 60 Hz, N WebSocket clients on loopback (default 50)
 * for S seconds (default 60). Everything runs as the real binary: the bench
 * makes a synth store in a temp dir (`mimic synth`, `ingest`, `index`),
 * starts `mimic vest simulate --motion demo --loop --out pty:D/vest` and
 * `mimic serve --vest serial:D/vest --listen 127.0.0.1:0` as child
 * processes and kills them at the end.
 *
 * The clients are this process: the tests' RFC 6455 client
 * (tests/support/ws_client.h: its handshake, its frame reader fed from
 * here), one epoll loop per thread (--threads, default 1), which keeps only
 * the 112-byte header of each binary frame (the positions are read from the
 * socket and discarded). Per frame it records the end-to-end latency (its
 * CLOCK_MONOTONIC when the recv that completed the frame returned, minus the
 * header's arrival field: when the vest bytes that completed the frame
 * reached the server), the server's compute time field, the frame number
 * (gaps are drops) and the key flag, in arrays allocated before the run.
 * Latency minus the compute field is the fan-out (frame ready -> received).
 * A drop counts as "in a burst" when the frames on either side of it reached
 * the server much closer together than the vest period (the loop read a
 * backlog at once), else it happened in the fan-out.
 *
 * The reference, measured in the same run: the same stream with 1 client
 * for --ref-seconds (default 10), before the main phase; the latency with N
 * clients is printed as a ratio to it. Each figure is over all frames of a
 * phase (one long run, not a median of runs). CPU: the serve process's and
 * the vest simulator's utime + stime from /proc/PID/stat, and this
 * process's (the clients) from getrusage, over each phase, as % of one core.
 *
 * It never passes or fails on time: exit 0 when it ran, 1 when it could not
 * (a child failed, no frames), 2 on bad usage.
 *
 * usage: bench_serve [--clients N] [--seconds S] [--ref-seconds R]
 *                    [--format f32|i16] [--threads T] [--keep DIR] */
#include "bench_data.h"
#include "serve_procs.h"
#include "ws_client.h"

#include <arpa/inet.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <jansson.h>
#include <limits.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#ifndef MIMIC_BIN_DEFAULT
#define MIMIC_BIN_DEFAULT ""
#endif

#define HEAD MIMF_HEADER
#define RECV_BUF (256 * 1024)

typedef struct server_snap {
    double t, key_frames, vest_frames, frames, drops, sent, skipped;
    double serve_cpu, vest_cpu, self_cpu;
    sb_tasks_t tasks;
} server_snap_t;

static sb_child_t g_vest, g_serve;

static int snap(server_snap_t *s)
{
    char *m = sb_http_get("/metrics");
    s->t = sb_now();
    s->serve_cpu = sb_pid_cpu(g_serve.pid), s->vest_cpu = sb_pid_cpu(g_vest.pid), s->self_cpu = sb_self_cpu();
    sb_task_cpu(g_serve.pid, &s->tasks);
    if (!m)
        return -1;
    s->key_frames = sb_metric(m, "mimic_key_frames_total");
    s->vest_frames = sb_metric(m, "mimic_vest_frames_total");
    s->frames = sb_metric(m, "mimic_frames_total");
    s->drops = sb_metric(m, "mimic_frames_dropped_total");
    s->sent = sb_metric(m, "mimic_ws_frames_sent_total");
    s->skipped = sb_metric(m, "mimic_vest_frames_skipped_total"); /* -1 before the loop could skip */
    free(m);
    return 0;
}

/* ------------------------------------------------------------ WebSocket clients */

typedef struct wsc {
    ws_client_t ws; /* the connection; its reader (ws.rd) parses what the loop receives */
    int thread;
    /* the message being read: the start of a binary one, of a text one */
    uint8_t head[HEAD];
    char text[256];
    /* results */
    int hello, closed, error;
    uint64_t last, binary_before; /* frames seen before the window */
    uint32_t frames, keys, drops, bad, cap;
    uint32_t n_vertices, n_landmarks;
    float *lat_ms, *comp_ms;
    uint64_t prev_arrival;
    uint32_t burst_drops, same_arrival; /* see on_message */
} wsc_t;

typedef struct phase {
    int n, threads;
    wsc_t *c;
    int ep[16];
    pthread_t th[16];
    atomic_int recording, stop;
    uint64_t period_us;
    int i16;
} phase_t;

static const char *g_format = "f32";
static double g_rate = 60;

static void on_message(phase_t *ph, wsc_t *c, uint64_t t_us)
{
    const ws_reader_t *r = &c->ws.rd;
    if (r->msg_opcode == WS_TEXT) { /* text: hello, format, error */
        if (strstr(c->text, "\"hello\""))
            c->hello = 1;
        else if (strstr(c->text, "\"error\""))
            c->error++;
        return;
    }
    if (r->msg_opcode != WS_BINARY)
        return;
    const uint8_t *h = c->head;
    if (r->msg_len < HEAD || memcmp(h, "MIMF", 4)) {
        c->bad++;
        return;
    }
    mimf_t f;
    mimf_decode(h, HEAD, &f);
    uint64_t number = f.number, arrival = f.arrival;
    if (r->msg_len != mimf_size(&f) || f.i16 != ph->i16)
        c->bad++;
    c->n_vertices = f.n, c->n_landmarks = f.L;
    int rec = atomic_load_explicit(&ph->recording, memory_order_relaxed);
    if (rec && c->last && number > c->last + 1) {
        /* a drop is "in a burst" when the vest bytes of the frames around
         * it reached the server much closer together than the vest period
         * (the loop read a backlog at once, after a stall): frames were
         * then published faster than the vest rate */
        uint64_t gap = number - c->last - 1;
        c->drops += (uint32_t)gap;
        if (arrival - c->prev_arrival < (gap + 1) * ph->period_us / 2)
            c->burst_drops += (uint32_t)gap;
    }
    if (rec && c->last && number == c->last + 1 && arrival == c->prev_arrival)
        c->same_arrival++;
    c->prev_arrival = arrival;
    if (c->last && number <= c->last)
        c->bad++;
    c->last = number;
    if (!rec) {
        c->binary_before++;
        return;
    }
    if (c->frames < c->cap) {
        c->lat_ms[c->frames] = (float)((double)((int64_t)(t_us - arrival)) * 1e-3);
        c->comp_ms[c->frames] = (float)(f.compute * 1e-3);
    }
    c->frames++;
    c->keys += f.flags & 1u;
}

/* Feeds bytes received at t_us to the client's frame reader. */
static void feed(phase_t *ph, wsc_t *c, uint8_t *p, size_t n, uint64_t t_us)
{
    ws_reader_t *r = &c->ws.rd;
    for (;;) {
        ws_event_t ev;
        size_t k = ws_reader_next(r, p, n, &ev);
        p += k, n -= k;
        if (ev.type == WS_EV_NONE)
            return;
        if (ev.type == WS_EV_HEAD) {
            if (r->masked) { /* a server must not mask */
                c->error++, c->closed = 1;
                return;
            }
            if (r->opcode != WS_CONT && r->opcode < 8) /* a new data message */
                c->text[0] = 0;
        } else if (ev.type == WS_EV_DATA) {
            if (r->msg_opcode == WS_BINARY && ev.offset < HEAD) {
                size_t h = HEAD - ev.offset < ev.len ? HEAD - (size_t)ev.offset : ev.len;
                memcpy(c->head + ev.offset, ev.data, h);
            } else if (r->msg_opcode == WS_TEXT && ev.offset < sizeof c->text - 1) {
                size_t h = sizeof c->text - 1 - ev.offset < ev.len ? sizeof c->text - 1 - (size_t)ev.offset : ev.len;
                memcpy(c->text + ev.offset, ev.data, h);
                c->text[ev.offset + h] = 0;
            }
        } else if (r->opcode == WS_CLOSE) { /* WS_EV_END: the frame is whole */
            c->closed = 1;
            return;
        } else if (r->opcode == WS_PING) {
            if (ws_pong(&c->ws))
                c->error++;
        } else if (r->opcode < 8 && r->fin) {
            on_message(ph, c, t_us);
        }
    }
}

typedef struct th_arg {
    phase_t *ph;
    int k;
} th_arg_t;

static void *client_thread(void *arg)
{
    th_arg_t *a = arg;
    phase_t *ph = a->ph;
    uint8_t *buf = malloc(RECV_BUF);
    struct epoll_event ev[64];
    while (buf && !atomic_load(&ph->stop)) {
        int r = epoll_wait(ph->ep[a->k], ev, 64, 100);
        for (int i = 0; i < r; i++) {
            wsc_t *c = ev[i].data.ptr;
            for (;;) {
                ssize_t k = recv(c->ws.fd, buf, RECV_BUF, 0);
                if (k > 0) {
                    feed(ph, c, buf, (size_t)k, sb_now_us());
                    if (c->closed)
                        break;
                    continue;
                }
                if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
                    break;
                if (k < 0 && errno == EINTR)
                    continue;
                c->closed = 1; /* EOF or error */
                break;
            }
            if (c->closed)
                epoll_ctl(ph->ep[a->k], EPOLL_CTL_DEL, c->ws.fd, NULL);
        }
    }
    free(buf);
    return NULL;
}

/* Connects and upgrades one client (ws_connect: blocking, a 10 s deadline);
 * the bytes after the handshake go to its reader. */
static int client_connect(phase_t *ph, wsc_t *c)
{
    char path[64];
    snprintf(path, sizeof path, "/ws?format=%s", g_format);
    if (ws_connect(&c->ws, sb_port, path, 0))
        return -1;
    int one = 1;
    setsockopt(c->ws.fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    size_t n;
    uint8_t *rest = ws_take_buffered(&c->ws, &n);
    if (n)
        feed(ph, c, rest, n, sb_now_us());
    free(rest);
    fcntl(c->ws.fd, F_SETFL, fcntl(c->ws.fd, F_GETFL) | O_NONBLOCK);
    return 0;
}

/* ------------------------------------------------------------ one phase */

typedef struct result {
    int n, ready;
    double window;
    double lat_med, lat_p90, lat_p99, lat_max;
    double comp_med, comp_p90, comp_p99, comp_max;
    double cp99_min, cp99_med, cp99_max; /* per-client p99 latency */
    double frames_min, frames_med, drops_min, drops_med, drops_max, drops_total, burst_drops, same_arrival;
    double send_med, send_p90, send_p99, send_max; /* latency - compute: publish -> received */
    double keys_client_med; /* key frames per second seen by a client (median) */
    uint64_t bad, errors, closed, total_frames;
    double key_fps, vest_fps, frame_fps, server_drops, sent_fps, skipped;
    double serve_cpu, vest_cpu, self_cpu;
    double top_task_cpu, loop_share;
    int n_tasks;
    double key_ms, morph_ms, iter_per_key, key_interval, warm;
    double load_before, load_after;
    uint32_t n_vertices, n_landmarks;
} result_t;

static int cmp_desc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? 1 : x > y ? -1 : 0;
}

static int run_phase(int n, double seconds, int threads, result_t *R)
{
    memset(R, 0, sizeof *R);
    R->n = n;
    phase_t *ph = calloc(1, sizeof *ph);
    ph->n = n, ph->threads = threads < n ? threads : n;
    ph->i16 = !strcmp(g_format, "i16");
    ph->period_us = (uint64_t)(1e6 / g_rate);
    ph->c = calloc((size_t)n, sizeof *ph->c);
    /* room for 3x the vest rate over the window, allocated before the run */
    uint32_t cap = (uint32_t)(seconds * 180.0) + 1000;
    for (int i = 0; i < n; i++) {
        ph->c[i].ws.fd = -1;
        ph->c[i].cap = cap;
        ph->c[i].lat_ms = malloc(sizeof(float) * cap);
        ph->c[i].comp_ms = malloc(sizeof(float) * cap);
        if (!ph->c[i].lat_ms || !ph->c[i].comp_ms)
            return fprintf(stderr, "bench_serve: out of memory\n"), -1;
        memset(ph->c[i].lat_ms, 0, sizeof(float) * cap); /* touch the pages now */
        memset(ph->c[i].comp_ms, 0, sizeof(float) * cap);
    }
    th_arg_t args[16];
    for (int k = 0; k < ph->threads; k++) {
        ph->ep[k] = epoll_create1(EPOLL_CLOEXEC);
        args[k] = (th_arg_t){ph, k};
    }
    int connected = 0;
    for (int i = 0; i < n; i++) {
        wsc_t *c = &ph->c[i];
        c->thread = i % ph->threads;
        if (client_connect(ph, c)) {
            fprintf(stderr, "bench_serve: client %d could not connect to ws://127.0.0.1:%d/ws\n", i, sb_port);
            ws_close(&c->ws);
            c->closed = 1;
            continue;
        }
        connected++;
    }
    for (int i = 0; i < n; i++)
        if (ph->c[i].ws.fd >= 0) {
            struct epoll_event ev = {.events = EPOLLIN, .data.ptr = &ph->c[i]};
            epoll_ctl(ph->ep[ph->c[i].thread], EPOLL_CTL_ADD, ph->c[i].ws.fd, &ev);
        }
    for (int k = 0; k < ph->threads; k++)
        pthread_create(&ph->th[k], NULL, client_thread, &args[k]);

    /* every client has its hello and a first frame (at most 10 s) */
    double t0 = sb_now();
    int ready = 0;
    while (sb_now() - t0 < 10.0) {
        ready = 0;
        for (int i = 0; i < n; i++)
            ready += ph->c[i].hello && ph->c[i].last > 0 && !ph->c[i].closed;
        if (ready == n)
            break;
        usleep(20000);
    }
    R->ready = ready;
    if (ready < n)
        fprintf(stderr, "bench_serve: %d of %d clients connected, %d streaming after 10 s\n", connected, n, ready);
    int rc = 0;
    server_snap_t s0, s1;
    R->load_before = sb_loadavg1();
    if (ready == 0 || snap(&s0)) {
        rc = -1;
        fprintf(stderr, "bench_serve: no client receives frames%s\n", ready ? "" : " (or /metrics failed)");
    } else {
        atomic_store(&ph->recording, 1);
        double w0 = sb_now();
        while (sb_now() - w0 < seconds)
            usleep(50000);
        atomic_store(&ph->recording, 0);
        R->window = sb_now() - w0;
        if (snap(&s1)) {
            rc = -1;
            fprintf(stderr, "bench_serve: GET /metrics failed at the end of the phase (mimic serve %s)\n",
                    waitpid(g_serve.pid, NULL, WNOHANG) == 0 ? "is running" : "has exited");
            sb_print_log_tail(&g_serve);
        }
        char *st = sb_http_get("/api/status");
        json_t *j = st ? json_loads(st, 0, NULL) : NULL, *v = json_object_get(j, "vest");
        R->key_ms = json_real_value(json_object_get(v, "key_ms"));
        R->morph_ms = json_real_value(json_object_get(v, "morph_ms"));
        R->iter_per_key = json_number_value(json_object_get(v, "iterations_per_key"));
        R->key_interval = json_number_value(json_object_get(v, "key_interval"));
        R->warm = json_number_value(json_object_get(v, "warm_starts"));
        if (!j)
            fprintf(stderr, "bench_serve: GET /api/status failed\n");
        json_decref(j);
        free(st);
    }
    R->load_after = sb_loadavg1();
    atomic_store(&ph->stop, 1);
    for (int k = 0; k < ph->threads; k++)
        pthread_join(ph->th[k], NULL);
    for (int i = 0; i < n; i++)
        ws_close(&ph->c[i].ws);
    for (int k = 0; k < ph->threads; k++)
        close(ph->ep[k]);

    if (!rc) {
        uint64_t total = 0;
        for (int i = 0; i < n; i++)
            total += ph->c[i].frames < ph->c[i].cap ? ph->c[i].frames : ph->c[i].cap;
        R->total_frames = total;
        double *lat = malloc(sizeof(double) * (total + 1)), *comp = malloc(sizeof(double) * (total + 1));
        double *per = malloc(sizeof(double) * (size_t)n * 4), *fr = per + n, *dr = per + 2 * n, *ke = per + 3 * n;
        size_t k = 0;
        int m = 0;
        for (int i = 0; i < n; i++) {
            wsc_t *c = &ph->c[i];
            uint32_t f = c->frames < c->cap ? c->frames : c->cap;
            for (uint32_t j = 0; j < f; j++)
                lat[k + j] = c->lat_ms[j], comp[k + j] = c->comp_ms[j];
            if (f)
                per[m++] = bench_quantile(lat + k, (int)f, 0.99);
            k += f;
            fr[i] = c->frames, dr[i] = c->drops, ke[i] = c->keys / R->window;
            R->drops_total += c->drops, R->burst_drops += c->burst_drops, R->same_arrival += c->same_arrival;
            R->bad += c->bad, R->errors += (uint64_t)c->error, R->closed += (uint64_t)c->closed;
        }
        if (total) {
            R->lat_med = bench_median(lat, (int)total);
            R->lat_p90 = bench_quantile(lat, (int)total, 0.90);
            R->lat_p99 = bench_quantile(lat, (int)total, 0.99);
            R->lat_max = bench_quantile(lat, (int)total, 1.0);
            R->comp_med = bench_median(comp, (int)total);
            R->comp_p90 = bench_quantile(comp, (int)total, 0.90);
            R->comp_p99 = bench_quantile(comp, (int)total, 0.99);
            R->comp_max = bench_quantile(comp, (int)total, 1.0);
            /* lat is sorted now: the per-frame differences from the clients' arrays */
            size_t q = 0;
            for (int i = 0; i < n; i++) {
                wsc_t *c = &ph->c[i];
                uint32_t f = c->frames < c->cap ? c->frames : c->cap;
                for (uint32_t j = 0; j < f; j++)
                    lat[q++] = (double)c->lat_ms[j] - (double)c->comp_ms[j];
            }
            R->send_med = bench_median(lat, (int)total);
            R->send_p90 = bench_quantile(lat, (int)total, 0.90);
            R->send_p99 = bench_quantile(lat, (int)total, 0.99);
            R->send_max = bench_quantile(lat, (int)total, 1.0);
        }
        if (m) {
            R->cp99_min = bench_quantile(per, m, 0.0);
            R->cp99_med = bench_median(per, m);
            R->cp99_max = bench_quantile(per, m, 1.0);
        }
        R->frames_min = bench_quantile(fr, n, 0.0);
        R->frames_med = bench_median(fr, n);
        R->drops_min = bench_quantile(dr, n, 0.0);
        R->drops_med = bench_median(dr, n);
        R->drops_max = bench_quantile(dr, n, 1.0);
        R->keys_client_med = bench_median(ke, n);
        double dt = s1.t - s0.t;
        R->key_fps = (s1.key_frames - s0.key_frames) / dt;
        R->vest_fps = (s1.vest_frames - s0.vest_frames) / dt;
        R->frame_fps = (s1.frames - s0.frames) / dt;
        R->sent_fps = (s1.sent - s0.sent) / dt;
        R->server_drops = s1.drops - s0.drops;
        R->skipped = s0.skipped >= 0 ? s1.skipped - s0.skipped : -1;
        R->serve_cpu = 100.0 * (s1.serve_cpu - s0.serve_cpu) / dt;
        R->vest_cpu = 100.0 * (s1.vest_cpu - s0.vest_cpu) / dt;
        R->self_cpu = 100.0 * (s1.self_cpu - s0.self_cpu) / dt;
        /* the serve's busiest thread (the vest loop: query, transfer,
         * morph, encode) against all the rest (senders, the lws service thread) */
        double d[MAX_TASKS];
        int nd = 0;
        for (int i = 0; i < s1.tasks.n; i++) {
            double before = 0;
            for (int j = 0; j < s0.tasks.n; j++)
                if (s0.tasks.tid[j] == s1.tasks.tid[i])
                    before = s0.tasks.cpu[j];
            d[nd++] = 100.0 * (s1.tasks.cpu[i] - before) / dt;
        }
        qsort(d, (size_t)nd, sizeof *d, cmp_desc);
        R->n_tasks = nd;
        R->top_task_cpu = nd ? d[0] : 0;
        R->n_vertices = ph->c[0].n_vertices, R->n_landmarks = ph->c[0].n_landmarks;
        free(lat), free(comp), free(per);
    }
    for (int i = 0; i < n; i++)
        free(ph->c[i].lat_ms), free(ph->c[i].comp_ms);
    free(ph->c);
    free(ph);
    return rc;
}

static void print_result(const char *title, const result_t *R, double rate)
{
    printf("== %s: %d client%s, %.1f s window (%d streaming; load average %.2f -> %.2f)\n", title, R->n,
           R->n == 1 ? "" : "s", R->window, R->ready, R->load_before, R->load_after);
    printf("end-to-end latency (ms, vest bytes at the server -> frame received):  median %.3f  p90 %.3f  p99 %.3f  "
           "max %.3f   (%llu frames)\n",
           R->lat_med, R->lat_p90, R->lat_p99, R->lat_max, (unsigned long long)R->total_frames);
    printf("per-client p99 latency (ms):                        min %.3f  median %.3f  max %.3f\n", R->cp99_min,
           R->cp99_med, R->cp99_max);
    printf("server compute time field (ms, header offset 40):    median %.3f  p90 %.3f  p99 %.3f  max %.3f\n",
           R->comp_med, R->comp_p90, R->comp_p99, R->comp_max);
    printf("of which frame ready -> received (ms):               median %.3f  p90 %.3f  p99 %.3f  max %.3f\n",
           R->send_med, R->send_p90, R->send_p99, R->send_max);
    printf("frames received per client:                         min %.0f  median %.0f  (%.2f/s median; vest "
           "%.0f Hz)\n",
           R->frames_min, R->frames_med, R->frames_med / R->window, rate);
    printf("frames dropped per client:                          min %.0f  median %.0f  max %.0f  total %.0f  "
           "(server mimic_frames_dropped_total +%.0f)\n",
           R->drops_min, R->drops_med, R->drops_max, R->drops_total, R->server_drops);
    printf("drops in bursts (vest frames that reached the server together, after a stall): %.0f of %.0f; frames "
           "received sharing the previous frame's arrival time: %.0f\n",
           R->burst_drops, R->drops_total, R->same_arrival);
    printf("key frames per second:                              /metrics %.2f  key flag (median client) %.2f  "
           "key / vest frames %.3f\n",
           R->key_fps, R->keys_client_med, R->vest_fps > 0 ? R->key_fps / R->vest_fps : 0.0);
    printf("vest frames per second (/metrics):                  %.2f  (frames published %.2f/s, ws frames sent "
           "%.1f/s, vest frames skipped by the loop %.0f)\n",
           R->vest_fps, R->frame_fps, R->sent_fps, R->skipped);
    printf("CPU, %% of one core:                                 mimic serve %.1f  (busiest of its %d threads "
           "%.1f)  bench clients %.1f  vest simulator %.1f\n",
           R->serve_cpu, R->n_tasks, R->top_task_cpu, R->self_cpu, R->vest_cpu);
    printf("server /api/status vest:                            key_ms %.3f  morph_ms %.3f  iterations_per_key "
           "%.2f  key_interval %.0f  warm_starts %.0f\n",
           R->key_ms, R->morph_ms, R->iter_per_key, R->key_interval, R->warm);
    if (R->bad || R->errors || R->closed)
        printf("client problems:                                    %llu malformed or out-of-order frames, %llu "
               "errors, %llu closed early\n",
               (unsigned long long)R->bad, (unsigned long long)R->errors, (unsigned long long)R->closed);
}

/* ------------------------------------------------------------ main */

static const char usage[] =
    "usage: bench_serve [--clients N] [--seconds S] [--ref-seconds R] [--format f32|i16]\n"
    "                   [--threads T] [--rate HZ] [--drive auto|template|orientation] [--keep DIR]\n\n"
    "Load benchmark of mimic serve (issue 6): one simulated vest, N WebSocket clients on\n"
    "loopback. Makes a synth store (4 x 12 bodies) in a temp dir with the real mimic\n"
    "binary ($MIMIC_BIN, else the build's), starts `mimic vest simulate` on a pty and\n"
    "`mimic serve`, then measures a 1-client reference phase and the N-client phase.\n\n"
    "  --clients N      WebSocket clients in the main phase (default 50)\n"
    "  --seconds S      length of the main phase (default 60)\n"
    "  --ref-seconds R  length of the 1-client reference phase (default 10; 0: none)\n"
    "  --format F       f32 (default) or i16 positions\n"
    "  --threads T      client threads (epoll loops), 1..16 (default 1)\n"
    "  --rate HZ        vest rate (default 60)\n"
    "  --drive D        serve's --drive (default auto: the vest's segment orientations)\n"
    "  --keep DIR       work in DIR and keep it (default: a temp dir, removed)\n"
    "  -h, --help       this help\n";

static const char *find_bin(char *buf, size_t size)
{
    const char *e = getenv("MIMIC_BIN");
    if (e && *e)
        return e;
    if (*MIMIC_BIN_DEFAULT && access(MIMIC_BIN_DEFAULT, X_OK) == 0)
        return MIMIC_BIN_DEFAULT;
    ssize_t n = readlink("/proc/self/exe", buf, size - 32);
    if (n > 0) {
        buf[n] = 0;
        char *s = strrchr(buf, '/');
        if (s) {
            strcpy(s, "/../cli/mimic");
            if (access(buf, X_OK) == 0)
                return buf;
        }
    }
    return NULL;
}

static void rm_rf(const char *dir)
{
    pid_t p = fork();
    if (p == 0) {
        execlp("rm", "rm", "-rf", dir, (char *)NULL);
        _exit(127);
    }
    if (p > 0)
        waitpid(p, NULL, 0);
}

int main(int argc, char **argv)
{
    int clients = 50, threads = 1, c;
    double seconds = 60, ref_seconds = 10, rate = 60;
    const char *keep = NULL, *drive = "auto";
    static const struct option lo[] = {{"clients", required_argument, 0, 'c'}, {"seconds", required_argument, 0, 's'},
                                       {"ref-seconds", required_argument, 0, 'r'}, {"format", required_argument, 0, 'f'},
                                       {"threads", required_argument, 0, 't'}, {"rate", required_argument, 0, 'R'},
                                       {"keep", required_argument, 0, 'k'},    {"help", no_argument, 0, 'h'},
                                       {"drive", required_argument, 0, 'd'},
                                       {0, 0, 0, 0}};
    while ((c = getopt_long(argc, argv, "h", lo, NULL)) != -1) {
        if (c == 'c') clients = atoi(optarg);
        else if (c == 's') seconds = atof(optarg);
        else if (c == 'r') ref_seconds = atof(optarg);
        else if (c == 'f') g_format = optarg;
        else if (c == 't') threads = atoi(optarg);
        else if (c == 'R') rate = g_rate = atof(optarg);
        else if (c == 'k') keep = optarg;
        else if (c == 'd') drive = optarg;
        else if (c == 'h') return fputs(usage, stdout), 0;
        else return fputs(usage, stderr), 2;
    }
    if (optind < argc || clients < 1 || clients > 900 || seconds < 1 || seconds > 3600 || ref_seconds < 0 ||
        ref_seconds > 3600 || threads < 1 || threads > 16 || rate < 1 || rate > 2000 ||
        (strcmp(g_format, "f32") && strcmp(g_format, "i16")))
        return fputs(usage, stderr), 2;
    signal(SIGPIPE, SIG_IGN);

    char binbuf[4096];
    sb_bin = find_bin(binbuf, sizeof binbuf);
    if (!sb_bin)
        return fprintf(stderr, "bench_serve: cannot find the mimic binary (set MIMIC_BIN)\n"), 1;

    printf("command:");
    for (int i = 0; i < argc; i++)
        printf(" %s", argv[i]);
    printf("\nnproc %ld, load average %.2f, mimic %s\n", sysconf(_SC_NPROCESSORS_ONLN), sb_loadavg1(), sb_bin);
    fflush(stdout);

    if (keep) {
        snprintf(sb_dir, sizeof sb_dir, "%s", keep);
        mkdir(sb_dir, 0755);
    } else {
        const char *tmp = getenv("TMPDIR");
        snprintf(sb_dir, sizeof sb_dir, "%s/bench_serve_XXXXXX", tmp && *tmp ? tmp : "/tmp");
        if (!mkdtemp(sb_dir))
            return fprintf(stderr, "bench_serve: cannot make a temp dir: %s\n", strerror(errno)), 1;
    }
    char bodies[4200], store[4200], vest[4200], vest_out[4300], serial[4300], rate_s[32], maxc[32];
    snprintf(bodies, sizeof bodies, "%s/bodies", sb_dir);
    snprintf(store, sizeof store, "%s/store", sb_dir);
    snprintf(vest, sizeof vest, "%s/vest", sb_dir);
    snprintf(vest_out, sizeof vest_out, "pty:%s", vest);
    snprintf(serial, sizeof serial, "serial:%s", vest);
    snprintf(rate_s, sizeof rate_s, "%g", rate);
    snprintf(maxc, sizeof maxc, "%d", clients + 4 > 64 ? clients + 4 : 64);

    int status = 1;
    double t_setup = sb_now();
    char *a_synth[] = {"synth", "--out", bodies, "--subjects", "4", "--poses", "12", NULL};
    char *a_ingest[] = {"ingest", "--store", store, bodies, NULL};
    char *a_index[] = {"index", "--store", store, NULL};
    if (sb_run_mimic("synth", a_synth, 60) || sb_run_mimic("ingest", a_ingest, 60) || sb_run_mimic("index", a_index, 120))
        goto done;
    printf("store: 4 subjects x 12 poses (mimic synth, ingest, index) in %.1f s\n", sb_now() - t_setup);

    char line[4096];
    char *a_vest[] = {"vest", "simulate", "--motion", "demo", "--rate", rate_s, "--loop", "--out", vest_out, NULL};
    if (sb_spawn(&g_vest, "vest", a_vest, 1) || sb_first_line(&g_vest, line, sizeof line, 10.0)) {
        fprintf(stderr, "bench_serve: mimic vest simulate did not print its pty:\n");
        sb_print_log_tail(&g_vest);
        goto done;
    }
    char *a_serve[] = {"serve",  "--store",  store,    "--avatar",        "1",    "--vest",
                       serial,   "--vest-pose", "t",   "--listen",        "127.0.0.1:0", "--max-clients",
                       maxc,     "--drive", (char *)drive, NULL};
    if (sb_spawn(&g_serve, "serve", a_serve, 1) || sb_first_line(&g_serve, line, sizeof line, 30.0)) {
        fprintf(stderr, "bench_serve: mimic serve did not print its URL:\n");
        sb_print_log_tail(&g_serve);
        goto done;
    }
    const char *colon = strrchr(line, ':');
    sb_port = colon ? atoi(colon + 1) : 0;
    if (sb_port <= 0) {
        fprintf(stderr, "bench_serve: mimic serve printed '%s', not a URL\n", line);
        goto done;
    }
    printf("vest: mimic vest simulate --motion demo --rate %s --loop --out %s (pid %d)\n", rate_s, vest_out,
           (int)g_vest.pid);
    printf("serve: mimic serve --store %s --avatar 1 --vest %s --vest-pose t --listen 127.0.0.1:0 --max-clients %s "
           "(pid %d, port %d)\n",
           store, serial, maxc, (int)g_serve.pid, sb_port);
    printf("clients: raw RFC 6455 over loopback, format %s, %d epoll thread%s\n", g_format, threads,
           threads == 1 ? "" : "s");
    fflush(stdout);

    /* warm-up: wait until the loop publishes frames (it needs the vest
     * streaming and a first key frame), 1 client for 2 s, not counted */
    result_t warm, ref = {0}, main_r;
    double t_wait = sb_now();
    for (;;) {
        char *m = sb_http_get("/metrics");
        double f = m ? sb_metric(m, "mimic_frames_total") : -1;
        free(m);
        if (f > 0)
            break;
        if (sb_now() - t_wait > 20.0) {
            fprintf(stderr, "bench_serve: mimic serve published no frame in 20 s:\n");
            sb_print_log_tail(&g_serve);
            goto done;
        }
        usleep(100000);
    }
    if (run_phase(1, 2.0, 1, &warm))
        goto done;
    if (ref_seconds > 0) {
        if (run_phase(1, ref_seconds, 1, &ref))
            goto done;
        print_result("reference", &ref, rate);
        fflush(stdout);
    }
    if (run_phase(clients, seconds, threads, &main_r))
        goto done;
    print_result("load", &main_r, rate);
    mimf_t frame = {.n = main_r.n_vertices, .L = main_r.n_landmarks, .i16 = !strcmp(g_format, "i16")};
    printf("frame: %u vertices, %u landmarks, %zu bytes (%s)\n", main_r.n_vertices, main_r.n_landmarks,
           mimf_size(&frame), g_format);
    if (ref_seconds > 0 && ref.lat_med > 0)
        printf("latency %d clients / 1 client (same run):           median %.2f  p90 %.2f  p99 %.2f\n", clients,
               main_r.lat_med / ref.lat_med, main_r.lat_p90 / ref.lat_p90, main_r.lat_p99 / ref.lat_p99);
    printf("targets: p99 <= 10 ms: %.3f ms; key frames per vest frame 1: %.3f; drops for clients that keep up 0: "
           "%.0f\n",
           main_r.lat_p99, main_r.vest_fps > 0 ? main_r.key_fps / main_r.vest_fps : 0.0, main_r.drops_total);
    status = 0;

done:
    sb_stop_child(&g_serve);
    sb_stop_child(&g_vest);
    if (!keep && sb_dir[0])
        rm_rf(sb_dir);
    fflush(stdout);
    return status;
}
