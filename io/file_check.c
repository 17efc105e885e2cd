/* What a mesh file declares about itself, checked before and after the
 * library reads it: header element counts (PLY, OFF), the exact body size of
 * binary PLY and STL, nan/inf spelled out in text files, an OBJ cut mid-line. */
#include "file_check.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

int mim__format_of(const char *path)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash)) return FMT_UNKNOWN;
    static const struct { const char *ext; int fmt; } tab[] = {
        {".off", FMT_OFF}, {".ply", FMT_PLY}, {".obj", FMT_OBJ}, {".stl", FMT_STL}, {".gltf", FMT_GLTF}, {".glb", FMT_GLB},
    };
    for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
        if (strcasecmp(dot, tab[i].ext) == 0) return tab[i].fmt;
    return FMT_UNKNOWN;
}

static uint64_t ply_type_size(const char *t)
{
    static const struct { const char *name; uint64_t size; } tab[] = {
        {"char", 1},  {"uchar", 1},  {"int8", 1},   {"uint8", 1},  {"short", 2},   {"ushort", 2},
        {"int16", 2}, {"uint16", 2}, {"int", 4},    {"uint", 4},   {"int32", 4},   {"uint32", 4},
        {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8},
    };
    for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
        if (strcmp(t, tab[i].name) == 0) return tab[i].size;
    return 0;
}

/* Splits a header line into at most 8 words; 0 words for a blank line. */
static int split_words(char *line, char **w, int max)
{
    int n = 0;
    char *save = NULL;
    for (char *t = strtok_r(line, " \t\r", &save); t && n < max; t = strtok_r(NULL, " \t\r", &save)) w[n++] = t;
    return n;
}

/* The PLY header is checked strictly before OpenMesh sees it: its header
 * parser crashes on some malformed headers. */
static int parse_ply(const char *path, const unsigned char *head, size_t len, mim__decl_t *d, mim_error_t *err)
{
    const char *s = (const char *)head, *end = s + len;
    const char *eh = NULL;
    for (const char *p = s; p + 10 <= end; p++)
        if (memcmp(p, "end_header", 10) == 0 && (p == s || p[-1] == '\n') &&
            (p + 10 == end || p[10] == '\n' || (p[10] == '\r' && p + 11 < end && p[11] == '\n'))) {
            eh = p;
            break;
        }
    if (len < 4 || memcmp(s, "ply", 3) != 0 || (s[3] != '\n' && s[3] != '\r'))
        return mim_error_set(err, MIM_EFORMAT, "%s: not a PLY file (no 'ply' magic line)", path);
    if (!eh) {
        if (d->file_bytes <= len)
            return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: PLY header has no end_header", path);
        return mim_error_set(err, MIM_EFORMAT, "%s: PLY header is longer than 64 KiB", path);
    }
    const char *nl = memchr(eh, '\n', (size_t)(end - eh));
    if (!nl) return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: PLY header has no end_header line end", path);
    d->header_bytes = (uint64_t)(nl + 1 - s);

    enum { NONE, VERT, FACE, OTHER } cur = NONE;
    int face_lists = 0, other_lists = 0, have_format = 0, xyz = 0, line_no = 0;
    d->sizes_known = 1;
    const char *p = s;
    while (p < eh) {
        const char *q = memchr(p, '\n', (size_t)(eh - p));
        if (!q) q = eh;
        line_no++;
        char line[512];
        if ((size_t)(q - p) >= sizeof line)
            return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d is too long", path, line_no);
        memcpy(line, p, (size_t)(q - p));
        line[q - p] = 0;
        p = q + 1;
        for (char *c = line; *c; c++)
            if ((unsigned char)*c < 32 && *c != '\t' && *c != '\r')
                return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d has a control character", path, line_no);
        char *w[8];
        int n = split_words(line, w, 8);
        if (n == 0 || line_no == 1) continue; /* "ply" */
        if (!strcmp(w[0], "comment") || !strcmp(w[0], "obj_info")) continue;
        if (!strcmp(w[0], "format")) {
            if (n != 3 || strcmp(w[2], "1.0") ||
                (strcmp(w[1], "ascii") && strcmp(w[1], "binary_little_endian") && strcmp(w[1], "binary_big_endian")))
                return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d: expected 'format ascii|binary_little_endian|binary_big_endian 1.0'",
                                     path, line_no);
            d->binary = strcmp(w[1], "ascii") != 0;
            have_format = 1;
        } else if (!strcmp(w[0], "element")) {
            char *e;
            long long cnt = n == 3 ? strtoll(w[2], &e, 10) : -1;
            if (n != 3 || *e || cnt < 0 || cnt > (1LL << 31))
                return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d: expected 'element NAME COUNT'", path, line_no);
            if (!strcmp(w[1], "vertex")) cur = VERT, d->n_vertices = cnt;
            else if (!strcmp(w[1], "face")) cur = FACE, d->n_faces = cnt;
            else cur = OTHER, d->sizes_known = d->sizes_known && cnt == 0, d->other_elements |= cnt > 0;
        } else if (!strcmp(w[0], "property") && n >= 2 && !strcmp(w[1], "list")) {
            if (n != 5 || cur == NONE)
                return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d: expected 'property list TYPE TYPE NAME' after an element",
                                     path, line_no);
            uint64_t cs = ply_type_size(w[2]), is = ply_type_size(w[3]);
            if (!cs || !is) return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d: unknown type", path, line_no);
            /* a face's vertex count must be small: OpenMesh allocates by it */
            if (cur == FACE && cs > 2)
                return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d: the face list count must be a uchar or ushort",
                                     path, line_no);
            if (cur == FACE && !face_lists++) d->face_fixed_bytes += cs, d->index_bytes = is;
            else other_lists = 1;
        } else if (!strcmp(w[0], "property")) {
            uint64_t ts = n == 3 ? ply_type_size(w[1]) : 0;
            if (!ts || cur == NONE)
                return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d: expected 'property TYPE NAME' after an element",
                                     path, line_no);
            if (cur == VERT) {
                d->vertex_bytes += ts;
                d->vertex_props++;
                if (!strcmp(w[2], "x")) xyz |= 1;
                if (!strcmp(w[2], "y")) xyz |= 2;
                if (!strcmp(w[2], "z")) xyz |= 4;
            } else if (cur == FACE) {
                d->face_fixed_bytes += ts;
                d->face_fixed_props++;
            }
        } else {
            return mim_error_set(err, MIM_EFORMAT, "%s: PLY header line %d: unknown keyword '%.32s'", path, line_no, w[0]);
        }
    }
    if (!have_format) return mim_error_set(err, MIM_EFORMAT, "%s: PLY header has no format line", path);
    if (d->n_vertices < 0 || xyz != 7)
        return mim_error_set(err, MIM_EFORMAT, "%s: PLY header needs a vertex element with x, y and z", path);
    if (d->n_faces >= 0 && face_lists != 1)
        return mim_error_set(err, MIM_EFORMAT, "%s: PLY face element needs one list of vertex indices", path);
    if (other_lists) d->sizes_known = 0;
    return 0;
}

/* OFF: only whether it is "OFF BINARY"; the text layout is checked whole by
 * mim__off_check once the file is read. */
static int parse_off(const char *path, const unsigned char *head, size_t len, mim__decl_t *d, mim_error_t *err)
{
    (void)path, (void)err;
    const char *nl = memchr(head, '\n', len);
    size_t n = nl ? (size_t)(nl - (const char *)head) : len;
    d->binary = memmem(head, n, "BINARY", 6) != NULL;
    return 0;
}

int mim__decl_parse(const char *path, int format, const unsigned char *head, size_t len, uint64_t file_bytes,
                    mim__decl_t *d, mim_error_t *err)
{
    memset(d, 0, sizeof *d);
    d->format = format;
    d->n_vertices = d->n_faces = -1;
    d->file_bytes = file_bytes;
    switch (format) {
    case FMT_PLY: return parse_ply(path, head, len, d, err);
    case FMT_OFF: return parse_off(path, head, len, d, err);
    case FMT_STL: {
        int ascii = len >= 5 && memcmp(head, "solid", 5) == 0 && memmem(head, len, "facet", 5) != NULL;
        if (len >= 84) {
            uint32_t nt;
            memcpy(&nt, head + 80, 4);
            if (file_bytes == 84 + 50ULL * nt) ascii = 0; /* binary, even if the header says "solid" */
            else if (!ascii && file_bytes < 84 + 50ULL * nt)
                return mim_error_set(err, MIM_ETRUNCATED,
                                     "%s: truncated: binary STL declares %u triangles (%llu bytes), file has %llu",
                                     path, nt, 84 + 50ULL * nt, (unsigned long long)file_bytes);
            if (!ascii) d->n_faces = nt;
        } else if (!ascii) {
            return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: %llu bytes is less than a binary STL header",
                                 path, (unsigned long long)file_bytes);
        }
        d->binary = !ascii;
        return 0;
    }
    case FMT_GLB:
        if (len >= 12 && memcmp(head, "glTF", 4) == 0) {
            uint32_t total;
            memcpy(&total, head + 8, 4);
            if (file_bytes < total)
                return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: GLB declares %u bytes, file has %llu", path,
                                     total, (unsigned long long)file_bytes);
        }
        d->binary = 1;
        return 0;
    default: return 0;
    }
}

static int nonfinite_word(const char *t, size_t n)
{
    if (n && (*t == '-' || *t == '+')) t++, n--;
    return n >= 3 && (strncasecmp(t, "nan", 3) == 0 || strncasecmp(t, "inf", 3) == 0);
}

uint64_t mim__text_nonfinite(const char *text, size_t len, int format, const char *body, char *token, size_t token_size)
{
    const char *p = body ? body : text, *end = text + len;
    uint64_t line = 1;
    for (const char *c = text; c < p; c++) line += *c == '\n';
    while (p < end) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        const char *q = p;
        while (q < eol && (*q == ' ' || *q == '\t')) q++;
        /* only coordinate lines: OBJ "v ", STL "vertex", any non-comment line of OFF/PLY */
        int check = q < eol && *q != '#';
        if (format == FMT_OBJ) check = eol - q > 2 && q[0] == 'v' && (q[1] == ' ' || q[1] == '\t');
        if (format == FMT_STL) check = eol - q > 6 && strncmp(q, "vertex", 6) == 0;
        if (check) {
            const char *t = q;
            while (t < eol) {
                while (t < eol && isspace((unsigned char)*t)) t++;
                const char *w = t;
                while (t < eol && !isspace((unsigned char)*t)) t++;
                if (t > w && nonfinite_word(w, (size_t)(t - w))) {
                    size_t n = (size_t)(t - w) < token_size - 1 ? (size_t)(t - w) : token_size - 1;
                    memcpy(token, w, n);
                    token[n] = 0;
                    return line;
                }
            }
        }
        p = eol + 1;
        line++;
    }
    return 0;
}

int mim__obj_last_line_cut(const char *text, size_t len)
{
    if (!len || text[len - 1] == '\n') return 0;
    const char *start = text + len;
    while (start > text && start[-1] != '\n') start--;
    int words = 0;
    const char *p = start, *end = text + len;
    while (p < end) {
        while (p < end && isspace((unsigned char)*p)) p++;
        if (p < end) words++;
        while (p < end && !isspace((unsigned char)*p)) p++;
    }
    /* "v x y z" needs 4 words, "f a b c" 4; fewer means the file stops mid-line */
    if (start[0] == 'v' && (start[1] == ' ' || start[1] == '\t')) return words < 4;
    if (start[0] == 'f' && (start[1] == ' ' || start[1] == '\t')) return words < 4;
    return 0;
}

int mim__stl_ascii_complete(const char *text, size_t len)
{
    size_t from = len > 512 ? len - 512 : 0;
    return memmem(text + from, len - from, "endsolid", 8) != NULL;
}

static int is_number(const char *w, size_t n, int integer)
{
    char tmp[64];
    if (n == 0 || n >= sizeof tmp) return 0;
    memcpy(tmp, w, n);
    tmp[n] = 0;
    char *e;
    if (integer) (void)strtoll(tmp, &e, 10);
    else (void)strtod(tmp, &e);
    return *e == 0;
}

/* Words of one line, at most max. */
static int words_of(const char *p, const char *eol, const char **w, size_t *wl, int max)
{
    int n = 0;
    for (const char *q = p; q < eol && n < max;) {
        while (q < eol && isspace((unsigned char)*q)) q++;
        if (q >= eol) break;
        w[n] = q;
        while (q < eol && !isspace((unsigned char)*q)) q++;
        wl[n] = (size_t)(q - w[n]);
        n++;
    }
    return n;
}

int mim__ply_ascii_check(const char *path, const char *text, size_t len, const mim__decl_t *d, mim_error_t *err)
{
    /* OpenMesh's ASCII PLY reader trusts every count it reads (it allocated
     * 4 GiB for one face), so the body is checked first: nv lines of exactly
     * the vertex properties, then nf lines "k i1 .. ik [props]" with
     * 3 <= k <= 255. */
    if (d->other_elements)
        return mim_error_set(err, MIM_EUNSUPPORTED, "%s: ASCII PLY with elements other than vertex and face", path);
    const char *p = text + d->header_bytes, *end = text + len;
    uint64_t line = 0;
    for (const char *c = text; c < p; c++) line += *c == '\n';
    int64_t v = 0, f = 0, nf = d->n_faces > 0 ? d->n_faces : 0;
    while (p < end && (v < d->n_vertices || f < nf)) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        line++;
        const char *w[300];
        size_t wl[300];
        int n = words_of(p, eol, w, wl, 300), last = eol == end;
        p = eol + 1;
        if (n == 0) continue;
        if (v < d->n_vertices) {
            int ok = n == d->vertex_props;
            for (int i = 0; ok && i < n; i++) ok = is_number(w[i], wl[i], 0);
            if (!ok)
                return last ? mim_error_set(err, MIM_ETRUNCATED, "%s:%llu: truncated in a vertex line", path, (unsigned long long)line)
                            : mim_error_set(err, MIM_EFORMAT, "%s:%llu: a vertex line needs %d numbers", path,
                                            (unsigned long long)line, d->vertex_props);
            v++;
        } else {
            long k = is_number(w[0], wl[0], 1) ? strtol(w[0], NULL, 10) : -1;
            int ok = k >= 3 && k <= 255 && n == k + 1 + d->face_fixed_props;
            for (int i = 1; ok && i <= k; i++) ok = is_number(w[i], wl[i], 1);
            if (!ok)
                return last ? mim_error_set(err, MIM_ETRUNCATED, "%s:%llu: truncated in a face line", path, (unsigned long long)line)
                            : mim_error_set(err, MIM_EFORMAT, "%s:%llu: a face line needs 'k i1 .. ik' with 3 <= k <= 255", path,
                                            (unsigned long long)line);
            f++;
        }
    }
    if (v < d->n_vertices || f < nf)
        return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: header declares %lld vertices and %lld faces, file holds %lld and %lld",
                             path, (long long)d->n_vertices, (long long)nf, (long long)v, (long long)f);
    return 0;
}

int mim__off_check(const char *path, const char *text, size_t len, mim__decl_t *d, mim_error_t *err)
{
    /* OpenMesh's OFF reader trusts the file: it loops over the declared
     * counts past the end of a short file and allocates by any polygon size
     * it reads. So the layout is checked here first: a line "[ST][C][N][4]OFF",
     * a line "nv nf [ne]", nv lines of >= 3 numbers, nf lines "k i1 .. ik"
     * with 3 <= k <= 256. Blank lines are allowed between them. */
    const char *p = text, *end = text + len;
    uint64_t line = 0;
    int stage = 0; /* 0 magic, 1 counts, 2 vertices, 3 faces */
    int64_t nv = 0, nf = 0, v = 0, f = 0;
    while (p < end && !(stage == 3 && f == nf)) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        line++;
        const char *w[260];
        size_t wl[260];
        int n = words_of(p, eol, w, wl, 260);
        int last = eol == end; /* a bad last line without its newline: the file was cut */
        p = eol + 1;
        if (n == 0) continue;
        if (stage == 0) {
            if (n != 1 || wl[0] < 3 || wl[0] > 7 || memcmp(w[0] + wl[0] - 3, "OFF", 3))
                return mim_error_set(err, MIM_EFORMAT, "%s:%llu: expected the OFF keyword alone on its line", path,
                                     (unsigned long long)line);
            stage = 1;
        } else if (stage == 1) {
            if ((n != 2 && n != 3) || !is_number(w[0], wl[0], 1) || !is_number(w[1], wl[1], 1))
                return mim_error_set(err, MIM_EFORMAT, "%s:%llu: expected the counts 'vertices faces edges'", path,
                                     (unsigned long long)line);
            nv = strtoll(w[0], NULL, 10);
            nf = strtoll(w[1], NULL, 10);
            if (nv < 0 || nf < 0 || nv > (1LL << 28) || nf > (1LL << 28))
                return mim_error_set(err, MIM_EFORMAT, "%s:%llu: counts out of range", path, (unsigned long long)line);
            d->n_vertices = nv;
            d->n_faces = nf;
            stage = nv ? 2 : 3;
        } else if (stage == 2) {
            if (n < 3 || !is_number(w[0], wl[0], 0) || !is_number(w[1], wl[1], 0) || !is_number(w[2], wl[2], 0))
                return last ? mim_error_set(err, MIM_ETRUNCATED, "%s:%llu: truncated in a vertex line", path, (unsigned long long)line)
                            : mim_error_set(err, MIM_EFORMAT, "%s:%llu: a vertex line needs 3 numbers", path, (unsigned long long)line);
            if (++v == nv) stage = 3;
        } else {
            long k = is_number(w[0], wl[0], 1) ? strtol(w[0], NULL, 10) : -1;
            if (last && (k < 3 || (k <= 256 && n < k + 1))) /* k bounded first: k + 1 must not overflow */
                return mim_error_set(err, MIM_ETRUNCATED, "%s:%llu: truncated in a face line", path, (unsigned long long)line);
            if (k < 3 || k > 256 || n < k + 1)
                return mim_error_set(err, MIM_EFORMAT, "%s:%llu: a face line needs 'k i1 .. ik' with 3 <= k <= 256", path,
                                     (unsigned long long)line);
            for (long i = 1; i <= k; i++)
                if (!is_number(w[i], wl[i], 1))
                    return mim_error_set(err, MIM_EFORMAT, "%s:%llu: face index '%.*s' is not an integer", path,
                                         (unsigned long long)line, (int)(wl[i] < 20 ? wl[i] : 20), w[i]);
            f++;
        }
    }
    if (stage < 2 && !(stage == 3))
        return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: OFF header is incomplete", path);
    if (v < nv || f < nf)
        return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: header declares %lld vertices and %lld faces, file holds %lld and %lld",
                             path, (long long)nv, (long long)nf, (long long)v, (long long)f);
    return 0;
}

uint64_t mim__obj_bad_face_line(const char *text, size_t len)
{
    /* Each "f" line needs >= 3 references "v", "v/vt", "v//vn" or "v/vt/vn"
     * with v a (possibly negative) integer. OpenMesh's OBJ reader asserts on
     * a face without usable references, so such a file must not reach it. */
    const char *p = text, *end = text + len;
    uint64_t line = 1;
    while (p < end) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        const char *q = p;
        while (q < eol && (*q == ' ' || *q == '\t')) q++;
        if (eol - q >= 2 && q[0] == 'f' && (q[1] == ' ' || q[1] == '\t')) {
            int refs = 0;
            q += 2;
            while (q < eol) {
                while (q < eol && isspace((unsigned char)*q)) q++;
                if (q >= eol) break;
                const char *w = q;
                while (q < eol && !isspace((unsigned char)*q)) q++;
                const char *d = w;
                if (d < q && *d == '-') d++;
                if (d >= q || !isdigit((unsigned char)*d)) return line;
                while (d < q && isdigit((unsigned char)*d)) d++;
                for (; d < q; d++) /* the rest: /vt, //vn, /vt/vn */
                    if (*d != '/' && *d != '-' && !isdigit((unsigned char)*d)) return line;
                refs++;
            }
            if (refs < 3) return line;
        }
        p = eol + 1;
        line++;
    }
    return 0;
}
