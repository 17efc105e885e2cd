/* bench/landmark_scan: reading a landmark batch, without recognising it:
 * the streaming reader (mim_landmark_frames_scan_file, each frame handed
 * out and dropped; mim_landmark_frames_read, the frames gathered) against
 * jansson's tree of the same file (json_load_file, the reader mimic had
 * before). Each runs in its own child process, best of --runs (default 3):
 * seconds and how much its peak resident size grew. Never passes or fails.
 *
 * usage: bench_landmark_scan FILE [--landmarks N] [--runs R]
 * (bench/query_batch.sh KEEP=DIR writes a batch at the 64 MiB cap) */
#include "mim_core.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int drop(void *user, const mim_landmark_frame_t *f, mim_error_t *err)
{
    (void)f, (void)err;
    ++*(uint32_t *)user;
    return 0;
}

/* reader 0: scan, 1: read, 2: jansson. Frames (or 1 for jansson's tree), or -1. */
static long run(int reader, const char *path, uint32_t n)
{
    mim_error_t e = {0};
    uint32_t frames = 0;
    if (reader == 0) {
        if (mim_landmark_frames_scan_file(path, n, n - 1, drop, &frames, &e)) return fprintf(stderr, "%s\n", e.msg), -1;
        return frames;
    }
    if (reader == 1) {
        mim_landmark_frames_t f;
        if (mim_landmark_frames_read(path, n, n - 1, &f, &e)) return fprintf(stderr, "%s\n", e.msg), -1;
        frames = f.n_frames;
        mim_landmark_frames_free(&f);
        return frames;
    }
    json_error_t je;
    json_t *j = json_load_file(path, JSON_REJECT_DUPLICATES, &je);
    if (!j) return fprintf(stderr, "%s:%d:%d: %s\n", path, je.line, je.column, je.text), -1;
    long nf = (long)json_array_size(json_object_get(j, "frames"));
    json_decref(j);
    return nf;
}

int main(int argc, char **argv)
{
    const char *path = NULL;
    uint32_t n = 16;
    int runs = 3;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--landmarks") && i + 1 < argc) n = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc) runs = atoi(argv[++i]);
        else if (argv[i][0] != '-' && !path) path = argv[i];
        else return fprintf(stderr, "usage: bench_landmark_scan FILE [--landmarks N] [--runs R]\n"), 2;
    }
    if (!path || n < MIM_LANDMARKS_MIN || runs < 1)
        return fprintf(stderr, "usage: bench_landmark_scan FILE [--landmarks N] [--runs R]\n"), 2;
    static const char *names[] = {"stream, frames dropped (scan_file)", "stream, frames kept (read)",
                                  "jansson tree (json_load_file)"};
    double loadavg[1] = {0};
    getloadavg(loadavg, 1);
    printf("%s, %d runs each, load average %.2f\n%-36s %8s %10s %10s\n", path, runs, loadavg[0], "reader", "frames",
           "seconds", "peak +MiB");
    for (int r = 0; r < 3; r++) {
        double best_s = 1e30, best_mib = 1e30;
        long frames = -1;
        for (int k = 0; k < runs; k++) {
            int fd[2];
            if (pipe(fd)) return 1;
            pid_t pid = fork();
            if (pid == 0) {
                struct rusage r0, r1;
                getrusage(RUSAGE_SELF, &r0);
                double t0 = now();
                long nf = run(r, path, n);
                double out[3] = {(double)nf, now() - t0, 0};
                getrusage(RUSAGE_SELF, &r1);
                out[2] = (double)(r1.ru_maxrss - r0.ru_maxrss) / 1024;
                _exit(write(fd[1], out, sizeof out) == sizeof out ? 0 : 1);
            }
            double got[3] = {-1, 0, 0};
            if (read(fd[0], got, sizeof got) != sizeof got) got[0] = -1;
            waitpid(pid, NULL, 0);
            close(fd[0]), close(fd[1]);
            frames = (long)got[0];
            if (got[1] < best_s) best_s = got[1];
            if (got[2] < best_mib) best_mib = got[2];
        }
        printf("%-36s %8ld %10.2f %10.1f\n", names[r], frames, best_s, best_mib);
    }
    return 0;
}
