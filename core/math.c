/* Small vector, quaternion and rotation-matrix math (Hamilton convention,
 * unit quaternions); slerp and quaternion-to-matrix are inline in mim_core.h. */
#include "mim_core.h"

#include <math.h>

double mim_v3_norm(mim_vec3 a) { return sqrt(mim_v3_dot(a, a)); }

mim_vec3 mim_v3_normalize(mim_vec3 a)
{
    double n = mim_v3_norm(a);
    return n > 0 ? mim_v3_scale(a, 1.0 / n) : a;
}

mim_quat mim_quat_identity(void)
{
    mim_quat q = {0, 0, 0, 1};
    return q;
}

mim_quat mim_quat_axis_angle(mim_vec3 axis, double radians)
{
    mim_vec3 a = mim_v3_normalize(axis);
    double s = sin(radians * 0.5);
    mim_quat q = {a.x * s, a.y * s, a.z * s, cos(radians * 0.5)};
    return q;
}

mim_quat mim_quat_between(mim_vec3 a, mim_vec3 b)
{
    a = mim_v3_normalize(a), b = mim_v3_normalize(b);
    double d = mim_v3_dot(a, b);
    if (mim_v3_dot(a, a) == 0 || mim_v3_dot(b, b) == 0)
        return mim_quat_identity();
    if (d < -1 + 1e-12) { /* opposite: half a turn about any axis normal to a */
        mim_vec3 n = mim_v3_cross(a, fabs(a.x) < 0.9 ? mim_v3(1, 0, 0) : mim_v3(0, 1, 0));
        return mim_quat_axis_angle(n, M_PI);
    }
    /* (1 + d, a x b) normalised is the half-angle quaternion of the arc */
    mim_vec3 c = mim_v3_cross(a, b);
    mim_quat q = {c.x, c.y, c.z, 1 + d};
    return mim_quat_normalize(q);
}

mim_quat mim_quat_mul(mim_quat a, mim_quat b)
{
    mim_quat r = {
        a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
        a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
        a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
    };
    return r;
}

mim_quat mim_quat_normalize(mim_quat q)
{
    double n = sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    if (n <= 0) return mim_quat_identity();
    mim_quat r = {q.x / n, q.y / n, q.z / n, q.w / n};
    return r;
}

mim_vec3 mim_quat_rotate(mim_quat q, mim_vec3 v)
{
    /* v' = v + 2w (u x v) + 2 u x (u x v), u = vector part */
    mim_vec3 u = {q.x, q.y, q.z};
    mim_vec3 t = mim_v3_scale(mim_v3_cross(u, v), 2.0);
    return mim_v3_add(mim_v3_add(v, mim_v3_scale(t, q.w)), mim_v3_cross(u, t));
}

mim_quat mim_quat_from_matrix(const double m[9])
{
    /* mRC = row R, column C = m[3C + R] */
    double m00 = m[0], m11 = m[4], m22 = m[8];
    double m01 = m[3], m10 = m[1], m02 = m[6], m20 = m[2], m12 = m[7], m21 = m[5];
    double tr = m00 + m11 + m22;
    mim_quat q;
    if (tr > 0.0) {
        double s = 2.0 * sqrt(1.0 + tr);
        q.w = 0.25 * s, q.x = (m21 - m12) / s, q.y = (m02 - m20) / s, q.z = (m10 - m01) / s;
    } else if (m00 > m11 && m00 > m22) {
        double s = 2.0 * sqrt(1.0 + m00 - m11 - m22);
        q.w = (m21 - m12) / s, q.x = 0.25 * s, q.y = (m01 + m10) / s, q.z = (m02 + m20) / s;
    } else if (m11 > m22) {
        double s = 2.0 * sqrt(1.0 + m11 - m00 - m22);
        q.w = (m02 - m20) / s, q.x = (m01 + m10) / s, q.y = 0.25 * s, q.z = (m12 + m21) / s;
    } else {
        double s = 2.0 * sqrt(1.0 + m22 - m00 - m11);
        q.w = (m10 - m01) / s, q.x = (m02 + m20) / s, q.y = (m12 + m21) / s, q.z = 0.25 * s;
    }
    /* a matrix that is only nearly orthonormal gives a nearly unit q */
    double inv = 1.0 / sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    q.x *= inv, q.y *= inv, q.z *= inv, q.w *= inv;
    return q;
}

/* The eigenvector of the largest eigenvalue of a symmetric 4 x 4 matrix A
 * (overwritten), by cyclic Jacobi rotations: each zeroes one off-diagonal
 * entry, and the sweeps converge quadratically, to the rounding of the
 * entries, with no library call. */
static void top_eigenvector4(double A[4][4], double q[4])
{
    double V[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    for (int sweep = 0; sweep < 32; sweep++) {
        double off = 0, diag = 0;
        for (int p = 0; p < 4; p++) {
            diag += A[p][p] * A[p][p];
            for (int r = p + 1; r < 4; r++) off += A[p][r] * A[p][r];
        }
        if (!(off > 1e-36 * diag)) break; /* also ends on NaN */
        for (int p = 0; p < 3; p++)
            for (int r = p + 1; r < 4; r++) {
                const double apr = A[p][r];
                if (apr == 0) continue;
                /* J^T A J with J = [c s; -s c] in the (p, r) plane zeroes A[p][r]
                 * when t = s / c solves t^2 + 2 theta t - 1 = 0 (the smaller root) */
                const double theta = (A[r][r] - A[p][p]) / (2 * apr);
                const double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1));
                const double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 4; k++) {
                    if (k == p || k == r) continue;
                    const double akp = A[k][p], akr = A[k][r];
                    A[k][p] = A[p][k] = c * akp - s * akr;
                    A[k][r] = A[r][k] = s * akp + c * akr;
                }
                A[p][p] -= t * apr, A[r][r] += t * apr, A[p][r] = A[r][p] = 0;
                for (int k = 0; k < 4; k++) {
                    const double vkp = V[k][p], vkr = V[k][r];
                    V[k][p] = c * vkp - s * vkr, V[k][r] = s * vkp + c * vkr;
                }
            }
    }
    int top = 0;
    for (int p = 1; p < 4; p++)
        if (A[p][p] > A[top][top]) top = p;
    for (int k = 0; k < 4; k++) q[k] = V[k][top];
}

/* The same eigenvector the fast way (Theobald's QCP): Horn's matrix is
 * symmetric and traceless, so its eigenvalues are the roots of
 * l^4 - (|A|^2 / 2) l^2 - (tr A^3 / 3) l + det A, all real. Newton's method
 * from above the largest (at most sqrt(3/4) |A|, as the others sum to
 * minus it) falls onto it monotonically, where the quartic is convex; the
 * eigenvector is then the largest column of the adjugate of A - l I.
 * Returns 0 (Jacobi's rotations then decide) when the steps do not settle
 * or the largest root is close to the next, where that column is made of
 * cancelling terms. */
static double det3(double a, double b, double c, double d, double e, double f, double g, double h, double i)
{
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
}

/* The determinant of B without row x and column y. */
static double minor3(const double B[4][4], int x, int y)
{
    static const int rest[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    const int *r = rest[x], *c = rest[y];
    return det3(B[r[0]][c[0]], B[r[0]][c[1]], B[r[0]][c[2]], B[r[1]][c[0]], B[r[1]][c[1]], B[r[1]][c[2]], B[r[2]][c[0]],
                B[r[2]][c[1]], B[r[2]][c[2]]);
}

static int top_eigenvector4_qcp(const double A[4][4], double q[4])
{
    double f2 = 0, t3 = 0, A2[4][4];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) {
            f2 += A[r][c] * A[r][c];
            A2[r][c] = A[r][0] * A[0][c] + A[r][1] * A[1][c] + A[r][2] * A[2][c] + A[r][3] * A[3][c];
        }
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) t3 += A2[r][c] * A[c][r];
    if (!(f2 > 0) || !isfinite(f2)) return 0;
    const double det = A[0][0] * det3(A[1][1], A[1][2], A[1][3], A[2][1], A[2][2], A[2][3], A[3][1], A[3][2], A[3][3]) -
                       A[0][1] * det3(A[1][0], A[1][2], A[1][3], A[2][0], A[2][2], A[2][3], A[3][0], A[3][2], A[3][3]) +
                       A[0][2] * det3(A[1][0], A[1][1], A[1][3], A[2][0], A[2][1], A[2][3], A[3][0], A[3][1], A[3][3]) -
                       A[0][3] * det3(A[1][0], A[1][1], A[1][2], A[2][0], A[2][1], A[2][2], A[3][0], A[3][1], A[3][2]);
    const double c2 = -0.5 * f2, c1 = -t3 / 3, scale = sqrt(f2);
    double l = sqrt(0.75 * f2);
    int settled = 0;
    for (int it = 0; it < 64 && !settled; it++) {
        const double p = ((l * l + c2) * l + c1) * l + det, dp = (4 * l * l + 2 * c2) * l + c1;
        if (!(dp > 0)) break;
        const double step = p / dp;
        l -= step;
        settled = !(fabs(step) > 1e-15 * scale);
    }
    if (!settled) return 0;
    /* adj(A - l I) = (product of the gaps) v v^T: its largest column is
     * the one of its largest diagonal entry */
    double B[4][4], diag[4];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) B[r][c] = A[r][c] - (r == c ? l : 0);
    int col = 0;
    for (int c = 0; c < 4; c++) {
        diag[c] = minor3(B, c, c);
        if (fabs(diag[c]) > fabs(diag[col])) col = c;
    }
    double best = 0;
    for (int r = 0; r < 4; r++) {
        q[r] = r == col ? diag[col] : ((r + col) % 2 ? -1 : 1) * minor3(B, col, r);
        best += q[r] * q[r];
    }
    /* the column is the product of the three gaps to the other roots
     * times a component of the eigenvector (the largest at least 1/2):
     * below 1e-4 of the scale cubed, its digits cancel (each entry is off
     * by some rounding of the scale cubed) */
    return best > 1e-8 * scale * scale * scale * scale * scale * scale;
}

mim_quat mim_quat_best_rotation(const double M[3][3])
{
    double N[4][4] = {
        {M[0][0] + M[1][1] + M[2][2], M[1][2] - M[2][1], M[2][0] - M[0][2], M[0][1] - M[1][0]},
        {M[1][2] - M[2][1], M[0][0] - M[1][1] - M[2][2], M[0][1] + M[1][0], M[2][0] + M[0][2]},
        {M[2][0] - M[0][2], M[0][1] + M[1][0], -M[0][0] + M[1][1] - M[2][2], M[1][2] + M[2][1]},
        {M[0][1] - M[1][0], M[2][0] + M[0][2], M[1][2] + M[2][1], -M[0][0] - M[1][1] + M[2][2]},
    };
    double q[4];
    if (!top_eigenvector4_qcp(N, q)) top_eigenvector4(N, q);
    const double n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (!(n2 > 0) || !isfinite(n2)) return mim_quat_identity();
    return mim_quat_normalize((mim_quat){q[1], q[2], q[3], q[0]});
}
