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

/* A sample line as mimic writes it, read without building a JSON tree
 * (jansson's tree and its per-number locale lookups took 3 s for 100 000
 * lines): an object of "joints" (34 arrays of 3 numbers) and, at most
 * once, "log_density" (a number or null), JSON whitespace anywhere
 * between. Anything else (other keys, escapes, a repeated key, a joint
 * beyond reach, an integer of more than 15 digits, a bad byte) returns 0,
 * and the line goes to jansson, which reads it or says what is wrong. A
 * line read here holds the values jansson's would: a fraction or exponent
 * by strtod (as jansson), an integer exactly (jansson's integers, -0 as
 * 0). */
typedef struct cursor {
    const char *p, *end;
} cursor_t;

static void skip_space(cursor_t *c)
{
    while (c->p < c->end && (*c->p == ' ' || *c->p == '\t' || *c->p == '\r' || *c->p == '\n')) c->p++;
}

static int eat(cursor_t *c, char ch)
{
    skip_space(c);
    if (c->p >= c->end || *c->p != ch) return 0;
    c->p++;
    return 1;
}

static int eat_word(cursor_t *c, const char *w)
{
    skip_space(c);
    const size_t n = strlen(w);
    if ((size_t)(c->end - c->p) < n || memcmp(c->p, w, n)) return 0;
    c->p += n;
    return 1;
}

static int is_digit(char ch) { return ch >= '0' && ch <= '9'; }

/* A JSON number (RFC 8259's grammar), finite. */
static int fast_number(cursor_t *c, double *x)
{
    skip_space(c);
    const char *s = c->p, *q = s;
    if (q < c->end && *q == '-') q++;
    if (q >= c->end || !is_digit(*q)) return 0;
    const char *int_start = q;
    if (*q == '0') q++;
    else
        while (q < c->end && is_digit(*q)) q++;
    const size_t int_digits = (size_t)(q - int_start);
    int real = 0;
    if (q < c->end && *q == '.') {
        real = 1, q++;
        if (q >= c->end || !is_digit(*q)) return 0;
        while (q < c->end && is_digit(*q)) q++;
    }
    if (q < c->end && (*q == 'e' || *q == 'E')) {
        real = 1, q++;
        if (q < c->end && (*q == '+' || *q == '-')) q++;
        if (q >= c->end || !is_digit(*q)) return 0;
        while (q < c->end && is_digit(*q)) q++;
    }
    if (q - s > 63) return 0;
    if (real) {
        char buf[64], *stop;
        memcpy(buf, s, (size_t)(q - s));
        buf[q - s] = 0;
        *x = strtod(buf, &stop);
        if (stop != buf + (q - s)) return 0; /* a locale whose decimal point is not '.' */
    } else {
        if (int_digits > 15) return 0;
        long long v = 0;
        for (const char *d = int_start; d < q; d++) v = 10 * v + (*d - '0');
        *x = (double)(*s == '-' ? -v : v);
    }
    c->p = q;
    return isfinite(*x);
}

int mim__pairs_line_fast(const char *line, size_t n, double *joints, double *log_density)
{
    cursor_t c = {line, line + n};
    int have_joints = 0, have_ld = 0;
    *log_density = NAN;
    if (!eat(&c, '{')) return 0;
    do {
        if (eat_word(&c, "\"joints\"")) {
            if (have_joints++ || !eat(&c, ':') || !eat(&c, '[')) return 0;
            for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
                if ((i && !eat(&c, ',')) || !eat(&c, '[')) return 0;
                for (int k = 0; k < 3; k++)
                    if ((k && !eat(&c, ',')) || !fast_number(&c, &joints[3 * i + k]) || fabs(joints[3 * i + k]) > MIM_PLAUSIBLE_REACH_M)
                        return 0;
                if (!eat(&c, ']')) return 0;
            }
            if (!eat(&c, ']')) return 0;
        } else if (eat_word(&c, "\"log_density\"")) {
            if (have_ld++ || !eat(&c, ':')) return 0;
            if (!eat_word(&c, "null") && !fast_number(&c, log_density)) return 0;
        } else {
            return 0;
        }
    } while (eat(&c, ','));
    if (!eat(&c, '}') || !have_joints) return 0;
    skip_space(&c);
    return c.p == c.end;
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
        double *dst = out->joints + (size_t)out->n * 3 * MIM_PAIR_JOINTS;
        if (mim__pairs_line_fast(line, n, dst, &out->log_density[out->n])) {
            out->line[out->n++] = line_no;
            continue;
        }
        json_error_t je;
        json_t *o = json_loadb(line, n, JSON_REJECT_DUPLICATES, &je);
        json_t *arr = o ? json_object_get(o, "joints") : NULL, *ld = o ? json_object_get(o, "log_density") : NULL;
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
