/* The pure-C face of the C++ shims (OpenMesh, tinygltf). Internal to io/.
 * Each shim fills `raw` with what the file holds, triangulated, without
 * judging it beyond what its library reports; read.c validates. */
#ifndef MIM_IO_READ_SHIM_H
#define MIM_IO_READ_SHIM_H

#include "mim_core.h"
#include "mim_io.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mim__raw_mesh {
    mim_mesh_t mesh;          /* triangulated; faces may hold bad indices (see below) */
    uint64_t n_polygons;      /* faces as the file gave them, before triangulation */
    uint64_t n_polygon_refs;  /* sum of polygon sizes (for size checks of binary PLY) */
    int64_t first_bad_face;   /* polygon with an index >= n_vertices, or -1 */
    uint64_t bad_index;       /* that index */
    int library_failed;       /* the library said the read failed */
    char library_msg[256];    /* what the library said, if anything */
} mim__raw_mesh_t;

void mim__raw_mesh_free(mim__raw_mesh_t *r);

/* OFF, PLY (ASCII, binary), OBJ, STL (ASCII, binary) through OpenMesh;
 * format is "off", "ply", "obj" or "stl". Safe to call from many threads. */
int mim__openmesh_read(const char *path, const char *format, mim__raw_mesh_t *out);
/* What the glTF shim found of a skin. Unlike the mesh, the shim judges
 * the skin itself (types, counts, ranges, values: see mim_io_read_skin),
 * because it decodes it; read.c only prefixes the path to msg. */
typedef struct mim__raw_skin {
    mim_io_skin_t skin; /* filled when rc is 0 */
    int rc;             /* 0, MIM_ENOTFOUND, MIM_EFORMAT, MIM_ETRUNCATED, MIM_EUNSUPPORTED, MIM_ENOMEM */
    char msg[256];      /* one line, without the path */
} mim__raw_skin_t;

/* glTF / GLB through tinygltf: the whole scene (mim_io.h, "a glTF
 * scene"), triangles/strips/fans, placed in the world; parts (malloc'd,
 * *n_parts entries) says where each primitive went. skin: NULL, or where
 * to put the scene's rig (read from the same parse; its rc says whether
 * it was found and well formed, whatever the mesh's return code). opt
 * may be NULL (every mesh). */
int mim__gltf_read(const char *path, const mim_io_read_options_t *opt, mim__raw_mesh_t *out, mim__raw_skin_t *skin,
                   mim_io_part_t **parts, uint32_t *n_parts);

#ifdef __cplusplus
}
#endif
#endif
