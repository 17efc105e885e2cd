/* serve/ internals shared by server.c (civetweb, routing), api.c
 * (handlers) and metrics.c. */
#ifndef MIM_SERVE_INTERNAL_H
#define MIM_SERVE_INTERNAL_H

#include "mim_serve.h"
#include "mim_session.h"
#include "mim_vest.h"

#include <jansson.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

struct mg_connection;
struct mg_context;

/* ---- metrics.c ---- */
typedef enum mim__counter {
    MIM__C_QUERIES,     /* answered landmark queries */
    MIM__C_TRANSFERS,   /* answered transfers */
    MIM__C_VEST_FRAMES, /* vest frames turned into landmarks */
    MIM__C_SKIPPED,     /* vest frames skipped: the loop was behind and took a newer one */
    MIM__C_FRAMES,      /* frames published (the real-time loop) */
    MIM__C_KEY_FRAMES,  /* key frames made (query + transfer) */
    MIM__C_MORPH_FRAMES, /* frames morphed between two key frames */
    MIM__C_INCOMPLETE,  /* vest frames with lost landmarks (held at their last position) */
    MIM__C_DROPS,       /* frames dropped for slow clients */
    MIM__C_VEST_ERRORS, /* vest read or decode errors */
    MIM__C_VEST_DISCONNECTS, /* times the vest went away */
    MIM__C_VEST_RECONNECTS,  /* times it came back */
    MIM__C_WS_JOINED,   /* WebSocket clients that joined */
    MIM__C_WS_LEFT,     /* and left */
    MIM__C_WS_SENT,     /* binary frames sent */
    MIM__C_WS_MESSAGES, /* client messages received */
    MIM__C_WS_BAD,      /* of which malformed */
    MIM__C_COUNT
} mim__counter_t;

typedef enum mim__route {
    MIM__R_STATUS, MIM__R_AVATAR, MIM__R_QUERY, MIM__R_TRANSFER, MIM__R_METRICS, MIM__R_VIEWER, MIM__R_OTHER,
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
/* Prometheus text exposition format 0.0.4 (malloc'd; NULL when out of memory). */
char *mim__metrics_text(mim__metrics_t *m);

/* ---- ws.c: the WebSocket avatar stream ---- */
typedef struct mim__ws mim__ws_t;
int mim__ws_open(mim__ws_t **out, mim_serve_t *sv, unsigned max_clients, mim_error_t *err);
void mim__ws_attach(mim__ws_t *ws, struct mg_context *ctx); /* registers /ws */
/* Queues f for every client (each client's oldest frame is dropped when its
 * queue is full); returns at once whatever the clients do. */
void mim__ws_publish(mim__ws_t *ws, const mim_serve_frame_t *f);
void mim__ws_close(mim__ws_t **ws); /* after civetweb has stopped; accepts NULL */
json_t *mim__ws_status(mim__ws_t *ws);
unsigned mim__ws_clients(mim__ws_t *ws);
/* A client's text message (untrusted): the format it asks for (0 f32, 1
 * i16), or -1 with the reason, one line, in why. */
int mim__ws_parse_message(const char *data, size_t len, char *why, size_t why_size);

/* ---- loop.c: the vest thread ---- */
typedef struct mim__loop mim__loop_t;
/* Calibrates the avatar's rig for a wearer tared in pose (MIM_VEST_POSE_*),
 * opens the vest (a mim_vest_transport_open spec) and starts the thread. */
int mim__loop_open(mim__loop_t **out, mim_serve_t *sv, const mim_serve_options_t *opt, mim_error_t *err);
const char *mim__loop_state(mim__loop_t *l);
void mim__loop_close(mim__loop_t **l); /* stops and joins; accepts NULL */
json_t *mim__loop_status(mim__loop_t *l); /* null without a vest */

/* ---- the service ---- */
struct mim_serve {
    mim_session_t *s;           /* store, index, avatar, factor: the transfer pipeline (borrowed) */
    /* what the session holds, read-only, for the handlers */
    const mim_mesh_t *mesh;     /* the avatar at rest, the store's faces */
    const mim_landmark_map_t *map;
    const mim_query_t *q;       /* NULL when the store has no index */
    const char *store;          /* the store's path */
    double t_start;
    size_t max_body;
    struct mg_context *ctx;
    int port;
    mim__loop_t *loop;          /* NULL without --vest */
    mim__ws_t *ws;              /* the /ws stream */
    mim__metrics_t m;
};

/* ---- server.c: replies (each returns the status sent) ---- */
int mim__reply(struct mg_connection *c, int status, const char *type, const void *body, size_t len,
               const char *extra_headers);
int mim__reply_json(struct mg_connection *c, int status, json_t *j); /* steals j */
int mim__reply_error(struct mg_connection *c, int status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* ---- api.c: handlers (body is NUL-terminated; NULL for GET) ---- */
int mim__api_status(mim_serve_t *sv, struct mg_connection *c, const char *body, size_t len);
int mim__api_avatar(mim_serve_t *sv, struct mg_connection *c, const char *body, size_t len);
int mim__api_query(mim_serve_t *sv, struct mg_connection *c, const char *body, size_t len);
int mim__api_transfer(mim_serve_t *sv, struct mg_connection *c, const char *body, size_t len);
int mim__api_metrics(mim_serve_t *sv, struct mg_connection *c, const char *body, size_t len);

#endif
