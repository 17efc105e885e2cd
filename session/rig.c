/* An avatar's rig (issue 28): its joints mapped to the 17 body segments by
 * name (mim_vest_segments_of_joints: Mixamo, Blender, SMPL, VRM humanoid
 * names), each segment's pivot the mapped joint nearest the root, and the
 * 16 landmarks placed from those pivots (mim_reg_rig_landmarks), so a
 * rigged avatar needs no landmark file. */
#include "internal.h"

#include "mim_vest_kinematics.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int mim_session_rig_pivots(const mim_io_skin_t *skin, double pivots[3 * MIM_SEGMENTS], uint8_t have[MIM_SEGMENTS],
                           uint32_t *covered)
{
    memset(have, 0, MIM_SEGMENTS);
    *covered = 0;
    if (!skin || !skin->n_joints || !skin->joint_positions) return MIM_ENOTFOUND;
    const char **names = malloc(skin->n_joints * sizeof *names);
    int *seg = malloc(skin->n_joints * sizeof *seg);
    uint32_t *depth = malloc(skin->n_joints * sizeof *depth);
    if (!names || !seg || !depth) {
        free(names), free(seg), free(depth);
        return MIM_ENOMEM;
    }
    for (uint32_t j = 0; j < skin->n_joints; j++) {
        names[j] = skin->names[j];
        uint32_t d = 0;
        for (int32_t a = skin->parent ? skin->parent[j] : -1; a >= 0 && d <= skin->n_joints; a = skin->parent[a]) d++;
        depth[j] = d;
    }
    *covered = mim_vest_segments_of_joints(names, skin->n_joints, seg);
    /* The segment's pivot: its joint nearest the root; but the head turns
     * about the head joint, not the neck's base (which maps to the head
     * segment too), and a head's end or top is no pivot at all. */
    uint32_t best[MIM_SEGMENTS];
    for (uint32_t j = 0; j < skin->n_joints; j++) {
        int g = seg[j];
        if (g == MIM_VEST_HEAD) {
            const char *n = names[j];
            int head = strcasestr(n, "head") && !strcasestr(n, "end") && !strcasestr(n, "top");
            if (!head) continue;
        }
        if (g < 0 || (have[g] && depth[j] >= best[g])) continue;
        have[g] = 1, best[g] = depth[j];
        for (int c = 0; c < 3; c++) pivots[3 * g + c] = skin->joint_positions[3 * (size_t)j + c];
    }
    free(names), free(seg), free(depth);
    return 0;
}

int mim_session_rig_landmarks(const mim_mesh_t *mesh, const mim_io_skin_t *skin, const mim_landmark_map_t *map,
                              float *out, char *how, size_t how_size, mim_error_t *err)
{
    double piv[3 * MIM_SEGMENTS];
    uint8_t have[MIM_SEGMENTS];
    uint32_t covered = 0;
    int rc = mim_session_rig_pivots(skin, piv, have, &covered);
    if (rc == MIM_ENOMEM) return mim_error_set(err, rc, "out of memory for the rig");
    if (rc) return mim_error_set(err, MIM_ENOLANDMARKS, "no rig");
    if (covered < MIM_SESSION_RIG_MIN_SEGMENTS)
        return mim_error_set(err, MIM_ENOLANDMARKS,
                             "its rig's %u joint names give %u of the 17 body segments (at least %d needed)",
                             skin->n_joints, covered, MIM_SESSION_RIG_MIN_SEGMENTS);
    float lm[3 * MIM_REG_RIG_LANDMARKS];
    char missing[512];
    mim_error_t e = {0};
    if ((rc = mim_reg_rig_landmarks(mesh, piv, have, lm, missing, sizeof missing, &e)))
        return mim_error_set(err, rc, "%s%s%s", mim_error_text(&e), missing[0] ? ": " : "", missing);
    for (uint32_t l = 0; l < map->count; l++) {
        int k = -1;
        for (int r = 0; r < MIM_REG_RIG_LANDMARKS && k < 0; r++)
            if (!strcmp(map->names[l], mim_reg_rig_landmark_names[r])) k = r;
        if (k < 0)
            return mim_error_set(err, MIM_ENOLANDMARKS,
                                 "the store's landmark '%s' has no rule from a rig (only the 16 default landmarks have)",
                                 map->names[l]);
        memcpy(out + 3 * l, lm + 3 * k, 3 * sizeof(float));
    }
    if (how && how_size)
        snprintf(how, how_size, "its rig (%u joints on %u of the 17 segments%s)", skin->n_joints, covered,
                 skin->from_vrm ? ", VRM humanoid names" : "");
    return 0;
}

int mim_session_rest_pose(const mim_session_t *s, double *arm_deg)
{
    *arm_deg = NAN;
    int at[4] = {-1, -1, -1, -1};
    static const char *const want[4] = {"l_shoulder", "l_elbow", "r_shoulder", "r_elbow"};
    for (uint32_t l = 0; l < s->map.count; l++)
        for (int k = 0; k < 4; k++)
            if (!strcmp(s->map.names[l], want[k])) at[k] = (int)s->map.vertex[l];
    if (!s->mesh.positions || at[0] < 0 || at[1] < 0 || at[2] < 0 || at[3] < 0) return -1;
    double sum = 0;
    for (int side = 0; side < 2; side++) { /* each upper arm's angle below the horizontal (+Y up) */
        const float *a = s->mesh.positions + 3 * (size_t)at[2 * side], *b = s->mesh.positions + 3 * (size_t)at[2 * side + 1];
        double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(len > 0)) return -1;
        sum += asin(fmax(-1, fmin(1, -d[1] / len))) * 180 / M_PI;
    }
    *arm_deg = sum / 2;
    return *arm_deg < MIM_SESSION_T_POSE_MAX_DEG ? MIM_VEST_POSE_T
           : *arm_deg < MIM_SESSION_A_POSE_MAX_DEG ? MIM_VEST_POSE_A
                                                   : MIM_VEST_POSE_REST;
}
