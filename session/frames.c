/* What gives a key frame its vertex frames (mim_session.h's drives): the
 * templates' frames, cached a slot each, plain or by relative transfer,
 * blended and corrected (the template drive); the avatar's rest offsets
 * turned by measured segment rotations (the orientation drive) or by its
 * landmark skeleton's (the skeleton drive). session.c's transfer calls
 * them under s->lock. */
#include "internal.h"

#include "mim_vest_kinematics.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Template id's slot (under s->lock): the one holding it, else the least
 * recently used of the first `slots` (the templates the request blends: one
 * template keeps one slot, as a vest holding a pose needs), read again. */
int mim__session_cache_template(mim_session_t *s, uint64_t id, uint32_t slots, template_slot_t **out, mim_error_t *err)
{
    template_slot_t *slot = &s->slot[0];
    for (uint32_t k = 0; k < MIM_XFER_BLEND_MAX; k++) {
        if (s->slot[k].id == id) {
            s->slot[k].used = ++s->tick;
            *out = &s->slot[k];
            return 0;
        }
        if (k < slots && s->slot[k].used < slot->used)
            slot = &s->slot[k];
    }
    const size_t n = s->mesh.n_vertices;
    slot->id = 0, slot->has_W = slot->has_rF = slot->Q_of = 0;
    if (!slot->pos && !(slot->pos = malloc(3 * n * sizeof *slot->pos)))
        return mim_error_set(err, MIM_ENOMEM, "out of memory for a template of %zu vertices", n);
    if (!slot->F && !(slot->F = malloc(9 * n * sizeof *slot->F)))
        return mim_error_set(err, MIM_ENOMEM, "out of memory for a template of %zu vertices", n);
    int rc = mim_session_template(s, id, slot->pos, slot->F, slot->label, sizeof slot->label, err);
    if (rc)
        return rc;
    slot->id = id, slot->used = ++s->tick;
    *out = slot;
    return 0;
}

/* The orientation drive's offsets into s->oD (under s->lock): the rest
 * offsets turned per segment, lost segments from their neighbours, and the
 * vertices whose heaviest segment has no rotation at all from the
 * template's frames, which are loaded only then. */
int mim__session_orientation_offsets(mim_session_t *s, const mim_session_request_t *req, mim_session_report_t *r,
                                     mim_error_t *err)
{
    const uint32_t n = s->mesh.n_vertices;
    mim_quat R[MIM_VEST_SEGMENTS];
    uint8_t have[MIM_VEST_SEGMENTS];
    int8_t from[MIM_VEST_SEGMENTS];
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++) {
        have[g] = !req->orient_present || req->orient_present[g];
        R[g] = have[g] ? req->orientations[g] : mim_quat_identity();
    }
    r->orient_filled = mim_vest_rotations_fill(R, have, from);
    mim_xfer_skin_offsets(n, s->skin, s->restD, R, s->oD);
    int unfilled = 0;
    for (int g = 0; g < MIM_VEST_SEGMENTS; g++)
        unfilled |= from[g] < 0;
    if (!unfilled)
        return 0;
    template_slot_t *t;
    int rc = mim__session_cache_template(s, r->template_id, 1, &t, err);
    if (rc)
        return rc;
    for (uint32_t i = 0; i < n; i++)
        if (from[s->skin[i].bone[0]] < 0) {
            mim_xfer_decode(1, t->F + 9 * (size_t)i, s->W + 3 * (size_t)i, s->oD + 3 * (size_t)i);
            r->orient_from_template++;
        }
    return 0;
}

/* The skeleton drive's offsets into s->oD (under s->lock): the rest
 * offsets turned per segment as the avatar's landmark skeleton turns from
 * its rest landmarks onto the targets u. */
int mim__session_skeleton_offsets(mim_session_t *s, const float *u, mim_error_t *err)
{
    float rest[3 * MIM_LANDMARKS_MAX];
    for (uint32_t l = 0; l < s->map.count; l++)
        memcpy(rest + 3 * l, s->mesh.positions + 3 * (size_t)s->map.vertex[l], 3 * sizeof *rest);
    mim_quat R[MIM_SEGMENTS];
    int rc = mim_xfer_segment_correction(&s->map, rest, u, R, err);
    if (!rc)
        mim_xfer_skin_offsets(s->mesh.n_vertices, s->skin, s->restD, R, s->oD);
    return rc;
}

/* The template drive's frames and W (under s->lock): each template's
 * frames, or with relative transfer the avatar's rest frames turned by the
 * template's turn from its reference (within the gate); then turned by the
 * segment correction from its landmark skeleton onto the targets u when
 * the avatar is segmented; then blended with these weights (issue 15).
 * *frames points at them, *W at the avatar's W or, relative, its W plus
 * the templates' change; the first template's slot in *first. A blend
 * without the correction gives its offsets in *offsets instead of frames
 * (*frames NULL): each template's quaternions are kept with it, so a held
 * pose pays for them once and each key frame only sums them. */
int mim__session_template_frames(mim_session_t *s, const mim_session_request_t *req, mim_session_report_t *r,
                                 double *weights, const float *u, const double **frames, const double **offsets,
                                 const double **W, template_slot_t **first, mim_error_t *err)
{
    const uint32_t n = s->mesh.n_vertices, nl = s->map.count;
    const double *src[MIM_XFER_BLEND_MAX], *wp[MIM_XFER_BLEND_MAX], *wr[MIM_XFER_BLEND_MAX];
    double scale[MIM_XFER_BLEND_MAX];
    subject_ref_t *ref[MIM_XFER_BLEND_MAX];
    size_t at[MIM_XFER_BLEND_MAX];
    int relative = (req->relative ? req->relative : MIM_SESSION_DEFAULT_RELATIVE) > 0;
    /* only in a store whose subjects take a pose alike (MIM_SESSION_RELATIVE_SPREAD_DEG says why) */
    relative = relative && !(mim__session_store_spread(s) > MIM_SESSION_RELATIVE_SPREAD_DEG);
    /* Only references that stand as the avatar does (MIM_SESSION_RELATIVE_GATE_DEG; else another body's
     * way of moving): the templates whose references do are blended relative, the others left out;
     * with none, the plain path over them all. And all or none of a blend: changes and shapes mixed
     * would mix two meanings. */
    uint32_t kept = 0;
    uint64_t keep_id[MIM_XFER_BLEND_MAX];
    double keep_w[MIM_XFER_BLEND_MAX];
    for (uint32_t j = 0; relative && j < r->n_templates; j++) {
        subject_ref_t *found;
        mim_error_t damage = {0};
        int rc = mim__session_reference(s, r->templates[j], &found, &damage, err);
        if (rc)
            return rc;
        if (damage.code && !r->degraded[0])
            snprintf(r->degraded, sizeof r->degraded, "%s", mim_error_text(&damage));
        if (!found || !found->near) continue;
        at[kept] = (size_t)(found - s->refs); /* an index: a later template's new reference may move s->refs */
        keep_id[kept] = r->templates[j], keep_w[kept] = weights ? weights[j] : 1.0;
        if (weights && r->queried) { /* sharper, and by build (MIM_SESSION_RELATIVE_BUILD_POWER says why) */
            const double b = isfinite(found->build) ? found->build : 1.0; /* unknown: unlike */
            keep_w[kept] = pow(keep_w[kept], MIM_SESSION_RELATIVE_DISTANCE_POWER) *
                           pow(1.0 / (b + MIM_SESSION_BUILD_DISTANCE_FLOOR), MIM_SESSION_RELATIVE_BUILD_POWER);
        }
        kept++;
    }
    relative = relative && kept > 0;
    /* The plain path: the avatar's own frames turned by its landmark skeleton where it may
     * (MIM_SESSION_DEFAULT_PLAIN_SKELETON says why); a map without the default landmarks keeps the
     * templates' frames. */
    if (!relative && MIM_SESSION_DEFAULT_PLAIN_SKELETON && req->drive == MIM_DRIVE_AUTO && r->queried && u &&
        req->landmarks && s->skin && req->segment_correction <= 0) {
        mim_error_t serr = {0};
        int rc = mim__session_skeleton_offsets(s, u, &serr);
        if (rc != MIM_EUNSUPPORTED) {
            if (rc)
                return mim_error_set(err, rc, "%s", mim_error_text(&serr));
            r->drive = MIM_DRIVE_SKELETON, r->n_templates = 1, weights[0] = 1.0;
            *W = s->W, *frames = NULL, *offsets = s->oD;
            return mim__session_cache_template(s, r->templates[0], 1, first, err);
        }
    }
    if (relative) { /* the blend of those alone, with their weights */
        for (uint32_t j = 0; j < kept; j++) r->templates[j] = keep_id[j];
        r->n_templates = kept;
        if (weights) memcpy(weights, keep_w, kept * sizeof *keep_w);
    }
    for (uint32_t j = 0; relative && j < r->n_templates; j++)
        ref[j] = &s->refs[at[j]];
    int correct = s->skin && u &&
                  (req->segment_correction > 0 ||
                   (req->segment_correction == 0 && !relative && MIM_SESSION_DEFAULT_PLAIN_CORRECTION));
    *W = s->W;
    *frames = *offsets = NULL;
    template_slot_t *slots[MIM_XFER_BLEND_MAX];
    for (uint32_t j = 0; j < r->n_templates; j++) {
        template_slot_t *t;
        int rc = mim__session_cache_template(s, r->templates[j], r->n_templates, &t, err);
        if (rc)
            return rc;
        slots[j] = t;
        if (!j)
            *first = t;
        src[j] = t->F;
        if (relative) {
            if (!t->has_W) {
                if (!t->W && !(t->W = malloc(3 * (size_t)n * sizeof *t->W)))
                    return mim_error_set(err, MIM_ENOMEM, "out of memory for a template of %u vertices", n);
                mim_xfer_encode(s->topo, t->pos, t->F, t->W);
                t->has_W = 1;
            }
            if (!t->has_rF) {
                if (!t->rF && !(t->rF = malloc(9 * (size_t)n * sizeof *t->rF)))
                    return mim_error_set(err, MIM_ENOMEM, "out of memory for a template of %u vertices", n);
                mim_xfer_frames_relative(n, t->F, ref[j]->F, s->restF, t->rF);
                t->has_rF = 1;
            }
            src[j] = t->rF, r->frames_turned++;
            wp[j] = t->W, wr[j] = ref[j]->W, scale[j] = ref[j]->scale;
            r->references[j] = ref[j]->id;
        }
        if (!correct)
            continue;
        if (!t->cF && !(t->cF = malloc(9 * (size_t)n * sizeof *t->cF)))
            return mim_error_set(err, MIM_ENOMEM, "out of memory for a template of %u vertices", n);
        float lm[3 * MIM_LANDMARKS_MAX];
        for (uint32_t l = 0; l < nl; l++)
            memcpy(lm + 3 * l, t->pos + 3 * (size_t)s->map.vertex[l], 3 * sizeof *lm);
        mim_quat R[MIM_SEGMENTS];
        mim_error_t cerr = {0};
        if ((rc = mim_xfer_segment_correction(&s->map, lm, u, R, &cerr)) == MIM_EUNSUPPORTED) {
            correct = 0; /* a map without the default landmarks (the first template finds out) */
            continue;
        }
        if (rc)
            return mim_error_set(err, rc, "%s", mim_error_text(&cerr));
        mim_xfer_skin_frames(n, s->skin, src[j], R, t->cF);
        src[j] = t->cF;
    }
    r->corrected = correct;
    if (relative) {
        mim_xfer_encoding_relative(n, r->n_templates, wp, wr, weights, scale, s->W, s->rW);
        *W = s->rW;
        r->relative = 1, r->reference_id = r->references[0];
    }
    if (r->n_templates == 1) {
        *frames = src[0];
        return 0;
    }
    if (correct) { /* turned for these landmarks: nothing to keep */
        mim_xfer_frames_blend(n, r->n_templates, src, weights, s->bF);
        *frames = s->bF;
        return 0;
    }
    const double *quats[MIM_XFER_BLEND_MAX];
    for (uint32_t j = 0; j < r->n_templates; j++) {
        template_slot_t *t = slots[j];
        const int of = src[j] == t->rF ? 2 : 1;
        if (t->Q_of != of) {
            if (!t->Q && !(t->Q = malloc(4 * (size_t)n * sizeof *t->Q)))
                return mim_error_set(err, MIM_ENOMEM, "out of memory for a template of %u vertices", n);
            mim_xfer_frames_to_quats(n, src[j], t->Q);
            t->Q_of = of;
        }
        quats[j] = t->Q;
    }
    mim_xfer_offsets_blend(n, r->n_templates, quats, weights, *W, s->bD);
    *offsets = s->bD;
    return 0;
}
