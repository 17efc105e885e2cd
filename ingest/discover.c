/* Dataset discovery: the mesh files under the paths a user gives, in a
 * stable (sorted) order so that ingest assigns ids deterministically.
 * Symlinks are followed, but every real folder (device, inode) is walked
 * once: a link back into the walk is a loop, reported once and skipped,
 * and the rest of the folder goes on; a dangling link is a failed input. */
#include "mim_ingest.h"
#include "mim_io.h"

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <search.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MAX_DEPTH 64

typedef struct {
    char **v;
    size_t n, cap;
} strvec;

static int push(strvec *s, const char *p)
{
    if (s->n == s->cap) {
        size_t cap = s->cap ? s->cap * 2 : 64;
        char **nv = realloc(s->v, cap * sizeof *nv);
        if (!nv) return MIM_ENOMEM;
        s->v = nv;
        s->cap = cap;
    }
    if (!(s->v[s->n] = strdup(p))) return MIM_ENOMEM;
    s->n++;
    return 0;
}

static int pushf(strvec *s, const char *fmt, ...) __attribute__((format(printf, 2, 3), noinline));
static int pushf(strvec *s, const char *fmt, ...)
{
    char line[8400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    return push(s, line);
}

static void strvec_free(strvec *s)
{
    for (size_t i = 0; i < s->n; i++) free(s->v[i]);
    free(s->v);
    memset(s, 0, sizeof *s);
}

/* A real folder: where it is, and the path it was first met under. */
typedef struct {
    dev_t dev;
    ino_t ino;
    char path[];
} seen_t;

static int cmp_seen(const void *a, const void *b)
{
    const seen_t *x = a, *y = b;
    if (x->dev != y->dev) return x->dev < y->dev ? -1 : 1;
    return x->ino < y->ino ? -1 : x->ino > y->ino;
}

typedef struct {
    void *walked;    /* seen_t tree: folders entered */
    void *ancestors; /* seen_t tree: the folders that hold the root */
    const char *root;
    strvec files, failed, skipped;
} walk_t;

static const seen_t *find(void *const *tree, const struct stat *st)
{
    seen_t key = {.dev = st->st_dev, .ino = st->st_ino};
    void *const *hit = tfind(&key, tree, cmp_seen);
    return hit ? *(seen_t *const *)hit : NULL;
}

static int remember(void **tree, const struct stat *st, const char *path)
{
    seen_t *s = malloc(sizeof *s + strlen(path) + 1);
    if (!s) return MIM_ENOMEM;
    s->dev = st->st_dev;
    s->ino = st->st_ino;
    strcpy(s->path, path);
    void *r = tsearch(s, tree, cmp_seen);
    if (!r) {
        free(s);
        return MIM_ENOMEM;
    }
    if (*(seen_t **)r != s) free(s); /* already there */
    return 0;
}

/* The folders above the root ("/", "/data", ... of its real path): a link
 * to one of them would walk the root again from above. */
static int remember_ancestors(walk_t *w, const char *root)
{
    char real[PATH_MAX];
    if (!realpath(root, real)) return 0; /* the walk reports what is wrong with it */
    for (char *slash = real;; slash++) {
        slash = strchr(slash, '/');
        if (!slash) break;
        char keep = slash[1];
        if (slash == real) slash[1] = 0; /* "/" */
        else *slash = 0;
        struct stat st;
        int rc = stat(real, &st) == 0 ? remember(&w->ancestors, &st, real) : 0;
        if (slash == real) slash[1] = keep;
        else *slash = '/';
        if (rc) return rc;
    }
    return 0;
}

/* A symlink that stat cannot follow (errno se): a loop of links is skipped,
 * a link to nothing is a failed input. Out of line: walk recurses. */
static __attribute__((noinline)) int broken_link(walk_t *w, const char *path, int se)
{
    char target[4096];
    ssize_t tl = readlink(path, target, sizeof target - 1);
    target[tl > 0 ? tl : 0] = 0;
    if (se == ELOOP)
        return pushf(&w->skipped, "%s: symlink loop (the link to %s never resolves), skipped", path, target);
    if (se == ENOENT || se == ENOTDIR)
        return pushf(&w->failed, "%s: dangling symlink to %s", path, target);
    return pushf(&w->failed, "%s: symlink to %s cannot be followed: %s", path, target, strerror(se));
}

/* A folder met in the walk: walk it, unless it has been walked already. */
static int walk(walk_t *w, const char *dir, int depth, int via_link, mim_error_t *err);

static int enter(walk_t *w, const char *path, const struct stat *st, int via_link, int depth, mim_error_t *err)
{
    const seen_t *s = find(&w->walked, st);
    if (s)
        return via_link ? pushf(&w->skipped, "%s: symlink loop (already walked as %s), skipped", path, s->path)
                        : pushf(&w->skipped, "%s: folder already walked as %s (a bind mount?), skipped", path, s->path);
    if ((s = find(&w->ancestors, st)))
        return pushf(&w->skipped, "%s: symlink loop (to %s, which holds %s), skipped", path, s->path, w->root);
    if (depth > MAX_DEPTH)
        return pushf(&w->failed, "%s: folders nest deeper than %d levels, not walked", path, MAX_DEPTH);
    int rc = remember(&w->walked, st, path);
    return rc ? rc : walk(w, path, depth, via_link, err);
}

static int walk(walk_t *w, const char *dir, int depth, int via_link, mim_error_t *err)
{
    DIR *d = opendir(dir);
    if (!d) {
        int e = errno;
        if (depth == 0) return mim_error_set(err, -e, "%s: cannot list folder: %s", dir, strerror(e));
        return pushf(&w->failed, "%s: cannot list folder: %s", dir, strerror(e));
    }
    int rc = 0;
    struct dirent *e;
    char path[4096];
    while (!rc && (e = readdir(d))) {
        if (e->d_name[0] == '.') continue; /* ., .., hidden files and temp files */
        int n = snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (n < 0 || (size_t)n >= sizeof path) {
            rc = pushf(&w->failed, "%s/%s: path longer than %zu bytes, not read", dir, e->d_name, sizeof path - 1);
            continue;
        }
        struct stat st, lst;
        if (lstat(path, &lst) != 0) {
            if (errno != ENOENT) rc = pushf(&w->failed, "%s: cannot read: %s", path, strerror(errno));
            continue; /* ENOENT: removed since it was listed */
        }
        int link = S_ISLNK(lst.st_mode);
        if (!link) {
            st = lst;
        } else if (stat(path, &st) != 0) {
            rc = broken_link(w, path, errno);
            continue;
        }
        if (S_ISDIR(st.st_mode)) rc = enter(w, path, &st, via_link || link, depth + 1, err);
        else if (S_ISREG(st.st_mode) && mim_io_format_known(path)) rc = push(&w->files, path);
    }
    closedir(d);
    return rc;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

int mim_discover(char *const *paths, size_t n, mim_file_list_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    strvec all = {0}, failed = {0}, skipped = {0};
    int rc = 0;
    for (size_t i = 0; i < n && !rc; i++) {
        struct stat st;
        char p[4096];
        snprintf(p, sizeof p, "%s", paths[i]);
        size_t l = strlen(p);
        while (l > 1 && p[l - 1] == '/') p[--l] = 0;
        if (stat(p, &st) == 0 && S_ISDIR(st.st_mode)) {
            walk_t w = {.root = p};
            rc = remember(&w.walked, &st, p);
            if (!rc) rc = remember_ancestors(&w, p);
            if (!rc) rc = walk(&w, p, 0, 0, err);
            tdestroy(w.walked, free);
            tdestroy(w.ancestors, free);
            strvec *from[3] = {&w.files, &w.failed, &w.skipped}, *to[3] = {&all, &failed, &skipped};
            for (int k = 0; k < 3; k++) {
                if (!rc && from[k]->n > 1) qsort(from[k]->v, from[k]->n, sizeof *from[k]->v, cmp_str);
                for (size_t j = 0; j < from[k]->n && !rc; j++) rc = push(to[k], from[k]->v[j]);
                strvec_free(from[k]);
            }
        } else {
            rc = push(&all, p); /* missing or odd paths are reported by the reader */
        }
    }
    if (rc) {
        strvec_free(&all), strvec_free(&failed), strvec_free(&skipped);
        return rc == MIM_ENOMEM && !(err && err->code) ? mim_error_set(err, rc, "out of memory listing the files") : rc;
    }
    out->paths = all.v;
    out->count = all.n;
    out->failed = failed.v;
    out->n_failed = failed.n;
    out->skipped = skipped.v;
    out->n_skipped = skipped.n;
    return 0;
}

void mim_file_list_free(mim_file_list_t *l)
{
    if (!l) return;
    strvec v[3] = {{l->paths, l->count, 0}, {l->failed, l->n_failed, 0}, {l->skipped, l->n_skipped, 0}};
    for (int k = 0; k < 3; k++) strvec_free(&v[k]);
    memset(l, 0, sizeof *l);
}

int mim_discover_landmarks(char *const *paths, size_t n, char *out, size_t size)
{
    for (size_t i = 0; i < n; i++) {
        struct stat st;
        char cand[4096];
        if (stat(paths[i], &st) != 0) continue;
        if (S_ISDIR(st.st_mode)) {
            snprintf(cand, sizeof cand, "%s/landmarks.json", paths[i]);
        } else {
            const char *slash = strrchr(paths[i], '/');
            if (slash) snprintf(cand, sizeof cand, "%.*s/landmarks.json", (int)(slash - paths[i]), paths[i]);
            else snprintf(cand, sizeof cand, "landmarks.json");
        }
        if (stat(cand, &st) == 0 && S_ISREG(st.st_mode)) {
            snprintf(out, size, "%s", cand);
            return 1;
        }
    }
    return 0;
}
