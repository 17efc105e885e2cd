/* mimic serve: the real-time service over a store and an avatar
 * (mim_serve.h): viewer, WebSocket stream, HTTP JSON API, until SIGINT or
 * SIGTERM. */
#include "args.h"
#include "commands.h"
#include "mim_serve.h"
#include "mim_vest.h"
#include "output.h"

#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic serve --store DIR --avatar (MESH|ID) [--vest SPEC [--vest-pose rest|t|a]]\n"
            "                   [--key-rate auto|HZ] [--listen HOST:PORT] [--max-body BYTES]\n"
            "                   [--max-clients N] [--warm-start auto|on|off] [--drive auto|template|orientation]\n"
            "                   [--blend K] [--segment-correction on|off]\n\n"
            "Serves pose transfer until Ctrl-C or SIGTERM: the web viewer at /, the avatar\n"
            "stream at /ws and the JSON API. Prints the viewer's URL on stdout.\n"
            "With --vest, every vest frame becomes landmarks on the avatar and one avatar\n"
            "frame on the stream: a key frame (nearest template, then transfer with the\n"
            "cached factor) as often as the measured compute time allows, morphs between.\n\n"
            "  --store DIR          the template store (its index, if built, answers /api/query)\n"
            "  --avatar MESH|ID     a mesh file, or a template id; a mesh of another connectivity\n"
            "                       is registered onto the store's once and bound (kept in the store)\n"
            "  --avatar-landmarks FILE  that mesh's landmarks (default: NAME.landmarks.json beside it,\n"
            "                       or a built-in map of its connectivity)\n"
            "  --vest SPEC          a recording (played in real time), serial:PATH, hid:VID:PID or\n"
            "                       udp:HOST:PORT (as mimic vest replay takes)\n"
            "  --vest-pose P        the wearer's pose at the tare: rest (as the avatar), t or a\n"
            "                       (default rest)\n"
            "  --key-rate auto|HZ   key frames per second; auto (default): one at every vest\n"
            "                       frame the compute time affords, fewer when it cannot\n"
            "  --listen HOST:PORT   where to listen (default %s; port 0: any free port)\n"
            "  --max-body BYTES     request body limit (default %zu; larger bodies get 413)\n"
            "  --max-clients N      WebSocket clients at once (default %u)\n"
            "  --warm-start W       start each key frame's transfer from the previous one (same\n"
            "                       template): faster, less accurate (bench/RESULTS.md); auto\n"
            "                       (default) only when cold key frames do not fit the vest period\n"
            "  --drive D            what drives key frames: auto (default: the vest's segment\n"
            "                       orientations, one solve; the template where there are none),\n"
            "                       template (the template's frames, iterated) or orientation\n"
            "  --blend K            the template drive blends the frames of the K nearest templates\n"
            "                       (default 1; mimic transfer --help)\n"
            "  --segment-correction on|off  each template's frames turned onto the landmarks first\n"
            "                       (default off)\n"
            "  -h, --help           this help\n\n"
            "Routes (schemas/serve-*.schema.json, schemas/serve-ws-frame.md):\n"
            "  GET  /               the web viewer\n"
            "  GET  /ws             WebSocket avatar stream (?format=f32|i16)\n"
            "  GET  /api/status     store, avatar, index, uptime, frames\n"
            "  GET  /api/avatar     the avatar's rest mesh\n"
            "  POST /api/query      one landmark frame -> nearest templates (?k=N)\n"
            "  POST /api/transfer   {\"template\": ID} and/or {\"landmarks\": [...]} -> GLB\n"
            "  GET  /metrics        Prometheus text (mimic_*)\n",
            MIM_SERVE_DEFAULT_LISTEN, MIM_SERVE_DEFAULT_MAX_BODY, MIM_SERVE_DEFAULT_MAX_CLIENTS);
}

int mim_cmd_serve(int argc, char **argv)
{
    static const struct option longopts[] = {{"store", required_argument, 0, 's'},
                                              {"avatar", required_argument, 0, 'a'}, {"avatar-landmarks", required_argument, 0, 'A'},
                                              {"listen", required_argument, 0, 'l'},
                                              {"max-body", required_argument, 0, 'b'},
                                              {"vest", required_argument, 0, 'v'},
                                              {"vest-pose", required_argument, 0, 'p'},
                                              {"key-rate", required_argument, 0, 'k'},
                                              {"max-clients", required_argument, 0, 'c'},
                                              {"warm-start", required_argument, 0, 'w'},
                                              {"drive", required_argument, 0, 'd'},
                                              {"blend", required_argument, 0, 'B'},
                                              {"segment-correction", required_argument, 0, 'C'},
                                              {"help", no_argument, 0, 'h'},
                                              {0, 0, 0, 0}};
    const char *store = NULL, *avatar = NULL, *avatar_lm = NULL;
    mim_serve_options_t o = {.log = mim_cli_log};
    int c;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "s:a:l:b:v:p:k:c:w:d:B:C:h", longopts, NULL)) != -1) {
        uint64_t v;
        if (c == 's') store = optarg;
        else if (c == 'a') avatar = optarg;
        else if (c == 'A') avatar_lm = optarg;
        else if (c == 'l') o.listen = optarg;
        else if (c == 'v') o.vest = optarg;
        else if (c == 'p') {
            if (mim_cli_pose("serve", "vest-pose", optarg, &o.vest_pose)) return 2;
        }
        else if (c == 'k') {
            if (mim_cli_key_rate("serve", optarg, &o.key_rate)) return 2;
        }
        else if (c == 'w') {
            if (!strcmp(optarg, "auto")) o.warm_start = 0;
            else if (!strcmp(optarg, "on")) o.warm_start = 1;
            else if (!strcmp(optarg, "off")) o.warm_start = -1;
            else {
                fprintf(stderr, "mimic serve: --warm-start '%s' is not auto, on or off\n", optarg);
                return 2;
            }
        }
        else if (c == 'd') {
            if (mim_cli_drive("serve", optarg, &o.drive)) return 2;
        }
        else if (c == 'B') {
            if (mim_cli_number("serve", "blend", optarg, 1, MIM_XFER_BLEND_MAX, &v)) return 2;
            o.blend = (uint32_t)v;
        }
        else if (c == 'C') {
            if (mim_cli_on_off("serve", "segment-correction", optarg, &o.segment_correction)) return 2;
        }
        else if (c == 'c') {
            if (mim_cli_number("serve", "max-clients", optarg, 1, 1000, &v)) return 2;
            o.max_clients = (unsigned)v;
        }
        else if (c == 'b') {
            if (mim_cli_number("serve", "max-body", optarg, 1, (uint64_t)1 << 30, &v)) return 2;
            o.max_body = (size_t)v;
        } else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic serve: unknown or incomplete option '%s' (see mimic serve --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "mimic serve: unexpected argument '%s' (see mimic serve --help)\n", argv[optind]);
        return 2;
    }
    if (!store || !avatar) {
        fprintf(stderr, "mimic serve: --store and --avatar are required (see mimic serve --help)\n");
        return 2;
    }
    const char *listen = o.listen ? o.listen : MIM_SERVE_DEFAULT_LISTEN;
    int host_len = mim_cli_listen("serve", listen);
    if (host_len < 0)
        return 2;

    /* Blocked before the server's threads start, so they inherit the mask
     * and the signals reach sigwait below: shutdown runs in plain code. */
    sigset_t stop;
    sigemptyset(&stop);
    sigaddset(&stop, SIGINT);
    sigaddset(&stop, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop, NULL);
    signal(SIGPIPE, SIG_IGN); /* a client that hangs up is a write error, not a crash */
    /* Every connection is a file descriptor, and the service must outlast
     * hundreds of idle or hostile ones: the soft limit goes up to the hard
     * one. A process-wide act, so the program does it, not serve/. */
    struct rlimit nofile;
    if (!getrlimit(RLIMIT_NOFILE, &nofile) && nofile.rlim_cur < nofile.rlim_max) {
        nofile.rlim_cur = nofile.rlim_max;
        setrlimit(RLIMIT_NOFILE, &nofile);
    }

    mim_error_t err = {0};
    mim_session_t *session = NULL;
    mim_session_options_t so;
    mim_cli_session_options(&so, avatar_lm);
    int rc = mim_session_open(&session, store, &so, &err);
    if (rc) { /* the command cannot run (README: exit status) */
        fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
        return 2;
    }
    if ((rc = mim_session_load_avatar(session, avatar, &err))) { /* bad input, or no index for a foreign avatar */
        fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
        mim_session_close(&session);
        return rc == MIM_ENOINDEX ? 2 : 1;
    }
    mim_serve_t *sv = NULL;
    if (mim_serve_open(&sv, session, &o, &err)) { /* the vest or the address */
        fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
        mim_session_close(&session);
        return 1;
    }
    printf("http://%.*s:%d/\n", host_len, listen, mim_serve_port(sv));
    fflush(stdout);
    fprintf(stderr, "mimic serve: %s with avatar %s on port %d (Ctrl-C stops)\n", store, avatar,
            mim_serve_port(sv));
    int sig = 0;
    sigwait(&stop, &sig);
    fprintf(stderr, "mimic serve: %s: stopping\n", sig == SIGINT ? "SIGINT" : "SIGTERM");
    mim_serve_close(&sv);
    mim_session_close(&session);
    return 0;
}
