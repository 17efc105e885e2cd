/* transfer/ internals shared between its files (not installed). */
#ifndef MIM_TRANSFER_INTERNAL_H
#define MIM_TRANSFER_INTERNAL_H

#include "mim_transfer.h"

struct mim_xfer_topology {
    uint32_t n, n_faces;
    uint32_t *faces;     /* copy, 3 * n_faces */
    uint32_t *adj_start; /* n + 1 */
    uint32_t *adj;       /* sorted one-ring neighbours */
};

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
    cholmod_factor *L;
    cholmod_dense *B, *X, *Y, *E;
    uint64_t analyses, factorizations, solves;
    double t_analyze, t_factorize;
    /* transfer workspaces: 3n positions (current, previous), 9n frames,
     * 3n right-hand side scratch */
    double *pos, *prev, *frames, *r;
};

/* Solves with s->B filled (nf x 3); the solution is in s->X->x. */
int mim__xfer_solve(mim_xfer_solver_t *s, mim_error_t *err);
#endif
