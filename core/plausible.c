/* Plausibility: what a body mesh and a landmark skeleton can be, stated once
 * (the limits are in mim_core.h, docs/reference.md repeats them). Readers and the
 * landmark parser accept any finite numbers; these checks turn away what no
 * body gives (every vertex at one point, a coordinate of 3e38, 16 landmarks
 * at one point) with one line that says which vertex or landmark and why,
 * before it reaches the store, the descriptor or the solver. One pass over
 * the positions; the culprit is looked for only once a check has failed. */
#include "mim_core.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    double lo[3], hi[3];
    uint32_t count;       /* positions looked at (present landmarks) */
    int64_t nonfinite;    /* first non-finite one, or -1 */
    int nonfinite_axis;
} extent_t;

static void extent_of(const float *pos, const uint8_t *present, uint32_t n, extent_t *e)
{
    /* float min/max without branches, and one flag for a non-finite
     * coordinate (NaN fails every comparison): the common case, a good
     * mesh, costs one quick pass; the first bad coordinate is looked for
     * only when the flag is up. */
    float lx = INFINITY, ly = INFINITY, lz = INFINITY, hx = -INFINITY, hy = -INFINITY, hz = -INFINITY;
    int bad = 0;
    uint32_t count = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (present && !present[i])
            continue;
        const float x = pos[3 * (size_t)i], y = pos[3 * (size_t)i + 1], z = pos[3 * (size_t)i + 2];
        bad |= !(fabsf(x) <= FLT_MAX) | !(fabsf(y) <= FLT_MAX) | !(fabsf(z) <= FLT_MAX);
        lx = x < lx ? x : lx, ly = y < ly ? y : ly, lz = z < lz ? z : lz;
        hx = x > hx ? x : hx, hy = y > hy ? y : hy, hz = z > hz ? z : hz;
        count++;
    }
    e->count = count;
    e->nonfinite = -1;
    e->nonfinite_axis = 0;
    e->lo[0] = lx, e->lo[1] = ly, e->lo[2] = lz;
    e->hi[0] = hx, e->hi[1] = hy, e->hi[2] = hz;
    for (uint32_t i = 0; bad && i < n; i++) {
        if (present && !present[i])
            continue;
        for (int a = 0; a < 3; a++)
            if (!isfinite(pos[3 * (size_t)i + (size_t)a])) {
                e->nonfinite = i, e->nonfinite_axis = a;
                return;
            }
    }
}

/* The axis along which the positions spread the most, and that spread. */
static int widest_axis(const extent_t *e, double *span)
{
    int w = 0;
    double best = -1;
    for (int a = 0; a < 3; a++) {
        double s = e->hi[a] - e->lo[a];
        if (s > best)
            best = s, w = a;
    }
    *span = best < 0 ? 0 : best;
    return w;
}

/* Along axis a, the position farthest from the mean: the outlier that makes
 * the spread too wide (a coordinate of 3e38 among a body's). */
static uint32_t farthest_from_mean(const float *pos, const uint8_t *present, uint32_t n, int a)
{
    double sum = 0;
    uint32_t m = 0;
    for (uint32_t i = 0; i < n; i++)
        if (!present || present[i])
            sum += pos[3 * (size_t)i + (size_t)a], m++;
    double mean = m ? sum / m : 0, best = -1;
    uint32_t at = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (present && !present[i])
            continue;
        double d = fabs(pos[3 * (size_t)i + (size_t)a] - mean);
        if (d > best)
            best = d, at = i;
    }
    return at;
}

/* The first position with a coordinate farther than MIM_PLAUSIBLE_REACH_M
 * from the origin, or -1; its axis in *axis. */
static int64_t beyond_reach(const float *pos, const uint8_t *present, uint32_t n, const extent_t *e, int *axis)
{
    int far = 0;
    for (int a = 0; a < 3; a++)
        far |= e->lo[a] < -MIM_PLAUSIBLE_REACH_M || e->hi[a] > MIM_PLAUSIBLE_REACH_M;
    if (!far)
        return -1;
    for (uint32_t i = 0; i < n; i++) {
        if (present && !present[i])
            continue;
        for (int a = 0; a < 3; a++)
            if (fabs(pos[3 * (size_t)i + (size_t)a]) > MIM_PLAUSIBLE_REACH_M) {
                *axis = a;
                return i;
            }
    }
    return -1;
}

/* The checks a body and a landmark set share (finite, inside the box,
 * within reach of the origin, not a point), on the present points; at
 * names the set, sep joins it to "NOUN i" ("PATH: vertex 12", "PATH, frame
 * 3, landmark 7"); nouns names them all ("vertices"), counted in the
 * span message ("the 40 vertices"). A set with fewer than min_count present
 * points is not judged on its span (two landmarks may meet: hands together). */
static int check_points(const float *positions, const uint8_t *present, uint32_t n, const char *at, const char *sep,
                        const char *noun, const char *nouns, const char *counted, uint32_t min_count, mim_error_t *err)
{
    extent_t e;
    extent_of(positions, present, n, &e);
    if (e.nonfinite >= 0)
        return mim_error_set(err, MIM_ENONFINITE, "%s%s%s %lld: coordinate %c = %g is not finite", at, sep, noun,
                             (long long)e.nonfinite, "xyz"[e.nonfinite_axis],
                             (double)positions[3 * (size_t)e.nonfinite + (size_t)e.nonfinite_axis]);
    if (e.count == 0)
        return 0; /* nothing present (a vest frame may be all nulls): nothing to judge */
    double span;
    int a = widest_axis(&e, &span);
    if (span > MIM_PLAUSIBLE_BOX_M) {
        uint32_t v = farthest_from_mean(positions, present, n, a);
        return mim_error_set(err, MIM_EFORMAT,
                             "%s%s%s %u: coordinate %c = %g outside the %g m box a body fits in (the %s span %g m along %c)",
                             at, sep, noun, v, "xyz"[a], (double)positions[3 * (size_t)v + (size_t)a],
                             MIM_PLAUSIBLE_BOX_M, nouns, span, "xyz"[a]);
    }
    int axis = 0;
    int64_t far = beyond_reach(positions, present, n, &e, &axis);
    if (far >= 0)
        return mim_error_set(err, MIM_EFORMAT,
                             "%s%s%s %lld: coordinate %c = %g is more than %g m from the origin (a body must lie within it)",
                             at, sep, noun, (long long)far, "xyz"[axis],
                             (double)positions[3 * (size_t)far + (size_t)axis], MIM_PLAUSIBLE_REACH_M);
    if (e.count >= min_count && span < MIM_PLAUSIBLE_MIN_SPAN_M)
        return mim_error_set(err, MIM_EFORMAT, "%s: %s span %.1f mm: not a body (at least %g mm)", at, counted,
                             span * 1e3, MIM_PLAUSIBLE_MIN_SPAN_M * 1e3);
    return 0;
}

int mim_body_check(const float *positions, uint32_t n, const char *origin, mim_error_t *err)
{
    if (!origin)
        origin = "mesh";
    if (!positions || !n)
        return mim_error_set(err, MIM_EEMPTY, "%s: no vertices: not a body", origin);
    char counted[48];
    snprintf(counted, sizeof counted, "the %u vertices", n);
    return check_points(positions, NULL, n, origin, ": ", "vertex", "vertices", counted, 0, err);
}

int mim_landmarks_check(const float *positions, const uint8_t *present, uint32_t n, const char *origin, long frame,
                        mim_error_t *err)
{
    char at[600];
    if (!origin)
        origin = "landmarks";
    if (frame >= 0)
        snprintf(at, sizeof at, "%s: frame %ld", origin, frame);
    else
        snprintf(at, sizeof at, "%s", origin);
    if (!positions && n)
        return mim_error_set(err, MIM_EINVAL, "%s: no landmark positions", at);
    int rc = check_points(positions, present, n, at, ", ", "landmark", "landmarks", "landmarks", 3, err);
    if (rc)
        return rc;
    /* The pose descriptor's angles are between segments joining landmarks;
     * two landmarks at one point leave their segment without a direction. */
    for (uint32_t i = 0; i < n; i++) {
        if (present && !present[i])
            continue;
        const float *p = positions + 3 * (size_t)i;
        for (uint32_t j = i + 1; j < n; j++) {
            if (present && !present[j])
                continue;
            const float *q = positions + 3 * (size_t)j;
            if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2])
                return mim_error_set(err, MIM_EFORMAT,
                                     "%s: landmarks %u and %u are at one point (%g, %g, %g): the pose angles need a segment between them",
                                     at, i, j, (double)p[0], (double)p[1], (double)p[2]);
        }
    }
    return 0;
}
