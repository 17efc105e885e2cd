/* The processes of bench/serve: serve_procs.h. */
#include "serve_procs.h"

#include "http_client.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

double sb_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

uint64_t sb_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* ------------------------------------------------------------ children */


const char *sb_bin;
char sb_dir[4096];

/* Starts `mimic args...` with stdout to a pipe (or /dev/null) and stderr
 * to D/name.log. The child dies with the bench (PR_SET_PDEATHSIG). */
int sb_spawn(sb_child_t *c, const char *name, char *const args[], int want_stdout)
{
    memset(c, 0, sizeof *c);
    c->name = name, c->out = -1;
    snprintf(c->log, sizeof c->log, "%s/%s.log", sb_dir, name);
    int p[2] = {-1, -1};
    if (want_stdout && pipe2(p, O_CLOEXEC))
        return -1;
    int n_args = 0;
    while (args[n_args])
        n_args++;
    char **argv = calloc((size_t)n_args + 2, sizeof *argv); /* freed by exec, or below */
    if (!argv)
        return -1;
    int n = 0;
    argv[n++] = (char *)sb_bin;
    for (int i = 0; i < n_args; i++)
        argv[n++] = args[i];
    argv[n] = NULL;
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0)
        return free(argv), -1;
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent)
            _exit(127);
        int e = open(c->log, O_WRONLY | O_CREAT | O_TRUNC, 0644), o = want_stdout ? p[1] : open("/dev/null", O_WRONLY);
        if (e >= 0)
            dup2(e, 2);
        if (o >= 0)
            dup2(o, 1);
        setenv("MIMIC_PROGRESS", "0", 1);
        execv(argv[0], argv);
        fprintf(stderr, "bench_serve: cannot run %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    free(argv);
    c->pid = pid;
    if (want_stdout) {
        close(p[1]);
        c->out = p[0];
    }
    return 0;
}

void sb_print_log_tail(const sb_child_t *c)
{
    FILE *f = fopen(c->log, "r");
    if (!f)
        return;
    char line[1024];
    int n = 0;
    while (fgets(line, sizeof line, f) && n++ < 20)
        fprintf(stderr, "  %s: %s", c->name, line);
    fclose(f);
}

/* Waits for it to exit, at most timeout seconds (then kills it); its exit
 * status, or -1. */
int sb_wait_child(sb_child_t *c, double timeout)
{
    double t0 = sb_now();
    int st;
    for (;;) {
        pid_t r = waitpid(c->pid, &st, WNOHANG);
        if (r == c->pid) {
            c->pid = 0;
            return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
        }
        if (r < 0)
            return -1;
        if (sb_now() - t0 > timeout) {
            kill(c->pid, SIGKILL);
            waitpid(c->pid, &st, 0);
            c->pid = 0;
            return -1;
        }
        usleep(10000);
    }
}

void sb_stop_child(sb_child_t *c)
{
    if (c->pid > 0) {
        kill(c->pid, SIGTERM);
        if (sb_wait_child(c, 5.0) < 0 && c->pid > 0)
            kill(c->pid, SIGKILL);
    }
    if (c->out >= 0)
        close(c->out), c->out = -1;
}

/* Runs `mimic args...` to completion (at most timeout seconds); 0 if it
 * exited 0. */
int sb_run_mimic(const char *name, char *const args[], double timeout)
{
    sb_child_t c;
    if (sb_spawn(&c, name, args, 0))
        return fprintf(stderr, "bench_serve: cannot start mimic %s\n", args[0]), -1;
    int rc = sb_wait_child(&c, timeout);
    if (rc != 0) {
        fprintf(stderr, "bench_serve: mimic %s failed (status %d):\n", args[0], rc);
        sb_print_log_tail(&c);
        return -1;
    }
    return 0;
}

/* The first line of a child's stdout, waiting at most timeout seconds. */
int sb_first_line(sb_child_t *c, char *buf, size_t size, double timeout)
{
    size_t n = 0;
    double t0 = sb_now();
    while (n + 1 < size) {
        double left = timeout - (sb_now() - t0);
        if (left <= 0)
            return -1;
        struct pollfd p = {c->out, POLLIN, 0};
        int r = poll(&p, 1, (int)(left * 1000) + 1);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return -1;
        ssize_t k = read(c->out, buf + n, 1);
        if (k <= 0)
            return -1;
        if (buf[n] == '\n') {
            buf[n] = 0;
            return 0;
        }
        n++;
    }
    return -1;
}

/* utime + stime of a process (or one of its tasks) in seconds; -1 if gone. */
double sb_proc_cpu(const char *stat_path)
{
    FILE *f = fopen(stat_path, "r");
    if (!f)
        return -1;
    char buf[2048];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    char *p = strrchr(buf, ')');
    if (!p)
        return -1;
    unsigned long ut = 0, stt = 0;
    /* after ")": state(3) ppid pgrp session tty tpgid flags minflt cminflt majflt cmajflt utime(14) stime(15) */
    if (sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &stt) != 2)
        return -1;
    return (double)(ut + stt) / (double)sysconf(_SC_CLK_TCK);
}

double sb_pid_cpu(pid_t pid)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    return sb_proc_cpu(path);
}

double sb_self_cpu(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)ru.ru_stime.tv_usec;
}

/* CPU seconds of each task (thread) of a process, by tid. */

void sb_task_cpu(pid_t pid, sb_tasks_t *t)
{
    char path[128];
    snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
    t->n = 0;
    DIR *d = opendir(path);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d)) && t->n < MAX_TASKS) {
        if (e->d_name[0] == '.')
            continue;
        char sp[300];
        snprintf(sp, sizeof sp, "/proc/%d/task/%s/stat", (int)pid, e->d_name);
        double c = sb_proc_cpu(sp);
        if (c >= 0)
            t->tid[t->n] = atoi(e->d_name), t->cpu[t->n++] = c;
    }
    closedir(d);
}

double sb_loadavg1(void)
{
    double l = -1;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (fscanf(f, "%lf", &l) != 1)
            l = -1;
        fclose(f);
    }
    return l;
}

/* ------------------------------------------------------------ HTTP GET (http_client.h) */

int sb_port;

/* GET path once (5 s at most); the body (malloc'd, NUL-terminated), or NULL. */
static char *http_get1(const char *path)
{
    hc_reply_t r;
    int rc = hc_request(&r, sb_port, "GET", path, NULL, NULL, 0, 5000);
    if (rc == HC_ECONNECT) {
        fprintf(stderr, "bench_serve: GET %s: cannot connect to port %d: %s\n", path, sb_port, strerror(errno));
        return NULL;
    }
    if (rc) { /* not sent, or no memory */
        hc_reply_free(&r);
        return NULL;
    }
    if (strncmp(r.raw, "HTTP/1.1 200", 12) || !r.head) {
        char *eol = strchr(r.raw, '\r');
        if (eol)
            *eol = 0;
        fprintf(stderr, "bench_serve: GET %s: %s\n", path, r.raw_len ? r.raw : "no reply");
        hc_reply_free(&r);
        return NULL;
    }
    char *b = r.raw;
    memmove(b, r.body, strlen(r.body) + 1);
    r.raw = NULL;
    hc_reply_free(&r);
    return b;
}

/* GET path, tried up to 3 times (each failure is told on stderr). */
char *sb_http_get(const char *path)
{
    char *b = NULL;
    for (int i = 0; i < 3 && !(b = http_get1(path)); i++)
        usleep(100000);
    return b;
}

/* A counter or gauge without labels from Prometheus text; -1 if absent. */
double sb_metric(const char *text, const char *name)
{
    size_t nl = strlen(name);
    for (const char *p = text; p && *p; p = strchr(p, '\n') ? strchr(p, '\n') + 1 : NULL)
        if (!strncmp(p, name, nl) && p[nl] == ' ')
            return atof(p + nl + 1);
    return -1;
}


/* The same, of one session: name{session="session"}; -1 if absent. */
double sb_metric_session(const char *text, const char *name, const char *session)
{
    char key[256];
    int kl = snprintf(key, sizeof key, "%s{session=\"%s\"} ", name, session);
    if (kl <= 0 || (size_t)kl >= sizeof key)
        return -1;
    for (const char *p = text; p && *p; p = strchr(p, '\n') ? strchr(p, '\n') + 1 : NULL)
        if (!strncmp(p, key, (size_t)kl))
            return atof(p + kl);
    return -1;
}
