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
