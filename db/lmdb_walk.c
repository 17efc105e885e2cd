/* LMDB's b-tree pages checked by reading them with pread, before LMDB
 * follows them through its map. LMDB trusts its pages: a damaged node
 * offset or size sends it past the page, past the file's end (SIGBUS) or
 * out of the map (SIGSEGV). Within one read transaction (its snapshot
 * pinned, so no writer recycles a page under the walk) this reads the
 * snapshot's meta page and walks the trees from its roots, checking every
 * page it reaches (liblmdb 0.9, 64-bit: page and node layouts below). An
 * open walks the table list and the root page of every table (a few page
 * reads); mim_db_check walks everything.
 *
 *   page:  u64 pgno, u16 pad, u16 flags, u16 lower, u16 upper (or u32
 *          pages for overflow), then u16 node offsets from byte 16
 *   node:  u16 lo, u16 hi (leaf: data size; branch: child page with flags
 *          as bits 32..47), u16 flags (F_BIGDATA 1, F_SUBDATA 2,
 *          F_DUPDATA 4), u16 key size, key, data
 *   LEAF2: (lower - 16) / 2 fixed-size keys from byte 16 (DUPFIXED)
 *   MDB_db (48 bytes, a named table or a duplicate sub-tree):
 *          u32 pad (LEAF2 key size), u16 flags, u16 depth, u64 branch,
 *          leaf, overflow pages, u64 entries, u64 root */
#include "internal.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define HDR 16
#define P_BRANCH 0x01
#define P_LEAF 0x02
#define P_OVERFLOW 0x04
#define P_LEAF2 0x20
#define P_SUBP 0x40
#define F_BIGDATA 0x01
#define F_SUBDATA 0x02
#define F_DUPDATA 0x04
#define DB_DUPSORT 0x04 /* MDB_DUPSORT, as kept in MDB_db.md_flags */
#define DB_DUPFIXED 0x10
#define P_INVALID UINT64_MAX
#define MAX_DEPTH 32 /* LMDB's CURSOR_STACK */

typedef struct {
    mim_db_t *db;
    uint32_t psize;
    uint64_t last_pg;
    int full;
    uint8_t *seen; /* full walks: a page reached twice is a loop or a cross-link */
    unsigned char *bufs[MAX_DEPTH + 2];
    mim__db_walk_fn problem;
    void *ctx;
    const char *table; /* where the walk is, for messages */
    int table_index;   /* DBI_*, or -1 */
    int in_main;       /* walking the table list (LMDB's main database) */
    int bit;           /* of `bad` for damage found here: MIM__WALK_* or a DBI_* */
    unsigned bad;      /* bit per DBI_* with a damaged page; bit DBI_COUNT_: LMDB's own trees */
    uint64_t pages;
} walk_t;

static uint16_t u16_at(const unsigned char *p) { uint16_t v; memcpy(&v, p, 2); return v; }
static uint32_t u32_at(const unsigned char *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t u64_at(const unsigned char *p) { uint64_t v; memcpy(&v, p, 8); return v; }

__attribute__((format(printf, 3, 4))) static int bad(walk_t *w, uint64_t pgno, const char *fmt, ...)
{
    char what[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    w->bad |= 1u << w->bit;
    if (w->problem) {
        char line[512];
        snprintf(line, sizeof line, "store damaged: %s: LMDB page %llu (%s): %s", w->db->path, (unsigned long long)pgno,
                 w->table, what);
        w->problem(w->ctx, w->table_index >= 0 ? mim__db_table_names[w->table_index] : "lmdb", line);
    }
    return -1;
}

static int read_page(walk_t *w, uint64_t pgno, unsigned char *buf)
{
    if (pgno < 2 || pgno > w->last_pg)
        return bad(w, pgno, "page number outside the store's pages 2..%llu", (unsigned long long)w->last_pg);
    if (w->seen) {
        if (w->seen[pgno >> 3] & (1u << (pgno & 7))) return bad(w, pgno, "reached twice (a loop or a cross-link)");
        w->seen[pgno >> 3] |= (uint8_t)(1u << (pgno & 7));
    }
    ssize_t n = pread(w->db->fd, buf, w->psize, (off_t)(pgno * w->psize));
    if (n != (ssize_t)w->psize) return bad(w, pgno, "cannot be read (%s)", n < 0 ? strerror(errno) : "short read");
    if (u64_at(buf) != pgno) return bad(w, pgno, "holds page %llu's header", (unsigned long long)u64_at(buf));
    w->pages++;
    return 0;
}

static int walk_tree(walk_t *w, uint64_t root, uint16_t db_flags, uint32_t ksize, int depth);

/* An overflow record's first page: its run of pages fits, and holds dsize. */
static int check_overflow(walk_t *w, uint64_t pgno, uint32_t dsize)
{
    unsigned char *p = w->bufs[MAX_DEPTH + 1];
    if (read_page(w, pgno, p)) return -1;
    uint32_t pages = u32_at(p + 12);
    if (!(u16_at(p + 10) & P_OVERFLOW)) return bad(w, pgno, "not the overflow page a record names");
    if (pages == 0 || pgno + pages - 1 > w->last_pg || (uint64_t)pages * w->psize - HDR < dsize)
        return bad(w, pgno, "overflow run of %u pages does not hold its %u bytes inside the store", pages, dsize);
    if (w->seen)
        for (uint64_t q = pgno + 1; q < pgno + pages; q++) {
            if (w->seen[q >> 3] & (1u << (q & 7))) return bad(w, q, "reached twice (a loop or a cross-link)");
            w->seen[q >> 3] |= (uint8_t)(1u << (q & 7));
        }
    return 0;
}

/* The nodes of one page (or of a duplicate sub-page of `size` bytes inside
 * a leaf). Reads the first page of every overflow record it names; follows
 * children and duplicate sub-trees in full walks and in the table list,
 * and each table named in the table list. */
static int check_page(walk_t *w, uint64_t pgno, const unsigned char *p, size_t size, uint16_t db_flags,
                      uint32_t ksize, int depth)
{
    uint16_t flags = u16_at(p + 10), lower = u16_at(p + 12), upper = u16_at(p + 14);
    int leaf2 = flags & P_LEAF2, branch = flags & P_BRANCH, deeper = w->full || w->in_main;
    if (!(flags & (P_BRANCH | P_LEAF)) || (branch && (flags & (P_LEAF | P_LEAF2))))
        return bad(w, pgno, "not a b-tree page (flags 0x%x)", flags);
    if (lower < HDR || lower > upper || upper > size || (lower - HDR) % 2)
        return bad(w, pgno, "free-space bounds %u..%u do not fit a page of %zu bytes", lower, upper, size);
    unsigned n = (lower - HDR) / 2u;
    if (branch && n == 0) return bad(w, pgno, "a branch page without children");
    if (leaf2) {
        if (flags & P_SUBP) ksize = u16_at(p + 8); /* a sub-page keeps its key size in its pad */
        if (!ksize || HDR + (size_t)n * ksize > size) return bad(w, pgno, "%u keys of %u bytes do not fit", n, ksize);
        return 0;
    }
    for (unsigned i = 0; i < n; i++) {
        size_t off = u16_at(p + HDR + 2 * i);
        if (off < upper || off + 8 > size) return bad(w, pgno, "node %u at byte %zu is outside the page's data", i, off);
        const unsigned char *node = p + off;
        uint16_t nflags = u16_at(node + 4), nk = u16_at(node + 6);
        if (off + 8 + nk > size) return bad(w, pgno, "node %u: its key of %u bytes runs past the page", i, nk);
        if (branch) {
            uint64_t child = u16_at(node) | (uint64_t)u16_at(node + 2) << 16 | (uint64_t)nflags << 32;
            if (deeper && walk_tree(w, child, db_flags, ksize, depth + 1)) return -1;
            continue;
        }
        uint32_t dsize = u16_at(node) | (uint32_t)u16_at(node + 2) << 16;
        const unsigned char *data = node + 8 + nk;
        if (nflags & F_BIGDATA) {
            if (off + 8 + nk + 8 > size) return bad(w, pgno, "node %u: its overflow page number runs past the page", i);
            if (check_overflow(w, u64_at(data), dsize)) return -1;
            continue;
        }
        if (off + 8 + nk + dsize > size) return bad(w, pgno, "node %u: its %u data bytes run past the page", i, dsize);
        if (nflags & F_SUBDATA) {
            if (dsize != 48) return bad(w, pgno, "node %u: a sub-database record of %u bytes", i, dsize);
            uint16_t sub_flags = u16_at(data + 4);
            uint32_t sub_ksize = u32_at(data);
            uint64_t sub_root = u64_at(data + 40);
            if (nflags & F_DUPDATA) { /* a key's duplicates, as a sub-tree */
                if (w->full && walk_tree(w, sub_root, sub_flags, sub_ksize, depth + 1)) return -1;
            } else if (w->in_main) { /* a named table: its name, then its tree */
                char name[48], label[80];
                size_t len = nk < sizeof name - 1 ? nk : sizeof name - 1;
                for (size_t c = 0; c < len; c++) name[c] = node[8 + c] >= 32 && node[8 + c] < 127 ? (char)node[8 + c] : '?';
                name[len] = 0;
                int index = -1;
                for (int t = 0; t < DBI_COUNT_; t++)
                    if (nk == strlen(mim__db_table_names[t]) && !memcmp(node + 8, mim__db_table_names[t], nk)) index = t;
                snprintf(label, sizeof label, "table '%s'", name);
                const char *saved = w->table;
                w->table = label, w->table_index = index, w->in_main = 0, w->bit = index >= 0 ? index : MIM__WALK_LIST;
                walk_tree(w, sub_root, sub_flags, sub_ksize, depth + 1); /* its damage is its own */
                w->table = saved, w->table_index = -1, w->in_main = 1, w->bit = MIM__WALK_LIST;
            }
        } else if (nflags & F_DUPDATA) { /* a key's duplicates, in a sub-page */
            if (dsize < HDR || !(u16_at(data + 10) & P_SUBP))
                return bad(w, pgno, "node %u: duplicates without a valid sub-page", i);
            if (check_page(w, pgno, data, dsize, db_flags, ksize, depth)) return -1;
        }
    }
    return 0;
}

static int walk_tree(walk_t *w, uint64_t root, uint16_t db_flags, uint32_t ksize, int depth)
{
    if (root == P_INVALID) return 0; /* an empty tree */
    if (depth >= MAX_DEPTH) return bad(w, root, "the tree is deeper than LMDB allows");
    unsigned char *p = w->bufs[depth];
    if (read_page(w, root, p)) return -1;
    return check_page(w, root, p, w->psize, db_flags, ksize, depth);
}

int mim__db_walk(mim_db_t *db, MDB_txn *txn, int full, mim__db_walk_fn problem, void *ctx, unsigned *bad_tables,
                 uint64_t *pages)
{
    walk_t w = {.db = db, .psize = db->page_size, .full = full, .problem = problem, .ctx = ctx, .table_index = -1};
    if (bad_tables) *bad_tables = 0;
    if (pages) *pages = 0;
    /* the snapshot's own meta page: LMDB keeps the last two */
    uint64_t txnid = mdb_txn_id(txn);
    unsigned char meta[152];
    int found = 0;
    for (int i = 0; i < 2 && !found; i++) {
        if (pread(db->fd, meta, sizeof meta, (off_t)i * db->page_size) != (ssize_t)sizeof meta) break;
        found = u64_at(meta + 144) == txnid;
    }
    if (!found) return 0; /* overwritten since (two commits): nothing to compare with */
    w.last_pg = u64_at(meta + 136);
    int rc = 0;
    for (int i = 0; i < MAX_DEPTH + 2 && !rc; i++)
        if (!(w.bufs[i] = malloc(w.psize))) rc = MIM_ENOMEM;
    if (!rc && full && !(w.seen = calloc(w.last_pg / 8 + 1, 1))) rc = MIM_ENOMEM;
    if (!rc) {
        w.table = "free-page list";
        w.bit = MIM__WALK_FREE;
        walk_tree(&w, u64_at(meta + 40 + 40), u16_at(meta + 40 + 4), u32_at(meta + 40), 0);
        w.table = "table list";
        w.in_main = 1;
        w.bit = MIM__WALK_LIST;
        walk_tree(&w, u64_at(meta + 88 + 40), u16_at(meta + 88 + 4), u32_at(meta + 88), 0);
    }
    for (int i = 0; i < MAX_DEPTH + 2; i++) free(w.bufs[i]);
    free(w.seen);
    if (bad_tables) *bad_tables = w.bad;
    if (pages) *pages = w.pages;
    return rc;
}
