/* Small vector and quaternion math (Hamilton convention, unit quaternions). */
#include "mim_core.h"

#include <math.h>

double mim_v3_norm(mim_vec3 a) { return sqrt(mim_v3_dot(a, a)); }

mim_vec3 mim_v3_normalize(mim_vec3 a)
{
    double n = mim_v3_norm(a);
    return n > 0 ? mim_v3_scale(a, 1.0 / n) : a;
}

mim_quat mim_quat_identity(void)
{
    mim_quat q = {0, 0, 0, 1};
    return q;
}

mim_quat mim_quat_axis_angle(mim_vec3 axis, double radians)
{
    mim_vec3 a = mim_v3_normalize(axis);
    double s = sin(radians * 0.5);
    mim_quat q = {a.x * s, a.y * s, a.z * s, cos(radians * 0.5)};
    return q;
}

mim_quat mim_quat_mul(mim_quat a, mim_quat b)
{
    mim_quat r = {
        a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
        a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
        a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
    };
    return r;
}

mim_quat mim_quat_normalize(mim_quat q)
{
    double n = sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    if (n <= 0) return mim_quat_identity();
    mim_quat r = {q.x / n, q.y / n, q.z / n, q.w / n};
    return r;
}

mim_vec3 mim_quat_rotate(mim_quat q, mim_vec3 v)
{
    /* v' = v + 2w (u x v) + 2 u x (u x v), u = vector part */
    mim_vec3 u = {q.x, q.y, q.z};
    mim_vec3 t = mim_v3_scale(mim_v3_cross(u, v), 2.0);
    return mim_v3_add(mim_v3_add(v, mim_v3_scale(t, q.w)), mim_v3_cross(u, t));
}

mim_quat mim_quat_slerp(mim_quat a, mim_quat b, double t)
{
    double d = a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w;
    if (d < 0) { /* take the short way */
        b.x = -b.x; b.y = -b.y; b.z = -b.z; b.w = -b.w;
        d = -d;
    }
    double wa, wb;
    if (d > 0.9995) {
        wa = 1 - t;
        wb = t;
    } else {
        double th = acos(d), s = sin(th);
        wa = sin((1 - t) * th) / s;
        wb = sin(t * th) / s;
    }
    mim_quat r = {wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z, wa * a.w + wb * b.w};
    return mim_quat_normalize(r);
}
