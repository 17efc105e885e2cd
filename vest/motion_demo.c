/* The built-in demo motion: a wearer who goes through eight poses that a
 * template store of mimic synth bodies also holds (rest, T, arms up, wave,
 * reach, squat, walk, bow), 1.5 s each with smooth transitions, so that
 * `mimic demo` and the tests can drive a simulated vest with no motion file
 * from outside. It is made as BVH text (Y up, the body's left +X, forward
 * +Z, a T-pose rest) and read by the ordinary BVH reader, so it takes the
 * same path as any user's motion. */
#include "mim_vest_motion.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Joints in hierarchy order; each has 3 channels Z X Y (the root 6). */
enum { HIPS, CHEST, HEAD, LCLAV, LARM, LFORE, LHAND, RCLAV, RARM, RFORE, RHAND, LTHIGH, LSHIN, LFOOT, RTHIGH,
       RSHIN, RFOOT, NJOINTS };
enum { Z, X, Y };

static const char hierarchy[] =
    "HIERARCHY\n"
    "ROOT Hips\n{\n\tOFFSET 0 96 0\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
    "\tJOINT Chest\n\t{\n\t\tOFFSET 0 24 0\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\tJOINT Head\n\t\t{\n\t\t\tOFFSET 0 32 0\n\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\tEnd Site\n\t\t\t{\n\t\t\t\tOFFSET 0 18 0\n\t\t\t}\n\t\t}\n"
    "\t\tJOINT LeftShoulder\n\t\t{\n\t\t\tOFFSET 4 26 0\n\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\tJOINT LeftArm\n\t\t\t{\n\t\t\t\tOFFSET 14 0 0\n\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\tJOINT LeftForeArm\n\t\t\t\t{\n\t\t\t\t\tOFFSET 29 0 0\n\t\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\t\tJOINT LeftHand\n\t\t\t\t\t{\n\t\t\t\t\t\tOFFSET 26 0 0\n"
    "\t\t\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\t\t\tEnd Site\n\t\t\t\t\t\t{\n\t\t\t\t\t\t\tOFFSET 16 0 0\n\t\t\t\t\t\t}\n"
    "\t\t\t\t\t}\n\t\t\t\t}\n\t\t\t}\n\t\t}\n"
    "\t\tJOINT RightShoulder\n\t\t{\n\t\t\tOFFSET -4 26 0\n\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\tJOINT RightArm\n\t\t\t{\n\t\t\t\tOFFSET -14 0 0\n\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\tJOINT RightForeArm\n\t\t\t\t{\n\t\t\t\t\tOFFSET -29 0 0\n\t\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\t\tJOINT RightHand\n\t\t\t\t\t{\n\t\t\t\t\t\tOFFSET -26 0 0\n"
    "\t\t\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\t\t\tEnd Site\n\t\t\t\t\t\t{\n\t\t\t\t\t\t\tOFFSET -16 0 0\n\t\t\t\t\t\t}\n"
    "\t\t\t\t\t}\n\t\t\t\t}\n\t\t\t}\n\t\t}\n\t}\n"
    "\tJOINT LeftUpLeg\n\t{\n\t\tOFFSET 10 -2 0\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\tJOINT LeftLeg\n\t\t{\n\t\t\tOFFSET 0 -44 0\n\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\tJOINT LeftFoot\n\t\t\t{\n\t\t\t\tOFFSET 0 -43 0\n\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\tEnd Site\n\t\t\t\t{\n\t\t\t\t\tOFFSET 0 -6 14\n\t\t\t\t}\n\t\t\t}\n\t\t}\n\t}\n"
    "\tJOINT RightUpLeg\n\t{\n\t\tOFFSET -10 -2 0\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\tJOINT RightLeg\n\t\t{\n\t\t\tOFFSET 0 -44 0\n\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\tJOINT RightFoot\n\t\t\t{\n\t\t\t\tOFFSET 0 -43 0\n\t\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\t\t\t\tEnd Site\n\t\t\t\t{\n\t\t\t\t\tOFFSET 0 -6 14\n\t\t\t\t}\n\t\t\t}\n\t\t}\n\t}\n}\n";

/* One key pose: (joint, channel, degrees) set, the rest 0 (the T-pose).
 * Signs follow the axes above: the left arm lies along +X, so Z+ raises
 * it and Y- swings it forward; the right arm mirrors; a leg's X- lifts it
 * forward and a shin's X+ bends the knee. */
typedef struct {
    signed char j, c;
    float deg;
} chan_t;
#define POSE_END {-1, 0, 0}
#define ARMS_DOWN {LARM, Z, -72}, {RARM, Z, 72}

static const chan_t poses[][16] = {
    {ARMS_DOWN, {LFORE, Y, -8}, {RFORE, Y, 8}, POSE_END},                                 /* rest */
    {POSE_END},                                                                            /* T */
    {{LARM, Z, 78}, {RARM, Z, -78}, {LCLAV, Z, 12}, {RCLAV, Z, -12}, {HEAD, X, -10}, POSE_END}, /* arms up */
    {{LARM, Z, -70}, {RARM, Z, -45}, {RFORE, Z, -80}, {HEAD, Y, -12}, POSE_END},          /* wave (right) */
    {{LARM, Y, -85}, {RARM, Y, 85}, {CHEST, X, 12}, {HEAD, X, 8}, POSE_END},               /* reach forward */
    {{HIPS, X, 18}, {LTHIGH, X, -95}, {RTHIGH, X, -95}, {LSHIN, X, 100}, {RSHIN, X, 100}, {LFOOT, X, -15},
     {RFOOT, X, -15}, {LARM, Y, -80}, {RARM, Y, 80}, POSE_END},                            /* squat */
    {ARMS_DOWN, POSE_END},                                                                 /* walk (+ cycle) */
    {{HIPS, X, 35}, {CHEST, X, 25}, {HEAD, X, 15}, {LTHIGH, X, -30}, {RTHIGH, X, -30}, ARMS_DOWN, POSE_END}, /* bow */
};
#define N_POSES (sizeof poses / sizeof poses[0])
#define WALK_POSE 6
#define WAVE_POSE 3
#define SECONDS_PER_POSE 1.5
#define FPS 30

static void pose_channels(size_t p, double ch[NJOINTS][3])
{
    memset(ch, 0, sizeof(double) * NJOINTS * 3);
    for (const chan_t *c = poses[p]; c->j >= 0; c++)
        ch[c->j][c->c] = c->deg;
}

/* The channels at time t: hold each pose for the first half of its slot,
 * ease into the next over the second half; the walk and the wave move on
 * top of their pose while it holds. */
static void channels_at(double t, double ch[NJOINTS][3])
{
    double slot = fmod(t / SECONDS_PER_POSE, (double)N_POSES);
    size_t p = (size_t)slot;
    double f = slot - (double)p, a[NJOINTS][3], b[NJOINTS][3];
    pose_channels(p, a);
    pose_channels((p + 1) % N_POSES, b);
    double s = f < 0.5 ? 0.0 : (f - 0.5) * 2.0;
    s = s * s * (3.0 - 2.0 * s); /* smoothstep */
    for (int j = 0; j < NJOINTS; j++)
        for (int c = 0; c < 3; c++)
            ch[j][c] = (1.0 - s) * a[j][c] + s * b[j][c];
    double hold = 1.0 - s, ph = 2.0 * M_PI * t / 0.9;
    if (p == WALK_POSE) {
        ch[LTHIGH][X] += hold * -25.0 * sin(ph), ch[RTHIGH][X] += hold * 25.0 * sin(ph);
        ch[LSHIN][X] += hold * (20.0 + 20.0 * cos(ph)), ch[RSHIN][X] += hold * (20.0 - 20.0 * cos(ph));
        ch[LARM][Y] += hold * 25.0 * sin(ph), ch[RARM][Y] += hold * 25.0 * sin(ph);
        ch[CHEST][Y] += hold * 6.0 * sin(ph);
    } else if (p == WAVE_POSE) {
        ch[RFORE][Z] += hold * 25.0 * sin(2.0 * ph);
    }
}

int mim_vest_motion_demo(mim_vest_motion_t *m, mim_error_t *err)
{
    const int frames = (int)(N_POSES * SECONDS_PER_POSE * FPS);
    const size_t per_line = (6 + 3 * (NJOINTS - 1)) * 12 + 2;
    size_t cap = sizeof hierarchy + 64 + (size_t)frames * per_line;
    char *text = malloc(cap);
    if (!text)
        return mim_error_set(err, MIM_ENOMEM, "out of memory for the demo motion");
    size_t n = (size_t)snprintf(text, cap, "%sMOTION\nFrames: %d\nFrame Time: %.6f\n", hierarchy, frames, 1.0 / FPS);
    for (int f = 0; f < frames && n < cap; f++) {
        double ch[NJOINTS][3];
        channels_at((double)f / FPS, ch);
        n += (size_t)snprintf(text + n, cap - n, "0 96 0");
        for (int j = 0; j < NJOINTS && n < cap; j++)
            n += (size_t)snprintf(text + n, cap - n, " %.3f %.3f %.3f", ch[j][Z], ch[j][X], ch[j][Y]);
        if (n < cap)
            n += (size_t)snprintf(text + n, cap - n, "\n");
    }
    int rc = n < cap ? mim_vest_motion_parse_bvh(m, text, n, "the demo motion", err)
                     : mim_error_set(err, MIM_ENOMEM, "demo motion: text buffer too small");
    free(text);
    return rc;
}
