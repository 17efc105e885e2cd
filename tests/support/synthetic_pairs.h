/* Synthetic pose-pairs for the sampler's and coverage's tests and benches:
 * two standing people posed at random by forward kinematics
 * (mim_pairs_pose_joints), so that nothing needs motion capture. */
#ifndef MIM_TEST_SYNTHETIC_PAIRS_H
#define MIM_TEST_SYNTHETIC_PAIRS_H

#include "mim_core.h"

/* Two people facing each other 1.2 m apart, standing (mim_sample_joint_names
 * order, metres, y up; B is A turned half a circle about y): 34 x 3. */
void sp_rest_pair(double *out);
/* The rest pair with every joint turned at random by up to `spread`
 * radians and B moved sideways by up to 0.1 m. */
void sp_random_pair(mim_rng_t *r, double spread, double *out);

#endif
