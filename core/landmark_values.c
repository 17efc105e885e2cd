/* One frame's values checked the same whoever parsed them
 * (landmark_values.h): a landmark array, [[x, y, z] | null, ...] in the
 * order of the landmark map, and an orientations object, {"pelvis":
 * [x, y, z, w] | null, ...} keyed by the vest's segments. A wrong count
 * or a bad coordinate names the frame and the landmark (or the segment);
 * each frame must be a plausible skeleton (plausible.c). Also the jansson
 * form of both, for the vest's UDP datagrams. */
#include "landmark_values.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

const char *mim__where(char *buf, size_t size, const char *origin, long frame)
{
    if (frame < 0)
        return origin;
    snprintf(buf, size, "%s: frame %ld", origin, frame);
    return buf;
}

int mim__landmarks_not_array(const char *origin, long frame, mim_error_t *err)
{
    char wb[600];
    return mim_error_set(err, MIM_EFORMAT, "%s: \"landmarks\" must be an array", mim__where(wb, sizeof wb, origin, frame));
}

int mim__landmark_entry(const mim__seen_t *e, const char *origin, long frame, uint32_t i, float *pos,
                        uint8_t *present, mim_error_t *err)
{
    char wb[600];
    if (e->kind == MIM__SEEN_NULL) {
        present[i] = 0;
        pos[3 * i] = pos[3 * i + 1] = pos[3 * i + 2] = NAN;
        return 0;
    }
    if (e->kind != MIM__SEEN_ARRAY || e->count != 3)
        return mim_error_set(err, MIM_EFORMAT, "%s, landmark %u: expected [x, y, z] or null",
                             mim__where(wb, sizeof wb, origin, frame), i);
    for (int c = 0; c < 3; c++) {
        if (!e->isnum[c])
            return mim_error_set(err, MIM_EFORMAT, "%s, landmark %u: %c is not a number",
                                 mim__where(wb, sizeof wb, origin, frame), i, "xyz"[c]);
        double x = e->v[c];
        if (!isfinite(x) || !isfinite((float)x))
            return mim_error_set(err, MIM_ENONFINITE, "%s, landmark %u: %c = %g is not a finite float",
                                 mim__where(wb, sizeof wb, origin, frame), i, "xyz"[c], x);
        pos[3 * i + (uint32_t)c] = (float)x;
    }
    present[i] = 1;
    return 0;
}

int mim__landmarks_close(size_t count, uint32_t n, uint32_t max_missing, const mim_error_t *pending,
                         const char *origin, long frame, const float *pos, const uint8_t *present, mim_error_t *err)
{
    char wb[600];
    if (count != n)
        return mim_error_set(err, MIM_EFORMAT, "%s has %zu landmarks, the landmark map has %u",
                             mim__where(wb, sizeof wb, origin, frame), count, n);
    if (pending && pending->code)
        return mim_error_set(err, pending->code, "%s", pending->msg);
    uint32_t missing = 0;
    for (uint32_t i = 0; i < n; i++)
        missing += !present[i];
    if (missing > max_missing)
        return mim_error_set(err, MIM_EFORMAT, "%s has %u missing landmarks, at most %u allowed",
                             mim__where(wb, sizeof wb, origin, frame), missing, max_missing);
    /* finite numbers, but a body? (one place for files, the API and UDP) */
    return mim_landmarks_check(pos, present, n, origin, frame, err);
}

void mim__orient_clear(double *q, uint8_t *have)
{
    for (int s = 0; s < MIM_SEGMENTS; s++) {
        q[4 * s] = q[4 * s + 1] = q[4 * s + 2] = 0, q[4 * s + 3] = 1;
        have[s] = 0;
    }
}

int mim__orientations_not_object(const char *origin, long frame, mim_error_t *err)
{
    char wb[600];
    return mim_error_set(err, MIM_EFORMAT, "%s: \"orientations\" must be an object",
                         mim__where(wb, sizeof wb, origin, frame));
}

int mim__segment_find(const char *key, size_t key_len)
{
    for (int s = 0; s < MIM_SEGMENTS; s++)
        if (strlen(mim_segment_names[s]) == key_len && !memcmp(key, mim_segment_names[s], key_len))
            return s;
    return -1;
}

int mim__orientation_entry(const char *key, int s, const mim__seen_t *e, const char *origin, long frame, double *q,
                           uint8_t *have, mim_error_t *err)
{
    char wb[600];
    if (s < 0) {
        char names[256];
        size_t k = 0;
        for (int i = 0; i < MIM_SEGMENTS; i++)
            k += (size_t)snprintf(names + k, sizeof names - k, "%s%s", i ? ", " : "", mim_segment_names[i]);
        return mim_error_set(err, MIM_EFORMAT, "%s: orientation '%.40s' is not a vest segment (%s)",
                             mim__where(wb, sizeof wb, origin, frame), key, names);
    }
    if (e->kind == MIM__SEEN_NULL)
        return 0; /* a lost sensor */
    if (e->kind != MIM__SEEN_ARRAY || e->count != 4)
        return mim_error_set(err, MIM_EFORMAT, "%s, orientation '%s': expected [x, y, z, w] or null",
                             mim__where(wb, sizeof wb, origin, frame), key);
    double big = 0;
    for (int i = 0; i < 4; i++) {
        if (!e->isnum[i])
            return mim_error_set(err, MIM_EFORMAT, "%s, orientation '%s': %c is not a number",
                                 mim__where(wb, sizeof wb, origin, frame), key, "xyzw"[i]);
        if (!isfinite(e->v[i])) /* neither reader lets these through today */
            return mim_error_set(err, MIM_ENONFINITE, "%s, orientation '%s': %c = %g is not finite",
                                 mim__where(wb, sizeof wb, origin, frame), key, "xyzw"[i], e->v[i]);
        big = fmax(big, fabs(e->v[i]));
    }
    /* scaled, so that [1e200, 0, 0, 0] reports its norm, not inf */
    double norm = 0;
    for (int i = 0; big > 0 && i < 4; i++)
        norm += (e->v[i] / big) * (e->v[i] / big);
    norm = big * sqrt(norm);
    if (!(fabs(norm - 1) <= MIM_ORIENT_UNIT_TOL))
        return mim_error_set(err, MIM_EFORMAT, "%s: orientation '%s' is not a unit quaternion (norm %.3g)",
                             mim__where(wb, sizeof wb, origin, frame), key, norm);
    for (int i = 0; i < 4; i++)
        q[4 * s + i] = e->v[i] / norm;
    have[s] = 1;
    return 0;
}

/* ---- the same from jansson values (vest UDP datagrams) ---- */

static void seen_json(const json_t *v, mim__seen_t *e)
{
    memset(e, 0, sizeof *e);
    e->kind = json_is_null(v) ? MIM__SEEN_NULL : json_is_array(v) ? MIM__SEEN_ARRAY : MIM__SEEN_OTHER;
    e->count = json_array_size(v);
    for (size_t i = 0; i < e->count && i < 4; i++) {
        json_t *x = json_array_get(v, i);
        e->isnum[i] = json_is_number(x);
        e->v[i] = json_number_value(x);
    }
}

int mim_landmark_array_parse(const json_t *lm, uint32_t n, uint32_t max_missing, const char *origin, long frame,
                             float *pos, uint8_t *present, mim_error_t *err)
{
    if (!origin)
        origin = "landmarks";
    if (!json_is_array(lm))
        return mim__landmarks_not_array(origin, frame, err);
    size_t count = json_array_size(lm);
    for (uint32_t i = 0; i < n && count == n; i++) {
        mim__seen_t e;
        seen_json(json_array_get(lm, i), &e);
        int rc = mim__landmark_entry(&e, origin, frame, i, pos, present, err);
        if (rc)
            return rc;
    }
    return mim__landmarks_close(count, n, max_missing, NULL, origin, frame, pos, present, err);
}

int mim_orientations_parse(const json_t *obj, const char *origin, long frame, double *q, uint8_t *have,
                           mim_error_t *err)
{
    if (!origin)
        origin = "orientations";
    mim__orient_clear(q, have);
    if (!json_is_object(obj))
        return mim__orientations_not_object(origin, frame, err);
    const char *key;
    json_t *v;
    json_object_foreach((json_t *)obj, key, v) {
        mim__seen_t e;
        seen_json(v, &e);
        int rc = mim__orientation_entry(key, mim__segment_find(key, strlen(key)), &e, origin, frame, q, have, err);
        if (rc)
            return rc;
    }
    return 0;
}
