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
 * Many vests in one process (issue 16): --vests N (default 1, which is all
 * of the above, unchanged) starts N simulated vests (`mimic vest simulate
 * ... --out pty:D/vK`) and one `mimic serve` with N sessions
 * (`--session vK:vest=serial:D/vK,avatar=ID`, the avatars the first pose of
 * each synth subject in turn: templates 1, 13, 25, 37, 1, ...), and
 * --clients clients PER SESSION (default 10 then), each on
 * /ws?session=vK (its hello must name that session). --vests 1,2,4,8 is a
 * sweep: each N in turn, a fresh serve and vests on the same store, and a
 * table of the runs at the end; in a sweep (or with N > 1) even N = 1 is a
 * --session. Per session: frames received per client, latency p50/p99,
 * drops, and from its /metrics lines (session="vK") the key frames, vest
 * frames and vest frames the loop skipped over the window, hence the
 * achieved key rate and key frames per vest frame that reached it; from
 * /api/status its vest's state, key interval and key_ms. Pooled: the
 * figures above over every client. The reference phase is 1 client on
 * session v1 while all N sessions run. Then three verdicts: every session
 * had a key frame for every vest frame (key frames >= 99.5 % of the vest
 * frames that reached it, skipped ones included), the min/max achieved key
 * rate across sessions (fairness), and every session live (its vest
 * streaming, >= 1 key frame/s, every client of it >= 1 frame/s). The vest
 * simulators' CPU is summed (they share the two cores with serve here).
 *
 * It never passes or fails on time: exit 0 when it ran, 1 when it could not
 * (a child failed, no frames), 2 on bad usage.
 *
 * usage: bench_serve [--vests N|N1,N2,...] [--clients N] [--seconds S]
 *                    [--ref-seconds R] [--format f32|i16] [--threads T]
 *                    [--keep DIR] */
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
#include <math.h>
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

#define MAX_VESTS 64

typedef struct server_snap {
    double t, key_frames, vest_frames, frames, drops, sent, skipped;
    double serve_cpu, vest_cpu, self_cpu;
    sb_tasks_t tasks;
    /* per session (g_ns of them), from its session="vK" lines */
    double s_key[MAX_VESTS], s_vest[MAX_VESTS], s_frames[MAX_VESTS], s_drops[MAX_VESTS], s_skipped[MAX_VESTS];
} server_snap_t;

static sb_child_t g_serve, g_vests[MAX_VESTS];
static int g_nv = 1; /* vest simulators running */
static int g_ns;     /* sessions v1..vN of the serve; 0: the single vest of --vest, on plain /ws */

static int snap(server_snap_t *s)
{
    char *m = sb_http_get("/metrics");
    s->t = sb_now();
    s->serve_cpu = sb_pid_cpu(g_serve.pid), s->self_cpu = sb_self_cpu();
    s->vest_cpu = g_nv == 1 ? sb_pid_cpu(g_vests[0].pid) : 0;
    for (int k = 0; g_nv > 1 && k < g_nv; k++) {
        double v = sb_pid_cpu(g_vests[k].pid);
        s->vest_cpu += v > 0 ? v : 0;
    }
    sb_task_cpu(g_serve.pid, &s->tasks);
    if (!m)
        return -1;
    s->key_frames = sb_metric(m, "mimic_key_frames_total");
    s->vest_frames = sb_metric(m, "mimic_vest_frames_total");
    s->frames = sb_metric(m, "mimic_frames_total");
    s->drops = sb_metric(m, "mimic_frames_dropped_total");
    s->sent = sb_metric(m, "mimic_ws_frames_sent_total");
    s->skipped = sb_metric(m, "mimic_vest_frames_skipped_total"); /* -1 before the loop could skip */
    for (int k = 0; k < g_ns; k++) {
        char nm[16];
        snprintf(nm, sizeof nm, "v%d", k + 1);
        s->s_key[k] = sb_metric_session(m, "mimic_key_frames_total", nm);
        s->s_vest[k] = sb_metric_session(m, "mimic_vest_frames_total", nm);
        s->s_frames[k] = sb_metric_session(m, "mimic_frames_total", nm);
        s->s_drops[k] = sb_metric_session(m, "mimic_frames_dropped_total", nm);
        s->s_skipped[k] = sb_metric_session(m, "mimic_vest_frames_skipped_total", nm);
    }
    free(m);
    return 0;
}

/* ------------------------------------------------------------ WebSocket clients */

typedef struct wsc {
    ws_client_t ws; /* the connection; its reader (ws.rd) parses what the loop receives */
    int thread;
    int sess; /* its session v(sess + 1), with --vests */
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
    int n_sess; /* sessions the clients are spread over (/ws?session=vK); 0: plain /ws */
    wsc_t *c;
    int ep[16];
    pthread_t th[16];
    atomic_int recording, stop;
    uint64_t period_us;
    int i16;
} phase_t;

static const char *g_format = "f32";
static double g_rate = 60;

/* Whether a hello names session v(sess + 1): "session": "vK" */
static int hello_names(const char *text, int sess)
{
    const char *p = strstr(text, "\"session\"");
    if (!p)
        return 0;
    p += 9;
    while (*p == ' ' || *p == ':')
        p++;
    char want[24];
    int n = snprintf(want, sizeof want, "\"v%d\"", sess + 1);
    return !strncmp(p, want, (size_t)n);
}

static void on_message(phase_t *ph, wsc_t *c, uint64_t t_us)
{
    const ws_reader_t *r = &c->ws.rd;
    if (r->msg_opcode == WS_TEXT) { /* text: hello, format, error */
        if (strstr(c->text, "\"hello\"")) {
            c->hello = 1;
            if (ph->n_sess && !hello_names(c->text, c->sess)) /* the stream of another session */
                c->error++;
        }
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
    if (ph->n_sess)
        snprintf(path, sizeof path, "/ws?format=%s&session=v%d", g_format, c->sess + 1);
    else
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
    double key_ms, morph_ms, iter_per_key, key_interval, warm, key_cpu_ms;
    double cores, slots, capacity; /* /api/status compute (NaN: a serve without it) */
    double load_before, load_after;
    uint32_t n_vertices, n_landmarks;
} result_t;

/* One session's figures in a phase (--vests). */
typedef struct sess_result {
    int clients;
    double frames_min, frames_med;    /* received per client of it */
    double lat_med, lat_p99, lat_max; /* over its clients' frames */
    double drops, burst_drops;        /* frame-number gaps of its clients */
    /* from its /metrics lines over the window */
    double key_fps, vest_fps, frame_fps, skipped, server_drops;
    double key_per_vest, key_per_arrived; /* key frames / vest frames made; / those + the skipped */
    /* from /api/status at the end */
    double key_interval, key_ms, key_rate_hz, iter_per_key;
    char state[16], avatar[32];
    int live;
} sess_result_t;

static int cmp_desc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? 1 : x > y ? -1 : 0;
}

/* A phase of n clients for seconds. n_sess > 0: the clients are spread
 * evenly over sessions v1..v(n_sess) (/ws?session=); S (g_ns entries, or
 * NULL) gets every session's figures. */
static int run_phase(int n, double seconds, int threads, result_t *R, int n_sess, sess_result_t *S)
{
    memset(R, 0, sizeof *R);
    if (S)
        memset(S, 0, sizeof *S * (size_t)g_ns);
    R->n = n;
    phase_t *ph = calloc(1, sizeof *ph);
    ph->n = n, ph->threads = threads < n ? threads : n;
    ph->n_sess = n_sess;
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
        c->sess = n_sess ? (int)((long)i * n_sess / n) : 0;
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
        R->key_cpu_ms = json_number_value(json_object_get(v, "key_cpu_ms"));
        json_t *cm = json_object_get(j, "compute");
        R->cores = cm ? json_number_value(json_object_get(cm, "cores")) : NAN;
        R->slots = cm ? json_number_value(json_object_get(cm, "slots")) : NAN;
        R->capacity = cm ? json_number_value(json_object_get(cm, "capacity")) : NAN;
        if (!j)
            fprintf(stderr, "bench_serve: GET /api/status failed\n");
        json_t *list = json_object_get(j, "sessions");
        for (size_t i = 0; S && i < json_array_size(list); i++) {
            json_t *one = json_array_get(list, i), *sv = json_object_get(one, "vest");
            const char *name = json_string_value(json_object_get(one, "name"));
            int k = name && name[0] == 'v' ? atoi(name + 1) - 1 : -1;
            if (k < 0 || k >= g_ns)
                continue;
            S[k].key_interval = json_number_value(json_object_get(sv, "key_interval"));
            S[k].key_ms = json_number_value(json_object_get(sv, "key_ms"));
            S[k].key_rate_hz = json_number_value(json_object_get(sv, "key_rate_hz"));
            S[k].iter_per_key = json_number_value(json_object_get(sv, "iterations_per_key"));
            const char *st_s = json_string_value(json_object_get(sv, "state"));
            const char *av = json_string_value(json_object_get(one, "avatar"));
            snprintf(S[k].state, sizeof S[k].state, "%s", st_s ? st_s : "?");
            snprintf(S[k].avatar, sizeof S[k].avatar, "%s", av ? av : "?");
        }
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
        /* every session: its clients' frames, and its /metrics lines */
        for (int q = 0; S && q < g_ns; q++) {
            sess_result_t *E = &S[q];
            size_t kk = 0;
            int m2 = 0;
            for (int i = 0; i < n; i++) {
                wsc_t *c = &ph->c[i];
                if (!n_sess || c->sess != q)
                    continue;
                uint32_t f = c->frames < c->cap ? c->frames : c->cap;
                for (uint32_t j = 0; j < f; j++)
                    lat[kk++] = c->lat_ms[j];
                fr[m2++] = c->frames;
                E->drops += c->drops, E->burst_drops += c->burst_drops;
            }
            E->clients = m2;
            if (kk) {
                E->lat_med = bench_median(lat, (int)kk);
                E->lat_p99 = bench_quantile(lat, (int)kk, 0.99);
                E->lat_max = bench_quantile(lat, (int)kk, 1.0);
            }
            if (m2) {
                E->frames_min = bench_quantile(fr, m2, 0.0);
                E->frames_med = bench_median(fr, m2);
            }
            E->key_fps = (s1.s_key[q] - s0.s_key[q]) / dt;
            E->vest_fps = (s1.s_vest[q] - s0.s_vest[q]) / dt;
            E->frame_fps = (s1.s_frames[q] - s0.s_frames[q]) / dt;
            E->server_drops = s1.s_drops[q] - s0.s_drops[q];
            E->skipped = s1.s_skipped[q] - s0.s_skipped[q];
            double made = s1.s_vest[q] - s0.s_vest[q], keys = s1.s_key[q] - s0.s_key[q];
            E->key_per_vest = made > 0 ? keys / made : 0;
            E->key_per_arrived = made + E->skipped > 0 ? keys / (made + E->skipped) : 0;
            E->live = !strcmp(E->state, "streaming") && E->key_fps >= 1.0 &&
                      (!m2 || E->frames_min >= R->window);
        }
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
           "%.2f  key_interval %.0f  warm_starts %.0f  key_cpu_ms %.3f\n",
           R->key_ms, R->morph_ms, R->iter_per_key, R->key_interval, R->warm, R->key_cpu_ms);
    if (isfinite(R->capacity))
        printf("server /api/status compute:                         cores %.0f  slots %.0f  capacity %.2f cores\n",
               R->cores, R->slots, R->capacity);
    if (R->bad || R->errors || R->closed)
        printf("client problems:                                    %llu malformed or out-of-order frames, %llu "
               "errors, %llu closed early\n",
               (unsigned long long)R->bad, (unsigned long long)R->errors, (unsigned long long)R->closed);
}

/* ------------------------------------------------------------ main */

/* ------------------------------------------------------------ many vests (--vests) */

/* One run of a sweep, for the table at the end. */
typedef struct row {
    int vests, clients, ran;
    double load, window, key_min, skipped_pct, kr_min, kr_max, ki_max, fps_min;
    double lat_med, lat_p99, ref_p99, drops, server_drops, serve_cpu, serve_top, vest_cpu, self_cpu, key_ms_med;
    char capacity_s[16]; /* /api/status compute.capacity at the end ("-": a serve without it) */
    int all_keyed, all_live;
} row_t;

static void print_sessions(const sess_result_t *S, int ns, const result_t *R, int per, row_t *row)
{
    printf("per session (%d clients each; key frames, vest frames, skipped, key rate and frames/s from its "
           "/metrics lines over the window; key interval, key_ms and state from /api/status at the end):\n",
           per);
    printf("| session | avatar | frames/client min | latency p50 ms | p99 ms | drops (bench) | server drops | "
           "key frames/s | vest frames/s | skipped | key / vest | key / (vest + skipped) | frames/s published | "
           "key interval | key_ms | state |\n");
    printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
    double kr_min = 1e30, kr_max = 0, key_min = 1e30, ki_max = 0, fps_min = 1e30, skipped = 0, arrived = 0;
    double *kms = malloc(sizeof(double) * (size_t)(ns + 1));
    int all_keyed = 1, all_live = 1;
    for (int k = 0; k < ns; k++) {
        const sess_result_t *E = &S[k];
        printf("| v%d | %s | %.0f | %.3f | %.3f | %.0f | %.0f | %.2f | %.2f | %.0f | %.3f | %.3f | %.2f | %.0f | "
               "%.3f | %s%s |\n",
               k + 1, E->avatar, E->frames_min, E->lat_med, E->lat_p99, E->drops, E->server_drops, E->key_fps,
               E->vest_fps, E->skipped, E->key_per_vest, E->key_per_arrived, E->frame_fps, E->key_interval,
               E->key_ms, E->state, E->live ? "" : " (NOT live)");
        kr_min = E->key_fps < kr_min ? E->key_fps : kr_min;
        kr_max = E->key_fps > kr_max ? E->key_fps : kr_max;
        key_min = E->key_per_arrived < key_min ? E->key_per_arrived : key_min;
        ki_max = E->key_interval > ki_max ? E->key_interval : ki_max;
        fps_min = E->frame_fps < fps_min ? E->frame_fps : fps_min;
        skipped += E->skipped, arrived += E->vest_fps * R->window + E->skipped;
        all_keyed &= E->key_per_arrived >= 0.995;
        all_live &= E->live;
        if (kms)
            kms[k] = E->key_ms;
    }
    double key_ms_med = kms && ns ? bench_median(kms, ns) : 0;
    free(kms);
    printf("pooled (%d sessions, %d clients): latency p50 %.3f ms  p99 %.3f ms (target <= 16)  drops (bench) %.0f  "
           "server drops %.0f  key frames/s %.2f (%.2f a session)  key / vest frames %.3f  serve CPU %.1f %% of one "
           "core  vest simulators %.1f %%  bench clients %.1f %%\n",
           ns, R->n, R->lat_med, R->lat_p99, R->drops_total, R->server_drops, R->key_fps,
           ns ? R->key_fps / ns : 0.0, R->vest_fps > 0 ? R->key_fps / R->vest_fps : 0.0, R->serve_cpu, R->vest_cpu,
           R->self_cpu);
    printf("verdict N=%d: all %d sessions had a key frame for every vest frame: %s  (key / (vest + skipped) min "
           "%.3f; %.0f of %.0f vest frames skipped; key interval max %.0f)\n",
           ns, ns, all_keyed ? "yes" : "no", key_min, skipped, arrived, ki_max);
    printf("verdict N=%d: key rate across sessions (fairness): min %.2f  max %.2f Hz  (min / max %.3f)\n", ns,
           kr_min, kr_max, kr_max > 0 ? kr_min / kr_max : 0.0);
    printf("verdict N=%d: every session live: %s  (frames published min %.2f/s a session; p99 %.3f ms; drops "
           "%.0f; load average %.2f -> %.2f)\n",
           ns, all_live ? "yes" : "no", fps_min, R->lat_p99, R->drops_total, R->load_before, R->load_after);
    if (row) {
        row->load = R->load_after, row->window = R->window;
        row->key_min = key_min, row->skipped_pct = arrived > 0 ? 100.0 * skipped / arrived : 0;
        row->kr_min = kr_min, row->kr_max = kr_max, row->ki_max = ki_max, row->fps_min = fps_min;
        row->lat_med = R->lat_med, row->lat_p99 = R->lat_p99, row->drops = R->drops_total;
        row->server_drops = R->server_drops, row->serve_cpu = R->serve_cpu, row->serve_top = R->top_task_cpu;
        row->vest_cpu = R->vest_cpu, row->self_cpu = R->self_cpu, row->key_ms_med = key_ms_med;
        if (isfinite(R->capacity))
            snprintf(row->capacity_s, sizeof row->capacity_s, "%.2f", R->capacity);
        else
            snprintf(row->capacity_s, sizeof row->capacity_s, "-");
        row->all_keyed = all_keyed, row->all_live = all_live;
    }
}

/* ------------------------------------------------------------ main */

static const char usage[] =
    "usage: bench_serve [--vests N|N1,N2,...] [--clients N] [--seconds S] [--ref-seconds R]\n"
    "                   [--format f32|i16] [--threads T] [--rate HZ] [--drive auto|template|orientation]\n"
    "                   [--keep DIR]\n\n"
    "Load benchmark of mimic serve (issues 6, 16): simulated vests, WebSocket clients on\n"
    "loopback. Makes a synth store (4 x 12 bodies) in a temp dir with the real mimic\n"
    "binary ($MIMIC_BIN, else the build's), starts `mimic vest simulate` on a pty and\n"
    "`mimic serve`, then measures a 1-client reference phase and the N-client phase.\n\n"
    "  --vests N        N simulated vests, one mimic serve with N sessions (--session vK:...),\n"
    "                   --clients clients per session; N1,N2,...: a sweep, one run per N and\n"
    "                   a table at the end (default 1: one vest on --vest, plain /ws)\n"
    "  --clients N      WebSocket clients in the main phase (default 50; with --vests > 1 or a\n"
    "                   sweep: per session, default 10)\n"
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

/* The run's settings (main's options). */
static struct {
    int clients, threads;
    double seconds, ref_seconds, rate;
    const char *drive;
    char store[4200], rate_s[32], maxc[32];
} g;

static void stop_children(void)
{
    sb_stop_child(&g_serve);
    for (int k = 0; k < g_nv; k++)
        sb_stop_child(&g_vests[k]);
}

/* One run: nv vests (multi: as sessions v1..v(nv), else the single vest of
 * --vest), the warm-up, the reference and the main phase; 0 if it ran. The
 * children are stopped before it returns. */
static int run_vests(int nv, int multi, row_t *row)
{
    static char names[MAX_VESTS][16], vest_out[MAX_VESTS][4300], specs[MAX_VESTS][4400];
    char line[4096];
    int status = 1;
    g_nv = nv, g_ns = multi ? nv : 0;
    memset(g_vests, 0, sizeof g_vests);
    memset(&g_serve, 0, sizeof g_serve);
    g_serve.out = -1;
    for (int k = 0; k < nv; k++)
        g_vests[k].out = -1;
    if (multi)
        printf("\n==== %d vest%s, %d clients per session\n", nv, nv == 1 ? "" : "s", g.clients);
    for (int k = 0; k < nv; k++) {
        if (multi) {
            snprintf(names[k], sizeof names[k], "v%d", k + 1);
            snprintf(vest_out[k], sizeof vest_out[k], "pty:%s/v%d", sb_dir, k + 1);
        } else {
            snprintf(names[k], sizeof names[k], "vest");
            snprintf(vest_out[k], sizeof vest_out[k], "pty:%s/vest", sb_dir);
        }
        unlink(vest_out[k] + 4); /* a link left by the run before */
        char *a_vest[] = {"vest", "simulate", "--motion", "demo", "--rate", g.rate_s, "--loop", "--out", vest_out[k], NULL};
        if (sb_spawn(&g_vests[k], names[k], a_vest, 1) || sb_first_line(&g_vests[k], line, sizeof line, 10.0)) {
            fprintf(stderr, "bench_serve: mimic vest simulate did not print its pty:\n");
            sb_print_log_tail(&g_vests[k]);
            goto done;
        }
    }
    char serial[4400];
    snprintf(serial, sizeof serial, "serial:%.4290s", vest_out[0] + 4);
    char **a_serve = calloc((size_t)(2 * nv + 20), sizeof *a_serve);
    if (!a_serve)
        goto done;
    int na = 0;
    a_serve[na++] = "serve", a_serve[na++] = "--store", a_serve[na++] = g.store;
    if (multi) {
        for (int k = 0; k < nv; k++) {
            /* the first pose of each synth subject in turn: templates 1, 13, 25, 37 */
            snprintf(specs[k], sizeof specs[k], "v%d:vest=serial:%.4290s,avatar=%d", k + 1, vest_out[k] + 4, 1 + 12 * (k % 4));
            a_serve[na++] = "--session", a_serve[na++] = specs[k];
        }
    } else {
        a_serve[na++] = "--avatar", a_serve[na++] = "1", a_serve[na++] = "--vest", a_serve[na++] = serial;
    }
    char *rest[] = {"--vest-pose", "t", "--listen", "127.0.0.1:0", "--max-clients", g.maxc, "--drive", (char *)g.drive, NULL};
    for (int i = 0; rest[i]; i++)
        a_serve[na++] = rest[i];
    a_serve[na] = NULL;
    int spawned = sb_spawn(&g_serve, "serve", a_serve, 1);
    free(a_serve);
    if (spawned || sb_first_line(&g_serve, line, sizeof line, 30.0 + nv)) {
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
    if (multi) {
        printf("vests: %d x mimic vest simulate --motion demo --rate %s --loop --out pty:%s/vK (pids", nv, g.rate_s,
               sb_dir);
        for (int k = 0; k < nv; k++)
            printf(" %d", (int)g_vests[k].pid);
        printf(")\nserve: mimic serve --store %s", g.store);
        for (int k = 0; k < nv && k < 4; k++)
            printf(" --session %s", specs[k]);
        if (nv > 4)
            printf(" ... (%d sessions, avatars cycling 1, 13, 25, 37)", nv);
        printf(" --vest-pose t --listen 127.0.0.1:0 --max-clients %s --drive %s (pid %d, port %d)\n", g.maxc, g.drive,
               (int)g_serve.pid, sb_port);
        printf("clients: raw RFC 6455 over loopback, format %s, %d per session on /ws?session=vK (%d in all), %d "
               "epoll thread%s\n",
               g_format, g.clients, g.clients * nv, g.threads, g.threads == 1 ? "" : "s");
    } else {
        printf("vest: mimic vest simulate --motion demo --rate %s --loop --out %s (pid %d)\n", g.rate_s, vest_out[0],
               (int)g_vests[0].pid);
        printf("serve: mimic serve --store %s --avatar 1 --vest %s --vest-pose t --listen 127.0.0.1:0 --max-clients %s "
               "(pid %d, port %d)\n",
               g.store, serial, g.maxc, (int)g_serve.pid, sb_port);
        printf("clients: raw RFC 6455 over loopback, format %s, %d epoll thread%s\n", g_format, g.threads,
               g.threads == 1 ? "" : "s");
    }
    fflush(stdout);

    /* warm-up: wait until the loop publishes frames (it needs the vest
     * streaming and a first key frame; with sessions, every session's),
     * 1 client (a session) for 2 s, not counted */
    result_t warm, ref = {0}, main_r;
    double t_wait = sb_now();
    for (;;) {
        char *m = sb_http_get("/metrics");
        double f = m ? sb_metric(m, "mimic_frames_total") : -1;
        for (int k = 0; m && k < g_ns && f > 0; k++)
            if (sb_metric_session(m, "mimic_frames_total", names[k]) <= 0)
                f = 0;
        free(m);
        if (f > 0)
            break;
        if (sb_now() - t_wait > 20.0 + nv) {
            fprintf(stderr, "bench_serve: mimic serve published no frame%s in %.0f s:\n",
                    g_ns ? " in some session" : "", 20.0 + nv);
            sb_print_log_tail(&g_serve);
            goto done;
        }
        usleep(100000);
    }
    if (run_phase(g_ns ? g_ns : 1, 2.0, g_ns ? g.threads : 1, &warm, g_ns, NULL))
        goto done;
    if (g.ref_seconds > 0) {
        /* with sessions: 1 client on v1 while all of them run */
        if (run_phase(1, g.ref_seconds, 1, &ref, g_ns ? 1 : 0, NULL))
            goto done;
        print_result(g_ns ? "reference (1 client on session v1, every session running)" : "reference", &ref, g.rate);
        fflush(stdout);
    }
    int n_main = g_ns ? g.clients * g_ns : g.clients;
    sess_result_t *S = g_ns ? calloc((size_t)g_ns, sizeof *S) : NULL;
    if (g_ns && !S)
        goto done;
    if (run_phase(n_main, g.seconds, g.threads, &main_r, g_ns, S)) {
        free(S);
        goto done;
    }
    print_result("load", &main_r, g.rate);
    mimf_t frame = {.n = main_r.n_vertices, .L = main_r.n_landmarks, .i16 = !strcmp(g_format, "i16")};
    printf("frame: %u vertices, %u landmarks, %zu bytes (%s)\n", main_r.n_vertices, main_r.n_landmarks,
           mimf_size(&frame), g_format);
    if (g.ref_seconds > 0 && ref.lat_med > 0)
        printf("latency %d clients / 1 client (same run):           median %.2f  p90 %.2f  p99 %.2f\n", n_main,
               main_r.lat_med / ref.lat_med, main_r.lat_p90 / ref.lat_p90, main_r.lat_p99 / ref.lat_p99);
    if (g_ns) {
        row->vests = nv, row->clients = n_main, row->ref_p99 = ref.lat_p99;
        print_sessions(S, g_ns, &main_r, g.clients, row);
        row->ran = 1;
    } else {
        printf("targets: p99 <= 10 ms: %.3f ms; key frames per vest frame 1: %.3f; drops for clients that keep up 0: "
               "%.0f\n",
               main_r.lat_p99, main_r.vest_fps > 0 ? main_r.key_fps / main_r.vest_fps : 0.0, main_r.drops_total);
    }
    free(S);
    status = 0;

done:
    stop_children();
    fflush(stdout);
    return status;
}

/* "1,2,4": the values, each 1..MAX_VESTS; their count, or -1. */
static int parse_vests(const char *s, int *v, int cap)
{
    int n = 0;
    while (*s) {
        char *end;
        long x = strtol(s, &end, 10);
        if (end == s || x < 1 || x > MAX_VESTS || n >= cap)
            return -1;
        v[n++] = (int)x;
        s = end;
        if (*s == ',')
            s++;
        else if (*s)
            return -1;
    }
    return n ? n : -1;
}

int main(int argc, char **argv)
{
    int clients = -1, threads = 1, c, vests[32] = {1}, n_vests = 1;
    double seconds = 60, ref_seconds = 10, rate = 60;
    const char *keep = NULL, *drive = "auto";
    static const struct option lo[] = {{"clients", required_argument, 0, 'c'}, {"seconds", required_argument, 0, 's'},
                                       {"ref-seconds", required_argument, 0, 'r'}, {"format", required_argument, 0, 'f'},
                                       {"threads", required_argument, 0, 't'}, {"rate", required_argument, 0, 'R'},
                                       {"keep", required_argument, 0, 'k'},    {"help", no_argument, 0, 'h'},
                                       {"drive", required_argument, 0, 'd'},   {"vests", required_argument, 0, 'V'},
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
        else if (c == 'V') {
            if ((n_vests = parse_vests(optarg, vests, 32)) < 0)
                return fputs(usage, stderr), 2;
        }
        else if (c == 'h') return fputs(usage, stdout), 0;
        else return fputs(usage, stderr), 2;
    }
    g_serve.out = -1;
    for (int k = 0; k < MAX_VESTS; k++)
        g_vests[k].out = -1;
    int multi = n_vests > 1 || vests[0] > 1, max_vests = 0;
    for (int i = 0; i < n_vests; i++)
        max_vests = vests[i] > max_vests ? vests[i] : max_vests;
    if (clients < 0)
        clients = multi ? 10 : 50;
    if (optind < argc || clients < 1 || clients > 900 || (multi && clients * max_vests > 2000) || seconds < 1 ||
        seconds > 3600 || ref_seconds < 0 || ref_seconds > 3600 || threads < 1 || threads > 16 || rate < 1 ||
        rate > 2000 || (strcmp(g_format, "f32") && strcmp(g_format, "i16")))
        return fputs(usage, stderr), 2;
    signal(SIGPIPE, SIG_IGN);
    struct rlimit nofile; /* a socket a client */
    if (!getrlimit(RLIMIT_NOFILE, &nofile) && nofile.rlim_cur < nofile.rlim_max) {
        nofile.rlim_cur = nofile.rlim_max;
        setrlimit(RLIMIT_NOFILE, &nofile);
    }

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
    char bodies[4200];
    snprintf(bodies, sizeof bodies, "%s/bodies", sb_dir);
    snprintf(g.store, sizeof g.store, "%s/store", sb_dir);
    snprintf(g.rate_s, sizeof g.rate_s, "%g", rate);
    snprintf(g.maxc, sizeof g.maxc, "%d", clients + 4 > 64 ? clients + 4 : 64);
    g.clients = clients, g.threads = threads, g.seconds = seconds, g.ref_seconds = ref_seconds, g.rate = rate;
    g.drive = drive;

    int status = 1;
    row_t rows[32];
    memset(rows, 0, sizeof rows);
    double t_setup = sb_now();
    char *a_synth[] = {"synth", "--out", bodies, "--subjects", "4", "--poses", "12", NULL};
    char *a_ingest[] = {"ingest", "--store", g.store, bodies, NULL};
    char *a_index[] = {"index", "--store", g.store, NULL};
    if (sb_run_mimic("synth", a_synth, 60) || sb_run_mimic("ingest", a_ingest, 60) ||
        sb_run_mimic("index", a_index, 120))
        goto done;
    printf("store: 4 subjects x 12 poses (mimic synth, ingest, index) in %.1f s\n", sb_now() - t_setup);

    int ran = 0;
    for (int i = 0; i < n_vests; i++) {
        if (i)
            sleep(2); /* the last run's children are gone; let the machine settle */
        if (run_vests(vests[i], multi, &rows[i]) == 0)
            ran++;
        else if (!multi)
            goto done;
        else
            fprintf(stderr, "bench_serve: the run with %d vests did not complete\n", vests[i]);
    }
    if (multi && n_vests > 1) {
        printf("\n==== sweep: %d clients per session, %.0f s each, vests at %s Hz, format %s\n", clients, seconds,
               g.rate_s, g_format);
        printf("| vests | clients | load avg (end) | key / (vest + skipped) min | skipped %% | key rate min / max "
               "(Hz) | min / max | key interval max | key_ms median | frames/s published min | p50 ms | p99 ms | "
               "1-client ref p99 ms | drops (bench) | server drops | serve CPU %% (busiest thread) | serve CPU %% a vest | "
               "compute capacity (cores) | vest sims CPU %% "
               "| clients CPU %% | every frame keyed | all live |\n");
        printf("|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---|---|"
               "\n");
        for (int i = 0; i < n_vests; i++) {
            const row_t *r = &rows[i];
            if (!r->ran) {
                printf("| %d | - | did not complete |\n", vests[i]);
                continue;
            }
            printf("| %d | %d | %.2f | %.3f | %.2f | %.2f / %.2f | %.3f | %.0f | %.2f | %.2f | %.3f | %.3f | %.3f | "
                   "%.0f | %.0f | %.1f (%.1f) | %.2f | %s | %.1f | %.1f | %s | %s |\n",
                   r->vests, r->clients, r->load, r->key_min, r->skipped_pct, r->kr_min, r->kr_max,
                   r->kr_max > 0 ? r->kr_min / r->kr_max : 0.0, r->ki_max, r->key_ms_med, r->fps_min, r->lat_med,
                   r->lat_p99, r->ref_p99, r->drops, r->server_drops, r->serve_cpu, r->serve_top,
                   r->serve_cpu / r->vests, r->capacity_s, r->vest_cpu,
                   r->self_cpu, r->all_keyed ? "yes" : "no", r->all_live ? "yes" : "no");
        }
        int best = 0;
        for (int i = 0; i < n_vests; i++)
            if (rows[i].ran && rows[i].all_keyed && rows[i].lat_p99 <= 16.0 && rows[i].drops == 0 &&
                rows[i].vests > best)
                best = rows[i].vests;
        printf("largest N with every vest frame keyed, p99 <= 16 ms and no drops: %d%s", best, best ? "" : " (none)");
        int told = 0;
        for (int i = 0; i < n_vests; i++)
            if (rows[i].vests < best && !(rows[i].ran && rows[i].all_keyed && rows[i].lat_p99 <= 16.0 && rows[i].drops == 0))
                printf("%s%d", told++ ? ", " : "; smaller N that did not hold in this sweep: ", rows[i].vests);
        printf("\n");
    }
    status = ran ? 0 : 1;

done:
    stop_children();
    if (!keep && sb_dir[0])
        rm_rf(sb_dir);
    fflush(stdout);
    return status;
}
