/* CSV tables with a header line (manifests, pose maps): the header names
 * the columns a reader needs, in any order, more allowed; fields may be
 * double-quoted; blank lines and lines starting with '#' are skipped. */
#include "mim_ingest.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CSV_MAX_FIELDS 64

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

int mim_csv_read(const char *path, const char *what, const char *const *columns, int n_columns, mim_csv_row_fn row,
                 void *ctx, mim_error_t *err)
{
    if (n_columns < 1 || n_columns > CSV_MAX_FIELDS) return mim_error_set(err, MIM_EINVAL, "%s: bad column count", path);
    FILE *f = fopen(path, "r");
    if (!f) return mim_error_set(err, -errno, "%s: cannot open %s: %s", path, what, strerror(errno));
    char line[8192];
    char *fields[CSV_MAX_FIELDS];
    int col[CSV_MAX_FIELDS], have_header = 0, rc = 0, need = 0;
    size_t lineno = 0;
    while (!rc && fgets(line, sizeof line, f)) {
        lineno++;
        if (!strchr(line, '\n') && !feof(f)) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%zu: line is longer than %zu characters", path, lineno, sizeof line);
            break;
        }
        trim(line);
        if (!line[0] || line[0] == '#') continue;
        int nf = split_csv(line, fields, CSV_MAX_FIELDS);
        for (int i = 0; i < nf; i++) trim(fields[i]);
        if (!have_header) {
            have_header = 1;
            for (int c = 0; c < n_columns && !rc; c++) {
                col[c] = -1;
                for (int i = 0; i < nf; i++)
                    if (!strcmp(fields[i], columns[c])) col[c] = i;
                if (col[c] < 0) {
                    char names[512] = "";
                    for (int k = 0; k < n_columns; k++)
                        snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s",
                                 k == 0 ? "" : k == n_columns - 1 ? " and " : ", ", columns[k]);
                    rc = mim_error_set(err, MIM_EFORMAT, "%s:%zu: header must name the columns %s", path, lineno, names);
                }
                if (col[c] > need) need = col[c];
            }
            continue;
        }
        if (nf <= need) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%zu: expected at least %d fields, found %d", path, lineno, need + 1,
                               nf);
            break;
        }
        const char *picked[CSV_MAX_FIELDS];
        for (int c = 0; c < n_columns; c++) picked[c] = fields[col[c]];
        rc = row(ctx, picked, lineno, err);
    }
    fclose(f);
    if (!rc && !have_header) rc = mim_error_set(err, MIM_EFORMAT, "%s: %s is empty (no header line)", path, what);
    return rc;
}
