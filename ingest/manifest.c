/* Manifest files: CSV whose header names at least `file`, `subject` and
 * `pose` (any order, more columns allowed); `file` is relative to the
 * manifest's folder. Fields may be double-quoted. */
#include "mim_ingest.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    char *real; /* real path of the file, or NULL if it does not exist */
    char *name; /* the file field as written */
    mim_labels_t labels;
} entry_t;

struct mim_manifest {
    entry_t *e;
    size_t n;
};

typedef struct {
    mim_manifest_t *m;
    char dir[PATH_MAX];
    size_t cap;
} loading_t;

static int manifest_row(void *ctx, const char *const *f, size_t lineno, mim_error_t *err)
{
    (void)lineno, (void)err;
    loading_t *l = ctx;
    mim_manifest_t *m = l->m;
    if (m->n == l->cap) {
        l->cap = l->cap ? l->cap * 2 : 128;
        entry_t *ne = realloc(m->e, l->cap * sizeof *ne);
        if (!ne) return MIM_ENOMEM;
        m->e = ne;
    }
    entry_t *e = &m->e[m->n++];
    memset(e, 0, sizeof *e);
    char full[PATH_MAX * 2], real[PATH_MAX];
    if (f[0][0] == '/') snprintf(full, sizeof full, "%s", f[0]);
    else snprintf(full, sizeof full, "%s/%s", l->dir, f[0]);
    e->name = strdup(f[0]);
    e->real = realpath(full, real) ? strdup(real) : NULL;
    snprintf(e->labels.subject, sizeof e->labels.subject, "%s", f[1]);
    snprintf(e->labels.pose, sizeof e->labels.pose, "%s", f[2]);
    return 0;
}

int mim_manifest_load(mim_manifest_t **out, const char *path, mim_error_t *err)
{
    *out = NULL;
    loading_t l = {.m = calloc(1, sizeof(mim_manifest_t))};
    if (!l.m) return mim_error_set(err, MIM_ENOMEM, "out of memory");
    snprintf(l.dir, sizeof l.dir, "%s", path);
    char *slash = strrchr(l.dir, '/');
    if (slash) *slash = 0;
    else snprintf(l.dir, sizeof l.dir, ".");
    static const char *const columns[] = {"file", "subject", "pose"};
    int rc = mim_csv_read(path, "manifest", columns, 3, manifest_row, &l, err);
    if (rc) {
        mim_manifest_free(&l.m);
        return rc;
    }
    *out = l.m;
    return 0;
}

void mim_manifest_free(mim_manifest_t **pm)
{
    if (!pm || !*pm) return;
    mim_manifest_t *m = *pm;
    for (size_t i = 0; i < m->n; i++) {
        free(m->e[i].real);
        free(m->e[i].name);
    }
    free(m->e);
    free(m);
    *pm = NULL;
}

int mim_manifest_lookup(const mim_manifest_t *m, const char *path, mim_labels_t *out)
{
    char real[PATH_MAX];
    if (realpath(path, real))
        for (size_t i = 0; i < m->n; i++)
            if (m->e[i].real && !strcmp(m->e[i].real, real)) {
                *out = m->e[i].labels;
                return 1;
            }
    /* Files moved away from the manifest: match the bare file name. */
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    for (size_t i = 0; i < m->n; i++) {
        const char *eb = strrchr(m->e[i].name, '/');
        eb = eb ? eb + 1 : m->e[i].name;
        if (!strcmp(eb, base)) {
            *out = m->e[i].labels;
            return 1;
        }
    }
    return 0;
}
