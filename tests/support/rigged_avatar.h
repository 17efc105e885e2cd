/* Realistic rigged glTF test avatars (GLB) made from mimic's procedural
 * bodies (synth/), for the tests of the avatar reader: avatars "as their
 * authors ship them" (DESIGN.md "Data to work with"): several meshes and
 * primitives, vertices split along UV seams, flat shading, separate shells
 * (eyes, boots), a prop parented to a bone, centimetres under a node scale,
 * Mixamo / Blender / VRM 0.x / VRM 1.0 joint names or none, closed fists,
 * an A-pose or a T-pose rest, a texture.
 *
 * The file: one node per synth joint (the synth hierarchy, translations
 * only) under a root node "Armature" (scale 0.01 when centimetres); the
 * skin's joints are those nodes in synth joint order (skin joint j = synth
 * joint j), its inverse bind matrices the inverse of each joint's transform
 * relative to Armature (so that vertices stored in Armature units come out
 * in metres once the joints' world transforms, Armature's scale included,
 * are applied). Skinned mesh nodes are scene roots without a transform (the
 * validator warns about any other place, and the spec ignores it); without
 * a skin (RA_NAMES_NONE) the mesh nodes are children of Armature. The prop
 * is a node with translation and rotation, child of the right hand's joint
 * node, not skinned.
 *
 * Mesh order: JointRings (when joint_rings_first), Body (one primitive, or
 * two with two_primitives: upper, then lower body), Eyes, Boots (shells),
 * Sword (prop); one primitive each except Body. Every primitive has
 * POSITION (with min/max), NORMAL, indices (unsigned short when the
 * primitive has fewer than 65536 vertices, else unsigned int), TEXCOORD_0
 * when texture or split_seams, and JOINTS_0 / WEIGHTS_0 (unsigned short /
 * float, two non-zero weights on body vertices, one on rigid shells) when
 * skinned.
 *
 * No cmocka, no output: callers check what they need. */
#ifndef MIM_TEST_RIGGED_AVATAR_H
#define MIM_TEST_RIGGED_AVATAR_H

#include <stddef.h>
#include <stdint.h>

typedef enum { RA_NAMES_MIXAMO, RA_NAMES_BLENDER, RA_NAMES_VRM0, RA_NAMES_VRM1, RA_NAMES_NONE } ra_names_t;

typedef struct ra_options {
    uint32_t vertices;     /* synth body vertex count, 0: 3000 */
    uint64_t seed;         /* synth seed, 0: 7 */
    uint32_t subject;      /* synth subject (the synth is made with subject + 1 subjects) */
    int tpose;             /* 1: the rest is synth pose 1 (T-pose), else pose 0 (A-pose) */
    ra_names_t names;      /* joint names; VRM0 also turns the model to face -Z; NONE: no skin */
    int split_seams;       /* UV islands per body part (trunk, arms, legs), each cut at its back:
                              vertices on the cuts are bitwise-equal copies with other UVs */
    int flat;              /* every triangle of every primitive has its own 3 vertices, face normals */
    int joint_rings_first; /* a mesh "JointRings" (a small torus around the bone at each joint,
                              skinned rigidly to it) first in meshes[], nodes[] and the scene */
    int shells;            /* meshes "Eyes" (two spheres sunk half into the face) and "Boots" (a
                              closed shell 5 mm outside each foot, up to the ankle) */
    int prop;              /* mesh "Sword" (0.8 m x 3 cm x 1 cm box) in a node that is a child of the
                              right hand's joint node, held in the hand, pointing forward and down */
    int centimetres;       /* positions and translations in cm, Armature scaled by 0.01 */
    int fists;             /* the hands beyond the wrist pulled towards a point 4 cm past the wrist */
    int texture;           /* a material with a 16x16 checker PNG (in the GLB), TEXCOORD_0 everywhere */
    int two_primitives;    /* Body as two primitives: upper body, lower body (pelvis and legs);
                              vertices on the cut are in both; the lower one has another material
                              when texture */
} ra_options_t;

#define RA_MAX_PRIMITIVES 16
#define RA_N_JOINTS 19
#define RA_N_LANDMARKS 16

typedef struct ra_primitive_info {
    char mesh_name[64];
    uint32_t n_vertices, n_faces;
    int is_body; /* a primitive of mesh "Body" */
} ra_primitive_info_t;

typedef struct ra_avatar_info {
    uint32_t n_primitives; /* in the order a reader meets them: meshes[] order, then primitives order */
    ra_primitive_info_t primitive[RA_MAX_PRIMITIVES];
    uint32_t n_vertices; /* sum over primitives */
    /* 3 * n_vertices: every vertex in metres in the world frame as a glTF
     * viewer shows the file (node transforms and the skin at its bind pose
     * applied), primitives concatenated in the order above, each in its
     * vertex order as written; computed from the generator's own data, not
     * by reading the file (malloc'd, ra_info_free) */
    float *world;
    float landmarks[3 * RA_N_LANDMARKS]; /* the synth landmark vertices of the body (world, metres),
                                            in mim_synth_landmarks' order */
    float joints[3 * RA_N_JOINTS];       /* the synth joints (world, metres), synth order */
    uint32_t n_body_welded;              /* body vertices once coincident copies are merged
                                            (= the synth body's vertex count) */
} ra_avatar_info_t;

/* Writes the avatar to path (a GLB). info may be NULL. Returns 0, or a
 * negative MIM_E* code with a one-line reason in why. */
int ra_write(const ra_options_t *opt, const char *path, ra_avatar_info_t *info, char *why, size_t why_size);
void ra_info_free(ra_avatar_info_t *info); /* accepts NULL; frees world and zeroes it */

#endif
