/* Files: reading one into memory (the open, grow and error handling that
 * the landmark map, mesh and motion readers share), and the one atomic
 * write (temporary, fsync, rename, fsync of the folder) every writer uses. */
#include "mim_core.h"

#include <errno.h>
#include <fcntl.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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

int mim_file_sync(const char *path)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return errno;
    int e = fsync(fd) != 0 && errno != EINVAL ? errno : 0; /* some file systems cannot sync a folder */
    close(fd);
    return e;
}

int mim_file_sync_folder(const char *path)
{
    const char *slash = strrchr(path, '/');
    char dir[4096];
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else if (slash == path)
        snprintf(dir, sizeof dir, "/");
    else if ((size_t)(slash - path) < sizeof dir)
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
    else
        return ENAMETOOLONG;
    return mim_file_sync(dir);
}

int mim_file_write_atomic(const char *path, const mim_file_part_t *parts, size_t n_parts, mim_error_t *err)
{
    static atomic_uint serial;
    size_t len = strlen(path);
    char *tmp = malloc(len + 48);
    if (!tmp)
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    /* unique per process and call, so concurrent writers of one path never
     * share a temporary; O_EXCL refuses a leftover of the same name */
    snprintf(tmp, len + 48, "%s.tmp.%ld.%u", path, (long)getpid(), atomic_fetch_add(&serial, 1));
    int fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
        int e = errno;
        free(tmp);
        return mim_error_set(err, MIM_EIO, "%s: cannot write: %s", path, strerror(e));
    }
    int e = 0;
    for (size_t p = 0; p < n_parts && !e; p++) {
        const unsigned char *data = parts[p].data;
        for (size_t done = 0; done < parts[p].size && !e;) {
            ssize_t w = write(fd, data + done, parts[p].size - done);
            if (w < 0) {
                if (errno != EINTR)
                    e = errno;
            } else {
                done += (size_t)w;
            }
        }
    }
    if (!e && fsync(fd) != 0)
        e = errno;
    if (close(fd) != 0 && !e)
        e = errno;
    if (!e && rename(tmp, path) != 0)
        e = errno;
    if (e) {
        unlink(tmp);
        free(tmp);
        return mim_error_set(err, MIM_EIO, "%s: cannot write: %s", path, strerror(e));
    }
    free(tmp);
    if ((e = mim_file_sync_folder(path)) != 0)
        return mim_error_set(err, MIM_EIO, "%s: written, but its folder could not be synced: %s", path, strerror(e));
    return 0;
}
