/* bvh_turn.h: a BVH turned by a signed permutation P (a proper rotation).
 * OFFSET o becomes P o. A channel about (or along) axis a holding v becomes
 * one about axis b holding s v, where P e_a = s e_b: the same slot in the
 * frame lines, a new label. Forward kinematics then gives P p for every
 * joint p, since P R(a, v) P^T = R(P e_a, v). */
#include "bvh_turn.h"

#include "test_support.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CHANNELS 4096

/* P e_a = sign[a] e_to[a], for a = x, y, z */
typedef struct { int to[3], sign[3]; } perm_t;

static perm_t lay_down(int up)
{
    switch (up) {
    case 3: return (perm_t){{0, 2, 1}, {1, 1, -1}};   /* (x, y, z) -> (x, -z, y): +y to +z */
    case -3: return (perm_t){{0, 2, 1}, {1, -1, 1}};  /* (x, z, -y): +y to -z */
    case 1: return (perm_t){{1, 0, 2}, {-1, 1, 1}};   /* (y, -x, z): +y to +x */
    case -1: return (perm_t){{1, 0, 2}, {1, -1, 1}};  /* (-y, x, z): +y to -x */
    case -2: return (perm_t){{0, 1, 2}, {1, -1, -1}}; /* (x, -y, -z) */
    default: return (perm_t){{0, 1, 2}, {1, 1, 1}};
    }
}

static void grow(char **b, size_t *n, size_t *cap, const char *s)
{
    size_t l = strlen(s);
    while (*n + l + 1 > *cap) *b = realloc(*b, *cap = *cap ? 2 * *cap : 1 << 16);
    memcpy(*b + *n, s, l + 1);
    *n += l;
}

char *bt_turn(const char *bvh, int up)
{
    const perm_t P = lay_down(up);
    static int axis_of[MAX_CHANNELS];
    int n_ch = 0, in_motion = 0;
    char *out = NULL, line[1 << 15], buf[1 << 16];
    size_t n = 0, cap = 0;
    const char *p = bvh;
    while (*p) {
        const char *e = strchr(p, '\n');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        assert_true(len < sizeof line);
        memcpy(line, p, len), line[len] = 0;
        p += len + (e ? 1 : 0);
        const char *t = line + strspn(line, " \t");
        double v[3];
        if (!in_motion && !strncmp(t, "OFFSET", 6) && sscanf(t + 6, "%lf %lf %lf", &v[0], &v[1], &v[2]) == 3) {
            double w[3];
            for (int a = 0; a < 3; a++) w[P.to[a]] = P.sign[a] * v[a];
            snprintf(buf, sizeof buf, "%.*sOFFSET %.17g %.17g %.17g\n", (int)(t - line), line, w[0], w[1], w[2]);
        } else if (!in_motion && !strncmp(t, "CHANNELS", 8)) {
            int k = 0, used = 0;
            assert_int_equal(sscanf(t + 8, "%d%n", &k, &used), 1);
            const char *q = t + 8 + used;
            int m = snprintf(buf, sizeof buf, "%.*sCHANNELS %d", (int)(t - line), line, k);
            for (int i = 0; i < k; i++) {
                char name[32];
                int u = 0;
                assert_int_equal(sscanf(q, "%31s%n", name, &u), 1);
                q += u;
                int a = (name[0] | 0x20) - 'x';
                assert_true(a >= 0 && a < 3 && n_ch < MAX_CHANNELS);
                axis_of[n_ch++] = a;
                m += snprintf(buf + m, sizeof buf - (size_t)m, " %c%s", "XYZ"[P.to[a]], name + 1);
            }
            snprintf(buf + m, sizeof buf - (size_t)m, "\n");
        } else if (!in_motion) {
            snprintf(buf, sizeof buf, "%s\n", line);
            if (!strncmp(t, "Frame Time", 10)) in_motion = 1;
        } else { /* a frame: the same slots, values signed */
            int m = 0, used = 0;
            const char *q = line;
            double x;
            for (int i = 0; i < n_ch; i++) {
                assert_int_equal(sscanf(q, "%lf%n", &x, &used), 1);
                q += used;
                m += snprintf(buf + m, sizeof buf - (size_t)m, "%s%.17g", i ? " " : "", P.sign[axis_of[i]] * x);
            }
            snprintf(buf + m, sizeof buf - (size_t)m, "\n");
        }
        grow(&out, &n, &cap, buf);
    }
    return out;
}
