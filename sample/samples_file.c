/* Pose-pair samples as JSON lines (schemas/pair-samples.md): a header line
 * naming the 34 joints, then one pose-pair per line, so that a long run
 * can be read (and appended to) line by line. Written and read here, once. */
#include "internal.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

char *mim_pairs_jsonl_header(void)
{
    json_t *names = mim__pairs_joint_labels();
    json_t *h = json_pack("{s:s, s:o, s:s}", "format", "mimic pair samples 1", "joints", names, "units", "metres");
    char *txt = h ? json_dumps(h, JSON_COMPACT | JSON_PRESERVE_ORDER) : NULL;
    json_decref(h);
    return txt;
}

char *mim_pairs_jsonl_line(const double *joints, double log_density)
{
    json_t *arr = json_array();
    for (int i = 0; arr && i < MIM_PAIR_JOINTS; i++)
        json_array_append_new(arr, json_pack("[f, f, f]", joints[3 * i], joints[3 * i + 1], joints[3 * i + 2]));
    json_t *o = arr ? json_pack("{s:o, s:o}", "joints", arr, "log_density",
                                isfinite(log_density) ? json_real(log_density) : json_null())
                    : NULL;
    char *txt = o ? json_dumps(o, JSON_COMPACT | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(9)) : NULL;
    json_decref(o);
    return txt;
}

void mim_pairs_samples_free(mim_pairs_samples_t *s)
{
    if (!s) return;
    free(s->joints), free(s->log_density), free(s->line);
    memset(s, 0, sizeof *s);
}

static int parse_header(const char *line, size_t len, const char *origin, long ln, mim_error_t *err)
{
    json_error_t je;
    json_t *h = json_loadb(line, len, JSON_REJECT_DUPLICATES, &je);
    json_t *names = h ? json_object_get(h, "joints") : NULL;
    const char *fmt = h ? json_string_value(json_object_get(h, "format")) : NULL;
    int rc = 0;
    if (!h) rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld:%d: %s", origin, ln, je.column, je.text);
    else if (!fmt || strcmp(fmt, "mimic pair samples 1"))
        rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld: not a mimic pair-samples file (the header's \"format\" is not "
                                             "\"mimic pair samples 1\")", origin, ln);
    else if (!json_is_array(names) || json_array_size(names) != MIM_PAIR_JOINTS)
        rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld: the header names %zu joints, not %d", origin, ln,
                           json_is_array(names) ? json_array_size(names) : (size_t)0, MIM_PAIR_JOINTS);
    else {
        json_t *want = mim__pairs_joint_labels();
        for (int i = 0; i < MIM_PAIR_JOINTS && !rc; i++) {
            const char *got = json_string_value(json_array_get(names, (size_t)i));
            const char *w = json_string_value(json_array_get(want, (size_t)i));
            if (!got || !w || strcmp(got, w))
                rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld: joint %d is \"%s\", not \"%s\"", origin, ln, i,
                                   got ? got : "?", w ? w : "?");
        }
        json_decref(want);
    }
    json_decref(h);
    return rc;
}

int mim_pairs_samples_parse(const char *text, size_t len, const char *origin, mim_pairs_samples_t *out,
                            mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!origin) origin = "samples";
    if (!text && len) return mim_error_set(err, MIM_EINVAL, "%s: no text", origin);
    const char *p = text, *end = text + len;
    long line_no = 0;
    uint32_t cap = 0;
    int rc = 0, have_header = 0;
    while (p < end && !rc) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t n = nl ? (size_t)(nl - p) : (size_t)(end - p);
        line_no++;
        const char *line = p;
        p = nl ? nl + 1 : end;
        size_t k = 0;
        while (k < n && (line[k] == ' ' || line[k] == '\t' || line[k] == '\r')) k++;
        if (k == n) continue; /* a blank line */
        if (!have_header) {
            if ((rc = parse_header(line, n, origin, line_no, err))) break;
            have_header = 1;
            continue;
        }
        if (out->n == MIM_PAIRS_SAMPLES_MAX) {
            rc = mim_error_set(err, MIM_EUNSUPPORTED, "%s:%ld: more than %u samples", origin, line_no, MIM_PAIRS_SAMPLES_MAX);
            break;
        }
        if (out->n == cap) {
            uint32_t nc = cap ? 2 * cap : 256;
            double *j = realloc(out->joints, (size_t)nc * 3 * MIM_PAIR_JOINTS * sizeof *j);
            if (j) out->joints = j;
            double *d = realloc(out->log_density, (size_t)nc * sizeof *d);
            if (d) out->log_density = d;
            long *l = realloc(out->line, (size_t)nc * sizeof *l);
            if (l) out->line = l;
            if (!j || !d || !l) {
                rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory at %u samples", origin, out->n);
                break;
            }
            cap = nc;
        }
        json_error_t je;
        json_t *o = json_loadb(line, n, JSON_REJECT_DUPLICATES, &je);
        json_t *arr = o ? json_object_get(o, "joints") : NULL, *ld = o ? json_object_get(o, "log_density") : NULL;
        double *dst = out->joints + (size_t)out->n * 3 * MIM_PAIR_JOINTS;
        if (!o) rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld:%d: %s", origin, line_no, je.column, je.text);
        else if (!json_is_array(arr) || json_array_size(arr) != MIM_PAIR_JOINTS)
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld: \"joints\" must hold %d [x, y, z]", origin, line_no, MIM_PAIR_JOINTS);
        else if (ld && !json_is_number(ld) && !json_is_null(ld))
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld: \"log_density\" is not a number", origin, line_no);
        for (int i = 0; !rc && i < MIM_PAIR_JOINTS; i++) {
            json_t *xyz = json_array_get(arr, (size_t)i);
            if (!json_is_array(xyz) || json_array_size(xyz) != 3) {
                rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld: joint %d is not [x, y, z]", origin, line_no, i);
                break;
            }
            for (int c = 0; c < 3 && !rc; c++) {
                json_t *v = json_array_get(xyz, (size_t)c);
                double x = json_number_value(v);
                if (!json_is_number(v)) rc = mim_error_set(err, MIM_EFORMAT, "%s:%ld: joint %d: a coordinate is not a number", origin, line_no, i);
                else if (!isfinite(x) || fabs(x) > MIM_PLAUSIBLE_REACH_M)
                    rc = mim_error_set(err, MIM_ENONFINITE, "%s:%ld: joint %d: coordinate %g is not within %g m", origin,
                                       line_no, i, x, MIM_PLAUSIBLE_REACH_M);
                else dst[3 * i + c] = x;
            }
        }
        if (!rc) {
            out->line[out->n] = line_no;
            out->log_density[out->n++] = ld && json_is_number(ld) ? json_number_value(ld) : NAN;
        }
        json_decref(o);
    }
    if (!rc && !have_header) rc = mim_error_set(err, MIM_EEMPTY, "%s: empty: no header line", origin);
    if (!rc && !out->n) rc = mim_error_set(err, MIM_EEMPTY, "%s: no samples after the header", origin);
    if (rc) mim_pairs_samples_free(out);
    return rc;
}
