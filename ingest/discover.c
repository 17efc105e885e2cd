/* Dataset discovery: the mesh files under the paths a user gives, in a
 * stable (sorted) order so that ingest assigns ids deterministically. */
#include "mim_ingest.h"
#include "mim_io.h"

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

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

static int walk(const char *dir, strvec *out, int depth, mim_error_t *err)
{
    if (depth > 64) return mim_error_set(err, MIM_EINVAL, "%s: folders nest too deep (a symlink loop?)", dir);
    DIR *d = opendir(dir);
    if (!d) return mim_error_set(err, -errno, "%s: cannot list folder: %s", dir, strerror(errno));
    int rc = 0;
    struct dirent *e;
    char path[4096];
    while (!rc && (e = readdir(d))) {
        if (e->d_name[0] == '.') continue; /* ., .., hidden files and temp files */
        int n = snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (n < 0 || (size_t)n >= sizeof path) continue;
        struct stat st;
        if (stat(path, &st) != 0) continue;
        if (S_ISDIR(st.st_mode)) rc = walk(path, out, depth + 1, err);
        else if (S_ISREG(st.st_mode) && mim_io_format_known(path)) rc = push(out, path);
    }
    closedir(d);
    return rc;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

int mim_discover(char *const *paths, size_t n, mim_file_list_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    strvec all = {0};
    int rc = 0;
    for (size_t i = 0; i < n && !rc; i++) {
        struct stat st;
        char p[4096];
        snprintf(p, sizeof p, "%s", paths[i]);
        size_t l = strlen(p);
        while (l > 1 && p[l - 1] == '/') p[--l] = 0;
        if (stat(p, &st) == 0 && S_ISDIR(st.st_mode)) {
            strvec sub = {0};
            rc = walk(p, &sub, 0, err);
            if (!rc) qsort(sub.v, sub.n, sizeof *sub.v, cmp_str);
            for (size_t j = 0; j < sub.n; j++) {
                if (!rc) rc = push(&all, sub.v[j]);
                free(sub.v[j]);
            }
            free(sub.v);
        } else {
            rc = push(&all, p); /* missing or odd paths are reported by the reader */
        }
    }
    if (rc) {
        for (size_t j = 0; j < all.n; j++) free(all.v[j]);
        free(all.v);
        return rc;
    }
    out->paths = all.v;
    out->count = all.n;
    return 0;
}

void mim_file_list_free(mim_file_list_t *l)
{
    if (!l) return;
    for (size_t i = 0; i < l->count; i++) free(l->paths[i]);
    free(l->paths);
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
