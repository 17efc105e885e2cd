/* 2D pose-pairs as the likelihood compares them (seed 002 eq. 9): an
 * annotation in pixels and a projection in metres meet after both are
 * centred and scaled to unit RMS radius; M of eq. 9 is then the 2D
 * rotation of least squares (closed form: the angle of the summed cross
 * and dot products), and the shape density's shape contexts are taken in
 * that common frame. */
#include "internal.h"

#include <math.h>
#include <string.h>

#define N MIM_PAIR_JOINTS

void mim_pairs2d_project(const double *joints, const double dir[3], double *uv)
{
    int a = fabs(dir[0]) < fabs(dir[1]) ? (fabs(dir[0]) < fabs(dir[2]) ? 0 : 2) : (fabs(dir[1]) < fabs(dir[2]) ? 1 : 2);
    double x[3] = {0, 0, 0};
    x[a] = 1;
    double d = x[0] * dir[0] + x[1] * dir[1] + x[2] * dir[2], n = 0;
    for (int c = 0; c < 3; c++) x[c] -= d * dir[c], n += x[c] * x[c];
    n = sqrt(n);
    for (int c = 0; c < 3; c++) x[c] /= n;
    double y[3] = {dir[1] * x[2] - dir[2] * x[1], dir[2] * x[0] - dir[0] * x[2], dir[0] * x[1] - dir[1] * x[0]};
    for (int i = 0; i < N; i++) {
        const double *p = joints + 3 * i;
        uv[2 * i] = x[0] * p[0] + x[1] * p[1] + x[2] * p[2];
        uv[2 * i + 1] = y[0] * p[0] + y[1] * p[1] + y[2] * p[2];
    }
}

double mim_pairs2d_normalise(const double *in, double *out)
{
    double cx = 0, cy = 0;
    for (int i = 0; i < N; i++) cx += in[2 * i], cy += in[2 * i + 1];
    cx /= N, cy /= N;
    double r2 = 0;
    for (int i = 0; i < N; i++) {
        out[2 * i] = in[2 * i] - cx, out[2 * i + 1] = in[2 * i + 1] - cy;
        r2 += out[2 * i] * out[2 * i] + out[2 * i + 1] * out[2 * i + 1];
    }
    double r = sqrt(r2 / N);
    if (!(r > 1e-12) || !isfinite(r)) return 0;
    for (int i = 0; i < 2 * N; i++) out[i] /= r;
    return r;
}

double mim_pairs2d_align(const double *a, const double *b, double *c, double *s)
{
    double dot = 0, cross = 0;
    for (int i = 0; i < N; i++) {
        dot += a[2 * i] * b[2 * i] + a[2 * i + 1] * b[2 * i + 1];
        cross += a[2 * i + 1] * b[2 * i] - a[2 * i] * b[2 * i + 1];
    }
    double h = hypot(dot, cross);
    *c = h > 0 ? dot / h : 1.0, *s = h > 0 ? cross / h : 0.0;
    /* |a|^2 = |b|^2 = N (unit RMS radius): |a - R b|^2 = 2N - 2h */
    return fmax(0.0, (2.0 * N - 2.0 * h) / N);
}

void mim_pairs2d_rotate(const double *b, double c, double s, double *out)
{
    for (int i = 0; i < N; i++) {
        double x = b[2 * i], y = b[2 * i + 1];
        out[2 * i] = c * x - s * y, out[2 * i + 1] = s * x + c * y;
    }
}

void mim__pairs2d_shape_contexts(const double *p, float sc[N][MIM__SC2_BINS])
{
    double mean = 0;
    for (int i = 0; i < N; i++)
        for (int j = i + 1; j < N; j++) mean += hypot(p[2 * j] - p[2 * i], p[2 * j + 1] - p[2 * i + 1]);
    mean /= N * (N - 1) / 2.0;
    if (!(mean > 0)) mean = 1.0;
    const double r0 = log(mean / 8.0), r1 = log(mean * 2.0);
    const float w = 1.0f / (N - 1);
    memset(sc, 0, sizeof(float) * N * MIM__SC2_BINS);
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            if (j == i) continue;
            double dx = p[2 * j] - p[2 * i], dy = p[2 * j + 1] - p[2 * i + 1], r = hypot(dx, dy);
            /* bin coordinates with bin centres at integers; radius clamped
             * to the outer bins, angle wrapping around */
            double fr = r > 0 ? (log(r) - r0) / (r1 - r0) * MIM__SC2_R - 0.5 : 0.0;
            double fa = (atan2(dy, dx) + M_PI) / (2 * M_PI) * MIM__SC2_A - 0.5;
            fr = fmin(fmax(fr, 0.0), MIM__SC2_R - 1.0);
            int r_lo = (int)floor(fr), a_lo = (int)floor(fa);
            double tr = fr - r_lo, ta = fa - a_lo;
            for (int dr = 0; dr < 2; dr++) {
                int rb = r_lo + dr;
                if (rb >= MIM__SC2_R) continue;
                for (int da = 0; da < 2; da++) {
                    int ab = ((a_lo + da) % MIM__SC2_A + MIM__SC2_A) % MIM__SC2_A;
                    double k = (dr ? tr : 1 - tr) * (da ? ta : 1 - ta);
                    sc[i][rb * MIM__SC2_A + ab] += (float)(w * k);
                }
            }
        }
}
