/* Reading a file into memory: one place for the open, grow and error
 * handling that the landmark map, mesh and motion readers share. */
#include "mim_core.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int mim_file_read(const char *path, size_t max_bytes, char **text, size_t *len, mim_error_t *err)
{
    *text = NULL;
    *len = 0;
    size_t limit = max_bytes ? max_bytes : SIZE_MAX - 1;
    FILE *f = fopen(path, "rb");
    if (!f) return mim_error_set(err, -errno, "%s: cannot open: %s", path, strerror(errno));
    /* The size is only a hint for the first allocation: reading goes on to
     * the end, since a pipe has none and a file may grow meanwhile. */
    size_t cap = 65536;
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && S_ISREG(st.st_mode))
        cap = (uint64_t)st.st_size < limit ? (size_t)st.st_size + 1 : limit;
    if (cap > limit) cap = limit;
    size_t n = 0;
    char *b = malloc(cap + 1);
    while (b) {
        n += fread(b + n, 1, cap - n, f);
        if (n < cap || cap == limit) break; /* end of file, read error, or the limit */
        size_t grown = cap > limit / 2 ? limit : cap * 2;
        char *nb = realloc(b, grown + 1);
        if (!nb) free(b);
        b = nb;
        cap = grown;
    }
    if (!b) {
        fclose(f);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        free(b);
        return mim_error_set(err, MIM_EIO, "%s: read error", path);
    }
    b[n] = 0;
    *text = b;
    *len = n;
    return 0;
}
