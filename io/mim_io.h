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

/* ---- a glTF scene: its parts and its rig (read.c, gltf_scene.cpp) ---- */
/* A glTF/GLB file is read as its whole default scene (issue 28): every
 * primitive of every mesh a node of the scene instantiates, in the order
 * of a depth-first walk of the scene's nodes (children in their listed
 * order; a node's primitives in their order), each placed in the world:
 * a skinned primitive (its node has a skin, it has JOINTS_0 and
 * WEIGHTS_0) by its skin at the joints' current transforms (glTF 2.0
 * 3.7.3: world(joint) * inverseBindMatrix, the node's own transform
 * ignored), anything else by its node's world transform; node scales (a
 * root "Armature" at 0.01 over centimetres) are applied, so the result is
 * in the file's metres. A file whose scene instantiates no mesh reads its
 * meshes in meshes[] order, untransformed. Vertices keep the file's split
 * copies (UV and normal seams) and order; parts say where each primitive
 * went. Other formats read as one part. */
#define MIM_IO_SKIN_NAME_MAX 64
#define MIM_IO_MAX_PARTS 4096u /* more primitives than this: MIM_EUNSUPPORTED, naming the count */
typedef struct mim_io_part {
    char name[MIM_IO_SKIN_NAME_MAX]; /* its mesh's name, else its node's, else "" */
    uint32_t mesh, primitive;        /* indices into the file's meshes[] and that mesh's primitives[] */
    int32_t node;                    /* the node that placed it; -1: none */
    int32_t material;                /* -1: none */
    uint32_t first_vertex, n_vertices, first_face, n_faces;
} mim_io_part_t;

/* Which parts to read: the primitives of the meshes (or nodes) with these
 * names; n_meshes 0 (or opt NULL): all. A name that matches nothing is
 * MIM_ENOTFOUND, listing the names there are. */
typedef struct mim_io_read_options {
    const char *const *meshes;
    uint32_t n_meshes;
} mim_io_read_options_t;

/* The scene's rig, over all its skins: the union of their joints (each
 * joint node once), and each vertex's four heaviest influences. A vertex
 * of a primitive placed under a joint node (a sword in a hand, a hat on
 * the head) without a skin of its own hangs on that joint alone. A vertex
 * on no joint has weights 0. Joint names are the nodes' names, or the
 * humanoid bone names of a VRM file (VRM 0.x "VRM", VRM 1.0 "VRMC_vrm"
 * extensions: "leftUpperArm", ...) where it maps the node. */
typedef struct mim_io_skin {
    uint32_t n_vertices;   /* the whole scene's, as mim_io_read_mesh reads it */
    uint32_t n_joints;     /* the skin's joints */
    uint16_t *joints;      /* 4 * n_vertices: JOINTS_0, indices into the joints */
    float *weights;        /* 4 * n_vertices: WEIGHTS_0, each vertex's normalised to sum 1 (all 0 if they were) */
    char (*names)[MIM_IO_SKIN_NAME_MAX]; /* n_joints names ("" for a node without one), truncated */
    float *joint_positions; /* 3 * n_joints: each joint's origin in the world, as the vertices are placed */
    int32_t *parent;        /* n_joints: the nearest ancestor that is a joint too, or -1 */
    int from_vrm;           /* 1: names from a VRM humanoid map */
} mim_io_skin_t;

typedef struct mim_io_scene {
    mim_mesh_t mesh;        /* every part's vertices and faces, in part order */
    uint32_t n_parts;
    mim_io_part_t *parts;
    int skin_rc;            /* 0: skin holds the rig; MIM_ENOTFOUND: none; else why it could not be read */
    char skin_msg[4352];    /* with skin_rc != 0: one line, naming the file */
    mim_io_skin_t skin;
} mim_io_scene_t;
/* The scene (or, for other formats, the one mesh as one part) with its
 * rig. The mesh gets mim_io_read_mesh's checks; the rig's failure does not
 * fail the read (skin_rc says). opt may be NULL. Errors: mim_io_read_mesh's,
 * MIM_ENOTFOUND for a selected name that is in no mesh or node,
 * MIM_EUNSUPPORTED for more than MIM_IO_MAX_PARTS parts, MIM_EFORMAT for
 * a node graph that is not a forest or a bad node transform, all naming
 * the file. Free with mim_io_scene_free. Safe from many threads. */
int mim_io_read_scene(const char *path, const mim_io_read_options_t *opt, mim_io_scene_t *out, mim_error_t *err);
void mim_io_scene_free(mim_io_scene_t *s); /* accepts NULL; zeroes */

/* The rig of the whole scene mim_io_read_mesh reads from a .gltf/.glb.
 * Returns 0; MIM_ENOTFOUND when the scene has no vertex on a joint (a
 * format other than glTF/GLB, no skinned primitive and no primitive under
 * a joint: not an error for callers, who then segment by geometry);
 * mim_io_read_mesh's errors for a file whose mesh it cannot read;
 * MIM_EFORMAT for a malformed skin, with one line naming what: a
 * JOINTS_0 that is not VEC4 of unsigned byte/short, a WEIGHTS_0 not VEC4
 * of float or normalised unsigned byte/short, a count that differs from
 * POSITION's, a joint index >= the skin's joints, a negative or
 * non-finite weight, a skin joint that is not a valid node index, a skin
 * without joints, inverseBindMatrices that are not MAT4 float of one per
 * joint; MIM_ETRUNCATED for skin data past the end of its buffer;
 * MIM_EUNSUPPORTED for a sparse skin accessor; MIM_ENOMEM. On failure
 * *out is zeroed. Safe to call from many threads. Free with
 * mim_io_skin_free. */
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
    /* An avatar's parts (mim_io_read_scene; issue 28): each becomes a mesh
     * and a node of its own, with its vertices in order, and every node
     * gets the same weights animation; n_parts 0: one part, the mesh. The
     * parts must cover the vertices and faces in order, each face inside
     * its part (MIM_EINVAL, naming the part). Normals are then shared by
     * a vertex's coincident copies wherever they bend less than 30 degrees
     * apart: seams stay smooth, hard edges (flat shading) hard. */
    const mim_io_part_t *parts;
    uint32_t n_parts;
    /* The glTF/GLB the parts were read from (as look_read says): the
     * output keeps its materials, textures (images embedded), samplers
     * and each part's TEXCOORD_n and COLOR_n (as floats), and so looks as
     * the author made it. The rig and morph targets are not kept (the
     * poses are baked). A look that cannot be had (another format, a file
     * gone or changed, an image that cannot be embedded) leaves the output
     * plain: *look_kept (may be NULL) says which. NULL: plain. */
    const char *look;
    const mim_io_read_options_t *look_read;
    int *look_kept;
} mim_io_sequence_t;
int mim_io_write_sequence_glb(const char *path, const mim_io_sequence_t *seq, mim_error_t *err);
/* The same GLB in memory: *data (malloc'd, the caller frees) and *size;
 * origin names it in messages. */
int mim_io_encode_sequence_glb(const mim_io_sequence_t *seq, const char *origin, unsigned char **data, size_t *size,
                               mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
