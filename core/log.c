/* One-line messages on stderr, prefixed "mimic: ". */
#include "mim_core.h"

#include <stdio.h>

int mim_log_level = 1;

static void vlog(const char *fmt, va_list ap)
{
    fputs("mimic: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
}

void mim_log(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(fmt, ap);
    va_end(ap);
}

void mim_log_verbose(const char *fmt, ...)
{
    if (mim_log_level < 2) return;
    va_list ap;
    va_start(ap, fmt);
    vlog(fmt, ap);
    va_end(ap);
}
