/* Mode (a), "template only": the pose comes from the template alone, the
 * proportions from the avatar. The paper (seed 000, Section 3.4) fixes one
 * vertex and lets the template's frames carry the pose; measured on synth
 * and mh-bodies, one anchor leaves the low frequencies free and the body
 * drifts (bench/transfer_accuracy.c). So mimic retargets the landmarks
 * first: it walks the landmark skeleton from the pelvis, taking each
 * segment's direction from the template and its length from the avatar's
 * rest pose, places the result where the template stands (same ankle
 * midpoint), and then solves as in mode (b) with those positions. */
#include "internal.h"

#include <math.h>
#include <string.h>

int mim__xfer_landmark_tree(const mim_landmark_map_t *map, int *root, int child[MIM__XFER_BONES],
                            int parent[MIM__XFER_BONES], const char *what, mim_error_t *err)
{
    const char *missing;
    *root = mim_landmarks_find(map, "pelvis");
    if (mim_landmark_skeleton(map, child, parent, &missing))
        return missing ? mim_error_set(err, MIM_EUNSUPPORTED, "transfer: %s needs landmark '%s'", what, missing)
                       : mim_error_set(err, MIM_EUNSUPPORTED,
                                       "transfer: %s needs the 16 default landmarks (pelvis, spine, ...)", what);
    return 0;
}

int mim_xfer_retarget_landmarks(const mim_landmark_map_t *map, const float *avatar_rest, const float *tmpl,
                                float *out, mim_error_t *err)
{
    int root, child[MIM__XFER_BONES], parent[MIM__XFER_BONES];
    int rc = mim__xfer_landmark_tree(map, &root, child, parent, "retargeting", err);
    if (rc) return rc;
    /* the template's landmark positions at landmark vertices */
    for (int c = 0; c < 3; c++)
        out[3 * root + c] = tmpl[3 * (size_t)map->vertex[root] + c];
    for (size_t k = 0; k < MIM__XFER_BONES; k++) {
        const uint32_t vc = map->vertex[child[k]], vp = map->vertex[parent[k]];
        double dir[3], len = 0.0, d2 = 0.0;
        for (int c = 0; c < 3; c++) {
            dir[c] = (double)tmpl[3 * (size_t)vc + c] - tmpl[3 * (size_t)vp + c];
            d2 += dir[c] * dir[c];
            double a = (double)avatar_rest[3 * (size_t)vc + c] - avatar_rest[3 * (size_t)vp + c];
            len += a * a;
        }
        double scale = d2 > 0.0 ? sqrt(len / d2) : 0.0;
        for (int c = 0; c < 3; c++)
            out[3 * child[k] + c] = (float)(out[3 * parent[k] + c] + scale * dir[c]);
    }
    /* placed where the template stands: the midpoints of the ankles
     * coincide (the template's pelvis would sink or lift a body with
     * other leg lengths) */
    const int la = mim_landmarks_find(map, "l_ankle"), ra = mim_landmarks_find(map, "r_ankle");
    double shift[3];
    for (int c = 0; c < 3; c++)
        shift[c] = 0.5 * ((double)tmpl[3 * (size_t)map->vertex[la] + c] + tmpl[3 * (size_t)map->vertex[ra] + c] -
                          out[3 * la + c] - out[3 * ra + c]);
    for (uint32_t l = 0; l < map->count; l++)
        for (int c = 0; c < 3; c++)
            out[3 * l + c] = (float)(out[3 * l + c] + shift[c]);
    return 0;
}
