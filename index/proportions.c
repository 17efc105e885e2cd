/* Canonical proportions: every frame the index sees, template or query,
 * is redrawn on the store's mean segment lengths with its own segment
 * directions (the landmark skeleton's bones). The angle descriptor (seed
 * 000, Section 3.2) is blind to rotation, translation and scale, but not
 * to proportions: the angle at the pelvis between the head and a wrist
 * moves with the arm's length, so one pose taken by bodies of other
 * proportions gives other angles (about 1 rad for motion capture joints
 * against a synth avatar, bench/RESULTS.md "Sampled templates found again
 * by their own joints"). On canonical proportions only the directions of
 * the bones are left, which is what a pose is.
 *
 * Lost landmarks (a query's present flags): a present landmark is placed
 * from the nearest present one towards the root, or along the tree when
 * the root is lost, its anchor. When the two are one bone apart, the bone
 * takes its canonical length in its own direction; when lost landmarks lie
 * between them their distance is unknown, so the displacement is the
 * frame's own, scaled by the frame's proportions to the canonical ones
 * (summed over the bones it has). Lost landmarks keep their positions.
 *
 * What sees them: the angles (the descriptor, the tree that selects it,
 * the SVMs, the k-NN and its vote, the angle discriminants). The shape
 * discriminants and the completion keep the frame as it is: redrawing
 * carries each landmark's noise down the chain to its children, and their
 * Gaussians model noise on each landmark alone (shape.c); measured on
 * bench_query_accuracy's hard set, classes from canonical frames lost
 * 6-10 points at 2-3 cm of noise (bench/RESULTS.md). */
#include "internal.h"

#include <math.h>
#include <string.h>

int mim_index_skeleton(const mim_landmark_map_t *map, int32_t *parent)
{
    int child_of[MIM_LANDMARK_BONES], parent_of[MIM_LANDMARK_BONES];
    const char *missing;
    if (mim_landmark_skeleton(map, child_of, parent_of, &missing)) return MIM_EUNSUPPORTED;
    for (uint32_t l = 0; l < map->count; l++) parent[l] = -1;
    for (uint32_t k = 0; k < MIM_LANDMARK_BONES; k++) parent[child_of[k]] = parent_of[k];
    return 0;
}

int mim__proportions_check(const int32_t *parent, uint32_t L)
{
    if (L > MIM_LANDMARKS_MAX) return -1;
    uint32_t roots = 0;
    for (uint32_t l = 0; l < L; l++) {
        if (parent[l] == -1) {
            roots++;
            continue;
        }
        if (parent[l] < 0 || (uint32_t)parent[l] >= L) return -1;
        uint32_t v = l, steps = 0; /* the root is reached within L steps */
        while (parent[v] != -1 && steps++ <= L) v = (uint32_t)parent[v];
        if (parent[v] != -1) return -1;
    }
    return roots == 1 ? 0 : -1;
}

int mim__proportions_build(mim__proportions_t *p, const mim_index_input_t *in, mim_error_t *err)
{
    const uint32_t L = in->n_landmarks, n = in->n_templates;
    memset(p, 0, sizeof *p);
    if (mim__proportions_check(in->parent, L))
        return mim_error_set(err, MIM_EINVAL, "index: the landmark skeleton is not a tree over the %u landmarks", L);
    for (uint32_t l = 0; l < L; l++) {
        p->parent[l] = in->parent[l];
        if (in->parent[l] < 0) continue;
        double sum = 0;
        for (uint32_t t = 0; t < n; t++) {
            const float *a = in->landmarks + ((size_t)t * L + l) * 3,
                        *b = in->landmarks + ((size_t)t * L + (uint32_t)in->parent[l]) * 3;
            double s = 0;
            for (int c = 0; c < 3; c++) s += ((double)a[c] - b[c]) * ((double)a[c] - b[c]);
            sum += sqrt(s);
        }
        p->length[l] = (float)(sum / n);
        if (!(p->length[l] > 0))
            return mim_error_set(err, MIM_EINVAL, "index: landmarks %u and %u coincide in every template", l,
                                 (uint32_t)in->parent[l]);
    }
    p->on = 1;
    return 0;
}

static int usable(const float *pos, const uint8_t *present, uint32_t l)
{
    return (!present || present[l]) && isfinite(pos[3 * l]) && isfinite(pos[3 * l + 1]) && isfinite(pos[3 * l + 2]);
}

/* The bone between neighbours u and v: its canonical length. */
static float bone_length(const mim__proportions_t *p, uint32_t u, uint32_t v)
{
    return p->parent[v] == (int32_t)u ? p->length[v] : p->length[u];
}

/* Visits the tree from start, each landmark after a neighbour: order gets
 * the landmarks, from[] the neighbour each was reached from (-1: start). */
static uint32_t walk(const mim__proportions_t *p, uint32_t L, uint32_t start, uint32_t *order, int32_t *from)
{
    uint32_t n = 0;
    order[n++] = start, from[start] = -1;
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t u = order[i];
        for (uint32_t v = 0; v < L; v++) {
            const int adjacent = p->parent[v] == (int32_t)u || p->parent[u] == (int32_t)v;
            if (!adjacent || v == start || (from[v] != -2)) continue;
            from[v] = (int32_t)u;
            order[n++] = v;
        }
    }
    return n;
}

/* The frame's canonical length over its own, over the bones it has
 * whole (1 when it has none). */
static double frame_ratio(const mim__proportions_t *p, uint32_t L, const float *pos, const uint8_t *present)
{
    double canon = 0, own = 0;
    for (uint32_t l = 0; l < L; l++) {
        const int32_t q = p->parent[l];
        if (q < 0 || !usable(pos, present, l) || !usable(pos, present, (uint32_t)q)) continue;
        double s = 0;
        for (int c = 0; c < 3; c++) s += ((double)pos[3 * l + c] - pos[3 * q + c]) * ((double)pos[3 * l + c] - pos[3 * q + c]);
        canon += p->length[l], own += sqrt(s);
    }
    return own > 0 ? canon / own : 1;
}

static uint32_t first_usable(const mim__proportions_t *p, uint32_t L, const float *pos, const uint8_t *present)
{
    for (uint32_t l = 0; l < L; l++)
        if (p->parent[l] < 0 && usable(pos, present, l)) return l;
    for (uint32_t l = 0; l < L; l++)
        if (usable(pos, present, l)) return l;
    return L;
}

void mim__proportions_apply(const mim__proportions_t *p, uint32_t L, const float *pos, const uint8_t *present,
                            float *out)
{
    memcpy(out, pos, sizeof *out * 3 * L);
    const uint32_t start = first_usable(p, L, pos, present);
    if (start == L) return;
    const double ratio = frame_ratio(p, L, pos, present);
    uint32_t order[MIM_LANDMARKS_MAX], anchor[MIM_LANDMARKS_MAX];
    int32_t from[MIM_LANDMARKS_MAX];
    for (uint32_t l = 0; l < L; l++) from[l] = -2;
    const uint32_t n = walk(p, L, start, order, from);
    anchor[start] = start;
    for (uint32_t i = 1; i < n; i++) {
        const uint32_t v = order[i], u = (uint32_t)from[v], a = anchor[u];
        anchor[v] = a;
        if (!usable(pos, present, v)) continue;
        anchor[v] = v;
        double dir[3], len = 0;
        for (int c = 0; c < 3; c++) {
            dir[c] = (double)pos[3 * v + c] - pos[3 * a + c];
            len += dir[c] * dir[c];
        }
        len = sqrt(len);
        /* one bone: its canonical length; lost landmarks between: the
         * frame's own displacement, rescaled */
        const double scale = a == u ? (len > 0 ? bone_length(p, u, v) / len : 0) : ratio;
        for (int c = 0; c < 3; c++) out[3 * v + c] = (float)(out[3 * a + c] + scale * dir[c]);
    }
}
