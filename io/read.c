/* mim_io_read_mesh: one entry for every mesh format. The libraries parse
 * (OpenMesh, tinygltf); this file decides whether what they returned is a
 * whole, finite, consistent mesh, and says precisely what is wrong if not. */
#include "file_check.h"
#include "read_shim.h"
#include "mim_io.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define HEAD_BYTES 65536

static const char *format_name(int f)
{
    switch (f) {
    case FMT_OFF: return "OFF";
    case FMT_PLY: return "PLY";
    case FMT_OBJ: return "OBJ";
    case FMT_STL: return "STL";
    case FMT_GLTF: return "glTF";
    case FMT_GLB: return "GLB";
    default: return "mesh";
    }
}

int mim_io_format_known(const char *path) { return mim__format_of(path) != FMT_UNKNOWN; }

static int validate(const char *path, int fmt, const mim__decl_t *d, mim__raw_mesh_t *raw, int shim_rc,
                    mim_error_t *err)
{
    const mim_mesh_t *m = &raw->mesh;
    if (shim_rc == MIM_ENOMEM) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory while reading", path);
    if (fmt == FMT_GLTF || fmt == FMT_GLB) {
        if (shim_rc) return mim_error_set(err, shim_rc, "%s: %s", path, raw->library_msg);
    }
    /* Fewer elements than the header declares: the file stops early. */
    if (d->n_vertices >= 0 && (int64_t)m->n_vertices < d->n_vertices)
        return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: header declares %lld vertices, file holds %u", path,
                             (long long)d->n_vertices, m->n_vertices);
    if (d->n_faces >= 0 && (int64_t)raw->n_polygons < d->n_faces && fmt != FMT_STL)
        return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: header declares %lld faces, file holds %llu", path,
                             (long long)d->n_faces, (unsigned long long)raw->n_polygons);
    if (fmt == FMT_PLY && d->binary && d->sizes_known && d->n_vertices >= 0 && d->n_faces >= 0) {
        uint64_t refs = raw->n_polygon_refs > 3 * (uint64_t)d->n_faces ? raw->n_polygon_refs : 3 * (uint64_t)d->n_faces;
        uint64_t need = d->header_bytes + (uint64_t)d->n_vertices * d->vertex_bytes +
                        (uint64_t)d->n_faces * d->face_fixed_bytes + refs * d->index_bytes;
        if (d->file_bytes < need)
            return mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: %llu bytes, the header's %lld vertices and %lld faces need %llu",
                                 path, (unsigned long long)d->file_bytes, (long long)d->n_vertices,
                                 (long long)d->n_faces, (unsigned long long)need);
    }
    if (raw->first_bad_face >= 0)
        return mim_error_set(err, MIM_EINDEX, "%s: face %lld refers to vertex %llu, but there are only %u vertices", path,
                             (long long)raw->first_bad_face, (unsigned long long)raw->bad_index, m->n_vertices);
    if (shim_rc || raw->library_failed) {
        if (m->n_vertices == 0 && m->n_faces == 0 && d->file_bytes > 0 && raw->library_msg[0] && fmt != FMT_OBJ)
            return mim_error_set(err, MIM_EFORMAT, "%s: not a valid %s file (%s)", path, format_name(fmt), raw->library_msg);
    }
    if (m->n_vertices == 0 || m->n_faces == 0)
        return mim_error_set(err, MIM_EEMPTY, "%s: empty mesh: %u vertices, %u faces", path, m->n_vertices, m->n_faces);
    for (uint32_t v = 0; v < m->n_vertices; v++) {
        const float *p = m->positions + 3 * (size_t)v;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return mim_error_set(err, MIM_ENONFINITE, "%s: vertex %u has a non-finite coordinate (%g, %g, %g)", path, v,
                                 (double)p[0], (double)p[1], (double)p[2]);
    }
    if (shim_rc || raw->library_failed)
        return mim_error_set(err, MIM_EFORMAT, "%s: not a valid %s file (%s)", path, format_name(fmt),
                             raw->library_msg[0] ? raw->library_msg : "unreadable");
    return 0;
}

/* The whole read of one mesh file, and of its skin when skin is not NULL
 * and of its parts when parts is not NULL (glTF/GLB only: the same parse;
 * another format is one part). */
static int read_checked(const char *path, const mim_io_read_options_t *opt, mim_mesh_t *out, mim__raw_skin_t *skin,
                        mim_io_part_t **parts, uint32_t *n_parts, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (parts) *parts = NULL, *n_parts = 0;
    struct stat st;
    if (stat(path, &st) != 0)
        return mim_error_set(err, errno == ENOENT ? MIM_ENOTFOUND : -errno, "%s: cannot read: %s", path, strerror(errno));
    if (S_ISDIR(st.st_mode)) return mim_error_set(err, MIM_EINVAL, "%s: is a directory, not a mesh file", path);
    if (!S_ISREG(st.st_mode)) return mim_error_set(err, MIM_EINVAL, "%s: not a regular file", path);
    int fmt = mim__format_of(path);
    if (fmt == FMT_UNKNOWN)
        return mim_error_set(err, MIM_EUNSUPPORTED,
                             "%s: unknown mesh format (expected .off .ply .obj .stl .gltf or .glb)", path);
    if (st.st_size == 0) return mim_error_set(err, MIM_EEMPTY, "%s: empty mesh: the file has 0 bytes", path);

    /* The head tells what the file declares; text files are then read whole
     * for the nan/inf scan (binary ones are checked by size and by value). */
    char *buf = NULL;
    size_t len = 0;
    int rc = mim_file_read(path, HEAD_BYTES, &buf, &len, err);
    if (rc) return rc;
    mim__decl_t d;
    rc = mim__decl_parse(path, fmt, (const unsigned char *)buf, len, (uint64_t)st.st_size, &d, err);
    int text = !d.binary && fmt != FMT_GLTF && fmt != FMT_GLB;
    if (!rc && text && (uint64_t)st.st_size > len) {
        free(buf);
        buf = NULL;
        rc = mim_file_read(path, (size_t)st.st_size, &buf, &len, err);
    }
    if (!rc && text) {
        char tok[32];
        const char *body = fmt == FMT_PLY ? buf + d.header_bytes : NULL;
        uint64_t line = mim__text_nonfinite(buf, len, fmt, body, tok, sizeof tok);
        if (line)
            rc = mim_error_set(err, MIM_ENONFINITE, "%s:%llu: '%s' is not a finite coordinate", path,
                               (unsigned long long)line, tok);
        else if (fmt == FMT_OBJ && mim__obj_last_line_cut(buf, len))
            rc = mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: the last line stops part-way", path);
        else if (fmt == FMT_OBJ && (line = mim__obj_bad_face_line(buf, len)))
            rc = mim_error_set(err, MIM_EFORMAT, "%s:%llu: a face needs at least 3 vertex references like 7, 7/2 or 7//3",
                               path, (unsigned long long)line);
        else if (fmt == FMT_OFF && memchr(buf, '#', len))
            /* OpenMesh's OFF reader takes a comment line for data and misreads the rest */
            rc = mim_error_set(err, MIM_EUNSUPPORTED, "%s: OFF with '#' comment lines is not supported; remove the comments",
                               path);
        else if (fmt == FMT_OFF)
            rc = mim__off_check(path, buf, len, &d, err);
        else if (fmt == FMT_STL && !mim__stl_ascii_complete(buf, len))
            rc = mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: ASCII STL without its closing endsolid", path);
    }
    /* Before the library reads: a body too short for the header's counts is
     * truncated, and must not reach OpenMesh, which would loop over the
     * declared counts on a failed stream. */
    if (!rc && fmt == FMT_PLY && d.binary && d.sizes_known) {
        uint64_t need = d.header_bytes + (uint64_t)d.n_vertices * d.vertex_bytes +
                        (uint64_t)(d.n_faces > 0 ? d.n_faces : 0) * (d.face_fixed_bytes + 3 * d.index_bytes);
        if (d.file_bytes < need)
            rc = mim_error_set(err, MIM_ETRUNCATED, "%s: truncated: %llu bytes, the header's %lld vertices and %lld faces need at least %llu",
                               path, (unsigned long long)d.file_bytes, (long long)d.n_vertices, (long long)d.n_faces,
                               (unsigned long long)need);
    } else if (!rc && fmt == FMT_PLY && !d.binary) {
        rc = mim__ply_ascii_check(path, buf, len, &d, err);
    } else if (!rc && fmt == FMT_OFF && d.binary) {
        rc = mim_error_set(err, MIM_EUNSUPPORTED, "%s: binary OFF is not supported; use PLY", path);
    }
    if (!rc && (d.n_vertices == 0 || d.n_faces == 0))
        rc = mim_error_set(err, MIM_EEMPTY, "%s: empty mesh: the header declares %lld vertices and %lld faces", path,
                           (long long)d.n_vertices, (long long)d.n_faces);
    free(buf);
    if (rc) return rc;

    mim__raw_mesh_t raw;
    static const char *const om_format[] = {[FMT_OFF] = "off", [FMT_PLY] = "ply", [FMT_OBJ] = "obj", [FMT_STL] = "stl"};
    const int gltf = fmt == FMT_GLTF || fmt == FMT_GLB;
    mim_io_part_t *pv = NULL;
    uint32_t np = 0;
    int shim_rc = gltf ? mim__gltf_read(path, opt, &raw, skin, &pv, &np) : mim__openmesh_read(path, om_format[fmt], &raw);
    rc = validate(path, fmt, &d, &raw, shim_rc, err);
    if (!rc && !gltf && parts) { /* one part: the whole file */
        if (!(pv = calloc(1, sizeof *pv))) rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory while reading", path);
        else np = 1, pv->node = pv->material = -1, pv->n_vertices = raw.mesh.n_vertices, pv->n_faces = raw.mesh.n_faces;
    }
    if (rc) {
        free(pv);
        mim__raw_mesh_free(&raw);
        return rc;
    }
    if (parts) *parts = pv, *n_parts = np;
    else free(pv);
    *out = raw.mesh; /* ownership moves to the caller */
    return 0;
}

int mim_io_read_mesh(const char *path, mim_mesh_t *out, mim_error_t *err)
{
    return read_checked(path, NULL, out, NULL, NULL, NULL, err);
}

void mim_io_skin_free(mim_io_skin_t *s)
{
    if (!s) return;
    free(s->joints);
    free(s->weights);
    free(s->names);
    free(s->joint_positions);
    free(s->parent);
    memset(s, 0, sizeof *s);
}

void mim_io_scene_free(mim_io_scene_t *s)
{
    if (!s) return;
    mim_mesh_free(&s->mesh);
    free(s->parts);
    mim_io_skin_free(&s->skin);
    memset(s, 0, sizeof *s);
}

int mim_io_read_scene(const char *path, const mim_io_read_options_t *opt, mim_io_scene_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    mim__raw_skin_t skin;
    memset(&skin, 0, sizeof skin);
    int fmt = mim__format_of(path);
    const int gltf = fmt == FMT_GLTF || fmt == FMT_GLB;
    int rc = read_checked(path, opt, &out->mesh, gltf ? &skin : NULL, &out->parts, &out->n_parts, err);
    if (rc) {
        mim_io_skin_free(&skin.skin);
        memset(out, 0, sizeof *out);
        return rc;
    }
    if (!gltf) {
        out->skin_rc = MIM_ENOTFOUND;
        snprintf(out->skin_msg, sizeof out->skin_msg, "%s: no skin: skins are read from glTF and GLB files only", path);
    } else {
        out->skin_rc = skin.rc;
        if (skin.rc) snprintf(out->skin_msg, sizeof out->skin_msg, "%s: %s", path, skin.msg);
        else out->skin = skin.skin; /* ownership moves */
    }
    return 0;
}

/* The skin comes from the same parse as the mesh, and only once the mesh
 * has passed every check mim_io_read_mesh makes: a skin of a mesh that
 * cannot be read is no use to anyone. read_gltf.cpp judges the skin. */
int mim_io_read_skin(const char *path, mim_io_skin_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    int fmt = mim__format_of(path);
    if (fmt != FMT_GLTF && fmt != FMT_GLB)
        return mim_error_set(err, MIM_ENOTFOUND, "%s: no skin: skins are read from glTF and GLB files only (.gltf, .glb)",
                             path);
    mim__raw_skin_t skin;
    memset(&skin, 0, sizeof skin);
    mim_mesh_t mesh;
    int rc = read_checked(path, NULL, &mesh, &skin, NULL, NULL, err);
    mim_mesh_free(&mesh);
    if (!rc && skin.rc == MIM_ENOMEM) rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory while reading the skin", path);
    else if (!rc && skin.rc) rc = mim_error_set(err, skin.rc, "%s: %s", path, skin.msg);
    if (rc) {
        mim_io_skin_free(&skin.skin);
        return rc;
    }
    *out = skin.skin; /* ownership moves to the caller */
    return 0;
}
