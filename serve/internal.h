/* serve/ internals shared by server.c (libwebsockets context, service
 * thread), http.c (HTTP transactions), workers.c (the handler pool),
 * api.c (handlers), ws.c (the /ws stream), loop.c (the vest thread) and
 * metrics.c. */
#ifndef MIM_SERVE_INTERNAL_H
#define MIM_SERVE_INTERNAL_H

#include "mim_serve.h"
#include "mim_session.h"
#include "mim_vest.h"

#include <jansson.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

struct lws;
struct lws_context;

/* ---- metrics.c ---- */
typedef enum mim__counter {
    MIM__C_QUERIES,     /* answered landmark queries */
    MIM__C_TRANSFERS,   /* answered transfers */
    MIM__C_VEST_FRAMES, /* vest frames turned into landmarks */
    MIM__C_SKIPPED,     /* vest frames skipped: the loop was behind and took a newer one */
    MIM__C_FRAMES,      /* frames published (the real-time loop) */
    MIM__C_KEY_FRAMES,  /* key frames made (query + transfer) */
    MIM__C_MORPH_FRAMES, /* frames morphed between two key frames */
    MIM__C_INCOMPLETE,  /* vest frames with lost landmarks */
    MIM__C_COMPLETED,   /* lost landmarks filled in by retrieval (mim_session_complete) */
    MIM__C_DROPS,       /* frames dropped for slow clients */
    MIM__C_VEST_ERRORS, /* vest read or decode errors */
    MIM__C_VEST_DISCONNECTS, /* times the vest went away */
    MIM__C_VEST_RECONNECTS,  /* times it came back */
    MIM__C_WS_JOINED,   /* WebSocket clients that joined */
    MIM__C_WS_LEFT,     /* and left */
    MIM__C_WS_SENT,     /* binary frames sent */
    MIM__C_WS_MESSAGES, /* client messages received */
    MIM__C_WS_BAD,      /* of which malformed */
    MIM__C_WS_EVICTED,  /* clients closed for not reading (ws.c) */
    MIM__C_COUNT
} mim__counter_t;

typedef enum mim__route {
    MIM__R_STATUS, MIM__R_AVATAR, MIM__R_QUERY, MIM__R_TRANSFER, MIM__R_METRICS, MIM__R_SESSIONS, MIM__R_VIEWER,
    MIM__R_OTHER,
    MIM__R_COUNT
} mim__route_t;

typedef enum mim__hist {
    MIM__H_QUERY, MIM__H_TRANSFER, MIM__H_KEY_FRAME, MIM__H_MORPH_FRAME, MIM__H_FRAME, MIM__H_COUNT
} mim__hist_t;

typedef enum mim__gauge {
    MIM__G_KEY_INTERVAL, MIM__G_KEY_RATE, MIM__G_FRAME_RATE, MIM__G_VEST_UP, MIM__G_WS_CLIENTS, MIM__G_COUNT
} mim__gauge_t;

#define MIM__BUCKETS 14
typedef struct mim__histogram {
    uint64_t counts[MIM__BUCKETS + 1]; /* the last is +Inf */
    uint64_t n;
    double sum;
} mim__histogram_t;

#define MIM__STATUSES 8 /* 200 400 404 405 413 500 503 other */
typedef struct mim__metrics {
    pthread_mutex_t lock;
    uint64_t counters[MIM__C_COUNT];
    uint64_t requests[MIM__R_COUNT][MIM__STATUSES];
    mim__histogram_t request_seconds[MIM__R_COUNT];
    mim__histogram_t hist[MIM__H_COUNT];
    double gauges[MIM__G_COUNT];
} mim__metrics_t;

void mim__metrics_init(mim__metrics_t *m);
void mim__metrics_destroy(mim__metrics_t *m);
void mim__metrics_add(mim__metrics_t *m, mim__counter_t c, uint64_t n);
uint64_t mim__metrics_get(mim__metrics_t *m, mim__counter_t c);
void mim__metrics_observe(mim__metrics_t *m, mim__hist_t h, double seconds);
void mim__metrics_set(mim__metrics_t *m, mim__gauge_t g, double v);
void mim__metrics_request(mim__metrics_t *m, mim__route_t r, int status, double seconds);
/* Prometheus text exposition format 0.0.4 (malloc'd; NULL when out of
 * memory): the service's own m, and each session's, labelled
 * session="names[i]"; a family's unlabelled sample is the process's total
 * (the largest key interval for that gauge). */
char *mim__metrics_text(mim__metrics_t *m, mim__metrics_t *const *sessions, const char *const *names, size_t n);

/* ---- a request and its reply, as the handlers see them ---- */
typedef struct mim__request {
    const char *path;   /* the decoded path, without the query */
    const char *body;   /* NUL-terminated (not counted in len); NULL for GET */
    size_t len;
    int head;           /* a HEAD request: the reply's headers only */
    int k_given;        /* ?k= : 0 absent, 1 given (in k), -1 too long to be a number */
    char k[32];
    int session_given;  /* ?session= : 0 absent, 1 given (in session), -1 too long to be a name */
    char session[MIM_SERVE_SESSION_NAME_MAX + 1];
    char name[MIM_SERVE_SESSION_NAME_MAX + 2]; /* /api/sessions/NAME: NAME, or "" (one byte more: too long shows) */
    int json;           /* Content-Type: application/json */
} mim__request_t;

/* Built by a handler on any thread, sent by the service thread. */
typedef struct mim__reply {
    int status;
    const char *type;              /* a string literal */
    unsigned char *body;           /* malloc'd, owned; or NULL with */
    const unsigned char *fixed;    /* bytes that live as long as the program (viewer assets) */
    size_t len;
    char headers[1024];            /* extra header lines, each "Name: value\r\n" */
    const char *cache;             /* Cache-Control value; NULL: no-store */
} mim__reply_t;

/* Each returns the status. A reply that cannot be built becomes a 500 with
 * a fixed body; error messages are made one line of valid UTF-8 (bytes of
 * a request path that are not, or are control characters, show as '?'). */
int mim__reply_take(mim__reply_t *r, int status, const char *type, void *body_malloced, size_t len);
int mim__reply_json(mim__reply_t *r, int status, json_t *j); /* steals j */
int mim__reply_error(mim__reply_t *r, int status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
void mim__reply_free(mim__reply_t *r);
/* Copies s into out (size n) as printable ASCII and valid UTF-8 only,
 * everything else as '?'. */
void mim__printable(const char *s, size_t len, char *out, size_t n);

/* ---- api.c: handlers (body is NUL-terminated; NULL for GET) ---- */
typedef int (*mim__handler_t)(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_status(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_avatar(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_avatar_glb(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_query(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_transfer(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_metrics(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
/* sessions (schemas/serve-session.schema.json): GET and POST /api/sessions,
 * GET and DELETE /api/sessions/NAME */
int mim__api_sessions(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_session_add(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_session(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);
int mim__api_session_remove(mim_serve_t *sv, const mim__request_t *rq, mim__reply_t *rp);

/* ---- viewer.c ---- */
/* The embedded file at path ("/", "/viewer.js", ...) for GET or HEAD: 200,
 * or 0 (nothing set) when path is none of them. */
int mim__viewer_reply(const char *path, mim__reply_t *rp);

/* ---- workers.c: the handler pool ---- */
/* Handlers that take milliseconds (query, transfer, the avatar's JSON) run
 * on these threads, so that the service thread never stalls the stream. A
 * job is owned by the pool from submit until the service thread takes it
 * back from mim__workers_done. */
typedef struct mim__job {
    mim__handler_t fn;
    mim__request_t rq;
    char *body;             /* malloc'd, the request's (rq.body points here) */
    char path[256];         /* the request's, printable (rq.path points here) */
    mim__reply_t rp;
    int status;
    struct lws *wsi;        /* the connection waiting for it (service thread only) */
    int orphaned;           /* the connection closed first (service thread only) */
    struct mim__job *next;
} mim__job_t;
typedef struct mim__workers mim__workers_t;
int mim__workers_open(mim__workers_t **out, mim_serve_t *sv, unsigned threads, mim_error_t *err);
/* The context whose service thread a finished job wakes (NULL: none, before
 * it is destroyed). */
void mim__workers_attach(mim__workers_t *w, struct lws_context *ctx);
/* 0, or -1 when the pool's queue is full (the caller answers 503). */
int mim__workers_submit(mim__workers_t *w, mim__job_t *job);
/* Jobs waiting or running now (for the queue bound and status). */
unsigned mim__workers_pending(mim__workers_t *w);
/* The finished jobs, oldest first, handed over; NULL when none. */
mim__job_t *mim__workers_done(mim__workers_t *w);
/* A job not yet started is taken back (1: the caller frees it); a running
 * one is left to finish (0). */
int mim__workers_cancel(mim__workers_t *w, mim__job_t *job);
/* After the context is destroyed: joins, frees the jobs left; accepts NULL. */
void mim__workers_close(mim__workers_t **w);
void mim__job_free(mim__job_t *job);

/* ---- http.c: HTTP transactions on the service thread ---- */
/* The lws protocol callback's HTTP reasons; returns what lws expects. */
int mim__http_callback(mim_serve_t *sv, struct lws *wsi, int reason, void *user, void *in, size_t len);
/* A finished job back on the service thread: its reply goes out. */
void mim__http_job_done(mim_serve_t *sv, mim__job_t *job);
/* A JSON error written at once (a refused WebSocket upgrade). 0 or -1. */
int mim__http_answer_now(mim_serve_t *sv, struct lws *wsi, int status, const char *why);
/* The value of URL argument name as lws decoded it: 1 (value in out), 0
 * absent, -1 longer than out holds. */
int mim__url_arg(struct lws *wsi, const char *name, char *out, size_t n);

/* ---- ws.c: the WebSocket avatar stream ---- */
typedef struct mim__ws mim__ws_t;
typedef struct mim__vs mim__vs_t; /* a session (sessions.c, below) */
int mim__ws_open(mim__ws_t **out, mim_serve_t *sv, unsigned max_clients, mim_error_t *err);
/* From now on publish wakes the service thread of ctx (NULL: stop). */
void mim__ws_attach(mim__ws_t *ws, struct lws_context *ctx);
/* Queues f for every client of session vs (each client's oldest frame is
 * dropped when its queue is full) and wakes the service thread; returns at
 * once whatever the clients do. Any thread (the vest loop's). */
void mim__ws_publish(mim__ws_t *ws, mim__vs_t *vs, const mim_serve_frame_t *f);
/* The upgrade of GET /ws[?session=NAME], on the service thread: 0 accepts
 * it; else the HTTP status to refuse it with and its reason in why. */
int mim__ws_confirm(mim__ws_t *ws, struct lws *wsi, char *why, size_t why_size);
/* Session vs is gone: its clients are closed (1001, "session removed")
 * from the service thread. Any thread. */
void mim__ws_drop_session(mim__ws_t *ws, mim__vs_t *vs);
/* The lws protocol callback's WebSocket reasons; returns what lws expects. */
int mim__ws_callback(mim__ws_t *ws, struct lws *wsi, int reason, void *user, void *in, size_t len);
/* On the service thread after a wake-up: asks for a writable callback for
 * every client with something queued. */
void mim__ws_service(mim__ws_t *ws);
void mim__ws_close(mim__ws_t **ws); /* after the context is destroyed; accepts NULL */
/* Session vs's stream (NULL: every session's together). */
json_t *mim__ws_status(mim__ws_t *ws, const mim__vs_t *vs);
unsigned mim__ws_clients(mim__ws_t *ws, const mim__vs_t *vs);
/* A client's text message (untrusted): the format it asks for (0 f32, 1
 * i16), or -1 with the reason, one line, in why. */
int mim__ws_parse_message(const char *data, size_t len, char *why, size_t why_size);
#define MIM__WS_MESSAGE_MAX 4096u /* bytes of one client message, fragments joined */

/* ---- loop.c: the vest thread ---- */
typedef struct mim__loop mim__loop_t;
/* Calibrates session vs's avatar rig for a wearer tared in pose
 * (MIM_VEST_POSE_*), opens its vest (opt->vest, a mim_vest_transport_open
 * spec) and starts the thread, which publishes to vs's stream. */
int mim__loop_open(mim__loop_t **out, mim__vs_t *vs, const mim_serve_options_t *opt, mim_error_t *err);
const char *mim__loop_state(mim__loop_t *l);
void mim__loop_close(mim__loop_t **l); /* stops and joins; accepts NULL */
json_t *mim__loop_status(mim__loop_t *l); /* null without a vest */

/* ---- gate.c: the compute slots the sessions' loops share ---- */
/* At most `slots` key frames or morphs compute at once, and a loop that
 * waits gets the next free slot in the order it came (a queue), so no
 * loop overtakes another forever. How often each loop computes a key
 * frame is fair.c's. */
typedef struct mim__gate_waiter {
    struct mim__gate_waiter *next;
    pthread_cond_t turn; /* signalled when granted */
    int granted;         /* the slot is its own */
} mim__gate_waiter_t;
typedef struct mim__gate {
    pthread_mutex_t lock;
    unsigned slots, busy;
    mim__gate_waiter_t *head, *tail; /* the loops waiting, first come first (on their stacks) */
} mim__gate_t;
void mim__gate_init(mim__gate_t *g, unsigned slots);
void mim__gate_destroy(mim__gate_t *g);
void mim__gate_enter(mim__gate_t *g);
void mim__gate_leave(mim__gate_t *g);

/* ---- fair.c: the common key interval of the sessions (fair.c says why) ---- */
#define MIM__FAIR_K_MAX 30u    /* as loop.c: never fewer key frames than one every 30 vest frames */
#define MIM__FAIR_BUDGET 0.8   /* as loop.c: the fraction of a vest period one session's compute may take */
/* A session's costs, CPU seconds (0 or NaN: not measured yet). */
typedef struct mim__fair_demand {
    double key_cold, key_warm; /* a key frame, cold and warm-started */
    double morph, linear;      /* a frames morph, a linear one */
    double period;             /* its vest's period, seconds (0: 1/60) */
    uint32_t fixed_k;          /* a fixed key rate's interval (--key-rate); 0: auto */
    int warm_ok;               /* its warm start is auto (the rule may turn it on) */
} mim__fair_demand_t;
typedef struct mim__fair_choice {
    uint32_t k;  /* the common key interval, 1..MIM__FAIR_K_MAX */
    int warm;    /* warm-start key frames (where a session's warm start is auto) */
    int linear;  /* linear morphs */
} mim__fair_choice_t;
/* The rule alone: the smallest common k for the auto sessions of d[0..n)
 * whose total CPU demand fits capacity (cores), after the fixed-rate
 * sessions' demand; cold key frames only at k = 1, then warm ones with
 * frames morphs, then linear morphs; {1, 0, 0} when nothing is measured
 * or no session is auto; {K_MAX, 1, 1} when nothing fits. */
mim__fair_choice_t mim__fair_choose(const mim__fair_demand_t *d, size_t n, double capacity);
/* What the process and its cores did so far (cpu.c reads it), at wall. */
typedef struct mim__fair_sample {
    double wall;    /* mim_now(), seconds */
    double process; /* the process's CPU time, seconds (NaN: unknown) */
    double idle;    /* idle seconds of the cores it may run on, summed (NaN: unknown) */
} mim__fair_sample_t;
typedef void (*mim__fair_sampler_t)(void *user, mim__fair_sample_t *s);
typedef struct mim__fair {
    pthread_mutex_t lock;
    mim__fair_demand_t *d, *packed; /* per entry (an id), and the used ones packed */
    unsigned char *used;
    unsigned char *active;         /* per entry: sending frames (counted), from its first until idle */
    size_t n;
    double cores;                  /* the cores the process may run on */
    double capacity_max, capacity; /* cores for compute: at most (given, else the cores; no more than the slots), now */
    double slots;                  /* the gate's */
    double got;                    /* the compute's CPU per second plus idle cores (smoothed; <0: not measured yet) */
    double share;                  /* of a core a slot holder runs: its CPU over wall time (smoothed; <0: not yet) */
    double made;                   /* of the vest frames, those the loops made (smoothed; <0: not yet) */
    double rest;                   /* cores the process uses but for the compute (smoothed; <0: not measured yet) */
    mim__fair_sampler_t sample;    /* reads the process's CPU time and its cores' idle time (NULL: none) */
    void *sample_user;
    mim__fair_sample_t s0;         /* at the window's start */
    double window_start, w_cpu, w_wall; /* the window: its start, the compute's CPU and wall seconds in slots, */
    double w_made, w_vest;              /* frames made, and vest frames (made or skipped) */
    mim__fair_choice_t choice;
} mim__fair_t;
/* cores: the process's (cpu.c); slots: the gate's; given: --compute-cores
 * (0: none, the capacity is at most the cores). sample is called once a
 * window (may be NULL: the capacity stays at its most). */
void mim__fair_init(mim__fair_t *f, unsigned cores, unsigned slots, double given, mim__fair_sampler_t sample,
                    void *sample_user);
void mim__fair_destroy(mim__fair_t *f);
/* A loop's entry (-1 when out of memory: the loop keeps its own k). */
int mim__fair_join(mim__fair_t *f);
void mim__fair_leave(mim__fair_t *f, int id); /* accepts -1 */
/* Its vest is away, ended or failed: not counted until its next frame
 * (accepts -1). */
void mim__fair_idle(mim__fair_t *f, int id);
/* A loop's published frame: its costs now (d), the CPU and wall seconds
 * its compute (key frame or morph) took in a compute slot, and the vest
 * frames it skipped since its previous one, at now (mim_now()); returns
 * the common choice. */
mim__fair_choice_t mim__fair_frame(mim__fair_t *f, int id, const mim__fair_demand_t *d, double cpu, double wall,
                                   uint32_t skipped, double now);
void mim__fair_state(mim__fair_t *f, mim__fair_choice_t *choice, double *capacity);

/* ---- cpu.c: the cores the service may run on, the CPU it used, their idle time ---- */
#define MIM__CPU_MAX 1024
typedef struct mim__cpu {
    unsigned cores;                   /* in the process's affinity mask (else online) */
    double tick;                      /* seconds a /proc/stat tick */
    unsigned char mine[MIM__CPU_MAX]; /* which CPUs those are */
} mim__cpu_t;
void mim__cpu_init(mim__cpu_t *c);
/* Idle and iowait ticks of the CPUs marked in mine, summed over the
 * "cpuN ..." lines of /proc/stat text (NaN: no such line). */
double mim__cpu_idle_ticks(const char *stat, const unsigned char *mine);
void mim__cpu_sample(void *user, mim__fair_sample_t *s); /* a mim__fair_sampler_t; user: a mim__cpu_t */

/* ---- sessions.c: the vests a service drives, one avatar each (issue 16) ---- */
struct mim__vs {
    char name[MIM_SERVE_SESSION_NAME_MAX + 1];
    mim_serve_t *sv;
    mim_session_t *s;          /* its pipeline: a fork of the service's session (owned), or that session */
    int owned;
    mim_serve_session_spec_t spec;
    const mim_mesh_t *mesh;    /* the avatar at rest, the store's faces (a foreign avatar's proxy) */
    const mim_mesh_t *out_mesh; /* the avatar as given, what its clients see */
    const mim_landmark_map_t *map;
    double t_start;
    mim__metrics_t m;          /* its own counters, labelled session="NAME" in /metrics */
    pthread_mutex_t lock;      /* guards loop against removal while status reads it */
    mim__loop_t *loop;         /* NULL without a vest, and once removed */
    unsigned refs;             /* under sv->sessions_lock: the list's, each lookup's, each stream client's */
    int removed;               /* under sv->sessions_lock: invisible to lookups, freed at its last reference */
    struct mim__vs *next;
};
/* Session name (NULL or "": the default one, the first of the list) with
 * a reference the caller releases; NULL when there is no such live one. */
mim__vs_t *mim__sessions_get(mim_serve_t *sv, const char *name);
void mim__vs_release(mim__vs_t *vs);
int mim__vs_removed(mim__vs_t *vs); /* 1 once mim_serve_session_remove has taken it off */
/* The live sessions, in the order they were added, each with a reference
 * (mim__sessions_release_all); *n 0 and NULL when none or out of memory. */
mim__vs_t **mim__sessions_all(mim_serve_t *sv, size_t *n);
void mim__sessions_release_all(mim__vs_t **v, size_t n);
/* A session's part of /api/status and /api/sessions (schemas/serve-status.schema.json). */
json_t *mim__vs_status(mim__vs_t *vs);
/* At close: every session's loop stopped (before the context goes), then
 * every session freed (after it, when no client holds one). */
/* The session MIM_SERVE_DEFAULT_SESSION of the service's own session (its
 * avatar), with opt's vest and key rate. */
int mim__sessions_open_default(mim_serve_t *sv, const mim_serve_options_t *opt, mim_error_t *err);
void mim__sessions_stop_all(mim_serve_t *sv);
void mim__sessions_free_all(mim_serve_t *sv);
/* Checks a session name: 1..MIM_SERVE_SESSION_NAME_MAX of [A-Za-z0-9_.-]. */
int mim__session_name_ok(const char *name);

/* ---- the per-connection data lws keeps for us (protocol user space) ---- */
typedef struct mim__conn {
    struct mim__http_tx *tx;       /* http.c: the HTTP transaction under way */
    struct mim__ws_client *client; /* ws.c: once the upgrade is done */
} mim__conn_t;

/* ---- the service ---- */
struct mim_serve {
    mim_session_t *s;           /* store and index (and the default session's avatar): borrowed */
    mim_serve_options_t opt;    /* what every session's loop runs with, but its vest and key rate */
    const mim_landmark_map_t *map;
    const mim_query_t *q;       /* NULL when the store has no index */
    const char *store;          /* the store's path */
    double t_start;
    size_t max_body;
    size_t body_bytes;          /* request bodies held now (service thread) */
    struct lws_context *ctx;
    struct lws_vhost *vhost;
    pthread_t service;          /* the lws service thread */
    int service_started;
    atomic_int stop;
    int port;
    mim__workers_t *workers;
    pthread_mutex_t sessions_lock;
    mim__vs_t *sessions;        /* live and removed ones still referenced, in the order added */
    mim__cpu_t cpu;             /* the cores it may run on */
    mim__gate_t gate;
    mim__fair_t fair;           /* the sessions' common key interval */
    /* The index readied on a thread of its own at start (server.c): a
     * store's index is used in place and each class is checked and its
     * kd-forest loaded when a query first needs it (index/blob.c), about
     * 0.1 s a class at 1 000 000 templates; done here, a vest's first key
     * frame in a pose does not pay for it. */
    pthread_t warm;
    int warm_started;
    atomic_int index_ready;     /* 0 readying, 1 ready, -1 a part is damaged (index_error) */
    char index_error[256];
    mim__ws_t *ws;              /* the /ws streams, every session's */
    mim__metrics_t m;           /* the service's own (HTTP requests, the API's queries and transfers) */
};

#endif
