/* The real-time loop of mimic serve (issue 6, part 1): a thread reads the
 * vest, turns each whole vest frame into landmarks (calibrated rig, forward
 * kinematics), and makes it a key frame when every landmark is present and
 * the store has an index: query -> nearest template -> transfer with the
 * cached solver. Morphing between key frames, the adaptive key rate and the
 * WebSocket stream come with part 2; for now every complete frame is a key
 * frame and the latest pose is kept for them. */
#include "internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct mim__loop {
    mim_serve_t *sv;
    mim_vest_rig_t rig;
    mim_vest_transport_t *t;
    mim_vest_decoder_t *dec;
    mim_vest_state_t st;
    mim_vest_assembler_t as;
    pthread_t thread;
    int started;
    atomic_int stop;
    char spec[1024];
    float *tpos, *out; /* key frame work arrays, 3 * n */
    double *F;         /* 9 * n */
    pthread_mutex_t lock; /* guards what /api/status reads: */
    char state[16];    /* "streaming", "ended" or "failed" */
    char error[512];
    uint64_t last_template;
};

static void set_state(mim__loop_t *l, const char *state, const char *error)
{
    pthread_mutex_lock(&l->lock);
    snprintf(l->state, sizeof l->state, "%s", state);
    if (error)
        snprintf(l->error, sizeof l->error, "%s", error);
    pthread_mutex_unlock(&l->lock);
}

/* One vest frame's landmarks: counted, and a key frame when complete. */
static void landmarks_frame(mim__loop_t *l, const float *xyz, uint32_t present_count)
{
    mim_serve_t *sv = l->sv;
    double t0 = mim_now();
    mim__metrics_add(&sv->m, MIM__C_FRAMES, 1);
    if (!sv->q || present_count < sv->s.map.count)
        return; /* transfer holds every landmark exactly: it needs them all */
    mim_error_t err = {0};
    mim_index_query_options_t qo = {.k = 1};
    mim_index_answer_t a;
    mim_index_hit_t hit;
    int rc = mim_query_frame(sv->q, xyz, NULL, &qo, &a, &hit, &err);
    if (!rc && !a.n_hits)
        rc = mim_error_set(&err, MIM_ENOTFOUND, "the index returned no template");
    if (!rc) {
        mim__metrics_add(&sv->m, MIM__C_QUERIES, 1);
        pthread_mutex_lock(&sv->lock);
        rc = mim_serve_session_template(&sv->s, hit.id, l->tpos, l->F, NULL, 0, &err);
        mim_xfer_options_t o = {0};
        if (!rc)
            rc = mim_xfer_transfer(sv->solver, sv->s.W, sv->s.mesh.n_vertices, l->F, xyz, sv->s.map.count, &o,
                                   l->out, NULL, &err);
        pthread_mutex_unlock(&sv->lock);
    }
    if (rc) {
        mim__metrics_add(&sv->m, MIM__C_VEST_ERRORS, 1);
        set_state(l, "streaming", mim_error_text(&err));
        return;
    }
    mim__metrics_add(&sv->m, MIM__C_TRANSFERS, 1);
    mim__metrics_add(&sv->m, MIM__C_KEY_FRAMES, 1);
    mim__metrics_observe(&sv->m, MIM__H_KEY_FRAME, mim_now() - t0);
    pthread_mutex_lock(&l->lock);
    l->last_template = hit.id;
    pthread_mutex_unlock(&l->lock);
}

static void sensor_frame(mim__loop_t *l, uint64_t t)
{
    float xyz[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX];
    uint32_t n = mim_vest_fk(&l->rig, &l->st, t, 0, xyz, present);
    landmarks_frame(l, xyz, n);
}

static void on_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    mim__loop_t *l = user;
    uint64_t t[2], m[2];
    int done = mim_vest_assembler_push(&l->as, info, t, m), k = 0;
    /* a frame closed by this packet's later timestamp is taken before the
     * packet's orientations enter the state (as mimic vest replay does) */
    if (done > 0 && t[0] < info->t_us)
        sensor_frame(l, t[0]), k = 1;
    for (uint32_t i = 0; i < n; i++)
        mim_vest_state_update(&l->st, &f[i]);
    for (; k < done; k++)
        sensor_frame(l, t[k]);
}

static void *run(void *arg)
{
    mim__loop_t *l = arg;
    mim_serve_t *sv = l->sv;
    while (!atomic_load(&l->stop)) {
        mim_vest_chunk_t ch;
        mim_error_t err = {0};
        int r = mim_vest_transport_read(l->t, &ch, &err);
        if (r == -ETIMEDOUT)
            continue;
        if (r == 0) {
            uint64_t tl, ml;
            if (mim_vest_assembler_flush(&l->as, &tl, &ml))
                sensor_frame(l, tl);
            set_state(l, "ended", NULL);
            return NULL;
        }
        if (r < 0) {
            mim__metrics_add(&sv->m, MIM__C_VEST_ERRORS, 1);
            set_state(l, "failed", mim_error_text(&err));
            return NULL;
        }
        if (ch.kind == MIM_VEST_CHUNK_STREAM) {
            if (ch.restart)
                mim_vest_decoder_reset(l->dec);
            mim_vest_decoder_feed(l->dec, ch.data, ch.len, ch.t_us);
            continue;
        }
        /* a UDP landmark datagram: landmarks already */
        uint64_t tu;
        float xyz[3 * MIM_LANDMARKS_MAX];
        uint8_t present[MIM_LANDMARKS_MAX];
        uint32_t n = 0, have = 0;
        if (mim_vest_udp_parse((const char *)ch.data, ch.len, &tu, xyz, present, MIM_LANDMARKS_MAX, &n, NULL) ||
            n != sv->s.map.count) {
            mim__metrics_add(&sv->m, MIM__C_VEST_ERRORS, 1);
            continue;
        }
        for (uint32_t k = 0; k < n; k++)
            have += present[k] != 0;
        landmarks_frame(l, xyz, have);
    }
    set_state(l, "stopped", NULL);
    return NULL;
}

int mim__loop_open(mim__loop_t **out, mim_serve_t *sv, const char *spec, int pose, mim_error_t *err)
{
    *out = NULL;
    mim__loop_t *l = calloc(1, sizeof *l);
    mim_vest_skeleton_t *sk = malloc(sizeof *sk);
    const size_t n = sv->s.mesh.n_vertices;
    int rc = 0;
    if (l) {
        l->tpos = malloc(3 * n * sizeof *l->tpos);
        l->out = malloc(3 * n * sizeof *l->out);
        l->F = malloc(9 * n * sizeof *l->F);
    }
    if (!l || !sk || !l->tpos || !l->out || !l->F)
        rc = mim_error_set(err, MIM_ENOMEM, "out of memory for the vest loop");
    if (!rc) {
        l->sv = sv;
        pthread_mutex_init(&l->lock, NULL);
        snprintf(l->spec, sizeof l->spec, "%s", spec);
        snprintf(l->state, sizeof l->state, "streaming");
        mim_vest_state_reset(&l->st);
        mim_vest_calib_options_t co = {pose};
        rc = mim_vest_skeleton_estimate(sk, &sv->s.mesh, &sv->s.map, err);
        if (!rc)
            rc = mim_vest_calibrate(&l->rig, sk, &co, NULL, err);
        mim_vest_transport_options_t to = {.timeout_ms = 200, .realtime = 1};
        if (!rc)
            rc = mim_vest_transport_open(&l->t, spec, &to, err);
        mim_vest_decoder_options_t dopt = {.header_flags = l->t ? mim_vest_transport_header_flags(l->t) : 0};
        if (!rc && mim_vest_decoder_open(&l->dec, &dopt, on_packet, l))
            rc = mim_error_set(err, MIM_ENOMEM, "out of memory for the vest decoder");
    }
    if (!rc && (rc = -pthread_create(&l->thread, NULL, run, l)) != 0)
        rc = mim_error_set(err, rc, "cannot start the vest thread: %s", strerror(-rc));
    if (l)
        l->started = !rc;
    free(sk);
    if (rc) {
        mim__loop_close(&l);
        return rc;
    }
    *out = l;
    return 0;
}

void mim__loop_close(mim__loop_t **pl)
{
    mim__loop_t *l = pl ? *pl : NULL;
    if (!l)
        return;
    if (l->started) {
        atomic_store(&l->stop, 1);
        pthread_join(l->thread, NULL);
    }
    mim_vest_decoder_close(&l->dec);
    mim_vest_transport_close(&l->t);
    if (l->sv)
        pthread_mutex_destroy(&l->lock);
    free(l->tpos), free(l->out), free(l->F);
    free(l);
    *pl = NULL;
}

json_t *mim__loop_status(mim__loop_t *l)
{
    if (!l)
        return json_null();
    pthread_mutex_lock(&l->lock);
    json_t *j = json_pack("{s:s, s:s, s:o, s:o, s:I}", "spec", l->spec, "state", l->state, "error",
                          l->error[0] ? json_string(l->error) : json_null(), "last_template",
                          l->last_template ? json_integer((json_int_t)l->last_template) : json_null(), "reconnects",
                          (json_int_t)mim_vest_transport_reconnects(l->t));
    pthread_mutex_unlock(&l->lock);
    return j;
}
