/* mimic serve: the real-time service (DESIGN.md, serve/), on libwebsockets:
 *   GET  /               the web viewer (three.js, embedded at build time)
 *   GET  /ws             WebSocket avatar stream, schemas/serve-ws-frame.md
 *   GET  /api/status     schemas/serve-status.schema.json
 *   GET  /api/avatar     schemas/serve-avatar.schema.json
 *   POST /api/query      one landmark frame -> schemas/query.schema.json
 *   POST /api/transfer   schemas/serve-transfer-request.schema.json -> GLB
 *   GET  /metrics        Prometheus text, names prefixed mimic_
 * Errors are JSON, schemas/serve-error.schema.json. With a vest, a thread
 * turns each vest frame into landmarks, makes key frames (query, then
 * transfer with the cached factor, warm-started from the last key frame
 * when time is short) as often as its measured compute time allows, fills
 * the frames between by morphing (seed 000 Section 3.5) and publishes
 * every frame to the stream. serve composes db/, query/, transfer/ and vest/; cli/ sits above
 * it.
 *
 * Threads: serve starts its own, with default attributes (the host needs
 * to do nothing about them): one libwebsockets service thread that does
 * all the network I/O, the vest loop, and a small pool (threads, below)
 * for the requests that compute. What a hostile client meets (limits and
 * timeouts) is in serve/http.c and serve/ws.c. Two effects reach the whole
 * process, both libwebsockets': its log level (serve turns it off) and
 * SIGPIPE, ignored when the context is created. Each connection needs a
 * file descriptor: a host that expects many clients raises its own
 * RLIMIT_NOFILE before mim_serve_open (mimic serve does). */
#ifndef MIM_SERVE_H
#define MIM_SERVE_H

#include "mim_core.h"
#include "mim_session.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MIM_SERVE_DEFAULT_LISTEN "127.0.0.1:8080"
#define MIM_SERVE_DEFAULT_MAX_BODY ((size_t)1 << 20)

/* One frame the real-time loop publishes (what a /ws binary message holds).
 * The arrays are lent for the duration of the on_frame call only. */
typedef struct mim_serve_frame {
    uint64_t number;       /* from 1, every published frame */
    uint64_t t_vest_us;    /* the vest frame's time, as the transport gives it */
    uint64_t arrival_us;   /* CLOCK_MONOTONIC us when its last vest bytes arrived */
    uint64_t template_id;  /* of the latest key frame */
    uint32_t compute_us;   /* arrival to ready */
    uint32_t key_interval; /* vest frames per key frame when it was made */
    int key;               /* 1: a key pose itself; 0: morphed between two */
    char label[32];        /* the recognised pose class */
    uint32_t n_vertices, n_landmarks;
    const float *positions; /* 3 * n_vertices */
    const float *landmarks; /* 3 * n_landmarks, NaN where the vest lost one */
} mim_serve_frame_t;

typedef struct mim_serve_options {
    const char *listen; /* HOST:PORT (port 0: any free port); NULL: MIM_SERVE_DEFAULT_LISTEN */
    size_t max_body;    /* request body limit in bytes (413 above it); 0: MIM_SERVE_DEFAULT_MAX_BODY */
    unsigned threads;   /* threads for query, transfer and avatar requests; 0: 2 */
    const char *vest;   /* NULL: no vest; else a vest spec (mim_vest_transport_open: a recording,
                           serial:PATH, hid:..., udp:HOST:PORT), read by the real-time loop */
    int vest_pose;      /* the wearer's pose at the tare: MIM_VEST_POSE_* (0: as the avatar rests) */
    double key_rate;    /* key frames per second; 0: adaptive, a key frame at every vest frame the
                           measured compute time affords */
    /* Warm-start key frames from the previous key frame's solution (same
     * template): 0 auto (only when cold key frames do not fit the vest
     * period), 1 always, -1 never. It costs ~0.6x the time for ~13 % more
     * error (bench/warm_start.c). */
    int warm_start;
    /* What drives a key frame's frames (mim_session_drive_t): 0 auto (the
     * vest's segment orientations; the template when the avatar cannot be
     * segmented, or for UDP landmark frames without "orientations"), 1
     * template, 2 orientation (refused at open, MIM_EINVAL or the reason,
     * for an avatar that cannot be segmented; a UDP frame without
     * orientations is then a vest error). Other values: MIM_EINVAL. */
    int drive;
    /* The template drive's templates (mim_session_request_t's blend, 0:
     * MIM_SESSION_DEFAULT_BLEND) and segment correction (1: on). */
    uint32_t blend;
    int segment_correction;
    unsigned max_clients; /* WebSocket clients at once; 0: MIM_SERVE_DEFAULT_MAX_CLIENTS */
    /* Called on the loop thread for every published frame (may be NULL),
     * e.g. to record the served sequence; it must return quickly. */
    void (*on_frame)(void *user, const mim_serve_frame_t *frame);
    void *user;
    /* The vest loop's notes (the vest lost, streaming again), one line each,
     * from the loop thread; NULL: quiet. */
    mim_log_fn log;
    void *log_ctx;
} mim_serve_options_t;

#define MIM_SERVE_DEFAULT_MAX_CLIENTS 64u

typedef struct mim_serve mim_serve_t;

/* Serves session s: its store, index (without one /api/query answers 503),
 * avatar and factor (mim_session_open, then mim_session_load_avatar). The
 * session is borrowed: the caller closes it after mim_serve_close. Starts
 * the vest loop (opt->vest) and starts listening. Errors name the vest or
 * the address. */
int mim_serve_open(mim_serve_t **out, mim_session_t *s, const mim_serve_options_t *opt, mim_error_t *err);
/* The port actually bound (useful with port 0). */
int mim_serve_port(const mim_serve_t *s);
/* The vest loop's state, a static string: "streaming", "reconnecting",
 * "ended", "failed", "stopped", or "none" without a vest. */
const char *mim_serve_vest_state(mim_serve_t *s);
/* The avatar mesh as clients see it (mim_session_output_mesh: its own
 * faces and rest positions; the frames are in its vertex order), valid
 * until close, and the number of frames published so far. */
const mim_mesh_t *mim_serve_avatar_mesh(const mim_serve_t *s);
uint64_t mim_serve_frames(mim_serve_t *s);
/* Stops listening, closes every connection (a request being computed is
 * waited for, its answer dropped) and frees everything. Accepts NULL;
 * nulls the pointer. */
void mim_serve_close(mim_serve_t **s);

#ifdef __cplusplus
}
#endif
#endif
