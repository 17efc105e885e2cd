/* The small CMU-named skeleton the pairs tests write BVH takes with: joint,
 * parent, offset (units); a person about 30 units tall, so that the unit is
 * guessed as CMU's ASF unit (0.0254 / 0.45 m). Defined here, included by
 * each test that writes such takes. */
#ifndef MIM_TEST_CMU_SKELETON_H
#define MIM_TEST_CMU_SKELETON_H

static const struct { const char *name; int parent; double off[3]; } cmu_skel[] = {
    {"Hips", -1, {0, 0, 0}},          {"LeftUpLeg", 0, {1.5, -1, 0}},   {"LeftLeg", 1, {0, -7.5, 0}},
    {"LeftFoot", 2, {0, -7.5, 0}},    {"RightUpLeg", 0, {-1.5, -1, 0}}, {"RightLeg", 4, {0, -7.5, 0}},
    {"RightFoot", 5, {0, -7.5, 0}},   {"Spine", 0, {0, 2, 0}},          {"Spine1", 7, {0, 3, 0}},
    {"Neck", 8, {0, 3, 0}},           {"Head", 9, {0, 1.5, 0}},         {"LeftArm", 8, {3, 2.5, 0}},
    {"LeftForeArm", 11, {5, 0, 0}},   {"LeftHand", 12, {4.5, 0, 0}},    {"RightArm", 8, {-3, 2.5, 0}},
    {"RightForeArm", 14, {-5, 0, 0}}, {"RightHand", 15, {-4.5, 0, 0}},
};
#define CMU_SKEL_JOINTS ((int)(sizeof cmu_skel / sizeof *cmu_skel))

#endif
