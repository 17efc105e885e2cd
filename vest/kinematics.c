/* Forward kinematics from sensor orientations to landmark positions, and the
 * grouping of decoded packets into whole vest frames.
 *
 * Segment s turns by R_s = Q_s T_s^-1 C_s: its tared reading Q_s (software
 * tare T_s) after the rest -> calibration rotation C_s. Pivots chain from the
 * pelvis, which stays where it is in the avatar (inertial sensors give no
 * translation; the pose descriptor of seed 000, sec. 3.2, uses angles between
 * landmark segments and does not need one): p_s = p_parent + R_parent j_s,
 * and landmark i on segment s is p_s + R_s o_i. A segment without a recent
 * reading, or below one, has unknown landmarks: they are NaN, not frozen. */
#include "mim_vest_decode.h"
#include "mim_vest_kinematics.h"

#include <math.h>
#include <string.h>

void mim_vest_state_reset(mim_vest_state_t *st)
{
    if (!st) return;
    memset(st, 0, sizeof *st);
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) st->q[s] = mim_quat_identity();
}

void mim_vest_state_update(mim_vest_state_t *st, const mim_vest_frame_t *f)
{
    if (!st || !f || f->sensor >= MIM_VEST_SEGMENTS) return;
    mim_quat q = {f->q[0], f->q[1], f->q[2], f->q[3]};
    st->q[f->sensor] = q;
    st->t_us[f->sensor] = f->t_us;
    st->seen[f->sensor] = 1;
}

/* R_s = Q_s T_s^-1 C_s (the header comment) */
static mim_quat segment_rotation(const mim_vest_rig_t *rig, const mim_quat q[MIM_VEST_SEGMENTS], uint32_t s)
{
    return mim_quat_normalize(mim_quat_mul(mim_quat_mul(q[s], rig->tare_inv[s]), rig->calib[s]));
}

void mim_vest_segment_rotations(const mim_vest_rig_t *rig, const mim_quat q[MIM_VEST_SEGMENTS], const uint8_t *have,
                                mim_quat R[MIM_VEST_SEGMENTS])
{
    for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++)
        R[s] = !have || have[s] ? segment_rotation(rig, q, s) : mim_quat_identity();
}

uint32_t mim_vest_rotations_fill(mim_quat R[MIM_VEST_SEGMENTS], const uint8_t have[MIM_VEST_SEGMENTS],
                                 int8_t from[MIM_VEST_SEGMENTS])
{
    int8_t src[MIM_VEST_SEGMENTS];
    uint32_t filled = 0;
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++) src[s] = have[s] ? (int8_t)s : -1;
    if (!have[MIM_VEST_PELVIS] && have[MIM_VEST_CHEST]) /* the pelvis has no parent: its child stands in */
        R[MIM_VEST_PELVIS] = R[MIM_VEST_CHEST], src[MIM_VEST_PELVIS] = MIM_VEST_CHEST, filled++;
    for (int s = 1; s < MIM_VEST_SEGMENTS; s++) { /* parents come first */
        int p = mim_vest_segment_parent((uint32_t)s);
        if (have[s] || src[p] < 0) continue;
        R[s] = R[p], src[s] = src[p], filled++;
    }
    if (from) memcpy(from, src, sizeof src);
    return filled;
}

uint32_t mim_vest_fk_orient(const mim_vest_rig_t *rig, const mim_quat q[MIM_VEST_SEGMENTS], const uint8_t *have,
                            float *xyz, uint8_t *present)
{
    mim_quat R[MIM_VEST_SEGMENTS];
    mim_vec3 P[MIM_VEST_SEGMENTS];
    uint8_t ok[MIM_VEST_SEGMENTS];
    for (uint32_t s = 0; s < MIM_VEST_SEGMENTS; s++) { /* parents come first */
        int p = mim_vest_segment_parent(s);
        ok[s] = (!have || have[s]) && (p < 0 || ok[p]);
        if (!ok[s]) continue;
        R[s] = segment_rotation(rig, q, s);
        P[s] = p < 0 ? rig->root : mim_v3_add(P[p], mim_quat_rotate(R[p], rig->joint[s]));
    }
    uint32_t n = 0;
    for (uint32_t i = 0; i < rig->n_landmarks; i++) {
        uint32_t s = rig->segment[i];
        if (s < MIM_VEST_SEGMENTS && ok[s]) {
            mim_vec3 v = mim_v3_add(P[s], mim_quat_rotate(R[s], rig->offset[i]));
            xyz[3 * i] = (float)v.x, xyz[3 * i + 1] = (float)v.y, xyz[3 * i + 2] = (float)v.z;
            if (present) present[i] = 1;
            n++;
        } else {
            xyz[3 * i] = xyz[3 * i + 1] = xyz[3 * i + 2] = NAN;
            if (present) present[i] = 0;
        }
    }
    return n;
}

uint32_t mim_vest_fk(const mim_vest_rig_t *rig, const mim_vest_state_t *st, uint64_t now_us, uint64_t timeout_us,
                     float *xyz, uint8_t *present)
{
    uint8_t have[MIM_VEST_SEGMENTS];
    mim_vest_fresh(st, now_us, timeout_us, have);
    return mim_vest_fk_orient(rig, st->q, have, xyz, present);
}

void mim_vest_fresh(const mim_vest_state_t *st, uint64_t now_us, uint64_t timeout_us, uint8_t have[MIM_VEST_SEGMENTS])
{
    if (!timeout_us) timeout_us = MIM_VEST_TIMEOUT_US_DEFAULT;
    for (int s = 0; s < MIM_VEST_SEGMENTS; s++)
        have[s] = st->seen[s] && (st->t_us[s] >= now_us || now_us - st->t_us[s] <= timeout_us);
}

int mim_vest_assembler_push(mim_vest_assembler_t *a, const mim_vest_packet_info_t *info, uint64_t t_done[2],
                            uint64_t mask[2])
{
    int n = 0;
    if (a->open && info->t_us < a->t_us) return 0; /* a late packet of a finished frame */
    if (a->open && info->t_us > a->t_us) {
        if (!a->done) t_done[n] = a->t_us, mask[n] = a->got, n++;
        a->expect = a->got; /* the next frame should carry the same sensors */
        a->open = 0;
    }
    if (!a->open) a->open = 1, a->t_us = info->t_us, a->got = 0, a->done = 0;
    a->got |= info->active;
    if (!a->done && a->expect && (a->got & a->expect) == a->expect) {
        t_done[n] = a->t_us, mask[n] = a->got, n++;
        a->done = 1;
    }
    return n;
}

int mim_vest_assembler_flush(mim_vest_assembler_t *a, uint64_t *t_done, uint64_t *mask)
{
    if (!a->open || a->done) return 0;
    *t_done = a->t_us, *mask = a->got;
    a->done = 1;
    return 1;
}
