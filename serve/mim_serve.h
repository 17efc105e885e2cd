/* mimic serve: the real-time service (DESIGN.md, serve/). This part is the
 * HTTP JSON API over a store and an avatar, on civetweb:
 *   GET  /api/status     schemas/serve-status.schema.json
 *   GET  /api/avatar     schemas/serve-avatar.schema.json
 *   POST /api/query      one landmark frame -> schemas/query.schema.json
 *   POST /api/transfer   schemas/serve-transfer-request.schema.json -> GLB
 *   GET  /metrics        Prometheus text, names prefixed mimic_
 * Errors are JSON, schemas/serve-error.schema.json. With a vest, a thread
 * turns each vest frame into landmarks and each complete one into a key
 * frame (query, then transfer); the WebSocket stream, morphing between key
 * frames and the adaptive key rate are still to come. serve composes db/,
 * query/, transfer/ and vest/; cli/ sits above it. */
#ifndef MIM_SERVE_H
#define MIM_SERVE_H

#include "mim_core.h"

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MIM_SERVE_DEFAULT_LISTEN "127.0.0.1:8080"
#define MIM_SERVE_DEFAULT_MAX_BODY ((size_t)1 << 20)

typedef struct mim_serve_options {
    const char *listen; /* HOST:PORT (port 0: any free port); NULL: MIM_SERVE_DEFAULT_LISTEN */
    size_t max_body;    /* request body limit in bytes (413 above it); 0: MIM_SERVE_DEFAULT_MAX_BODY */
    unsigned threads;   /* HTTP worker threads; 0: 4 */
    const char *vest;   /* NULL: no vest; else a vest spec (mim_vest_transport_open: a recording,
                           serial:PATH, hid:..., udp:HOST:PORT), read by the real-time loop */
    int vest_pose;      /* the wearer's pose at the tare: MIM_VEST_POSE_* (0: as the avatar rests) */
} mim_serve_options_t;

typedef struct mim_serve mim_serve_t;

/* Opens the store read-only, loads the avatar (a mesh file with the store's
 * connectivity, or an all-digit template id), the index if the store has
 * one (without it /api/query answers 503), factorises the transfer solver
 * once, starts the vest loop (opt->vest) and starts listening. Errors name the store, the avatar or the
 * address. */
int mim_serve_open(mim_serve_t **out, const char *store, const char *avatar, const mim_serve_options_t *opt,
                   mim_error_t *err);
/* The port actually bound (useful with port 0). */
int mim_serve_port(const mim_serve_t *s);
/* Stops listening (waits for requests in flight) and frees everything.
 * Accepts NULL; nulls the pointer. */
void mim_serve_close(mim_serve_t **s);

#ifdef __cplusplus
}
#endif
#endif
