/* bench/vest: decoder throughput and latency from a packet's last byte to
 * its landmark frame.
 *
 * The stream is what the simulated vest sends for a full 17-sensor kit (3
 * hub packets per frame, 127 + 127 + 111 bytes). Throughput: packets decoded
 * per second on one core (the process is pinned to one CPU), fed in 4 KiB
 * reads, against a reference measured in the same run: one additive pass
 * over the same bytes (what any decoder must at least do to check the
 * checksums). Latency: for each frame, everything but the last byte is fed
 * first; the clock runs from feeding the last byte until the 16 landmarks
 * of that frame are computed (decode, assemble, forward kinematics on a
 * synthetic avatar). Each figure is the median of several runs.
 *
 * usage: bench_vest [--frames N] [--runs R] */
#include "bench_data.h"
#include "mim_synth.h"
#include "mim_vest.h"

#include <getopt.h>
#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct {
    uint64_t packets;
    const mim_vest_rig_t *rig;
    mim_vest_state_t st;
    mim_vest_assembler_t as;
    float xyz[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX];
    uint64_t landmark_frames;
} ctx_t;

static void count_only(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    (void)info, (void)f, (void)n;
    ((ctx_t *)user)->packets++;
}

static void to_landmarks(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    ctx_t *c = user;
    uint64_t t[2], m[2];
    int done = mim_vest_assembler_push(&c->as, info, t, m), k = 0;
    if (done > 0 && t[0] < info->t_us) {
        mim_vest_fk(c->rig, &c->st, t[0], 0, c->xyz, c->present);
        c->landmark_frames++, k = 1;
    }
    for (uint32_t i = 0; i < n; i++) mim_vest_state_update(&c->st, &f[i]);
    for (; k < done; k++) {
        mim_vest_fk(c->rig, &c->st, t[k], 0, c->xyz, c->present);
        c->landmark_frames++;
    }
}

int main(int argc, char **argv)
{
    int frames = 100000, runs = 7, c;
    static const struct option lo[] = {{"frames", required_argument, 0, 'f'}, {"runs", required_argument, 0, 'r'}, {0, 0, 0, 0}};
    while ((c = getopt_long(argc, argv, "", lo, NULL)) != -1) {
        if (c == 'f') frames = atoi(optarg);
        else if (c == 'r') runs = atoi(optarg);
        else return fprintf(stderr, "usage: bench_vest [--frames N] [--runs R]\n"), 2;
    }
    if (frames < 10 || runs < 1 || runs > 64) return fprintf(stderr, "bench_vest: bad --frames or --runs\n"), 2;

    /* a synthetic avatar and its rig */
    mim_error_t err = {0};
    mim_synth_t *s = NULL;
    mim_synth_options_t so = {1, 1, 0, 1, 0, 0, 0};
    mim_mesh_t mesh = {0};
    mim_landmark_map_t map;
    static mim_vest_skeleton_t sk;
    static mim_vest_rig_t rig;
    if (mim_synth_create(&s, &so, &err) || mim_mesh_alloc(&mesh, mim_synth_n_vertices(s), mim_synth_n_faces(s)))
        return fprintf(stderr, "bench_vest: %s\n", err.msg), 1;
    memcpy(mesh.faces, mim_synth_faces(s), sizeof *mesh.faces * 3 * mesh.n_faces);
    mim_synth_body(s, 0, 0, mesh.positions);
    mim_synth_landmarks(s, &map);
    if (mim_vest_skeleton_estimate(&sk, &mesh, &map, &err) || mim_vest_calibrate(&rig, &sk, NULL, NULL, &err))
        return fprintf(stderr, "bench_vest: %s\n", err.msg), 1;

    /* the stream: frames of 17 random unit quaternions, 3 packets each */
    uint8_t *stream = malloc((size_t)frames * 3 * MIM_VEST_MAX_PACKET);
    size_t *frame_end = malloc(sizeof *frame_end * (size_t)frames);
    size_t n = 0;
    uint64_t rng = 12345;
    for (int k = 0; k < frames; k++) {
        float q[MIM_VEST_SEGMENTS][4];
        for (int i = 0; i < MIM_VEST_SEGMENTS; i++) {
            double a[4], nn = 0;
            for (int j = 0; j < 4; j++) {
                rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
                a[j] = (double)(rng >> 11) / 9007199254740992.0 - 0.5, nn += a[j] * a[j];
            }
            for (int j = 0; j < 4; j++) q[i][j] = (float)(a[j] / sqrt(nn));
        }
        for (int first = 0; first < MIM_VEST_SEGMENTS; first += 6) {
            mim_vest_hub_packet_t p = {0};
            p.timestamp_us = (uint32_t)(k * 16667u), p.logical_id = MIM_VEST_ID_HUB;
            int cnt = MIM_VEST_SEGMENTS - first < 6 ? MIM_VEST_SEGMENTS - first : 6;
            for (int i = 0; i < cnt; i++) p.active |= 1ull << (first + i);
            p.q = (const float(*)[4])q[first];
            n += mim_vest_encode_hub_packet(stream + n, 3 * MIM_VEST_MAX_PACKET, &p);
        }
        frame_end[k] = n;
    }

    /* one core */
    cpu_set_t saved, one;
    sched_getaffinity(0, sizeof saved, &saved);
    CPU_ZERO(&one);
    for (int cpu = 0; cpu < CPU_SETSIZE; cpu++)
        if (CPU_ISSET(cpu, &saved)) {
            CPU_SET(cpu, &one);
            break;
        }
    sched_setaffinity(0, sizeof one, &one);

    double thr[64], ref[64], lat_med[64], lat_p99[64], e2e[64];
    volatile unsigned sink = 0;
    double *lat = malloc(sizeof *lat * (size_t)frames);
    for (int r = 0; r < runs; r++) {
        /* throughput: decode only */
        ctx_t cx = {0};
        mim_vest_decoder_t *d = NULL;
        mim_vest_decoder_open(&d, NULL, count_only, &cx);
        double t0 = now();
        for (size_t i = 0; i < n; i += 4096) mim_vest_decoder_feed(d, stream + i, n - i < 4096 ? n - i : 4096, 0);
        double dt = now() - t0;
        mim_vest_decoder_close(&d);
        if (cx.packets != (uint64_t)frames * 3) return fprintf(stderr, "bench_vest: decoded %llu packets of %d\n", (unsigned long long)cx.packets, frames * 3), 1;
        thr[r] = (double)cx.packets / dt;
        /* reference: one additive pass over the same bytes */
        t0 = now();
        unsigned sum = 0;
        for (size_t i = 0; i < n; i++) sum += stream[i];
        sink += sum;
        ref[r] = (double)cx.packets / (now() - t0);
        /* decode + landmarks, whole stream */
        ctx_t cy;
        memset(&cy, 0, sizeof cy);
        cy.rig = &rig;
        mim_vest_state_reset(&cy.st);
        mim_vest_decoder_open(&d, NULL, to_landmarks, &cy);
        t0 = now();
        for (size_t i = 0; i < n; i += 4096) mim_vest_decoder_feed(d, stream + i, n - i < 4096 ? n - i : 4096, 0);
        e2e[r] = (double)frames / (now() - t0);
        mim_vest_decoder_close(&d);
        /* latency: last byte of a frame -> its landmarks */
        memset(&cy, 0, sizeof cy);
        cy.rig = &rig;
        mim_vest_state_reset(&cy.st);
        mim_vest_decoder_open(&d, NULL, to_landmarks, &cy);
        size_t at = 0;
        for (int k = 0; k < frames; k++) {
            mim_vest_decoder_feed(d, stream + at, frame_end[k] - 1 - at, 0);
            uint64_t before = cy.landmark_frames;
            double a = now();
            mim_vest_decoder_feed(d, stream + frame_end[k] - 1, 1, 0);
            lat[k] = now() - a;
            if (k > 1 && cy.landmark_frames != before + 1)
                return fprintf(stderr, "bench_vest: frame %d gave no landmarks at its last byte\n", k), 1;
            at = frame_end[k];
        }
        mim_vest_decoder_close(&d);
        lat_med[r] = bench_median(lat + 2, frames - 2) * 1e6;
        lat_p99[r] = bench_quantile(lat + 2, frames - 2, 0.99) * 1e6;
    }
    sched_setaffinity(0, sizeof saved, &saved);
    (void)sink;
    printf("vest stream: %d frames x 3 packets (17 sensors), %zu bytes, %d runs, one core\n", frames, n, runs);
    double m_thr = bench_median(thr, runs), m_ref = bench_median(ref, runs);
    printf("decoder throughput        %.3g packets/s  (%.1f MB/s)   target >= 1e6\n", m_thr, m_thr * (double)n / (3.0 * frames) / 1e6);
    printf("additive-pass reference   %.3g packets/s  decoder/reference = %.2f\n", m_ref, m_thr / m_ref);
    printf("decode + landmarks        %.3g frames/s\n", bench_median(e2e, runs));
    printf("latency last byte -> 16 landmarks: median %.2f us, p99 %.2f us (median over runs)   target < 20 us\n",
           bench_median(lat_med, runs), bench_median(lat_p99, runs));
    free(lat), free(stream), free(frame_end);
    mim_mesh_free(&mesh);
    mim_synth_destroy(&s);
    return 0;
}
