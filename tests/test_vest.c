/* Tests of vest/: protocol encoder and decoder (any chunking, corruption,
 * resync), calibration and forward kinematics on a synthetic avatar, motion
 * readers, the simulated vest through a real pseudo-terminal (with faults,
 * a disconnect and a reconnect), HID over a substituted device layer, UDP
 * landmark frames, `mimic vest list/record/replay/simulate`. */
#include "mim_synth.h"
#include "mim_vest.h"
#include "test_support.h"

#include <errno.h>
#include <fcntl.h>
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

/* ------------------------------------------------------------ helpers */

static uint64_t rng = 88172645463325252ull;
static uint64_t rnd(void)
{
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return rng;
}
static double rnd01(void) { return (double)(rnd() >> 11) / 9007199254740992.0; }

static void rand_quat(float q[4])
{
    double a[4], n = 0;
    for (int i = 0; i < 4; i++) a[i] = rnd01() * 2 - 1, n += a[i] * a[i];
    n = sqrt(n);
    if (n < 1e-3) a[3] = 1, n = 1;
    for (int i = 0; i < 4; i++) q[i] = (float)(a[i] / n);
}

/* A synthetic avatar (subject 0, rest pose) and its rig. */
typedef struct {
    mim_mesh_t mesh;
    mim_landmark_map_t map;
    mim_vest_skeleton_t sk;
    mim_vest_rig_t rig;
    float joints[3 * 32];
    mim_synth_t *s;
} avatar_t;

static void avatar_make(avatar_t *a, int pose)
{
    memset(a, 0, sizeof *a);
    mim_synth_options_t so = {1, 2, 3000, 1};
    mim_error_t err = {0};
    assert_int_equal(mim_synth_create(&a->s, &so, &err), 0);
    assert_int_equal(mim_mesh_alloc(&a->mesh, mim_synth_n_vertices(a->s), mim_synth_n_faces(a->s)), 0);
    memcpy(a->mesh.faces, mim_synth_faces(a->s), sizeof(uint32_t) * 3 * a->mesh.n_faces);
    assert_int_equal(mim_synth_body(a->s, 0, 0, a->mesh.positions), 0);
    assert_int_equal(mim_synth_joints(a->s, 0, 0, a->joints), 0);
    mim_synth_landmarks(a->s, &a->map);
    assert_int_equal(mim_vest_skeleton_estimate(&a->sk, &a->mesh, &a->map, &err), 0);
    mim_vest_calib_options_t co = {pose};
    assert_int_equal(mim_vest_calibrate(&a->rig, &a->sk, &co, NULL, &err), 0);
}

static void avatar_free(avatar_t *a)
{
    mim_mesh_free(&a->mesh);
    mim_synth_destroy(&a->s);
}

/* A small BVH written by the test: Y up, the body's left +X, T-pose rest;
 * arms swing, legs step, the torso turns. Centimetres, 30 frames/s. */
static char *make_bvh(int frames)
{
    static const char *hier =
        "HIERARCHY\n"
        "ROOT Hips\n{\n OFFSET 0 95 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
        " JOINT Chest\n {\n  OFFSET 0 25 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "  JOINT Head\n  {\n   OFFSET 0 30 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "   End Site\n   {\n    OFFSET 0 20 0\n   }\n  }\n"
        "  JOINT LeftShoulder\n  {\n   OFFSET 5 25 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "   JOINT LeftArm\n   {\n    OFFSET 12 0 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "    JOINT LeftForeArm\n    {\n     OFFSET 28 0 0\n     CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "     JOINT LeftHand\n     {\n      OFFSET 25 0 0\n      CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "      End Site\n      {\n       OFFSET 15 0 0\n      }\n     }\n    }\n   }\n  }\n"
        "  JOINT RightShoulder\n  {\n   OFFSET -5 25 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "   JOINT RightArm\n   {\n    OFFSET -12 0 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "    JOINT RightForeArm\n    {\n     OFFSET -28 0 0\n     CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "     JOINT RightHand\n     {\n      OFFSET -25 0 0\n      CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "      End Site\n      {\n       OFFSET -15 0 0\n      }\n     }\n    }\n   }\n  }\n }\n"
        " JOINT LeftUpLeg\n {\n  OFFSET 9 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "  JOINT LeftLeg\n  {\n   OFFSET 0 -45 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "   JOINT LeftFoot\n   {\n    OFFSET 0 -42 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "    End Site\n    {\n     OFFSET 0 -5 15\n    }\n   }\n  }\n }\n"
        " JOINT RightUpLeg\n {\n  OFFSET -9 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "  JOINT RightLeg\n  {\n   OFFSET 0 -45 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "   JOINT RightFoot\n   {\n    OFFSET 0 -42 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "    End Site\n    {\n     OFFSET 0 -5 15\n    }\n   }\n  }\n }\n}\n";
    size_t cap = strlen(hier) + 64 + (size_t)frames * 16 * 3 * 16;
    char *b = malloc(cap);
    size_t n = (size_t)snprintf(b, cap, "%sMOTION\nFrames: %d\nFrame Time: 0.033333\n", hier, frames);
    for (int f = 0; f < frames; f++) {
        double t = f / 30.0, s = sin(2 * M_PI * t), c = cos(2 * M_PI * t);
        /* joints in hierarchy order: Hips(6) Chest Head LSh LArm LFore LHand RSh RArm RFore RHand LUp LLeg LFoot RUp RLeg RFoot */
        double v[6 + 16 * 3] = {0};
        v[0] = 2 * s, v[1] = 1, v[2] = 10 * t; /* root translation: ignored by a vest */
        v[3] = 3 * s, v[4] = 5 * c, v[5] = 20 * s;   /* hips Z X Y */
        double *j = v + 6;
        j[0 * 3 + 2] = -15 * s;                    /* chest turns */
        j[1 * 3 + 1] = 10 * c;                     /* head nods */
        j[3 * 3 + 0] = -75 + 10 * s, j[3 * 3 + 1] = 30 * s; /* left arm down, swinging */
        j[4 * 3 + 1] = -20 - 20 * c;               /* left elbow */
        j[5 * 3 + 2] = 15 * s;                     /* left wrist */
        j[7 * 3 + 0] = 75 - 10 * s, j[7 * 3 + 1] = -30 * s;
        j[8 * 3 + 1] = -20 + 20 * c;
        j[10 * 3 + 1] = -25 * s;                   /* left thigh */
        j[11 * 3 + 1] = 30 + 25 * c;               /* left knee */
        j[12 * 3 + 1] = -10 * s;
        j[13 * 3 + 1] = 25 * s;
        j[14 * 3 + 1] = 30 - 25 * c;
        for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) n += (size_t)snprintf(b + n, cap - n, "%.6f ", v[i]);
        n += (size_t)snprintf(b + n, cap - n, "\n");
    }
    return b;
}

static char *write_bvh(const char *dir, int frames)
{
    char *text = make_bvh(frames), *path = ts_path(dir, "motion.bvh");
    assert_int_equal(ts_write_file(path, text, strlen(text)), 0);
    free(text);
    return path;
}

static void load_motion(mim_vest_motion_t *m, int frames)
{
    char *text = make_bvh(frames);
    mim_error_t err = {0};
    int rc = mim_vest_motion_parse_bvh(m, text, strlen(text), "test.bvh", &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, 0);
    free(text);
}

/* Collects the frames a decoder emits. */
typedef struct {
    mim_vest_frame_t *f;
    size_t n, cap;
    uint64_t packets;
} sink_t;

static void sink_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *fr, uint32_t n)
{
    sink_t *s = user;
    (void)info;
    s->packets++;
    for (uint32_t i = 0; i < n; i++) {
        if (s->n == s->cap) s->f = realloc(s->f, sizeof *s->f * (s->cap = s->cap ? 2 * s->cap : 1024));
        s->f[s->n++] = fr[i];
    }
}

/* ------------------------------------------------------------ encoder */

static void test_commands(void **state)
{
    (void)state;
    uint8_t b[64];
    assert_int_equal(mim_vest_cmd_tare(b, sizeof b, NULL), 3);
    assert_int_equal(b[0], 0xF7), assert_int_equal(b[1], 0x60), assert_int_equal(b[2], 0x60);
    mim_vest_link_t w = {1, MIM_VEST_ID_HUB, 0};
    assert_int_equal(mim_vest_cmd_start(b, sizeof b, &w), 4);
    assert_int_equal(b[0], 0xF8), assert_int_equal(b[1], 0xF0), assert_int_equal(b[2], 0x55);
    assert_int_equal(b[3], (0xF0 + 0x55) % 256);
    w.want_header = 1;
    assert_int_equal(mim_vest_cmd_stop(b, sizeof b, &w), 4);
    assert_int_equal(b[0], 0xFA), assert_int_equal(b[2], 0x56);
    mim_vest_link_t wired_h = {0, 0, 1};
    assert_int_equal(mim_vest_cmd_set_timing(b, sizeof b, &wired_h, 0x01020304u, 0xFFFFFFFFu, 0), 15);
    assert_int_equal(b[0], 0xF9), assert_int_equal(b[1], 0x52);
    assert_int_equal(b[2], 1), assert_int_equal(b[5], 4), assert_int_equal(b[6], 0xFF);
    unsigned sum = 0;
    for (int i = 1; i < 14; i++) sum += b[i];
    assert_int_equal(b[14], sum % 256);
    assert_int_equal(mim_vest_cmd_set_header(b, sizeof b, NULL, 0x5E), 7);
    assert_int_equal(b[1], 0xDD), assert_int_equal(b[5], 0x5E);
    assert_int_equal(mim_vest_cmd_set_header(b, sizeof b, &w, 0x5E), 8);
    assert_int_equal(b[2], 0xDB);
    uint8_t slots[8] = {0, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
    assert_int_equal(mim_vest_cmd_set_slots(b, sizeof b, NULL, slots), 11);
    assert_int_equal(b[1], 0x50), assert_int_equal(b[10], (0x50 + 7 * 0xFF) % 256);
    assert_int_equal(mim_vest_cmd_tare(b, 2, NULL), 0); /* no room */
    assert_true(mim_vest_cmd_stream_setup(b, sizeof b, &w, 0x5E, 16667) > 30);
    /* sizes and capacity */
    assert_int_equal(mim_vest_header_size(MIM_VEST_HDR_ALL), 13);
    assert_int_equal(mim_vest_header_size(MIM_VEST_HDR_DEFAULT), 8);
    assert_int_equal(mim_vest_hub_capacity(MIM_VEST_HDR_DEFAULT), 6);
    assert_int_equal(mim_vest_hub_capacity(MIM_VEST_HDR_ALL), 5);
}

/* ------------------------------------------------------------ decoder */

typedef struct {
    uint8_t *bytes;
    size_t n, cap;
    mim_vest_frame_t *sent;
    size_t n_sent, cap_sent;
} stream_t;

static void stream_put(stream_t *s, const void *p, size_t n)
{
    while (s->n + n > s->cap) s->bytes = realloc(s->bytes, s->cap = s->cap ? 2 * s->cap : 4096);
    memcpy(s->bytes + s->n, p, n);
    s->n += n;
}

/* Random packets with header flags f, garbage between some of them. */
static void make_stream(stream_t *s, uint32_t f, int packets, int garbage)
{
    memset(s, 0, sizeof *s);
    uint32_t cap = mim_vest_hub_capacity(f);
    uint32_t ts = 0xFFFFF000u; /* crosses the u32 wrap */
    uint64_t t64 = ts;
    for (int k = 0; k < packets; k++) {
        float q[6][4];
        mim_vest_hub_packet_t p = {0};
        p.header_flags = f, p.timestamp_us = ts, p.battery = (uint8_t)rnd(), p.status = (uint8_t)rnd();
        uint32_t ns = 1 + (uint32_t)(rnd() % cap), c = 0;
        while (c < ns) {
            uint32_t id = (uint32_t)(rnd() % 64);
            if (p.active >> id & 1) continue;
            p.active |= 1ull << id, c++;
        }
        c = 0;
        for (uint32_t id = 0; id < 64; id++)
            if (p.active >> id & 1) {
                rand_quat(q[c]);
                mim_vest_frame_t fr = {f & MIM_VEST_HDR_TIMESTAMP ? t64 : 7, id, {q[c][0], q[c][1], q[c][2], q[c][3]}, p.status};
                if (s->n_sent == s->cap_sent) s->sent = realloc(s->sent, sizeof *s->sent * (s->cap_sent = s->cap_sent ? 2 * s->cap_sent : 1024));
                s->sent[s->n_sent++] = fr;
                c++;
            }
        p.q = (const float(*)[4])q;
        uint8_t buf[MIM_VEST_MAX_PACKET];
        size_t len = mim_vest_encode_hub_packet(buf, sizeof buf, &p);
        assert_true(len > 0 && len <= MIM_VEST_MAX_PACKET);
        stream_put(s, buf, len);
        if (garbage && rnd() % 4 == 0) {
            uint8_t g[40];
            size_t gn = rnd() % sizeof g;
            for (size_t i = 0; i < gn; i++) g[i] = (uint8_t)rnd();
            stream_put(s, g, gn);
        }
        ts += 16667, t64 += 16667;
    }
}

static void feed_chunked(mim_vest_decoder_t *d, const uint8_t *b, size_t n, size_t max_chunk)
{
    for (size_t i = 0; i < n;) {
        size_t k = 1 + rnd() % max_chunk;
        if (k > n - i) k = n - i;
        mim_vest_decoder_feed(d, b + i, k, 7);
        i += k;
    }
}

static void assert_frames_equal(const mim_vest_frame_t *a, const mim_vest_frame_t *b, int check_t)
{
    assert_int_equal(a->sensor, b->sensor);
    assert_memory_equal(a->q, b->q, sizeof a->q);
    assert_int_equal(a->status, b->status);
    if (check_t) assert_true(a->t_us == b->t_us);
}

static void test_decode_chunking(void **state)
{
    (void)state;
    static const uint32_t flags[] = {MIM_VEST_HDR_DEFAULT, MIM_VEST_HDR_ALL, 0x02, 0x0A, 0x42, 0x7E};
    static const size_t chunks[] = {1, 2, 3, 7, 64, 129, 1000};
    for (size_t fi = 0; fi < sizeof flags / sizeof flags[0]; fi++)
        for (size_t ci = 0; ci < sizeof chunks / sizeof chunks[0]; ci++) {
            stream_t s;
            make_stream(&s, flags[fi], 300, 0);
            sink_t k = {0};
            mim_vest_decoder_t *d = NULL;
            mim_vest_decoder_options_t o = {.header_flags = flags[fi]};
            assert_int_equal(mim_vest_decoder_open(&d, &o, sink_packet, &k), 0);
            feed_chunked(d, s.bytes, s.n, chunks[ci]);
            assert_int_equal(k.n, s.n_sent);
            for (size_t i = 0; i < k.n; i++) assert_frames_equal(&k.f[i], &s.sent[i], 1);
            mim_vest_decoder_stats_t st;
            mim_vest_decoder_get_stats(d, &st);
            assert_int_equal(st.packets, 300);
            assert_int_equal(st.skipped_bytes, 0);
            assert_int_equal(st.bytes, s.n);
            mim_vest_decoder_close(&d);
            assert_null(d);
            free(k.f), free(s.bytes), free(s.sent);
        }
    /* garbage between packets: every packet still decoded, the garbage counted */
    stream_t s;
    make_stream(&s, MIM_VEST_HDR_DEFAULT, 500, 1);
    sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, sink_packet, &k), 0);
    feed_chunked(d, s.bytes, s.n, 50);
    assert_int_equal(k.n, s.n_sent);
    for (size_t i = 0; i < k.n; i++) assert_frames_equal(&k.f[i], &s.sent[i], 1);
    mim_vest_decoder_stats_t st;
    mim_vest_decoder_get_stats(d, &st);
    assert_true(st.skipped_bytes > 0);
    mim_vest_decoder_close(&d);
    free(k.f), free(s.bytes), free(s.sent);
}

/* Every single-byte change of a packet is caught, and the packet behind it
 * still decodes. */
static void test_decode_every_corruption(void **state)
{
    (void)state;
    stream_t s;
    make_stream(&s, MIM_VEST_HDR_DEFAULT, 2, 0);
    size_t first = 3 + 8 + 20 + 16 * (size_t)0; /* recomputed below */
    /* length of the first packet: from the first sent packet's sensor count */
    uint32_t ns0 = 0;
    for (size_t i = 0; i < s.n_sent && s.sent[i].t_us == s.sent[0].t_us; i++) ns0++;
    first = 3 + 8 + 20 + 16 * (size_t)ns0;
    int caught = 0;
    for (size_t at = 0; at < first; at++)
        for (int x = 1; x < 256; x += 37) {
            uint8_t *b = malloc(s.n);
            memcpy(b, s.bytes, s.n);
            b[at] ^= (uint8_t)x;
            sink_t k = {0};
            mim_vest_decoder_t *d = NULL;
            assert_int_equal(mim_vest_decoder_open(&d, NULL, sink_packet, &k), 0);
            mim_vest_decoder_feed(d, b, s.n, 0);
            /* more bytes come on a live link: a longer claimed length is then settled */
            uint8_t pad[300];
            memset(pad, 1, sizeof pad);
            mim_vest_decoder_feed(d, pad, sizeof pad, 0);
            /* only the second packet's frames come out */
            assert_int_equal(k.n, s.n_sent - ns0);
            /* (the u32 clock wraps between the two packets; unwrapping needs the first) */
            for (size_t i = 0; i < k.n; i++) {
                assert_frames_equal(&k.f[i], &s.sent[ns0 + i], 0);
                assert_int_equal((uint32_t)k.f[i].t_us, (uint32_t)s.sent[ns0 + i].t_us);
            }
            mim_vest_decoder_stats_t st;
            mim_vest_decoder_get_stats(d, &st);
            uint64_t rej = 0;
            for (int r = 0; r < MIM_VEST_REJ_COUNT; r++) rej += st.rejected[r];
            caught += rej > 0 || at < 3; /* a broken sync is skipped, not rejected */
            mim_vest_decoder_close(&d);
            free(k.f), free(b);
        }
    assert_true(caught > 0);
    free(s.bytes), free(s.sent);

    /* reasons: too long, bad quaternion */
    float q[7][4];
    for (int i = 0; i < 7; i++) rand_quat(q[i]);
    mim_vest_hub_packet_t p = {0};
    p.active = 0x7F, p.q = (const float(*)[4])q;
    uint8_t buf[256];
    assert_int_equal(mim_vest_encode_hub_packet(buf, sizeof buf, &p), 0); /* 7 sensors do not fit */
    p.active = 0x3F;
    size_t len = mim_vest_encode_hub_packet(buf, sizeof buf, &p);
    assert_int_equal(len, 127);
    buf[3 + 8 + 11 + 7] |= 0x40; /* claim a 7th sensor: 143 bytes, but fix the checksums? no: length rejects first */
    sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, sink_packet, &k), 0);
    mim_vest_decoder_feed(d, buf, len, 0);
    uint8_t pad[200] = {1};
    mim_vest_decoder_feed(d, pad, sizeof pad, 0);
    mim_vest_decoder_stats_t st;
    mim_vest_decoder_get_stats(d, &st);
    assert_true(st.rejected[MIM_VEST_REJ_LENGTH] >= 1);
    assert_int_equal(k.n, 0);
    mim_vest_decoder_close(&d);
    q[0][0] = 2, q[0][1] = 0, q[0][2] = 0, q[0][3] = 0; /* norm 2, checksums right */
    p.active = 1;
    len = mim_vest_encode_hub_packet(buf, sizeof buf, &p);
    assert_int_equal(mim_vest_decoder_open(&d, NULL, sink_packet, &k), 0);
    mim_vest_decoder_feed(d, buf, len, 0);
    mim_vest_decoder_get_stats(d, &st);
    assert_int_equal(st.rejected[MIM_VEST_REJ_QUATERNION], 1);
    assert_int_equal(k.n, 0);
    mim_vest_decoder_close(&d);
    free(k.f);
    assert_string_equal(mim_vest_reject_name(MIM_VEST_REJ_DATA_CHECKSUM), "data_checksum");
}

/* A wired sensor streaming by itself: header + quaternion, no sync bytes. */
static void test_decode_wired(void **state)
{
    (void)state;
    stream_t s = {0};
    float q[300][4];
    for (int k = 0; k < 300; k++) {
        rand_quat(q[k]);
        uint8_t b[64];
        size_t n = mim_vest_encode_wired_packet(b, sizeof b, MIM_VEST_HDR_DEFAULT, 1000u * (uint32_t)k, 7, q[k]);
        assert_int_equal(n, 8 + 16);
        if (k == 100) b[12] ^= 0x10; /* one corrupted packet */
        stream_put(&s, b, n);
        if (k % 50 == 3) stream_put(&s, "\x01\x02\x03", 3); /* line noise */
    }
    sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    mim_vest_decoder_options_t o = {.header_flags = MIM_VEST_HDR_DEFAULT, .wired = 1};
    assert_int_equal(mim_vest_decoder_open(&d, &o, sink_packet, &k), 0);
    feed_chunked(d, s.bytes, s.n, 40);
    assert_int_equal(k.n, 299);
    for (size_t i = 0, j = 0; i < k.n; i++, j++) {
        if (j == 100) j++;
        assert_int_equal(k.f[i].sensor, 7); /* the logical id */
        assert_true(k.f[i].t_us == 1000u * j);
        assert_memory_equal(k.f[i].q, q[j], sizeof q[j]);
    }
    mim_vest_decoder_stats_t st;
    mim_vest_decoder_get_stats(d, &st);
    assert_true(st.rejected[MIM_VEST_REJ_DATA_CHECKSUM] + st.rejected[MIM_VEST_REJ_HEADER] +
                st.rejected[MIM_VEST_REJ_LENGTH] + st.rejected[MIM_VEST_REJ_QUATERNION] > 0);
    mim_vest_decoder_close(&d);
    free(k.f), free(s.bytes);
}

/* ------------------------------------------------------------ skeleton, calibration, kinematics */

static double dist3(mim_vec3 a, const float *b) { return mim_v3_norm(mim_v3_sub(a, mim_v3(b[0], b[1], b[2]))); }

static int synth_joint(const avatar_t *a, const char *name)
{
    for (uint32_t j = 0; j < mim_synth_n_joints(a->s); j++)
        if (!strcmp(mim_synth_joint_name(a->s, j), name)) return (int)j;
    fail_msg("no synth joint %s", name);
    return -1;
}

static void test_skeleton_synth(void **state)
{
    (void)state;
    avatar_t a;
    avatar_make(&a, MIM_VEST_POSE_REST);
    /* joint centres under the landmarks against the generator's own joints */
    static const struct { int seg; const char *joint; double tol; } pv[] = {
        {MIM_VEST_L_UPPERARM, "l_upperarm", 0.05}, {MIM_VEST_L_FOREARM, "l_forearm", 0.04},
        {MIM_VEST_L_HAND, "l_hand", 0.04},         {MIM_VEST_L_SHIN, "l_shin", 0.04},
        {MIM_VEST_L_FOOT, "l_foot", 0.05},         {MIM_VEST_L_THIGH, "l_thigh", 0.06},
        {MIM_VEST_R_FOREARM, "r_forearm", 0.04},   {MIM_VEST_R_SHIN, "r_shin", 0.04}};
    for (size_t i = 0; i < sizeof pv / sizeof pv[0]; i++) {
        double d = dist3(a.sk.pivot[pv[i].seg], a.joints + 3 * synth_joint(&a, pv[i].joint));
        if (d > pv[i].tol) fail_msg("%s pivot %.3f m from the synth joint", pv[i].joint, d);
    }
    /* left and right mirror each other */
    for (int s = MIM_VEST_L_SHOULDER; s < MIM_VEST_SEGMENTS; s += 2) {
        mim_vec3 l = a.sk.pivot[s], r = a.sk.pivot[s + 1];
        assert_true(fabs(l.x + r.x) < 0.01 && fabs(l.y - r.y) < 0.01 && fabs(l.z - r.z) < 0.01);
        assert_true(l.x >= 0);
        assert_true(fabs(a.sk.length[s] - a.sk.length[s + 1]) < 0.01);
    }
    assert_true(a.sk.length[MIM_VEST_L_UPPERARM] > 0.2 && a.sk.length[MIM_VEST_L_UPPERARM] < 0.4);
    assert_true(a.sk.length[MIM_VEST_L_SHIN] > 0.3 && a.sk.length[MIM_VEST_L_SHIN] < 0.5);
    assert_int_equal(a.sk.segment[5], MIM_VEST_L_UPPERARM); /* l_elbow */
    assert_int_equal(a.sk.segment[13], MIM_VEST_L_SHIN);    /* l_ankle */
    /* a map without a needed landmark is refused with its name */
    mim_landmark_map_t bad = a.map;
    snprintf(bad.names[5], sizeof bad.names[5], "elbow_l");
    mim_vest_skeleton_t sk;
    mim_error_t err = {0};
    assert_int_equal(mim_vest_skeleton_estimate(&sk, &a.mesh, &bad, &err), MIM_ENOLANDMARKS);
    assert_non_null(strstr(err.msg, "l_elbow"));
    avatar_free(&a);
}

static void test_fk(void **state)
{
    (void)state;
    avatar_t a;
    avatar_make(&a, MIM_VEST_POSE_REST);
    uint32_t n = a.rig.n_landmarks;
    float xyz[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX];
    mim_quat q[MIM_VEST_SEGMENTS];
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) q[s] = mim_quat_identity();
    /* identity readings, rest calibration: the avatar's own landmarks */
    assert_int_equal(mim_vest_fk_orient(&a.rig, q, NULL, xyz, present), n);
    for (uint32_t i = 0; i < n; i++) assert_true(dist3(a.sk.landmark[i], xyz + 3 * i) < 1e-5);
    /* every sensor turned the same way: the body turns rigidly about the pelvis */
    mim_quat R = mim_quat_axis_angle(mim_v3_normalize(mim_v3(0.3, 1, -0.2)), 1.1);
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) q[s] = R;
    mim_vest_fk_orient(&a.rig, q, NULL, xyz, present);
    for (uint32_t i = 0; i < n; i++) {
        mim_vec3 want = mim_v3_add(a.rig.root, mim_quat_rotate(R, mim_v3_sub(a.sk.landmark[i], a.rig.root)));
        assert_true(dist3(want, xyz + 3 * i) < 1e-5);
    }
    /* bending the left elbow moves only the left wrist, about the elbow */
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) q[s] = mim_quat_identity();
    q[MIM_VEST_L_FOREARM] = mim_quat_axis_angle(mim_v3(1, 0, 0), -1.2);
    mim_vest_fk_orient(&a.rig, q, NULL, xyz, present);
    for (uint32_t i = 0; i < n; i++) {
        double d = dist3(a.sk.landmark[i], xyz + 3 * i);
        if (i == 7) assert_true(d > 0.05);
        else assert_true(d < 1e-5);
    }
    mim_vec3 el = a.sk.pivot[MIM_VEST_L_FOREARM];
    assert_true(fabs(dist3(el, xyz + 21) - mim_v3_norm(mim_v3_sub(a.sk.landmark[7], el))) < 1e-5);
    /* a software tare: readings relative to the tare give the same pose */
    mim_quat tare[MIM_VEST_SEGMENTS], q2[MIM_VEST_SEGMENTS];
    mim_vest_rig_t rig2;
    mim_vest_calib_options_t co = {MIM_VEST_POSE_REST};
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) {
        tare[s] = mim_quat_axis_angle(mim_v3_normalize(mim_v3(s, 1, 2)), 0.1 * s);
        q2[s] = mim_quat_mul(q[s], tare[s]);
    }
    assert_int_equal(mim_vest_calibrate(&rig2, &a.sk, &co, tare, NULL), 0);
    float xyz2[3 * MIM_LANDMARKS_MAX];
    mim_vest_fk_orient(&rig2, q2, NULL, xyz2, present);
    for (uint32_t i = 0; i < 3 * n; i++) assert_true(fabs(xyz[i] - xyz2[i]) < 1e-5);
    /* T-pose calibration: at the tare, the arms are straight out sideways */
    avatar_t t;
    avatar_make(&t, MIM_VEST_POSE_T);
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) q[s] = mim_quat_identity();
    mim_vest_fk_orient(&t.rig, q, NULL, xyz, present);
    for (int side = 0; side < 2; side++) {
        const float *sh = xyz + 3 * (3 + side), *wr = xyz + 3 * (7 + side);
        assert_true(fabs(wr[1] - sh[1]) < 0.08);               /* wrist at shoulder height */
        assert_true((side ? -1 : 1) * (wr[0] - sh[0]) > 0.4);  /* far out on its side */
    }
    avatar_free(&t);
    avatar_free(&a);
}

static void test_missing_sensor(void **state)
{
    (void)state;
    avatar_t a;
    avatar_make(&a, MIM_VEST_POSE_REST);
    mim_vest_state_t st;
    mim_vest_state_reset(&st);
    float xyz[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX];
    assert_int_equal(mim_vest_fk(&a.rig, &st, 0, 0, xyz, present), 0); /* nothing yet */
    for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
        mim_vest_frame_t f = {1000000, s, {0, 0, 0, 1}, 0};
        mim_vest_state_update(&st, &f);
    }
    assert_int_equal(mim_vest_fk(&a.rig, &st, 1000000, 0, xyz, present), 16);
    /* everyone reports again at 1.5 s but the left upper arm */
    for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
        if (s == MIM_VEST_L_UPPERARM) continue;
        mim_vest_frame_t f = {1500000, s, {0, 0, 0, 1}, 0};
        mim_vest_state_update(&st, &f);
    }
    assert_int_equal(mim_vest_fk(&a.rig, &st, 1500000, 0, xyz, present), 14);
    assert_int_equal(present[5], 0), assert_int_equal(present[7], 0); /* l_elbow, l_wrist */
    assert_true(isnan(xyz[15]) && isnan(xyz[21]));
    assert_int_equal(present[6], 1), assert_int_equal(present[8], 1);
    /* within the timeout it still counts */
    assert_int_equal(mim_vest_fk(&a.rig, &st, 1500000, 600000, xyz, present), 16);
    /* the pelvis gone: nothing can be placed */
    st.t_us[MIM_VEST_PELVIS] = 0;
    assert_int_equal(mim_vest_fk(&a.rig, &st, 1500000, 0, xyz, present), 0);
    avatar_free(&a);
}

static void test_assembler(void **state)
{
    (void)state;
    mim_vest_assembler_t as = {0};
    uint64_t t[2], m[2];
    mim_vest_packet_info_t p = {0};
    p.t_us = 10, p.active = 0x3F;
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 0);
    p.active = 0x0FC0;
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 0); /* first frame: size unknown */
    p.t_us = 20, p.active = 0x3F;
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 1);
    assert_true(t[0] == 10 && m[0] == 0x0FFF);
    p.active = 0x0FC0;
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 1); /* complete: no wait */
    assert_true(t[0] == 20 && m[0] == 0x0FFF);
    p.t_us = 30, p.active = 0x3F; /* a sensor group goes silent */
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 0);
    p.t_us = 40; /* closes 30 late, and 40 is complete at once with the smaller set */
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 2);
    assert_true(t[0] == 30 && m[0] == 0x3F && t[1] == 40 && m[1] == 0x3F);
    assert_int_equal(mim_vest_assembler_flush(&as, t, m), 0);
    p.t_us = 35; /* late: ignored */
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 0);
    p.t_us = 50, p.active = 0x0FC0;
    assert_int_equal(mim_vest_assembler_push(&as, &p, t, m), 0);
    assert_int_equal(mim_vest_assembler_flush(&as, t, m), 1);
    assert_true(t[0] == 50 && m[0] == 0x0FC0);
}

/* ------------------------------------------------------------ motion */

static void test_motion_bvh(void **state)
{
    (void)state;
    mim_vest_motion_t m;
    load_motion(&m, 31);
    assert_int_equal(m.n_frames, 31);
    assert_true(fabs(m.frame_time - 0.033333) < 1e-9);
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) assert_int_equal(m.have[s], 1);
    assert_string_equal(m.joint[MIM_VEST_L_UPPERARM], "LeftArm");
    assert_true(m.rest_arm_deg > 85 && m.rest_arm_deg < 95); /* T-pose rest */
    /* frame 0: left arm Zrotation -75 about the hips' rotation (all zero at t=0 but Xrot 5) */
    mim_quat hips = mim_quat_axis_angle(mim_v3(1, 0, 0), 5 * M_PI / 180);
    mim_quat q0 = m.q[MIM_VEST_PELVIS];
    assert_true(fabs(fabs(q0.x * hips.x + q0.y * hips.y + q0.z * hips.z + q0.w * hips.w) - 1) < 1e-9);
    /* the left upper arm's world rotation takes +X (the rest arm) down */
    mim_vec3 arm = mim_quat_rotate(m.q[MIM_VEST_L_UPPERARM], mim_v3(1, 0, 0));
    assert_true(arm.y < -0.9);
    mim_vec3 rarm = mim_quat_rotate(m.q[MIM_VEST_R_UPPERARM], mim_v3(-1, 0, 0));
    assert_true(rarm.y < -0.9);
    mim_vest_motion_free(&m);

    /* the same motion with Z up: the axes are mapped back to Y up */
    char *text = make_bvh(3);
    mim_error_t err = {0};
    char *bad = strdup("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0\n");
    assert_int_equal(mim_vest_motion_parse_bvh(&m, bad, strlen(bad), "tiny.bvh", &err), MIM_EFORMAT);
    assert_non_null(strstr(err.msg, "head"));
    free(bad);
    /* truncated */
    mim_error_clear(&err);
    assert_true(mim_vest_motion_parse_bvh(&m, text, strlen(text) - 30, "cut.bvh", &err) < 0);
    assert_non_null(strstr(err.msg, "cut.bvh:"));
    free(text);
}

static void test_motion_shared(void **state)
{
    (void)state;
    char p1[4096], p2[4096];
    snprintf(p1, sizeof p1, "%s/makehuman-motion/animations/walk1.bvh", ts_shared_data());
    if (access(p1, R_OK)) skip();
    mim_vest_motion_t m;
    mim_error_t err = {0};
    int rc = mim_vest_motion_read_bvh(&m, p1, &err);
    if (rc) fail_msg("%s", err.msg);
    assert_true(m.n_frames > 1);
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) assert_int_equal(m.have[s], 1);
    assert_true(m.rest_arm_deg > 60); /* MakeHuman's rest pose holds the arms out */
    mim_vest_motion_free(&m);
    snprintf(p1, sizeof p1, "%s/cmu-mocap/20.asf", ts_shared_data());
    snprintf(p2, sizeof p2, "%s/cmu-mocap/20_11.amc", ts_shared_data());
    if (access(p1, R_OK) || access(p2, R_OK)) return;
    rc = mim_vest_motion_read_amc(&m, p1, p2, &err);
    if (rc) fail_msg("%s", err.msg);
    assert_true(m.n_frames > 100);
    assert_int_equal(m.have[MIM_VEST_L_FOREARM], 1);
    assert_int_equal(m.have[MIM_VEST_HEAD], 1);
    assert_string_equal(m.joint[MIM_VEST_L_THIGH], "lfemur");
    /* walking: the shin swings, and all rotations are unit */
    double lo = 1, hi = -1;
    for (uint32_t f = 0; f < m.n_frames; f++) {
        mim_quat q = m.q[(size_t)f * MIM_VEST_SEGMENTS + MIM_VEST_L_SHIN];
        assert_true(fabs(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w - 1) < 1e-9);
        lo = fmin(lo, q.w), hi = fmax(hi, q.w);
    }
    assert_true(hi - lo > 0.01);
    mim_vest_motion_free(&m);
}

/* ------------------------------------------------------------ simulator: faults */

/* The simulator's packets with 5 % corrupted: every intact packet decodes,
 * no corrupted one does, and >= 95 % of vest frames come out. */
static void test_corruption_5pct(void **state)
{
    (void)state;
    mim_vest_motion_t m;
    load_motion(&m, 61);
    mim_vest_sim_options_t clean_o = {0}, bad_o = {0};
    bad_o.corrupt = 0.05, bad_o.seed = 42;
    mim_vest_sim_t *clean = NULL, *bad = NULL;
    assert_int_equal(mim_vest_sim_open(&clean, &m, &clean_o, NULL), 0);
    assert_int_equal(mim_vest_sim_open(&bad, &m, &bad_o, NULL), 0);
    uint64_t frames = 1500; /* past the motion's end: the last frame repeats */
    stream_t s = {0};
    size_t want_frames = 0, corrupted_packets = 0, packets = 0;
    mim_vest_frame_t *want = calloc(frames * MIM_VEST_SEGMENTS, sizeof *want);
    uint8_t *frame_ok = calloc(frames, 1);
    for (uint64_t k = 0; k < frames; k++) {
        uint8_t a[1024], b[1024];
        uint32_t counts[3] = {0};
        size_t na = mim_vest_sim_frame(clean, k, a, sizeof a, NULL);
        size_t nb = mim_vest_sim_frame(bad, k, b, sizeof b, counts);
        assert_int_equal(na, nb);
        /* split at the clean packet boundaries; a packet that differs is lost */
        mim_quat q[MIM_VEST_SEGMENTS];
        uint64_t t;
        mim_vest_sim_orientations(clean, k, q, NULL, &t);
        size_t off = 0;
        while (off < na) {
            size_t len = 3 + 8 + 20;
            uint64_t act = 0;
            for (int i = 0; i < 8; i++) act = act << 8 | a[off + 3 + 8 + 11 + i];
            len += 16 * (size_t)__builtin_popcountll(act);
            packets++;
            int hit = memcmp(a + off, b + off, len) != 0;
            corrupted_packets += hit;
            for (uint32_t id = 0; id < MIM_VEST_SEGMENTS; id++) {
                if (!(act >> id & 1) || hit) continue;
                mim_vest_frame_t f = {t, id, {(float)q[id].x, (float)q[id].y, (float)q[id].z, (float)q[id].w}, 0};
                want[want_frames++] = f;
                frame_ok[k] = 1;
            }
            off += len;
        }
        assert_int_equal(counts[0], 3);
        stream_put(&s, b, nb);
    }
    double frac = (double)corrupted_packets / (double)packets;
    assert_true(frac > 0.03 && frac < 0.07);
    sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, sink_packet, &k), 0);
    feed_chunked(d, s.bytes, s.n, 200);
    assert_int_equal(k.n, want_frames);
    for (size_t i = 0; i < k.n; i++) assert_frames_equal(&k.f[i], &want[i], 1);
    size_t ok = 0;
    for (uint64_t i = 0; i < frames; i++) ok += frame_ok[i];
    assert_true((double)ok / (double)frames >= 0.95);
    /* the decoder's frames are what the motion gives */
    mim_vest_decoder_close(&d);
    free(k.f), free(s.bytes), free(want), free(frame_ok);
    mim_vest_sim_close(&clean), mim_vest_sim_close(&bad);
    mim_vest_motion_free(&m);
}

/* ------------------------------------------------------------ through a pty */

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

/* Reads a transport to its end (replay) or until it gives up (live). */
static int drain(mim_vest_transport_t *t, live_t *L, mim_vest_decoder_t *d, int stop_on_timeout)
{
    for (;;) {
        mim_vest_chunk_t c;
        mim_error_t err = {0};
        int r = mim_vest_transport_read(t, &c, &err);
        if (r == 0) return 0;
        if (r == -ETIMEDOUT && !stop_on_timeout) continue;
        if (r < 0) return r;
        if (c.restart) mim_vest_decoder_reset(d);
        mim_vest_decoder_feed(d, c.data, c.len, c.t_us);
    }
    (void)L;
}

static void test_pty_end_to_end(void **state)
{
    (void)state;
    avatar_t a;
    avatar_make(&a, MIM_VEST_POSE_T);
    mim_vest_motion_t m;
    load_motion(&m, 31); /* one second */
    mim_vest_sim_options_t so = {0};
    so.rate_hz = 100;
    mim_vest_sim_t *sim = NULL;
    assert_int_equal(mim_vest_sim_open(&sim, &m, &so, NULL), 0);
    simthread_t st;
    pthread_t th;
    sim_start(&st, &th, sim, "pty", NULL);
    char spec[300];
    snprintf(spec, sizeof spec, "serial:%s", st.path);
    mim_vest_transport_options_t to = {0};
    to.timeout_ms = 300, to.reconnect_limit_ms = 300, to.backoff_min_ms = 10;
    mim_vest_transport_t *t = NULL;
    mim_error_t err = {0};
    int rc = mim_vest_transport_open(&t, spec, &to, &err);
    if (rc) fail_msg("%s", err.msg);
    live_t L;
    memset(&L, 0, sizeof L);
    L.rig = &a.rig, L.sim = sim;
    mim_vest_state_reset(&L.st);
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, live_packet, &L), 0);
    rc = drain(t, &L, d, 0);
    assert_int_equal(rc, -ENODEV); /* the simulator has gone */
    uint64_t tl, ml;
    if (mim_vest_assembler_flush(&L.as, &tl, &ml)) live_check(&L, tl, ml);
    pthread_join(th, NULL);
    assert_int_equal(st.rc, 0);
    /* the frames through (a pty queue that overflows on a loaded machine
     * drops bytes, as a real port does), landmarks equal to the motion's
     * forward kinematics */
    assert_true(L.frames >= mim_vest_sim_n_frames(sim) * 9 / 10);
    assert_true(L.checked >= L.frames * 16 * 9 / 10);
    assert_true(L.max_err < 1e-4);
    mim_vest_decoder_close(&d);
    mim_vest_transport_close(&t);
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    avatar_free(&a);
}

static void test_pty_disconnect(void **state)
{
    (void)state;
    avatar_t a;
    avatar_make(&a, MIM_VEST_POSE_T);
    mim_vest_motion_t m;
    load_motion(&m, 46); /* 1.5 s */
    mim_vest_sim_options_t so = {0};
    so.disconnect_at = 0.5, so.disconnect_for = 0.3;
    mim_vest_sim_t *sim = NULL;
    assert_int_equal(mim_vest_sim_open(&sim, &m, &so, NULL), 0);
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
    mim_vest_transport_t *t = NULL;
    mim_error_t err = {0};
    int rc = mim_vest_transport_open(&t, spec, &to, &err);
    if (rc) fail_msg("%s", err.msg);
    live_t L;
    memset(&L, 0, sizeof L);
    L.rig = &a.rig, L.sim = sim;
    mim_vest_state_reset(&L.st);
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, live_packet, &L), 0);
    rc = drain(t, &L, d, 0);
    assert_int_equal(rc, -ENODEV); /* after the stream ended for good */
    pthread_join(th, NULL);
    assert_int_equal(st.rc, 0);
    assert_true(mim_vest_transport_reconnects(t) >= 1);
    /* frames from before and after the outage, all right */
    assert_true(L.first_t < 500000);
    assert_true(L.last_t > 1000000);
    assert_true(L.frames > 40);
    assert_true(L.max_err < 1e-4);
    mim_vest_decoder_close(&d);
    mim_vest_transport_close(&t);
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    avatar_free(&a);
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
    size_t k = 1 + (size_t)(rnd() % 63);
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
    stream_t s;
    make_stream(&s, MIM_VEST_HDR_DEFAULT, 200, 0);
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
    sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, sink_packet, &k), 0);
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
        assert_frames_equal(&k.f[i], &s.sent[j], 1);
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

    /* the simulator sends landmark frames; the UDP transport receives them */
    avatar_t a;
    avatar_make(&a, MIM_VEST_POSE_T);
    mim_vest_motion_t m;
    load_motion(&m, 16);
    mim_vest_sim_options_t so = {0};
    so.rate_hz = 100;
    mim_vest_sim_t *sim = NULL;
    assert_int_equal(mim_vest_sim_open(&sim, &m, &so, NULL), 0);
    mim_vest_transport_t *tr = NULL;
    mim_vest_transport_options_t to = {0};
    to.timeout_ms = 500;
    int port = 0, rc = -1;
    char spec[64], out[64];
    for (int tries = 0; tries < 20 && rc; tries++) {
        port = 20000 + (int)(rnd() % 30000);
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
        frames++;
    }
    pthread_join(th, NULL);
    assert_int_equal(st.rc, 0);
    assert_true(frames >= mim_vest_sim_n_frames(sim) * 9 / 10);
    assert_true(max_err < 1e-4);
    mim_vest_transport_close(&tr);
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    avatar_free(&a);
}

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
        for (int j = 0; j < 300; j++) data[i][j] = (uint8_t)rnd();
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
    char *bvh = write_bvh(dir, 31), *rec = ts_path(dir, "walk.vest"), *exp = ts_path(dir, "expected.jsonl");
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
    mim_vest_motion_t m;
    load_motion(&m, 31);
    mim_vest_sim_options_t sopt = {0};
    sopt.rate_hz = 50;
    mim_vest_sim_t *sim = NULL;
    assert_int_equal(mim_vest_sim_open(&sim, &m, &sopt, NULL), 0);
    const char *pargs[] = {"vest", "replay", rec, NULL};
    assert_int_equal(ts_run_mimic(&out, &err, pargs), 0);
    uint64_t lines = 0, found = 0;
    for (char *line = out, *nl; line && *line; line = nl) {
        nl = strchr(line, '\n');
        if (nl) *nl++ = 0;
        unsigned long long t;
        assert_int_equal(sscanf(line, "{\"t\":%llu,", &t), 1);
        uint64_t k = (uint64_t)llround((double)t * 50 / 1e6);
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
    assert_true(lines >= mim_vest_sim_n_frames(sim) * 9 / 10);
    assert_true(found >= lines * MIM_VEST_SEGMENTS * 9 / 10);
    free(out), free(err);

    /* landmarks: the forward kinematics of the motion on the avatar (the
     * simulator's --expected file, same avatar and tare pose) */
    const char *largs[] = {"vest", "replay", rec, "--avatar", "synth", "--pose", "t", NULL};
    assert_int_equal(ts_run_mimic(&out, &err, largs), 0);
    char *want = ts_read_file(exp, NULL);
    assert_non_null(want);
    uint64_t matched = 0;
    double max_err = 0;
    for (char *line = out, *nl; line && *line; line = nl) {
        nl = strchr(line, '\n');
        if (nl) *nl++ = 0;
        unsigned long long t;
        assert_int_equal(sscanf(line, "{\"t\":%llu,", &t), 1);
        char key[64];
        snprintf(key, sizeof key, "{\"t\":%llu,", t);
        char *w = strstr(want, key);
        assert_non_null(w);
        char *wl = strndup(w, strcspn(w, "\n"));
        float g[48], e[48];
        uint8_t pg[16], pe[16];
        uint64_t tu;
        uint32_t n1, n2;
        assert_int_equal(mim_vest_udp_parse(line, strlen(line), &tu, g, pg, 16, &n1, NULL), 0);
        assert_int_equal(mim_vest_udp_parse(wl, strlen(wl), &tu, e, pe, 16, &n2, NULL), 0);
        assert_int_equal(n1, 16), assert_int_equal(n2, 16);
        for (int i = 0; i < 48; i++) max_err = fmax(max_err, fabs(g[i] - e[i]));
        free(wl);
        matched++;
    }
    assert_true(matched == lines);
    assert_true(max_err < 1e-4);
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
        cmocka_unit_test(test_commands),
        cmocka_unit_test(test_decode_chunking),
        cmocka_unit_test(test_decode_every_corruption),
        cmocka_unit_test(test_decode_wired),
        cmocka_unit_test(test_skeleton_synth),
        cmocka_unit_test(test_fk),
        cmocka_unit_test(test_missing_sensor),
        cmocka_unit_test(test_assembler),
        cmocka_unit_test(test_motion_bvh),
        cmocka_unit_test(test_motion_shared),
        cmocka_unit_test(test_corruption_5pct),
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
