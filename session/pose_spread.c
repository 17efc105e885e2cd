/* How alike a store's subjects take one pose (mim_session.h,
 * mim_session_pose_spread): relative transfer's premise, checked on the
 * store itself. Bodies posed by one rig share each pose's angles up to
 * their proportions; people imitating a pose do not (about 11 degrees a
 * bone apart). */
#include "internal.h"

#include "mim_index.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *const *poses, *const *subjects;
} order_t;

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double mim__angles_rms(const float *a, const float *b, uint32_t na)
{
    double d = 0;
    uint32_t m = 0;
    for (uint32_t i = 0; i < na; i++)
        if (isfinite(a[i]) && isfinite(b[i]))
            d += ((double)a[i] - b[i]) * ((double)a[i] - b[i]), m++;
    return m ? sqrt(d / m) : NAN;
}

/* Indices by pose, then subject (stable: a subject's templates keep their
 * order); qsort has no user pointer, and a library keeps no process-wide
 * state. */
static void merge_sort(uint32_t *v, uint32_t *tmp, uint32_t n, const order_t *o)
{
    if (n < 2) return;
    const uint32_t h = n / 2;
    merge_sort(v, tmp, h, o);
    merge_sort(v + h, tmp, n - h, o);
    uint32_t i = 0, j = h, k = 0;
    while (i < h && j < n) {
        int c = strcmp(o->poses[v[i]], o->poses[v[j]]);
        if (!c) c = strcmp(o->subjects[v[i]], o->subjects[v[j]]);
        tmp[k++] = c <= 0 ? v[i++] : v[j++];
    }
    while (i < h) tmp[k++] = v[i++];
    while (j < n) tmp[k++] = v[j++];
    memcpy(v, tmp, n * sizeof *v);
}

double mim_session_pose_spread(uint32_t count, uint32_t n_landmarks, const float *landmarks,
                               const char *const *subjects, const char *const *poses)
{
    if (!landmarks || !subjects || !poses || n_landmarks < 3 || n_landmarks > MIM_LANDMARKS_MAX) return NAN;
    const uint32_t n = count < MIM_SESSION_SPREAD_TEMPLATES ? count : MIM_SESSION_SPREAD_TEMPLATES;
    const uint32_t na = mim_index_angle_count(n_landmarks);
    uint32_t *idx = malloc(2 * (size_t)(n ? n : 1) * sizeof *idx);
    float *a = malloc(2 * (size_t)na * sizeof *a);
    double *d = malloc(MIM_SESSION_SPREAD_PAIRS * sizeof *d);
    double spread = NAN;
    if (!idx || !a || !d) goto done;
    uint32_t m = 0; /* labelled templates only: an empty pose or subject says nothing */
    for (uint32_t i = 0; i < n; i++)
        if (subjects[i] && poses[i] && subjects[i][0] && poses[i][0]) idx[m++] = i;
    const order_t o = {poses, subjects};
    merge_sort(idx, idx + n, m, &o);
    /* within each pose, each subject's first template against the next subject's first */
    uint32_t pairs = 0, prev = UINT32_MAX; /* the last subject's first template in this pose */
    for (uint32_t k = 0; k < m && pairs < MIM_SESSION_SPREAD_PAIRS; k++) {
        const uint32_t j = idx[k];
        if (k > 0 && !strcmp(poses[idx[k - 1]], poses[j]) && !strcmp(subjects[idx[k - 1]], subjects[j]))
            continue; /* the same subject's repeat of the pose */
        if (prev != UINT32_MAX && !strcmp(poses[prev], poses[j])) {
            mim_index_angles(landmarks + 3 * (size_t)n_landmarks * prev, NULL, n_landmarks, a);
            mim_index_angles(landmarks + 3 * (size_t)n_landmarks * j, NULL, n_landmarks, a + na);
            const double r = mim__angles_rms(a, a + na, na) * 180.0 / M_PI;
            if (isfinite(r)) d[pairs++] = r;
        }
        prev = j;
    }
    if (pairs) {
        qsort(d, pairs, sizeof *d, cmp_double);
        spread = pairs % 2 ? d[pairs / 2] : 0.5 * (d[pairs / 2 - 1] + d[pairs / 2]);
    }
done:
    free(idx), free(a), free(d);
    return spread;
}
