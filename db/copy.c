/* A snapshot copy of a live store (issue 16: a store shipped to replicas).
 *
 * LMDB copies the state of one read transaction while writers go on
 * (mdb_env_copy2), compacted with MDB_CP_COMPACT: free pages are left out
 * and the pages renumbered, so the copy is as small as the data. It is
 * written into a temporary directory beside the destination, flushed, and
 * renamed into place only when whole: a copy that fails half-way (a full
 * disk, a signal) leaves no store at the destination to be mistaken for a
 * good one. */
#include "internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static void remove_tmp(const char *tmp)
{
    char f[4200];
    snprintf(f, sizeof f, "%.4100s/data.mdb", tmp);
    unlink(f);
    snprintf(f, sizeof f, "%.4100s/lock.mdb", tmp);
    unlink(f);
    rmdir(tmp);
}

int mim_db_copy(mim_db_t *db, const char *dst, uint64_t *bytes, mim_error_t *err)
{
    if (!db || !dst || !dst[0]) return mim_error_set(err, MIM_EINVAL, "store copy: no store or destination");
    struct stat st;
    if (lstat(dst, &st) == 0)
        return mim_error_set(err, MIM_EINVAL, "%s: exists: a copy goes to a new directory", dst);
    if (errno != ENOENT) return mim_error_set(err, -errno, "%s: %s", dst, strerror(errno));
    char name[4096], tmp[4100];
    if (snprintf(name, sizeof name, "%s", dst) >= 4000) /* room for the temporary suffix */
        return mim_error_set(err, MIM_EINVAL, "store copy: destination path too long");
    size_t len = strlen(name);
    while (len > 1 && name[len - 1] == '/') name[--len] = 0; /* "dst/" names dst */
    snprintf(tmp, sizeof tmp, "%.4000s.copy-XXXXXX", name); /* name is shorter, checked above */
    if (!mkdtemp(tmp)) return mim_error_set(err, -errno, "%s: cannot make the copy's directory: %s", dst, strerror(errno));
    int rc = mdb_env_copy2(db->env, tmp, MDB_CP_COMPACT);
    if (rc) {
        remove_tmp(tmp);
        return mim_error_set(err, rc > 0 ? -rc : MIM_ESTORE, "%s: copying %s: %s", dst, db->path, mdb_strerror(rc));
    }
    char data[4200];
    snprintf(data, sizeof data, "%.4100s/data.mdb", tmp);
    if ((rc = mim_file_sync(data)) || (rc = mim_file_sync(tmp))) {
        remove_tmp(tmp);
        return mim_error_set(err, -rc, "%s: flushing the copy: %s", dst, strerror(rc));
    }
    if (stat(data, &st) == 0 && bytes) *bytes = (uint64_t)st.st_size;
    /* no replacing: dst may have appeared since the check (an empty
     * directory would be replaced by rename) */
    int moved = renameat2(AT_FDCWD, tmp, AT_FDCWD, dst, RENAME_NOREPLACE);
    if (moved != 0 && errno == EINVAL) /* a file system without it: the check above stands */
        moved = rename(tmp, dst);
    if (moved != 0) {
        rc = -errno;
        remove_tmp(tmp);
        return mim_error_set(err, rc, "%s: cannot put the copy in place: %s", dst, strerror(-rc));
    }
    mim_file_sync_folder(name); /* the new name; the copy is whole either way */
    return 0;
}
