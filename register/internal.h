/* register/ internals shared between its files (not installed). */
#ifndef MIM_REGISTER_INTERNAL_H
#define MIM_REGISTER_INTERNAL_H

#include "mim_register.h"

#include <flann/flann.h>

/* A surface to find closest points on: the target of a registration, or
 * the proxy an avatar is bound to. The kd-tree (FLANN's single tree,
 * searched exactly) is over its vertices; a closest point is then sought
 * on every triangle around the k nearest vertices. */
typedef struct mim__reg_surface {
    uint32_t n, nf;
    const uint32_t *faces; /* the caller's, 3 * nf */
    float *pos;            /* copy of the positions (FLANN wants them writable) */
    float *fnormal;        /* 3 * nf unit face normals */
    float *sphere;         /* 4 * nf: each triangle's bounding sphere (centroid, radius), to skip it early */
    uint32_t *vf_start;    /* n + 1: faces around each vertex */
    uint32_t *vf;
    uint8_t *edge_boundary; /* 3 * nf: edge (f_k, f_k+1) belongs to one triangle only */
    uint8_t *vertex_boundary; /* n */
    flann_index_t index;
    struct FLANNParameters params;
} mim__reg_surface_t;

/* Opens the surface after the target check (mim_reg_target_check); with
 * check 0 the mesh is trusted (a proxy of the store's connectivity); with
 * check 2 it is an avatar of several pieces (mim_reg_options_t pieces):
 * a body, indices in range, but any number of pieces, and an edge of more
 * than two triangles is simply no boundary. */
int mim__reg_surface_open(mim__reg_surface_t *s, const mim_mesh_t *m, int check, const char *origin,
                          mim_error_t *err);
void mim__reg_surface_close(mim__reg_surface_t *s);

typedef struct mim__reg_hit {
    uint32_t face;
    float point[3];
    float u, v;    /* barycentric: point = (1 - u - v) a + u b + v c */
    double d2;     /* squared distance */
    int boundary;  /* the closest point is on the surface's boundary */
} mim__reg_hit_t;

#define MIM__REG_KNN 4
/* Closest points of nq query points (3 * nq floats). Allocates its own
 * FLANN result arrays (nq * MIM__REG_KNN); MIM_ENOMEM or MIM_EUNSUPPORTED. */
int mim__reg_surface_closest(const mim__reg_surface_t *s, const float *queries, uint32_t nq, mim__reg_hit_t *hits,
                             mim_error_t *err);

/* Non-rigid ICP (nicp.c) over the connectivity topo, from x0 (3 * n
 * doubles) onto the surface, with landmark vertices lm_vertex (count) held
 * softly at lm_target (3 * count floats); data_w (n, NULL: all 1) weighs
 * each vertex's closest point. */
typedef struct mim__reg_nicp mim__reg_nicp_t;
int mim__reg_nicp_open(mim__reg_nicp_t **out, const mim_xfer_topology_t *topo, mim_error_t *err);
void mim__reg_nicp_close(mim__reg_nicp_t **p);
int mim__reg_nicp_run(mim__reg_nicp_t *p, const mim_reg_options_t *opt, const mim__reg_surface_t *surface,
                      const uint32_t *lm_vertex, const float *lm_target, uint32_t count, const double *x0,
                      const double *data_w, double *x, uint32_t *iterations, double *rejected, mim_error_t *err);

/* Options with defaults filled in. */
mim_reg_options_t mim__reg_options(const mim_reg_options_t *opt);
#endif
