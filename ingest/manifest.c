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

/* Splits one CSV line in place; returns the field count (at most max). */
static int split_csv(char *line, char **fields, int max)
{
    int n = 0;
    char *p = line;
    while (n < max) {
        char *w = p, *start = p;
        if (*p == '"') {
            p++;
            for (;;) {
                if (!*p) break;
                if (*p == '"' && p[1] == '"') {
                    *w++ = '"';
                    p += 2;
                } else if (*p == '"') {
                    p++;
                    break;
                } else {
                    *w++ = *p++;
                }
            }
            while (*p && *p != ',') p++;
        } else {
            while (*p && *p != ',') *w++ = *p++;
        }
        int last = !*p;
        if (*p) p++;
        *w = 0;
        fields[n++] = start;
        if (last) break;
    }
    return n;
}

static void trim(char *s)
{
    size_t n = strlen(s);
    while (n && (s[n - 1] == '\r' || s[n - 1] == '\n' || s[n - 1] == ' ')) s[--n] = 0;
    size_t i = 0;
    while (s[i] == ' ') i++;
    if (i) memmove(s, s + i, n - i + 1);
}

int mim_manifest_load(mim_manifest_t **out, const char *path, mim_error_t *err)
{
    *out = NULL;
    FILE *f = fopen(path, "r");
    if (!f) return mim_error_set(err, -errno, "%s: cannot open manifest: %s", path, strerror(errno));
    mim_manifest_t *m = calloc(1, sizeof *m);
    char dir[PATH_MAX];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash) *slash = 0;
    else snprintf(dir, sizeof dir, ".");

    char line[8192];
    char *fields[64];
    int col_file = -1, col_subject = -1, col_pose = -1, rc = 0;
    size_t cap = 0, lineno = 0;
    while (!rc && m && fgets(line, sizeof line, f)) {
        lineno++;
        if (!strchr(line, '\n') && !feof(f)) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%zu: line is longer than %zu characters", path, lineno, sizeof line);
            break;
        }
        trim(line);
        if (!line[0] || line[0] == '#') continue;
        int nf = split_csv(line, fields, 64);
        for (int i = 0; i < nf; i++) trim(fields[i]);
        if (col_file < 0) { /* header */
            for (int i = 0; i < nf; i++) {
                if (!strcmp(fields[i], "file")) col_file = i;
                if (!strcmp(fields[i], "subject")) col_subject = i;
                if (!strcmp(fields[i], "pose")) col_pose = i;
            }
            if (col_file < 0 || col_subject < 0 || col_pose < 0)
                rc = mim_error_set(err, MIM_EFORMAT, "%s:%zu: header must name the columns file, subject and pose", path,
                                   lineno);
            continue;
        }
        int need = col_file > col_subject ? col_file : col_subject;
        need = need > col_pose ? need : col_pose;
        if (nf <= need) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%zu: expected at least %d fields, found %d", path, lineno,
                               need + 1, nf);
            break;
        }
        if (m->n == cap) {
            cap = cap ? cap * 2 : 128;
            entry_t *ne = realloc(m->e, cap * sizeof *ne);
            if (!ne) {
                rc = MIM_ENOMEM;
                break;
            }
            m->e = ne;
        }
        entry_t *e = &m->e[m->n++];
        memset(e, 0, sizeof *e);
        char full[PATH_MAX * 2], real[PATH_MAX];
        if (fields[col_file][0] == '/') snprintf(full, sizeof full, "%s", fields[col_file]);
        else snprintf(full, sizeof full, "%s/%s", dir, fields[col_file]);
        e->name = strdup(fields[col_file]);
        e->real = realpath(full, real) ? strdup(real) : NULL;
        snprintf(e->labels.subject, sizeof e->labels.subject, "%s", fields[col_subject]);
        snprintf(e->labels.pose, sizeof e->labels.pose, "%s", fields[col_pose]);
    }
    fclose(f);
    if (!rc && col_file < 0) rc = mim_error_set(err, MIM_EFORMAT, "%s: manifest is empty (no header line)", path);
    if (rc) {
        mim_manifest_free(&m);
        return rc;
    }
    *out = m;
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
