/* Segment skinning for the orientation drive (issue 17): which body
 * segments move each vertex, and the vertex frames of a pose given each
 * segment's rotation.
 *
 * Weights: every vertex starts on the bone (a segment pivot -> end) nearest
 * to it, then the one-hot weights diffuse over the surface, `smoothing`
 * steps of w_i <- (w_i + sum of the one-ring's w_j) / (1 + deg_i), so that
 * frames blend across a joint over a few rings instead of jumping. The
 * diffusion follows the mesh, not space: an arm by the body does not leak
 * into the hip. Around the shoulders, hips and spine the band is wider
 * (mim_xfer_skin_from_bones_wide): soft tissue there follows both
 * segments far from the joint. Each vertex keeps its MIM_XFER_SKIN_INFLUENCES largest
 * weights, normalised (as a glTF skin's JOINTS_0 / WEIGHTS_0).
 *
 * Frames: a vertex's rotation is the normalised weighted sum of its
 * segments' quaternions, each taken in the hemisphere of the heaviest one
 * (q and -q are one rotation), close to the rotation average for the
 * nearby rotations that meet at a joint; its rest frame turned by it is
 * the frame the solve asks for (seed 000 eq. 3: delta_i = R_i F_i W_i).
 * The solve needs only delta_i, so the orientation drive turns the rest
 * offset F_i W_i, kept per avatar, instead (mim_xfer_skin_offsets): a
 * vector turned by an unnormalised quaternion, where the frames cost a
 * normalisation, a matrix and a 3x3 product per vertex, and the solve's
 * right-hand side then read 9 doubles a vertex instead of 3. */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static double bone_distance2(const float *p, const double *bone)
{
    double ab[3], ap[3], l2 = 0, t = 0;
    for (int c = 0; c < 3; c++) {
        ab[c] = bone[3 + c] - bone[c], ap[c] = p[c] - bone[c];
        l2 += ab[c] * ab[c], t += ap[c] * ab[c];
    }
    t = l2 > 0 ? t / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double d2 = 0;
    for (int c = 0; c < 3; c++) {
        double d = ap[c] - t * ab[c];
        d2 += d * d;
    }
    return d2;
}

/* One diffusion step of the dense weights w into next. */
static void diffuse(const mim_xfer_topology_t *t, uint32_t n_bones, const float *w, float *next)
{
    for (uint32_t i = 0; i < t->n; i++) {
        float *o = next + (size_t)i * n_bones;
        memcpy(o, w + (size_t)i * n_bones, n_bones * sizeof *o);
        uint32_t deg = t->adj_start[i + 1] - t->adj_start[i];
        for (uint32_t k = t->adj_start[i]; k < t->adj_start[i + 1]; k++) {
            const float *nb = w + (size_t)t->adj[k] * n_bones;
            for (uint32_t b = 0; b < n_bones; b++) o[b] += nb[b];
        }
        for (uint32_t b = 0; b < n_bones; b++) o[b] /= (float)(1 + deg);
    }
}

int mim_xfer_skin_from_bones(const mim_xfer_topology_t *t, const float *positions, const double *bones,
                             uint32_t n_bones, uint32_t smoothing, mim_xfer_skin_t *skin, mim_error_t *err)
{
    return mim_xfer_skin_from_bones_wide(t, positions, bones, n_bones, smoothing, 0, 0, skin, err);
}

int mim_xfer_skin_from_bones_wide(const mim_xfer_topology_t *t, const float *positions, const double *bones,
                                  uint32_t n_bones, uint32_t smoothing, uint64_t wide_bones, uint32_t wide_smoothing,
                                  mim_xfer_skin_t *skin, mim_error_t *err)
{
    if (!t || !positions || !bones || !skin)
        return mim_error_set(err, MIM_EINVAL, "skin: NULL topology, positions, bones or output");
    if (!n_bones || n_bones > MIM_XFER_SKIN_MAX_BONES)
        return mim_error_set(err, MIM_EINVAL, "skin: %u bones (1..%d)", n_bones, MIM_XFER_SKIN_MAX_BONES);
    for (uint32_t b = 0; b < 6 * n_bones; b++)
        if (!isfinite(bones[b]))
            return mim_error_set(err, MIM_ENONFINITE, "skin: bone %u has a non-finite end", b / 6);
    const uint32_t n = t->n;
    float *w = calloc((size_t)n * n_bones, sizeof *w), *next = malloc((size_t)n * n_bones * sizeof *next);
    if (!w || !next) {
        free(w), free(next);
        return mim_error_set(err, MIM_ENOMEM, "skin: out of memory (%u vertices, %u bones)", n, n_bones);
    }
    for (uint32_t i = 0; i < n; i++) {
        double best = DBL_MAX;
        uint32_t at = 0;
        for (uint32_t b = 0; b < n_bones; b++) {
            double d2 = bone_distance2(positions + 3 * (size_t)i, bones + 6 * (size_t)b);
            if (d2 < best) best = d2, at = b;
        }
        w[(size_t)i * n_bones + at] = 1.0f;
    }
    for (uint32_t step = 0; step < smoothing; step++) {
        diffuse(t, n_bones, w, next);
        float *tmp = w;
        w = next, next = tmp;
    }
    mim_xfer_skin_from_dense(n, w, n_bones, NULL, skin); /* every row holds weight: no fallback needed */
    if (wide_bones && wide_smoothing > smoothing) {
        for (uint32_t step = smoothing; step < wide_smoothing; step++) {
            diffuse(t, n_bones, w, next);
            float *tmp = w;
            w = next, next = tmp;
        }
        for (uint32_t i = 0; i < n; i++)
            if (skin[i].bone[0] < 64 && (wide_bones >> skin[i].bone[0] & 1))
                mim_xfer_skin_from_dense(1, w + (size_t)i * n_bones, n_bones, NULL, skin + i);
    }
    free(w), free(next);
    return 0;
}

uint32_t mim_xfer_skin_from_dense(uint32_t n_vertices, const float *w, uint32_t n_bones, const mim_xfer_skin_t *fallback,
                                  mim_xfer_skin_t *skin)
{
    uint32_t fell_back = 0, used = n_bones < MIM_XFER_SKIN_MAX_BONES ? n_bones : MIM_XFER_SKIN_MAX_BONES;
    for (uint32_t i = 0; i < n_vertices; i++) {
        const float *wi = w + (size_t)i * n_bones;
        mim_xfer_skin_t *s = skin + i, keep = {{0}, {1}};
        if (fallback) keep = fallback[i]; /* read first: fallback may be skin itself */
        memset(s, 0, sizeof *s);
        for (uint32_t b = 0; b < used; b++) { /* insertion into the largest few */
            int k = MIM_XFER_SKIN_INFLUENCES;
            while (k > 0 && wi[b] > s->weight[k - 1]) k--;
            if (k == MIM_XFER_SKIN_INFLUENCES) continue;
            memmove(s->weight + k + 1, s->weight + k, (MIM_XFER_SKIN_INFLUENCES - 1 - k) * sizeof *s->weight);
            memmove(s->bone + k + 1, s->bone + k, (MIM_XFER_SKIN_INFLUENCES - 1 - k) * sizeof *s->bone);
            s->weight[k] = wi[b], s->bone[k] = (uint8_t)b;
        }
        float sum = 0;
        for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES; k++) sum += s->weight[k];
        if (!(sum > 0)) { /* no weight here (a rig's unmapped joints only): the fallback's, else bone 0 */
            *s = keep;
            fell_back++;
            continue;
        }
        for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES; k++) s->weight[k] /= sum;
    }
    return fell_back;
}

/* The weighted sum of a vertex's segment quaternions, each in the
 * hemisphere of the heaviest one, not normalised; *h gets the heaviest. */
static inline mim_quat blend_sum(const mim_xfer_skin_t *s, const mim_quat *rot, mim_quat *h)
{
    *h = rot[s->bone[0]];
    mim_quat q = {0, 0, 0, 0};
    for (int k = 0; k < MIM_XFER_SKIN_INFLUENCES && s->weight[k] > 0; k++) {
        mim_quat r = rot[s->bone[k]];
        double w = s->weight[k];
        if (r.x * h->x + r.y * h->y + r.z * h->z + r.w * h->w < 0) w = -w;
        q.x += w * r.x, q.y += w * r.y, q.z += w * r.z, q.w += w * r.w;
    }
    return q;
}

/* opposite rotations cancelling: the heaviest decides */
#define CANCELLED(q) (!((q).x * (q).x + (q).y * (q).y + (q).z * (q).z + (q).w * (q).w > 1e-24))

mim_quat mim_xfer_skin_rotation(const mim_xfer_skin_t *s, const mim_quat *rot)
{
    mim_quat h, q = blend_sum(s, rot, &h);
    if (CANCELLED(q)) return h;
    return mim_quat_normalize(q);
}

void mim_xfer_skin_frames(uint32_t n_vertices, const mim_xfer_skin_t *skin, const double *rest_frames,
                          const mim_quat *rot, double *frames)
{
    for (uint32_t i = 0; i < n_vertices; i++) {
        double R[9];
        mim_quat_to_matrix(mim_xfer_skin_rotation(skin + i, rot), R);
        const double *f = rest_frames + 9 * (size_t)i;
        double *o = frames + 9 * (size_t)i;
        for (int col = 0; col < 3; col++)
            for (int r = 0; r < 3; r++)
                o[3 * col + r] = R[r] * f[3 * col] + R[3 + r] * f[3 * col + 1] + R[6 + r] * f[3 * col + 2];
    }
}

void mim_xfer_skin_offsets(uint32_t n_vertices, const mim_xfer_skin_t *restrict skin, const double *restrict rest_offsets,
                           const mim_quat *restrict rot, double *restrict offsets)
{
    for (uint32_t i = 0; i < n_vertices; i++) {
        const double *d = rest_offsets + 3 * (size_t)i;
        mim_quat h, q = blend_sum(skin + i, rot, &h);
        if (CANCELLED(q)) q = h;
        mim_vec3 v = mim_quat_rotate_unnormalized(q, mim_v3(d[0], d[1], d[2]));
        double *o = offsets + 3 * (size_t)i;
        o[0] = v.x, o[1] = v.y, o[2] = v.z;
    }
}
