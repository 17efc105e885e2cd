/* A pull reader of JSON (json_pull.h): the grammar of a format asks for
 * the next value and gets it from the bytes at hand, which are read a
 * chunk at a time. No tree and no copy of the text: memory is this
 * struct, whatever the input's size. Strict RFC 8259, as jansson reads it
 * (the library that reads mimic's other JSON), so that a streamed format
 * accepts what it accepted through jansson; skipping a value walks it
 * with the open levels kept as bits, without recursion. */
#include "json_pull.h"

#include <errno.h>
#include <locale.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void mim__jp_init(mim__jp_t *jp, const char *text, size_t len, mim__jp_refill_fn refill, void *src,
                  const char *origin, mim_error_t *err)
{
    memset(jp, 0, sizeof *jp);
    jp->p = (const unsigned char *)text;
    jp->end = jp->p + (text ? len : 0);
    jp->refill = refill;
    jp->src = src;
    jp->origin = origin;
    jp->err = err;
    jp->line = jp->col = 1;
    /* strtod reads the locale's decimal point */
    const char *point = localeconv()->decimal_point;
    jp->point = point[0] ? point[0] : '.';
}

/* The byte at hand, not taken; -1 at the end of the input, -2 failed. */
static int look_more(mim__jp_t *jp)
{
    while (jp->p == jp->end) {
        if (jp->failed)
            return -2;
        if (!jp->refill)
            return -1;
        int r = jp->refill(jp);
        if (r < 0) {
            jp->failed = r < -1 ? r : MIM_EIO;
            return -2;
        }
        if (r == 0)
            jp->refill = NULL;
    }
    return *jp->p;
}

static inline int look(mim__jp_t *jp) { return jp->p < jp->end ? *jp->p : look_more(jp); }

static void take(mim__jp_t *jp)
{
    unsigned char c = *jp->p++;
    if (c == '\n')
        jp->line++, jp->col = 1;
    else if ((c & 0xC0) != 0x80) /* a character, not the rest of one */
        jp->col++;
}

int mim__jp_fail_at(mim__jp_t *jp, unsigned long line, unsigned long col, const char *fmt, ...)
{
    if (jp->failed)
        return jp->failed;
    char what[300];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    jp->failed = MIM_EFORMAT;
    return mim_error_set(jp->err, MIM_EFORMAT, "%s:%lu:%lu: %s", jp->origin, line, col, what);
}

int mim__jp_expected(mim__jp_t *jp, int c, const char *wanted)
{
    if (c == -2 || c < -1)
        return jp->failed;
    if (c == -1)
        return mim__jp_fail(jp, "expected %s, found the end of the input", wanted);
    if (c > ' ' && c < 0x7f)
        return mim__jp_fail(jp, "expected %s, found '%c'", wanted, c);
    return mim__jp_fail(jp, "expected %s, found byte 0x%02x", wanted, (unsigned)c);
}

int mim__jp_peek(mim__jp_t *jp)
{
    for (;;) {
        int c = look(jp);
        if (c == ' ' || c == '\t' || c == '\n' || c == '\r') {
            take(jp);
            continue;
        }
        return c == -2 ? jp->failed : c;
    }
}

int mim__jp_open(mim__jp_t *jp)
{
    int c = mim__jp_peek(jp);
    if (c != '{' && c != '[')
        return mim__jp_expected(jp, c, "'{' or '['");
    if (jp->depth == MIM__JP_MAX_DEPTH)
        return mim__jp_fail(jp, "more than %d levels of nesting", MIM__JP_MAX_DEPTH);
    unsigned char bit = (unsigned char)(1u << (jp->depth % 8));
    if (c == '{')
        jp->kind[jp->depth / 8] |= bit;
    else
        jp->kind[jp->depth / 8] &= (unsigned char)~bit;
    jp->depth++;
    take(jp);
    return 0;
}

static void put(char *buf, size_t size, size_t *n, unsigned char c)
{
    if (buf && *n + 1 < size)
        buf[*n] = (char)c;
    (*n)++;
}

static int hex4(mim__jp_t *jp, unsigned *v)
{
    *v = 0;
    for (int i = 0; i < 4; i++) {
        int c = look(jp), h = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10
                                                            : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
        if (h < 0)
            return c == -2 ? jp->failed : mim__jp_fail(jp, "\\u must be followed by four hex digits");
        *v = *v * 16 + (unsigned)h;
        take(jp);
    }
    return 0;
}

/* \u escape (the 'u' at hand) into a code point: surrogates in pairs, no
 * U+0000. */
static int escape_u(mim__jp_t *jp, unsigned long line, unsigned long col, unsigned *cp)
{
    take(jp);
    int rc = hex4(jp, cp);
    if (rc)
        return rc;
    if (*cp == 0)
        return mim__jp_fail_at(jp, line, col, "\\u0000 is not allowed in a string");
    if (*cp >= 0xDC00 && *cp <= 0xDFFF)
        return mim__jp_fail_at(jp, line, col, "\\u%04X is half of a surrogate pair without its first half", *cp);
    if (*cp >= 0xD800 && *cp <= 0xDBFF) {
        unsigned lo;
        if (look(jp) != '\\')
            return mim__jp_fail_at(jp, line, col, "\\u%04X is half of a surrogate pair without its second half", *cp);
        take(jp);
        if (look(jp) != 'u')
            return mim__jp_fail_at(jp, line, col, "\\u%04X is half of a surrogate pair without its second half", *cp);
        take(jp);
        if ((rc = hex4(jp, &lo)))
            return rc;
        if (lo < 0xDC00 || lo > 0xDFFF)
            return mim__jp_fail_at(jp, line, col, "\\u%04X is half of a surrogate pair without its second half", *cp);
        *cp = 0x10000 + ((*cp - 0xD800) << 10) + (lo - 0xDC00);
    }
    return 0;
}

/* A string (the '"' at hand), decoded into buf (cut to size - 1 bytes,
 * NUL-terminated; NULL: checked only), its full length in *len. */
static int string(mim__jp_t *jp, char *buf, size_t size, size_t *len)
{
    size_t n = 0;
    take(jp);
    for (;;) {
        int c = look(jp);
        if (c < 0)
            return c == -2 ? jp->failed : mim__jp_fail(jp, "the input ends inside a string");
        if (c == '"') {
            take(jp);
            break;
        }
        if (c < 0x20)
            return mim__jp_fail(jp, "control character 0x%02x in a string", (unsigned)c);
        if (c == '\\') {
            unsigned long line = jp->line, col = jp->col;
            take(jp);
            unsigned cp;
            c = look(jp);
            const char *plain = "\"\\/bfnrt", *is = "\"\\/\b\f\n\r\t", *k = c > 0 ? strchr(plain, c) : NULL;
            if (k && *k) {
                cp = (unsigned char)is[k - plain];
                take(jp);
            } else if (c == 'u') {
                int rc = escape_u(jp, line, col, &cp);
                if (rc)
                    return rc;
            } else {
                return c == -2 ? jp->failed : mim__jp_fail_at(jp, line, col, "invalid escape in a string");
            }
            if (cp < 0x80) {
                put(buf, size, &n, (unsigned char)cp);
            } else if (cp < 0x800) {
                put(buf, size, &n, (unsigned char)(0xC0 | cp >> 6));
                put(buf, size, &n, (unsigned char)(0x80 | (cp & 0x3F)));
            } else if (cp < 0x10000) {
                put(buf, size, &n, (unsigned char)(0xE0 | cp >> 12));
                put(buf, size, &n, (unsigned char)(0x80 | ((cp >> 6) & 0x3F)));
                put(buf, size, &n, (unsigned char)(0x80 | (cp & 0x3F)));
            } else {
                put(buf, size, &n, (unsigned char)(0xF0 | cp >> 18));
                put(buf, size, &n, (unsigned char)(0x80 | ((cp >> 12) & 0x3F)));
                put(buf, size, &n, (unsigned char)(0x80 | ((cp >> 6) & 0x3F)));
                put(buf, size, &n, (unsigned char)(0x80 | (cp & 0x3F)));
            }
            continue;
        }
        if (c < 0x80) {
            put(buf, size, &n, (unsigned char)c);
            take(jp);
            continue;
        }
        /* UTF-8: no overlong forms, no surrogates, nothing past U+10FFFF */
        int more;
        int lo = 0x80, hi = 0xBF;
        if (c >= 0xC2 && c <= 0xDF)
            more = 1;
        else if (c >= 0xE0 && c <= 0xEF)
            more = 2, lo = c == 0xE0 ? 0xA0 : 0x80, hi = c == 0xED ? 0x9F : 0xBF;
        else if (c >= 0xF0 && c <= 0xF4)
            more = 3, lo = c == 0xF0 ? 0x90 : 0x80, hi = c == 0xF4 ? 0x8F : 0xBF;
        else
            return mim__jp_fail(jp, "invalid UTF-8 byte 0x%02x", (unsigned)c);
        put(buf, size, &n, (unsigned char)c);
        take(jp);
        for (int i = 0; i < more; i++, lo = 0x80, hi = 0xBF) {
            c = look(jp);
            if (c < lo || c > hi)
                return c == -2 ? jp->failed
                       : c == -1 ? mim__jp_fail(jp, "the input ends inside a string")
                                 : mim__jp_fail(jp, "invalid UTF-8 byte 0x%02x", (unsigned)c);
            put(buf, size, &n, (unsigned char)c);
            take(jp);
        }
    }
    if (buf && size)
        buf[n < size ? n : size - 1] = 0;
    if (len)
        *len = n;
    return 0;
}

/* The start of the next member or item of the open level, whose closing
 * byte is close: 0 after taking close, 1 when one follows (after the ','
 * between two taken), < 0 on error. */
static int next_in(mim__jp_t *jp, int close, int *first)
{
    int c = mim__jp_peek(jp);
    if (c == close) {
        jp->depth--;
        take(jp);
        return 0;
    }
    if (c < -1)
        return c;
    if (!*first) {
        if (c != ',')
            return mim__jp_expected(jp, c, close == '}' ? "',' or '}'" : "',' or ']'");
        take(jp);
    }
    *first = 0;
    return 1;
}

int mim__jp_member(mim__jp_t *jp, int *first, char *key, size_t key_size, size_t *key_len)
{
    int rc = next_in(jp, '}', first);
    if (rc <= 0)
        return rc;
    int c = mim__jp_peek(jp);
    if (c != '"')
        return mim__jp_expected(jp, c, "a member name in double quotes");
    jp->key_line = jp->line, jp->key_col = jp->col;
    if ((rc = string(jp, key, key_size, key_len)))
        return rc;
    c = mim__jp_peek(jp);
    if (c != ':')
        return mim__jp_expected(jp, c, "':'");
    take(jp);
    return 1;
}

int mim__jp_item(mim__jp_t *jp, int *first) { return next_in(jp, ']', first); }

static int is_digit(int c) { return c >= '0' && c <= '9'; }

int mim__jp_number(mim__jp_t *jp, double *v)
{
    char buf[MIM__JP_NUMBER_MAX + 1];
    size_t n = 0;
    int real = 0, c = mim__jp_peek(jp);
    unsigned long line = jp->line, col = jp->col;
#define PUT()                                                                                                        \
    do {                                                                                                             \
        if (n == MIM__JP_NUMBER_MAX)                                                                                 \
            return mim__jp_fail_at(jp, line, col, "a number of more than %d characters", MIM__JP_NUMBER_MAX);               \
        buf[n++] = (char)c;                                                                                          \
        take(jp);                                                                                                    \
        c = look(jp);                                                                                                \
    } while (0)
    if (c == '-')
        PUT();
    if (c == '0') {
        PUT();
        if (is_digit(c))
            return mim__jp_fail_at(jp, line, col, "invalid number: a leading zero");
    } else if (is_digit(c)) {
        while (is_digit(c))
            PUT();
    } else {
        return c == -2 ? jp->failed : mim__jp_fail_at(jp, line, col, "invalid number");
    }
    if (c == '.') {
        real = 1;
        PUT();
        if (!is_digit(c))
            return c == -2 ? jp->failed : mim__jp_fail_at(jp, line, col, "invalid number: no digit after '.'");
        while (is_digit(c))
            PUT();
    }
    if (c == 'e' || c == 'E') {
        real = 1;
        PUT();
        if (c == '+' || c == '-')
            PUT();
        if (!is_digit(c))
            return c == -2 ? jp->failed : mim__jp_fail_at(jp, line, col, "invalid number: no digit in the exponent");
        while (is_digit(c))
            PUT();
    }
#undef PUT
    if (c == -2)
        return jp->failed;
    buf[n] = 0;
    errno = 0;
    if (!real) { /* as jansson: an integer, then its double */
        long long i = strtoll(buf, NULL, 10);
        if (errno == ERANGE)
            return mim__jp_fail_at(jp, line, col, "integer %.40s%s does not fit 64 bits", buf, n > 40 ? "..." : "");
        *v = (double)i;
        return 0;
    }
    char *dot = jp->point != '.' ? strchr(buf, '.') : NULL;
    if (dot)
        *dot = jp->point;
    double x = strtod(buf, NULL);
    if (errno == ERANGE && (x == HUGE_VAL || x == -HUGE_VAL)) {
        if (dot)
            *dot = '.';
        return mim__jp_fail_at(jp, line, col, "number %.40s%s is too large for a double", buf, n > 40 ? "..." : "");
    }
    *v = x;
    return 0;
}

static int literal(mim__jp_t *jp, const char *word)
{
    unsigned long line = jp->line, col = jp->col;
    for (const char *w = word; *w; w++) {
        int c = look(jp);
        if (c != *w)
            return c == -2 ? jp->failed : mim__jp_fail_at(jp, line, col, "invalid literal (null, true or false)");
        take(jp);
    }
    return 0;
}

int mim__jp_null(mim__jp_t *jp)
{
    int c = mim__jp_peek(jp);
    if (c < -1)
        return c;
    if (c != 'n')
        return 0;
    int rc = literal(jp, "null");
    return rc ? rc : 1;
}

int mim__jp_skip(mim__jp_t *jp)
{
    int base = jp->depth;
    for (;;) {
        /* a value */
        int c = mim__jp_peek(jp), rc;
        if (c == '{' || c == '[') {
            int first = 1;
            if ((rc = mim__jp_open(jp)))
                return rc;
            rc = c == '{' ? mim__jp_member(jp, &first, NULL, 0, NULL) : mim__jp_item(jp, &first);
            if (rc < 0)
                return rc;
            if (rc == 1)
                continue; /* its first value */
        } else if (c == '"') {
            if ((rc = string(jp, NULL, 0, NULL)))
                return rc;
        } else if (c == '-' || is_digit(c)) {
            double v;
            if ((rc = mim__jp_number(jp, &v)))
                return rc;
        } else if (c == 't' || c == 'f' || c == 'n') {
            if ((rc = literal(jp, c == 't' ? "true" : c == 'f' ? "false" : "null")))
                return rc;
        } else {
            return mim__jp_expected(jp, c, "a value");
        }
        /* after a value: close levels until one goes on */
        for (;;) {
            if (jp->depth == base)
                return 0;
            int first = 0, d = jp->depth - 1;
            rc = jp->kind[d / 8] >> (d % 8) & 1 ? mim__jp_member(jp, &first, NULL, 0, NULL) : mim__jp_item(jp, &first);
            if (rc < 0)
                return rc;
            if (rc == 1)
                break;
        }
    }
}

int mim__jp_end(mim__jp_t *jp)
{
    int c = mim__jp_peek(jp);
    if (c == -1)
        return 0;
    return c < -1 ? c : mim__jp_fail(jp, "only white space may follow the JSON value, found '%c'",
                                     c > ' ' && c < 0x7f ? c : '?');
}
