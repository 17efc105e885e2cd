/* Ground truth for register/: meshes re-triangulated from bodies we have,
 * where the true position of every original vertex is known.
 *
 * - rt_subdivide: 1->4 midpoint subdivision; the original vertices keep
 *   their index and position, the new ones (one per edge) follow them.
 * - rt_shuffle: the same mesh with its vertices and faces in a random order
 *   (and each face's corners rotated, which keeps its orientation).
 * - rt_decimate: OpenMesh's Decimater with the quadric module
 *   (decimate.cpp). It collapses half-edges, so every vertex it keeps is an
 *   original vertex at its original position; rt_decimate_map says which.
 *
 * Outputs are allocated with mim_mesh_alloc (free with mim_mesh_free) and
 * left zeroed on failure. Each returns 0 or MIM_EINVAL (NULL, empty mesh, a
 * face index out of range, a mesh OpenMesh cannot hold as a manifold),
 * MIM_ENOMEM or MIM_EUNSUPPORTED (the result would not fit in 32-bit
 * indices; OpenMesh failed). No output on stdout or stderr. */
#ifndef MIM_RETRIANGULATE_H
#define MIM_RETRIANGULATE_H

#include "mim_core.h"

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* 1->4 midpoint subdivision: V + E vertices (vertex i < in->n_vertices is
 * in's vertex i; the midpoint of each edge is made once and shared by the
 * faces on it), 4 F faces, orientation kept. */
int rt_subdivide(const mim_mesh_t *in, mim_mesh_t *out);

/* The same mesh in a random vertex order and face order, from seed (core's
 * mim_rng_t). new_of_old (in->n_vertices entries, may be NULL) receives the
 * new index of each old vertex: out->positions of new_of_old[i] equal
 * in->positions of i. */
int rt_shuffle(const mim_mesh_t *in, uint64_t seed, mim_mesh_t *out, uint32_t *new_of_old);

/* Quadric decimation (OpenMesh ModQuadricT, with ModNormalFlippingT so that
 * no triangle turns over) to about target_vertices (>= 4) vertices;
 * unreferenced vertices are removed (garbage collection). A closed
 * manifold input gives a closed manifold output. A target at or above
 * in->n_vertices returns a copy of in (less any vertex on no face). */
int rt_decimate(const mim_mesh_t *in, uint32_t target_vertices, mim_mesh_t *out);
/* As rt_decimate; orig_of_new (may be NULL) is malloc'd (the caller frees)
 * with out->n_vertices entries: the index in `in` of each output vertex,
 * whose position it keeps exactly. On failure *orig_of_new is NULL. */
int rt_decimate_map(const mim_mesh_t *in, uint32_t target_vertices, mim_mesh_t *out, uint32_t **orig_of_new);

/* ---- measuring registrations (register/'s tests and benches) ---- */
/* Per-vertex distance (mm) of a to b, count vertices: the mean and the p95
 * (the registration report's quantile). 0 or MIM_ENOMEM. */
int rt_correspondence(const float *a, const float *b, uint32_t count, double *mean_mm, double *p95_mm);
/* A registration target made from a truth body: how 0 subdivided 1->4,
 * 1 decimated to about 40 %; then in a random vertex order (seed). */
int rt_target(const mim_mesh_t *truth, int how, uint64_t seed, mim_mesh_t *target);
/* A closed tetrahedron, 1.6 m tall, at x0: 4 positions (12 floats) and 4
 * triangles (12 indices, counted from base): a small body-sized mesh, and
 * two of them a mesh in two pieces. */
void rt_tetrahedron(float *pos, uint32_t *faces, uint32_t base, float x0);

#ifdef __cplusplus
}
#endif
#endif
