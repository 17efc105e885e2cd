/* Which way is up in a joint motion: head above feet, as its author stood
 * the rest pose, else as the person stands over the take. BVH does not say
 * (many exports are z up, mimic is y up). */
#include "mim_vest_motion.h"

#include <math.h>

#define REST_SHARE 0.8   /* of |head - feet|: the rest pose stands along one axis (cos 37 deg) */
#define FRAMES_AGREE 0.5 /* the frames' mean unit direction is at least this long: they agree */
#define FRAMES_SHARE 0.6 /* of its length along one axis */

static mim_vec3 head_over_feet(const float *p, int32_t head, int32_t fl, int32_t fr)
{
    const float *h = p + 3 * head, *a = p + 3 * fl, *b = p + 3 * fr;
    return mim_v3(h[0] - 0.5 * (a[0] + b[0]), h[1] - 0.5 * (a[1] + b[1]), h[2] - 0.5 * (a[2] + b[2]));
}

int mim_vest_joint_motion_up(const mim_vest_joint_motion_t *m, int32_t head, int32_t foot_l, int32_t foot_r,
                             int *from_rest)
{
    *from_rest = 0;
    if (!m || head < 0 || foot_l < 0 || foot_r < 0 || (uint32_t)head >= m->n_joints ||
        (uint32_t)foot_l >= m->n_joints || (uint32_t)foot_r >= m->n_joints)
        return 0;
    if (m->rest) {
        int up = mim_axis_snap(head_over_feet(m->rest, head, foot_l, foot_r), REST_SHARE);
        if (up) {
            *from_rest = 1;
            return up;
        }
    }
    mim_vec3 sum = mim_v3(0, 0, 0);
    for (uint32_t f = 0; f < m->n_frames; f++) {
        mim_vec3 v = head_over_feet(m->positions + (size_t)f * m->n_joints * 3, head, foot_l, foot_r);
        if (isfinite(v.x) && isfinite(v.y) && isfinite(v.z)) sum = mim_v3_add(sum, mim_v3_normalize(v));
    }
    if (!m->n_frames || !(mim_v3_norm(sum) >= FRAMES_AGREE * m->n_frames)) return 0;
    return mim_axis_snap(sum, FRAMES_SHARE);
}
