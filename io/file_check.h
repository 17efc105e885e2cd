/* Internal to io/: what a mesh file declares about itself (header counts,
 * binary body size), and text scans, so that read.c can tell a truncated or
 * non-finite file from one the library merely failed to parse. */
#ifndef MIM_IO_FILE_CHECK_H
#define MIM_IO_FILE_CHECK_H

#include "mim_core.h"

enum { FMT_UNKNOWN, FMT_OFF, FMT_PLY, FMT_OBJ, FMT_STL, FMT_GLTF, FMT_GLB };

typedef struct mim__decl {
    int format;
    int binary;
    int64_t n_vertices; /* declared by the header; -1 unknown */
    int64_t n_faces;
    /* binary PLY: body size = nv * vertex_bytes + nf * (face_fixed_bytes) + refs * index_bytes */
    int sizes_known;
    uint64_t header_bytes, vertex_bytes, face_fixed_bytes, index_bytes, other_bytes;
    uint64_t file_bytes;
    /* PLY: property counts, and whether elements other than vertex and face
     * hold data */
    int vertex_props, face_fixed_props, other_elements;
} mim__decl_t;

int mim__format_of(const char *path);
/* Parses what the file's beginning declares. head holds the first bytes of the file. */
int mim__decl_parse(const char *path, int format, const unsigned char *head, size_t head_len,
                    uint64_t file_bytes, mim__decl_t *out, mim_error_t *err);
/* For text formats: finds a coordinate token spelled nan/inf; returns its
 * 1-based line or 0. */
uint64_t mim__text_nonfinite(const char *text, size_t len, int format, const char *header_end, char *token,
                             size_t token_size);
/* OBJ: 1 if the last line is a vertex or face line cut short. */
int mim__obj_last_line_cut(const char *text, size_t len);
/* ASCII PLY: checks the body layout (see file_check.c). */
int mim__ply_ascii_check(const char *path, const char *text, size_t len, const mim__decl_t *d, mim_error_t *err);
/* ASCII OFF: checks the whole layout (see file_check.c); sets the counts in d. */
int mim__off_check(const char *path, const char *text, size_t len, mim__decl_t *d, mim_error_t *err);
/* OBJ: the 1-based line of the first face line without 3 well-formed
 * vertex references, or 0. */
uint64_t mim__obj_bad_face_line(const char *text, size_t len);
/* ASCII STL: 1 if the file closes with endsolid. */
int mim__stl_ascii_complete(const char *text, size_t len);

#endif
