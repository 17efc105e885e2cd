/* Relative transfer's references (issue 15; mim_session.h says what
 * relative transfer is): per template subject, its template nearest to the
 * avatar's rest landmarks over all index angles, with that template's W,
 * the encodings' scale and, within MIM_SESSION_RELATIVE_GATE_DEG, its
 * frames. session.c's template drive reads them. */
#include "internal.h"

#include "mim_index.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The reference of subject `subject` (under s->lock): its template of the
 * store's connectivity nearest to the avatar's rest landmarks, its W and
 * scale, and its frames when within the gate. Appended to s->refs. */
static int make_reference(mim_session_t *s, const char *subject, const float *table, char *const *subjects,
                          const uint64_t *ids, uint32_t count, subject_ref_t **out, mim_error_t *err)
{
    const uint32_t n = s->mesh.n_vertices, L = s->map.count, na = mim_index_angle_count(L);
    if (s->n_refs == s->cap_refs) {
        uint32_t cap = s->cap_refs ? 2 * s->cap_refs : 1; /* from 1: a blend meets a move of the array early (tests) */
        subject_ref_t *r = realloc(s->refs, cap * sizeof *r);
        if (!r) return mim_error_set(err, MIM_ENOMEM, "out of memory for a reference");
        s->refs = r, s->cap_refs = cap;
    }
    subject_ref_t *ref = &s->refs[s->n_refs];
    *ref = (subject_ref_t){.subject = strdup(subject), .scale = NAN, .build = NAN};
    float *ang = malloc(na * sizeof *ang), lm[3 * MIM_LANDMARKS_MAX]; /* the avatar's rest landmarks */
    for (uint32_t l = 0; l < L; l++)
        memcpy(lm + 3 * l, s->mesh.positions + 3 * (size_t)s->map.vertex[l], 3 * sizeof *lm);
    if (!s->rest_angles && (s->rest_angles = malloc(na * sizeof *s->rest_angles)))
        mim_index_angles(lm, NULL, L, s->rest_angles);
    if (!ref->subject || !ang || !s->rest_angles) {
        free(ref->subject), free(ang);
        return mim_error_set(err, MIM_ENOMEM, "out of memory for a reference");
    }
    double best = INFINITY;
    for (uint32_t i = 0; i < count; i++) {
        if (strcmp(subjects[i], subject))
            continue;
        mim_index_angles(table + 3 * (size_t)L * i, NULL, L, ang);
        double d = mim__angles_rms(ang, s->rest_angles, na);
        if (d < best)
            best = d, ref->id = ids[i], ref->build = mim_xfer_build_distance(lm, table + 3 * (size_t)L * i, L);
    }
    free(ang);
    int rc = 0;
    if (ref->id) {
        ref->near = best < MIM_SESSION_RELATIVE_GATE_DEG * M_PI / 180;
        float *pos = malloc(3 * (size_t)n * sizeof *pos);
        double *F = malloc(9 * (size_t)n * sizeof *F);
        ref->W = malloc(3 * (size_t)n * sizeof *ref->W);
        rc = pos && F && ref->W ? 0 : mim_error_set(err, MIM_ENOMEM, "out of memory for a reference");
        mim_error_t terr = {0};
        /* W as the avatar's own is made, so that a reference that is the
         * avatar changes nothing; a reference that cannot be read (a damaged
         * record) leaves the subject on the plain path, once and for all */
        if (!rc && mim_session_template(s, ref->id, pos, F, NULL, 0, &terr)) {
            mim_error_set(&ref->damage, terr.code, "relative transfer is off for subject %s: its reference, "
                          "template %llu, cannot be read: %s", subject, (unsigned long long)ref->id,
                          mim_error_text(&terr));
            free(ref->W), ref->W = NULL;
            ref->id = 0;
        }
        if (!rc && ref->id) {
            mim_xfer_encode(s->topo, pos, F, ref->W);
            ref->scale = mim_xfer_encoding_scale(n, s->W, ref->W);
        }
        free(pos);
        if (!rc && ref->id && ref->near)
            ref->F = F, F = NULL;
        free(F);
    }
    if (rc) {
        free(ref->subject), free(ref->W), free(ref->F);
        return rc;
    }
    s->n_refs++;
    *out = ref->id ? ref : NULL;
    return 0;
}

static void damage_of(const subject_ref_t *ref, mim_error_t *damage)
{
    if (damage && ref->damage.code) *damage = ref->damage;
}

/* None when the template has no subject label, is not in the store's
 * landmark table (another connectivity), or the table cannot be read (a
 * damaged template elsewhere in the store must not stop transfers, but it
 * is reported: *damage). */
int mim__session_reference(mim_session_t *s, uint64_t id, subject_ref_t **out, mim_error_t *damage,
                           mim_error_t *err)
{
    *out = NULL;
    const float *table;
    char *const *subjects;
    const uint64_t *ids;
    uint32_t count;
    mim_error_t terr = {0};
    if (mim__session_landmark_table(s, &table, &subjects, &ids, &count, &terr)) {
        if (damage)
            mim_error_set(damage, terr.code, "relative transfer is off: the store's templates cannot be read: %s",
                          mim_error_text(&terr));
        return 0;
    }
    uint32_t lo = 0, hi = count; /* ids ascend */
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (ids[mid] < id) lo = mid + 1;
        else hi = mid;
    }
    if (lo == count || ids[lo] != id || !subjects[lo][0])
        return 0;
    for (uint32_t i = 0; i < s->n_refs; i++)
        if (!strcmp(s->refs[i].subject, subjects[lo])) {
            *out = s->refs[i].id ? &s->refs[i] : NULL;
            damage_of(&s->refs[i], damage);
            return 0;
        }
    int rc = make_reference(s, subjects[lo], table, subjects, ids, count, out, err);
    if (!rc) damage_of(&s->refs[s->n_refs - 1], damage);
    return rc;
}
