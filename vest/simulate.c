/* A simulated vest: motion data turned into the PrioVR hub's real wire
 * protocol (through the same encoder the tests check the decoder with), at a
 * steady rate, with injected faults: dropped packets, corrupted bytes, a
 * disconnect, and sensor error (orientation noise, drift). Outputs: a
 * pseudo-terminal (what a USB CDC serial port looks like to mimic), UDP
 * landmark frames, or a recording file. */
#include "mim_vest_simulate.h"
#include "mim_vest_transport.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netdb.h>
#include <pty.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

struct mim_vest_sim {
    const mim_vest_motion_t *m;
    mim_vest_sim_options_t o;
    uint64_t period; /* stream frames in one pass over the motion */
    mim_rng_t rng; /* the faults: deterministic for a seed */
    mim_vec3 drift_axis[MIM_VEST_SEGMENTS];
};

/* rng streams of the sensor error, apart from the packet faults' */
#define DRIFT_STREAM 0x0d21f7u
#define NOISE_SEED_TAG 0x6f7269656e74ull /* "orient": noise of frame k is stream k */

static mim_vec3 random_axis(mim_rng_t *r)
{
    for (;;) { /* a Gaussian vector's direction is uniform on the sphere */
        mim_vec3 v = {mim_rng_gauss(r), mim_rng_gauss(r), mim_rng_gauss(r)};
        double n = sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
        if (n > 1e-9) return (mim_vec3){v.x / n, v.y / n, v.z / n};
    }
}

int mim_vest_sim_open(mim_vest_sim_t **out, const mim_vest_motion_t *m, const mim_vest_sim_options_t *opt,
                      mim_error_t *err)
{
    *out = NULL;
    if (!m || !m->n_frames || !m->q) return mim_error_set(err, MIM_EINVAL, "vest simulate: empty motion");
    mim_vest_sim_t *s = calloc(1, sizeof *s);
    if (!s) return mim_error_set(err, MIM_ENOMEM, "vest simulate: out of memory");
    s->m = m;
    if (opt) s->o = *opt;
    if (s->o.rate_hz == 0) s->o.rate_hz = 60;
    if (!(s->o.rate_hz >= 1 && s->o.rate_hz <= 2000) || !(s->o.drop >= 0 && s->o.drop <= 1) ||
        !(s->o.corrupt >= 0 && s->o.corrupt <= 1) || !(s->o.disconnect_at >= 0) || !(s->o.disconnect_for >= 0) ||
        !(s->o.orient_noise_deg >= 0 && s->o.orient_noise_deg <= 180) ||
        !(s->o.drift_deg_per_min >= 0 && s->o.drift_deg_per_min <= 3600)) {
        free(s);
        return mim_error_set(err, MIM_EINVAL,
                             "vest simulate: rate must be 1..2000 Hz, fault probabilities 0..1, orientation noise "
                             "0..180 degrees, drift 0..3600 degrees a minute");
    }
    if (s->o.disconnect_for == 0) s->o.disconnect_for = 0.5;
    if (!s->o.header_flags) s->o.header_flags = MIM_VEST_HDR_DEFAULT;
    double dur = m->n_frames > 1 ? (m->n_frames - 1) * m->frame_time : 1.0;
    s->period = (uint64_t)floor(dur * s->o.rate_hz + 1e-9) + 1;
    mim_rng_seed(&s->rng, s->o.seed, 0x7e57u);
    mim_rng_t r;
    mim_rng_seed(&r, s->o.seed, DRIFT_STREAM);
    for (int i = 0; i < MIM_VEST_SEGMENTS; i++) s->drift_axis[i] = random_axis(&r);
    *out = s;
    return 0;
}

void mim_vest_sim_close(mim_vest_sim_t **s)
{
    if (!s || !*s) return;
    free(*s);
    *s = NULL;
}

uint64_t mim_vest_sim_n_frames(const mim_vest_sim_t *s) { return s->period; }
double mim_vest_sim_rate(const mim_vest_sim_t *s) { return s->o.rate_hz; }

void mim_vest_sim_orientations(const mim_vest_sim_t *s, uint64_t k, mim_quat q[MIM_VEST_SEGMENTS],
                               uint8_t have[MIM_VEST_SEGMENTS], uint64_t *t_us)
{
    if (t_us) *t_us = (uint64_t)llround((double)k * 1e6 / s->o.rate_hz);
    if (!q) return;
    double t = (double)(k % s->period) / s->o.rate_hz;
    if (s->m->n_frames == 1) t = 0;
    mim_vest_motion_sample(s->m, t, q);
    for (int i = 0; i < MIM_VEST_SEGMENTS; i++) {
        /* what the wire carries: float32 */
        mim_quat w = {(float)q[i].x, (float)q[i].y, (float)q[i].z, (float)q[i].w};
        q[i] = w;
        if (have) have[i] = s->m->have[i];
    }
}

void mim_vest_sim_wire_orientations(const mim_vest_sim_t *s, uint64_t k, mim_quat q[MIM_VEST_SEGMENTS],
                                    uint8_t have[MIM_VEST_SEGMENTS], uint64_t *t_us)
{
    mim_vest_sim_orientations(s, k, q, have, t_us);
    if (!q || (s->o.orient_noise_deg == 0 && s->o.drift_deg_per_min == 0)) return;
    const double deg = 3.141592653589793 / 180;
    /* noise of frame k from its own stream: any output, any call order, same error */
    mim_rng_t r;
    mim_rng_seed(&r, s->o.seed ^ NOISE_SEED_TAG, k);
    double drift = s->o.drift_deg_per_min * deg * ((double)k / s->o.rate_hz) / 60;
    for (int i = 0; i < MIM_VEST_SEGMENTS; i++) {
        mim_quat e = mim_quat_axis_angle(s->drift_axis[i], drift);
        if (s->o.orient_noise_deg > 0) {
            mim_vec3 axis = random_axis(&r);
            e = mim_quat_mul(mim_quat_axis_angle(axis, s->o.orient_noise_deg * deg * mim_rng_gauss(&r)), e);
        }
        mim_quat w = mim_quat_normalize(mim_quat_mul(e, q[i]));
        q[i] = (mim_quat){(float)w.x, (float)w.y, (float)w.z, (float)w.w};
    }
}

size_t mim_vest_sim_frame(mim_vest_sim_t *s, uint64_t k, uint8_t *buf, size_t cap, uint32_t counts[3])
{
    mim_quat q[MIM_VEST_SEGMENTS];
    uint8_t have[MIM_VEST_SEGMENTS];
    uint64_t t;
    mim_vest_sim_wire_orientations(s, k, q, have, &t);
    uint32_t per = mim_vest_hub_capacity(s->o.header_flags);
    float fq[MIM_VEST_SEGMENTS][4];
    size_t n = 0;
    uint32_t made = 0, dropped = 0, corrupted = 0;
    for (uint32_t first = 0; first < MIM_VEST_SEGMENTS;) {
        mim_vest_hub_packet_t p = {0};
        p.header_flags = s->o.header_flags;
        p.timestamp_us = (uint32_t)t;
        p.serial = 0x2476A001u;
        p.logical_id = MIM_VEST_ID_HUB;
        p.battery = 95;
        uint32_t c = 0, id = first;
        for (; id < MIM_VEST_SEGMENTS && c < per; id++) {
            if (!have[id]) continue;
            p.active |= 1ull << id;
            fq[c][0] = (float)q[id].x, fq[c][1] = (float)q[id].y, fq[c][2] = (float)q[id].z, fq[c][3] = (float)q[id].w;
            c++;
        }
        first = id;
        if (!c) break;
        p.q = (const float(*)[4])fq;
        size_t len = mim_vest_encode_hub_packet(buf + n, cap - n, &p);
        if (!len) break;
        made++;
        if (s->o.drop > 0 && mim_rng_unit(&s->rng) < s->o.drop) {
            dropped++;
            continue;
        }
        if (s->o.corrupt > 0 && mim_rng_unit(&s->rng) < s->o.corrupt) {
            size_t at = (size_t)mim_rng_below(&s->rng, len);
            buf[n + at] ^= (uint8_t)(1 + mim_rng_below(&s->rng, 255));
            corrupted++;
        }
        n += len;
    }
    if (counts) counts[0] += made, counts[1] += dropped, counts[2] += corrupted;
    return n;
}

/* ---- outputs ---- */

static void sleep_until(double t)
{
    double now = mim_now();
    if (t <= now) return;
    double d = t - now;
    struct timespec ts = {(time_t)d, (long)((d - floor(d)) * 1e9)};
    while (nanosleep(&ts, &ts) && errno == EINTR) {
    }
}

typedef struct {
    int master, slave;
    char path[256];
} pty_t;

static int pty_open(pty_t *p, const char *link, mim_error_t *err)
{
    struct termios tio;
    memset(&tio, 0, sizeof tio);
    cfmakeraw(&tio);
    cfsetispeed(&tio, B115200);
    cfsetospeed(&tio, B115200);
    tio.c_cflag |= CS8 | CLOCAL | CREAD;
    if (openpty(&p->master, &p->slave, p->path, &tio, NULL))
        return mim_error_set(err, -errno, "vest simulate: openpty: %s", strerror(errno));
    int fl = fcntl(p->master, F_GETFL);
    fcntl(p->master, F_SETFL, fl | O_NONBLOCK); /* a full queue drops bytes, as a real port does */
    if (link) {
        char tmp[4096];
        snprintf(tmp, sizeof tmp, "%s.tmp%d", link, (int)getpid());
        unlink(tmp);
        if (symlink(p->path, tmp) || rename(tmp, link)) {
            int e = errno;
            unlink(tmp);
            close(p->master), close(p->slave);
            return mim_error_set(err, -e, "vest simulate: link %s -> %s: %s", link, p->path, strerror(e));
        }
    }
    return 0;
}

/* The vest goes away: its pty closes and its link, if any, goes too, as a
 * USB serial port's device node does. A link left behind would point at a
 * /dev/pts number the kernel hands to the next process that opens a pty,
 * and a reader reconnecting through it would read that stranger's stream. */
static void pty_close(pty_t *p, const char *link)
{
    if (link) unlink(link);
    if (p->master >= 0) close(p->master);
    if (p->slave >= 0) close(p->slave);
    p->master = p->slave = -1;
}

static int udp_connect(const char *hostport, mim_error_t *err)
{
    char host[256];
    const char *colon = strrchr(hostport, ':');
    if (!colon || colon == hostport || (size_t)(colon - hostport) >= sizeof host)
        return mim_error_set(err, MIM_EINVAL, "vest simulate: '%s' is not HOST:PORT", hostport);
    memcpy(host, hostport, (size_t)(colon - hostport));
    host[colon - hostport] = 0;
    struct addrinfo hints = {0}, *ai = NULL;
    hints.ai_socktype = SOCK_DGRAM;
    int g = getaddrinfo(host, colon + 1, &hints, &ai);
    if (g) return mim_error_set(err, MIM_EINVAL, "vest simulate: udp:%s: %s", hostport, gai_strerror(g));
    int fd = socket(ai->ai_family, SOCK_DGRAM, 0);
    if (fd < 0 || connect(fd, ai->ai_addr, ai->ai_addrlen)) {
        int e = errno;
        if (fd >= 0) close(fd);
        freeaddrinfo(ai);
        return mim_error_set(err, -e, "vest simulate: udp:%s: %s", hostport, strerror(e));
    }
    freeaddrinfo(ai);
    return fd;
}

int mim_vest_sim_run(mim_vest_sim_t *s, const mim_vest_sim_run_t *run, mim_error_t *err)
{
    if (!s || !run || !run->out) return mim_error_set(err, MIM_EINVAL, "vest simulate: no output");
    enum { PTY, UDP, FILE_ } kind;
    const char *out = run->out, *link = NULL;
    if (!strcmp(out, "pty")) kind = PTY;
    else if (!strncmp(out, "pty:", 4)) kind = PTY, link = out + 4;
    else if (!strncmp(out, "udp:", 4)) kind = UDP;
    else kind = FILE_;
    if (kind == UDP && !run->rig) return mim_error_set(err, MIM_EINVAL, "vest simulate: udp output needs an avatar rig");
    pty_t pty = {-1, -1, ""};
    int fd = -1, rc = 0;
    mim_vest_recorder_t *rec = NULL;
    if (kind == PTY) {
        if ((rc = pty_open(&pty, link, err))) return rc;
        if (run->ready) run->ready(run->user, link ? link : pty.path);
    } else if (kind == UDP) {
        if ((fd = udp_connect(out + 4, err)) < 0) return fd;
        if (run->ready) run->ready(run->user, out);
    } else {
        if ((rc = mim_vest_recorder_open(&rec, out, s->o.header_flags, err))) return rc;
        if (run->ready) run->ready(run->user, out);
    }
    int realtime = kind != FILE_ || run->realtime;
    double t0 = mim_now();
    uint8_t buf[8 * MIM_VEST_MAX_PACKET];
    uint64_t total = s->o.loop ? UINT64_MAX : s->period;
    int down = 0;
    double dis_at = s->o.disconnect_at, dis_end = s->o.disconnect_at + s->o.disconnect_for;
    for (uint64_t k = 0; k < total && !rc; k++) {
        if (run->stop && *run->stop) break;
        double tk = (double)k / s->o.rate_hz;
        if (realtime) sleep_until(t0 + tk);
        if (dis_at > 0 && tk >= dis_at && tk < dis_end) {
            if (!down && kind == PTY) pty_close(&pty, link);
            down = 1;
            continue; /* the hub's clock runs on while it is away */
        }
        if (down) {
            down = 0;
            if (kind == PTY) {
                char old[256];
                snprintf(old, sizeof old, "%s", pty.path);
                if ((rc = pty_open(&pty, link, err))) break;
                if (run->ready && (link == NULL && strcmp(old, pty.path))) run->ready(run->user, pty.path);
            }
        }
        if (kind == UDP) {
            mim_quat q[MIM_VEST_SEGMENTS];
            uint8_t have[MIM_VEST_SEGMENTS];
            uint64_t t;
            mim_vest_sim_wire_orientations(s, k, q, have, &t);
            float xyz[3 * MIM_LANDMARKS_MAX];
            uint8_t present[MIM_LANDMARKS_MAX];
            mim_quat R[MIM_VEST_SEGMENTS];
            mim_vest_fk_orient(run->rig, q, have, xyz, present);
            mim_vest_segment_rotations(run->rig, q, have, R);
            if (s->o.drop > 0 && mim_rng_unit(&s->rng) < s->o.drop) continue;
            char *js = mim_vest_udp_format_orient(t, xyz, present, run->rig->n_landmarks, R, have);
            if (!js) {
                rc = mim_error_set(err, MIM_ENOMEM, "vest simulate: out of memory");
                break;
            }
            size_t len = strlen(js);
            if (s->o.corrupt > 0 && mim_rng_unit(&s->rng) < s->o.corrupt && len)
                js[mim_rng_below(&s->rng, len)] ^= (char)(1 + mim_rng_below(&s->rng, 127));
            if (send(fd, js, len, 0) < 0 && errno != ECONNREFUSED) /* nobody listening yet is fine */
                rc = mim_error_set(err, -errno, "vest simulate: %s: %s", out, strerror(errno));
            free(js);
            continue;
        }
        size_t n = mim_vest_sim_frame(s, k, buf, sizeof buf, NULL);
        if (!n) continue;
        if (kind == PTY) {
            ssize_t w = write(pty.master, buf, n);
            if (w < 0 && errno != EAGAIN && errno != EIO)
                rc = mim_error_set(err, -errno, "vest simulate: write to %s: %s", pty.path, strerror(errno));
        } else {
            uint64_t t;
            mim_vest_sim_orientations(s, k, NULL, NULL, &t);
            mim_vest_chunk_t c = {MIM_VEST_CHUNK_STREAM, t, buf, n, 0};
            rc = mim_vest_recorder_write(rec, &c, err);
        }
    }
    if (kind == PTY) {
        /* let the reader drain the port's input queue before it disappears */
        for (int i = 0; i < 100 && !rc; i++) {
            int q = 0;
            if (ioctl(pty.slave, FIONREAD, &q) || q <= 0) break;
            sleep_until(mim_now() + 0.01);
        }
        pty_close(&pty, link);
    }
    if (fd >= 0) close(fd);
    if (rec) {
        int r2 = mim_vest_recorder_close(&rec, err);
        if (!rc) rc = r2;
    }
    return rc;
}
