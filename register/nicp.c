/* Non-rigid ICP with decreasing stiffness (Amberg, Romdhani and Vetter
 * 2007, "Optimal step nonrigid ICP algorithms for surface registration").
 *
 * Amberg's unknowns are an affine transform per vertex with a stiffness
 * term on the differences across edges. mimic's unknowns are the vertex
 * positions X themselves, and the stiffness is on the shape's Laplacian
 * offsets in its own local frames, the intrinsic encoding of seed 000
 * (Section 3.1): W0 = F(X0)^T L X0 of the initial shape X0 (the nearest
 * template already transferred into the target's landmarks). Each step
 * asks L X to equal F(X) W0 with the frames F of the current shape, so the
 * term turns with the surface: a part may rotate as a whole (a foot
 * pointed where the template's is flexed) at the cost of its joint only,
 * and the initial shape's details, with its correspondence (which vertex
 * is the left wrist), ride along while the surface closes onto the
 * target. One step, for stiffness alpha and landmark weight beta:
 *
 *   E(X) = sum_i w_i |x_i - c_i|^2 + alpha |L X - F W0|^2 + beta sum_l |x_l - u_l|^2
 *
 * w_i: 1, and MIM_REG_DEFAULT_EXTREMITY_WEIGHT at the hands and feet,
 * whose closest points lie on the wrong finger or the wrong surface more
 * often than not (mim_register.h says what was measured).
 * c_i: the closest point on the target's surface to x_i, moved along the
 * surface's normal towards the target vertices whose nearest shape vertex
 * is i (the other direction, in the stiffer half of the stages), or their
 * mean when the closest point is rejected; a vertex whose matches are all
 * rejected (on the target's boundary, normals too far apart, too far
 * away) gets its own position (held, where Amberg sets its weight to 0:
 * so the matrix below is the same at every step of a stage). L: the
 * uniform Laplacian (symmetric); u_l: the target's landmarks. The minimum
 * solves
 *
 *   (D + alpha L^T L + beta P) X = D C + alpha L^T F W0 + beta P U,   D = diag(w),
 *
 * three right-hand sides with one sparse SPD matrix. Its pattern is that
 * of L^T L (two rings) and never changes: CHOLMOD analyses it once per
 * context and factorises it numerically once per stage. As Amberg does,
 * each stage iterates closest points and solves until the largest move is
 * below 0.1 mm (or the step cap); then alpha and beta decrease
 * geometrically to the last stage's, and so do the rejection radius (from
 * 4x max_distance) and angle (from 90 degrees to max_angle_deg). Defaults
 * (mim_register.h) measured with bench/register.c and with the 96
 * mh-bodies registered onto a synth store (bench/RESULTS.md). */
#include "internal.h"

#include <cholmod.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct mim__reg_nicp {
    const mim_xfer_topology_t *topo;
    uint32_t n;
    cholmod_common cc;
    cholmod_sparse *LtL; /* upper triangle, sorted */
    cholmod_sparse *A;   /* same pattern: alpha L^T L + diagonal */
    int32_t *diag;       /* n: position of (i, i) in A->x */
    cholmod_factor *F;
    cholmod_dense *B, *X, *Y, *E;
    double *frames, *W0, *delta, *ltd; /* the initial shape's encoding; F W0 now; L^T of that */
    float *xf;
    mim__reg_hit_t *hits;
};

#define MOVE_TOL 1e-4 /* metres: a stage has converged when no vertex moves more */
#define MIM__REG_REACH 4.0
#define MIM__REG_BACKWARD_UNTIL 0.5 /* stage fraction */

void mim__reg_nicp_close(mim__reg_nicp_t **pp)
{
    if (!pp || !*pp) return;
    mim__reg_nicp_t *p = *pp;
    cholmod_free_sparse(&p->LtL, &p->cc);
    cholmod_free_sparse(&p->A, &p->cc);
    cholmod_free_factor(&p->F, &p->cc);
    cholmod_free_dense(&p->B, &p->cc);
    cholmod_free_dense(&p->X, &p->cc);
    cholmod_free_dense(&p->Y, &p->cc);
    cholmod_free_dense(&p->E, &p->cc);
    cholmod_finish(&p->cc);
    free(p->diag), free(p->frames), free(p->W0), free(p->delta), free(p->ltd), free(p->xf), free(p->hits);
    free(p);
    *pp = NULL;
}

/* L (uniform, n x n, unsymmetric storage) from the one-rings. */
static cholmod_sparse *laplacian(mim__reg_nicp_t *p)
{
    size_t nnz = 0;
    for (uint32_t v = 0; v < p->n; v++) {
        uint32_t deg;
        mim_xfer_neighbors(p->topo, v, &deg);
        nnz += deg + 1;
    }
    cholmod_sparse *L = cholmod_allocate_sparse(p->n, p->n, nnz, 1, 1, 0, CHOLMOD_REAL, &p->cc);
    if (!L) return NULL;
    int *Lp = L->p, *Li = L->i;
    double *Lx = L->x;
    size_t w = 0;
    for (uint32_t v = 0; v < p->n; v++) {
        uint32_t deg;
        const uint32_t *nb = mim_xfer_neighbors(p->topo, v, &deg);
        Lp[v] = (int)w;
        int placed = 0;
        for (uint32_t k = 0; k <= deg; k++) { /* neighbours are sorted: put the diagonal in order */
            if (!placed && (k == deg || nb[k] > v)) {
                Li[w] = (int)v, Lx[w++] = (double)deg, placed = 1;
            }
            if (k < deg) Li[w] = (int)nb[k], Lx[w++] = -1.0;
        }
    }
    Lp[p->n] = (int)w;
    return L;
}

int mim__reg_nicp_open(mim__reg_nicp_t **out, const mim_xfer_topology_t *topo, mim_error_t *err)
{
    *out = NULL;
    mim__reg_nicp_t *p = calloc(1, sizeof *p);
    if (!p) return mim_error_set(err, MIM_ENOMEM, "registration: out of memory");
    p->topo = topo;
    p->n = mim_xfer_topology_n_vertices(topo);
    cholmod_start(&p->cc);
    p->cc.supernodal = CHOLMOD_SIMPLICIAL;
    p->cc.print = 0;
    p->cc.error_handler = NULL;
    cholmod_sparse *L = laplacian(p);
    cholmod_sparse *S = L ? cholmod_aat(L, NULL, 0, 1, &p->cc) : NULL; /* L L^T = L^T L */
    p->LtL = S ? cholmod_copy(S, 1, 1, &p->cc) : NULL;
    cholmod_free_sparse(&S, &p->cc);
    cholmod_free_sparse(&L, &p->cc);
    if (p->LtL) cholmod_sort(p->LtL, &p->cc);
    p->A = p->LtL ? cholmod_copy_sparse(p->LtL, &p->cc) : NULL;
    size_t n = p->n;
    p->diag = malloc(n * sizeof *p->diag);
    p->frames = malloc(9 * n * sizeof *p->frames);
    p->W0 = malloc(3 * n * sizeof *p->W0);
    p->delta = malloc(3 * n * sizeof *p->delta);
    p->ltd = malloc(3 * n * sizeof *p->ltd);
    p->xf = malloc(3 * n * sizeof *p->xf);
    p->hits = malloc(n * sizeof *p->hits);
    p->B = cholmod_zeros(n, 3, CHOLMOD_REAL, &p->cc);
    if (!p->A || !p->diag || !p->frames || !p->W0 || !p->delta || !p->ltd || !p->xf || !p->hits || !p->B) {
        mim__reg_nicp_close(&p);
        return mim_error_set(err, MIM_ENOMEM, "registration: out of memory");
    }
    const int *Ap = p->A->p, *Ai = p->A->i;
    for (uint32_t j = 0; j < p->n; j++) {
        p->diag[j] = -1;
        for (int k = Ap[j]; k < Ap[j + 1]; k++)
            if ((uint32_t)Ai[k] == j) p->diag[j] = k;
        if (p->diag[j] < 0) {
            mim__reg_nicp_close(&p);
            return mim_error_set(err, MIM_EUNSUPPORTED, "registration: vertex %u has no diagonal entry", j);
        }
    }
    p->F = cholmod_analyze(p->A, &p->cc);
    if (!p->F) {
        mim__reg_nicp_close(&p);
        return mim_error_set(err, MIM_EUNSUPPORTED, "registration: CHOLMOD could not analyse the system");
    }
    *out = p;
    return 0;
}

static void vertex_normal(const double *frames, uint32_t i, double n[3])
{
    n[0] = frames[9 * i], n[1] = frames[9 * i + 1], n[2] = frames[9 * i + 2];
}

/* The other direction: each target vertex's nearest vertex of the current
 * shape (FLANN's single tree over it, rebuilt per step), kept under the
 * same distance and normal tests. A part of the target that sticks out
 * past every closest point of the shape (a pointed foot where the
 * template's is flexed) is then still pulled on. Sums per shape vertex. */
static int backward(mim__reg_nicp_t *p, const mim__reg_surface_t *surface, double d2_max, double cos_max,
                    double *sum, uint32_t *cnt, int *ind, float *dist, mim_error_t *err)
{
    uint32_t n = p->n;
    memset(sum, 0, (size_t)3 * n * sizeof *sum);
    memset(cnt, 0, (size_t)n * sizeof *cnt);
    struct FLANNParameters fp = surface->params;
    float speedup = 0.0f;
    flann_index_t ix = flann_build_index_float(p->xf, (int)n, 3, &speedup, &fp);
    if (!ix) return mim_error_set(err, MIM_EUNSUPPORTED, "registration: FLANN could not build a tree");
    int frc = flann_find_nearest_neighbors_index_float(ix, surface->pos, (int)surface->n, ind, dist, 1, &fp);
    flann_free_index_float(ix, &fp);
    if (frc) return mim_error_set(err, MIM_EUNSUPPORTED, "registration: FLANN search failed");
    for (uint32_t j = 0; j < surface->n; j++) {
        int i = ind[j];
        if (i < 0 || (uint32_t)i >= n || !(dist[j] <= d2_max) || surface->vertex_boundary[j]) continue;
        double tn[3] = {0, 0, 0}, nv[3];
        for (uint32_t k = surface->vf_start[j]; k < surface->vf_start[j + 1]; k++)
            for (int c = 0; c < 3; c++) tn[c] += surface->fnormal[3 * surface->vf[k] + c];
        double l = sqrt(tn[0] * tn[0] + tn[1] * tn[1] + tn[2] * tn[2]);
        vertex_normal(p->frames, (uint32_t)i, nv);
        if (!(l > 0) || (nv[0] * tn[0] + nv[1] * tn[1] + nv[2] * tn[2]) < cos_max * l) continue;
        for (int c = 0; c < 3; c++) sum[3 * i + c] += surface->pos[3 * j + c];
        cnt[i]++;
    }
    return 0;
}

int mim__reg_nicp_run(mim__reg_nicp_t *p, const mim_reg_options_t *opt, const mim__reg_surface_t *surface,
                      const uint32_t *lm_vertex, const float *lm_target, uint32_t count, const double *x0,
                      const double *data_w, double *x, uint32_t *iterations, double *rejected, mim_error_t *err)
{
    uint32_t n = p->n;
    *iterations = 0, *rejected = 0.0;
    int rc = 0;
    double *back_sum = malloc((size_t)3 * n * sizeof *back_sum);
    uint32_t *back_n = malloc((size_t)n * sizeof *back_n);
    int *bind = malloc((size_t)surface->n * sizeof *bind);
    float *bdist = malloc((size_t)surface->n * sizeof *bdist);
    if (!back_sum || !back_n || !bind || !bdist) {
        rc = mim_error_set(err, MIM_ENOMEM, "registration: out of memory");
        goto out;
    }
    for (size_t i = 0; i < (size_t)3 * n; i++)
        p->xf[i] = (float)x0[i];
    mim_xfer_frames(p->topo, p->xf, p->frames);
    mim_xfer_encode(p->topo, p->xf, p->frames, p->W0);
    memcpy(x, x0, (size_t)3 * n * sizeof *x);
    const double *ltl = p->LtL->x;
    double *ax = p->A->x;
    size_t nnz = ((const int *)p->A->p)[n];
    for (uint32_t stage = 0; stage < opt->stages; stage++) {
        double f = opt->stages > 1 ? (double)stage / (opt->stages - 1) : 1.0;
        double alpha = opt->stiffness_first * pow(opt->stiffness_last / opt->stiffness_first, f);
        double beta = opt->landmark_weight * alpha / opt->stiffness_first;
        /* The first, stiffest stages reach MIM__REG_REACH times farther:
         * where the landmarks of the target and of the store mean slightly
         * different places (an ankle on the bone or on the skin), a whole
         * part can start that far off, and only a stiff step can bring it
         * in without tearing. */
        double reach = opt->max_distance * pow(MIM__REG_REACH, 1.0 - f), d2_max = reach * reach;
        /* and accept normals further apart, so that a part turned the
         * other way (a foot pointed where the template's is flexed) is
         * still pulled on: from 90 degrees to max_angle_deg at the last. */
        double angle = 90.0 + (opt->max_angle_deg - 90.0) * f, cos_max = cos(angle * M_PI / 180.0);
        for (uint32_t it = 0; it < opt->iterations; it++) {
            for (size_t i = 0; i < (size_t)3 * n; i++)
                p->xf[i] = (float)x[i];
            mim_xfer_frames_d(p->topo, x, p->frames);
            /* The shape's Laplacian offsets in the current frames (seed 000,
             * Section 3.1): the smoothness term turns with the surface. */
            mim_xfer_decode(n, p->frames, p->W0, p->delta);
            mim_xfer_laplacian_apply(p->topo, p->delta, p->ltd);
            rc = mim__reg_surface_closest(surface, p->xf, n, p->hits, err);
            /* Target-to-shape matches only in the first, stiffer half of
             * the stages: they bring in parts that stick out, but they
             * also pull sideways, which the soft stages would turn into
             * sliding (bench/register.c). */
            if (f > MIM__REG_BACKWARD_UNTIL) memset(back_n, 0, (size_t)n * sizeof *back_n);
            else if (!rc) rc = backward(p, surface, d2_max, cos_max, back_sum, back_n, bind, bdist, err);
            if (rc) goto out;
            uint32_t kept = 0;
            double *b = p->B->x;
            for (uint32_t i = 0; i < n; i++) {
                const mim__reg_hit_t *h = p->hits + i;
                double nv[3];
                vertex_normal(p->frames, i, nv);
                const float *fnrm = surface->fnormal + 3 * h->face;
                int ok = h->d2 < INFINITY && !h->boundary && h->d2 <= d2_max &&
                         nv[0] * fnrm[0] + nv[1] * fnrm[1] + nv[2] * fnrm[2] >= cos_max;
                kept += ok;
                /* The data target: the closest point, moved halfway along
                 * the surface's normal towards the target vertices that
                 * have this vertex as theirs (across the surface only:
                 * their mean lies beside the vertex on a denser target,
                 * and a sideways pull would slide it); their mean itself
                 * when the closest point is rejected (a part turned away,
                 * bent back by its stiffness, bench/register.c). A vertex
                 * with neither is held where it is (its target is itself)
                 * instead of being let go (weight 0, as in Amberg): then
                 * the matrix is the same at every step of a stage and is
                 * factorised once per stage, not per step. */
                double dn = 0.0;
                if (ok && back_n[i])
                    for (int c = 0; c < 3; c++) dn += (back_sum[3 * i + c] / back_n[i] - h->point[c]) * fnrm[c];
                for (int c = 0; c < 3; c++) {
                    double t = ok ? h->point[c] + 0.5 * dn * fnrm[c] : x[3 * i + c];
                    if (back_n[i] && !ok) t = back_sum[3 * i + c] / back_n[i];
                    b[i + (size_t)c * n] = (data_w ? data_w[i] : 1.0) * t + alpha * p->ltd[3 * i + c];
                }
            }
            *rejected = 1.0 - (double)kept / n;
            for (uint32_t l = 0; l < count; l++) {
                uint32_t v = lm_vertex[l];
                for (int c = 0; c < 3; c++)
                    b[v + (size_t)c * n] += beta * lm_target[3 * l + c];
            }
            if (it == 0) {
                for (size_t k = 0; k < nnz; k++)
                    ax[k] = alpha * ltl[k];
                for (uint32_t i = 0; i < n; i++)
                    ax[p->diag[i]] += data_w ? data_w[i] : 1.0;
                for (uint32_t l = 0; l < count; l++)
                    ax[p->diag[lm_vertex[l]]] += beta;
                if (!cholmod_factorize(p->A, p->F, &p->cc) || p->cc.status != CHOLMOD_OK) {
                    rc = mim_error_set(err, MIM_EUNSUPPORTED, "registration: CHOLMOD factorisation failed (status %d)",
                                       p->cc.status);
                    goto out;
                }
            }
            if (!cholmod_solve2(CHOLMOD_A, p->F, p->B, NULL, &p->X, NULL, &p->Y, &p->E, &p->cc)) {
                rc = mim_error_set(err, MIM_EUNSUPPORTED, "registration: CHOLMOD solve failed");
                goto out;
            }
            const double *sol = p->X->x;
            double move = 0.0;
            for (uint32_t i = 0; i < n; i++) {
                double d2 = 0.0;
                for (int c = 0; c < 3; c++) {
                    double v = sol[i + (size_t)c * n];
                    d2 += (v - x[3 * i + c]) * (v - x[3 * i + c]);
                    x[3 * i + c] = v;
                }
                if (!(d2 <= move)) move = d2; /* a NaN counts */
            }
            ++*iterations;
            if (!isfinite(move)) {
                rc = mim_error_set(err, MIM_ENONFINITE, "registration: the solve diverged");
                goto out;
            }
            if (sqrt(move) < MOVE_TOL) break;
        }
    }
out:
    free(back_sum), free(back_n), free(bind), free(bdist);
    return rc;
}
