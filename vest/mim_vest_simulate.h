/* mimic vest, the simulated vest: a motion played as the PrioVR hub's real
 * wire protocol (through the encoder of mim_vest_protocol.h) at a steady
 * rate, with injected faults (dropped packets, corrupted bytes, a
 * disconnect, orientation noise and drift), into a pseudo-terminal, UDP
 * landmark frames, or a recording.
 * Implemented by simulate.c.
 *
 * Threads: a simulator is used by one thread at a time; mim_vest_sim_frame
 * and mim_vest_sim_run advance its fault generator. */
#ifndef MIM_VEST_SIMULATE_H
#define MIM_VEST_SIMULATE_H

#include "mim_core.h"
#include "mim_vest_kinematics.h"
#include "mim_vest_motion.h"
#include "mim_vest_protocol.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Zero-initialise: every 0 means the default. Copied by open. */
typedef struct mim_vest_sim_options {
    double rate_hz;          /* 1..2000; 0 = 60 */
    double drop, corrupt;    /* probability per packet (per datagram for udp), 0..1 */
    double disconnect_at;    /* seconds into the stream; 0 = never */
    double disconnect_for;   /* seconds; 0 = 0.5 */
    int loop;
    uint64_t seed;           /* fault randomness: same seed, same calls, same bytes */
    uint32_t header_flags;   /* 0 = default */
    /* Sensor error on what is sent (mim_vest_sim_wire_orientations): each
     * frame each sensor turned by a random rotation (random axis, Gaussian
     * angle of this standard deviation, 0..180 degrees), and per sensor a
     * fixed random axis whose angle grows with stream time (0..3600 degrees
     * a minute). 0 = none. Drawn from the seed apart from drop and corrupt,
     * whose bytes they leave as they were. */
    double orient_noise_deg, drift_deg_per_min;
} mim_vest_sim_options_t;

typedef struct mim_vest_sim mim_vest_sim_t;
/* Creates a simulator of motion m (malloc'd; free it with mim_vest_sim_close).
 * m is borrowed, not copied: it must stay alive and unchanged until close.
 * out must not be NULL (not checked); opt NULL = defaults. Returns 0;
 * MIM_EINVAL (m NULL or without frames, rate outside 1..2000 Hz, a
 * probability outside 0..1, a negative or NaN disconnect time, orientation
 * noise or drift outside its range); MIM_ENOMEM.
 * *out is NULL on failure. */
int mim_vest_sim_open(mim_vest_sim_t **out, const mim_vest_motion_t *m, const mim_vest_sim_options_t *opt,
                      mim_error_t *err);
/* Frees the simulator (not the motion); accepts NULL and *s NULL; sets *s to NULL. */
void mim_vest_sim_close(mim_vest_sim_t **s);
/* Stream frames in the motion (a single-frame motion streams one second);
 * with loop, the stream never ends but frames repeat with this period. */
uint64_t mim_vest_sim_n_frames(const mim_vest_sim_t *s);
/* The stream rate in Hz, after the default. */
double mim_vest_sim_rate(const mim_vest_sim_t *s);
/* The true orientations of frame k (the motion's, as float32 on the wire
 * would give them), its timestamp (k / rate, microseconds), and which
 * sensors it carries (the motion's have[]). q, have and t_us may each be
 * NULL. Independent of the faults (orientation noise and drift included):
 * it does not touch the fault generator, and is what --expected writes. */
void mim_vest_sim_orientations(const mim_vest_sim_t *s, uint64_t k, mim_quat q[MIM_VEST_SEGMENTS],
                               uint8_t have[MIM_VEST_SEGMENTS], uint64_t *t_us);
/* What frame k sends on the wire: the true orientations turned by the
 * orientation noise and drift (world frame: q' = N D q), as float32; equal
 * to mim_vest_sim_orientations when both are 0. A function of the seed and
 * k alone (the same for every call, in any order); it does not touch the
 * fault generator. Arguments as mim_vest_sim_orientations. */
void mim_vest_sim_wire_orientations(const mim_vest_sim_t *s, uint64_t k, mim_quat q[MIM_VEST_SEGMENTS],
                                    uint8_t have[MIM_VEST_SEGMENTS], uint64_t *t_us);
/* The packets of frame k, carrying the wire's orientations (faults applied:
 * a dropped packet is left out, a corrupted one has one byte changed).
 * Returns bytes written (0 if all were dropped); packets that do not fit in
 * cap are left out, and cap >= 4 * MIM_VEST_MAX_PACKET is always enough. counts (may be NULL) are added to,
 * not reset: [0] packets made, [1] dropped, [2] corrupted. */
size_t mim_vest_sim_frame(mim_vest_sim_t *s, uint64_t k, uint8_t *buf, size_t cap, uint32_t counts[3]);

typedef struct mim_vest_sim_run {
    /* pty | pty:LINK | udp:HOST:PORT | FILE (a recording). pty:LINK makes
     * LINK a symlink to the pty (replaced atomically) and leaves it there. */
    const char *out;
    /* needed by udp: the landmarks and segment orientations of the wire's
     * orientations on this rig are sent; read during the run */
    const mim_vest_rig_t *rig;
    int realtime;               /* pty and udp always; FILE only when set */
    /* Called on the running thread with the pty path (or LINK), the udp
     * spec or the file name when the output is ready, and again after a
     * simulated reconnect if the pty path changed (never with LINK). The
     * string is valid during the call only. May be NULL. */
    void (*ready)(void *user, const char *path);
    void *user;
    volatile int *stop;         /* set non-zero to stop, checked once per frame (may be NULL) */
} mim_vest_sim_run_t;
/* Streams the whole motion to run->out, blocking the calling thread (with
 * loop, until *stop is set or an error occurs). A simulated disconnect
 * closes and reopens the pty; for udp and FILE the frames in that span are
 * left out. A pty whose reader lags drops bytes, as a real port does; udp
 * sends to nobody listening are not errors. Returns 0 when done or stopped;
 * MIM_EINVAL (s, run or out NULL; udp without a rig; udp HOST:PORT bad or
 * not resolvable); -errno (openpty, LINK, socket/connect, send, pty write);
 * the recorder's codes for FILE (mim_vest_transport.h); MIM_ENOMEM. */
int mim_vest_sim_run(mim_vest_sim_t *s, const mim_vest_sim_run_t *run, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
