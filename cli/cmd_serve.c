/* mimic serve: the real-time service over a store and an avatar
 * (mim_serve.h): viewer, WebSocket stream, HTTP JSON API, until SIGINT or
 * SIGTERM. */
#include "args.h"
#include "commands.h"
#include "mim_serve.h"
#include "mim_vest.h"
#include "mim_vest_kinematics.h"
#include "output.h"

#include <getopt.h>
#include <malloc.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic serve --store DIR [--avatar (MESH|ID) [--vest SPEC]] [--vest-pose rest|t|a]\n"
            "                   [--session NAME:vest=SPEC,avatar=MESH|ID[,key-rate=HZ] ...]\n"
            "                   [--sessions FILE.json]\n"
            "                   [--key-rate auto|HZ] [--listen HOST:PORT] [--max-body BYTES]\n"
            "                   [--max-clients N] [--compute-cores C] [--compute-slots N]\n"
            "                   [--warm-start auto|on|off]\n"
            "                   [--drive auto|template|orientation|skeleton]\n"
            "                   [--blend K] [--segment-correction on|off] [--relative on|off]\n\n"
            "Serves pose transfer until Ctrl-C or SIGTERM: the web viewer at /, the avatar\n"
            "stream at /ws and the JSON API. Prints the viewer's URL on stdout.\n"
            "With --vest, every vest frame becomes landmarks on the avatar and one avatar\n"
            "frame on the stream: a key frame (nearest template, then transfer with the\n"
            "cached factor) as often as the measured compute time allows, morphs between.\n"
            "Many vests in one process: each --session is a vest with its own avatar and\n"
            "stream (/ws?session=NAME); they share the store, its index and the cores\n"
            "(--avatar and --vest make the session named default). Give --avatar or a session.\n\n"
            "  --store DIR          the template store (its index, if built, answers /api/query)\n"
            "  --avatar MESH|ID     a mesh file, or a template id; a mesh of another connectivity\n"
            "                       is registered onto the store's once and bound (kept in the store)\n"
            "  --avatar-landmarks FILE  that mesh's landmarks (default: NAME.landmarks.json beside it,\n"
            "                       or a built-in map of its connectivity)\n"
            MIM_CLI_AVATAR_HELP
            "  --vest SPEC          a recording (played in real time), serial:PATH, hid:VID:PID or\n"
            "                       udp:HOST:PORT (as mimic vest replay takes)\n"
            "  --vest-pose P        the wearer's pose at the tare: rest (as the avatar), t or a\n"
            "                       (default rest; every session's)\n"
            "  --session NAME:vest=SPEC,avatar=MESH|ID[,key-rate=HZ]  one more vest and avatar\n"
            "                       (NAME: " MIM_SERVE_SESSION_NAME_RULE "; vest may be left out);\n"
            "                       repeat it for more\n"
            "  --sessions FILE      sessions from a JSON file: {\"sessions\": [{\"name\", \"avatar\",\n"
            "                       \"vest\", \"key_rate\"}, ...]} (schemas/serve-sessions.schema.json)\n"
            "  --key-rate auto|HZ   key frames per second; auto (default): one at every vest\n"
            "                       frame the compute time affords, fewer when it cannot\n"
            "  --listen HOST:PORT   where to listen (default %s; port 0: any free port)\n"
            "  --max-body BYTES     request body limit (default %zu; larger bodies get 413)\n"
            "  --max-clients N      WebSocket clients of one session at once (default %u); a\n"
            "                       client that stopped reading yields its place after %g s and\n"
            "                       is closed after %g s\n"
            "  --compute-cores C    cores the key frames of every session may take together, at\n"
            "                       most (default: the cores the process may run on; less when\n"
            "                       measured busy): past it, every auto session's key rate drops\n"
            "                       alike\n"
            "  --compute-slots N    key frames and morphs computed at once, over all sessions\n"
            "                       (default: the cores the process may run on)\n"
            "  --warm-start W       start each key frame's transfer from the previous one (same\n"
            "                       template): faster, less accurate (bench/RESULTS.md); auto\n"
            "                       (default) only when cold key frames do not fit the vest period\n"
            "  --drive D            what drives key frames: auto (default: the vest's segment\n"
            "                       orientations, one solve; where there are none, the templates'\n"
            "                       frames where --relative holds, else skeleton), template (the\n"
            "                       templates' frames, iterated), orientation or skeleton (the\n"
            "                       avatar's own frames turned by its landmark skeleton, one solve)\n"
            "  --blend K            the template drive blends the frames of the K nearest templates\n"
            "                       (default %d; mimic transfer --help)\n"
            "  --segment-correction on|off  each template's frames turned onto the landmarks first\n"
            "                       (default: where the transfer is not relative)\n"
            "  --relative on|off    the template drive by relative transfer (default on; mimic\n"
            "                       transfer --help)\n"
            "  -h, --help           this help\n\n"
            "Routes (schemas/serve-*.schema.json, schemas/serve-ws-frame.md):\n"
            "  GET  /               the web viewer\n"
            "  GET  /ws             WebSocket avatar stream (?format=f32|i16, ?session=NAME)\n"
            "  GET  /api/status     store, index, uptime, frames, every session\n"
            "  GET  /api/avatar     the avatar's rest mesh (?session=NAME)\n"
            "  POST /api/query      one landmark frame -> nearest templates (?k=N)\n"
            "  POST /api/transfer   {\"template\": ID} and/or {\"landmarks\": [...]} -> GLB\n"
            "                       (?session=NAME)\n"
            "  GET  /api/sessions   the sessions; POST one {\"name\", \"avatar\", \"vest\"} to add it\n"
            "  GET|DELETE /api/sessions/NAME  one session's status; remove it\n"
            "  GET  /metrics        Prometheus text (mimic_*; per session: session=\"NAME\")\n"
            "Without ?session= a route means the first session.\n",
            MIM_SERVE_DEFAULT_LISTEN, MIM_SERVE_DEFAULT_MAX_BODY, MIM_SERVE_DEFAULT_MAX_CLIENTS,
            MIM_SERVE_STALL_YIELD_S, MIM_SERVE_STALL_CLOSE_S, MIM_SESSION_DEFAULT_BLEND);
}

/* The sessions of --session and --sessions, in the order given. */
typedef struct spec_list {
    mim_serve_session_spec_t *v;
    size_t n, cap;
} spec_list_t;

#define MAX_SESSIONS MIM_SERVE_MAX_SESSIONS

static mim_serve_session_spec_t *spec_next(spec_list_t *l)
{
    if (l->n == MAX_SESSIONS) {
        fprintf(stderr, "mimic serve: more than %d sessions\n", MAX_SESSIONS);
        return NULL;
    }
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 8;
        mim_serve_session_spec_t *v = realloc(l->v, cap * sizeof *v);
        if (!v) {
            fprintf(stderr, "mimic serve: out of memory for the sessions\n");
            return NULL;
        }
        l->v = v, l->cap = cap;
    }
    return &l->v[l->n];
}

/* --session NAME:vest=SPEC,avatar=MESH|ID[,key-rate=HZ]: 0, or 2 with the
 * reason on stderr. */
static int add_spec_text(spec_list_t *l, const char *text)
{
    mim_serve_session_spec_t *sp = spec_next(l);
    mim_error_t err = {0};
    if (!sp)
        return 2;
    if (mim_serve_session_spec_parse(text, sp, &err)) {
        fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
        return 2;
    }
    l->n++;
    return 0;
}

/* --sessions FILE: {"sessions": [spec, ...]} (schemas/serve-sessions.schema.json). */
static int add_spec_file(spec_list_t *l, const char *path)
{
    json_error_t je;
    json_t *root = json_load_file(path, JSON_REJECT_DUPLICATES, &je), *list = json_object_get(root, "sessions");
    int rc = 0;
    if (!root) {
        fprintf(stderr, "mimic serve: --sessions %s:%d:%d: %s\n", path, je.line, je.column, je.text);
        rc = 2;
    } else if (!json_is_object(root) || json_object_size(root) != 1 || !json_is_array(list)) {
        fprintf(stderr, "mimic serve: --sessions %s: expected {\"sessions\": [{\"name\", \"avatar\", ...}, ...]}\n",
                path);
        rc = 2;
    }
    for (size_t i = 0; !rc && i < json_array_size(list); i++) {
        mim_serve_session_spec_t *sp = spec_next(l);
        char where[4200];
        snprintf(where, sizeof where, "--sessions %s: sessions[%zu]", path, i);
        mim_error_t err = {0};
        if (!sp)
            rc = 2;
        else if (mim_serve_session_spec_json(json_array_get(list, i), where, sp, &err)) {
            fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
            rc = 2;
        } else
            l->n++;
    }
    json_decref(root);
    return rc;
}

static int run(int argc, char **argv, spec_list_t *specs);

/* A session holds a few MB in arrays of 50 KB to 2 MB (frames, encodings,
 * its factor's workspaces). Freed, they stay in glibc's heap (its mmap
 * threshold rises as such blocks come and go): 256 sessions added and
 * deleted kept all of their 1.3 GB (bench/RESULTS.md, "Memory of
 * sessions"). When a removed session is freed, the heap's free pages go
 * back to the system. (A fixed, low mmap threshold did that too, but cost
 * every key frame a few mmap/munmap pairs of its 220 KB buffers.)
 * Process-wide: decided here, by the command, never by a library. */
static void give_back(void *user)
{
    (void)user;
    malloc_trim(0);
}

int mim_cmd_serve(int argc, char **argv)
{
    spec_list_t specs = {0};
    int rc = run(argc, argv, &specs);
    free(specs.v);
    return rc;
}

static int run(int argc, char **argv, spec_list_t *specs)
{
    static const struct option longopts[] = {{"store", required_argument, 0, 's'},
                                              {"avatar", required_argument, 0, 'a'}, {"avatar-landmarks", required_argument, 0, 'A'}, MIM_CLI_AVATAR_LONGOPTS,
                                              {"listen", required_argument, 0, 'l'},
                                              {"max-body", required_argument, 0, 'b'},
                                              {"vest", required_argument, 0, 'v'},
                                              {"vest-pose", required_argument, 0, 'p'},
                                              {"key-rate", required_argument, 0, 'k'},
                                              {"max-clients", required_argument, 0, 'c'},
                                              {"compute-cores", required_argument, 0, 'P'},
                                              {"compute-slots", required_argument, 0, 'N'},
                                              {"warm-start", required_argument, 0, 'w'},
                                              {"drive", required_argument, 0, 'd'},
                                              {"blend", required_argument, 0, 'B'},
                                              {"segment-correction", required_argument, 0, 'C'},
                                              {"relative", required_argument, 0, 'R'},
                                              {"session", required_argument, 0, 'S'},
                                              {"sessions", required_argument, 0, 'F'},
                                              {"help", no_argument, 0, 'h'},
                                              {0, 0, 0, 0}};
    const char *store = NULL, *avatar = NULL;
    mim_cli_avatar_t av = {0};
    mim_serve_options_t o = {.log = mim_cli_log, .on_session_freed = give_back};
    int c, rc = 0;
    optind = 0;
    opterr = 0;
    while (!rc && (c = getopt_long(argc, argv, "s:a:l:b:v:p:k:c:P:N:w:d:B:C:R:S:F:h", longopts, NULL)) != -1) {
        uint64_t v;
        if (c == 'S') rc = add_spec_text(specs, optarg);
        else if (c == 'F') rc = add_spec_file(specs, optarg);
        else if (c == 's') store = optarg;
        else if (c == 'a') avatar = optarg;
        else if (c == 'A') av.landmarks = optarg;
        else if (c == MIM_CLI_OPT_AVATAR_MESH || c == MIM_CLI_OPT_MAX_DISTANCE) {
            if (mim_cli_avatar_option("serve", c, optarg, &av) < 0) return 2;
        }
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
            o.segment_correction = o.segment_correction ? 1 : -1;
        }
        else if (c == 'R') {
            int on;
            if (mim_cli_on_off("serve", "relative", optarg, &on)) return 2;
            o.relative = on ? 1 : -1;
        }
        else if (c == 'P') {
            if (mim_cli_real("serve", "compute-cores", optarg, 0.0, 1024.0, 1, NULL, &o.compute_cores)) return 2;
        }
        else if (c == 'N') {
            if (mim_cli_number("serve", "compute-slots", optarg, 1, 1024, &v)) return 2;
            o.compute_slots = (unsigned)v;
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
    if (rc)
        return rc;
    if (optind < argc) {
        fprintf(stderr, "mimic serve: unexpected argument '%s' (see mimic serve --help)\n", argv[optind]);
        return 2;
    }
    if (!store || (!avatar && !specs->n)) {
        fprintf(stderr, "mimic serve: --store and --avatar or a --session are required (see mimic serve --help)\n");
        return 2;
    }
    if (o.vest && !avatar) {
        fprintf(stderr, "mimic serve: --vest drives --avatar: give it one (or use --session NAME:vest=...,avatar=...)\n");
        return 2;
    }
    for (size_t i = 0; i < specs->n; i++) {
        int twice = avatar && !strcmp(specs->v[i].name, MIM_SERVE_DEFAULT_SESSION);
        for (size_t j = 0; j < i; j++)
            twice |= !strcmp(specs->v[i].name, specs->v[j].name);
        if (twice) {
            fprintf(stderr, "mimic serve: session %s is given twice%s\n", specs->v[i].name,
                    avatar ? " (--avatar makes the session default)" : "");
            return 2;
        }
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
    mim_cli_session_options(&so, &av);
    rc = mim_session_open(&session, store, &so, &err);
    if (rc) { /* the command cannot run (docs/reference.md: exit statuses) */
        fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
        return 2;
    }
    if (avatar && (rc = mim_session_load_avatar(session, avatar, &err))) { /* bad input, or no index for a foreign avatar */
        fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
        mim_session_close(&session);
        return rc == MIM_ENOINDEX ? 2 : 1;
    }
    if (avatar && o.vest && o.vest_pose == MIM_VEST_POSE_REST) { /* issue 28: say what a tare in another pose needs */
        double deg = 0;
        int pose = mim_session_rest_pose(session, &deg);
        if (pose == MIM_VEST_POSE_T || pose == MIM_VEST_POSE_A)
            fprintf(stderr,
                    "mimic serve: %s stands in %s (upper arms %.0f degrees below the horizontal): --vest-pose rest "
                    "takes the wearer at the tare to stand so; a wearer tared in %s needs --vest-pose %s\n",
                    avatar, pose == MIM_VEST_POSE_T ? "a T-pose" : "an A-pose", deg,
                    pose == MIM_VEST_POSE_T ? "an A-pose" : "a T-pose", pose == MIM_VEST_POSE_T ? "a" : "t");
    }
    mim_serve_t *sv = NULL;
    if (mim_serve_open(&sv, session, &o, &err)) { /* the vest or the address */
        fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
        mim_session_close(&session);
        return 1;
    }
    for (size_t i = 0; i < specs->n; i++) {
        fprintf(stderr, "mimic serve: session %s: avatar %s%s%s\n", specs->v[i].name, specs->v[i].avatar,
                specs->v[i].vest[0] ? ", vest " : "", specs->v[i].vest);
        if ((rc = mim_serve_session_add(sv, &specs->v[i], &err))) {
            fprintf(stderr, "mimic serve: %s\n", mim_error_text(&err));
            mim_serve_close(&sv);
            mim_session_close(&session);
            return rc == MIM_ENOINDEX ? 2 : 1;
        }
    }
    printf("http://%.*s:%d/\n", host_len, listen, mim_serve_port(sv));
    fflush(stdout);
    if (avatar)
        fprintf(stderr, "mimic serve: %s with avatar %s on port %d (Ctrl-C stops)\n", store, avatar,
                mim_serve_port(sv));
    else
        fprintf(stderr, "mimic serve: %s with %zu sessions on port %d (Ctrl-C stops)\n", store, specs->n,
                mim_serve_port(sv));
    int sig = 0;
    sigwait(&stop, &sig);
    fprintf(stderr, "mimic serve: %s: stopping\n", sig == SIGINT ? "SIGINT" : "SIGTERM");
    mim_serve_close(&sv);
    mim_session_close(&session);
    return 0;
}
