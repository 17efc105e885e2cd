/* The penetration term of seed 002's physical prior (eq. 2, eta): the sum
 * of the penetration depths between the bones of a pose-pair, each bone a
 * capsule, as the paper measures them with the Open Dynamics Engine.
 *
 * ODE keeps process-wide state (dInitODE2 may be called once until
 * dCloseODE): a library must not own it, so the program initialises ODE
 * once before the first context (mimic's main does) and each thread opens
 * its own context (dAllocateODEDataForThread, and its own geoms).
 *
 * Bones and radii (the paper's rigged models are not given): per person
 * the spine in three pieces (pelvis-spine, spine-chest, chest-neck, radius
 * 0.12 m), the head (neck to head, 0.10 m, extended by its radius), the
 * clavicles (chest to shoulder, 0.04), upper arms (0.05), forearms
 * (0.04), the pelvis to each hip (0.08), thighs (0.07) and shins (0.05).
 * Pairs counted: every bone of A against every bone of B, and within a
 * person every two bones that neither meet at a joint nor are joined by a
 * third (a forearm through the torso); those touch by construction.
 *
 * The capsules are coarse (an arm hanging by the body overlaps the lowest
 * spine piece's capsule in natural poses), so eta may be measured beyond
 * an allowance per pair of bones: the deepest penetration that pair shows
 * in the prior motions (mim_penetration_learn). */
#include "mim_sample.h"

#include <ode/ode.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* joint indices (mim_sample_joint_names) */
enum { HEAD, CHEST, PELVIS, LSH, RSH, LEL, REL, LWR, RWR, LHIP, RHIP, LKN, RKN, LAN, RAN, SPINE, NECK };
static const struct { uint8_t a, b; float r; } bones[] = {
    {PELVIS, SPINE, 0.12f}, {SPINE, CHEST, 0.12f}, {CHEST, NECK, 0.12f}, {NECK, HEAD, 0.10f},
    {CHEST, LSH, 0.04f},    {CHEST, RSH, 0.04f},   {LSH, LEL, 0.05f},    {RSH, REL, 0.05f},
    {LEL, LWR, 0.04f},      {REL, RWR, 0.04f},     {PELVIS, LHIP, 0.08f}, {PELVIS, RHIP, 0.08f},
    {LHIP, LKN, 0.07f},     {RHIP, RKN, 0.07f},    {LKN, LAN, 0.05f},    {RKN, RAN, 0.05f},
};
#define NB ((int)(sizeof bones / sizeof *bones))
_Static_assert(sizeof bones / sizeof *bones * 2 * sizeof bones / sizeof *bones == MIM_PENETRATION_ALLOWANCES,
               "the allowances are 2 x NB x NB");

struct mim_penetration {
    dGeomID probe[2];      /* two capsules for mim_penetration_capsules */
    dGeomID geom[2 * NB];  /* person A's bones, then B's */
};

int mim_penetration_open(mim_penetration_t **out, mim_error_t *err)
{
    *out = NULL;
    if (!dAllocateODEDataForThread(dAllocateMaskAll))
        return mim_error_set(err, MIM_EUNSUPPORTED, "penetration: ODE has no data for this thread (is ODE initialised?)");
    mim_penetration_t *p = calloc(1, sizeof *p);
    if (!p) return mim_error_set(err, MIM_ENOMEM, "penetration: out of memory");
    for (int k = 0; k < 2; k++) p->probe[k] = dCreateCapsule(0, 0.1, 0.1);
    for (int k = 0; k < 2 * NB; k++) p->geom[k] = dCreateCapsule(0, bones[k % NB].r, 0.1);
    *out = p;
    return 0;
}

void mim_penetration_close(mim_penetration_t **pp)
{
    if (!pp || !*pp) return;
    mim_penetration_t *p = *pp;
    for (int k = 0; k < 2; k++) dGeomDestroy(p->probe[k]);
    for (int k = 0; k < 2 * NB; k++) dGeomDestroy(p->geom[k]);
    free(p);
    *pp = NULL;
}

/* Places capsule g (radius r) from a to b: ODE's capsule lies along its
 * local z, centred, its length without the caps. */
static void place(dGeomID g, const double a[3], const double b[3], double r)
{
    double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    dGeomCapsuleSetParams(g, r, len > 1e-6 ? len : 1e-6);
    dGeomSetPosition(g, 0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2]));
    /* a rotation taking z to d: the shortest arc */
    mim_vec3 z = mim_v3(0, 0, 1), u = len > 1e-9 ? mim_v3(d[0] / len, d[1] / len, d[2] / len) : z;
    mim_vec3 axis = mim_v3_cross(z, u);
    double s = mim_v3_norm(axis), c = mim_v3_dot(z, u);
    mim_quat q = s > 1e-12 ? mim_quat_axis_angle(mim_v3_scale(axis, 1.0 / s), atan2(s, c))
                           : (c > 0 ? mim_quat_identity() : mim_quat_axis_angle(mim_v3(1, 0, 0), M_PI));
    dQuaternion dq = {q.w, q.x, q.y, q.z};
    dGeomSetQuaternion(g, dq);
}

static int joined(int a, int b)
{
    if (a == b) return 1;
    for (int k = 0; k < NB; k++)
        if ((bones[k].a == a && bones[k].b == b) || (bones[k].a == b && bones[k].b == a)) return 1;
    return 0;
}

/* Two bones of one person that meet at a joint, or whose ends one bone
 * joins (a thigh and the lowest spine piece, through the pelvis), touch by
 * construction: their capsules overlap in any pose. */
static int near_bones(int i, int j)
{
    return joined(bones[i].a, bones[j].a) || joined(bones[i].a, bones[j].b) || joined(bones[i].b, bones[j].a) ||
           joined(bones[i].b, bones[j].b);
}

static double depth(dGeomID a, dGeomID b)
{
    dContactGeom c[4];
    int n = dCollide(a, b, 4, c, sizeof c[0]);
    double best = 0;
    for (int i = 0; i < n; i++)
        if (c[i].depth > best) best = c[i].depth;
    return best;
}

double mim_penetration_capsules(mim_penetration_t *p, const double a0[3], const double a1[3], double ra,
                                const double b0[3], const double b1[3], double rb)
{
    place(p->probe[0], a0, a1, ra);
    place(p->probe[1], b0, b1, rb);
    return depth(p->probe[0], p->probe[1]);
}

/* Pair k's bones (k over i < j of the 2 x NB bones) and whether it counts. */
static int pair_counts(int i, int j)
{
    int same = (i < NB) == (j < NB);
    return !(same && near_bones(i % NB, j % NB));
}

/* Where pair (i, j) keeps its allowance: one entry per unordered pair of
 * bone kinds, within a person or across the two (the two people share it,
 * so that what A shows, B may do). */
static int allowance_index(int i, int j)
{
    int same = (i < NB) == (j < NB), a = i % NB, b = j % NB;
    if (a > b) {
        int t = a;
        a = b, b = t;
    }
    return (same ? 0 : NB * NB) + a * NB + b;
}

static void place_all(mim_penetration_t *p, const double *joints)
{
    for (int k = 0; k < 2 * NB; k++) {
        const double *base = joints + (k < NB ? 0 : 3 * MIM_PAIR_PERSON_JOINTS);
        place(p->geom[k], base + 3 * bones[k % NB].a, base + 3 * bones[k % NB].b, bones[k % NB].r);
    }
}

double mim_penetration_pair(mim_penetration_t *p, const double *joints, const double *allowed)
{
    place_all(p, joints);
    double eta = 0;
    for (int i = 0; i < 2 * NB; i++)
        for (int j = i + 1; j < 2 * NB; j++) {
            if (!pair_counts(i, j)) continue;
            double d = depth(p->geom[i], p->geom[j]) - (allowed ? allowed[allowance_index(i, j)] : 0.0);
            if (d > 0) eta += d;
        }
    return eta;
}

void mim_penetration_learn(mim_penetration_t *p, const double *joints, double *allowed)
{
    place_all(p, joints);
    for (int i = 0; i < 2 * NB; i++)
        for (int j = i + 1; j < 2 * NB; j++) {
            if (!pair_counts(i, j)) continue;
            double d = depth(p->geom[i], p->geom[j]);
            double *a = &allowed[allowance_index(i, j)];
            if (d > *a) *a = d;
        }
}
