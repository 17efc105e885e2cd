/* The camera view of a 2D pose-pair annotation (seed 002, Section 4.2):
 * each person's backbone and root in camera coordinates from its 2D
 * torso, then the pair's local frame of eq. 3 and the camera's forward
 * axis (0, 0, 1) as eq. 4's angles, exactly as mim_pairs_local_frame and
 * mim_pairs_view_angles treat a 3D pair and a camera.
 *
 * Choices (the paper lifts each person's "extended torso" with Akhter and
 * Black's pose-conditioned prior, [10]):
 * - The torso varies little between poses, so mimic fits ONE rigid mean
 *   torso per person (learned from 3D pose-pairs) by scaled-orthographic
 *   Procrustes: min over s, R of sum |x_i - s [R X_i]_xy|^2 over the 8
 *   centred torso points, R model to camera (x right, y down, z forward,
 *   as mim_pairs_camera_t). Start: the similarity (Umeyama) between the
 *   model and the pixels at depth 0; then Levenberg-Marquardt on (R, s).
 *   A flat-ish torso has two minima mirrored in depth (the Necker
 *   ambiguity): a second start from the first fit's depths negated, and
 *   the lower error wins (choosing the higher raises the median error
 *   from 9 to 15 degrees). The affine fit followed by the nearest scaled
 *   rotation would need the model's 3 x 3 scatter inverted, ill-posed for
 *   a flat torso; the similarity start needs nothing of the kind.
 * - The backbone is the model's, R (chest - pelvis); the observed 2D
 *   backbone in its place, or turning each fit by the ray to the person
 *   (paraperspective), changed the error by under 0.2 degrees.
 * - Roots: x, y from the pelvis pixels over the two people's mean scale;
 *   depth f / s per person (s in pixels per metre), f = 0.75 x the image
 *   width: a 67 degree horizontal field of view, a phone's main camera
 *   (about 26 mm equivalent) and the middle of annotate.c's cameras. The depth
 *   difference is where nearly all the error comes from (people of other
 *   sizes than the mean torso look nearer or farther; f scales it): with
 *   the true depth difference the median error falls from ~10 to ~2
 *   degrees; f = the width gives ~2.5 degrees more than 0.75 width on
 *   annotate.c's cameras.
 * - Measured (2 px of noise, annotate.c's cameras): median 9.5 degrees,
 *   95th percentile 39, on synthetic pairs (tests/test_pairs_views.c);
 *   the best constant view: 76.
 * - A person's frame when learning: x from r_hip to l_hip; when the hips
 *   sit within 3 cm of each other (skeletons whose hip joints are the
 *   pelvis) the shoulders' line instead. */
#include "mim_sample.h"

#include <lapacke.h>
#include <math.h>
#include <string.h>

enum { CHEST = 1, PELVIS = 2, L_SHOULDER = 3, R_SHOULDER = 4, L_HIP = 9, R_HIP = 10, SPINE = 15, NECK = 16 };
enum { NT = MIM_PAIRS_TORSO_POINTS, T_PELVIS = 0, T_CHEST = 4 };
static const int torso_joint[NT] = {PELVIS, L_HIP, R_HIP, SPINE, CHEST, NECK, L_SHOULDER, R_SHOULDER};

static mim_vec3 joint(const double *p, int j) { return mim_v3(p[3 * j], p[3 * j + 1], p[3 * j + 2]); }

/* rows x, y, z of a person's frame (person's 17 joints, world); -1 when degenerate */
static int person_frame(const double *p, mim_vec3 axis[3])
{
    mim_vec3 x = mim_v3_sub(joint(p, L_HIP), joint(p, R_HIP));
    if (!(mim_v3_norm(x) >= 0.03)) x = mim_v3_sub(joint(p, L_SHOULDER), joint(p, R_SHOULDER));
    mim_vec3 y = mim_v3_sub(joint(p, CHEST), joint(p, PELVIS));
    if (!(mim_v3_norm(x) > 1e-6) || !(mim_v3_norm(y) > 1e-6)) return -1;
    x = mim_v3_normalize(x);
    y = mim_v3_sub(y, mim_v3_scale(x, mim_v3_dot(x, y)));
    if (!(mim_v3_norm(y) > 1e-6)) return -1;
    axis[0] = x, axis[1] = mim_v3_normalize(y), axis[2] = mim_v3_cross(axis[0], axis[1]);
    return 0;
}

int mim_pairs_torso_learn(const double *pairs, uint32_t n, mim_pairs_torso_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    uint32_t used = 0;
    for (uint32_t k = 0; k < 2 * (uint64_t)n; k++) {
        const double *p = pairs + (size_t)k * 3 * MIM_PAIR_PERSON_JOINTS;
        mim_vec3 axis[3];
        if (person_frame(p, axis)) continue;
        mim_vec3 o = joint(p, PELVIS);
        int finite = 1;
        double q[NT][3];
        for (int t = 0; t < NT; t++) {
            mim_vec3 d = mim_v3_sub(joint(p, torso_joint[t]), o);
            for (int c = 0; c < 3; c++) finite &= isfinite(q[t][c] = mim_v3_dot(axis[c], d));
        }
        if (!finite) continue;
        for (int t = 0; t < NT; t++)
            for (int c = 0; c < 3; c++) out->point[t][c] += q[t][c];
        used++;
    }
    if (!used) return mim_error_set(err, MIM_EINVAL, "torso: no person with a usable frame among %u pose-pairs", n);
    for (int t = 0; t < NT; t++)
        for (int c = 0; c < 3; c++) out->point[t][c] /= used;
    return 0;
}

static double det3(const double *m)
{
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[3] * (m[1] * m[8] - m[2] * m[7]) + m[6] * (m[1] * m[5] - m[2] * m[4]);
}

/* The similarity Y_i ~ s R X_i (Umeyama 1991) of centred points; R row-major. */
static int similarity(const double X[NT][3], const double Y[NT][3], double var_x, double R[9], double *s)
{
    double H[9] = {0}, U[9], Vt[9], S[3], superb[2]; /* column-major H = sum Y X^T = U S V^T */
    for (int i = 0; i < NT; i++)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) H[3 * c + r] += Y[i][r] * X[i][c];
    if (LAPACKE_dgesvd(LAPACK_COL_MAJOR, 'A', 'A', 3, 3, H, 3, S, U, 3, Vt, 3, superb) != 0) return -1;
    double d = det3(U) * det3(Vt) < 0 ? -1.0 : 1.0; /* a rotation, not a reflection */
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            R[3 * r + c] = U[r] * Vt[3 * c] + U[3 + r] * Vt[3 * c + 1] + d * U[6 + r] * Vt[3 * c + 2];
    *s = (S[0] + S[1] + d * S[2]) / var_x;
    return 0;
}

typedef struct fit {
    double R[9], s, err; /* model to camera: x_i ~ s [R X_i]_xy */
} fit_t;

static double residual(const double X[NT][3], const double Y[NT][3], const double R[9], double s, double q[NT][3])
{
    double e = 0;
    for (int i = 0; i < NT; i++) {
        for (int r = 0; r < 3; r++) q[i][r] = R[3 * r] * X[i][0] + R[3 * r + 1] * X[i][1] + R[3 * r + 2] * X[i][2];
        e += (Y[i][0] - s * q[i][0]) * (Y[i][0] - s * q[i][0]) + (Y[i][1] - s * q[i][1]) * (Y[i][1] - s * q[i][1]);
    }
    return e;
}

/* Levenberg-Marquardt on sum |y_i - s [R X_i]_xy|^2 from the similarity to Y (pixels, and depths that
 * pick the start): R <- exp([w]x) R, s <- s (1 + sigma), the 4 x 4 normal equations by LAPACKE. */
static void refine(const double X[NT][3], const double Y[NT][3], double var_x, fit_t *f)
{
    f->err = INFINITY;
    if (similarity(X, Y, var_x, f->R, &f->s)) return;
    double q[NT][3], lambda = 1e-3;
    f->err = residual(X, Y, f->R, f->s, q);
    for (int it = 0; it < 100 && lambda < 1e6; it++) {
        double A[16] = {0}, g[4] = {0};
        for (int i = 0; i < NT; i++) {
            const double s = f->s, *v = q[i];
            /* d(s [q + w x q]_xy, s (1 + sigma) q_xy) / d(w, sigma) */
            double J[2][4] = {{0, s * v[2], -s * v[1], s * v[0]}, {-s * v[2], 0, s * v[0], s * v[1]}};
            double r[2] = {Y[i][0] - s * v[0], Y[i][1] - s * v[1]};
            for (int k = 0; k < 2; k++)
                for (int a = 0; a < 4; a++) {
                    g[a] += J[k][a] * r[k];
                    for (int b = 0; b < 4; b++) A[4 * a + b] += J[k][a] * J[k][b];
                }
        }
        for (int a = 0; a < 4; a++) A[5 * a] *= 1 + lambda;
        if (LAPACKE_dposv(LAPACK_COL_MAJOR, 'U', 4, 1, A, 4, g, 4) != 0) break;
        double w = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]), Rn[9], dR[9]; /* dR column-major */
        mim_quat_to_matrix(w > 0 ? mim_quat_axis_angle(mim_v3(g[0] / w, g[1] / w, g[2] / w), w) : mim_quat_identity(), dR);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) Rn[3 * r + c] = dR[r] * f->R[c] + dR[3 + r] * f->R[3 + c] + dR[6 + r] * f->R[6 + c];
        double sn = f->s * (1 + g[3]), qn[NT][3], e = residual(X, Y, Rn, sn, qn);
        if (!(e < f->err)) {
            lambda *= 10;
            continue;
        }
        int done = f->err - e < 1e-10 * f->err;
        memcpy(f->R, Rn, sizeof Rn), memcpy(q, qn, sizeof q), f->s = sn, f->err = e, lambda *= 0.1;
        if (done) break;
    }
}

/* One person's torso fit (uv: its 17 joints' pixels). */
static int fit_person(const mim_pairs_torso_t *torso, const double *uv, fit_t *best)
{
    double X[NT][3], Y[NT][3], mx[3] = {0}, c[2] = {0, 0}, var_x = 0, var_y = 0;
    for (int t = 0; t < NT; t++) {
        for (int k = 0; k < 2; k++) c[k] += uv[2 * torso_joint[t] + k] / NT;
        for (int k = 0; k < 3; k++) mx[k] += torso->point[t][k] / NT;
    }
    for (int t = 0; t < NT; t++) {
        for (int k = 0; k < 3; k++) X[t][k] = torso->point[t][k] - mx[k], var_x += X[t][k] * X[t][k];
        for (int k = 0; k < 2; k++) Y[t][k] = uv[2 * torso_joint[t] + k] - c[k], var_y += Y[t][k] * Y[t][k];
        Y[t][2] = 0;
    }
    if (!isfinite(var_y) || !(var_y > 1e-6) || !(var_x > 1e-9) || !isfinite(var_x)) return -1;
    refine(X, Y, var_x, best);
    if (!isfinite(best->err)) return -1;
    /* the fit mirrored in depth: the other local minimum of a flat-ish torso */
    fit_t other;
    const double *R = best->R;
    for (int t = 0; t < NT; t++) Y[t][2] = -best->s * (R[6] * X[t][0] + R[7] * X[t][1] + R[8] * X[t][2]);
    refine(X, Y, var_x, &other);
    if (other.err < best->err) *best = other;
    return best->s > 0 ? 0 : -1;
}

int mim_pairs_annotation_view(const mim_pairs_torso_t *torso, const double *uv, uint32_t width, uint32_t height,
                              double *psi, double *phi)
{
    (void)height; /* the principal point cancels in the root difference */
    if (!width) return MIM_EINVAL;
    fit_t f[2];
    mim_vec3 back[2];
    for (int p = 0; p < 2; p++) {
        if (fit_person(torso, uv + 2 * p * MIM_PAIR_PERSON_JOINTS, &f[p])) return MIM_EINVAL;
        double b[3];
        for (int k = 0; k < 3; k++) b[k] = torso->point[T_CHEST][k] - torso->point[T_PELVIS][k];
        const double *R = f[p].R;
        back[p] = mim_v3_normalize(mim_v3(R[0] * b[0] + R[1] * b[1] + R[2] * b[2], R[3] * b[0] + R[4] * b[1] + R[5] * b[2],
                                          R[6] * b[0] + R[7] * b[1] + R[8] * b[2]));
    }
    /* r_B - r_A in camera coordinates: depth f / s of each person (scaled orthography) */
    const double focal = 0.75 * width, s_mean = 0.5 * (f[0].s + f[1].s);
    const double *pa = uv + 2 * PELVIS, *pb = uv + 2 * (MIM_PAIR_PERSON_JOINTS + PELVIS);
    mim_vec3 i = mim_v3((pb[0] - pa[0]) / s_mean, (pb[1] - pa[1]) / s_mean, focal / f[1].s - focal / f[0].s);
    if (!(mim_v3_norm(i) > 1e-9)) return MIM_EINVAL;
    /* eq. 3 as mim_pairs_local_frame does it: j made orthogonal to i, k = i x j */
    i = mim_v3_normalize(i);
    mim_vec3 j = mim_v3_add(back[0], back[1]);
    j = mim_v3_sub(j, mim_v3_scale(i, mim_v3_dot(i, j)));
    if (!(mim_v3_norm(j) > 1e-9)) return MIM_EINVAL;
    j = mim_v3_normalize(j);
    mim_vec3 k = mim_v3_cross(i, j);
    const double L[9] = {i.x, i.y, i.z, j.x, j.y, j.z, k.x, k.y, k.z}, forward[3] = {0, 0, 1};
    mim_pairs_view_angles(L, forward, psi, phi);
    return 0;
}
