/* mimic vest: list, record, replay and simulate a tracking vest (mim_vest.h).
 * Replay prints one JSON object per line: schemas/vest-replay.schema.json. */
#include "args.h"
#include "commands.h"
#include "mim_io.h"
#include "mim_synth.h"
#include "mim_vest.h"
#include "output.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static volatile sig_atomic_t interrupted;
static volatile int stop_flag;
static void on_signal(int sig)
{
    (void)sig;
    interrupted = 1;
    stop_flag = 1;
}

static void catch_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
}

/* A usage error: what is wrong and where the help is; exit status 2. */
__attribute__((format(printf, 2, 3))) static int usage_error(const char *cmd, const char *fmt, ...)
{
    char what[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    fprintf(stderr, "mimic vest %s: %s (see mimic vest %s --help)\n", cmd, what, cmd);
    return 2;
}

/* What getopt returned past a command's own options: -h/--help prints the
 * help (exit 0), anything else is a bad option (exit 2). */
static int help_or_bad_option(int c, const char *cmd, const char *help, char **argv)
{
    if (c != 'h') return usage_error(cmd, "unknown or incomplete option '%s'", argv[optind - 1]);
    fputs(help, stdout);
    return 0;
}

/* The avatar rig: a mesh and its landmark map, or "synth[:S]" for subject S
 * of the synthetic generator in its rest pose. */
static int load_rig(const char *cmd, const char *avatar, const char *map_path, int pose, mim_vest_rig_t *rig)
{
    mim_error_t err = {0};
    mim_mesh_t mesh = {0};
    mim_landmark_map_t map;
    mim_vest_skeleton_t *sk = malloc(sizeof *sk);
    int rc = sk ? 0 : MIM_ENOMEM;
    if (!rc && !strncmp(avatar, "synth", 5) && (avatar[5] == 0 || avatar[5] == ':')) {
        uint64_t subject = 0;
        if (avatar[5] == ':' && mim_cli_number(cmd, "avatar synth:", avatar + 6, 0, 999, &subject)) {
            free(sk);
            return 2;
        }
        mim_synth_options_t so = {(uint32_t)subject + 1, 1, 0, 1, 0, 0, 0};
        mim_synth_t *s = NULL;
        rc = mim_synth_create(&s, &so, &err);
        if (!rc) rc = mim_mesh_alloc(&mesh, mim_synth_n_vertices(s), mim_synth_n_faces(s));
        if (!rc) {
            memcpy(mesh.faces, mim_synth_faces(s), sizeof *mesh.faces * 3 * mesh.n_faces);
            rc = mim_synth_body(s, (uint32_t)subject, 0, mesh.positions);
            mim_synth_landmarks(s, &map);
        }
        mim_synth_destroy(&s);
    } else if (!rc) {
        if (!map_path) {
            fprintf(stderr, "mimic vest %s: --avatar MESH needs --map landmarks.json\n", cmd);
            free(sk);
            return 2;
        }
        rc = mim_io_read_mesh(avatar, &mesh, &err);
        if (!rc) rc = mim_landmarks_read(&map, map_path, &err);
    }
    mim_vest_calib_options_t co = {pose};
    if (!rc) rc = mim_vest_skeleton_estimate(sk, &mesh, &map, &err);
    if (!rc) rc = mim_vest_calibrate(rig, sk, &co, NULL, &err);
    if (rc) fprintf(stderr, "mimic vest %s: %s\n", cmd, err.code ? mim_error_text(&err) : mim_strerror(rc));
    mim_mesh_free(&mesh);
    free(sk);
    return rc ? 1 : 0;
}

/* A stream chunk goes to the decoder, restarted after a reconnect; returns 0
 * for a datagram, which the caller handles. */
static int feed_stream(mim_vest_decoder_t *dec, const mim_vest_chunk_t *ch)
{
    if (ch->kind != MIM_VEST_CHUNK_STREAM) return 0;
    if (ch->restart) mim_vest_decoder_reset(dec);
    mim_vest_decoder_feed(dec, ch->data, ch->len, ch->t_us);
    return 1;
}

/* ---------------------------------------------------------------- list */

static const char list_help[] =
    "usage: mimic vest list [--no-hid] [--sysfs DIR]\n\n"
    "Lists devices that look like a PrioVR / YOST 3-Space vest: serial ports\n"
    "/dev/ttyACM* and /dev/ttyUSB* whose USB vendor id is 2476, and HID devices of\n"
    "vendor 0x2476 (hidapi). Each line is a --device SPEC and a description.\n\n"
    "  --no-hid      skip the HID enumeration\n"
    "  --sysfs DIR   read the serial ports' USB ids under DIR instead of /sys\n"
    "  -h, --help    this help\n";

static int cmd_list(int argc, char **argv)
{
    static const struct option lo[] = {
        {"sysfs", required_argument, 0, 's'}, {"no-hid", no_argument, 0, 'n'}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    const char *sysfs = NULL;
    int hid = 1, c;
    optind = 0, opterr = 0;
    while ((c = getopt_long(argc, argv, ":h", lo, NULL)) != -1) {
        if (c == 's') sysfs = optarg;
        else if (c == 'n') hid = 0;
        else return help_or_bad_option(c, "list", list_help, argv);
    }
    mim_vest_device_t dev[64];
    mim_error_t err = {0};
    int n = mim_vest_list(dev, 64, sysfs, hid, &err);
    if (n < 0) {
        fprintf(stderr, "mimic vest list: %s\n", mim_error_text(&err));
        return 1;
    }
    if (n == 0) {
        printf("no vest found: no serial port (/dev/ttyACM*, /dev/ttyUSB*) with USB vendor id 2476%s\n",
               hid ? " and no HID device of vendor 0x2476" : "");
        return 0;
    }
    for (int i = 0; i < n; i++) printf("%-40s %s\n", dev[i].spec, dev[i].what);
    return 0;
}

/* -------------------------------------------------------------- record */

typedef struct {
    uint64_t packets;
} count_t;

static void count_packets(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    (void)info, (void)f, (void)n;
    ((count_t *)user)->packets++;
}

static const char record_help[] =
    "usage: mimic vest record --device SPEC [--duration S] -o FILE [--no-setup] [--timeout S]\n\n"
    "Records what a vest sends, as it arrives and with its timing, into FILE\n"
    "(schemas/vest-recording.md); `mimic vest replay FILE` plays it back. Stops after\n"
    "--duration seconds, on Ctrl-C, or when the device stays unplugged for 10 s\n"
    "(a live device is reconnected with backoff meanwhile).\n\n"
    "  --device SPEC  serial:PATH | hid:VID:PID[:SERIAL] (hex) | udp:HOST:PORT (listen)\n"
    "  --duration S   seconds to record (default: until stopped)\n"
    "  -o, --out FILE the recording\n"
    "  --no-setup     do not send the stream set-up commands to a serial/HID device\n"
    "                 (response header, slots, timing, start)\n"
    "  --timeout S    report a silent link after S seconds (default 1)\n"
    "  -h, --help     this help\n";

static int cmd_record(int argc, char **argv)
{
    static const struct option lo[] = {
        {"device", required_argument, 0, 'd'}, {"duration", required_argument, 0, 't'},
        {"out", required_argument, 0, 'o'},    {"no-setup", no_argument, 0, 'n'},
        {"timeout", required_argument, 0, 'w'}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    const char *spec = NULL, *out = NULL;
    double duration = 0, timeout = 1;
    int setup = 1, c;
    optind = 0, opterr = 0;
    while ((c = getopt_long(argc, argv, ":d:t:o:h", lo, NULL)) != -1) {
        if (c == 'd') spec = optarg;
        else if (c == 'o') out = optarg;
        else if (c == 'n') setup = 0;
        else if (c == 't') { if (mim_cli_real("vest record", "duration", optarg, 0.001, 1e7, 0, NULL, &duration)) return 2; }
        else if (c == 'w') { if (mim_cli_real("vest record", "timeout", optarg, 0.01, 3600, 0, NULL, &timeout)) return 2; }
        else return help_or_bad_option(c, "record", record_help, argv);
    }
    if (!spec || !out) return usage_error("record", "--device SPEC and -o FILE are required");
    catch_signals();
    mim_error_t err = {0};
    mim_vest_transport_options_t to = {.log = mim_cli_log};
    to.timeout_ms = (int)(timeout * 1000);
    mim_vest_transport_t *t = NULL;
    mim_vest_recorder_t *rec = NULL;
    mim_vest_decoder_t *dec = NULL;
    count_t cnt = {0};
    int rc = mim_vest_transport_open(&t, spec, &to, &err);
    if (!rc && mim_vest_transport_is_device(t) && setup) {
        uint8_t cmd[256];
        mim_vest_link_t link = {1, MIM_VEST_ID_HUB, 0};
        size_t n = mim_vest_cmd_stream_setup(cmd, sizeof cmd, &link, mim_vest_transport_header_flags(t), 16667);
        rc = mim_vest_transport_write(t, cmd, n, &err);
    }
    if (!rc) rc = mim_vest_recorder_open(&rec, out, mim_vest_transport_header_flags(t), &err);
    mim_vest_decoder_options_t dopt = {.header_flags = mim_vest_transport_header_flags(t)};
    if (!rc) rc = mim_vest_decoder_open(&dec, &dopt, count_packets, &cnt);
    if (rc) {
        fprintf(stderr, "mimic vest record: %s\n", err.code ? mim_error_text(&err) : mim_strerror(rc));
        mim_vest_transport_close(&t);
        mim_vest_recorder_close(&rec, NULL);
        return rc == MIM_ENOMEM ? 2 : 1;
    }
    double t0 = mim_now();
    uint64_t chunks = 0, bytes = 0;
    int status = 0, quiet = 0;
    while (!interrupted && (duration == 0 || mim_now() - t0 < duration)) {
        mim_vest_chunk_t ch;
        mim_error_clear(&err);
        int r = mim_vest_transport_read(t, &ch, &err);
        if (r == 0) break;
        if (r == -ETIMEDOUT) {
            if (!quiet) fprintf(stderr, "mimic vest record: %s\n", mim_error_text(&err));
            quiet = 1; /* once until data flows again */
            continue;
        }
        quiet = 0;
        if (r < 0) {
            fprintf(stderr, "mimic vest record: %s\n", mim_error_text(&err));
            status = 1;
            break;
        }
        if (!feed_stream(dec, &ch)) cnt.packets++; /* a datagram is one packet */
        if (mim_vest_recorder_write(rec, &ch, &err)) {
            fprintf(stderr, "mimic vest record: %s\n", mim_error_text(&err));
            status = 1;
            break;
        }
        chunks++, bytes += ch.len;
    }
    if (mim_vest_recorder_close(&rec, &err)) {
        fprintf(stderr, "mimic vest record: %s\n", mim_error_text(&err));
        status = 1;
    }
    mim_vest_decoder_stats_t st;
    mim_vest_decoder_get_stats(dec, &st);
    fprintf(stderr, "mimic vest record: %llu chunks, %llu bytes, %llu packets in %.1f s to %s (%u reconnects)\n",
            (unsigned long long)chunks, (unsigned long long)bytes, (unsigned long long)cnt.packets, mim_now() - t0,
            out, mim_vest_transport_reconnects(t));
    mim_vest_decoder_close(&dec);
    mim_vest_transport_close(&t);
    return status;
}

/* -------------------------------------------------------------- replay */

typedef struct {
    const mim_vest_rig_t *rig; /* NULL: print sensor frames */
    mim_vest_state_t st;
    mim_vest_assembler_t as;
    uint64_t frames_out;
    uint64_t timeout_us;
} replay_t;

static void print_frame(replay_t *r, uint64_t t, uint64_t mask)
{
    if (r->rig) {
        float xyz[3 * MIM_LANDMARKS_MAX];
        uint8_t present[MIM_LANDMARKS_MAX], have[MIM_VEST_SEGMENTS];
        mim_quat R[MIM_VEST_SEGMENTS];
        mim_vest_fk(r->rig, &r->st, t, r->timeout_us, xyz, present);
        /* a segment's rotation needs only its own sensor, not those above it */
        mim_vest_fresh(&r->st, t, r->timeout_us, have);
        mim_vest_segment_rotations(r->rig, r->st.q, have, R);
        char *js = mim_vest_udp_format_orient(t, xyz, present, r->rig->n_landmarks, R, have);
        if (js) puts(js);
        free(js);
    } else {
        printf("{\"t\":%llu,\"sensors\":[", (unsigned long long)t);
        int first = 1;
        for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) {
            if (!(mask >> s & 1) || !r->st.seen[s] || r->st.t_us[s] != t) continue;
            mim_quat q = r->st.q[s];
            printf("%s{\"id\":%u,\"name\":\"%s\",\"q\":[%.9g,%.9g,%.9g,%.9g]}", first ? "" : ",", s,
                   mim_vest_segment_name(s), (float)q.x, (float)q.y, (float)q.z, (float)q.w);
            first = 0;
        }
        printf("]}\n");
    }
    r->frames_out++;
}

static void on_packet(void *user, const mim_vest_packet_info_t *info, const mim_vest_frame_t *f, uint32_t n)
{
    replay_t *r = user;
    uint64_t t[2], m[2];
    int done = mim_vest_assembler_push(&r->as, info, t, m);
    int k = 0;
    /* a frame closed by this packet's later timestamp is printed before the
     * packet's orientations enter the state */
    if (done > 0 && t[0] < info->t_us) print_frame(r, t[0], m[0]), k = 1;
    for (uint32_t i = 0; i < n; i++) mim_vest_state_update(&r->st, &f[i]);
    for (; k < done; k++) print_frame(r, t[k], m[k]);
}

static const char replay_help[] =
    "usage: mimic vest replay FILE|SPEC [--realtime] [--avatar MESH --map landmarks.json]\n"
    "                          [--pose rest|t|a] [--timeout S]\n\n"
    "Decodes a recording (or a live device SPEC, as for record) and prints one JSON\n"
    "object per vest frame (schemas/vest-replay.schema.json): {\"t\": us, \"sensors\":\n"
    "[{\"id\", \"name\", \"q\": [x, y, z, w]}, ...]}. Given an avatar, prints its\n"
    "landmarks in map order and its 17 segments' rotations from its rest pose instead:\n"
    "{\"t\": us, \"landmarks\": [[x, y, z] | null, ...], \"orientations\": {\"pelvis\":\n"
    "[x, y, z, w] | null, ...}}, a frame `mimic transfer --landmarks` reads. A landmark\n"
    "is null when its sensor (or one above it) has been silent for longer than\n"
    "--timeout, an orientation when its own sensor has. Counts of rejected packets go\n"
    "to stderr.\n\n"
    "  --realtime        keep the recorded timing (default: as fast as possible)\n"
    "  --avatar MESH     the avatar mesh (any format mimic reads), or synth[:S] for a\n"
    "                    synthetic body (subject S, rest pose) with its own landmarks\n"
    "  --map FILE        the avatar's landmark map (schemas/landmarks.schema.json)\n"
    "  --pose P          the pose the wearer stood in at the tare: rest (as the\n"
    "                    avatar), t or a (default rest)\n"
    "  --timeout S       a sensor silent this long is missing (default 0.25)\n"
    "  -h, --help        this help\n";

static int cmd_replay(int argc, char **argv)
{
    static const struct option lo[] = {
        {"realtime", no_argument, 0, 'r'},      {"avatar", required_argument, 0, 'a'},
        {"map", required_argument, 0, 'm'},     {"pose", required_argument, 0, 'p'},
        {"timeout", required_argument, 0, 'w'}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    const char *avatar = NULL, *map = NULL;
    int realtime = 0, pose = MIM_VEST_POSE_REST, c;
    double timeout = 0.25;
    optind = 0, opterr = 0;
    while ((c = getopt_long(argc, argv, ":h", lo, NULL)) != -1) {
        if (c == 'r') realtime = 1;
        else if (c == 'a') avatar = optarg;
        else if (c == 'm') map = optarg;
        else if (c == 'p') { if (mim_cli_pose("vest replay", "pose", optarg, &pose)) return 2; }
        else if (c == 'w') { if (mim_cli_real("vest replay", "timeout", optarg, 0.001, 3600, 0, NULL, &timeout)) return 2; }
        else return help_or_bad_option(c, "replay", replay_help, argv);
    }
    if (optind != argc - 1) return usage_error("replay", "give one FILE or SPEC");
    const char *src = argv[optind];
    static mim_vest_rig_t rig;
    if (avatar) {
        int r = load_rig("replay", avatar, map, pose, &rig);
        if (r) return r;
    }
    catch_signals();
    mim_error_t err = {0};
    mim_vest_transport_options_t to = {.log = mim_cli_log};
    to.realtime = realtime;
    mim_vest_transport_t *t = NULL;
    int rc = mim_vest_transport_open(&t, src, &to, &err);
    if (rc) {
        fprintf(stderr, "mimic vest replay: %s\n", mim_error_text(&err));
        return 1;
    }
    replay_t *rp = calloc(1, sizeof *rp);
    mim_vest_decoder_t *dec = NULL;
    mim_vest_decoder_options_t dopt = {.header_flags = mim_vest_transport_header_flags(t)};
    if (!rp || mim_vest_decoder_open(&dec, &dopt, on_packet, rp)) {
        fprintf(stderr, "mimic vest replay: out of memory\n");
        free(rp), mim_vest_transport_close(&t);
        return 2;
    }
    rp->rig = avatar ? &rig : NULL;
    rp->timeout_us = (uint64_t)llround(timeout * 1e6);
    mim_vest_state_reset(&rp->st);
    int status = 0;
    uint64_t bad_udp = 0;
    while (!interrupted) {
        mim_vest_chunk_t ch;
        mim_error_clear(&err);
        int r = mim_vest_transport_read(t, &ch, &err);
        if (r == 0) break;
        if (r == -ETIMEDOUT) continue;
        if (r < 0) {
            fprintf(stderr, "mimic vest replay: %s\n", mim_error_text(&err));
            status = 1;
            break;
        }
        if (feed_stream(dec, &ch)) continue;
        uint64_t tu;
        float xyz[3 * MIM_LANDMARKS_MAX];
        uint8_t present[MIM_LANDMARKS_MAX];
        uint32_t n;
        mim_quat R[MIM_SEGMENTS];
        uint8_t have[MIM_SEGMENTS];
        int has_orient;
        if (mim_vest_udp_parse_orient((const char *)ch.data, ch.len, &tu, xyz, present, MIM_LANDMARKS_MAX, &n, R,
                                      have, &has_orient, NULL)) {
            bad_udp++;
            continue;
        }
        char *js = mim_vest_udp_format_orient(tu, xyz, present, n, has_orient ? R : NULL, have);
        if (js) puts(js), rp->frames_out++;
        free(js);
    }
    uint64_t tl, ml;
    if (mim_vest_assembler_flush(&rp->as, &tl, &ml)) print_frame(rp, tl, ml);
    fflush(stdout);
    mim_vest_decoder_stats_t st;
    mim_vest_decoder_get_stats(dec, &st);
    fprintf(stderr, "mimic vest replay: %llu frames out; %llu packets, %llu sensor frames, %llu bytes skipped",
            (unsigned long long)rp->frames_out, (unsigned long long)st.packets, (unsigned long long)st.frames,
            (unsigned long long)st.skipped_bytes);
    for (int i = 0; i < MIM_VEST_REJ_COUNT; i++)
        if (st.rejected[i]) fprintf(stderr, ", %llu %s", (unsigned long long)st.rejected[i], mim_vest_reject_name(i));
    if (bad_udp) fprintf(stderr, ", %llu bad udp frames", (unsigned long long)bad_udp);
    fprintf(stderr, "\n");
    mim_vest_decoder_close(&dec);
    mim_vest_transport_close(&t);
    free(rp);
    return status;
}

/* ------------------------------------------------------------ simulate */

static void print_ready(void *user, const char *path)
{
    (void)user;
    printf("%s\n", path);
    fflush(stdout);
}

static int faults_arg(const char *text, mim_vest_sim_options_t *o)
{
    char buf[256];
    snprintf(buf, sizeof buf, "%s", text);
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        char *eq = strchr(tok, '=');
        if (!eq) goto bad;
        *eq = 0;
        if (!strcmp(tok, "drop")) { if (mim_cli_real("vest simulate", "faults drop", eq + 1, 0, 1, 0, NULL, &o->drop)) return -1; }
        else if (!strcmp(tok, "corrupt")) { if (mim_cli_real("vest simulate", "faults corrupt", eq + 1, 0, 1, 0, NULL, &o->corrupt)) return -1; }
        else if (!strcmp(tok, "disconnect")) { if (mim_cli_real("vest simulate", "faults disconnect", eq + 1, 0.001, 1e7, 0, NULL, &o->disconnect_at)) return -1; }
        else if (!strcmp(tok, "down")) { if (mim_cli_real("vest simulate", "faults down", eq + 1, 0.001, 3600, 0, NULL, &o->disconnect_for)) return -1; }
        else if (!strcmp(tok, "orient-noise")) { if (mim_cli_real("vest simulate", "faults orient-noise", eq + 1, 0, 180, 0, NULL, &o->orient_noise_deg)) return -1; }
        else if (!strcmp(tok, "drift")) { if (mim_cli_real("vest simulate", "faults drift", eq + 1, 0, 3600, 0, NULL, &o->drift_deg_per_min)) return -1; }
        else goto bad;
    }
    return 0;
bad:
    fprintf(stderr, "mimic vest simulate: --faults '%s' is not a list of drop=P, corrupt=P, disconnect=T, down=S, "
                    "orient-noise=DEG, drift=DEG_PER_MIN\n", text);
    return -1;
}

static int write_expected(const char *path, mim_vest_sim_t *sim, const mim_vest_rig_t *rig)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "mimic vest simulate: %s: %s\n", path, strerror(errno));
        return -1;
    }
    for (uint64_t k = 0; k < mim_vest_sim_n_frames(sim); k++) {
        mim_quat q[MIM_VEST_SEGMENTS];
        uint8_t have[MIM_VEST_SEGMENTS];
        uint64_t t;
        float xyz[3 * MIM_LANDMARKS_MAX];
        uint8_t present[MIM_LANDMARKS_MAX];
        mim_quat R[MIM_VEST_SEGMENTS];
        mim_vest_sim_orientations(sim, k, q, have, &t); /* the truth: no sensor error */
        mim_vest_fk_orient(rig, q, have, xyz, present);
        mim_vest_segment_rotations(rig, q, have, R);
        char *js = mim_vest_udp_format_orient(t, xyz, present, rig->n_landmarks, R, have);
        if (js) fprintf(f, "%s\n", js);
        free(js);
    }
    if (fclose(f)) {
        fprintf(stderr, "mimic vest simulate: %s: write error\n", path);
        return -1;
    }
    return 0;
}

static const char simulate_help[] =
    "usage: mimic vest simulate --motion (FILE.(bvh|amc)|demo) [--asf FILE] [--rate HZ]\n"
    "         [--faults drop=P,corrupt=P,disconnect=T,down=S,orient-noise=DEG,\n"
    "                   drift=DEG_PER_MIN] [--loop] [--seed K]\n"
    "         --out (pty[:LINK]|udp:HOST:PORT|FILE) [--avatar MESH --map FILE] [--pose P]\n"
    "         [--expected FILE] [--realtime]\n\n"
    "A simulated PrioVR vest driven by motion data: each of the 17 sensors reports its\n"
    "segment's rotation since the motion's rest pose (where the simulated wearer\n"
    "tared), in the exact hub wire protocol (schemas/vest-protocol.md).\n"
    "With --out pty it opens a pseudo-terminal, prints its path as the first line of\n"
    "stdout (pty:LINK also keeps a symlink LINK to it, across simulated reconnects)\n"
    "and streams at the rate until the motion ends (--loop repeats it). udp:HOST:PORT\n"
    "sends the avatar's landmarks and segment orientations as JSON datagrams\n"
    "(schemas/vest-udp.schema.json); FILE writes a recording (as fast as possible\n"
    "unless --realtime).\n\n"
    "  --motion FILE   BVH, or AMC with --asf (CMU); 'demo': the built-in motion\n"
    "                  (eight poses in 12 s, T-pose rest)\n"
    "  --asf FILE      the ASF skeleton of an AMC motion\n"
    "  --up AXIS       the motion file's up axis, x, y, z, -x, -y or -z (default: the\n"
    "                  rest pose's, head above pelvis; said on stderr)\n"
    "  --rate HZ       stream frames per second, 1..2000 (default 60)\n"
    "  --faults LIST   drop=P and corrupt=P per packet (0..1), disconnect=T seconds\n"
    "                  into the stream for down=S seconds (default 0.5); sensor\n"
    "                  error on what is sent: orient-noise=DEG (each frame, each\n"
    "                  sensor turned about a random axis by a Gaussian angle of\n"
    "                  this standard deviation, 0..180) and drift=DEG_PER_MIN (per\n"
    "                  sensor a fixed random axis, the angle growing with time)\n"
    "  --loop          repeat the motion until stopped\n"
    "  --seed K        seed of the fault randomness (default 0)\n"
    "  --avatar MESH   avatar for udp output and --expected: a mesh, or synth[:S]\n"
    "                  (default synth)\n"
    "  --map FILE      the avatar's landmark map\n"
    "  --pose P        tare pose of the avatar rig: rest, t or a (default: t or a,\n"
    "                  whichever the motion's rest pose is nearer)\n"
    "  --expected FILE write the landmarks and segment orientations each frame\n"
    "                  should give (the avatar's forward kinematics of the motion,\n"
    "                  without sensor error), one JSON object per line\n"
    "  -h, --help      this help\n";

static int cmd_simulate(int argc, char **argv)
{
    static const struct option lo[] = {
        {"motion", required_argument, 0, 'm'}, {"asf", required_argument, 0, 's'},
        {"rate", required_argument, 0, 'r'},   {"faults", required_argument, 0, 'f'},
        {"loop", no_argument, 0, 'l'},         {"out", required_argument, 0, 'o'},
        {"seed", required_argument, 0, 'k'},   {"avatar", required_argument, 0, 'a'},
        {"map", required_argument, 0, 'p'},    {"pose", required_argument, 0, 'P'},
        {"expected", required_argument, 0, 'e'}, {"realtime", no_argument, 0, 'R'},
        {"up", required_argument, 0, 'U'},     {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0}};
    const char *motion = NULL, *asf = NULL, *out = NULL, *avatar = NULL, *map = NULL, *expected = NULL;
    mim_vest_sim_options_t so = {0};
    int pose = MIM_VEST_POSE_REST, pose_given = 0, realtime = 0, up = 0, c;
    optind = 0, opterr = 0;
    while ((c = getopt_long(argc, argv, ":h", lo, NULL)) != -1) {
        uint64_t v;
        if (c == 'm') motion = optarg;
        else if (c == 's') asf = optarg;
        else if (c == 'o') out = optarg;
        else if (c == 'l') so.loop = 1;
        else if (c == 'a') avatar = optarg;
        else if (c == 'p') map = optarg;
        else if (c == 'e') expected = optarg;
        else if (c == 'R') realtime = 1;
        else if (c == 'U') {
            if (mim_axis_parse(optarg, &up)) return usage_error("simulate", "--up: give x, y, z, -x, -y or -z");
        }
        else if (c == 'P') { if (mim_cli_pose("vest simulate", "pose", optarg, &pose)) return 2; pose_given = 1; }
        else if (c == 'r') { if (mim_cli_real("vest simulate", "rate", optarg, 1, 2000, 0, NULL, &so.rate_hz)) return 2; }
        else if (c == 'f') { if (faults_arg(optarg, &so)) return 2; }
        else if (c == 'k') { if (mim_cli_number("vest simulate", "seed", optarg, 0, UINT64_MAX, &v)) return 2; so.seed = v; }
        else return help_or_bad_option(c, "simulate", simulate_help, argv);
    }
    if (!motion || !out) return usage_error("simulate", "--motion FILE and --out are required");
    mim_error_t err = {0};
    mim_vest_motion_t m = {0};
    size_t ml = strlen(motion);
    int rc;
    if (!strcmp(motion, "demo")) {
        rc = mim_vest_motion_demo(&m, &err);
    } else if (ml > 4 && !strcasecmp(motion + ml - 4, ".amc")) {
        if (!asf) {
            fprintf(stderr, "mimic vest simulate: an AMC motion needs --asf FILE\n");
            return 2;
        }
        rc = mim_vest_motion_read_amc(&m, asf, motion, &err);
    } else {
        rc = mim_vest_motion_read_bvh(&m, motion, &err);
    }
    if (!rc && up) rc = mim_vest_motion_set_up(&m, up, &err);
    if (rc) {
        fprintf(stderr, "mimic vest simulate: %s\n", mim_error_text(&err));
        mim_vest_motion_free(&m);
        return 1;
    }
    if (strcmp(motion, "demo") && (up || m.up != 2)) /* a file turned upright: say so */
        mim_cli_logf("%s: %s is up (%s)", motion, mim_axis_name(m.up), up ? "given" : "the rest pose's; --up to change");
    if (m.rest_arm_deg >= 0) {
        int tpose = m.rest_arm_deg > 67.5;
        if (!pose_given) pose = tpose ? MIM_VEST_POSE_T : MIM_VEST_POSE_A;
        mim_cli_logf("%s: rest pose holds the arms %.0f deg from vertical (%s); replay with --pose %s", motion,
                     m.rest_arm_deg, tpose ? "T-pose" : "A-pose", tpose ? "t" : "a");
    }
    static mim_vest_rig_t rig;
    int need_rig = expected || !strncmp(out, "udp:", 4);
    if (need_rig && load_rig("simulate", avatar ? avatar : "synth", map, pose, &rig)) {
        mim_vest_motion_free(&m);
        return 1;
    }
    mim_vest_sim_t *sim = NULL;
    if ((rc = mim_vest_sim_open(&sim, &m, &so, &err))) {
        fprintf(stderr, "mimic vest simulate: %s\n", mim_error_text(&err));
        mim_vest_motion_free(&m);
        return 2;
    }
    if (expected && write_expected(expected, sim, &rig)) rc = -1;
    if (!rc) {
        catch_signals();
        mim_vest_sim_run_t run = {out, need_rig ? &rig : NULL, realtime, print_ready, NULL, &stop_flag};
        rc = mim_vest_sim_run(sim, &run, &err);
        if (rc) fprintf(stderr, "mimic vest simulate: %s\n", mim_error_text(&err));
    }
    mim_vest_sim_close(&sim);
    mim_vest_motion_free(&m);
    return rc ? 1 : 0;
}

/* ---------------------------------------------------------------- vest */

int mim_cmd_vest(int argc, char **argv)
{
    static const char *usage =
        "usage: mimic vest COMMAND [OPTIONS]\n\n"
        "The tracking vest (PrioVR / YOST 3-Space sensors): its devices, recordings,\n"
        "decoding and landmarks. Commands:\n\n"
        "  list       devices that look like vests (serial ports and HID, vendor 0x2476)\n"
        "  record     record a vest's stream to a file\n"
        "  replay     decode a recording (or a live device) to sensor frames or landmarks\n"
        "  simulate   a simulated vest driven by BVH or ASF/AMC motion\n\n"
        "`mimic vest COMMAND --help` describes a command.\n";
    if (argc < 2) {
        fputs(usage, stderr);
        return 2;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        fputs(usage, stdout);
        return 0;
    }
    if (!strcmp(argv[1], "list")) return cmd_list(argc - 1, argv + 1);
    if (!strcmp(argv[1], "record")) return cmd_record(argc - 1, argv + 1);
    if (!strcmp(argv[1], "replay")) return cmd_replay(argc - 1, argv + 1);
    if (!strcmp(argv[1], "simulate")) return cmd_simulate(argc - 1, argv + 1);
    fprintf(stderr, "mimic vest: unknown command '%s' (see mimic vest --help)\n", argv[1]);
    return 2;
}
