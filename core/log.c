/* The log callback helper: libraries format one line and hand it to the
 * caller's callback; where it goes (stderr, a file, nowhere) is the
 * caller's choice, so no library writes to the process's streams. */
#include "mim_core.h"

#include <stdio.h>

void mim_log_emit(mim_log_fn fn, void *ctx, int level, const char *fmt, ...)
{
    if (!fn)
        return;
    char line[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    /* one line, as the callback's contract says */
    for (char *c = line; *c; c++)
        if (*c == '\n' || *c == '\r')
            *c = ' ';
    fn(ctx, level, line);
}
