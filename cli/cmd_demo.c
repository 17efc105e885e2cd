/* mimic demo: the whole system in one command, with nothing from outside.
 * synth bodies -> template store -> recognition index -> a simulated vest
 * on a pseudo-terminal playing the built-in motion -> mimic serve (viewer,
 * WebSocket stream, API) on that vest -> demo.glb, the served sequence as
 * a morph-target animation. The steps are the subcommands themselves, run
 * in this process, so the demo shows what a user would run by hand. */
#include "args.h"
#include "commands.h"
#include "mim_io.h"
#include "mim_serve.h"
#include "mim_vest.h"
#include "output.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

#define MARKER ".mimic-demo"
#define GLB_FPS 10.0     /* frames of the served sequence kept for demo.glb */
#define GLB_MAX_FRAMES 600u
#define MAX_VESTS 16
#define SUBJECTS 4

static void help(FILE *out)
{
    fprintf(out,
            "usage: mimic demo [--dir DIR] [--duration S] [--headless] [--listen HOST:PORT]\n"
            "                  [--key-rate auto|HZ] [--vests N]\n\n"
            "Runs mimic end to end with data it makes itself: synthetic bodies (4 subjects x\n"
            "12 poses) into a template store, its recognition index, a simulated vest on a\n"
            "pseudo-terminal playing a built-in motion, and mimic serve on that vest. The\n"
            "viewer's URL goes to stdout on a line of its own; open it in a browser. When it\n"
            "stops (after --duration, or Ctrl-C / SIGTERM) it writes DIR/demo.glb, the served\n"
            "avatar sequence as a glTF animation (%g frames a second).\n\n"
            "  --dir DIR            where the bodies, the store and demo.glb go (default\n"
            "                       mimic-demo); a folder of an earlier demo is reused, any\n"
            "                       other non-empty folder is refused\n"
            "  --duration S         stop after S seconds (default: run until Ctrl-C)\n"
            "  --headless           do not try to open a browser\n"
            "  --listen HOST:PORT   where to serve (default %s; port 0: any free port)\n"
            "  --key-rate auto|HZ   as mimic serve (default auto)\n"
            "  --vests N            N simulated vests (default 1, at most %d), each driving its own\n"
            "                       avatar (another subject's body) in a session of one mimic serve:\n"
            "                       default, vest2, vest3, ... (the viewer switches between them);\n"
            "                       demo.glb records the first\n"
            "  -h, --help           this help\n",
            GLB_FPS, MIM_SERVE_DEFAULT_LISTEN, MAX_VESTS);
}

/* ---- the served sequence, kept for demo.glb ---- */
typedef struct recorder {
    pthread_mutex_t lock;
    uint32_t n_vertices, n, cap;
    mim_mesh_t faces; /* the avatar's faces (positions unused), kept past the service */
    float *positions; /* cap frames */
    double *times;
    uint64_t t0, last;
    int started;
} recorder_t;

static void record_frame(void *user, const mim_serve_frame_t *f)
{
    recorder_t *r = user;
    if (strcmp(f->session, MIM_SERVE_DEFAULT_SESSION)) /* the first vest's avatar only */
        return;
    pthread_mutex_lock(&r->lock);
    if (!r->started)
        r->t0 = f->t_vest_us, r->started = 1, r->last = f->t_vest_us - (uint64_t)(1e6 / GLB_FPS);
    if (r->n < r->cap && f->t_vest_us >= r->last + (uint64_t)(1e6 / GLB_FPS) && f->n_vertices == r->n_vertices) {
        memcpy(r->positions + 3 * (size_t)r->n_vertices * r->n, f->positions, 3 * (size_t)f->n_vertices * sizeof(float));
        r->times[r->n] = (double)(f->t_vest_us - r->t0) * 1e-6;
        /* times must increase strictly, also as float32 */
        if (r->n && (float)r->times[r->n] <= (float)r->times[r->n - 1])
            r->times[r->n] = r->times[r->n - 1] + 1e-3;
        r->n++;
        r->last = f->t_vest_us;
    }
    pthread_mutex_unlock(&r->lock);
}

/* ---- the simulated vest, on its own thread ---- */
typedef struct vest_thread {
    mim_vest_sim_t *sim;
    pthread_t thread;
    int inited, started;
    char out[4300];
    volatile int stop;
    pthread_mutex_t lock;
    pthread_cond_t ready_cv;
    int ready, done, rc;
    mim_error_t err;
} vest_thread_t;

static void sim_ready(void *user, const char *path)
{
    vest_thread_t *v = user;
    (void)path;
    pthread_mutex_lock(&v->lock);
    v->ready = 1;
    pthread_cond_broadcast(&v->ready_cv);
    pthread_mutex_unlock(&v->lock);
}

static void *sim_main(void *arg)
{
    vest_thread_t *v = arg;
    mim_vest_sim_run_t run = {.out = v->out, .ready = sim_ready, .user = v, .stop = &v->stop};
    int rc = mim_vest_sim_run(v->sim, &run, &v->err);
    pthread_mutex_lock(&v->lock);
    v->rc = rc, v->done = 1;
    pthread_cond_broadcast(&v->ready_cv);
    pthread_mutex_unlock(&v->lock);
    return NULL;
}

/* A simulated vest playing motion on the pseudo-terminal at pty, on a
 * thread of its own: 0 once it is ready (vt->started then says the thread
 * must be stopped), else the error. */
static int vest_start(vest_thread_t *vt, const mim_vest_motion_t *motion, const char *pty, mim_error_t *err)
{
    pthread_mutex_init(&vt->lock, NULL);
    pthread_cond_init(&vt->ready_cv, NULL);
    vt->inited = 1;
    snprintf(vt->out, sizeof vt->out, "pty:%s", pty);
    mim_vest_sim_options_t so = {.rate_hz = 60, .loop = 1};
    int rc = mim_vest_sim_open(&vt->sim, motion, &so, err);
    vt->started = !rc && pthread_create(&vt->thread, NULL, sim_main, vt) == 0;
    if (!rc && !vt->started)
        rc = mim_error_set(err, MIM_ENOMEM, "cannot start the simulated vest's thread");
    if (vt->started) {
        pthread_mutex_lock(&vt->lock);
        while (!vt->ready && !vt->done)
            pthread_cond_wait(&vt->ready_cv, &vt->lock);
        if (vt->done && vt->rc)
            rc = vt->rc, *err = vt->err;
        pthread_mutex_unlock(&vt->lock);
    }
    return rc;
}

static void vest_stop(vest_thread_t *vt)
{
    if (vt->started) {
        vt->stop = 1;
        pthread_join(vt->thread, NULL);
    }
    mim_vest_sim_close(&vt->sim);
    if (vt->inited) {
        pthread_cond_destroy(&vt->ready_cv);
        pthread_mutex_destroy(&vt->lock);
    }
}

static int remove_entry(const char *path, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb, (void)flag, (void)ftw;
    return remove(path) && errno != ENOENT ? -1 : 0;
}

/* DIR ready for a new demo: made, or an earlier demo's bodies and store removed. */
static int prepare_dir(const char *dir, char *sub, size_t size)
{
    if (mkdir(dir, 0777) && errno != EEXIST) {
        fprintf(stderr, "mimic demo: %s: cannot make the folder: %s\n", dir, strerror(errno));
        return -1;
    }
    snprintf(sub, size, "%s/%s", dir, MARKER);
    if (access(sub, F_OK)) {
        /* not an earlier demo's folder: only an empty one is taken */
        int empty = 1;
        DIR *d = opendir(dir);
        for (struct dirent *e; d && empty && (e = readdir(d)) != NULL;)
            empty = !strcmp(e->d_name, ".") || !strcmp(e->d_name, "..");
        if (d)
            closedir(d);
        if (!d || !empty) {
            fprintf(stderr, "mimic demo: %s: %s; choose another --dir\n", dir,
                    d ? "not empty and not the folder of an earlier demo" : strerror(errno));
            return -1;
        }
        FILE *f = fopen(sub, "w");
        if (!f || fclose(f)) {
            fprintf(stderr, "mimic demo: %s: cannot write: %s\n", sub, strerror(errno));
            return -1;
        }
    }
    const char *const old[] = {"bodies", "store"};
    for (size_t i = 0; i < 2; i++) {
        snprintf(sub, size, "%s/%s", dir, old[i]);
        if (!access(sub, F_OK) && nftw(sub, remove_entry, 16, FTW_DEPTH | FTW_PHYS)) {
            fprintf(stderr, "mimic demo: %s: cannot remove the earlier demo's files: %s\n", sub, strerror(errno));
            return -1;
        }
    }
    return 0;
}

/* xdg-open on the viewer's URL, as a child of its own (no shell: the host
 * is the user's text); a failure only costs the convenience. */
static void open_browser(int host_len, const char *listen, int port)
{
    char url[512];
    snprintf(url, sizeof url, "http://%.*s:%d/", host_len, listen, port);
    char *const argv[] = {"xdg-open", url, NULL};
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    posix_spawnattr_t at; /* the demo blocks SIGINT and SIGTERM; the browser must not */
    sigset_t none;
    sigemptyset(&none);
    posix_spawnattr_init(&at);
    posix_spawnattr_setsigmask(&at, &none);
    posix_spawnattr_setflags(&at, POSIX_SPAWN_SETSIGMASK);
    pid_t pid;
    if (posix_spawnp(&pid, "xdg-open", &fa, &at, argv, environ) != 0)
        fprintf(stderr, "mimic demo: could not start xdg-open; open the URL above in a browser\n");
    posix_spawnattr_destroy(&at);
    posix_spawn_file_actions_destroy(&fa);
}

static int step(const char *title, int (*cmd)(int, char **), char **argv)
{
    int argc = 0;
    while (argv[argc])
        argc++;
    printf("== %s\n", title);
    fflush(stdout);
    int rc = cmd(argc, argv);
    fflush(stdout);
    if (rc)
        fprintf(stderr, "mimic demo: the step '%s' failed\n", title);
    return rc;
}

int mim_cmd_demo(int argc, char **argv)
{
    static const struct option longopts[] = {{"dir", required_argument, 0, 'd'},
                                              {"duration", required_argument, 0, 't'},
                                              {"headless", no_argument, 0, 'H'},
                                              {"listen", required_argument, 0, 'l'},
                                              {"key-rate", required_argument, 0, 'k'},
                                              {"vests", required_argument, 0, 'n'},
                                              {"help", no_argument, 0, 'h'},
                                              {0, 0, 0, 0}};
    const char *dir = "mimic-demo", *listen = MIM_SERVE_DEFAULT_LISTEN;
    double duration = 0.0, key_rate = 0.0;
    int headless = 0, c;
    uint64_t vests = 1;
    optind = 0;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "d:t:Hl:k:n:h", longopts, NULL)) != -1) {
        if (c == 'd') dir = optarg;
        else if (c == 'n') {
            if (mim_cli_number("demo", "vests", optarg, 1, MAX_VESTS, &vests)) return 2;
        }
        else if (c == 'l') listen = optarg;
        else if (c == 'H') headless = 1;
        else if (c == 'k') {
            if (mim_cli_key_rate("demo", optarg, &key_rate)) return 2;
        } else if (c == 't') {
            if (mim_cli_real("demo", "duration", optarg, 0.0, 86400.0, 1, "is not a number of seconds in (0, 86400]",
                             &duration))
                return 2;
        } else if (c == 'h') return help(stdout), 0;
        else {
            fprintf(stderr, "mimic demo: unknown or incomplete option '%s' (see mimic demo --help)\n",
                    argv[optind - 1]);
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "mimic demo: unexpected argument '%s' (see mimic demo --help)\n", argv[optind]);
        return 2;
    }
    int host_len = mim_cli_listen("demo", listen);
    if (host_len < 0)
        return 2;

    char bodies[4200], store[4200], pty[4200], glb[4200];
    if (prepare_dir(dir, bodies, sizeof bodies))
        return 2;
    snprintf(bodies, sizeof bodies, "%s/bodies", dir);
    snprintf(store, sizeof store, "%s/store", dir);
    snprintf(pty, sizeof pty, "%s/vest", dir);
    snprintf(glb, sizeof glb, "%s/demo.glb", dir);

    char *synth_argv[] = {"synth", "--out", bodies, "--subjects", "4", "--poses", "12", NULL}; /* SUBJECTS */
    char *ingest_argv[] = {"ingest", "--store", store, bodies, NULL};
    char *index_argv[] = {"index", "--store", store, NULL};
    if (step("mimic synth: 4 subjects x 12 poses of synthetic bodies", mim_cmd_synth, synth_argv) ||
        step("mimic ingest: the bodies into the template store", mim_cmd_ingest, ingest_argv) ||
        step("mimic index: pose recognition (angle descriptor, per-class SVMs, FLANN)", mim_cmd_index, index_argv))
        return 1;

    /* Blocked before any thread starts, so that they inherit the mask and
     * the signals reach sigtimedwait below. */
    sigset_t stop;
    sigemptyset(&stop);
    sigaddset(&stop, SIGINT);
    sigaddset(&stop, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop, NULL);
    signal(SIGPIPE, SIG_IGN);

    printf("== mimic vest simulate: the built-in motion on %s (%s%s)\n",
           vests > 1 ? "pseudo-terminals" : "a pseudo-terminal", pty, vests > 1 ? ", vest2, ..." : "");
    fflush(stdout);
    mim_error_t err = {0};
    mim_vest_motion_t motion = {0};
    vest_thread_t vt[MAX_VESTS] = {{0}};
    int rc = mim_vest_motion_demo(&motion, &err);
    for (uint64_t i = 0; !rc && i < vests; i++) {
        char path[4200];
        if (i)
            snprintf(path, sizeof path, "%s/vest%llu", dir, (unsigned long long)i + 1);
        rc = vest_start(&vt[i], &motion, i ? path : pty, &err);
    }

    recorder_t rec = {.cap = GLB_MAX_FRAMES};
    pthread_mutex_init(&rec.lock, NULL);
    mim_session_t *session = NULL;
    mim_serve_t *sv = NULL;
    char vest_spec[4300];
    snprintf(vest_spec, sizeof vest_spec, "serial:%s", pty);
    if (!rc) {
        printf("== mimic serve: the avatar (template 1) driven by the vest%s\n",
               vests > 1 ? "; each other vest drives another body in a session of its own" : "");
        fflush(stdout);
        mim_serve_options_t o = {.listen = listen, .vest = vest_spec, .vest_pose = MIM_VEST_POSE_T,
                                 .key_rate = key_rate, .on_frame = record_frame, .user = &rec,
                                 .log = mim_cli_log};
        /* frames that arrive before the recorder is sized below are skipped:
         * its n_vertices is 0 until then */
        mim_session_options_t so;
        mim_cli_session_options(&so, NULL);
        rc = mim_session_open(&session, store, &so, &err);
        if (!rc)
            rc = mim_session_load_avatar(session, "1", &err);
        if (!rc)
            rc = mim_serve_open(&sv, session, &o, &err);
        for (uint64_t i = 1; !rc && i < vests; i++) {
            /* vest N drives pose 1 of subject N (cycling through the 4) */
            mim_serve_session_spec_t spec = {0};
            snprintf(spec.name, sizeof spec.name, "vest%llu", (unsigned long long)i + 1);
            snprintf(spec.avatar, sizeof spec.avatar, "%llu", (unsigned long long)(1 + 12 * (i % SUBJECTS)));
            snprintf(spec.vest, sizeof spec.vest, "serial:%s/vest%llu", dir, (unsigned long long)i + 1);
            printf("== session %s: template %s driven by %s\n", spec.name, spec.avatar, spec.vest);
            fflush(stdout);
            rc = mim_serve_session_add(sv, &spec, &err);
        }
    }
    if (!rc) {
        const mim_mesh_t *mesh = mim_serve_avatar_mesh(sv);
        pthread_mutex_lock(&rec.lock);
        rec.positions = malloc((size_t)rec.cap * 3 * mesh->n_vertices * sizeof(float));
        rec.times = malloc(rec.cap * sizeof(double));
        rec.faces.n_vertices = mesh->n_vertices, rec.faces.n_faces = mesh->n_faces;
        rec.faces.faces = malloc(3 * (size_t)mesh->n_faces * sizeof(uint32_t));
        if (rec.positions && rec.times && rec.faces.faces) {
            memcpy(rec.faces.faces, mesh->faces, 3 * (size_t)mesh->n_faces * sizeof(uint32_t));
            rec.n_vertices = mesh->n_vertices;
        } else {
            fprintf(stderr, "mimic demo: out of memory for the recording: no demo.glb will be written\n");
        }
        pthread_mutex_unlock(&rec.lock);
        printf("http://%.*s:%d/\n", host_len, listen, mim_serve_port(sv));
        fflush(stdout);
        fprintf(stderr, "mimic demo: the viewer is at http://%.*s:%d/ (%s)\n", host_len, listen,
                mim_serve_port(sv), duration > 0 ? "stops after --duration" : "Ctrl-C stops");
        if (!headless && getenv("DISPLAY"))
            open_browser(host_len, listen, mim_serve_port(sv));
        const double t_start = mim_now();
        double t_end = duration > 0 ? t_start + duration : INFINITY, t_report = t_start + 1.0;
        for (;;) {
            double now = mim_now(), wait = fmin(t_end, t_report) - now;
            if (wait <= 0 && now >= t_end)
                break;
            struct timespec ts = {(time_t)fmax(wait, 0), (long)(fmod(fmax(wait, 0), 1.0) * 1e9)};
            int sig = sigtimedwait(&stop, NULL, &ts);
            if (sig == SIGINT || sig == SIGTERM) {
                fprintf(stderr, "mimic demo: %s: stopping\n", sig == SIGINT ? "SIGINT" : "SIGTERM");
                break;
            }
            if (mim_now() >= t_report) {
                fprintf(stderr, "mimic demo: %.0f s, %llu frames served, vest %s\n", mim_now() - t_start,
                        (unsigned long long)mim_serve_frames(sv), mim_serve_vest_state(sv));
                t_report += 1.0;
            }
        }
    }
    mim_serve_close(&sv);
    mim_session_close(&session);
    for (uint64_t i = 0; i < vests; i++)
        vest_stop(&vt[i]);
    mim_vest_motion_free(&motion);
    if (rc) {
        fprintf(stderr, "mimic demo: %s\n", mim_error_text(&err));
    } else if (rec.n == 0) {
        fprintf(stderr, "mimic demo: no frame was served, so no %s\n", glb);
        rc = 1;
    } else {
        /* the served sequence, one morph target a kept frame, at its vest times */
        mim_io_sequence_t seq = {.mesh = &rec.faces, .n_frames = rec.n, .positions = rec.positions,
                                   .times = rec.times};
        rc = mim_io_write_sequence_glb(glb, &seq, &err);
        if (rc)
            fprintf(stderr, "mimic demo: %s\n", mim_error_text(&err));
        else
            printf("== wrote %s: %u frames of the served avatar over %.1f s\n", glb, rec.n, rec.times[rec.n - 1]);
    }
    free(rec.faces.faces);
    free(rec.positions);
    free(rec.times);
    pthread_mutex_destroy(&rec.lock);
    return rc ? 1 : 0;
}
