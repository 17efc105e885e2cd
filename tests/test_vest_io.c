/* Tests of vest/ input and output: the simulated vest through a real
 * pseudo-terminal (with a disconnect and a reconnect), serial errors, HID
 * over a substituted device layer, UDP landmark frames, recordings, and
 * `mimic vest list/record/replay/simulate`. */
#include "vest_support.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

/* The rig `mimic vest ... --avatar synth --pose P` builds (subject 0 of a
 * one-subject synth at its default size; vs_avatar_make's body differs). */
static void cli_synth_rig(mim_vest_rig_t *rig, int pose)
{
    mim_synth_options_t so = {1, 1, 0, 1, 0, 0, 0};
    mim_synth_t *s = NULL;
    mim_mesh_t mesh = {0};
    mim_landmark_map_t map;
    mim_vest_skeleton_t *sk = malloc(sizeof *sk);
    assert_int_equal(mim_synth_create(&s, &so, NULL), 0);
    assert_int_equal(mim_mesh_alloc(&mesh, mim_synth_n_vertices(s), mim_synth_n_faces(s)), 0);
    memcpy(mesh.faces, mim_synth_faces(s), sizeof *mesh.faces * 3 * mesh.n_faces);
    assert_int_equal(mim_synth_body(s, 0, 0, mesh.positions), 0);
    mim_synth_landmarks(s, &map);
    mim_vest_calib_options_t co = {pose};
    assert_int_equal(mim_vest_skeleton_estimate(sk, &mesh, &map, NULL), 0);
    assert_int_equal(mim_vest_calibrate(rig, sk, &co, NULL, NULL), 0);
    mim_mesh_free(&mesh);
    mim_synth_destroy(&s);
    free(sk);
}

/* ------------------------------------------------------------ through a pty */

/* The test motion of `frames` frames (into m, which the caller frees) in
 * a simulator with options so. */
static mim_vest_sim_t *sim_of_motion(mim_vest_motion_t *m, int frames, const mim_vest_sim_options_t *so)
{
    vs_load_motion(m, frames);
    mim_vest_sim_t *sim = NULL;
    assert_int_equal(mim_vest_sim_open(&sim, m, so, NULL), 0);
    return sim;
}

typedef struct {
    mim_vest_sim_t *sim;
    const char *out;
    const mim_vest_rig_t *rig;
    char path[256];
    int ready;
    int rc;
    pthread_mutex_t mu;
    pthread_cond_t cv;
} simthread_t;

static void sim_ready(void *user, const char *path)
{
    simthread_t *st = user;
    pthread_mutex_lock(&st->mu);
    if (path != st->path) snprintf(st->path, sizeof st->path, "%s", path);
    st->ready = 1;
    pthread_cond_signal(&st->cv);
    pthread_mutex_unlock(&st->mu);
}

static void *sim_main(void *arg)
{
    simthread_t *st = arg;
    mim_vest_sim_run_t run = {st->out, st->rig, 1, sim_ready, st, NULL};
    mim_error_t err = {0};
    st->rc = mim_vest_sim_run(st->sim, &run, &err);
    if (st->rc) fprintf(stderr, "simulator: %s\n", err.msg);
    sim_ready(st, st->path); /* never leave the reader waiting */
    return NULL;
}

static void sim_start(simthread_t *st, pthread_t *th, mim_vest_sim_t *sim, const char *out, const mim_vest_rig_t *rig)
{
    memset(st, 0, sizeof *st);
    st->sim = sim, st->out = out, st->rig = rig;
    pthread_mutex_init(&st->mu, NULL);
    pthread_cond_init(&st->cv, NULL);
    assert_int_equal(pthread_create(th, NULL, sim_main, st), 0);
    pthread_mutex_lock(&st->mu);
    while (!st->ready) pthread_cond_wait(&st->cv, &st->mu);
    pthread_mutex_unlock(&st->mu);
}

/* Live decoding: frames -> assembler -> state -> landmarks, compared with
 * the forward kinematics of the orientations the simulator sent. */
typedef struct {
    const mim_vest_rig_t *rig;
    mim_vest_sim_t *sim;
    mim_vest_state_t st;
    mim_vest_assembler_t as;
    uint64_t frames, checked;
    double max_err;
    uint64_t first_t, last_t;
    int saw_missing;
} live_t;

static void live_check(live_t *L, uint64_t t, uint64_t mask)
{
    (void)mask;
    float got[3 * MIM_LANDMARKS_MAX], want[3 * MIM_LANDMARKS_MAX];
    uint8_t pg[MIM_LANDMARKS_MAX], pw[MIM_LANDMARKS_MAX];
    /* only sensors that reported at t: a packet lost at a reconnect leaves
     * older readings, which are right for the runtime but not for this check */
    uint8_t fresh[MIM_VEST_SEGMENTS];
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) fresh[s] = L->st.seen[s] && L->st.t_us[s] == t;
    mim_vest_fk_orient(L->rig, L->st.q, fresh, got, pg);
    uint64_t k = (uint64_t)llround((double)t * mim_vest_sim_rate(L->sim) / 1e6);
    mim_quat q[MIM_VEST_SEGMENTS];
    uint8_t have[MIM_VEST_SEGMENTS];
    uint64_t tk;
    mim_vest_sim_orientations(L->sim, k, q, have, &tk);
    assert_true(tk == t);
    mim_vest_fk_orient(L->rig, q, have, want, pw);
    if (!L->frames) L->first_t = t;
    L->last_t = t;
    L->frames++;
    for (uint32_t i = 0; i < L->rig->n_landmarks; i++) {
        if (!pg[i]) {
            L->saw_missing = 1;
            continue;
        }
        for (int c = 0; c < 3; c++) {
            double e = fabs(got[3 * i + c] - want[3 * i + c]);
            if (!(e <= L->max_err)) L->max_err = e;
        }
        L->checked++;
    }
}

static void live_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    live_t *L = user;
    uint64_t t[2], m[2];
    int done = mim_vest_assembler_push(&L->as, info, t, m), k = 0;
    if (done > 0 && t[0] < info->t_us) live_check(L, t[0], m[0]), k = 1;
    for (uint32_t i = 0; i < n; i++) mim_vest_state_update(&L->st, &f[i]);
    for (; k < done; k++) live_check(L, t[k], m[k]);
}

/* Decodes the simulator's stream from spec into L until the transport gives
 * up (-ENODEV: the simulator has gone for good); returns the transport, for
 * its reconnect count. */
static mim_vest_transport_t *live_decode(live_t *L, const char *spec, const mim_vest_transport_options_t *to,
                                         const mim_vest_rig_t *rig, mim_vest_sim_t *sim)
{
    mim_vest_transport_t *t = NULL;
    mim_error_t err = {0};
    if (mim_vest_transport_open(&t, spec, to, &err)) fail_msg("%s", err.msg);
    memset(L, 0, sizeof *L);
    L->rig = rig, L->sim = sim;
    mim_vest_state_reset(&L->st);
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, live_packet, L), 0);
    int r;
    for (;;) {
        mim_vest_chunk_t c;
        mim_error_clear(&err);
        r = mim_vest_transport_read(t, &c, &err);
        if (r == -ETIMEDOUT) continue;
        if (r <= 0) break;
        if (c.restart) mim_vest_decoder_reset(d);
        mim_vest_decoder_feed(d, c.data, c.len, c.t_us);
    }
    assert_int_equal(r, -ENODEV);
    uint64_t tl, ml;
    if (mim_vest_assembler_flush(&L->as, &tl, &ml)) live_check(L, tl, ml);
    mim_vest_decoder_close(&d);
    return t;
}

static void test_pty_end_to_end(void **state)
{
    (void)state;
    vs_avatar_t a;
    vs_avatar_make(&a, MIM_VEST_POSE_T);
    mim_vest_sim_options_t so = {0};
    so.rate_hz = 100;
    mim_vest_motion_t m;
    mim_vest_sim_t *sim = sim_of_motion(&m, 31, &so); /* one second */
    /* through a link, which the simulator removes when it stops: a bare
     * /dev/pts/N path, retried after the stream ends, could open the next
     * process's pty (another test's vest) */
    char *dir = ts_tempdir("vest-e2e");
    char *link = ts_path(dir, "vest"), out[4200];
    snprintf(out, sizeof out, "pty:%s", link);
    simthread_t st;
    pthread_t th;
    sim_start(&st, &th, sim, out, NULL);
    char spec[4200];
    snprintf(spec, sizeof spec, "serial:%s", link);
    mim_vest_transport_options_t to = {0};
    to.timeout_ms = 300, to.reconnect_limit_ms = 300, to.backoff_min_ms = 10;
    live_t L;
    mim_vest_transport_t *t = live_decode(&L, spec, &to, &a.rig, sim);
    pthread_join(th, NULL);
    assert_int_equal(st.rc, 0);
    /* the frames through (a pty queue that overflows on a loaded machine
     * drops bytes, as a real port does), landmarks equal to the motion's
     * forward kinematics */
    assert_true(L.frames >= mim_vest_sim_n_frames(sim) * 9 / 10);
    assert_true(L.checked >= L.frames * 16 * 9 / 10);
    assert_true(L.max_err < 1e-4);
    mim_vest_transport_close(&t);
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    vs_avatar_free(&a);
    ts_rmtree(dir);
    free(link), free(dir);
}

static void test_pty_disconnect(void **state)
{
    (void)state;
    vs_avatar_t a;
    vs_avatar_make(&a, MIM_VEST_POSE_T);
    mim_vest_sim_options_t so = {0};
    so.disconnect_at = 0.5, so.disconnect_for = 0.3;
    mim_vest_motion_t m;
    mim_vest_sim_t *sim = sim_of_motion(&m, 46, &so); /* 1.5 s */
    char *dir = ts_tempdir("vest-link");
    char *link = ts_path(dir, "vest"), out[4200];
    snprintf(out, sizeof out, "pty:%s", link);
    simthread_t st;
    pthread_t th;
    sim_start(&st, &th, sim, out, NULL);
    assert_string_equal(st.path, link);
    char spec[4200];
    snprintf(spec, sizeof spec, "serial:%s", link);
    mim_vest_transport_options_t to = {0};
    to.timeout_ms = 2000, to.reconnect_limit_ms = 1500, to.backoff_min_ms = 10, to.backoff_max_ms = 100;
    live_t L;
    mim_vest_transport_t *t = live_decode(&L, spec, &to, &a.rig, sim); /* to the stream's end, past the outage */
    pthread_join(th, NULL);
    assert_int_equal(st.rc, 0);
    /* a vest that went away leaves no link behind (a stale one would point
     * at a /dev/pts number the next pty gets) */
    struct stat lst;
    assert_int_equal(lstat(link, &lst), -1);
    assert_true(mim_vest_transport_reconnects(t) >= 1);
    /* frames from before and after the outage, all right */
    assert_true(L.first_t < 500000);
    assert_true(L.last_t > 1000000);
    assert_true(L.frames > 40);
    assert_true(L.max_err < 1e-4);
    mim_vest_transport_close(&t);
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    vs_avatar_free(&a);
    ts_rmtree(dir);
    free(link), free(dir);
}

/* An unplugged device: one clear line. */
static void test_serial_errors(void **state)
{
    (void)state;
    mim_vest_transport_t *t = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_transport_open(&t, "serial:/dev/ttyACM-nonexistent", NULL, &err), -ENOENT);
    assert_non_null(strstr(err.msg, "serial /dev/ttyACM-nonexistent: no such device"));
    assert_null(strchr(err.msg, '\n'));
    mim_error_clear(&err);
    assert_int_equal(mim_vest_transport_open(&t, "serial:/dev/null", NULL, &err), -ENOTTY);
    assert_non_null(strstr(err.msg, "not a serial port"));
    mim_error_clear(&err);
    assert_int_equal(mim_vest_transport_open(&t, "hid:zz:1", NULL, &err), MIM_EINVAL);
    mim_error_clear(&err);
    assert_true(mim_vest_transport_open(&t, "/nonexistent/rec.vest", NULL, &err) < 0);
    assert_null(t);
}

/* ------------------------------------------------------------ HID over a substituted device layer */

typedef struct {
    const uint8_t *stream;
    size_t n, pos;
    int opens, fail_opens, unplug_at_read, reads, gone;
    char serial[64];
    uint8_t written[4096];
    size_t n_written;
    int dev;
} fakehid_t;

static void *fh_open(void *ctx, uint16_t vid, uint16_t pid, const char *serial)
{
    fakehid_t *f = ctx;
    if (vid != 0x2476 || pid != 0x1040) return NULL;
    f->opens++;
    if (f->gone) return NULL;
    if (f->fail_opens > 0) {
        f->fail_opens--;
        return NULL;
    }
    snprintf(f->serial, sizeof f->serial, "%s", serial ? serial : "");
    return &f->dev;
}

static int fh_read(void *ctx, void *dev, uint8_t *buf, size_t len, int ms)
{
    fakehid_t *f = ctx;
    (void)ms;
    assert_ptr_equal(dev, &f->dev);
    if (++f->reads == f->unplug_at_read) {
        f->fail_opens = 2; /* still gone for two tries */
        return -1;
    }
    if (f->pos >= f->n) return 0;
    size_t k = 1 + (size_t)(vs_rnd() % 63);
    if (k > f->n - f->pos) k = f->n - f->pos;
    assert_true(len >= 64);
    memset(buf, 0, 64);
    buf[0] = (uint8_t)k;
    memcpy(buf + 1, f->stream + f->pos, k);
    f->pos += k;
    return 64;
}

static int fh_write(void *ctx, void *dev, const uint8_t *buf, size_t len)
{
    fakehid_t *f = ctx;
    (void)dev;
    assert_int_equal(len, 65);
    assert_int_equal(buf[0], 0); /* report id */
    memcpy(f->written + f->n_written, buf + 2, buf[1]);
    f->n_written += buf[1];
    return (int)len;
}

static void fh_close(void *ctx, void *dev) { (void)ctx, (void)dev; }
static const char *fh_error(void *ctx, void *dev) { (void)ctx, (void)dev; return "fake: device gone"; }

static void test_hid_layer(void **state)
{
    (void)state;
    vs_stream_t s;
    vs_make_stream(&s, MIM_VEST_HDR_DEFAULT, 200, 0);
    fakehid_t f = {0};
    f.stream = s.bytes, f.n = s.n, f.unplug_at_read = 40;
    mim_vest_hid_layer_t layer = {&f, fh_open, fh_read, fh_write, fh_close, fh_error};
    mim_vest_transport_options_t to = {0};
    to.hid = &layer, to.timeout_ms = 50, to.backoff_min_ms = 1, to.backoff_max_ms = 4, to.reconnect_limit_ms = 2000;
    mim_vest_transport_t *t = NULL;
    mim_error_t err = {0};
    /* wrong product: a clear error */
    assert_int_equal(mim_vest_transport_open(&t, "hid:2476:9999", &to, &err), -ENODEV);
    assert_non_null(strstr(err.msg, "hid 2476:9999: cannot open (fake: device gone"));
    assert_int_equal(mim_vest_transport_open(&t, "hid:2476:1040:AB12", &to, &err), 0);
    assert_string_equal(f.serial, "AB12");
    assert_true(mim_vest_transport_is_device(t));
    /* commands go out in reports */
    uint8_t cmd[128];
    mim_vest_link_t link = {1, MIM_VEST_ID_HUB, 0};
    size_t nc = mim_vest_cmd_stream_setup(cmd, sizeof cmd, &link, MIM_VEST_HDR_DEFAULT, 10000);
    assert_int_equal(mim_vest_transport_write(t, cmd, nc, &err), 0);
    assert_int_equal(f.n_written, nc);
    assert_memory_equal(f.written, cmd, nc);
    /* the stream comes back whole, across an unplug (bytes in flight are lost) */
    vs_sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, vs_sink_packet, &k), 0);
    int restarts = 0;
    for (;;) {
        mim_vest_chunk_t c;
        int r = mim_vest_transport_read(t, &c, &err);
        if (r == -ETIMEDOUT) break; /* the fake has nothing more */
        assert_int_equal(r, 1);
        if (c.restart) mim_vest_decoder_reset(d), restarts++;
        mim_vest_decoder_feed(d, c.data, c.len, 0);
    }
    assert_int_equal(mim_vest_transport_reconnects(t), 1);
    assert_int_equal(restarts, 1);
    assert_int_equal(f.opens, 4); /* first, two failures, back */
    /* at most the packet cut by the unplug is lost; the rest in order */
    assert_true(k.n + 6 >= s.n_sent && k.n <= s.n_sent);
    for (size_t i = 0, j = 0; i < k.n; i++, j++) {
        while (j < s.n_sent && (k.f[i].t_us != s.sent[j].t_us || k.f[i].sensor != s.sent[j].sensor)) j++;
        assert_true(j < s.n_sent);
        vs_assert_frames_equal(&k.f[i], &s.sent[j], 1);
    }
    mim_vest_decoder_close(&d);
    mim_vest_transport_close(&t);
    /* unplugged for good: gives up after the limit with one line */
    f.pos = 0, f.reads = 0, f.unplug_at_read = 2, f.fail_opens = 0;
    to.reconnect_limit_ms = 50;
    assert_int_equal(mim_vest_transport_open(&t, "hid:2476:1040", &to, &err), 0);
    f.gone = 1;
    int r;
    mim_vest_chunk_t c;
    do mim_error_clear(&err);
    while ((r = mim_vest_transport_read(t, &c, &err)) == 1 || r == -ETIMEDOUT);
    assert_int_equal(r, -ENODEV);
    assert_non_null(strstr(err.msg, "hid 2476:1040: unplugged for"));
    mim_vest_transport_close(&t);
    free(k.f), free(s.bytes), free(s.sent);
}

/* ------------------------------------------------------------ UDP landmark frames */

static void test_udp(void **state)
{
    (void)state;
    float xyz[6] = {1, 2, 3, NAN, NAN, NAN}, got[3 * 4];
    uint8_t present[2] = {1, 0}, pg[4];
    char *js = mim_vest_udp_format(123, xyz, present, 2);
    assert_string_equal(js, "{\"t\":123,\"landmarks\":[[1.0,2.0,3.0],null]}");
    uint64_t t;
    uint32_t n;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_udp_parse(js, strlen(js), &t, got, pg, 4, &n, &err), 0);
    assert_true(t == 123 && n == 2 && pg[0] == 1 && pg[1] == 0 && got[2] == 3);
    free(js);
    assert_int_equal(mim_vest_udp_parse("{\"t\":1,\"landmarks\":[[1,2]]}", 26, &t, got, pg, 4, &n, &err), MIM_EFORMAT);
    assert_int_equal(mim_vest_udp_parse("{\"t\":1,", 7, &t, got, pg, 4, &n, &err), MIM_EFORMAT);
    /* without orientations: none kept, has_orient 0 */
    mim_quat R[MIM_SEGMENTS];
    uint8_t have[MIM_SEGMENTS];
    int has = -1;
    js = mim_vest_udp_format(123, xyz, present, 2);
    assert_int_equal(mim_vest_udp_parse_orient(js, strlen(js), &t, got, pg, 4, &n, R, have, &has, &err), 0);
    assert_true(has == 0 && have[3] == 0 && R[3].w == 1);
    free(js);
    /* a bad orientation makes the datagram bad, as a bad landmark does */
    const char *bq = "{\"t\":1,\"landmarks\":[[0,0,0],[1,0,0],[0,1,0],[0,0,1]],\"orientations\":{\"neck\":null}}";
    err = (mim_error_t){0};
    assert_int_equal(mim_vest_udp_parse(bq, strlen(bq), &t, got, pg, 4, &n, &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "udp frame: orientation 'neck' is not a vest segment (pelvis, "));

    /* the simulator sends landmark frames; the UDP transport receives them */
    vs_avatar_t a;
    vs_avatar_make(&a, MIM_VEST_POSE_T);
    mim_vest_sim_options_t so = {0};
    so.rate_hz = 100;
    mim_vest_motion_t m;
    mim_vest_sim_t *sim = sim_of_motion(&m, 16, &so);
    mim_vest_transport_t *tr = NULL;
    mim_vest_transport_options_t to = {0};
    to.timeout_ms = 500;
    int port = 0, rc = -1;
    char spec[64], out[64];
    for (int tries = 0; tries < 20 && rc; tries++) {
        port = 20000 + (int)(vs_rnd() % 30000);
        snprintf(spec, sizeof spec, "udp:127.0.0.1:%d", port);
        rc = mim_vest_transport_open(&tr, spec, &to, &err);
    }
    assert_int_equal(rc, 0);
    snprintf(out, sizeof out, "udp:127.0.0.1:%d", port);
    simthread_t st;
    pthread_t th;
    sim_start(&st, &th, sim, out, &a.rig);
    uint64_t frames = 0;
    double max_err = 0;
    for (;;) {
        mim_vest_chunk_t c;
        int r = mim_vest_transport_read(tr, &c, &err);
        if (r == -ETIMEDOUT) break;
        assert_int_equal(r, 1);
        assert_int_equal(c.kind, MIM_VEST_CHUNK_LANDMARKS);
        float lm[3 * MIM_LANDMARKS_MAX], want[3 * MIM_LANDMARKS_MAX];
        uint8_t p[MIM_LANDMARKS_MAX], pw[MIM_LANDMARKS_MAX];
        assert_int_equal(mim_vest_udp_parse((const char *)c.data, c.len, &t, lm, p, MIM_LANDMARKS_MAX, &n, &err), 0);
        assert_int_equal(n, 16);
        mim_quat q[MIM_VEST_SEGMENTS];
        uint8_t have[MIM_VEST_SEGMENTS];
        uint64_t tk;
        mim_vest_sim_orientations(sim, (uint64_t)llround((double)t * 100 / 1e6), q, have, &tk);
        assert_true(tk == t);
        mim_vest_fk_orient(&a.rig, q, have, want, pw);
        for (int i = 0; i < 48; i++) max_err = fmax(max_err, fabs(lm[i] - want[i]));
        /* and the segment orientations beside them, null where the motion has no sensor */
        mim_quat R[MIM_SEGMENTS], Rw[MIM_SEGMENTS];
        uint8_t hr[MIM_SEGMENTS];
        int has = 0;
        assert_int_equal(mim_vest_udp_parse_orient((const char *)c.data, c.len, &t, lm, p, MIM_LANDMARKS_MAX, &n, R,
                                                   hr, &has, &err), 0);
        assert_int_equal(has, 1);
        mim_vest_segment_rotations(&a.rig, q, have, Rw);
        for (int g = 0; g < MIM_SEGMENTS; g++) {
            assert_int_equal(hr[g], have[g]);
            if (have[g]) max_err = fmax(max_err, vs_angle_deg(R[g], Rw[g]) * M_PI / 180);
        }
        frames++;
    }
    pthread_join(th, NULL);
    assert_int_equal(st.rc, 0);
    assert_true(frames >= mim_vest_sim_n_frames(sim) * 9 / 10);
    assert_true(max_err < 1e-4);
    mim_vest_transport_close(&tr);
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    vs_avatar_free(&a);
}

/* The one writer of landmark lines, read back by both readers (the UDP
 * datagram's and the landmark frames'): orientations to 1e-6, null for a
 * lost sensor, keys in segment order. */
/* ------------------------------------------------------------ recordings */

static void test_record_replay_library(void **state)
{
    (void)state;
    char *dir = ts_tempdir("vest-rec");
    char *path = ts_path(dir, "a.vest");
    mim_vest_recorder_t *r = NULL;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_recorder_open(&r, path, 0x7E, &err), 0);
    uint8_t data[3][300];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 300; j++) data[i][j] = (uint8_t)vs_rnd();
    for (int i = 0; i < 3; i++) {
        mim_vest_chunk_t c = {i == 2 ? MIM_VEST_CHUNK_LANDMARKS : MIM_VEST_CHUNK_STREAM, 1000u * (uint64_t)i + 5,
                              data[i], 100u * (size_t)(i + 1), i == 1};
        assert_int_equal(mim_vest_recorder_write(r, &c, &err), 0);
    }
    assert_int_equal(mim_vest_recorder_close(&r, &err), 0);
    assert_null(r);
    mim_vest_transport_t *t = NULL;
    mim_vest_transport_options_t to = {0};
    to.realtime = 1;
    assert_int_equal(mim_vest_transport_open(&t, path, &to, &err), 0);
    assert_int_equal(mim_vest_transport_header_flags(t), 0x7E);
    double t0 = mim_now();
    for (int i = 0; i < 3; i++) {
        mim_vest_chunk_t c;
        assert_int_equal(mim_vest_transport_read(t, &c, &err), 1);
        assert_int_equal(c.len, 100u * (size_t)(i + 1));
        assert_memory_equal(c.data, data[i], c.len);
        assert_true(c.t_us == 1000u * (uint64_t)i + 5);
        assert_int_equal(c.restart, i == 1);
        assert_int_equal(c.kind, i == 2 ? MIM_VEST_CHUNK_LANDMARKS : MIM_VEST_CHUNK_STREAM);
    }
    assert_true(mim_now() - t0 >= 0.0018); /* the recorded 2 ms between first and last */
    mim_vest_chunk_t c;
    assert_int_equal(mim_vest_transport_read(t, &c, &err), 0);
    mim_vest_transport_close(&t);
    /* a cut file: one clear line */
    size_t len;
    free(ts_read_file(path, &len));
    assert_int_equal(ts_truncate(path, len - 50), 0);
    assert_int_equal(mim_vest_transport_open(&t, path, NULL, &err), 0);
    int rr;
    while ((rr = mim_vest_transport_read(t, &c, &err)) == 1) {
    }
    assert_int_equal(rr, MIM_ETRUNCATED);
    assert_non_null(strstr(err.msg, "cut short"));
    mim_vest_transport_close(&t);
    ts_write_file(path, "hello", 5);
    assert_int_equal(mim_vest_transport_open(&t, path, NULL, &err), MIM_EFORMAT);
    ts_rmtree(dir);
    free(path), free(dir);
}

/* ------------------------------------------------------------ the CLI */

/* Starts mimic with stdout on a pipe; returns the pid. */
static pid_t spawn_mimic(const char *const *args, FILE **out)
{
    int p[2];
    assert_int_equal(pipe(p), 0);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, p[1], 1);
    posix_spawn_file_actions_addclose(&fa, p[0]);
    int n = 0;
    while (args[n]) n++;
    char **argv = calloc((size_t)n + 2, sizeof *argv);
    argv[0] = (char *)ts_mimic_bin();
    for (int i = 0; i < n; i++) argv[i + 1] = (char *)args[i];
    pid_t pid;
    assert_int_equal(posix_spawn(&pid, argv[0], &fa, NULL, argv, environ), 0);
    posix_spawn_file_actions_destroy(&fa);
    free(argv);
    close(p[1]);
    *out = fdopen(p[0], "r");
    return pid;
}

static int wait_exit(pid_t pid)
{
    int status = 0;
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

static void test_cli_list(void **state)
{
    (void)state;
    char *out = NULL, *err = NULL;
    char *dir = ts_tempdir("vest-sysfs");
    const char *a1[] = {"vest", "list", "--no-hid", "--sysfs", dir, NULL};
    assert_int_equal(ts_run_mimic(&out, &err, a1), 0);
    assert_non_null(strstr(out, "no vest found"));
    free(out), free(err);
    /* a fake sysfs with one YOST port and one other */
    char p[4096];
    snprintf(p, sizeof p, "%s/class/tty/ttyACM3/device", dir);
    char cmd[6 * 4096 + 256];
    snprintf(cmd, sizeof cmd, "mkdir -p %s %s/class/tty/ttyUSB0/device && echo 2476 > %s/idVendor && "
             "echo 'PrioVR dongle' > %s/product && echo 0403 > %s/class/tty/ttyUSB0/device/idVendor",
             p, dir, p, p, dir);
    assert_int_equal(system(cmd), 0);
    assert_int_equal(ts_run_mimic(&out, &err, a1), 0);
    assert_non_null(strstr(out, "serial:/dev/ttyACM3"));
    assert_non_null(strstr(out, "PrioVR dongle"));
    assert_null(strstr(out, "ttyUSB0"));
    free(out), free(err);
    /* the real machine: whatever is there, it says so plainly */
    const char *a2[] = {"vest", "list", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, a2), 0);
    assert_true(strstr(out, "no vest found") || strstr(out, "serial:") || strstr(out, "hid:"));
    free(out), free(err);
    const char *a3[] = {"vest", "record", "--help", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, a3), 0);
    assert_non_null(strstr(out, "--device SPEC"));
    free(out), free(err);
    const char *a4[] = {"vest", "record", "--device", "serial:/dev/nonexistent-vest", "-o", "/tmp/x", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, a4), 1);
    assert_non_null(strstr(err, "serial /dev/nonexistent-vest: no such device"));
    free(out), free(err);
    ts_rmtree(dir);
    free(dir);
}

/* The simulator on a pty drives `mimic vest record`; `mimic vest replay`
 * then gives the frames the simulator sent and the landmarks of the motion. */
static void test_cli_record_replay(void **state)
{
    (void)state;
    char *dir = ts_tempdir("vest-cli");
    char *bvh = vs_write_bvh(dir, 31), *rec = ts_path(dir, "walk.vest"), *exp = ts_path(dir, "expected.jsonl");
    const char *sargs[] = {"vest", "simulate", "--motion", bvh, "--rate", "50", "--out", "pty", "--pose", "t",
                           "--expected", exp, NULL};
    FILE *so;
    pid_t sp = spawn_mimic(sargs, &so);
    char path[256] = "";
    assert_non_null(fgets(path, sizeof path, so));
    path[strcspn(path, "\n")] = 0;
    assert_true(!strncmp(path, "/dev/", 5));
    char dev[300];
    snprintf(dev, sizeof dev, "serial:%s", path);
    char *out = NULL, *err = NULL;
    const char *rargs[] = {"vest", "record", "--device", dev, "--duration", "2", "-o", rec, NULL};
    int rc = ts_run_mimic(&out, &err, rargs);
    if (rc) fail_msg("record: %s", err);
    assert_non_null(strstr(err, " packets in "));
    free(out), free(err);
    assert_int_equal(wait_exit(sp), 0);
    fclose(so);

    /* sensor frames: exactly what the simulator sent */
    mim_vest_sim_options_t sopt = {0};
    sopt.rate_hz = 50;
    mim_vest_motion_t m;
    mim_vest_sim_t *sim = sim_of_motion(&m, 31, &sopt);
    const char *pargs[] = {"vest", "replay", rec, NULL};
    assert_int_equal(ts_run_mimic(&out, &err, pargs), 0);
    uint64_t lines = 0, found = 0, first = UINT64_MAX;
    for (char *line = out, *nl; line && *line; line = nl) {
        nl = strchr(line, '\n');
        if (nl) *nl++ = 0;
        unsigned long long t;
        assert_int_equal(sscanf(line, "{\"t\":%llu,", &t), 1);
        uint64_t k = (uint64_t)llround((double)t * 50 / 1e6);
        if (k < first) first = k;
        mim_quat q[MIM_VEST_SEGMENTS];
        mim_vest_sim_orientations(sim, k, q, NULL, NULL);
        for (int s = 0; s < MIM_VEST_SEGMENTS; s++) {
            char key[32];
            snprintf(key, sizeof key, "{\"id\":%d,", s);
            char *at = strstr(line, key);
            if (!at) continue; /* a packet lost to a full pty queue */
            found++;
            float g[4];
            assert_int_equal(sscanf(strstr(at, "\"q\":["), "\"q\":[%g,%g,%g,%g]", &g[0], &g[1], &g[2], &g[3]), 4);
            assert_true(g[0] == (float)q[s].x && g[1] == (float)q[s].y && g[2] == (float)q[s].z && g[3] == (float)q[s].w);
        }
        lines++;
    }
    /* what the simulator sent before the recorder opened the port (a late
     * start on a busy machine) overflowed the pty and is gone, as from a
     * real port; from the first frame recorded on, the frames are there */
    assert_true(first < mim_vest_sim_n_frames(sim) / 2);
    assert_true(lines >= (mim_vest_sim_n_frames(sim) - first) * 9 / 10);
    assert_true(found >= lines * MIM_VEST_SEGMENTS * 9 / 10);
    free(out), free(err);

    /* landmarks: the forward kinematics of the motion on the avatar (the
     * simulator's --expected file, same avatar and tare pose) */
    const char *largs[] = {"vest", "replay", rec, "--avatar", "synth", "--pose", "t", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, largs), 0);
    char *want = ts_read_file(exp, NULL);
    assert_non_null(want);
    uint64_t matched = 0;
    double max_err = 0, max_deg = 0, max_truth_deg = 0;
    mim_vest_rig_t rig;
    cli_synth_rig(&rig, MIM_VEST_POSE_T);
    for (char *line = out, *nl; line && *line; line = nl) {
        nl = strchr(line, '\n');
        if (nl) *nl++ = 0;
        unsigned long long t;
        char *wl = vs_expected_line(want, line, &t);
        float g[48], e[48];
        uint8_t pg[16], pe[16];
        uint64_t tu;
        uint32_t n1, n2;
        assert_int_equal(mim_vest_udp_parse(line, strlen(line), &tu, g, pg, 16, &n1, NULL), 0);
        assert_int_equal(mim_vest_udp_parse(wl, strlen(wl), &tu, e, pe, 16, &n2, NULL), 0);
        assert_int_equal(n1, 16), assert_int_equal(n2, 16);
        for (int i = 0; i < 48; i++) max_err = fmax(max_err, fabs(g[i] - e[i]));
        /* both lines are frames for `mimic transfer --landmarks`, with the
         * orientations of the simulator's truth on this rig */
        mim_quat Rg[MIM_SEGMENTS], Re[MIM_SEGMENTS], q[MIM_SEGMENTS], Rt[MIM_SEGMENTS];
        uint8_t hg[MIM_SEGMENTS], he[MIM_SEGMENTS], have[MIM_SEGMENTS];
        assert_int_equal(vs_line_orientations(line, Rg, hg), 1);
        assert_int_equal(vs_line_orientations(wl, Re, he), 1);
        mim_vest_sim_orientations(sim, (uint64_t)llround((double)t * 50 / 1e6), q, have, NULL);
        mim_vest_segment_rotations(&rig, q, have, Rt);
        for (int s = 0; s < MIM_SEGMENTS; s++) {
            assert_int_equal(he[s], have[s]);
            assert_int_equal(hg[s], have[s]);
            if (!have[s]) continue;
            max_deg = fmax(max_deg, vs_angle_deg(Rg[s], Re[s]));
            max_truth_deg = fmax(max_truth_deg, vs_angle_deg(Re[s], Rt[s]));
        }
        free(wl);
        matched++;
    }
    assert_true(matched == lines);
    assert_true(max_err < 1e-4);
    assert_true(max_deg < 0.01);
    assert_true(max_truth_deg < 1e-4);
    free(want), free(out), free(err);
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    ts_rmtree(dir);
    free(bvh), free(rec), free(exp), free(dir);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pty_end_to_end),
        cmocka_unit_test(test_pty_disconnect),
        cmocka_unit_test(test_serial_errors),
        cmocka_unit_test(test_hid_layer),
        cmocka_unit_test(test_udp),
        cmocka_unit_test(test_record_replay_library),
        cmocka_unit_test(test_cli_list),
        cmocka_unit_test(test_cli_record_replay),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
