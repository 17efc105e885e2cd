/* Frames from several templates (issue 15). One template's frames carry
 * its subject's build and its small differences of pose; the k templates
 * nearest to the query, each first turned segment by segment so that its
 * landmark skeleton lies along the target's (the segment correction), then
 * averaged per vertex, carry less of either.
 *
 * Averaging: a vertex's frames are rotations; their weighted average is
 * the normalised weighted sum of their quaternions, each taken in the
 * hemisphere of the first (q and -q are one rotation). For rotations a
 * few tens of degrees apart, as the same pose's frames on other bodies
 * are, it is within a fraction of a degree of the geodesic mean and costs
 * one pass.
 *
 * Segment correction: each body segment's rotation from the template's
 * landmark skeleton to the target's. The pelvis and the chest are frames
 * of three landmarks (the hip or shoulder line, and the spine's
 * direction); every other segment takes its parent's rotation and then the
 * shortest arc from the parent-turned bone to the target's bone, so a
 * bone's twist, which landmarks cannot see, is the parent's. A hand and a
 * foot have no landmark beyond the wrist or the ankle: they take the
 * forearm's and the shin's.
 *
 * Relative transfer (deformation transfer): what a template's subject did
 * from its reference (itself in the avatar's rest pose) to the pose, done
 * to the avatar: its frames' turn P R^T on the avatar's rest frames, and
 * its encoding's change W_pose - W_ref added to the avatar's W. Unlike the
 * template's own frames this carries no foreign build, and the change of
 * W (folds at bent joints) is what one template cannot give at all: with
 * the avatar's rest W even its own true frames leave about 20 mm
 * (bench/blend_accuracy.c). */
#include "internal.h"

#include <math.h>
#include <string.h>

/* The weighted sum of one vertex's k quaternions (q[j]), each in the
 * hemisphere of the first that weighs, not normalised; w[j] == 0 skips. */
static inline mim_quat blend_sum(uint32_t k, const mim_quat *q, const double *w)
{
    mim_quat sum = {0, 0, 0, 0}, first = {0, 0, 0, 1};
    for (uint32_t j = 0; j < k; j++) {
        if (w[j] == 0)
            continue;
        if (sum.w == 0 && sum.x == 0 && sum.y == 0 && sum.z == 0)
            first = q[j];
        double s = q[j].x * first.x + q[j].y * first.y + q[j].z * first.z + q[j].w * first.w < 0 ? -w[j] : w[j];
        sum.x += s * q[j].x, sum.y += s * q[j].y, sum.z += s * q[j].z, sum.w += s * q[j].w;
    }
    return sum;
}

/* The weights as the blends take them into w; 0 when none weighs. */
static int blend_weights(uint32_t *k, const double *weights, double w[MIM_XFER_BLEND_MAX])
{
    double total = 0;
    *k = *k > MIM_XFER_BLEND_MAX ? MIM_XFER_BLEND_MAX : *k;
    for (uint32_t j = 0; j < *k; j++)
        total += w[j] = weights && weights[j] > 0 && isfinite(weights[j]) ? weights[j] : weights ? 0.0 : 1.0;
    return *k && total > 0;
}

void mim_xfer_frames_blend(uint32_t n_vertices, uint32_t k, const double *const *frames, const double *weights,
                           double *out)
{
    double w[MIM_XFER_BLEND_MAX];
    if (!blend_weights(&k, weights, w)) { /* nothing to weigh: the first (or nothing) */
        if (k && out != frames[0])
            memcpy(out, frames[0], 9 * (size_t)n_vertices * sizeof *out);
        return;
    }
    for (uint32_t i = 0; i < n_vertices; i++) {
        mim_quat q[MIM_XFER_BLEND_MAX];
        for (uint32_t j = 0; j < k; j++)
            if (w[j] != 0)
                q[j] = mim_quat_from_matrix(frames[j] + 9 * (size_t)i);
        mim_quat_to_matrix(mim_quat_normalize(blend_sum(k, q, w)), out + 9 * (size_t)i);
    }
}

void mim_xfer_offsets_blend(uint32_t n_vertices, uint32_t k, const double *const *quats, const double *weights,
                            const double *W, double *offsets)
{
    double w[MIM_XFER_BLEND_MAX];
    if (!blend_weights(&k, weights, w)) /* nothing to weigh: the first's frames */
        w[0] = 1.0, k = k ? 1 : 0;
    /* the templates that weigh, the first of them the hemisphere's (as
     * blend_sum takes it, but found once, not per vertex) */
    const double *q[MIM_XFER_BLEND_MAX];
    double wq[MIM_XFER_BLEND_MAX];
    uint32_t m = 0;
    for (uint32_t j = 0; j < k; j++)
        if (w[j] != 0)
            q[m] = quats[j], wq[m++] = w[j];
    for (uint32_t i = 0; i < n_vertices; i++) {
        const double *wi = W + 3 * (size_t)i;
        mim_vec3 v = mim_v3(wi[0], wi[1], wi[2]);
        if (m) {
            const double *f = q[0] + 4 * (size_t)i;
            mim_quat sum = {wq[0] * f[0], wq[0] * f[1], wq[0] * f[2], wq[0] * f[3]};
            for (uint32_t j = 1; j < m; j++) {
                const double *p = q[j] + 4 * (size_t)i;
                const double s = p[0] * f[0] + p[1] * f[1] + p[2] * f[2] + p[3] * f[3] < 0 ? -wq[j] : wq[j];
                sum.x += s * p[0], sum.y += s * p[1], sum.z += s * p[2], sum.w += s * p[3];
            }
            v = mim_quat_rotate_unnormalized(sum, v);
        }
        double *o = offsets + 3 * (size_t)i;
        o[0] = v.x, o[1] = v.y, o[2] = v.z;
    }
}

/* The segments as landmark geometry: a frame (pelvis, chest) of an axis
 * from -> to and an up direction up_from -> up_to; or a bone from -> to
 * turned after its parent; or a copy of the parent (hand, foot). */
typedef struct {
    int parent; /* segment index, -1: none */
    const char *from, *to, *up_from, *up_to;
} segment_t;

static const segment_t segments[MIM_SEGMENTS] = {
    /* pelvis */ {-1, "r_hip", "l_hip", "pelvis", "spine"},
    /* chest */ {-1, "r_shoulder", "l_shoulder", "spine", "chest"},
    /* head */ {1, "chest", "head", NULL, NULL},
    /* l_shoulder */ {1, "chest", "l_shoulder", NULL, NULL},
    /* r_shoulder */ {1, "chest", "r_shoulder", NULL, NULL},
    /* l_upperarm */ {3, "l_shoulder", "l_elbow", NULL, NULL},
    /* r_upperarm */ {4, "r_shoulder", "r_elbow", NULL, NULL},
    /* l_forearm */ {5, "l_elbow", "l_wrist", NULL, NULL},
    /* r_forearm */ {6, "r_elbow", "r_wrist", NULL, NULL},
    /* l_hand */ {7, NULL, NULL, NULL, NULL},
    /* r_hand */ {8, NULL, NULL, NULL, NULL},
    /* l_thigh */ {0, "l_hip", "l_knee", NULL, NULL},
    /* r_thigh */ {0, "r_hip", "r_knee", NULL, NULL},
    /* l_shin */ {11, "l_knee", "l_ankle", NULL, NULL},
    /* r_shin */ {12, "r_knee", "r_ankle", NULL, NULL},
    /* l_foot */ {13, NULL, NULL, NULL, NULL},
    /* r_foot */ {14, NULL, NULL, NULL, NULL},
};

static mim_vec3 at(const float *lm, int l) { return mim_v3(lm[3 * l], lm[3 * l + 1], lm[3 * l + 2]); }

/* The orthonormal frame (columns x, y, z) of axis a with up u. 0 when
 * they are parallel or zero. */
static int frame_of(mim_vec3 a, mim_vec3 u, double m[9])
{
    mim_vec3 x = mim_v3_normalize(a);
    mim_vec3 y = mim_v3_normalize(mim_v3_sub(u, mim_v3_scale(x, mim_v3_dot(u, x))));
    mim_vec3 z = mim_v3_cross(x, y);
    if (mim_v3_dot(x, x) == 0 || mim_v3_dot(y, y) == 0)
        return 0;
    const mim_vec3 c[3] = {x, y, z};
    for (int k = 0; k < 3; k++)
        m[3 * k] = c[k].x, m[3 * k + 1] = c[k].y, m[3 * k + 2] = c[k].z;
    return 1;
}

int mim_xfer_segment_correction(const mim_landmark_map_t *map, const float *from, const float *to,
                                mim_quat R[MIM_SEGMENTS], mim_error_t *err)
{
    int idx[MIM_SEGMENTS][4];
    for (int s = 0; s < MIM_SEGMENTS; s++) {
        const char *names[4] = {segments[s].from, segments[s].to, segments[s].up_from, segments[s].up_to};
        for (int k = 0; k < 4; k++)
            if ((idx[s][k] = names[k] ? mim_landmarks_find(map, names[k]) : -1) < 0 && names[k])
                return mim_error_set(err, MIM_EUNSUPPORTED, "transfer: segment correction needs landmark '%s'",
                                     names[k]);
    }
    for (uint32_t i = 0; i < 3 * map->count; i++)
        if (!isfinite(from[i]) || !isfinite(to[i]))
            return mim_error_set(err, MIM_ENONFINITE, "transfer: segment correction: landmark '%s' is not finite",
                                 map->names[i / 3]);
    for (int s = 0; s < MIM_SEGMENTS; s++) { /* parents come first */
        const int *l = idx[s];
        if (segments[s].up_from) {
            double a[9], b[9], ab[9];
            if (!frame_of(mim_v3_sub(at(from, l[1]), at(from, l[0])), mim_v3_sub(at(from, l[3]), at(from, l[2])), a) ||
                !frame_of(mim_v3_sub(at(to, l[1]), at(to, l[0])), mim_v3_sub(at(to, l[3]), at(to, l[2])), b)) {
                R[s] = mim_quat_identity(); /* a degenerate frame: no turn to take */
                continue;
            }
            for (int c = 0; c < 3; c++) /* b a^T, column-major */
                for (int r = 0; r < 3; r++)
                    ab[3 * c + r] = b[r] * a[c] + b[3 + r] * a[3 + c] + b[6 + r] * a[6 + c];
            R[s] = mim_quat_from_matrix(ab);
        } else if (segments[s].from) {
            mim_quat p = R[segments[s].parent];
            mim_vec3 d0 = mim_quat_rotate(p, mim_v3_sub(at(from, l[1]), at(from, l[0])));
            R[s] = mim_quat_normalize(mim_quat_mul(mim_quat_between(d0, mim_v3_sub(at(to, l[1]), at(to, l[0]))), p));
        } else {
            R[s] = R[segments[s].parent];
        }
    }
    return 0;
}

void mim_xfer_frames_relative(uint32_t n_vertices, const double *pose, const double *ref, const double *avatar_rest,
                              double *out)
{
    for (size_t i = 0; i < n_vertices; i++) {
        const double *P = pose + 9 * i, *R = ref + 9 * i, *A = avatar_rest + 9 * i;
        double C[9], o[9]; /* C = R^T A, o = P C; column-major, M[r][c] = M[3c + r] */
        for (int c = 0; c < 3; c++)
            for (int r = 0; r < 3; r++)
                C[3 * c + r] = R[3 * r] * A[3 * c] + R[3 * r + 1] * A[3 * c + 1] + R[3 * r + 2] * A[3 * c + 2];
        for (int c = 0; c < 3; c++)
            for (int r = 0; r < 3; r++)
                o[3 * c + r] = P[r] * C[3 * c] + P[3 + r] * C[3 * c + 1] + P[6 + r] * C[3 * c + 2];
        memcpy(out + 9 * i, o, sizeof o);
    }
}

void mim_xfer_encoding_relative(uint32_t n_vertices, uint32_t k, const double *const *W_pose,
                                const double *const *W_ref, const double *weights, const double *scale,
                                const double *W_avatar, double *out)
{
    double w[MIM_XFER_BLEND_MAX], total = 0;
    k = k > MIM_XFER_BLEND_MAX ? MIM_XFER_BLEND_MAX : k;
    for (uint32_t j = 0; j < k; j++)
        total += w[j] = weights && weights[j] > 0 && isfinite(weights[j]) ? weights[j] : weights ? 0.0 : 1.0;
    if (out != W_avatar)
        memcpy(out, W_avatar, 3 * (size_t)n_vertices * sizeof *out);
    if (!(total > 0))
        return;
    for (uint32_t j = 0; j < k; j++) {
        const double c = w[j] / total * (scale && isfinite(scale[j]) ? scale[j] : 1.0);
        if (c == 0)
            continue;
        const double *a = W_pose[j], *b = W_ref[j];
        for (size_t i = 0; i < 3 * (size_t)n_vertices; i++)
            out[i] += c * (a[i] - b[i]);
    }
}

double mim_xfer_encoding_scale(uint32_t n_vertices, const double *W_avatar, const double *W_ref)
{
    double a = 0, r = 0;
    for (size_t i = 0; i < 3 * (size_t)n_vertices; i++)
        a += W_avatar[i] * W_avatar[i], r += W_ref[i] * W_ref[i];
    if (!isfinite(a) || !isfinite(r) || !(r > 0))
        return NAN;
    return sqrt(a / r);
}

double mim_xfer_build_distance(const float *a, const float *b, uint32_t count)
{
    double sa = 0, sb = 0, d = 0;
    for (int pass = 0; pass < 2; pass++) /* the mean pair distances, then the normalised differences */
        for (uint32_t i = 0; i < count; i++)
            for (uint32_t j = i + 1; j < count; j++) {
                double da = 0, db = 0;
                for (int c = 0; c < 3; c++) {
                    const double xa = (double)a[3 * i + c] - a[3 * j + c], xb = (double)b[3 * i + c] - b[3 * j + c];
                    da += xa * xa, db += xb * xb;
                }
                da = sqrt(da), db = sqrt(db);
                if (!pass)
                    sa += da, sb += db;
                else
                    d += (da / sa - db / sb) * (da / sa - db / sb);
            }
    return sa > 0 && sb > 0 ? sqrt(d) : NAN;
}
