/* vest/segment_names.c: a rig's joint names to the vest's 17 segments, for
 * the common naming schemes (Mixamo, Biovision/CMU, Poser, SMPL, Blender,
 * 3ds Max biped) and names that are no body joint. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "mim_vest_kinematics.h"

#include <string.h>

typedef struct {
    const char *name;
    int segment;
} case_t;

static void check(const char *const *names, uint32_t n, const int *want, uint32_t covered)
{
    int got[64];
    assert_int_equal(mim_vest_segments_of_joints(names, n, got), covered);
    for (uint32_t j = 0; j < n; j++) {
        if (got[j] != want[j]) print_error("%s: %d, want %d\n", names[j], got[j], want[j]);
        assert_int_equal(got[j], want[j]);
    }
}

static void test_mixamo(void **state)
{
    (void)state;
    const char *names[] = {"mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine2", "mixamorig:Neck", "mixamorig:Head",
                           "mixamorig:LeftShoulder", "mixamorig:LeftArm", "mixamorig:LeftForeArm", "mixamorig:LeftHand",
                           "mixamorig:LeftHandIndex1", "mixamorig:RightShoulder", "mixamorig:RightArm",
                           "mixamorig:RightForeArm", "mixamorig:RightHandThumb2", "mixamorig:LeftUpLeg",
                           "mixamorig:LeftLeg", "mixamorig:LeftFoot", "mixamorig:LeftToeBase", "mixamorig:RightUpLeg",
                           "mixamorig:RightLeg", "mixamorig:RightFoot", "mixamorig:RightToe_End", "mixamorig:HeadTop_End"};
    const int want[] = {MIM_VEST_PELVIS,     MIM_VEST_CHEST,     MIM_VEST_CHEST,      MIM_VEST_HEAD,      MIM_VEST_HEAD,
                        MIM_VEST_L_SHOULDER, MIM_VEST_L_UPPERARM, MIM_VEST_L_FOREARM, MIM_VEST_L_HAND,    MIM_VEST_L_HAND,
                        MIM_VEST_R_SHOULDER, MIM_VEST_R_UPPERARM, MIM_VEST_R_FOREARM, MIM_VEST_R_HAND,    MIM_VEST_L_THIGH,
                        MIM_VEST_L_SHIN,     MIM_VEST_L_FOOT,     MIM_VEST_L_FOOT,    MIM_VEST_R_THIGH,   MIM_VEST_R_SHIN,
                        MIM_VEST_R_FOOT,     MIM_VEST_R_FOOT,     MIM_VEST_HEAD};
    check(names, sizeof names / sizeof *names, want, 17);
}

static void test_smpl(void **state)
{
    (void)state;
    /* SMPL: a joint turns the bone below it; "shoulder" is the upper arm because the rig has collars */
    const char *names[] = {"pelvis",      "left_hip",       "right_hip",   "spine1",      "left_knee",  "right_knee",
                           "spine2",      "left_ankle",     "right_ankle", "spine3",      "left_foot",  "right_foot",
                           "neck",        "left_collar",    "right_collar", "head",       "left_shoulder",
                           "right_shoulder", "left_elbow",  "right_elbow", "left_wrist",  "right_wrist", "left_hand",
                           "right_hand"};
    const int want[] = {MIM_VEST_PELVIS,     MIM_VEST_L_THIGH,    MIM_VEST_R_THIGH,    MIM_VEST_CHEST,
                        MIM_VEST_L_SHIN,     MIM_VEST_R_SHIN,     MIM_VEST_CHEST,      MIM_VEST_L_FOOT,
                        MIM_VEST_R_FOOT,     MIM_VEST_CHEST,      MIM_VEST_L_FOOT,     MIM_VEST_R_FOOT,
                        MIM_VEST_HEAD,       MIM_VEST_L_SHOULDER, MIM_VEST_R_SHOULDER, MIM_VEST_HEAD,
                        MIM_VEST_L_UPPERARM, MIM_VEST_R_UPPERARM, MIM_VEST_L_FOREARM,  MIM_VEST_R_FOREARM,
                        MIM_VEST_L_HAND,     MIM_VEST_R_HAND,     MIM_VEST_L_HAND,     MIM_VEST_R_HAND};
    check(names, sizeof names / sizeof *names, want, 17);
}

static void test_other_schemes(void **state)
{
    (void)state;
    const case_t cases[] = {
        /* Poser / Biovision */
        {"lShldr", MIM_VEST_L_UPPERARM}, {"rForeArm", MIM_VEST_R_FOREARM}, {"lCollar", MIM_VEST_L_SHOULDER},
        {"rThigh", MIM_VEST_R_THIGH}, {"lShin", MIM_VEST_L_SHIN}, {"abdomen", MIM_VEST_CHEST},
        /* 3ds Max biped */
        {"Bip01 L Hand", MIM_VEST_L_HAND}, {"Bip01 R Calf", MIM_VEST_R_SHIN}, {"Bip01 L Clavicle", MIM_VEST_L_SHOULDER},
        {"Bip01 Pelvis", MIM_VEST_PELVIS}, {"Bip01 R UpperArm", MIM_VEST_R_UPPERARM},
        /* Blender / Rigify */
        {"thigh.L", MIM_VEST_L_THIGH}, {"shin.R", MIM_VEST_R_SHIN}, {"DEF-forearm.L", MIM_VEST_L_FOREARM},
        {"upper_arm.R", MIM_VEST_R_UPPERARM}, {"hand_l", MIM_VEST_L_HAND}, {"foot_r", MIM_VEST_R_FOOT},
        /* VRM / Unity humanoid */
        {"J_Bip_L_LowerArm", MIM_VEST_L_FOREARM}, {"LeftUpperLeg", MIM_VEST_L_THIGH}, {"RightLowerLeg", MIM_VEST_R_SHIN},
        {"UpperChest", MIM_VEST_CHEST},
        /* no body joint, or no side where one is needed */
        {"Armature", -1}, {"skirt_01", -1}, {"hair_front", -1}, {"", -1}, {"Hand", -1}, {"LeftEarring", -1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        int got = mim_vest_segment_of_joint(cases[i].name, 0);
        if (got != cases[i].segment) print_error("%s: %d, want %d\n", cases[i].name, got, cases[i].segment);
        assert_int_equal(got, cases[i].segment);
    }
    assert_int_equal(mim_vest_segment_of_joint(NULL, 0), -1);
    assert_int_equal(mim_vest_segment_of_joint("LeftShoulder", 0), MIM_VEST_L_SHOULDER);
    assert_int_equal(mim_vest_segment_of_joint("LeftShoulder", 1), MIM_VEST_L_UPPERARM);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mixamo),
        cmocka_unit_test(test_smpl),
        cmocka_unit_test(test_other_schemes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
