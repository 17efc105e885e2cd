/* mimic io: every mesh reader and writer, and the checks on untrusted mesh
 * files. OpenMesh (OFF, PLY, OBJ, STL) and tinygltf (glTF, GLB) sit behind
 * two C++ shims each (read_*.cpp, write_*.cpp); no C++ type crosses into C.
 * Uses core/ only. */
#ifndef MIM_IO_H
#define MIM_IO_H

#include "mim_core.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- reading (read.c, file_check.c, read_openmesh.cpp, read_gltf.cpp) ---- */
/* Reads OFF, PLY (ASCII/binary), OBJ, STL (ASCII/binary) through OpenMesh and
 * glTF/GLB through tinygltf, by file extension; polygons are fan-triangulated.
 * Rejects, with a one-line message naming the file: a missing or unreadable
 * path, a truncated file, a NaN/infinite coordinate, a face index past the
 * vertex count, an empty mesh. On failure *out is left zeroed. Safe to call
 * from many threads. */
int mim_io_read_mesh(const char *path, mim_mesh_t *out, mim_error_t *err);
/* 1 if the file name has an extension mim_io_read_mesh handles. */
int mim_io_format_known(const char *path);

/* ---- a glTF skin (read.c, read_gltf.cpp) ---- */
#define MIM_IO_SKIN_NAME_MAX 64
typedef struct mim_io_skin {
    uint32_t n_vertices;   /* the first primitive's, as mim_io_read_mesh reads it */
    uint32_t n_joints;     /* the skin's joints */
    uint16_t *joints;      /* 4 * n_vertices: JOINTS_0, indices into the skin's joints */
    float *weights;        /* 4 * n_vertices: WEIGHTS_0, each vertex's normalised to sum 1 (all 0 if they were) */
    char (*names)[MIM_IO_SKIN_NAME_MAX]; /* n_joints node names ("" for a node without one), truncated */
} mim_io_skin_t;
/* The skin of the mesh mim_io_read_mesh reads from a .gltf/.glb: the first
 * primitive's JOINTS_0 and WEIGHTS_0 and the names of its skin's joint
 * nodes. The skin is that of the first node that instantiates mesh 0 with
 * a skin, else skins[0]. JOINTS_1/WEIGHTS_1 (influences past the fourth)
 * are ignored. Names longer than MIM_IO_SKIN_NAME_MAX - 1 bytes are cut
 * at a UTF-8 character boundary.
 * Returns 0; MIM_ENOTFOUND when the file has no skin (a format other
 * than glTF/GLB, no JOINTS_0, no WEIGHTS_0, or no skin: not an error for
 * callers, who then segment by geometry); mim_io_read_mesh's errors for a file whose mesh it cannot
 * read; MIM_EFORMAT for a malformed skin, with one line naming what: a
 * JOINTS_0 that is not VEC4 of unsigned byte/short, a WEIGHTS_0 not VEC4
 * of float or normalised unsigned byte/short, a count that differs from
 * POSITION's, a joint index >= n_joints, a negative or non-finite weight,
 * a skin joint that is not a valid node index, a skin without joints;
 * MIM_ETRUNCATED for skin data past the end of its buffer;
 * MIM_EUNSUPPORTED for a sparse skin accessor; MIM_ENOMEM. On failure *out is zeroed. Safe to call from many
 * threads. Free with mim_io_skin_free. */
int mim_io_read_skin(const char *path, mim_io_skin_t *out, mim_error_t *err);
void mim_io_skin_free(mim_io_skin_t *s); /* accepts NULL; zeroes */

/* ---- the landmark file beside a mesh (sidecar.c) ---- */
/* Writes to out the path of the landmark file that goes with mesh_path:
 * "dir/NAME.ext" gives "dir/NAME.landmarks.json" (only the last extension
 * goes: "a.b.ply" gives "a.b.landmarks.json"; a name without one, or a
 * dot-file like ".ply", keeps its whole name). Returns 1 when that path is
 * a regular file, 0 when not (out holds the path either way), MIM_EINVAL
 * when it does not fit in size bytes (with its NUL) or an argument is
 * NULL; out must not overlap mesh_path. Read it with
 * mim_landmark_file_read. */
int mim_io_landmarks_sidecar(const char *mesh_path, char *out, size_t size);

/* ---- writing (write.c, write_openmesh.cpp, write_gltf.cpp) ---- */
/* Writes one mesh; the format comes from the extension of path (any case):
 * .ply (binary little-endian), .obj, .off (OpenMesh; text formats print 9
 * significant digits, so float32 positions read back exactly) or .glb
 * (tinygltf: POSITION with min/max, area-weighted vertex NORMALs, indices).
 * Errors: MIM_EINVAL (NULL, empty mesh, face index out of range, unknown
 * extension: the message lists the known ones), MIM_ENONFINITE (a NaN/inf
 * position: names the vertex), MIM_EIO (cannot write: names the path and
 * the reason). The bytes go through mim_file_write_atomic, so a failure
 * never leaves a half-written file at path. */
int mim_io_write_mesh(const char *path, const mim_mesh_t *mesh, mim_error_t *err);

/* The GLB of one mesh, as mim_io_write_mesh writes it to a .glb file, in
 * memory: *data (malloc'd, the caller frees) and *size. origin names the
 * mesh in messages. Errors as mim_io_write_mesh, less the file ones; on
 * error *data is NULL. */
int mim_io_encode_glb(const mim_mesh_t *mesh, const char *origin, unsigned char **data, size_t *size,
                      mim_error_t *err);

/* A sequence of poses of one mesh as a GLB with a morph-target animation:
 * the base mesh is frame 0; every later frame is a morph target (its
 * POSITION displacement from frame 0, accessor min/max set, and its NORMAL
 * displacement); one animation "mimic" with a "weights" channel whose
 * keyframe i (at times[i] seconds) sets target i-1 to 1 and every other to
 * 0 (frame 0: all 0), LINEAR interpolation, so a player blends linearly
 * between consecutive frames (seed 000, Section 3.5, key-pose morphing).
 * positions holds n_frames * 3 * n_vertices floats (frame after frame);
 * faces are mesh->faces (mesh->positions is ignored and may be NULL).
 * times (n_frames seconds, >= 0, strictly increasing also as float32) may
 * be NULL: frame i at i / fps. names (n_frames strings, may be NULL, UTF-8)
 * name the frames: names[0] the mesh, names[1..] the targets in the mesh
 * extras "targetNames" (a common convention players show). One frame gives
 * a GLB of the mesh without targets or animation. path must end in .glb.
 * Errors as mim_io_write_mesh, plus MIM_EINVAL for n_frames 0, bad times
 * or fps (naming the frame). */
typedef struct mim_io_sequence {
    const mim_mesh_t *mesh;     /* faces and n_vertices */
    uint32_t n_frames;          /* >= 1 */
    const float *positions;     /* n_frames * 3 * n_vertices */
    const double *times;        /* NULL: i / fps */
    double fps;                 /* used when times is NULL; 0 means 30 */
    const char *const *names;   /* optional frame names */
} mim_io_sequence_t;
int mim_io_write_sequence_glb(const char *path, const mim_io_sequence_t *seq, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
