/* Helpers shared by the vest tests: vest_support.h. */
#include "vest_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static mim_rng_t rng = {0x9e3779b97f4a7c15ULL}; /* core's generator: the same sequence on every run */
uint64_t vs_rnd(void) { return mim_rng_u64(&rng); }
static double rnd01(void) { return mim_rng_unit(&rng); }

void vs_rand_quat(float q[4])
{
    double a[4], n = 0;
    for (int i = 0; i < 4; i++) a[i] = rnd01() * 2 - 1, n += a[i] * a[i];
    n = sqrt(n);
    if (n < 1e-3) a[3] = 1, n = 1;
    for (int i = 0; i < 4; i++) q[i] = (float)(a[i] / n);
}

void vs_avatar_make(vs_avatar_t *a, int pose)
{
    memset(a, 0, sizeof *a);
    mim_synth_options_t so = {1, 2, 3000, 1, 0, 0, 0};
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

void vs_avatar_free(vs_avatar_t *a)
{
    mim_mesh_free(&a->mesh);
    mim_synth_destroy(&a->s);
}

/* A small BVH written by the test: Y up, the body's left +X, T-pose rest;
 * arms swing, legs step, the torso turns. Centimetres, 30 frames/s. */
char *vs_make_bvh(int frames)
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

char *vs_write_bvh(const char *dir, int frames)
{
    char *text = vs_make_bvh(frames), *path = ts_path(dir, "motion.bvh");
    assert_int_equal(ts_write_file(path, text, strlen(text)), 0);
    free(text);
    return path;
}

void vs_load_motion(mim_vest_motion_t *m, int frames)
{
    char *text = vs_make_bvh(frames);
    mim_error_t err = {0};
    int rc = mim_vest_motion_parse_bvh(m, text, strlen(text), "test.bvh", &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, 0);
    free(text);
}

void vs_sink_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *fr, uint32_t n)
{
    vs_sink_t *s = user;
    (void)info;
    s->packets++;
    for (uint32_t i = 0; i < n; i++) {
        if (s->n == s->cap) s->f = realloc(s->f, sizeof *s->f * (s->cap = s->cap ? 2 * s->cap : 1024));
        s->f[s->n++] = fr[i];
    }
}

void vs_stream_put(vs_stream_t *s, const void *p, size_t n)
{
    while (s->n + n > s->cap) s->bytes = realloc(s->bytes, s->cap = s->cap ? 2 * s->cap : 4096);
    memcpy(s->bytes + s->n, p, n);
    s->n += n;
}

void vs_make_stream(vs_stream_t *s, uint32_t f, int packets, int garbage)
{
    memset(s, 0, sizeof *s);
    uint32_t cap = mim_vest_hub_capacity(f);
    uint32_t ts = 0xFFFFF000u; /* crosses the u32 wrap */
    uint64_t t64 = ts;
    for (int k = 0; k < packets; k++) {
        float q[6][4];
        mim_vest_hub_packet_t p = {0};
        p.header_flags = f, p.timestamp_us = ts, p.battery = (uint8_t)vs_rnd(), p.status = (uint8_t)vs_rnd();
        uint32_t ns = 1 + (uint32_t)(vs_rnd() % cap), c = 0;
        while (c < ns) {
            uint32_t id = (uint32_t)(vs_rnd() % 64);
            if (p.active >> id & 1) continue;
            p.active |= 1ull << id, c++;
        }
        c = 0;
        for (uint32_t id = 0; id < 64; id++)
            if (p.active >> id & 1) {
                vs_rand_quat(q[c]);
                mim_vest_frame_t fr = {f & MIM_VEST_HDR_TIMESTAMP ? t64 : 7, id, {q[c][0], q[c][1], q[c][2], q[c][3]}, p.status};
                if (s->n_sent == s->cap_sent) s->sent = realloc(s->sent, sizeof *s->sent * (s->cap_sent = s->cap_sent ? 2 * s->cap_sent : 1024));
                s->sent[s->n_sent++] = fr;
                c++;
            }
        p.q = (const float(*)[4])q;
        uint8_t buf[MIM_VEST_MAX_PACKET];
        size_t len = mim_vest_encode_hub_packet(buf, sizeof buf, &p);
        assert_true(len > 0 && len <= MIM_VEST_MAX_PACKET);
        vs_stream_put(s, buf, len);
        if (garbage && vs_rnd() % 4 == 0) {
            uint8_t g[40];
            size_t gn = vs_rnd() % sizeof g;
            for (size_t i = 0; i < gn; i++) g[i] = (uint8_t)vs_rnd();
            vs_stream_put(s, g, gn);
        }
        ts += 16667, t64 += 16667;
    }
}

void vs_assert_frames_equal(const mim_vest_frame_t *a, const mim_vest_frame_t *b, int check_t)
{
    assert_int_equal(a->sensor, b->sensor);
    assert_memory_equal(a->q, b->q, sizeof a->q);
    assert_int_equal(a->status, b->status);
    if (check_t) assert_true(a->t_us == b->t_us);
}

/* The angle between two orientations, in degrees. */
double vs_angle_deg(mim_quat a, mim_quat b)
{
    mim_quat d = mim_quat_mul(a, (mim_quat){-b.x, -b.y, -b.z, b.w});
    return 2 * atan2(sqrt(d.x * d.x + d.y * d.y + d.z * d.z), fabs(d.w)) * 180 / M_PI;
}

/* One vest landmark line read as a landmark frame (what `mimic transfer
 * --landmarks` does): its 17 orientations into R and have; returns 1 when
 * the line has them. */
int vs_line_orientations(const char *line, mim_quat R[MIM_SEGMENTS], uint8_t have[MIM_SEGMENTS])
{
    mim_landmark_frames_t f;
    mim_error_t err = {0};
    int rc = mim_landmark_frames_parse(line, strlen(line), "line", 16, 16, &f, &err);
    if (rc) fail_msg("%s", err.msg);
    int has = f.orientations != NULL;
    for (int s = 0; s < MIM_SEGMENTS && has; s++) {
        const double *q = f.orientations + 4 * s;
        R[s] = (mim_quat){q[0], q[1], q[2], q[3]};
        have[s] = f.orient_present[s];
    }
    mim_landmark_frames_free(&f);
    return has;
}

char *vs_expected_line(const char *want, const char *line, unsigned long long *t)
{
    assert_int_equal(sscanf(line, "{\"t\":%llu,", t), 1);
    char key[64];
    snprintf(key, sizeof key, "{\"t\":%llu,", *t);
    const char *w = strstr(want, key);
    assert_non_null(w);
    return strndup(w, strcspn(w, "\n"));
}
