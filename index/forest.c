/* A class's FLANN kd-forest as bytes, so that the index blob can keep it
 * and opening an index loads the forests instead of building them again
 * (issue 16: at 1 000 000 templates the build took 7.3 s of the open).
 *
 * FLANN's C API saves to and loads from a file path only. The bytes go
 * through an anonymous in-memory file (memfd_create) named by its
 * /proc/self/fd path: nothing touches the file system, and the file is
 * gone when its descriptor closes. FLANN's saved index holds the trees, not
 * the points: loading takes the class's descriptors as they are in the blob.
 *
 * A forest that cannot be loaded (no memfd on this kernel, no /proc, bytes
 * FLANN refuses) is built again from the descriptors, as before: a saved
 * forest is a cache of a deterministic function of the blob's data, never
 * its only copy. */
#include "internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

static int open_memfd(char *path, size_t size)
{
    int fd = memfd_create("mimic-forest", MFD_CLOEXEC);
    if (fd >= 0)
        snprintf(path, size, "/proc/self/fd/%d", fd);
    return fd;
}

int mim__forest_save(flann_index_t forest, void **bytes, size_t *len, mim_error_t *err)
{
    *bytes = NULL, *len = 0;
    char path[64];
    int fd = open_memfd(path, sizeof path);
    if (fd < 0)
        return mim_error_set(err, MIM_EUNSUPPORTED, "k-NN forest: no in-memory file (%s)", strerror(errno));
    int rc = 0;
    off_t size = flann_save_index_float(forest, path) == 0 ? lseek(fd, 0, SEEK_END) : -1;
    unsigned char *p = size > 0 ? malloc((size_t)size) : NULL;
    if (size <= 0)
        rc = mim_error_set(err, MIM_EUNSUPPORTED, "k-NN forest: FLANN could not save it");
    else if (!p)
        rc = mim_error_set(err, MIM_ENOMEM, "k-NN forest: out of memory (%lld bytes)", (long long)size);
    for (off_t at = 0; !rc && at < size;) {
        ssize_t got = pread(fd, p + at, (size_t)(size - at), at);
        if (got <= 0)
            rc = mim_error_set(err, MIM_EIO, "k-NN forest: cannot read it back (%s)", got < 0 ? strerror(errno) : "short");
        at += got > 0 ? got : 0;
    }
    close(fd);
    if (rc) {
        free(p);
        return rc;
    }
    *bytes = p, *len = (size_t)size;
    return 0;
}

flann_index_t mim__forest_load(const void *bytes, size_t len, float *points, uint32_t rows, uint32_t cols)
{
    char path[64];
    int fd = open_memfd(path, sizeof path);
    if (fd < 0)
        return NULL;
    const unsigned char *p = bytes;
    int ok = 1;
    for (size_t at = 0; ok && at < len;) {
        ssize_t put = write(fd, p + at, len - at);
        ok = put > 0;
        at += put > 0 ? (size_t)put : 0;
    }
    flann_index_t forest = ok ? flann_load_index_float(path, points, (int)rows, (int)cols) : NULL;
    close(fd);
    return forest;
}
