/* Argument helpers shared by the subcommands. */
#include "args.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int mim_cli_number(const char *cmd, const char *name, const char *text, uint64_t lo, uint64_t hi, uint64_t *out)
{
    int ok = text && *text >= '0' && *text <= '9';
    if (ok) {
        errno = 0;
        char *end;
        unsigned long long v = strtoull(text, &end, 10);
        ok = !errno && !*end && v >= lo && v <= hi;
        if (ok) *out = v;
    }
    if (!ok)
        fprintf(stderr, "mimic %s: --%s '%s' is not a number in %" PRIu64 "..%" PRIu64 "\n", cmd, name, text ? text : "",
                lo, hi);
    return ok ? 0 : -1;
}

int mim_cli_key_rate(const char *cmd, const char *text, double *out)
{
    if (!strcmp(text, "auto")) {
        *out = 0.0;
        return 0;
    }
    char *end;
    errno = 0;
    double v = strtod(text, &end);
    if (errno || end == text || *end || !(v > 0.0 && v <= 1000.0)) {
        fprintf(stderr, "mimic %s: --key-rate '%s' is neither auto nor a rate in (0, 1000] Hz\n", cmd, text);
        return -1;
    }
    *out = v;
    return 0;
}

int mim_cli_listen(const char *cmd, const char *listen)
{
    const char *colon = strrchr(listen, ':');
    if (!colon || colon == listen || !colon[1] || strspn(colon + 1, "0123456789") != strlen(colon + 1)) {
        fprintf(stderr, "mimic %s: --listen '%s' is not HOST:PORT (e.g. 127.0.0.1:8080)\n", cmd, listen);
        return -1;
    }
    return (int)(colon - listen);
}

int mim_cli_template_id(const char *cmd, const char *name, const char *text, uint64_t *id)
{
    int ok = text && *text >= '0' && *text <= '9';
    if (ok) {
        errno = 0;
        char *end;
        unsigned long long v = strtoull(text, &end, 10);
        ok = !errno && !*end && v >= 1;
        if (ok) *id = v;
    }
    if (!ok)
        fprintf(stderr, "mimic %s: --%s '%s' is not a template id (a number from mimic list)\n", cmd, name,
                text ? text : "");
    return ok ? 0 : -1;
}
