/* Tests of vest/ without devices: protocol encoder and decoder (any
 * chunking, corruption, resync), skeleton, calibration and forward
 * kinematics on a synthetic avatar, the frame assembler, motion readers,
 * and the simulator's fault injection (orientation noise and drift too). */
#include "vest_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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

/* Feeds b in random chunks of 1..max_chunk bytes. */
static void feed_chunked(mim_vest_decoder_t *d, const uint8_t *b, size_t n, size_t max_chunk)
{
    for (size_t i = 0; i < n;) {
        size_t k = 1 + vs_rnd() % max_chunk;
        if (k > n - i) k = n - i;
        mim_vest_decoder_feed(d, b + i, k, 7);
        i += k;
    }
}

static void test_decode_chunking(void **state)
{
    (void)state;
    static const uint32_t flags[] = {MIM_VEST_HDR_DEFAULT, MIM_VEST_HDR_ALL, 0x02, 0x0A, 0x42, 0x7E};
    static const size_t chunks[] = {1, 2, 3, 7, 64, 129, 1000};
    for (size_t fi = 0; fi < sizeof flags / sizeof flags[0]; fi++)
        for (size_t ci = 0; ci < sizeof chunks / sizeof chunks[0]; ci++) {
            vs_stream_t s;
            vs_make_stream(&s, flags[fi], 300, 0);
            vs_sink_t k = {0};
            mim_vest_decoder_t *d = NULL;
            mim_vest_decoder_options_t o = {.header_flags = flags[fi]};
            assert_int_equal(mim_vest_decoder_open(&d, &o, vs_sink_packet, &k), 0);
            feed_chunked(d, s.bytes, s.n, chunks[ci]);
            assert_int_equal(k.n, s.n_sent);
            for (size_t i = 0; i < k.n; i++) vs_assert_frames_equal(&k.f[i], &s.sent[i], 1);
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
    vs_stream_t s;
    vs_make_stream(&s, MIM_VEST_HDR_DEFAULT, 500, 1);
    vs_sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, vs_sink_packet, &k), 0);
    feed_chunked(d, s.bytes, s.n, 50);
    assert_int_equal(k.n, s.n_sent);
    for (size_t i = 0; i < k.n; i++) vs_assert_frames_equal(&k.f[i], &s.sent[i], 1);
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
    vs_stream_t s;
    vs_make_stream(&s, MIM_VEST_HDR_DEFAULT, 2, 0);
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
            vs_sink_t k = {0};
            mim_vest_decoder_t *d = NULL;
            assert_int_equal(mim_vest_decoder_open(&d, NULL, vs_sink_packet, &k), 0);
            mim_vest_decoder_feed(d, b, s.n, 0);
            /* more bytes come on a live link: a longer claimed length is then settled */
            uint8_t pad[300];
            memset(pad, 1, sizeof pad);
            mim_vest_decoder_feed(d, pad, sizeof pad, 0);
            /* only the second packet's frames come out */
            assert_int_equal(k.n, s.n_sent - ns0);
            /* (the u32 clock wraps between the two packets; unwrapping needs the first) */
            for (size_t i = 0; i < k.n; i++) {
                vs_assert_frames_equal(&k.f[i], &s.sent[ns0 + i], 0);
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
    for (int i = 0; i < 7; i++) vs_rand_quat(q[i]);
    mim_vest_hub_packet_t p = {0};
    p.active = 0x7F, p.q = (const float(*)[4])q;
    uint8_t buf[256];
    assert_int_equal(mim_vest_encode_hub_packet(buf, sizeof buf, &p), 0); /* 7 sensors do not fit */
    p.active = 0x3F;
    size_t len = mim_vest_encode_hub_packet(buf, sizeof buf, &p);
    assert_int_equal(len, 127);
    buf[3 + 8 + 11 + 7] |= 0x40; /* claim a 7th sensor: 143 bytes, but fix the checksums? no: length rejects first */
    vs_sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, vs_sink_packet, &k), 0);
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
    assert_int_equal(mim_vest_decoder_open(&d, NULL, vs_sink_packet, &k), 0);
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
    vs_stream_t s = {0};
    float q[300][4];
    for (int k = 0; k < 300; k++) {
        vs_rand_quat(q[k]);
        uint8_t b[64];
        size_t n = mim_vest_encode_wired_packet(b, sizeof b, MIM_VEST_HDR_DEFAULT, 1000u * (uint32_t)k, 7, q[k]);
        assert_int_equal(n, 8 + 16);
        if (k == 100) b[12] ^= 0x10; /* one corrupted packet */
        vs_stream_put(&s, b, n);
        if (k % 50 == 3) vs_stream_put(&s, "\x01\x02\x03", 3); /* line noise */
    }
    vs_sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    mim_vest_decoder_options_t o = {.header_flags = MIM_VEST_HDR_DEFAULT, .wired = 1};
    assert_int_equal(mim_vest_decoder_open(&d, &o, vs_sink_packet, &k), 0);
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

static int synth_joint(const vs_avatar_t *a, const char *name)
{
    for (uint32_t j = 0; j < mim_synth_n_joints(a->s); j++)
        if (!strcmp(mim_synth_joint_name(a->s, j), name)) return (int)j;
    fail_msg("no synth joint %s", name);
    return -1;
}

static void test_skeleton_synth(void **state)
{
    (void)state;
    vs_avatar_t a;
    vs_avatar_make(&a, MIM_VEST_POSE_REST);
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
    vs_avatar_free(&a);
}

static void test_fk(void **state)
{
    (void)state;
    vs_avatar_t a;
    vs_avatar_make(&a, MIM_VEST_POSE_REST);
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
    vs_avatar_t t;
    vs_avatar_make(&t, MIM_VEST_POSE_T);
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) q[s] = mim_quat_identity();
    mim_vest_fk_orient(&t.rig, q, NULL, xyz, present);
    for (int side = 0; side < 2; side++) {
        const float *sh = xyz + 3 * (3 + side), *wr = xyz + 3 * (7 + side);
        assert_true(fabs(wr[1] - sh[1]) < 0.08);               /* wrist at shoulder height */
        assert_true((side ? -1 : 1) * (wr[0] - sh[0]) > 0.4);  /* far out on its side */
    }
    vs_avatar_free(&t);
    vs_avatar_free(&a);
}

static void test_missing_sensor(void **state)
{
    (void)state;
    vs_avatar_t a;
    vs_avatar_make(&a, MIM_VEST_POSE_REST);
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
    vs_avatar_free(&a);
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
    vs_load_motion(&m, 31);
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
    char *text = vs_make_bvh(3);
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
    vs_load_motion(&m, 61);
    mim_vest_sim_options_t clean_o = {0}, bad_o = {0};
    bad_o.corrupt = 0.05, bad_o.seed = 42;
    mim_vest_sim_t *clean = NULL, *bad = NULL;
    assert_int_equal(mim_vest_sim_open(&clean, &m, &clean_o, NULL), 0);
    assert_int_equal(mim_vest_sim_open(&bad, &m, &bad_o, NULL), 0);
    uint64_t frames = 1500; /* past the motion's end: the last frame repeats */
    vs_stream_t s = {0};
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
        vs_stream_put(&s, b, nb);
    }
    double frac = (double)corrupted_packets / (double)packets;
    assert_true(frac > 0.03 && frac < 0.07);
    vs_sink_t k = {0};
    mim_vest_decoder_t *d = NULL;
    assert_int_equal(mim_vest_decoder_open(&d, NULL, vs_sink_packet, &k), 0);
    feed_chunked(d, s.bytes, s.n, 200);
    assert_int_equal(k.n, want_frames);
    for (size_t i = 0; i < k.n; i++) vs_assert_frames_equal(&k.f[i], &want[i], 1);
    size_t ok = 0;
    for (uint64_t i = 0; i < frames; i++) ok += frame_ok[i];
    assert_true((double)ok / (double)frames >= 0.95);
    /* the decoder's frames are what the motion gives */
    mim_vest_decoder_close(&d);
    free(k.f), free(s.bytes), free(want), free(frame_ok);
    mim_vest_sim_close(&clean), mim_vest_sim_close(&bad);
    mim_vest_motion_free(&m);
}

/* The angle between two orientations, in degrees (atan2 of a b^-1: acos
 * near 1 would turn float rounding into hundredths of a degree). */
static double angle_deg(mim_quat a, mim_quat b)
{
    mim_quat d = mim_quat_mul(a, (mim_quat){-b.x, -b.y, -b.z, b.w});
    return 2 * atan2(sqrt(d.x * d.x + d.y * d.y + d.z * d.z), fabs(d.w)) * 180 / M_PI;
}

/* orient-noise: the wire's orientations are the truth turned by about the
 * set angle (a Gaussian's mean |angle| is 0.8 sigma), the same for every
 * call; the packets carry them; drop and corrupt decide as without noise;
 * and with no noise the wire is the truth, byte for byte. */
static void test_orient_noise(void **state)
{
    (void)state;
    mim_vest_motion_t m;
    vs_load_motion(&m, 61);
    mim_vest_sim_options_t plain_o = {0}, noisy_o = {0};
    plain_o.drop = noisy_o.drop = 0.05, plain_o.corrupt = noisy_o.corrupt = 0.05;
    plain_o.seed = noisy_o.seed = 9;
    noisy_o.orient_noise_deg = 5;
    mim_vest_sim_t *plain = NULL, *noisy = NULL, *noisy2 = NULL;
    assert_int_equal(mim_vest_sim_open(&plain, &m, &plain_o, NULL), 0);
    assert_int_equal(mim_vest_sim_open(&noisy, &m, &noisy_o, NULL), 0);
    assert_int_equal(mim_vest_sim_open(&noisy2, &m, &noisy_o, NULL), 0);
    double sum = 0, maxa = 0;
    size_t n = 0, differ = 0;
    for (uint64_t k = 0; k < 200; k++) {
        mim_quat truth[MIM_VEST_SEGMENTS], wire[MIM_VEST_SEGMENTS], again[MIM_VEST_SEGMENTS], pw[MIM_VEST_SEGMENTS];
        uint8_t have[MIM_VEST_SEGMENTS];
        mim_vest_sim_orientations(noisy, k, truth, have, NULL);
        mim_vest_sim_wire_orientations(noisy, 199 - k, again, NULL, NULL); /* any order: the same error */
        mim_vest_sim_wire_orientations(noisy2, 199 - k, pw, NULL, NULL);
        assert_memory_equal(again, pw, sizeof pw);
        mim_vest_sim_wire_orientations(noisy, k, wire, NULL, NULL);
        mim_vest_sim_wire_orientations(plain, k, pw, NULL, NULL);
        assert_memory_equal(pw, truth, sizeof pw); /* no noise: the truth itself */
        for (int i = 0; i < MIM_VEST_SEGMENTS; i++) {
            if (!have[i]) continue;
            double a = angle_deg(wire[i], truth[i]);
            sum += a, maxa = fmax(maxa, a), n++;
        }
        /* the same packets are dropped and corrupted; the noisy ones carry the wire's */
        uint8_t a[1024], b[1024];
        uint32_t ca[3] = {0}, cb[3] = {0};
        size_t na = mim_vest_sim_frame(plain, k, a, sizeof a, ca);
        size_t nb = mim_vest_sim_frame(noisy, k, b, sizeof b, cb);
        assert_int_equal(na, nb);
        assert_memory_equal(ca, cb, sizeof ca);
        differ += na && memcmp(a, b, na) != 0;
        if (ca[1] || ca[2]) continue;
        vs_sink_t got = {0};
        mim_vest_decoder_t *d = NULL;
        assert_int_equal(mim_vest_decoder_open(&d, NULL, vs_sink_packet, &got), 0);
        mim_vest_decoder_feed(d, b, nb, 0);
        mim_vest_decoder_close(&d);
        assert_true(got.n > 0);
        for (size_t f = 0; f < got.n; f++) {
            mim_quat w = wire[got.f[f].sensor];
            assert_true(got.f[f].q[0] == (float)w.x && got.f[f].q[1] == (float)w.y && got.f[f].q[2] == (float)w.z &&
                        got.f[f].q[3] == (float)w.w);
        }
        free(got.f);
    }
    double mean = sum / (double)n;
    assert_true(mean > 2 && mean < 10);
    assert_true(maxa > 5 && maxa < 40);
    assert_true(differ > 150);
    mim_vest_sim_close(&plain), mim_vest_sim_close(&noisy), mim_vest_sim_close(&noisy2);
    /* out of range */
    mim_vest_sim_t *bad = NULL;
    mim_error_t err = {0};
    noisy_o.orient_noise_deg = -1;
    assert_int_equal(mim_vest_sim_open(&bad, &m, &noisy_o, &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "orientation noise 0..180 degrees"));
    noisy_o.orient_noise_deg = 0, noisy_o.drift_deg_per_min = NAN;
    assert_int_equal(mim_vest_sim_open(&bad, &m, &noisy_o, NULL), MIM_EINVAL);
    assert_null(bad);
    mim_vest_motion_free(&m);
}

/* drift: per sensor a fixed axis, the angle growing linearly with stream
 * time (past the motion's end too), other axes for other sensors. */
static void test_drift(void **state)
{
    (void)state;
    mim_vest_motion_t m;
    vs_load_motion(&m, 31);
    mim_vest_sim_options_t o = {0};
    o.rate_hz = 50, o.drift_deg_per_min = 12, o.seed = 4;
    mim_vest_sim_t *sim = NULL;
    assert_int_equal(mim_vest_sim_open(&sim, &m, &o, NULL), 0);
    mim_vec3 axis0 = {0, 0, 0};
    for (uint64_t sec = 0; sec <= 120; sec += 30) {
        uint64_t k = sec * 50;
        mim_quat truth[MIM_VEST_SEGMENTS], wire[MIM_VEST_SEGMENTS];
        uint8_t have[MIM_VEST_SEGMENTS];
        mim_vest_sim_orientations(sim, k, truth, have, NULL);
        mim_vest_sim_wire_orientations(sim, k, wire, NULL, NULL);
        for (int i = 0; i < MIM_VEST_SEGMENTS; i++) {
            if (!have[i]) continue;
            assert_true(fabs(angle_deg(wire[i], truth[i]) - 12.0 * (double)sec / 60) < 0.01);
            if (sec != 60) continue;
            /* the error's axis, in the world frame: wire = E truth */
            mim_quat ti = {-truth[i].x, -truth[i].y, -truth[i].z, truth[i].w};
            mim_quat e = mim_quat_mul(wire[i], ti);
            mim_vec3 ax = {e.x, e.y, e.z};
            double len = sqrt(ax.x * ax.x + ax.y * ax.y + ax.z * ax.z);
            ax = (mim_vec3){ax.x / len, ax.y / len, ax.z / len};
            if (i == 0) axis0 = ax;
            else assert_true(fabs(ax.x * axis0.x + ax.y * axis0.y + ax.z * axis0.z) < 0.999);
        }
    }
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
}

int main(void)
{
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
        cmocka_unit_test(test_orient_noise),
        cmocka_unit_test(test_drift),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
