/* The pure-C face of the writer shims (OpenMesh, tinygltf). Internal to io/.
 * The shims only encode: write.c checks the arguments before
 * (indices in range, finite positions, increasing times) and puts the bytes
 * on disk after (mim_file_write_atomic). No C++ type crosses into C. */
#ifndef MIM_IO_WRITE_SHIM_H
#define MIM_IO_WRITE_SHIM_H

#include "mim_core.h"
#include "mim_io.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Encoded file contents (malloc'd; the caller frees data). */
typedef struct mim__bytes {
    unsigned char *data;
    size_t size;
} mim__bytes_t;

/* Copies what a shim encoded into out (malloc'd, never NULL when it
 * succeeds, even for 0 bytes). Returns 0 or MIM_ENOMEM. */
int mim__bytes_copy(mim__bytes_t *out, const void *data, size_t size);

/* PLY (binary little-endian), OBJ or OFF through OpenMesh's writers;
 * format is "ply", "obj" or "off". Text formats print 9 significant digits
 * (float32 reads back exactly). Returns 0, MIM_ENOMEM, or MIM_EIO with what
 * OpenMesh said in msg. Safe to call from many threads (serialised). */
int mim__openmesh_encode(const mim_mesh_t *mesh, const char *format, mim__bytes_t *out, char *msg,
                         size_t msg_size);

/* A GLB through tinygltf. n_frames >= 1 poses of one mesh (faces from
 * mesh, positions and normals frame after frame, 3 * n_vertices floats
 * each, normals of unit length); frames after the first become morph
 * targets animated by a "weights" channel keyed at times (n_frames floats,
 * >= 0, strictly increasing; ignored for one frame). names: n_frames
 * strings or NULL (entries may be NULL). Returns 0, MIM_ENOMEM, or MIM_EIO
 * with the reason in msg. */
typedef struct mim__gltf_frames {
    const mim_mesh_t *mesh;
    uint32_t n_frames;
    const float *positions;
    const float *normals;
    const float *times;
    const char *const *names;
    /* The mesh's parts (issue 28): each becomes a mesh and a node of its
     * own, its vertices and faces in order. NULL: one part, the whole mesh. */
    const mim_io_part_t *parts;
    uint32_t n_parts;
    /* The file the parts were read from (read as look_read says), whose
     * materials, textures (images embedded) and the parts' other vertex
     * attributes (TEXCOORD_n, COLOR_n) the output keeps; NULL: none. */
    const char *look;
    const mim_io_read_options_t *look_read;
    int *look_kept; /* may be NULL: set to 1 when the look went in */
} mim__gltf_frames_t;
int mim__gltf_encode(const mim__gltf_frames_t *in, mim__bytes_t *out, char *msg, size_t msg_size);

#ifdef __cplusplus
}
#endif
#endif
