/* The constrained solve with one cached CHOLMOD factor (seed 000, Section
 * 3.4, equation (3)).
 *
 * Square (the paper): the constrained vertices' rows and columns are removed
 * from L, leaving L^c = L_ff (symmetric positive definite when every
 * connected component holds a constraint); their known terms move to the
 * right-hand side b^c.
 * Least squares (mimic's default): all n rows of L X = F*W stay in the
 * objective, the constrained unknowns are eliminated: minimise
 * ||L_:f X_f + L_:c U - F*W||^2, whose normal matrix L_:f^T L_:f = L_f: L_:f
 * is SPD too.
 * The normal matrix has the two-ring pattern, and its factor about 2.7x
 * the fill of L^c's. But L_:f^T L_:f = (L^c)^2 + K K^T with K = L_cf^T,
 * only nc (16) columns: so by the Woodbury identity the least-squares
 * solution is
 *     x = y + Z S^-1 (r_c - K^T y),   y = (L^c)^-1 r_f,
 *     Z = (L^c)^-2 K,  S = I + K^T Z   (nc x nc),
 * where r is the residual target F*W - L_:c U split into free rows r_f and
 * constrained rows r_c (check: ((L^c)^2 + K K^T) x = L^c r_f + K r_c, the
 * normal equations' right-hand side). Z S^-1 is computed once at open, so
 * a least-squares solve costs one L^c solve plus an n_free x nc product.
 * Either way the factor depends only on the connectivity and the
 * constrained set, so it is analysed and factored once here and every
 * transfer (any avatar, any template, any landmark positions) reuses it.
 * Factors are simplicial (faster than supernodal at 5-20k vertices); B, X
 * and the solve workspaces Y, E are allocated once and reused through
 * cholmod_solve2. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *chol_status(int st)
{
    switch (st) {
    case CHOLMOD_OK: return "ok";
    case CHOLMOD_NOT_INSTALLED: return "method not installed";
    case CHOLMOD_OUT_OF_MEMORY: return "out of memory";
    case CHOLMOD_TOO_LARGE: return "problem too large";
    case CHOLMOD_INVALID: return "invalid input";
    case CHOLMOD_NOT_POSDEF: return "matrix not positive definite";
    default: return "warning";
    }
}

static int plain_solve(mim_xfer_solver_t *s, mim_error_t *err);
static int own_workspaces(mim_xfer_solver_t *s, mim_error_t *err);

/* CSC of L_ff, upper triangle (stype 1). */
static cholmod_sparse *build_square(mim_xfer_solver_t *s)
{
    const mim_xfer_topology_t *t = s->topo;
    size_t nnz = 0;
    for (uint32_t j = 0; j < s->nf; j++) {
        uint32_t v = s->free_v[j];
        nnz++;
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++) {
            int32_t q = s->slot[t->adj[k]];
            if (q >= 0 && (uint32_t)q < j)
                nnz++;
        }
    }
    cholmod_sparse *A = cholmod_allocate_sparse(s->nf, s->nf, nnz, 1, 1, 1, CHOLMOD_REAL, &s->cc);
    if (!A)
        return NULL;
    int *Ap = A->p, *Ai = A->i;
    double *Ax = A->x;
    size_t w = 0;
    for (uint32_t j = 0; j < s->nf; j++) {
        uint32_t v = s->free_v[j];
        Ap[j] = (int)w;
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++) {
            int32_t q = s->slot[t->adj[k]];
            if (q >= 0 && (uint32_t)q < j) {
                Ai[w] = q;
                Ax[w++] = -1.0;
            }
        }
        Ai[w] = (int)j;
        Ax[w++] = (double)(t->adj_start[v + 1] - t->adj_start[v]);
    }
    Ap[s->nf] = (int)w;
    return A;
}

/* L_f: (nf x n, unsymmetric): the free rows of L. Its A A^T = L_f: L_:f. */
static cholmod_sparse *build_free_rows(mim_xfer_solver_t *s)
{
    const mim_xfer_topology_t *t = s->topo;
    size_t nnz = 0;
    for (uint32_t v = 0; v < s->n; v++) {
        nnz += s->slot[v] >= 0;
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++)
            nnz += s->slot[t->adj[k]] >= 0;
    }
    cholmod_sparse *A = cholmod_allocate_sparse(s->nf, s->n, nnz, 1, 1, 0, CHOLMOD_REAL, &s->cc);
    if (!A)
        return NULL;
    int *Ap = A->p, *Ai = A->i;
    double *Ax = A->x;
    size_t w = 0;
    for (uint32_t v = 0; v < s->n; v++) {
        Ap[v] = (int)w;
        int diag_done = s->slot[v] < 0;
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++) {
            uint32_t u = t->adj[k];
            if (!diag_done && u > v) {
                Ai[w] = s->slot[v];
                Ax[w++] = (double)(t->adj_start[v + 1] - t->adj_start[v]);
                diag_done = 1;
            }
            if (s->slot[u] >= 0) {
                Ai[w] = s->slot[u];
                Ax[w++] = -1.0;
            }
        }
        if (!diag_done) {
            Ai[w] = s->slot[v];
            Ax[w++] = (double)(t->adj_start[v + 1] - t->adj_start[v]);
        }
    }
    Ap[s->n] = (int)w;
    return A;
}

static int check_components(mim_xfer_solver_t *s, mim_error_t *err)
{
    const mim_xfer_topology_t *t = s->topo;
    uint32_t *queue = malloc((size_t)s->n * sizeof *queue);
    unsigned char *seen = calloc(s->n, 1);
    if (!queue || !seen) {
        free(queue);
        free(seen);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    }
    uint32_t head = 0, tail = 0;
    for (uint32_t c = 0; c < s->nc; c++) {
        seen[s->cons[c]] = 1;
        queue[tail++] = s->cons[c];
    }
    while (head < tail) {
        uint32_t v = queue[head++];
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++)
            if (!seen[t->adj[k]]) {
                seen[t->adj[k]] = 1;
                queue[tail++] = t->adj[k];
            }
    }
    int rc = 0;
    if (tail < s->n) {
        uint32_t v = 0;
        while (seen[v])
            v++;
        rc = mim_error_set(err, MIM_ETOPOLOGY,
                           "transfer: vertex %u lies in a part of the mesh with no constrained vertex "
                           "(%u of %u vertices unreachable)",
                           v, s->n - tail, s->n);
    }
    free(queue);
    free(seen);
    return rc;
}

/* The low-rank least-squares terms (see the top of this file): K as CSR
 * by constraint, Zs = Z S^-1 (column-major), and the r_c workspace. */
static int setup_low_rank(mim_xfer_solver_t *s, mim_error_t *err)
{
    const mim_xfer_topology_t *t = s->topo;
    const uint32_t nc = s->nc, nf = s->nf;
    s->k_start = malloc(((size_t)nc + 1) * sizeof *s->k_start);
    s->Zs = malloc((size_t)nf * nc * sizeof *s->Zs);
    s->rc = malloc(6 * (size_t)nc * sizeof *s->rc); /* r_c, then d */
    double *S = malloc((size_t)nc * nc * sizeof *S);
    if (!s->k_start || !s->Zs || !s->rc || !S) {
        free(S);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    }
    size_t cnt = 0;
    for (uint32_t c = 0; c < nc; c++) {
        s->k_start[c] = (uint32_t)cnt;
        uint32_t v = s->cons[c];
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++)
            cnt += s->slot[t->adj[k]] >= 0;
    }
    s->k_start[nc] = (uint32_t)cnt;
    s->k_free = malloc((cnt ? cnt : 1) * sizeof *s->k_free);
    cholmod_dense *K = cholmod_zeros(nf, nc, CHOLMOD_REAL, &s->cc);
    if (!s->k_free || !K) {
        free(S);
        cholmod_free_dense(&K, &s->cc);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    }
    double *Kx = K->x;
    for (uint32_t c = 0, w = 0; c < nc; c++) {
        uint32_t v = s->cons[c];
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++) {
            int32_t q = s->slot[t->adj[k]];
            if (q >= 0) {
                s->k_free[w++] = (uint32_t)q;
                Kx[(size_t)c * nf + (uint32_t)q] = -1.0;
            }
        }
    }
    cholmod_dense *Z1 = cholmod_solve(CHOLMOD_A, s->L, K, &s->cc);
    cholmod_dense *Z = Z1 ? cholmod_solve(CHOLMOD_A, s->L, Z1, &s->cc) : NULL;
    cholmod_free_dense(&Z1, &s->cc);
    cholmod_free_dense(&K, &s->cc);
    if (!Z) {
        free(S);
        return mim_error_set(err, MIM_EUNSUPPORTED, "transfer: CHOLMOD solve failed: %s",
                             chol_status(s->cc.status));
    }
    const double *Zx = Z->x; /* nf x nc, column-major */
    /* S = I + K^T Z, then its Cholesky factor in place (lower) */
    for (uint32_t a = 0; a < nc; a++)
        for (uint32_t b = 0; b < nc; b++) {
            double v = a == b ? 1.0 : 0.0;
            for (uint32_t k = s->k_start[a]; k < s->k_start[a + 1]; k++)
                v -= Zx[(size_t)b * nf + s->k_free[k]];
            S[a * nc + b] = v;
        }
    int rc = 0;
    for (uint32_t j = 0; j < nc && !rc; j++) {
        double d = S[j * nc + j];
        for (uint32_t k = 0; k < j; k++)
            d -= S[j * nc + k] * S[j * nc + k];
        if (!(d > 0.0)) {
            rc = mim_error_set(err, MIM_EUNSUPPORTED, "transfer: low-rank update not positive definite");
            break;
        }
        S[j * nc + j] = sqrt(d);
        for (uint32_t i = j + 1; i < nc; i++) {
            double v = S[i * nc + j];
            for (uint32_t k = 0; k < j; k++)
                v -= S[i * nc + k] * S[j * nc + k];
            S[i * nc + j] = v / S[j * nc + j];
        }
    }
    /* row j of Zs solves S zs = Z[j, :] (S symmetric, so Zs = Z S^-1);
     * Zs is stored column-major (nf x nc) like Z */
    double z[MIM_LANDMARKS_MAX];
    for (uint32_t j = 0; j < nf && !rc; j++) {
        for (uint32_t i = 0; i < nc; i++) {
            double v = Zx[(size_t)i * nf + j];
            for (uint32_t k = 0; k < i; k++)
                v -= S[i * nc + k] * z[k];
            z[i] = v / S[i * nc + i];
        }
        for (uint32_t i = nc; i-- > 0;) {
            double v = z[i];
            for (uint32_t k = i + 1; k < nc; k++)
                v -= S[k * nc + i] * z[k];
            z[i] = v / S[i * nc + i];
        }
        for (uint32_t i = 0; i < nc; i++)
            s->Zs[(size_t)i * nf + j] = z[i];
    }
    cholmod_free_dense(&Z, &s->cc);
    free(S);
    return rc;
}

/* -L_:c U: each constrained vertex c contributes +u_c to its neighbours'
 * rows (l = -1) and, in least squares, -deg(c) u_c to its own row; the
 * square system has no constrained rows. */
static int build_cterms(mim_xfer_solver_t *s, mim_error_t *err)
{
    const mim_xfer_topology_t *t = s->topo;
    size_t cnt = 0;
    for (uint32_t c = 0; c < s->nc; c++)
        cnt += 1 + t->adj_start[s->cons[c] + 1] - t->adj_start[s->cons[c]];
    s->cterm = malloc(cnt * sizeof *s->cterm);
    if (!s->cterm)
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    const int ls = s->formulation == MIM_XFER_LEAST_SQUARES;
    uint32_t w = 0;
    for (uint32_t c = 0; c < s->nc; c++) {
        uint32_t v = s->cons[c];
        if (ls)
            s->cterm[w++] = (struct mim__xfer_cterm){s->slot[v], c, -(double)(t->adj_start[v + 1] - t->adj_start[v])};
        for (uint32_t k = t->adj_start[v]; k < t->adj_start[v + 1]; k++)
            if (ls || s->slot[t->adj[k]] >= 0)
                s->cterm[w++] = (struct mim__xfer_cterm){s->slot[t->adj[k]], c, 1.0};
    }
    s->n_cterm = w;
    return 0;
}

int mim_xfer_solver_open(mim_xfer_solver_t **out, const mim_xfer_topology_t *t,
                         const uint32_t *constrained, uint32_t count,
                         const mim_xfer_solver_options_t *opt, mim_error_t *err)
{
    if (!out)
        return mim_error_set(err, MIM_EINVAL, "transfer: NULL solver handle");
    *out = NULL;
    if (!t || !constrained)
        return mim_error_set(err, MIM_EINVAL, "transfer: NULL topology or constrained vertex list");
    if (count == 0 || count >= t->n)
        return mim_error_set(err, MIM_EINVAL, "transfer: %u constrained vertices for %u vertices (need 1..%u)",
                             count, t->n, t->n - 1);
    mim_xfer_solver_options_t o = {0};
    if (opt)
        o = *opt;
    if (o.formulation != MIM_XFER_LEAST_SQUARES && o.formulation != MIM_XFER_SQUARE)
        return mim_error_set(err, MIM_EINVAL, "transfer: unknown formulation %d", (int)o.formulation);
    for (uint32_t c = 0; c < count; c++)
        if (constrained[c] >= t->n)
            return mim_error_set(err, MIM_EINVAL, "transfer: constrained vertex %u (#%u) past %u vertices",
                                 constrained[c], c, t->n);

    mim_xfer_solver_t *s = calloc(1, sizeof *s);
    if (!s || !(s->owners = malloc(sizeof *s->owners))) {
        free(s);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    }
    *s->owners = 1;
    s->topo = t;
    s->formulation = o.formulation;
    /* the rank-nc update pays for itself for a few landmarks, not for
     * thousands of constrained vertices */
    s->low_rank = o.formulation == MIM_XFER_LEAST_SQUARES && !o.normal_factor && count <= MIM_LANDMARKS_MAX;
    s->n = t->n;
    s->nc = count;
    s->nf = t->n - count;
    s->cons = malloc(count * sizeof *s->cons);
    s->slot = malloc((size_t)t->n * sizeof *s->slot);
    s->free_v = malloc((size_t)s->nf * sizeof *s->free_v);
    int wrc = !s->cons || !s->slot || !s->free_v
                  ? mim_error_set(err, MIM_ENOMEM, "transfer: out of memory for %u vertices", t->n)
                  : own_workspaces(s, err);
    if (wrc) {
        mim_xfer_solver_close(&s);
        return wrc;
    }
    memcpy(s->cons, constrained, count * sizeof *s->cons);
    for (uint32_t v = 0; v < t->n; v++)
        s->slot[v] = 0;
    for (uint32_t c = 0; c < count; c++) {
        if (s->slot[constrained[c]] != 0) {
            int rc = mim_error_set(err, MIM_EINVAL, "transfer: vertex %u is constrained twice (#%u)",
                                   constrained[c], c);
            mim_xfer_solver_close(&s);
            return rc;
        }
        s->slot[constrained[c]] = -1 - (int32_t)c;
    }
    uint32_t nf = 0;
    for (uint32_t v = 0; v < t->n; v++)
        if (s->slot[v] == 0) {
            s->slot[v] = (int32_t)nf;
            s->free_v[nf++] = v;
        }
    int rc = check_components(s, err);
    if (!rc)
        rc = build_cterms(s, err);
    if (rc) {
        mim_xfer_solver_close(&s);
        return rc;
    }

    cholmod_start(&s->cc);
    s->cc_started = 1;
    s->cc.print = 0;
    s->cc.supernodal = o.supernodal ? CHOLMOD_SUPERNODAL : CHOLMOD_SIMPLICIAL;
    /* AMD only: on these meshes METIS and NESDIS give more fill than AMD,
     * not less, and take several times its analysis time (docs/development.md,
     * "Notes on the libraries") */
    s->cc.nmethods = 1;
    s->cc.method[0].ordering = CHOLMOD_AMD;
    s->cc.postorder = 1;

    cholmod_sparse *A = NULL;
    if (s->formulation == MIM_XFER_SQUARE || s->low_rank) {
        A = build_square(s);
    } else {
        cholmod_sparse *M = build_free_rows(s);
        cholmod_sparse *S = M ? cholmod_aat(M, NULL, 0, 1, &s->cc) : NULL;
        A = S ? cholmod_copy(S, 1, 1, &s->cc) : NULL;
        if (A && !cholmod_sort(A, &s->cc)) {
            cholmod_free_sparse(&A, &s->cc);
        }
        cholmod_free_sparse(&S, &s->cc);
        cholmod_free_sparse(&M, &s->cc);
    }
    if (!A) {
        rc = mim_error_set(err, MIM_ENOMEM, "transfer: building the %s matrix failed (%s)",
                           s->low_rank || s->formulation == MIM_XFER_SQUARE ? "L^c" : "normal",
                           chol_status(s->cc.status));
        mim_xfer_solver_close(&s);
        return rc;
    }
    double t0 = mim_now();
    s->L = cholmod_analyze(A, &s->cc);
    double t1 = mim_now();
    s->analyses++;
    s->t_analyze = t1 - t0;
    int ok = s->L != NULL;
    if (ok) {
        ok = cholmod_factorize(A, s->L, &s->cc) && s->cc.status == CHOLMOD_OK;
        s->factorizations++;
        s->t_factorize = mim_now() - t1;
    }
    cholmod_free_sparse(&A, &s->cc);
    if (!ok) {
        rc = mim_error_set(err, MIM_EUNSUPPORTED, "transfer: Cholesky factorization failed: %s",
                           chol_status(s->cc.status));
        mim_xfer_solver_close(&s);
        return rc;
    }
    if (s->low_rank && (rc = setup_low_rank(s, err)) != 0) {
        mim_xfer_solver_close(&s);
        return rc;
    }
    s->B = cholmod_zeros(s->nf, 3, CHOLMOD_REAL, &s->cc);
    if (!s->B) {
        mim_xfer_solver_close(&s);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    }
    /* one solve now allocates X, Y, E once; later solves reuse them */
    rc = plain_solve(s, err);
    s->solves = 0;
    if (rc) {
        mim_xfer_solver_close(&s);
        return rc;
    }
    *out = s;
    return 0;
}

/* Its own workspaces, and the first solve that allocates X, Y, E. */
static int own_workspaces(mim_xfer_solver_t *s, mim_error_t *err)
{
    const mim_xfer_topology_t *t = s->topo;
    s->pos = malloc(3 * (size_t)t->n * sizeof(double));
    s->prev = malloc(3 * (size_t)t->n * sizeof(double));
    s->r = malloc(3 * (size_t)t->n * sizeof(double));
    s->D = malloc(3 * (size_t)t->n * sizeof(double));
    s->fn = malloc(3 * (size_t)t->n_faces * sizeof(double));
    s->mframes = malloc(9 * (size_t)t->n * sizeof(double));
    s->mW = malloc(3 * (size_t)t->n * sizeof(double));
    if (!s->mW || !s->pos || !s->prev || !s->r || !s->D || !s->fn || !s->mframes)
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory for %u vertices", t->n);
    return 0;
}

int mim_xfer_solver_share(mim_xfer_solver_t **out, mim_xfer_solver_t *base, mim_error_t *err)
{
    if (!out)
        return mim_error_set(err, MIM_EINVAL, "transfer: NULL solver handle");
    *out = NULL;
    if (!base)
        return mim_error_set(err, MIM_EINVAL, "transfer: no solver to share");
    mim_xfer_solver_t *s = calloc(1, sizeof *s);
    if (!s)
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    s->topo = base->topo, s->formulation = base->formulation, s->low_rank = base->low_rank;
    s->n = base->n, s->nc = base->nc, s->nf = base->nf;
    s->cons = base->cons, s->slot = base->slot, s->free_v = base->free_v, s->L = base->L;
    s->k_start = base->k_start, s->k_free = base->k_free, s->cterm = base->cterm, s->n_cterm = base->n_cterm;
    s->Zs = base->Zs;
    s->owners = base->owners;
    __atomic_add_fetch(s->owners, 1, __ATOMIC_ACQ_REL);
    int rc = own_workspaces(s, err);
    if (!rc && s->low_rank && !(s->rc = malloc(6 * (size_t)s->nc * sizeof *s->rc)))
        rc = mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    if (!rc) {
        cholmod_start(&s->cc);
        s->cc_started = 1;
        s->cc.print = 0;
        s->cc.supernodal = base->cc.supernodal;
        if (!(s->B = cholmod_zeros(s->nf, 3, CHOLMOD_REAL, &s->cc)))
            rc = mim_error_set(err, MIM_ENOMEM, "transfer: out of memory");
    }
    if (!rc && !(rc = plain_solve(s, err)))
        s->solves = 0;
    if (rc) {
        mim_xfer_solver_close(&s);
        return rc;
    }
    *out = s;
    return 0;
}

void mim_xfer_solver_close(mim_xfer_solver_t **sp)
{
    if (!sp || !*sp)
        return;
    mim_xfer_solver_t *s = *sp;
    /* the factor and its company stay while another solver holds them */
    if (s->owners && __atomic_sub_fetch(s->owners, 1, __ATOMIC_ACQ_REL) > 0) {
        s->cons = NULL, s->slot = NULL, s->free_v = NULL, s->L = NULL;
        s->k_start = NULL, s->k_free = NULL, s->cterm = NULL, s->Zs = NULL;
    } else {
        free(s->owners);
    }
    if (s->cc_started) {
        cholmod_free_factor(&s->L, &s->cc);
        cholmod_free_dense(&s->B, &s->cc);
        cholmod_free_dense(&s->X, &s->cc);
        cholmod_free_dense(&s->Y, &s->cc);
        cholmod_free_dense(&s->E, &s->cc);
        cholmod_finish(&s->cc);
    }
    free(s->cons);
    free(s->slot);
    free(s->free_v);
    free(s->pos);
    free(s->prev);
    free(s->r);
    free(s->D);
    free(s->fn);
    free(s->mframes);
    free(s->mW);
    free(s->cterm);
    free(s->k_start);
    free(s->k_free);
    free(s->Zs);
    free(s->rc);
    free(s);
    *sp = NULL;
}

static int plain_solve(mim_xfer_solver_t *s, mim_error_t *err)
{
    if (!cholmod_solve2(CHOLMOD_A, s->L, s->B, NULL, &s->X, NULL, &s->Y, &s->E, &s->cc))
        return mim_error_set(err, MIM_EUNSUPPORTED, "transfer: CHOLMOD solve failed: %s",
                             chol_status(s->cc.status));
    s->solves++;
    return 0;
}

/* X (nf x 3, column-major) += Zs d, Zs nf x nc, d nc x 3 (row-major),
 * four columns of Zs a pass: the passes over X are what cost (each loads
 * and stores X; one column a pass spent half the correction's time
 * storing). Its own function, with restrict arguments, so that the row
 * loop vectorises (inside the loop over columns GCC does not). */
static void add_four_columns(double *restrict X0, double *restrict X1, double *restrict X2,
                             const double *restrict z0, const double *restrict z1, const double *restrict z2,
                             const double *restrict z3, const double *e, uint32_t nf)
{
    const double e0 = e[0], e1 = e[1], e2 = e[2], e3 = e[3], e4 = e[4], e5 = e[5], e6 = e[6], e7 = e[7], e8 = e[8],
                 e9 = e[9], e10 = e[10], e11 = e[11];
    for (uint32_t j = 0; j < nf; j++) {
        const double a = z0[j], b = z1[j], g = z2[j], h = z3[j];
        X0[j] += a * e0 + b * e3 + g * e6 + h * e9;
        X1[j] += a * e1 + b * e4 + g * e7 + h * e10;
        X2[j] += a * e2 + b * e5 + g * e8 + h * e11;
    }
}

static void add_columns(double *X, const double *Zs, const double *d, uint32_t nf, uint32_t nc)
{
    double *restrict X0 = X, *restrict X1 = X + nf, *restrict X2 = X + 2 * (size_t)nf;
    uint32_t c = 0;
    for (; c + 4 <= nc; c += 4) {
        const double *z = Zs + (size_t)c * nf;
        add_four_columns(X0, X1, X2, z, z + nf, z + 2 * (size_t)nf, z + 3 * (size_t)nf, d + 3 * c, nf);
    }
    for (; c < nc; c++) {
        const double *restrict z = Zs + (size_t)c * nf;
        const double d0 = d[3 * c], d1 = d[3 * c + 1], d2 = d[3 * c + 2];
        for (uint32_t j = 0; j < nf; j++) {
            X0[j] += z[j] * d0;
            X1[j] += z[j] * d1;
            X2[j] += z[j] * d2;
        }
    }
}

int mim__xfer_solve(mim_xfer_solver_t *s, mim_error_t *err)
{
    int rc = plain_solve(s, err);
    if (rc || !s->low_rank)
        return rc;
    /* x = y + Zs d,  d = r_c - K^T y (K's entries are -1) */
    const uint32_t nc = s->nc, nf = s->nf;
    double *X = s->X->x, *d = s->rc + 3 * (size_t)nc;
    for (uint32_t c = 0; c < nc; c++)
        for (uint32_t k = 0; k < 3; k++) {
            double v = s->rc[3 * c + k];
            for (uint32_t q = s->k_start[c]; q < s->k_start[c + 1]; q++)
                v += X[(size_t)k * nf + s->k_free[q]];
            d[3 * c + k] = v;
        }
    add_columns(X, s->Zs, d, nf, nc);
    return 0;
}

int mim_xfer_solver_solve_columns(mim_xfer_solver_t *s, const double *rhs, uint32_t columns, double *x,
                                  mim_error_t *err)
{
    if (!s || !rhs || !x)
        return mim_error_set(err, MIM_EINVAL, "transfer: NULL solver or array");
    if (columns < 1 || columns > 3)
        return mim_error_set(err, MIM_EINVAL, "transfer: %u right-hand sides (1..3)", columns);
    const size_t count = (size_t)columns * s->nf;
    memcpy(s->B->x, rhs, count * sizeof(double));
    cholmod_dense all = *s->B;
    s->B->ncol = columns, s->B->nzmax = count; /* a view of the first columns */
    int rc = plain_solve(s, err);
    *s->B = all;
    if (!rc)
        memcpy(x, s->X->x, count * sizeof(double));
    return rc;
}

int mim_xfer_solver_solve(mim_xfer_solver_t *s, const double *rhs, double *x, mim_error_t *err)
{
    return mim_xfer_solver_solve_columns(s, rhs, 3, x, err);
}

void mim_xfer_solver_stats(const mim_xfer_solver_t *s, mim_xfer_solver_stats_t *st)
{
    memset(st, 0, sizeof *st);
    if (!s)
        return;
    st->n_free = s->nf;
    st->n_constrained = s->nc;
    st->analyses = s->analyses;
    st->factorizations = s->factorizations;
    st->solves = s->solves;
    st->t_analyze = s->t_analyze;
    st->t_factorize = s->t_factorize;
    if (s->L && s->L->is_super == 0 && s->L->nz) {
        const int *nz = s->L->nz;
        double sum = 0;
        for (size_t j = 0; j < s->L->n; j++)
            sum += nz[j];
        st->factor_nnz = sum;
    } else if (s->L && s->L->is_super) {
        st->factor_nnz = (double)s->L->xsize;
    }
}
