/* Synthetic pose-pairs (synthetic_pairs.h). */
#include "synthetic_pairs.h"

#include "mim_sample.h"
#include "mim_sample_mcmc.h"

/* A standing person (mim_sample_joint_names order), facing +z, metres. */
static const double person_rest[MIM_PAIR_PERSON_JOINTS][3] = {
    {0, 1.70, 0.02},  {0, 1.40, 0},    {0, 1.00, 0},     {0.19, 1.45, 0}, {-0.19, 1.45, 0}, {0.24, 1.17, 0},
    {-0.24, 1.17, 0}, {0.27, 0.92, 0.05}, {-0.27, 0.92, 0.05}, {0.10, 0.95, 0}, {-0.10, 0.95, 0}, {0.11, 0.52, 0.02},
    {-0.11, 0.52, 0.02}, {0.11, 0.08, 0}, {-0.11, 0.08, 0}, {0, 1.20, 0}, {0, 1.55, 0}};

void sp_rest_pair(double *out)
{
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++)
        for (int c = 0; c < 3; c++) {
            out[3 * k + c] = person_rest[k][c];
            out[3 * (MIM_PAIR_PERSON_JOINTS + k) + c] = person_rest[k][c] * (c == 1 ? 1 : -1) + (c == 2 ? 1.2 : 0);
        }
}

void sp_random_pair(mim_rng_t *r, double spread, double *out)
{
    double rest[3 * MIM_PAIR_JOINTS];
    sp_rest_pair(rest);
    mim_pairs_pose_t pose;
    mim_pairs_pose_rest(rest, &pose);
    for (int p = 0; p < 2; p++)
        for (int g = 1; g < MIM_PAIRS_ROT; g++) {
            mim_vec3 axis = mim_v3_normalize(mim_v3(mim_rng_gauss(r), mim_rng_gauss(r), mim_rng_gauss(r)));
            pose.rot[p][g] = mim_quat_axis_angle(axis, spread * mim_rng_unit(r));
        }
    pose.root[1][0] += 0.2 * (mim_rng_unit(r) - 0.5);
    mim_pairs_pose_joints(&pose, out);
}
