/* transfer/ internals shared between its files (not installed). */
#ifndef MIM_TRANSFER_INTERNAL_H
#define MIM_TRANSFER_INTERNAL_H

#include "mim_transfer.h"

struct mim_xfer_topology {
    uint32_t n, n_faces;
    uint32_t *faces;     /* copy, 3 * n_faces */
    uint32_t *adj_start; /* n + 1 */
    uint32_t *adj;       /* sorted one-ring neighbours */
    uint32_t *vf_start;  /* n + 1: incident faces of each vertex, */
    uint32_t *vf;        /* so normals gather instead of scatter */
};

/* The landmark skeleton over the 16 default names (retarget.c): 15 bones,
 * each a child landmark and its parent, parents before children, rooted at
 * the pelvis. Fills the map indices; MIM_EUNSUPPORTED (naming what) when
 * the map is not the 16 default landmarks; what names the caller. */
#define MIM__XFER_BONES MIM_LANDMARK_BONES
int mim__xfer_landmark_tree(const mim_landmark_map_t *map, int *root, int child[MIM__XFER_BONES],
                            int parent[MIM__XFER_BONES], const char *what, mim_error_t *err);

#include <cholmod.h>

struct mim_xfer_solver {
    const mim_xfer_topology_t *topo;
    mim_xfer_formulation_t formulation;
    uint32_t n, nc, nf;
    uint32_t *cons;     /* nc constrained vertices, caller's order */
    int32_t *slot;      /* n: free index (>= 0), or -1 - constraint index */
    uint32_t *free_v;   /* nf free vertices, increasing */
    cholmod_common cc;
    int cc_started;
    int low_rank;       /* least squares through L^c + rank-nc update */
    cholmod_factor *L;
    cholmod_dense *B, *X, *Y, *E;
    uint64_t analyses, factorizations, solves;
    double t_analyze, t_factorize;
    /* transfer workspaces: 3n positions (current, previous), 3n offsets
     * F(X) W of the last iterate, 3n right-hand side scratch, face normals */
    double *pos, *prev, *D, *r, *fn;
    double *mframes, *mW; /* morph: frames and W of one in-between pose */
    /* low-rank least squares: K = L_cf^T has -1 at (j, c) for each free
     * one-ring neighbour j of constrained vertex c (k_start/k_free, CSR
     * by c); Zs = (L^c)^-2 K S^-1, n_free x nc column-major, S = I + K^T
     * (L^c)^-2 K; rc = the constrained rows of the residual target, nc x 3 */
    uint32_t *k_start, *k_free;
    /* the constraint terms of the right-hand side, -L_:c U (square: free
     * rows only): row slot (as slot[]), constraint, coefficient */
    struct mim__xfer_cterm { int32_t row; uint32_t con; double coef; } *cterm;
    uint32_t n_cterm;
    double *Zs, *rc;
    /* cons, slot, free_v, L, k_start, k_free, cterm and Zs depend only on
     * the connectivity and the constrained set: solvers made by
     * mim_xfer_solver_share hold them with the one they came from, and the
     * last to close frees them (owners counts the holders) */
    int *owners;
};

/* The Laplacian offsets F(v_i) W_i (3 * n) of the frames mim_xfer_frames_d
 * gives, with a face-normal workspace (3 * n_faces doubles). */
void mim__xfer_offsets_ws(const mim_xfer_topology_t *t, const double *positions, const double *W, double *offsets,
                          double *face_normals);

/* Solves with s->B filled (nf x 3) and, for low-rank least squares,
 * s->rc (nc x 3); the solution is in s->X->x. */
int mim__xfer_solve(mim_xfer_solver_t *s, mim_error_t *err);
#endif
