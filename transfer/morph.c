/* Morphing between key poses (seed 000, Section 3.5). The paper
 * interpolates vertex positions linearly between two key poses; where a
 * limb rotates, the straight-line paths cut the arc and the limb shrinks
 * (the paper's Fig. 14). mimic's alternative interpolates what the
 * encoding is made of instead: each vertex's local frame (quaternion
 * slerp between the key poses' frames), its encoding W (lerp between the
 * key poses' own W = F^T L X, which differ little when both keys are the
 * same avatar) and the landmark positions (lerp), and solves once with the
 * cached factor. At t = 0 and 1 the right-hand side is exactly L X of the
 * key, so the keys come back unchanged; in between, offsets turn with
 * their frames instead of shortening along chords. */
#include "internal.h"

#include <math.h>
#include <string.h>

/* Rotation matrix with columns f1 f2 f3 -> unit quaternion (x y z w),
 * Shepperd's method: branch on the largest diagonal term for accuracy. */
static void matrix_to_quat(const double *f, double *q)
{
    /* m[r][c] = component r of column c = f[3c + r] */
    double m00 = f[0], m11 = f[4], m22 = f[8];
    double m01 = f[3], m10 = f[1], m02 = f[6], m20 = f[2], m12 = f[7], m21 = f[5];
    double tr = m00 + m11 + m22, x, y, z, w;
    if (tr > 0.0) {
        double s = 2.0 * sqrt(1.0 + tr);
        w = 0.25 * s, x = (m21 - m12) / s, y = (m02 - m20) / s, z = (m10 - m01) / s;
    } else if (m00 > m11 && m00 > m22) {
        double s = 2.0 * sqrt(1.0 + m00 - m11 - m22);
        w = (m21 - m12) / s, x = 0.25 * s, y = (m01 + m10) / s, z = (m02 + m20) / s;
    } else if (m11 > m22) {
        double s = 2.0 * sqrt(1.0 + m11 - m00 - m22);
        w = (m02 - m20) / s, x = (m01 + m10) / s, y = 0.25 * s, z = (m12 + m21) / s;
    } else {
        double s = 2.0 * sqrt(1.0 + m22 - m00 - m11);
        w = (m10 - m01) / s, x = (m02 + m20) / s, y = (m12 + m21) / s, z = 0.25 * s;
    }
    double inv = 1.0 / sqrt(x * x + y * y + z * z + w * w);
    q[0] = x * inv, q[1] = y * inv, q[2] = z * inv, q[3] = w * inv;
}

static void quat_to_matrix(const double *q, double *f)
{
    double x = q[0], y = q[1], z = q[2], w = q[3];
    f[0] = 1 - 2 * (y * y + z * z), f[1] = 2 * (x * y + z * w), f[2] = 2 * (x * z - y * w);
    f[3] = 2 * (x * y - z * w), f[4] = 1 - 2 * (x * x + z * z), f[5] = 2 * (y * z + x * w);
    f[6] = 2 * (x * z + y * w), f[7] = 2 * (y * z - x * w), f[8] = 1 - 2 * (x * x + y * y);
}

void mim_xfer_frames_to_quats(uint32_t n_vertices, const double *frames, double *quats)
{
    for (size_t i = 0; i < n_vertices; i++)
        matrix_to_quat(frames + 9 * i, quats + 4 * i);
}

/* slerp along the shorter arc; nlerp when the two are nearly equal */
static void slerp(const double *a, const double *b, double t, double *out)
{
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3], sb = 1.0;
    if (d < 0.0)
        d = -d, sb = -1.0;
    double wa, wb;
    if (d > 0.9995) {
        wa = 1.0 - t, wb = t;
    } else {
        double th = acos(d), s = sin(th);
        wa = sin((1.0 - t) * th) / s, wb = sin(t * th) / s;
    }
    wb *= sb;
    double q[4], len = 0.0;
    for (int k = 0; k < 4; k++) {
        q[k] = wa * a[k] + wb * b[k];
        len += q[k] * q[k];
    }
    len = 1.0 / sqrt(len);
    for (int k = 0; k < 4; k++)
        out[k] = q[k] * len;
}

int mim_xfer_morph(mim_xfer_solver_t *s, mim_xfer_morph_method_t method, const mim_xfer_key_t *a,
                   const mim_xfer_key_t *b, double t, float *out, mim_error_t *err)
{
    if (!s || !a || !b || !a->positions || !b->positions || !out)
        return mim_error_set(err, MIM_EINVAL, "morph: NULL solver, key poses or output");
    if (!(t >= 0.0 && t <= 1.0))
        return mim_error_set(err, MIM_EINVAL, "morph: t = %g outside [0, 1]", t);
    const uint32_t n = s->n;
    if (method == MIM_XFER_MORPH_LINEAR) {
        for (size_t i = 0; i < 3 * (size_t)n; i++)
            out[i] = (float)((1.0 - t) * a->positions[i] + t * b->positions[i]);
        return 0;
    }
    if (method != MIM_XFER_MORPH_FRAMES)
        return mim_error_set(err, MIM_EINVAL, "morph: unknown method %d", (int)method);
    if (!a->quats || !b->quats || !a->W || !b->W || !a->landmarks || !b->landmarks)
        return mim_error_set(err, MIM_EINVAL, "morph: the frames method needs each key's frames, W and landmarks");
    if (s->nc > MIM_LANDMARKS_MAX)
        return mim_error_set(err, MIM_EINVAL, "morph: %u constrained vertices, at most %d", s->nc,
                             MIM_LANDMARKS_MAX);
    float u[3 * MIM_LANDMARKS_MAX];
    for (size_t k = 0; k < 3 * (size_t)s->nc; k++)
        u[k] = (float)((1.0 - t) * a->landmarks[k] + t * b->landmarks[k]);
    for (size_t i = 0; i < n; i++) {
        double q[4];
        slerp(a->quats + 4 * i, b->quats + 4 * i, t, q);
        quat_to_matrix(q, s->mframes + 9 * i);
    }
    for (size_t i = 0; i < 3 * (size_t)n; i++)
        s->mW[i] = (1.0 - t) * a->W[i] + t * b->W[i];
    /* one solve: the frames are given, not iterated */
    mim_xfer_options_t o = {.max_iterations = 1, .tol = -1.0, .no_early_stop = 1};
    return mim_xfer_transfer(s, s->mW, n, s->mframes, u, s->nc, &o, out, NULL, err);
}
