/* Signed coordinate axes, for motion files whose up axis is not mimic's +y
 * (many BVH exports are z up): naming, snapping a direction to the nearest
 * axis, and the rotation that stands such a file upright. */
#include "mim_core.h"

#include <math.h>
#include <string.h>

int mim_axis_parse(const char *s, int *axis)
{
    if (!s) return -1;
    int sign = 1;
    if (*s == '+' || *s == '-') sign = *s++ == '-' ? -1 : 1;
    if (!s[0] || s[1]) return -1;
    const char *at = strchr("xyz", s[0] | 0x20);
    if (!at || !*at) return -1;
    *axis = sign * (int)(at - "xyz" + 1);
    return 0;
}

const char *mim_axis_name(int axis)
{
    static const char *const names[] = {"-z", "-y", "-x", "none", "+x", "+y", "+z"};
    return axis >= -3 && axis <= 3 ? names[axis + 3] : "none";
}

int mim_axis_snap(mim_vec3 v, double min_share)
{
    const double a[3] = {v.x, v.y, v.z}, n = mim_v3_norm(v);
    int k = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(a[i]) > fabs(a[k])) k = i;
    if (!(n > 0) || !(fabs(a[k]) >= min_share * n)) return 0;
    return a[k] > 0 ? k + 1 : -(k + 1);
}

/* The quarter or half turn about the axis normal to both `up` and +y
 * (about x for z and -y, about z for x): no other turn, so a file's
 * heading is kept where it can be. */
void mim_axis_stand_up(int up, double p[3])
{
    const double x = p[0], y = p[1], z = p[2];
    switch (up) {
    case 1: p[0] = -y, p[1] = x; break;          /* +x up: a quarter turn about z */
    case -1: p[0] = y, p[1] = -x; break;         /* -x up */
    case -2: p[1] = -y, p[2] = -z; break;        /* -y up: a half turn about x */
    case 3: p[1] = z, p[2] = -y; break;          /* +z up: a quarter turn about x */
    case -3: p[1] = -z, p[2] = y; break;         /* -z up */
    default: break;                              /* +y up (or none): as it is */
    }
}
