/* Error codes, their names, and the first-error context. */
#include "mim_core.h"

#include <stdio.h>
#include <string.h>

const char *mim_strerror(int err)
{
    switch (err) {
    case MIM_OK: return "success";
    case MIM_EINVAL: return "invalid argument";
    case MIM_ENOMEM: return "out of memory";
    case MIM_EIO: return "input/output error";
    case MIM_EFORMAT: return "malformed data";
    case MIM_ETRUNCATED: return "file is truncated";
    case MIM_ENONFINITE: return "NaN or infinite coordinate";
    case MIM_EINDEX: return "face index past the vertex count";
    case MIM_EEMPTY: return "empty mesh";
    case MIM_ETOPOLOGY: return "connectivity differs from the store's";
    case MIM_ESCHEMA: return "store has another schema version";
    case MIM_ESTORE: return "store error";
    case MIM_ENOTFOUND: return "not found";
    case MIM_EUNSUPPORTED: return "unsupported";
    case MIM_ENOLANDMARKS: return "no landmark map";
    case MIM_ENOINDEX: return "the store has no index";
    default:
        if (err < 0 && err > -4096) return strerror(-err);
        return "unknown error";
    }
}

int mim_error_set(mim_error_t *e, int code, const char *fmt, ...)
{
    if (e && e->code == 0) {
        e->code = code;
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(e->msg, sizeof e->msg, fmt, ap);
        va_end(ap);
        /* one line: a message never carries a newline */
        for (char *c = e->msg; *c; c++)
            if (*c == '\n' || *c == '\r') *c = ' ';
    }
    return code;
}

void mim_error_clear(mim_error_t *e)
{
    if (e) {
        e->code = 0;
        e->msg[0] = '\0';
    }
}

const char *mim_error_text(const mim_error_t *e)
{
    if (!e) return "";
    if (e->msg[0]) return e->msg;
    return mim_strerror(e->code);
}
