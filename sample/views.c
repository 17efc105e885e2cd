/* Camera views relative to a pose-pair (seed 002, Section 4.2, eqs. 3-5):
 * the pair's local frame from its two backbones, a view direction as the
 * two angles of eq. 4, and the kernel density of eq. 5 over the views of
 * a set of annotations.
 *
 * Choices: the backbone of a person runs from the pelvis to the chest (the
 * paper's hip and chest joints), its root is the pelvis. eq. 3's i and j
 * need not be orthogonal; mimic makes j orthogonal to i (Gram-Schmidt) so
 * that (i, j, k) is a rotation and a view can be turned back into a world
 * direction. psi is measured with atan2 (the full circle; eq. 4's
 * arctan(c / a) cannot tell a from -a), and the kernel of eq. 5 wraps psi
 * around the circle (the Gaussian's images at +-2 pi are added). */
#include "mim_sample.h"

#include <math.h>

enum { PELVIS = 2, CHEST = 1 };

int mim_pairs_local_frame(const double *joints, double R[9])
{
    const double *pa = joints + 3 * PELVIS, *pb = joints + 3 * (MIM_PAIR_PERSON_JOINTS + PELVIS);
    const double *ca = joints + 3 * CHEST, *cb = joints + 3 * (MIM_PAIR_PERSON_JOINTS + CHEST);
    mim_vec3 i = mim_v3(pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]);
    mim_vec3 b1 = mim_v3_normalize(mim_v3(ca[0] - pa[0], ca[1] - pa[1], ca[2] - pa[2]));
    mim_vec3 b2 = mim_v3_normalize(mim_v3(cb[0] - pb[0], cb[1] - pb[1], cb[2] - pb[2]));
    if (mim_v3_norm(i) < 1e-9 || mim_v3_norm(b1) == 0 || mim_v3_norm(b2) == 0) return MIM_EINVAL;
    i = mim_v3_normalize(i);
    mim_vec3 j = mim_v3_add(b1, b2);
    j = mim_v3_sub(j, mim_v3_scale(i, mim_v3_dot(i, j))); /* orthogonal to i */
    if (mim_v3_norm(j) < 1e-9) return MIM_EINVAL;         /* the backbones lie along the line between the roots */
    j = mim_v3_normalize(j);
    mim_vec3 k = mim_v3_cross(i, j);
    /* columns i, j, k: local to world */
    R[0] = i.x, R[1] = i.y, R[2] = i.z, R[3] = j.x, R[4] = j.y, R[5] = j.z, R[6] = k.x, R[7] = k.y, R[8] = k.z;
    return 0;
}

void mim_pairs_view_angles(const double R[9], const double dir[3], double *psi, double *phi)
{
    /* (a, b, c): the direction in the local frame, R^T dir */
    double a = R[0] * dir[0] + R[1] * dir[1] + R[2] * dir[2];
    double b = R[3] * dir[0] + R[4] * dir[1] + R[5] * dir[2];
    double c = R[6] * dir[0] + R[7] * dir[1] + R[8] * dir[2];
    double n = sqrt(a * a + b * b + c * c);
    *psi = atan2(c, a);
    *phi = n > 0 ? acos(fmax(-1.0, fmin(1.0, b / n))) : 0.0;
}

void mim_pairs_view_direction(const double R[9], double psi, double phi, double dir[3])
{
    double a = sin(phi) * cos(psi), b = cos(phi), c = sin(phi) * sin(psi);
    for (int r = 0; r < 3; r++) dir[r] = R[r] * a + R[3 + r] * b + R[6 + r] * c;
}

static double wrap_gauss(double d, double sigma)
{
    double s = 0;
    for (int k = -1; k <= 1; k++) {
        double x = d + 2 * M_PI * k;
        s += exp(-x * x / (2 * sigma * sigma));
    }
    return s;
}

double mim_pairs_view_density(const double *views, uint32_t n, double sigma, double psi, double phi)
{
    if (!n || !(sigma > 0)) return 0.0;
    double s = 0;
    for (uint32_t i = 0; i < n; i++) {
        double dphi = phi - views[2 * i + 1];
        s += wrap_gauss(psi - views[2 * i], sigma) * exp(-dphi * dphi / (2 * sigma * sigma));
    }
    return s / (n * 2 * M_PI * sigma * sigma);
}

void mim_pairs_view_draw(const double *views, uint32_t n, double sigma, mim_rng_t *rng, double *psi, double *phi)
{
    /* eq. 5's sampling: an annotation's view at random, then its kernel */
    uint32_t i = (uint32_t)mim_rng_below(rng, n);
    double p = views[2 * i] + sigma * mim_rng_gauss(rng), f = views[2 * i + 1] + sigma * mim_rng_gauss(rng);
    p = fmod(p + M_PI, 2 * M_PI);
    if (p < 0) p += 2 * M_PI;
    *psi = p - M_PI;
    /* phi lives in [0, pi]: reflect at the poles */
    while (f < 0 || f > M_PI) f = f < 0 ? -f : 2 * M_PI - f;
    *phi = f;
}
