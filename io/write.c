/* Mesh and pose-sequence writers: argument checks, vertex normals, the
 * format dispatch by extension, and the atomic write (core's
 * mim_file_write_atomic) of what the OpenMesh and tinygltf shims encode. A sequence
 * becomes a morph-target animation that a player blends linearly between
 * key poses (seed 000, Section 3.5). */
#include "mim_io.h"
#include "write_shim.h"
#include "file_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define KNOWN_EXTENSIONS ".ply, .obj, .off, .glb"

/* The format of path by its extension (any case), or NULL. */
static const char *format_of(const char *path)
{
    static const char *const formats[] = {"ply", "obj", "off", "glb"};
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash))
        return NULL;
    for (size_t i = 0; i < sizeof formats / sizeof *formats; i++)
        if (!strcasecmp(dot + 1, formats[i]))
            return formats[i];
    return NULL;
}

static int check_faces(const char *path, const mim_mesh_t *mesh, mim_error_t *err)
{
    if (!mesh->faces)
        return mim_error_set(err, MIM_EINVAL, "%s: mesh without a face array", path);
    for (size_t i = 0; i < 3 * (size_t)mesh->n_faces; i++)
        if (mesh->faces[i] >= mesh->n_vertices)
            return mim_error_set(err, MIM_EINVAL, "%s: face %zu: vertex index %u out of range (%u vertices)", path,
                                 i / 3, mesh->faces[i], mesh->n_vertices);
    return 0;
}

static int check_finite(const char *path, const float *p, uint32_t n, uint32_t frame, int in_sequence,
                        mim_error_t *err)
{
    for (uint32_t v = 0; v < n; v++)
        for (int c = 0; c < 3; c++)
            if (!isfinite(p[3 * (size_t)v + c])) {
                if (in_sequence)
                    return mim_error_set(err, MIM_ENONFINITE, "%s: frame %u, vertex %u: position is not finite",
                                         path, frame, v);
                return mim_error_set(err, MIM_ENONFINITE, "%s: vertex %u: position is not finite", path, v);
            }
    return 0;
}

/* 1 if s is well-formed UTF-8 (no overlongs, surrogates or code points
 * past U+10FFFF): the names go into the GLB's JSON, which must be UTF-8. */
static int utf8_valid(const char *s)
{
    const unsigned char *p = (const unsigned char *)s;
    while (*p) {
        unsigned c = *p++;
        int more;
        unsigned cp, min;
        if (c < 0x80)
            continue;
        if ((c & 0xE0) == 0xC0)
            more = 1, cp = c & 0x1F, min = 0x80;
        else if ((c & 0xF0) == 0xE0)
            more = 2, cp = c & 0x0F, min = 0x800;
        else if ((c & 0xF8) == 0xF0)
            more = 3, cp = c & 0x07, min = 0x10000;
        else
            return 0;
        for (; more > 0; more--, p++) {
            if ((*p & 0xC0) != 0x80)
                return 0;
            cp = cp << 6 | (*p & 0x3F);
        }
        if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
            return 0;
    }
    return 1;
}

/* Area-weighted vertex normals: the sum of the un-normalised face normals
 * (whose length is twice the face area), normalised. A vertex on no face of
 * non-zero area gets +Y, since glTF wants every NORMAL of unit length. */
static void vertex_normals(const mim_mesh_t *mesh, const float *pos, float *nrm, double *acc)
{
    uint32_t n = mesh->n_vertices;
    memset(acc, 0, 3 * (size_t)n * sizeof *acc);
    for (uint32_t f = 0; f < mesh->n_faces; f++) {
        const uint32_t *t = mesh->faces + 3 * (size_t)f;
        const float *a = pos + 3 * (size_t)t[0], *b = pos + 3 * (size_t)t[1], *c = pos + 3 * (size_t)t[2];
        mim_vec3 e1 = mim_v3(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
        mim_vec3 e2 = mim_v3(c[0] - a[0], c[1] - a[1], c[2] - a[2]);
        mim_vec3 fn = mim_v3_cross(e1, e2);
        for (int k = 0; k < 3; k++) {
            double *s = acc + 3 * (size_t)t[k];
            s[0] += fn.x;
            s[1] += fn.y;
            s[2] += fn.z;
        }
    }
    for (uint32_t v = 0; v < n; v++) {
        const double *s = acc + 3 * (size_t)v;
        double len = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
        float *o = nrm + 3 * (size_t)v;
        if (len > 0 && isfinite(len)) {
            o[0] = (float)(s[0] / len);
            o[1] = (float)(s[1] / len);
            o[2] = (float)(s[2] / len);
        } else {
            o[0] = 0.0f;
            o[1] = 1.0f;
            o[2] = 0.0f;
        }
    }
}

int mim__bytes_copy(mim__bytes_t *out, const void *data, size_t size)
{
    out->data = malloc(size ? size : 1);
    if (!out->data) return MIM_ENOMEM;
    memcpy(out->data, data, size);
    out->size = size;
    return 0;
}

/* What a shim answered, as an error naming origin. */
static int encode_error(const char *origin, int rc, const char *msg, mim_error_t *err)
{
    if (rc == MIM_ENOMEM)
        return mim_error_set(err, rc, "%s: out of memory while encoding", origin);
    return mim_error_set(err, rc, "%s: %s", origin, msg[0] ? msg : mim_strerror(rc));
}

/* Puts what a shim encoded on disk at path, and frees it. */
static int encoded(const char *path, int rc, const char *msg, mim__bytes_t *b, mim_error_t *err)
{
    if (rc)
        return encode_error(path, rc, msg, err);
    mim_file_part_t part = {b->data, b->size};
    rc = mim_file_write_atomic(path, &part, 1, err);
    free(b->data);
    b->data = NULL;
    return rc;
}

/* A GLB's extras beyond one mesh and its frames: the parts and the look
 * (mim_io_sequence_t). */
typedef struct glb_extras {
    const mim_io_part_t *parts;
    uint32_t n_parts;
    const char *look;
    const mim_io_read_options_t *look_read;
    int look_kept; /* out: the look went into the GLB */
} glb_extras_t;

typedef struct {
    float key[3];
    uint32_t v;
} spot_t;

static int spot_cmp(const void *pa, const void *pb)
{
    const spot_t *a = pa, *b = pb;
    int c = memcmp(a->key, b->key, sizeof a->key);
    return c ? c : (a->v > b->v) - (a->v < b->v);
}

/* Coincident copies of a vertex (split along a UV seam or a hard edge)
 * share one normal where theirs, at frame 0, bend less than 30 degrees
 * apart: a seam is invisible, a hard edge (flat shading) stays hard.
 * group[v]: the copy whose normal v takes (itself when alone). */
#define SEAM_COS 0.866
static int seam_groups(const mim_mesh_t *mesh, const float *pos, const float *nrm, uint32_t *group)
{
    const uint32_t n = mesh->n_vertices;
    spot_t *sp = malloc(((size_t)n + 1) * sizeof *sp);
    if (!sp) return MIM_ENOMEM;
    for (uint32_t v = 0; v < n; v++) memcpy(sp[v].key, pos + 3 * (size_t)v, sizeof sp[v].key), sp[v].v = v;
    qsort(sp, n, sizeof *sp, spot_cmp);
    for (uint32_t i = 0; i < n;) {
        uint32_t j = i + 1;
        while (j < n && !memcmp(sp[j].key, sp[i].key, sizeof sp[i].key)) j++;
        for (uint32_t k = i; k < j; k++) {
            const uint32_t v = sp[k].v;
            group[v] = v;
            for (uint32_t r = i; r < k; r++) { /* the first earlier copy close enough that leads a group */
                const uint32_t u = sp[r].v;
                if (group[u] != u) continue;
                const float *a = nrm + 3 * (size_t)u, *c = nrm + 3 * (size_t)v;
                if (a[0] * c[0] + a[1] * c[1] + a[2] * c[2] >= SEAM_COS) {
                    group[v] = u;
                    break;
                }
            }
        }
        i = j;
    }
    free(sp);
    return 0;
}

/* Normals averaged over each seam group (frame by frame). */
static void seam_normals(uint32_t n, const uint32_t *group, float *nrm, double *acc)
{
    memset(acc, 0, 3 * (size_t)n * sizeof *acc);
    for (uint32_t v = 0; v < n; v++)
        for (int c = 0; c < 3; c++) acc[3 * (size_t)group[v] + c] += nrm[3 * (size_t)v + c];
    for (uint32_t v = 0; v < n; v++) {
        const double *s = acc + 3 * (size_t)group[v];
        double len = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
        if (len > 0 && isfinite(len))
            for (int c = 0; c < 3; c++) nrm[3 * (size_t)v + c] = (float)(s[c] / len);
    }
}

/* The GLB of n_frames poses (checked by the caller) into *b; errors name origin. */
static int encode_glb(const char *origin, const mim_mesh_t *mesh, uint32_t n_frames, const float *positions,
                      const float *times, const char *const *names, glb_extras_t *x, mim__bytes_t *b,
                      mim_error_t *err)
{
    size_t per = 3 * (size_t)mesh->n_vertices;
    const int seams = x && (x->n_parts > 1 || x->look);
    float *normals = calloc(per * n_frames + 1, sizeof *normals);
    double *acc = malloc((per + 1) * sizeof *acc);
    uint32_t *group = seams ? malloc(((size_t)mesh->n_vertices + 1) * sizeof *group) : NULL;
    if (!normals || !acc || (seams && !group)) {
        free(normals), free(acc), free(group);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
    }
    for (uint32_t f = 0; f < n_frames; f++)
        vertex_normals(mesh, positions + f * per, normals + f * per, acc);
    if (group && seam_groups(mesh, positions, normals, group) == 0)
        for (uint32_t f = 0; f < n_frames; f++) seam_normals(mesh->n_vertices, group, normals + f * per, acc);
    free(acc), free(group);
    mim__gltf_frames_t in = {
        .mesh = mesh, .n_frames = n_frames, .positions = positions, .normals = normals, .times = times,
        .names = names};
    if (x)
        in.parts = x->parts, in.n_parts = x->n_parts, in.look = x->look, in.look_read = x->look_read,
        in.look_kept = &x->look_kept;
    char msg[256] = "";
    int rc = mim__gltf_encode(&in, b, msg, sizeof msg);
    free(normals);
    return rc ? encode_error(origin, rc, msg, err) : 0;
}

static int write_glb(const char *path, const mim_mesh_t *mesh, uint32_t n_frames, const float *positions,
                     const float *times, const char *const *names, glb_extras_t *x, mim_error_t *err)
{
    mim__bytes_t b = {0};
    int rc = encode_glb(path, mesh, n_frames, positions, times, names, x, &b, err);
    return rc ? rc : encoded(path, 0, "", &b, err);
}

static int check_mesh_shape(const char *path, const mim_mesh_t *mesh, mim_error_t *err)
{
    if (!mesh)
        return mim_error_set(err, MIM_EINVAL, "%s: no mesh", path);
    if (mesh->n_vertices == 0 || mesh->n_faces == 0)
        return mim_error_set(err, MIM_EINVAL, "%s: empty mesh (%u vertices, %u faces)", path, mesh->n_vertices,
                             mesh->n_faces);
    return check_faces(path, mesh, err);
}

/* The checks every single-mesh output passes first; origin names it. */
static int check_mesh(const char *origin, const mim_mesh_t *mesh, mim_error_t *err)
{
    int rc = check_mesh_shape(origin, mesh, err);
    if (rc)
        return rc;
    if (!mesh->positions)
        return mim_error_set(err, MIM_EINVAL, "%s: mesh without positions", origin);
    return check_finite(origin, mesh->positions, mesh->n_vertices, 0, 0, err);
}

int mim_io_encode_glb(const mim_mesh_t *mesh, const char *origin, unsigned char **data, size_t *size,
                      mim_error_t *err)
{
    *data = NULL;
    *size = 0;
    if (!origin)
        origin = "GLB";
    int rc = check_mesh(origin, mesh, err);
    mim__bytes_t b = {0};
    if (!rc)
        rc = encode_glb(origin, mesh, 1, mesh->positions, NULL, NULL, NULL, &b, err);
    if (!rc)
        *data = b.data, *size = b.size;
    return rc;
}

int mim_io_write_mesh(const char *path, const mim_mesh_t *mesh, mim_error_t *err)
{
    if (!path || !path[0])
        return mim_error_set(err, MIM_EINVAL, "write: no output path");
    const char *format = format_of(path);
    if (!format)
        return mim_error_set(err, MIM_EINVAL, "%s: unknown extension; known: " KNOWN_EXTENSIONS, path);
    int rc = check_mesh(path, mesh, err);
    if (rc)
        return rc;
    if (!strcmp(format, "glb"))
        return write_glb(path, mesh, 1, mesh->positions, NULL, NULL, NULL, err);
    mim__bytes_t b = {0};
    char msg[256] = "";
    rc = mim__openmesh_encode(mesh, format, &b, msg, sizeof msg);
    return encoded(path, rc, msg, &b, err);
}

/* Checks a sequence (path names it) and makes its float times. */
static int check_sequence(const char *path, const mim_io_sequence_t *seq, float **times_out, mim_error_t *err)
{
    *times_out = NULL;
    if (!seq)
        return mim_error_set(err, MIM_EINVAL, "%s: no sequence", path);
    int rc = check_mesh_shape(path, seq->mesh, err);
    if (rc)
        return rc;
    if (seq->n_frames == 0)
        return mim_error_set(err, MIM_EINVAL, "%s: sequence without frames", path);
    if (!seq->positions)
        return mim_error_set(err, MIM_EINVAL, "%s: sequence without positions", path);
    uint32_t nf = seq->n_frames, nv = seq->mesh->n_vertices;
    for (uint32_t f = 0; f < nf; f++)
        if ((rc = check_finite(path, seq->positions + 3 * (size_t)nv * f, nv, f, 1, err)))
            return rc;
    for (uint32_t f = 0; seq->names && f < nf; f++)
        if (seq->names[f] && !utf8_valid(seq->names[f]))
            return mim_error_set(err, MIM_EINVAL, "%s: frame %u: name is not valid UTF-8", path, f);
    /* the parts tile the vertices and faces in order, each face inside its part */
    uint32_t v_at = 0, f_at = 0;
    for (uint32_t k = 0; k < seq->n_parts; k++) {
        const mim_io_part_t *p = seq->parts + k;
        if (p->first_vertex != v_at || p->first_face != f_at || !p->n_vertices ||
            p->n_vertices > nv - v_at || p->n_faces > seq->mesh->n_faces - f_at)
            return mim_error_set(err, MIM_EINVAL, "%s: part %u does not follow the part before it", path, k);
        for (uint32_t f = p->first_face; f < p->first_face + p->n_faces; f++)
            for (int c = 0; c < 3; c++) {
                uint32_t v = seq->mesh->faces[3 * (size_t)f + c];
                if (v < p->first_vertex || v - p->first_vertex >= p->n_vertices)
                    return mim_error_set(err, MIM_EINVAL, "%s: part %u: face %u uses vertex %u of another part", path,
                                         k, f, v);
            }
        v_at += p->n_vertices, f_at += p->n_faces;
    }
    if (seq->n_parts && (v_at != nv || f_at != seq->mesh->n_faces))
        return mim_error_set(err, MIM_EINVAL, "%s: the parts cover %u of %u vertices and %u of %u faces", path, v_at,
                             nv, f_at, seq->mesh->n_faces);
    double fps = seq->fps == 0 ? 30.0 : seq->fps;
    if (!seq->times && !(isfinite(fps) && fps > 0))
        return mim_error_set(err, MIM_EINVAL, "%s: fps %g is not a positive number", path, seq->fps);
    float *times = malloc((size_t)nf * sizeof *times);
    if (!times)
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    /* The file holds float32 times; they must increase as floats too. */
    for (uint32_t f = 0; f < nf; f++) {
        double t = seq->times ? seq->times[f] : f / fps;
        times[f] = (float)t;
        if (!isfinite(t) || !isfinite(times[f]) || t < 0) {
            free(times);
            return mim_error_set(err, MIM_EINVAL, "%s: frame %u: time %g is not a finite number >= 0", path, f, t);
        }
        if (f > 0 && !(times[f] > times[f - 1])) {
            free(times);
            return mim_error_set(err, MIM_EINVAL,
                                 "%s: frame %u: time %.9g does not increase (previous frame at %.9g)", path, f, t,
                                 seq->times ? seq->times[f - 1] : (f - 1) / fps);
        }
    }
    *times_out = times;
    return 0;
}

/* The sequence's extras, and whether its look can be kept (a glTF source). */
static glb_extras_t sequence_extras(const mim_io_sequence_t *seq)
{
    glb_extras_t x = {.parts = seq->parts, .n_parts = seq->n_parts, .look_read = seq->look_read};
    int fmt = seq->look ? mim__format_of(seq->look) : FMT_UNKNOWN;
    if (fmt == FMT_GLTF || fmt == FMT_GLB) x.look = seq->look;
    return x;
}

int mim_io_encode_sequence_glb(const mim_io_sequence_t *seq, const char *origin, unsigned char **data, size_t *size,
                               mim_error_t *err)
{
    *data = NULL;
    *size = 0;
    if (!origin) origin = "GLB";
    float *times = NULL;
    int rc = check_sequence(origin, seq, &times, err);
    if (rc) return rc;
    glb_extras_t x = sequence_extras(seq);
    mim__bytes_t b = {0};
    rc = encode_glb(origin, seq->mesh, seq->n_frames, seq->positions, times, seq->names, &x, &b, err);
    free(times);
    if (!rc) *data = b.data, *size = b.size;
    if (!rc && seq->look_kept) *seq->look_kept = x.look_kept;
    return rc;
}

int mim_io_write_sequence_glb(const char *path, const mim_io_sequence_t *seq, mim_error_t *err)
{
    if (!path || !path[0])
        return mim_error_set(err, MIM_EINVAL, "write: no output path");
    const char *format = format_of(path);
    if (!format || strcmp(format, "glb"))
        return mim_error_set(err, MIM_EINVAL, "%s: a pose sequence is written as .glb", path);
    float *times = NULL;
    int rc = check_sequence(path, seq, &times, err);
    if (rc) return rc;
    glb_extras_t x = sequence_extras(seq);
    mim__bytes_t b = {0};
    rc = encode_glb(path, seq->mesh, seq->n_frames, seq->positions, times, seq->names, &x, &b, err);
    free(times);
    if (!rc && seq->look_kept) *seq->look_kept = x.look_kept;
    return rc ? rc : encoded(path, 0, "", &b, err);
}
