/* Completion of lost landmarks by retrieval (seed 002, Section 6,
 * "Occluded Joint Inference"): the templates nearest to the landmarks
 * still seen, their robust centre, and that centre blended onto the seen
 * landmarks. mimic's version works on one person's landmarks over the
 * store's templates (the paper: pose-pairs over its samples, in D_I).
 *
 * Choices: templates are compared after the similarity that best maps
 * their seen landmarks onto the frame's (so any place, heading and size
 * match), by the RMS distance over the seen landmarks; the k nearest
 * (K, the paper's subset of 100 scaled down to a store of
 * bodies: the default measured with bench/complete.c) give, per landmark
 * and coordinate, the median of their aligned positions; a lost landmark
 * is that median plus the Gaussian-weighted mean of the seen landmarks'
 * residuals (frame - median), weighted by the median pose's distance
 * between the lost landmark and each seen one (sigma): the nearer a seen
 * landmark, the more its offset carries over.
 *
 * Issue 29: that answer is mixed with the index's pose classes' (each
 * class's Gaussian's conditional mean given the seen landmarks,
 * mim_index_complete), their share MIM_COMPLETE_DEFAULT_GAUSSIAN: 0.85x
 * the error of retrieval alone on the imitation set, 0.88x on mh-bodies
 * (bench/RESULTS.md).
 *
 * A lost limb end (wrist, ankle) whose parent and grandparent are seen
 * turns with its parent bone (turn_ends): the classes' Gaussians are linear
 * in the coordinates and their shared covariance averages over every pose,
 * so a seen elbow the person turned their own way carries the wrist only in
 * part. The classes' answer for the frame without the parent predicts
 * the parent bone as the seen landmarks imply it (a body's proportions);
 * what the seen parent bone turned beyond that, the rotation taking the
 * predicted bone onto the seen one, turns the predicted end's bone too:
 * 0.93x the error on the imitation set, the same on mh-bodies
 * (bench/RESULTS.md).
 *
 * Where the store holds a template that matches the seen landmarks closely
 * (the nearest one's RMS over them well under MIM_COMPLETE_LOCAL_GATE_M),
 * its neighbourhood is a model of this body: the MIM_COMPLETE_LOCAL_K
 * nearest, aligned, as a Gaussian (their mean and scatter, ridge
 * MIM_COMPLETE_LOCAL_RIDGE of the mean variance) give the conditional mean
 * of the lost coordinates (local_answer), weighted in by
 * exp(-d^2 / 2 gate^2). A person who takes the pose their own way is far
 * from every template and keeps the answer above (bench/RESULTS.md: the
 * imitation set unchanged, mh-bodies 0.86x, synth 0.58x). */
#include "internal.h"
#include "mim_register.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int cmp_f(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

/* The rotation taking the unit vector a onto the unit vector b about
 * their common normal (Rodrigues); a = -b: none. */
static void turn_between(const double a[3], const double b[3], double R[3][3])
{
    const double v[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    const double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2], f = c > -1 + 1e-9 ? 1 / (1 + c) : 0;
    const double K[3][3] = {{0, -v[2], v[1]}, {v[2], 0, -v[0]}, {-v[1], v[0], 0}};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double k2 = 0;
            for (int q = 0; q < 3; q++) k2 += K[i][q] * K[q][j];
            R[i][j] = (i == j) + (f > 0 ? K[i][j] + f * k2 : 0);
        }
}

/* cond (the classes' answer, all L) with each lost limb end whose parent
 * and grandparent are seen turned with its parent bone (the comment at
 * the top). Ends the map does not name are left as they are. */
static void turn_ends(const mim_index_t *ix, const mim_landmark_map_t *map, const float *positions,
                      const uint8_t *present, float *cond)
{
    static const char *const chain[][3] = {{"l_wrist", "l_elbow", "l_shoulder"}, {"r_wrist", "r_elbow", "r_shoulder"},
                                           {"l_ankle", "l_knee", "l_hip"},       {"r_ankle", "r_knee", "r_hip"}};
    enum { CHAINS = sizeof chain / sizeof *chain };
    const uint32_t L = map->count;
    uint8_t without[MIM_LANDMARKS_MAX];
    memcpy(without, present, L);
    for (int c = 0; c < CHAINS; c++) {
        int end[3];
        for (int j = 0; j < 3; j++) end[j] = mim_landmarks_find(map, chain[c][j]);
        if (end[0] < 0 || end[1] < 0 || end[2] < 0 || present[end[0]] || !present[end[1]] || !present[end[2]]) continue;
        /* the parent predicted from the other seen landmarks (one chain at a time: the rest as seen) */
        float t[3 * MIM_LANDMARKS_MAX];
        without[end[1]] = 0;
        int rc = mim_index_complete(ix, positions, without, t, NULL, NULL);
        without[end[1]] = 1;
        if (rc) continue;
        const uint32_t l = (uint32_t)end[0], p = (uint32_t)end[1], g = (uint32_t)end[2];
        double a[3], b[3], d[3], na = 0, nb = 0; /* predicted parent bone, seen parent bone, predicted end bone */
        for (int k = 0; k < 3; k++) {
            a[k] = t[3 * p + k] - positions[3 * g + k], b[k] = positions[3 * p + k] - positions[3 * g + k];
            d[k] = t[3 * l + k] - t[3 * p + k], na += a[k] * a[k], nb += b[k] * b[k];
        }
        na = sqrt(na), nb = sqrt(nb);
        if (!(na > 1e-9) || !(nb > 1e-9)) continue;
        for (int k = 0; k < 3; k++) a[k] /= na, b[k] /= nb;
        double R[3][3];
        turn_between(a, b, R);
        for (int i = 0; i < 3; i++) {
            double v = 0;
            for (int k = 0; k < 3; k++) v += R[i][k] * d[k];
            cond[3 * l + i] += (float)((v - d[i]) * nb / na);
        }
    }
}

/* The lost coordinates' conditional mean under the Gaussian of the nk
 * aligned neighbours (nk * 3L floats): mu_m + C_ms (C_ss + rho I)^-1 (x_s -
 * mu_s), C their scatter / (nk - 1) = c D D^T, rho the ridge times C's mean
 * variance; through the push-through identity only an nk x nk system is
 * solved: C_ms (C_ss + rho I)^-1 r = c D_m (c D_s^T D_s + rho I)^-1 D_s^T r.
 * out gets the lost landmarks; -1 when the system is singular. */
static int local_answer(const float *aligned, uint32_t nk, uint32_t L, const float *positions, const uint8_t *present,
                        double *out)
{
    enum { KMAX = MIM_COMPLETE_LOCAL_K };
    const uint32_t n = 3 * L;
    double mu[3 * MIM_LANDMARKS_MAX] = {0}, G[KMAX][KMAX + 1] = {{0}}, ss = 0;
    const double c = 1.0 / (nk - 1);
    for (uint32_t b = 0; b < nk; b++)
        for (uint32_t i = 0; i < n; i++) mu[i] += aligned[(size_t)b * n + i] / nk;
#define DEV(b, i) (aligned[(size_t)(b) * n + (i)] - mu[i])
    for (uint32_t b = 0; b < nk; b++)
        for (uint32_t i = 0; i < n; i++) ss += DEV(b, i) * DEV(b, i);
    const double rho = MIM_COMPLETE_LOCAL_RIDGE * c * ss / n;
    if (!(rho > 0)) return -1; /* the neighbours all one shape */
    for (uint32_t a = 0; a < nk; a++) { /* [c D_s^T D_s + rho I | D_s^T r] */
        for (uint32_t b = 0; b < nk; b++) {
            double v = 0;
            for (uint32_t i = 0; i < n; i++) v += present[i / 3] ? DEV(a, i) * DEV(b, i) : 0;
            G[a][b] = c * v + (a == b ? rho : 0);
        }
        double h = 0;
        for (uint32_t i = 0; i < n; i++) h += present[i / 3] ? DEV(a, i) * (positions[i] - mu[i]) : 0;
        G[a][nk] = h;
    }
    for (uint32_t a = 0; a < nk; a++) { /* symmetric positive definite: no pivoting */
        if (!(G[a][a] > 0)) return -1;
        for (uint32_t r = a + 1; r < nk; r++) {
            const double f = G[r][a] / G[a][a];
            for (uint32_t q = a; q <= nk; q++) G[r][q] -= f * G[a][q];
        }
    }
    double y[KMAX];
    for (uint32_t a = nk; a-- > 0;) {
        double v = G[a][nk];
        for (uint32_t q = a + 1; q < nk; q++) v -= G[a][q] * y[q];
        y[a] = v / G[a][a];
    }
    for (uint32_t i = 0; i < n; i++) {
        if (present[i / 3]) continue;
        double v = mu[i];
        for (uint32_t b = 0; b < nk; b++) v += c * DEV(b, i) * y[b];
        out[i] = v;
    }
#undef DEV
    return 0;
}

int mim_session_complete(mim_session_t *s, const float *positions, const uint8_t *present,
                         const mim_session_complete_options_t *opt, float *out, uint8_t *completed, mim_error_t *err)
{
    mim_session_complete_options_t o = opt ? *opt : (mim_session_complete_options_t){0};
    const uint32_t K = o.k ? (o.k < MIM_COMPLETE_MAX_K ? o.k : MIM_COMPLETE_MAX_K) : MIM_COMPLETE_DEFAULT_K;
    const double sigma = o.sigma > 0 ? o.sigma : MIM_COMPLETE_DEFAULT_SIGMA_M;
    const char *exclude_subject = o.exclude_subject;
    const mim_landmark_map_t *map = mim_session_map(s);
    const uint32_t L = map->count;
    uint32_t seen = 0;
    for (uint32_t l = 0; l < L; l++) seen += present[l] != 0;
    memcpy(out, positions, 3 * (size_t)L * sizeof *out);
    memset(completed, 0, L);
    if (seen == L) return 0;
    if (seen < MIM_COMPLETE_MIN_SEEN)
        return mim_error_set(err, MIM_EINVAL, "completion: %u landmarks seen, at least %d needed", seen,
                             MIM_COMPLETE_MIN_SEEN);
    /* the pose classes' conditional answer, when there is an index to give it */
    const double g = o.gaussian < 0 ? 0 : o.gaussian > 1 ? 1 : o.gaussian > 0 ? o.gaussian : MIM_COMPLETE_DEFAULT_GAUSSIAN;
    const mim_index_t *ix = o.index ? o.index : s->query ? mim_query_index(s->query) : NULL;
    float cond[3 * MIM_LANDMARKS_MAX];
    int have_cond = 0;
    if (g > 0 && ix) {
        mim_index_info_t info;
        mim_index_get_info(ix, &info);
        have_cond = info.n_landmarks == L && !mim_index_complete(ix, positions, present, cond, NULL, NULL);
        if (have_cond && !o.no_turn) turn_ends(ix, map, positions, present, cond);
    }
    const int alone = have_cond && g >= 1; /* the classes alone: the templates serve the local Gaussian only */
    if (alone) {
        for (uint32_t l = 0; l < L; l++)
            if (!present[l]) memcpy(out + 3 * l, cond + 3 * l, 3 * sizeof *out), completed[l] = 1;
        if (o.no_local) return 0;
    }
    const float *table;
    char *const *subjects;
    uint32_t n;
    int rc = mim__session_landmark_table(s, &table, &subjects, NULL, &n, alone ? NULL : err);
    if (rc) return alone ? 0 : rc;
    /* the seen landmarks, packed */
    float obs[3 * MIM_LANDMARKS_MAX], tl[3 * MIM_LANDMARKS_MAX], moved[3 * MIM_LANDMARKS_MAX];
    uint32_t idx[MIM_LANDMARKS_MAX], m = 0;
    for (uint32_t l = 0; l < L; l++)
        if (present[l]) idx[m] = l, memcpy(obs + 3 * m, positions + 3 * l, 3 * sizeof *obs), m++;
    /* the k nearest templates after their best similarity onto the seen landmarks */
    const uint32_t KS = K > MIM_COMPLETE_LOCAL_K ? K : MIM_COMPLETE_LOCAL_K; /* the median's and the local Gaussian's */
    uint32_t best[MIM_COMPLETE_MAX_K];
    double best_d[MIM_COMPLETE_MAX_K];
    uint32_t nb = 0;
    for (uint32_t t = 0; t < n; t++) {
        if (exclude_subject && subjects[t] && !strcmp(subjects[t], exclude_subject)) continue;
        const float *T = table + (size_t)t * L * 3;
        for (uint32_t k = 0; k < m; k++) memcpy(tl + 3 * k, T + 3 * idx[k], 3 * sizeof *tl);
        mim_reg_similarity_t sim;
        if (mim_reg_similarity_fit(tl, obs, m, &sim, NULL)) continue;
        mim_reg_similarity_apply(&sim, tl, m, moved);
        double d = 0;
        for (uint32_t k = 0; k < 3 * m; k++) d += (moved[k] - obs[k]) * (moved[k] - obs[k]);
        if (nb < KS || d < best_d[nb - 1]) {
            uint32_t at = nb < KS ? nb++ : nb - 1;
            while (at > 0 && best_d[at - 1] > d) best[at] = best[at - 1], best_d[at] = best_d[at - 1], at--;
            best[at] = t, best_d[at] = d;
        }
    }
    if (!nb && alone) return 0;
    if (!nb) return mim_error_set(err, MIM_ENOTFOUND, "completion: no template to complete from%s%s",
                                  exclude_subject ? " outside subject " : "", exclude_subject ? exclude_subject : "");
    /* each neighbour whole, aligned by its seen landmarks; the per-coordinate median */
    float *aligned = malloc((size_t)nb * L * 3 * sizeof *aligned), med[3 * MIM_LANDMARKS_MAX], col[MIM_COMPLETE_MAX_K];
    if (!aligned) return mim_error_set(err, MIM_ENOMEM, "completion: out of memory");
    for (uint32_t b = 0; b < nb; b++) {
        const float *T = table + (size_t)best[b] * L * 3;
        for (uint32_t k = 0; k < m; k++) memcpy(tl + 3 * k, T + 3 * idx[k], 3 * sizeof *tl);
        mim_reg_similarity_t sim;
        mim_reg_similarity_fit(tl, obs, m, &sim, NULL);
        mim_reg_similarity_apply(&sim, T, L, aligned + (size_t)b * L * 3);
    }
    const uint32_t nm = nb < K ? nb : K;
    for (uint32_t k = 0; k < 3 * L; k++) {
        for (uint32_t b = 0; b < nm; b++) col[b] = aligned[(size_t)b * L * 3 + k];
        qsort(col, nm, sizeof *col, cmp_f);
        med[k] = nm % 2 ? col[nm / 2] : 0.5f * (col[nm / 2 - 1] + col[nm / 2]);
    }
    /* the local Gaussian, weighted by how near the nearest template is */
    double loc[3 * MIM_LANDMARKS_MAX] = {0}, wl = 0;
    if (!o.no_local && nb >= MIM_COMPLETE_LOCAL_K &&
        !local_answer(aligned, MIM_COMPLETE_LOCAL_K, L, positions, present, loc)) {
        const double d = sqrt(best_d[0] / m) / MIM_COMPLETE_LOCAL_GATE_M;
        wl = exp(-0.5 * d * d);
    }
    free(aligned);
    /* the lost ones: the median plus the nearby seen landmarks' residuals */
    for (uint32_t l = 0; l < L; l++) {
        if (present[l]) continue;
        double wsum = 0, r[3] = {0, 0, 0};
        for (uint32_t k = 0; k < m; k++) {
            const float *mo = med + 3 * idx[k], *ml = med + 3 * l;
            double d2 = (mo[0] - ml[0]) * (mo[0] - ml[0]) + (mo[1] - ml[1]) * (mo[1] - ml[1]) + (mo[2] - ml[2]) * (mo[2] - ml[2]);
            double w = exp(-d2 / (2 * sigma * sigma));
            for (int c = 0; c < 3; c++) r[c] += w * (obs[3 * k + c] - mo[c]);
            wsum += w;
        }
        for (int c = 0; c < 3; c++) {
            double v = med[3 * l + c] + (wsum > 0 && !o.no_blend ? r[c] / wsum : 0.0);
            v = alone ? cond[3 * l + c] : have_cond ? (1 - g) * v + g * cond[3 * l + c] : v;
            out[3 * l + c] = (float)(wl > 0 ? (1 - wl) * v + wl * loc[3 * l + c] : v);
        }
        completed[l] = 1;
    }
    return 0;
}
