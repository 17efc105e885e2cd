/* bench/serve's side of the processes (serve_procs.c): the real `mimic`
 * binaries it runs as children, their CPU from /proc, and plain HTTP GETs
 * to the service (/metrics, /api/status; tests/support/http_client.h).
 * serve.c is the load itself. */
#ifndef MIM_BENCH_SERVE_PROCS_H
#define MIM_BENCH_SERVE_PROCS_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

extern const char *sb_bin; /* the mimic binary */
extern char sb_dir[4096];  /* the run's folder: children's logs, store, pty */
extern int sb_port;        /* the service's port */

typedef struct sb_child {
    pid_t pid;
    int out; /* read end of its stdout, kept open until it is killed */
    const char *name;
    char log[4200];
} sb_child_t;

#define MAX_TASKS 512
typedef struct sb_tasks {
    int n;
    int tid[MAX_TASKS];
    double cpu[MAX_TASKS];
} sb_tasks_t;

double sb_now(void);
uint64_t sb_now_us(void);
/* Starts `mimic args...` with stdout to a pipe (or /dev/null) and stderr
 * to D/name.log. The child dies with the bench (PR_SET_PDEATHSIG). */
int sb_spawn(sb_child_t *c, const char *name, char *const args[], int want_stdout);
void sb_print_log_tail(const sb_child_t *c);
/* Waits for it to exit, at most timeout seconds (then kills it); its exit
 * status, or -1. */
int sb_wait_child(sb_child_t *c, double timeout);
void sb_stop_child(sb_child_t *c);
/* Runs `mimic args...` to completion (at most timeout seconds); 0 if it
 * exited 0. */
int sb_run_mimic(const char *name, char *const args[], double timeout);
/* The first line of a child's stdout, waiting at most timeout seconds. */
int sb_first_line(sb_child_t *c, char *buf, size_t size, double timeout);
/* utime + stime of a process (or one of its tasks) in seconds; -1 if gone. */
double sb_proc_cpu(const char *stat_path);
double sb_pid_cpu(pid_t pid);
double sb_self_cpu(void);
void sb_task_cpu(pid_t pid, sb_tasks_t *t);
double sb_loadavg1(void);
/* GET path, tried up to 3 times (each failure is told on stderr). */
char *sb_http_get(const char *path);
/* A counter or gauge without labels from Prometheus text; -1 if absent. */
double sb_metric(const char *text, const char *name);
/* The same, of one session: name{session="session"} (serve's per-session
 * lines, issue 16); -1 if absent. */
double sb_metric_session(const char *text, const char *name, const char *session);

#endif
