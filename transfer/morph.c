/* Morphing between key poses (seed 000, Section 3.5). The paper
 * interpolates vertex positions linearly between two key poses; where a
 * limb rotates, the straight-line paths cut the arc and the limb shrinks
 * (the paper's Fig. 14). mimic's alternative interpolates what the
 * encoding is made of instead: each vertex's local frame (quaternion
 * slerp between the key poses' frames), its encoding W (lerp between the
 * key poses' own W = F^T L X, which differ little when both keys are the
 * same avatar) and the landmark positions (lerp, or along the skeleton:
 * inbetween.c, which the session uses), and solves once with the
 * cached factor. At t = 0 and 1 the right-hand side is exactly L X of the
 * key, so the keys come back unchanged; in between, offsets turn with
 * their frames instead of shortening along chords. */
#include "internal.h"

/* Frames are rotation matrices with columns f1 f2 f3 (mim_core.h's layout);
 * quaternions are x y z w. */
void mim_xfer_frames_to_quats(uint32_t n_vertices, const double *frames, double *quats)
{
    for (size_t i = 0; i < n_vertices; i++) {
        mim_quat q = mim_quat_from_matrix(frames + 9 * i);
        double *o = quats + 4 * i;
        o[0] = q.x, o[1] = q.y, o[2] = q.z, o[3] = q.w;
    }
}

int mim_xfer_morph(mim_xfer_solver_t *s, mim_xfer_morph_method_t method, const mim_xfer_key_t *a,
                   const mim_xfer_key_t *b, double t, float *out, mim_error_t *err)
{
    return mim_xfer_morph_between(s, method, a, b, t, NULL, out, err);
}

int mim_xfer_morph_between(mim_xfer_solver_t *s, mim_xfer_morph_method_t method, const mim_xfer_key_t *a,
                           const mim_xfer_key_t *b, double t, const float *landmarks, float *out, mim_error_t *err)
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
        u[k] = landmarks ? landmarks[k] : (float)((1.0 - t) * a->landmarks[k] + t * b->landmarks[k]);
    if (a->torso && b->torso) { /* relative to the torso, then the torso's turn: one way round for all */
        const mim_quat ta = {a->torso[0], a->torso[1], a->torso[2], a->torso[3]},
                       tb = {b->torso[0], b->torso[1], b->torso[2], b->torso[3]};
        const mim_quat ia = {-ta.x, -ta.y, -ta.z, ta.w}, ib = {-tb.x, -tb.y, -tb.z, tb.w}, tt = mim_quat_slerp(ta, tb, t);
        for (size_t i = 0; i < n; i++) {
            const double *qa = a->quats + 4 * i, *qb = b->quats + 4 * i;
            mim_quat A = mim_quat_mul(ia, (mim_quat){qa[0], qa[1], qa[2], qa[3]}),
                     B = mim_quat_mul(ib, (mim_quat){qb[0], qb[1], qb[2], qb[3]});
            mim_quat_to_matrix(mim_quat_mul(tt, mim_quat_slerp(A, B, t)), s->mframes + 9 * i);
        }
    } else {
        for (size_t i = 0; i < n; i++) {
            const double *qa = a->quats + 4 * i, *qb = b->quats + 4 * i;
            mim_quat A = {qa[0], qa[1], qa[2], qa[3]}, B = {qb[0], qb[1], qb[2], qb[3]};
            mim_quat_to_matrix(mim_quat_slerp(A, B, t), s->mframes + 9 * i);
        }
    }
    for (size_t i = 0; i < 3 * (size_t)n; i++)
        s->mW[i] = (1.0 - t) * a->W[i] + t * b->W[i];
    /* one solve: the frames are given, not iterated */
    mim_xfer_options_t o = {.max_iterations = 1, .tol = -1.0, .no_early_stop = 1};
    return mim_xfer_transfer(s, s->mW, n, s->mframes, u, s->nc, &o, out, NULL, err);
}
