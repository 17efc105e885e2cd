/* Labels from file-name layouts mimic recognises:
 *   FAUST  tr_reg_NNN     subject NNN/10, pose NNN%10
 *   SCAPE  meshNNN        one subject (0), pose NNN
 *   synth / mh-bodies     NAME_sSS_pPP  subject SS, pose PP
 * Numbers are written without leading zeros, as in the manifests. */
#include "mim_ingest.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Parses exactly `digits` digits (or, when digits is 0, one or more). */
static const char *number(const char *s, int digits, long *out)
{
    const char *p = s;
    while (isdigit((unsigned char)*p) && (digits == 0 || p - s < digits)) p++;
    if (p == s || (digits && p - s != digits) || p - s > 9) return NULL;
    *out = strtol(s, NULL, 10);
    return p;
}

int mim_labels_from_name(const char *path, mim_labels_t *out)
{
    memset(out, 0, sizeof *out);
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    char stem[256];
    snprintf(stem, sizeof stem, "%s", base);
    char *dot = strrchr(stem, '.');
    if (dot) *dot = 0;
    long a, b;
    const char *e;
    if (strncmp(stem, "tr_reg_", 7) == 0 && (e = number(stem + 7, 3, &a)) && !*e) {
        snprintf(out->subject, sizeof out->subject, "%ld", a / 10);
        snprintf(out->pose, sizeof out->pose, "%ld", a % 10);
        return 1;
    }
    if (strncmp(stem, "mesh", 4) == 0 && (e = number(stem + 4, 3, &a)) && !*e) {
        snprintf(out->subject, sizeof out->subject, "0");
        snprintf(out->pose, sizeof out->pose, "%ld", a);
        return 1;
    }
    /* ..._sSS_pPP at the end of the stem */
    char *s = strrchr(stem, '_');
    if (s && s[1] == 'p' && (e = number(s + 2, 0, &b)) && !*e) {
        *s = 0;
        char *t = strrchr(stem, '_');
        const char *sub = t ? t + 1 : stem;
        if (sub[0] == 's' && (e = number(sub + 1, 0, &a)) && !*e) {
            snprintf(out->subject, sizeof out->subject, "%ld", a);
            snprintf(out->pose, sizeof out->pose, "%ld", b);
            return 1;
        }
    }
    return 0;
}

/* ---- datasets (issue 30) ---- */

int mim_ingest_dataset_valid(const char *name)
{
    size_t n = name ? strlen(name) : 0;
    if (!n || n > MIM_INGEST_DATASET_MAX) return 0;
    for (size_t i = 0; i < n; i++)
        if (!isalnum((unsigned char)name[i]) && !strchr("._-", name[i])) return 0;
    return strcmp(name, ".") && strcmp(name, "..");
}

/* The last component of dir's real path, in the dataset character set
 * (anything else becomes '_'). */
static void folder_name(const char *dir, char *out, size_t size)
{
    char real[4096];
    const char *p = realpath(dir, real) ? real : dir;
    size_t l = strlen(p);
    while (l > 1 && p[l - 1] == '/') l--;
    size_t b = l;
    while (b > 0 && p[b - 1] != '/') b--;
    size_t k = 0;
    for (size_t i = b; i < l && k + 1 < size && k < MIM_INGEST_DATASET_MAX; i++)
        out[k++] = isalnum((unsigned char)p[i]) || strchr("._-", p[i]) ? p[i] : '_';
    out[k] = 0;
    if (!mim_ingest_dataset_valid(out)) snprintf(out, size, "root");
}

void mim_ingest_dataset_of(char *const *args, size_t n_args, const char *file, char *out, size_t size)
{
    if (!size) return;
    for (size_t i = 0; i < n_args; i++) {
        size_t l = strlen(args[i]);
        while (l > 1 && args[i][l - 1] == '/') l--;
        if (!strncmp(file, args[i], l) && file[l] == '/') { /* found under this folder */
            char dir[4096];
            snprintf(dir, sizeof dir, "%.*s", (int)l, args[i]);
            folder_name(dir, out, size);
            return;
        }
    }
    char dir[4096]; /* a file given as itself: the folder that holds it */
    const char *slash = strrchr(file, '/');
    if (slash) snprintf(dir, sizeof dir, "%.*s", (int)(slash - file == 0 ? 1 : slash - file), file);
    else snprintf(dir, sizeof dir, ".");
    folder_name(dir, out, size);
}
