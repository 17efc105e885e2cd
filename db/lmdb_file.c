/* The data file checked before LMDB maps it. LMDB maps data.mdb and
 * trusts it: a page past the end of a truncated file is SIGBUS on first
 * touch, not an error. So the two meta pages are read here (LMDB's on-disk
 * layout, 64-bit build of liblmdb 0.9: a 16-byte page header, then MDB_meta)
 * and the newer valid one, which is the one LMDB will use, must describe a
 * map that fits in the file: (last page + 1) * page size <= file size.
 *
 * A meta page, at offset 0 and at offset page size:
 *   0   u64 page number    8 u16 pad   10 u16 flags (P_META 0x08)
 *   16  u32 magic 0xBEEFC0DE          20 u32 data version (1)
 *   24  u64 fixed address             32 u64 map size
 *   40  MDB_db free list (48 bytes: u32 pad = page size, u16 flags,
 *       u16 depth, u64 branch, leaf, overflow pages, u64 entries, u64 root)
 *   88  MDB_db main database
 *   136 u64 last page number          144 u64 transaction id
 *
 * LMDB writes data pages before the meta page that names them and never
 * shrinks the file, so reading the metas first and the size after cannot
 * see a healthy store as short. A store being created by another process
 * (LMDB writes both metas in one write, under its own lock) can look empty
 * for a moment: a failed check is retried for a quarter of a second before
 * it is reported. */
#include "internal.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define META_BYTES 152
#define P_META 0x08
#define LMDB_MAGIC 0xBEEFC0DEu
#define LMDB_DATA_VERSION 1u
#define P_INVALID UINT64_MAX

typedef struct {
    uint32_t psize;
    uint64_t last_pg, txnid, main_root, free_root;
} meta_t;

static uint64_t u64_at(const unsigned char *p, size_t off)
{
    uint64_t v;
    memcpy(&v, p + off, 8);
    return v;
}
static uint32_t u32_at(const unsigned char *p, size_t off)
{
    uint32_t v;
    memcpy(&v, p + off, 4);
    return v;
}

/* Reads the meta page at offset off; a reason when it is not one. */
static const char *read_meta(int fd, off_t off, meta_t *m)
{
    unsigned char b[META_BYTES];
    ssize_t n = pread(fd, b, sizeof b, off);
    if (n < 0) return strerror(errno);
    if (n < (ssize_t)sizeof b) return "it ends inside the page";
    uint16_t flags;
    memcpy(&flags, b + 10, 2);
    if (!(flags & P_META) || u32_at(b, 16) != LMDB_MAGIC) return "no LMDB meta page there";
    if (u32_at(b, 20) != LMDB_DATA_VERSION) return "an LMDB data format this mimic does not read";
    m->psize = u32_at(b, 40);
    m->free_root = u64_at(b, 40 + 40);
    m->main_root = u64_at(b, 88 + 40);
    m->last_pg = u64_at(b, 136);
    m->txnid = u64_at(b, 144);
    return NULL;
}

/* One look at the file: 0, or a reason (written into why) it is damaged. */
static int check_once(const char *file, int *exists, uint32_t *page_size, char *why, size_t why_len)
{
    int fd = open(file, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        if (errno == ENOENT) {
            *exists = 0;
            return 0;
        }
        snprintf(why, why_len, "cannot be read: %s", strerror(errno));
        return -errno;
    }
    *exists = 1;
    int rc = MIM_ESTORE;
    struct stat st;
    meta_t m[2] = {{0}};
    const char *bad;
    if (fstat(fd, &st) != 0) {
        snprintf(why, why_len, "cannot be read: %s", strerror(errno));
        rc = -errno;
    } else if (!S_ISREG(st.st_mode)) {
        snprintf(why, why_len, "not a regular file");
    } else if (st.st_size == 0) {
        snprintf(why, why_len, "empty file (0 bytes): not an LMDB store");
    } else if ((bad = read_meta(fd, 0, &m[0]))) {
        snprintf(why, why_len, "not an LMDB store (first meta page: %s)", bad);
    } else if (m[0].psize < 512 || m[0].psize > 65536 || (m[0].psize & (m[0].psize - 1))) {
        snprintf(why, why_len, "not an LMDB store (meta page gives a page size of %u)", m[0].psize);
    } else if ((bad = read_meta(fd, (off_t)m[0].psize, &m[1]))) {
        snprintf(why, why_len, "truncated or not an LMDB store (second meta page, at byte %u: %s)", m[0].psize, bad);
    } else if (m[1].psize != m[0].psize) {
        snprintf(why, why_len, "meta pages disagree on the page size (%u, %u)", m[0].psize, m[1].psize);
    } else {
        const meta_t *cur = m[1].txnid > m[0].txnid ? &m[1] : &m[0];
        struct stat now; /* the size after the metas were read: the file only grows */
        uint64_t size = fstat(fd, &now) == 0 ? (uint64_t)now.st_size : (uint64_t)st.st_size;
        uint64_t pages = size / cur->psize;
        if (cur->last_pg < 1 || cur->last_pg >= (UINT64_MAX / cur->psize) - 1 || cur->last_pg + 1 > pages) {
            if (cur->last_pg + 1 > pages && cur->last_pg < (UINT64_MAX / cur->psize) - 1)
                snprintf(why, why_len,
                         "truncated: the file has %" PRIu64 " bytes, its newest meta page (transaction %" PRIu64
                         ") says the store uses %" PRIu64 " pages of %u bytes (%" PRIu64 " bytes)",
                         size, cur->txnid, cur->last_pg + 1, cur->psize, (cur->last_pg + 1) * cur->psize);
            else
                snprintf(why, why_len, "meta page gives an impossible last page (%" PRIu64 ")", cur->last_pg);
        } else if ((cur->main_root != P_INVALID && cur->main_root > cur->last_pg) ||
                   (cur->free_root != P_INVALID && cur->free_root > cur->last_pg)) {
            snprintf(why, why_len, "meta page names a root page past the store's last page (%" PRIu64 ")", cur->last_pg);
        } else {
            rc = 0;
            *page_size = cur->psize;
        }
    }
    close(fd);
    return rc;
}

int mim__db_file_check(const char *dir, int *exists, uint32_t *page_size, mim_error_t *err)
{
    char file[4096];
    if ((size_t)snprintf(file, sizeof file, "%s/data.mdb", dir) >= sizeof file)
        return mim_error_set(err, MIM_EINVAL, "%s: store path is too long", dir);
    char why[512];
    int rc = 0;
    *exists = 0;
    *page_size = 0;
    for (int attempt = 0; attempt < 10; attempt++) {
        if (attempt) nanosleep(&(struct timespec){0, 25 * 1000 * 1000}, NULL);
        if ((rc = check_once(file, exists, page_size, why, sizeof why)) == 0) return 0;
        if (rc != MIM_ESTORE) break; /* cannot read it: no point waiting */
    }
    if (rc == MIM_ESTORE) return mim_error_set(err, MIM_ESTORE, "store damaged: %s: %s", file, why);
    return mim_error_set(err, rc, "%s: %s", file, why);
}
