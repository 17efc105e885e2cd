/* core's pull reader of JSON (json_pull.c): the values of a text one at a
 * time, as a grammar asks for them, from a buffer or from chunks that a
 * refill function hands over, so that a file is never held whole and no
 * tree is built. Memory is the reader itself; skipped values (members a
 * grammar ignores) are checked and dropped. It accepts exactly RFC 8259
 * JSON as jansson does (UTF-8 checked, no \u0000, no NaN, integers that
 * fit 64 bits, reals that do not overflow, at most MIM__JP_MAX_DEPTH
 * levels), and a number of at most MIM__JP_NUMBER_MAX characters. Every
 * error is one line, "origin:line:column: what", MIM_EFORMAT, recorded in
 * err; after one, every call fails. Internal to core/. */
#ifndef MIM_CORE_JSON_PULL_H
#define MIM_CORE_JSON_PULL_H

#include "mim_core.h"

#define MIM__JP_MAX_DEPTH 2048 /* jansson's */
#define MIM__JP_NUMBER_MAX 512

typedef struct mim__jp mim__jp_t;
/* Sets jp->p and jp->end to the next chunk: 1, or 0 at the end of the
 * input, or a negative code after recording an error in jp->err. */
typedef int (*mim__jp_refill_fn)(mim__jp_t *jp);

struct mim__jp {
    const unsigned char *p, *end; /* the bytes at hand */
    mim__jp_refill_fn refill;     /* NULL: [p, end) is all */
    void *src;                    /* the refill's */
    const char *origin;           /* the start of messages */
    mim_error_t *err;
    unsigned long line, col;      /* of *p, from 1; col counts characters */
    unsigned long key_line, key_col; /* of the last member name */
    int depth, failed;
    char point;                   /* the locale's decimal point, for strtod */
    unsigned char kind[MIM__JP_MAX_DEPTH / 8]; /* per open level: 1 object, 0 array */
};

/* Over a buffer (refill NULL) or chunks. */
void mim__jp_init(mim__jp_t *jp, const char *text, size_t len, mim__jp_refill_fn refill, void *src,
                  const char *origin, mim_error_t *err);
/* The next byte that is not white space, not taken: '{', '[', '"', '-',
 * a digit, a letter...; -1 at the end of the input; < -1 after an error. */
int mim__jp_peek(mim__jp_t *jp);
/* Records "origin:line:column: what" and returns MIM_EFORMAT: at the next
 * byte (_fail), at the last member name that _member read (_fail_key), or
 * where told. */
int mim__jp_fail_at(mim__jp_t *jp, unsigned long line, unsigned long col, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
#define mim__jp_fail(jp, ...) mim__jp_fail_at((jp), (jp)->line, (jp)->col, __VA_ARGS__)
#define mim__jp_fail_key(jp, ...) mim__jp_fail_at((jp), (jp)->key_line, (jp)->key_col, __VA_ARGS__)
/* "expected WANTED, found 'x'" (or the end of the input) for c, what peek
 * gave; an error that peek gave is returned as it is. */
int mim__jp_expected(mim__jp_t *jp, int c, const char *wanted);

/* Containers. _open takes the '{' or '[' that peek showed. _member walks
 * an object: 1 when a member follows (its key, decoded and cut to
 * key_size - 1 bytes, NUL-terminated, in key; its full length in *key_len;
 * the ':' taken), 0 after the closing '}', < 0 on error. _item walks an
 * array likewise: 1 when an item follows, 0 after ']'. *first starts at 1. */
int mim__jp_open(mim__jp_t *jp);
int mim__jp_member(mim__jp_t *jp, int *first, char *key, size_t key_size, size_t *key_len);
int mim__jp_item(mim__jp_t *jp, int *first);

/* Scalars at the next byte. _number: a JSON number as a double (integers
 * through strtoll, as jansson reads them). _null: the literal null (1), or
 * 0 with nothing taken when the value is not null. */
int mim__jp_number(mim__jp_t *jp, double *v);
int mim__jp_null(mim__jp_t *jp);
/* Checks and drops the value at the next byte, however deep (to the depth
 * limit). */
int mim__jp_skip(mim__jp_t *jp);
/* After the top value: only white space may follow. */
int mim__jp_end(mim__jp_t *jp);

#endif
