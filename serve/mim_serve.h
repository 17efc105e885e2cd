/* mimic serve: the real-time service (DESIGN.md, serve/), on libwebsockets:
 *   GET  /               the web viewer (three.js, embedded at build time)
 *   GET  /ws             WebSocket avatar stream, schemas/serve-ws-frame.md
 *   GET  /api/status     schemas/serve-status.schema.json
 *   GET  /api/avatar     schemas/serve-avatar.schema.json
 *   POST /api/query      one landmark frame -> schemas/query.schema.json
 *   POST /api/transfer   schemas/serve-transfer-request.schema.json -> GLB
 *   GET  /api/sessions   {"sessions": [schemas/serve-session.schema.json]}
 *   POST /api/sessions   schemas/serve-session-request.schema.json -> 201
 *   GET, DELETE /api/sessions/NAME   one session; remove it
 *   GET  /metrics        Prometheus text, names prefixed mimic_
 * /ws, /api/avatar and /api/transfer take ?session=NAME (absent: the first
 * session).
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
/* A request's headers: up to MIM_SERVE_MAX_HEADER_BYTES of values are
 * taken; more, up to MIM_SERVE_HEADER_BUFFER, is answered 431 (Request
 * Header Fields Too Large) and closed; past the buffer libwebsockets
 * closes the connection without an answer. Headers libwebsockets does not
 * know are read and dropped, and count for neither. */
#define MIM_SERVE_MAX_HEADER_BYTES 8192
#define MIM_SERVE_HEADER_BUFFER 32768

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
    const char *session;   /* the session whose vest this is (mim_serve_session_spec_t's name) */
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
     * MIM_SESSION_DEFAULT_BLEND) and segment correction (mim_session_request_t's:
     * 1 on, -1 off, 0 the default). */
    uint32_t blend;
    int segment_correction;
    /* The template drive's relative transfer (mim_session_request_t's
     * relative): 0 default (on), 1 on, -1 off; other values: MIM_EINVAL
     * when the vest loop opens. */
    int relative;
    unsigned max_clients; /* WebSocket clients of one session at once; 0: MIM_SERVE_DEFAULT_MAX_CLIENTS */
    /* Key frames and morphs computed at once, over all sessions (gate.c);
     * 0: the cores the process may run on (its CPU affinity mask). */
    unsigned compute_slots;
    /* Cores of CPU the key frames and morphs of every session may take
     * together, at most: the sessions' common key interval is chosen to
     * fit what the compute can take as measured (serve/fair.c), and never
     * more than this; 0: the cores the process may run on. Less: every
     * session's key rate drops sooner, alike. */
    double compute_cores;
    /* Called on the loop thread for every published frame of every
     * session (frame->session says whose; may be NULL), e.g. to record the
     * served sequence; it must return quickly, and be thread-safe with
     * more than one session. */
    void (*on_frame)(void *user, const mim_serve_frame_t *frame);
    void *user;
    /* Called (with user) after a removed session's memory was freed, on
     * whichever thread let go of it last: where the program may give the
     * freed memory back to the system (mimic serve: malloc_trim), which a
     * library must not decide for the process. NULL: nothing. */
    void (*on_session_freed)(void *user);
    /* The vest loop's notes (the vest lost, streaming again), one line each,
     * from the loop thread; NULL: quiet. */
    mim_log_fn log;
    void *log_ctx;
} mim_serve_options_t;

#define MIM_SERVE_DEFAULT_MAX_CLIENTS 64u
/* A WebSocket client that has had frames dropped, with none written to
 * it since, for MIM_SERVE_STALL_CLOSE_S is closed; stalled for
 * MIM_SERVE_STALL_YIELD_S, it gives its place to a new viewer of its
 * session when every place is taken (the one stalled longest first). A
 * client that reads, however slowly, has a frame written at least every
 * few frames and is never stalled that long. */
#define MIM_SERVE_STALL_CLOSE_S 10.0
#define MIM_SERVE_STALL_YIELD_S 1.0

typedef struct mim_serve mim_serve_t;

/* ---- sessions (issue 16): many vests, each with its own avatar ----
 * A service drives any number of sessions, each a vest, an avatar on the
 * service's store (mim_session_fork: the store, index and connectivity
 * are shared, the avatar and its factor are the session's), a vest loop
 * and a stream at /ws?session=NAME. The session given to mim_serve_open,
 * when it has an avatar, is the one named MIM_SERVE_DEFAULT_SESSION with
 * opt->vest and opt->key_rate; /ws and the other routes without
 * ?session= mean the first session. */
#define MIM_SERVE_SESSION_NAME_MAX 32
/* What a session name may be (issue 30: "." and ".." were taken, and a
 * path normalised before routing could then never name them again). */
#define MIM_SERVE_SESSION_NAME_RULE "1 to 32 of A-Z a-z 0-9 _ . -, the first a letter or a digit"
#define MIM_SERVE_DEFAULT_SESSION "default"
#define MIM_SERVE_MAX_SESSIONS 256 /* live at once: each holds an avatar, its factor and a vest thread */
typedef struct mim_serve_session_spec {
    char name[MIM_SERVE_SESSION_NAME_MAX + 1]; /* MIM_SERVE_SESSION_NAME_RULE */
    char avatar[4096];    /* a mesh file, or a template id */
    char vest[1024];      /* a vest spec (mim_serve_options_t's vest); "": none */
    double key_rate;      /* key frames per second; 0: the service's (opt->key_rate) */
} mim_serve_session_spec_t;
/* "NAME:vest=SPEC,avatar=MESH|ID[,key-rate=R]" (the order of the fields is
 * free; a value ends at the next comma) into *out. MIM_EINVAL with the
 * reason, one line quoting the text. */
int mim_serve_session_spec_parse(const char *text, mim_serve_session_spec_t *out, mim_error_t *err);
/* {"name", "avatar", "vest", "key_rate"} (schemas/serve-session.schema.json,
 * the request of POST /api/sessions; a member of --sessions FILE's
 * "sessions") into *out; where (e.g. "request body") starts the message.
 * MIM_EFORMAT with the reason. */
int mim_serve_session_spec_json(const json_t *j, const char *where, mim_serve_session_spec_t *out, mim_error_t *err);

/* Serves session s: its store, index (without one /api/query answers 503),
 * and, when it has one (mim_session_load_avatar), its avatar and factor as
 * the session MIM_SERVE_DEFAULT_SESSION with the vest loop of opt->vest.
 * Without an avatar the service starts with no session (add them with
 * mim_serve_session_add; opt->vest is then refused, MIM_EINVAL). s is
 * borrowed: the caller closes it after mim_serve_close. Starts listening.
 * Errors name the vest or the address. */
int mim_serve_open(mim_serve_t **out, mim_session_t *s, const mim_serve_options_t *opt, mim_error_t *err);
/* Adds session spec while the service runs: a fork of the service's
 * session, the avatar loaded and factorised (seconds for a large one), its
 * vest loop started. Errors, one line: MIM_EINVAL for a bad name, -EEXIST
 * for a name taken, -ENOSPC past MIM_SERVE_MAX_SESSIONS, the avatar's
 * (mim_session_load_avatar), the vest's. Thread-safe. */
int mim_serve_session_add(mim_serve_t *sv, const mim_serve_session_spec_t *spec, mim_error_t *err);
/* Removes session name: its loop stops, its clients' streams close (1001);
 * a request computing on it finishes first. MIM_ENOTFOUND when there is no
 * such session. Thread-safe. */
int mim_serve_session_remove(mim_serve_t *sv, const char *name, mim_error_t *err);
/* The port actually bound (useful with port 0). */
int mim_serve_port(const mim_serve_t *s);
/* The first session's vest loop's state, a static string: "streaming",
 * "reconnecting", "ended", "failed", "stopped", or "none" without a vest
 * (or a session). */
const char *mim_serve_vest_state(mim_serve_t *s);
/* The first session's avatar mesh as clients see it
 * (mim_session_output_mesh: its own faces and rest positions; the frames
 * are in its vertex order), valid until close (NULL without a session),
 * and the number of frames published so far, every session's. */
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
