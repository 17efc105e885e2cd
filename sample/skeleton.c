/* The pose-pair model the chains walk in (seed 002 Section 3's theta):
 * per person a tree of 17 joints rooted at the pelvis, a local rotation at
 * each joint that has a child, and the bone vectors of a rest pose-pair.
 * BVH's convention: a joint's rotation turns the bones to its children, so
 * a joint's place is its parent's place plus the parent's global rotation
 * applied to the rest bone. */
#include "mim_sample_mcmc.h"

enum { HEAD, CHEST, PELVIS, LSH, RSH, LEL, REL, LWR, RWR, LHIP, RHIP, LKN, RKN, LAN, RAN, SPINE, NECK };

const int8_t mim_pairs_parent[MIM_PAIR_PERSON_JOINTS] = {
    [HEAD] = NECK, [CHEST] = SPINE, [PELVIS] = -1, [LSH] = CHEST, [RSH] = CHEST, [LEL] = LSH,
    [REL] = RSH,   [LWR] = LEL,     [RWR] = REL,   [LHIP] = PELVIS, [RHIP] = PELVIS, [LKN] = LHIP,
    [RKN] = RHIP,  [LAN] = LKN,     [RAN] = RKN,   [SPINE] = PELVIS, [NECK] = CHEST,
};
const int8_t mim_pairs_rot_joint[MIM_PAIRS_ROT] = {PELVIS, SPINE, CHEST, NECK, LSH, RSH, LEL, REL, LHIP, RHIP, LKN, RKN};

/* Parents before children; and each joint's rotation index (-1 for leaves). */
static const int8_t order[MIM_PAIR_PERSON_JOINTS] = {PELVIS, SPINE, LHIP, RHIP, CHEST, LKN, RKN, NECK, LSH,
                                                     RSH,    LAN,   RAN,  HEAD, LEL,   REL, LWR,  RWR};
static const int8_t rot_of[MIM_PAIR_PERSON_JOINTS] = {
    [HEAD] = -1, [CHEST] = 2, [PELVIS] = 0, [LSH] = 4, [RSH] = 5, [LEL] = 6, [REL] = 7, [LWR] = -1, [RWR] = -1,
    [LHIP] = 8,  [RHIP] = 9,  [LKN] = 10,   [RKN] = 11, [LAN] = -1, [RAN] = -1, [SPINE] = 1, [NECK] = 3,
};

int mim_pairs_group_free(int g)
{
    return g != 0 && g != MIM_PAIRS_GROUP_TRANS(0) && g >= 0 && g < MIM_PAIRS_GROUPS;
}

void mim_pairs_pose_rest(const double *pair, mim_pairs_pose_t *pose)
{
    for (int p = 0; p < 2; p++) {
        const double *j = pair + 3 * MIM_PAIR_PERSON_JOINTS * p;
        for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++)
            for (int c = 0; c < 3; c++)
                pose->offset[p][k][c] = mim_pairs_parent[k] < 0 ? 0.0 : j[3 * k + c] - j[3 * mim_pairs_parent[k] + c];
        for (int r = 0; r < MIM_PAIRS_ROT; r++) pose->rot[p][r] = mim_quat_identity();
        for (int c = 0; c < 3; c++) pose->root[p][c] = j[3 * PELVIS + c];
    }
}

void mim_pairs_pose_joints(const mim_pairs_pose_t *pose, double *joints)
{
    for (int p = 0; p < 2; p++) {
        double *out = joints + 3 * MIM_PAIR_PERSON_JOINTS * p;
        mim_quat global[MIM_PAIR_PERSON_JOINTS];
        for (int o = 0; o < MIM_PAIR_PERSON_JOINTS; o++) {
            int k = order[o], parent = mim_pairs_parent[k];
            if (parent < 0) {
                for (int c = 0; c < 3; c++) out[3 * k + c] = pose->root[p][c];
                global[k] = pose->rot[p][0];
                continue;
            }
            const double *off = pose->offset[p][k];
            mim_vec3 d = mim_quat_rotate(global[parent], mim_v3(off[0], off[1], off[2]));
            out[3 * k] = out[3 * parent] + d.x, out[3 * k + 1] = out[3 * parent + 1] + d.y;
            out[3 * k + 2] = out[3 * parent + 2] + d.z;
            global[k] = rot_of[k] < 0 ? global[parent] : mim_quat_mul(global[parent], pose->rot[p][rot_of[k]]);
        }
    }
}
