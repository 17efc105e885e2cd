/* The 19-joint skeleton and its rest (A-pose) joint positions per subject.
 *
 * Proportions are fractions of stature from standard anthropometry (Drillis
 * and Contini segment lengths; Winter, "Biomechanics and Motor Control of
 * Human Movement", fig. 4.1): hip joint ~0.515 H, knee 0.285 H, ankle 0.045 H,
 * shoulder joint 0.805 H, upper arm 0.172 H, forearm 0.15 H, hand 0.108 H.
 * Leg and arm multipliers change limb lengths; the torso absorbs the leg
 * change so the stature stays exact. Rest arms hang 45 degrees from vertical
 * (an A-pose, like MakeHuman's rest pose), legs slightly apart. */
#include "synth_internal.h"

#include <math.h>

const char *const mim__joint_name[MIM__NJ] = {
    "pelvis",    "spine",     "chest",      "neck",       "head",    "l_clavicle", "r_clavicle",
    "l_upperarm", "r_upperarm", "l_forearm", "r_forearm", "l_hand",  "r_hand",     "l_thigh",
    "r_thigh",   "l_shin",    "r_shin",     "l_foot",     "r_foot",
};
const int mim__joint_parent[MIM__NJ] = {-1, 0, 1, 2, 3, 2, 2, 5, 6, 7, 8, 9, 10, 0, 0, 13, 14, 15, 16};
const int mim__joint_mirror[MIM__NJ] = {0, 1, 2, 3, 4, 6, 5, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15, 18, 17};

int mim__bone_mirror(int b)
{
    if (b < MIM__NJ) return mim__joint_mirror[b];
    int j = (b - MIM__NJ) / (MIM__HK - 1), k = (b - MIM__NJ) % (MIM__HK - 1) + 1;
    return MIM__HELPER(mim__joint_mirror[j], k);
}

mim_vec3 mim__arm_dir(void)
{
    double a = MIM__ARM_ANGLE_DEG * M_PI / 180.0;
    return mim_v3(sin(a), -cos(a), 0);
}

mim_vec3 mim__arm_lat(void)
{
    double a = MIM__ARM_ANGLE_DEG * M_PI / 180.0;
    return mim_v3(cos(a), sin(a), 0);
}

static mim_vec3 mirror(mim_vec3 v) { return mim_v3(-v.x, v.y, v.z); }

void mim__skeleton_make(mim__skeleton_t *sk, const mim__subject_t *sub)
{
    double H = sub->height;
    sk->H = H;
    double y_ankle = 0.045 * H;
    double leg = 0.47 * H * sub->leg;
    double y_hip = y_ankle + leg;
    double y_knee = y_ankle + 0.51 * leg;
    double hd = sub->head;
    double y_head = H - 0.10 * H * hd;     /* skull base (atlas) */
    double y_neck = y_head - 0.066 * H * hd; /* C7, top of the torso */
    double torso = y_neck - y_hip;
    double hipw = 0.05 * H * sub->hip;

    mim_vec3 *j = sk->j;
    j[MIM__J_PELVIS] = mim_v3(0, y_hip, 0);
    /* spine joints sit towards the back, where the vertebrae bend */
    j[MIM__J_SPINE] = mim_v3(0, y_hip + 0.28 * torso, -0.018 * H);
    j[MIM__J_CHEST] = mim_v3(0, y_hip + 0.56 * torso, -0.016 * H);
    j[MIM__J_NECK] = mim_v3(0, y_neck, -0.012 * H);
    j[MIM__J_HEAD] = mim_v3(0, y_head, -0.002 * H);
    j[MIM__J_LCLAV] = mim_v3(0.014 * H, y_neck - 0.016 * H, 0.012 * H);
    j[MIM__J_LUARM] = mim_v3(0.099 * H * sub->shoulder, y_neck - 0.030 * H, -0.006 * H);
    sk->ua = 0.172 * H * sub->arm;
    sk->fa = 0.150 * H * sub->arm;
    sk->hand = 0.108 * H * sub->arm;
    mim_vec3 d = mim__arm_dir();
    j[MIM__J_LFARM] = mim_v3_add(j[MIM__J_LUARM], mim_v3_scale(d, sk->ua));
    j[MIM__J_LHAND] = mim_v3_add(j[MIM__J_LFARM], mim_v3_scale(d, sk->fa));
    sk->hand_tip = mim_v3_add(j[MIM__J_LHAND], mim_v3_scale(d, sk->hand));
    j[MIM__J_LTHIGH] = mim_v3(hipw, y_hip, 0);
    j[MIM__J_LSHIN] = mim_v3(hipw * 1.06, y_knee, 0.004 * H);
    j[MIM__J_LFOOT] = mim_v3(hipw * 1.16, y_ankle, -0.004 * H);
    sk->toe_tip = mim_v3(hipw * 1.16 + 0.008 * H, 0.012 * H, 0.118 * H);
    sk->head_top = mim_v3(0, H, -0.004 * H);
    sk->y_crotch = y_hip - 0.045 * H;

    static const int left[] = {MIM__J_LCLAV, MIM__J_LUARM, MIM__J_LFARM, MIM__J_LHAND,
                               MIM__J_LTHIGH, MIM__J_LSHIN, MIM__J_LFOOT};
    for (size_t i = 0; i < sizeof left / sizeof left[0]; i++)
        j[mim__joint_mirror[left[i]]] = mirror(j[left[i]]);
}
