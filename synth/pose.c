/* Poses: joint limits, the designed pose table, seeded random poses, forward
 * kinematics and linear blend skinning.
 *
 * A joint's rotation is given by three anatomical angles in degrees about
 * axes fixed in the rest frame (world axes at rest): q = R(flex) R(abd)
 * R(twist), twist applied first. Angles mean the same on both sides; a right
 * joint uses the mirror image of the left rotation (x -> -x: quaternion
 * (x, y, z, w) -> (x, -y, -z, w)). The rest pose is the A-pose, arms 45 deg
 * from vertical, so "abd" of the upper arm is measured from there.
 *
 * Joint limits (degrees, from the rest pose; after AAOS normal ranges of
 * motion, shoulder and hip ranges shared with the clavicle and pelvis):
 *
 *   joint      flex (axis)                 abd / lateral (axis)          twist (axis)
 *   pelvis     -20..50  forward tilt (+X)  -15..15 (-Z)                  -30..30 (+Y)
 *   spine      -20..40  bend forward (+X)  -20..20 to the left (-Z)      -25..25 (+Y)
 *   chest      -15..30                     -15..15                       -25..25
 *   neck       -35..40                     -25..25                       -45..45
 *   head       -25..25                     -15..15                       -30..30
 *   clavicle   -10..30  raise (+Z)         -15..25 forward (-Y)          none
 *   upper arm  -50..160 forward (-X)       -50..100 raise sideways (+Z)  -70..70 about the arm
 *   forearm      0..145 elbow flexion only (about arm x forward)         none
 *   hand       -70..80  palm-wards (-Z)    -25..30 thumb-wards            -60..60 about the arm
 *   thigh      -25..120 forward (-X)       -20..45 outwards (+Z)          -35..35 inwards (-Y)
 *   shin         0..140 knee flexion only, backwards (+X)                 none
 *   foot       -45..20  toes up (-X)       -20..25 sole inwards (-Z)      none
 *
 * The knee and the elbow have one axis each and a lower limit of 0: they
 * never bend sideways or hyperextend. Random poses draw every angle within
 * these limits (75% of each range, see RANDOM_SPAN). */
#include "synth_internal.h"

#include <math.h>
#include <string.h>

typedef struct {
    double lo, hi;
} range_t;

/* Random poses draw every angle uniformly from the limits scaled by this
 * towards the rest pose: all extremes at once are rarely human, and linear
 * blend skinning folds the skin in some of those combinations. */
#define RANDOM_SPAN 0.75

static const range_t limits[MIM__NJ][3] = {
    [MIM__J_PELVIS] = {{-20, 50}, {-15, 15}, {-30, 30}},
    [MIM__J_SPINE] = {{-20, 40}, {-20, 20}, {-25, 25}},
    [MIM__J_CHEST] = {{-15, 30}, {-15, 15}, {-25, 25}},
    [MIM__J_NECK] = {{-35, 40}, {-25, 25}, {-45, 45}},
    [MIM__J_HEAD] = {{-25, 25}, {-15, 15}, {-30, 30}},
    [MIM__J_LCLAV] = {{-10, 30}, {-15, 25}, {0, 0}},
    [MIM__J_RCLAV] = {{-10, 30}, {-15, 25}, {0, 0}},
    [MIM__J_LUARM] = {{-50, 160}, {-50, 100}, {-70, 70}},
    [MIM__J_RUARM] = {{-50, 160}, {-50, 100}, {-70, 70}},
    [MIM__J_LFARM] = {{0, 145}, {0, 0}, {0, 0}},
    [MIM__J_RFARM] = {{0, 145}, {0, 0}, {0, 0}},
    [MIM__J_LHAND] = {{-70, 80}, {-25, 30}, {-60, 60}},
    [MIM__J_RHAND] = {{-70, 80}, {-25, 30}, {-60, 60}},
    [MIM__J_LTHIGH] = {{-25, 120}, {-20, 45}, {-35, 35}},
    [MIM__J_RTHIGH] = {{-25, 120}, {-20, 45}, {-35, 35}},
    [MIM__J_LSHIN] = {{0, 140}, {0, 0}, {0, 0}},
    [MIM__J_RSHIN] = {{0, 140}, {0, 0}, {0, 0}},
    [MIM__J_LFOOT] = {{-45, 20}, {-20, 25}, {0, 0}},
    [MIM__J_RFOOT] = {{-45, 20}, {-20, 25}, {0, 0}},
};

/* Axes of the left / midline joints in the rest frame (flex, abd, twist). */
static void joint_axes(int j, mim_vec3 ax[3])
{
    mim_vec3 X = mim_v3(1, 0, 0), Y = mim_v3(0, 1, 0), Z = mim_v3(0, 0, 1);
    mim_vec3 d = mim__arm_dir(), lat = mim__arm_lat();
    mim_vec3 elbow = mim_v3_scale(lat, -1); /* d x Z: forearm moves forwards */
    switch (j) {
    case MIM__J_PELVIS: case MIM__J_SPINE: case MIM__J_CHEST: case MIM__J_NECK: case MIM__J_HEAD:
        ax[0] = X, ax[1] = mim_v3(0, 0, -1), ax[2] = Y;
        break;
    case MIM__J_LCLAV: case MIM__J_RCLAV:
        ax[0] = Z, ax[1] = mim_v3(0, -1, 0), ax[2] = X;
        break;
    case MIM__J_LUARM: case MIM__J_RUARM:
        ax[0] = mim_v3(-1, 0, 0), ax[1] = Z, ax[2] = d;
        break;
    case MIM__J_LFARM: case MIM__J_RFARM:
        ax[0] = elbow, ax[1] = Z, ax[2] = d;
        break;
    case MIM__J_LHAND: case MIM__J_RHAND:
        ax[0] = mim_v3(0, 0, -1), ax[1] = elbow, ax[2] = d;
        break;
    case MIM__J_LTHIGH: case MIM__J_RTHIGH:
        ax[0] = mim_v3(-1, 0, 0), ax[1] = Z, ax[2] = mim_v3(0, -1, 0);
        break;
    case MIM__J_LSHIN: case MIM__J_RSHIN:
        ax[0] = X, ax[1] = Z, ax[2] = Y;
        break;
    default: /* feet */
        ax[0] = mim_v3(-1, 0, 0), ax[1] = mim_v3(0, 0, -1), ax[2] = Y;
        break;
    }
}

static int is_right(int j)
{
    return j == MIM__J_RCLAV || j == MIM__J_RUARM || j == MIM__J_RFARM || j == MIM__J_RHAND ||
           j == MIM__J_RTHIGH || j == MIM__J_RSHIN || j == MIM__J_RFOOT;
}

void mim__pose_quats(const double deg[MIM__NJ][3], mim_quat q[MIM__NJ])
{
    for (int j = 0; j < MIM__NJ; j++) {
        mim_vec3 ax[3];
        joint_axes(j, ax);
        mim_quat r[3];
        for (int k = 0; k < 3; k++) r[k] = mim_quat_axis_angle(ax[k], deg[j][k] * M_PI / 180.0);
        mim_quat t = mim_quat_normalize(mim_quat_mul(r[0], mim_quat_mul(r[1], r[2])));
        if (is_right(j)) t.y = -t.y, t.z = -t.z;
        q[j] = t;
    }
}

/* ---- the designed poses: (joint, axis, degrees) triples; both sides are
 * listed where both move. Pose p in 1..11 is the same for every subject. */
typedef struct {
    uint8_t j, k;
    float deg;
} set_t;
#define L_R(jl, k, d) {MIM__J_L##jl, k, d}, {MIM__J_R##jl, k, d}
#define END {255, 0, 0}

static const char *const names[MIM__POSE_TABLE] = {
    "rest", "tpose", "arms_up", "walk", "squat", "sit", "kick", "wave", "reach", "lunge", "bow", "guard",
};

static const set_t table[MIM__POSE_TABLE][24] = {
    {END}, /* rest: identity */
    {L_R(UARM, 1, 45), END},                                               /* tpose: arms level */
    {L_R(CLAV, 0, 25), L_R(UARM, 1, 95), L_R(FARM, 0, 10), {MIM__J_HEAD, 0, -12}, END}, /* arms up */
    {{MIM__J_LTHIGH, 0, 28}, {MIM__J_RTHIGH, 0, -18}, {MIM__J_LSHIN, 0, 12}, {MIM__J_RSHIN, 0, 35},
     {MIM__J_LFOOT, 0, 8}, {MIM__J_RFOOT, 0, -15}, {MIM__J_LUARM, 1, -38}, {MIM__J_LUARM, 0, -25},
     {MIM__J_RUARM, 1, -38}, {MIM__J_RUARM, 0, 30}, {MIM__J_LFARM, 0, 15}, {MIM__J_RFARM, 0, 35},
     {MIM__J_CHEST, 2, 8}, END},                                                           /* walk */
    {{MIM__J_PELVIS, 0, 25}, {MIM__J_SPINE, 0, 15}, L_R(THIGH, 0, 105), L_R(THIGH, 1, 10), L_R(SHIN, 0, 110),
     L_R(FOOT, 0, 18), L_R(UARM, 1, -45), L_R(UARM, 0, 80), L_R(FARM, 0, 10), {MIM__J_HEAD, 0, -15}, END}, /* squat */
    {L_R(THIGH, 0, 90), L_R(SHIN, 0, 90), {MIM__J_SPINE, 0, 5}, L_R(UARM, 1, -40), L_R(UARM, 0, 35),
     L_R(FARM, 0, 60), END},                                                               /* sit */
    {{MIM__J_LTHIGH, 0, 85}, {MIM__J_LSHIN, 0, 15}, {MIM__J_LFOOT, 0, -30}, {MIM__J_RSHIN, 0, 10},
     {MIM__J_PELVIS, 0, -10}, {MIM__J_SPINE, 0, -10}, {MIM__J_LUARM, 1, 15}, {MIM__J_LUARM, 0, -20},
     {MIM__J_RUARM, 1, 15}, {MIM__J_RUARM, 0, 30}, L_R(FARM, 0, 70), END},                 /* kick */
    {{MIM__J_RUARM, 1, 50}, {MIM__J_RUARM, 0, 10}, {MIM__J_RUARM, 2, -70}, {MIM__J_RFARM, 0, 95}, {MIM__J_RHAND, 1, 15},
     {MIM__J_LUARM, 1, -38}, {MIM__J_NECK, 1, -8}, {MIM__J_HEAD, 2, -15}, END},            /* wave (right hand) */
    {L_R(UARM, 1, -45), L_R(UARM, 0, 95), L_R(FARM, 0, 5), L_R(CLAV, 1, 15), {MIM__J_SPINE, 0, 15},
     {MIM__J_CHEST, 0, 10}, {MIM__J_HEAD, 0, -10}, END},                                   /* reach forward */
    {{MIM__J_PELVIS, 0, 10}, {MIM__J_LTHIGH, 0, 80}, {MIM__J_LSHIN, 0, 85}, {MIM__J_LFOOT, 0, 10},
     {MIM__J_RTHIGH, 0, -25}, {MIM__J_RSHIN, 0, 25}, {MIM__J_RFOOT, 0, -20}, {MIM__J_SPINE, 0, -10},
     L_R(UARM, 1, -20), L_R(UARM, 0, -25), L_R(UARM, 2, 30), L_R(FARM, 0, 100), END},      /* lunge, hands on hips */
    {{MIM__J_PELVIS, 0, 40}, L_R(THIGH, 0, 40), {MIM__J_SPINE, 0, 25}, {MIM__J_CHEST, 0, 15},
     {MIM__J_NECK, 0, 20}, L_R(UARM, 1, -42), L_R(UARM, 0, 70), END},                      /* bow */
    {L_R(THIGH, 0, 20), {MIM__J_LTHIGH, 0, 30}, L_R(SHIN, 0, 30), L_R(FOOT, 0, 10), {MIM__J_CHEST, 2, -15},
     L_R(UARM, 1, -30), L_R(UARM, 0, 50), L_R(UARM, 2, 20), L_R(FARM, 0, 130), {MIM__J_HEAD, 0, 10}, END}, /* guard */
};

const char *mim__pose_table_name(uint32_t pose) { return pose < MIM__POSE_TABLE ? names[pose] : NULL; }

void mim__pose_angles(uint32_t pose, uint64_t seed, double deg[MIM__NJ][3])
{
    memset(deg, 0, sizeof(double) * MIM__NJ * 3);
    if (pose < MIM__POSE_TABLE) {
        /* later entries for the same joint and axis replace earlier ones */
        for (const set_t *s = table[pose]; s->j != 255; s++) deg[s->j][s->k] = s->deg;
        return;
    }
    mim_rng_t r;
    mim_rng_seed(&r, seed, 0x9053000000ULL + pose);
    for (int j = 0; j < MIM__NJ; j++)
        for (int k = 0; k < 3; k++) {
            double u = mim_rng_unit(&r);
            double lo = RANDOM_SPAN * limits[j][k].lo, hi = RANDOM_SPAN * limits[j][k].hi;
            deg[j][k] = lo + (hi - lo) * u;
        }
}

void mim__fk(const mim__skeleton_t *sk, const mim_quat q[MIM__NJ], mim_quat G[MIM__NJ], mim_vec3 P[MIM__NJ])
{
    for (int j = 0; j < MIM__NJ; j++) {
        int p = mim__joint_parent[j];
        if (p < 0) {
            G[j] = q[j];
            P[j] = sk->j[j];
        } else {
            G[j] = mim_quat_normalize(mim_quat_mul(G[p], q[j]));
            P[j] = mim_v3_add(P[p], mim_quat_rotate(G[p], mim_v3_sub(sk->j[j], sk->j[p])));
        }
    }
}

void mim__lbs(const mim__skeleton_t *sk, const mim_quat qj[MIM__NJ], const mim_quat G[MIM__NJ],
              const mim_vec3 P[MIM__NJ], uint32_t n, const double *rest, const uint8_t *wj, const float *ww,
              double *out)
{
    /* bone b: x' = R_b x + (P_j - R_b rest_j), pivot j = the joint itself or
     * the joint a helper belongs to; a helper turns by parent * q_j^(k/HK) */
    double M[MIM__NB][12];
    for (int b = 0; b < MIM__NB; b++) {
        int j = b;
        mim_quat q;
        if (b < MIM__NJ) {
            q = G[b];
        } else {
            j = (b - MIM__NJ) / (MIM__HK - 1);
            int k = (b - MIM__NJ) % (MIM__HK - 1) + 1, p = mim__joint_parent[j];
            mim_quat part = mim_quat_slerp(mim_quat_identity(), qj[j], (double)k / MIM__HK);
            q = p < 0 ? part : mim_quat_normalize(mim_quat_mul(G[p], part));
        }
        double xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z, xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z,
               wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
        double *m = M[b];
        m[0] = 1 - 2 * (yy + zz), m[1] = 2 * (xy - wz), m[2] = 2 * (xz + wy);
        m[4] = 2 * (xy + wz), m[5] = 1 - 2 * (xx + zz), m[6] = 2 * (yz - wx);
        m[8] = 2 * (xz - wy), m[9] = 2 * (yz + wx), m[10] = 1 - 2 * (xx + yy);
        mim_vec3 r = sk->j[j];
        m[3] = P[j].x - (m[0] * r.x + m[1] * r.y + m[2] * r.z);
        m[7] = P[j].y - (m[4] * r.x + m[5] * r.y + m[6] * r.z);
        m[11] = P[j].z - (m[8] * r.x + m[9] * r.y + m[10] * r.z);
    }
    for (uint32_t i = 0; i < n; i++) {
        double B[12] = {0};
        for (int k = 0; k < MIM__NW; k++) {
            double w = ww[(size_t)MIM__NW * i + k];
            if (w == 0) continue;
            const double *m = M[wj[(size_t)MIM__NW * i + k]];
            for (int t = 0; t < 12; t++) B[t] += w * m[t];
        }
        const double *x = rest + 3 * (size_t)i;
        double *o = out + 3 * (size_t)i;
        o[0] = B[0] * x[0] + B[1] * x[1] + B[2] * x[2] + B[3];
        o[1] = B[4] * x[0] + B[5] * x[1] + B[6] * x[2] + B[7];
        o[2] = B[8] * x[0] + B[9] * x[1] + B[10] * x[2] + B[11];
    }
}

#define IMITATION_LOOSE_ONES 4     /* one (subject, pose) in this many */
#define IMITATION_LOOSE_SCALE 1.9 /* is this much looser */
void mim__pose_imitate(uint32_t subject, uint32_t pose, uint64_t seed, double sigma_deg, double deg[MIM__NJ][3])
{
    if (!(sigma_deg > 0)) return; /* the rest too: nobody stands in a designed A-pose exactly */
    mim_rng_t r;
    mim_rng_seed(&r, seed, 0x1A17A7E000000ULL + ((uint64_t)subject << 24) + pose);
    /* one in IMITATION_LOOSE_ONES takes a pose more loosely, by
     * IMITATION_LOOSE_SCALE (the tail real people show: their p90 is 1.6
     * times their rms, where a Gaussian's is 1.2) */
    const double scale = mim_rng_unit(&r) * IMITATION_LOOSE_ONES < 1 ? IMITATION_LOOSE_SCALE : 1.0;
    for (int j = 0; j < MIM__NJ; j++)
        for (int k = 0; k < 3; k++) {
            const range_t *l = &limits[j][k];
            double g = mim_rng_gauss(&r); /* drawn for every axis: a locked one must not shift the others' */
            if (l->lo == l->hi) continue;
            deg[j][k] = fmin(l->hi, fmax(l->lo, deg[j][k] + scale * sigma_deg * g));
        }
}
