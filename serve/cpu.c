/* The cores the service may run on (its affinity mask; else the cores
 * online), the CPU time the whole process has used, and how idle those
 * cores were (fair.c's capacity: the compute can take what it gets plus
 * what nobody uses). Idle time comes from /proc/stat (Linux: each CPU's
 * idle and iowait ticks), over the CPUs of the affinity mask only; where
 * it cannot be read it is not known. */
#include "internal.h"

#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

void mim__cpu_init(mim__cpu_t *c)
{
    memset(c, 0, sizeof *c);
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0) {
        c->cores = (unsigned)CPU_COUNT(&set);
        for (int i = 0; i < MIM__CPU_MAX && i < CPU_SETSIZE; i++)
            c->mine[i] = (unsigned char)(CPU_ISSET(i, &set) != 0);
    } else {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        c->cores = n > 0 ? (unsigned)n : 1u;
        memset(c->mine, 1, sizeof c->mine);
    }
    long hz = sysconf(_SC_CLK_TCK);
    c->tick = hz > 0 ? 1.0 / (double)hz : 0.01;
}

double mim__cpu_idle_ticks(const char *stat, const unsigned char *mine)
{
    double ticks = 0.0;
    int any = 0;
    for (const char *p = stat; p && *p;) {
        unsigned cpu;
        unsigned long long v[5];
        /* "cpuN user nice system idle iowait ..." (the machine's sum, the
         * first line "cpu ...", does not match) */
        if (sscanf(p, "cpu%u %llu %llu %llu %llu %llu", &cpu, &v[0], &v[1], &v[2], &v[3], &v[4]) == 6 &&
            cpu < MIM__CPU_MAX && mine[cpu])
            ticks += (double)v[3] + (double)v[4], any = 1;
        p = strchr(p, '\n');
        p = p ? p + 1 : NULL;
    }
    return any ? ticks : NAN;
}

void mim__cpu_sample(void *user, mim__fair_sample_t *s)
{
    const mim__cpu_t *c = user;
    struct timespec ts;
    s->wall = mim_now();
    s->process = clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts) ? NAN : (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
    s->idle = NAN;
    FILE *f = fopen("/proc/stat", "re");
    if (!f)
        return;
    char line[512]; /* the cpu lines come first, one at a time */
    double ticks = 0.0;
    int any = 0;
    while (fgets(line, sizeof line, f) && !strncmp(line, "cpu", 3)) {
        double t = mim__cpu_idle_ticks(line, c->mine);
        if (isfinite(t))
            ticks += t, any = 1;
    }
    fclose(f);
    if (any)
        s->idle = ticks * c->tick;
}
