/* The generator object: shared connectivity, landmarks, poses; and the
 * evaluation of one subject in one pose. */
#include "synth_internal.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void mim__body_free(mim__body_t *b)
{
    free(b->rest), free(b->wj), free(b->ww);
    b->rest = NULL, b->wj = NULL, b->ww = NULL;
}

/* Cage -> rest mesh and refined, normalised skin weights. */
int mim__body_eval(const mim_synth_t *s, const mim__subject_t *sub, mim__body_t *b)
{
    memset(b, 0, sizeof *b);
    b->sub = *sub;
    mim__skeleton_make(&b->sk, sub);
    mim__cage_t c;
    int rc = mim__cage_build(&c, &s->lay, sub);
    if (rc) return rc;
    uint32_t nv = s->ref.nv;
    b->rest = malloc((size_t)nv * 3 * sizeof *b->rest);
    b->wj = malloc((size_t)nv * MIM__NW);
    b->ww = malloc((size_t)nv * MIM__NW * sizeof *b->ww);
    if (!b->rest || !b->wj || !b->ww) {
        mim__cage_free(&c);
        mim__body_free(b);
        return MIM_ENOMEM;
    }
    mim__refine_apply(&s->ref, c.pos, b->rest, 3);
    /* weights: refined like positions (sparse: each cage vertex has
     * MIM__CW bones), keep the MIM__NW largest (ties to the lower bone),
     * renormalise */
    const mim__refine_t *r = &s->ref;
    double acc[MIM__NB] = {0};
    for (uint32_t i = 0; i < nv; i++) {
        int bones[MIM__NB], nb = 0;
        for (uint32_t k = r->st_start[i]; k < r->st_start[i + 1]; k++) {
            uint32_t v = r->st_col[k];
            for (int q = 0; q < MIM__CW; q++) {
                float w = c.ww[MIM__CW * v + q];
                if (w == 0) continue;
                int bj = c.wj[MIM__CW * v + q];
                if (acc[bj] == 0) bones[nb++] = bj;
                acc[bj] += r->st_w[k] * w;
                if (acc[bj] == 0) acc[bj] = 1e-300; /* stays listed */
            }
        }
        uint8_t *oj = b->wj + (size_t)MIM__NW * i;
        float *ow = b->ww + (size_t)MIM__NW * i;
        double sum = 0;
        for (int k = 0; k < MIM__NW; k++) {
            int best = -1;
            for (int q = 0; q < nb; q++) {
                int bj = bones[q];
                if (acc[bj] > 0 && (best < 0 || acc[bj] > acc[best] || (acc[bj] == acc[best] && bj < best))) best = bj;
            }
            double w = best >= 0 && acc[best] > 1e-6 ? acc[best] : 0;
            oj[k] = (uint8_t)(best >= 0 ? best : 0);
            ow[k] = (float)w;
            sum += w;
            if (best >= 0) acc[best] = -1; /* taken */
        }
        for (int q = 0; q < nb; q++) acc[bones[q]] = 0;
        for (int k = 0; k < MIM__NW; k++) ow[k] = sum > 0 ? (float)(ow[k] / sum) : (k == 0 ? 1.0f : 0.0f);
    }
    mim__cage_free(&c);
    return 0;
}

void mim__body_pose(const mim_synth_t *s, const mim__body_t *b, uint32_t subject, uint32_t pose, double *work,
                    float *positions, float *joints)
{
    mim_quat q[MIM__NJ], G[MIM__NJ];
    mim_vec3 P[MIM__NJ];
    double deg[MIM__NJ][3];
    mim__pose_angles(pose, s->opt.seed, deg);
    mim__pose_imitate(subject, pose, s->opt.seed, s->opt.imitation_deg, deg);
    mim__pose_quats((const double(*)[3])deg, q);
    mim__fk(&b->sk, q, G, P);
    uint32_t nv = s->nv;
    mim__lbs(&b->sk, q, G, P, nv, b->rest, b->wj, b->ww, work);
    mim__tissue_apply(s, b->rest, subject, pose, work);
    /* stand on the ground: the lowest vertex at y = 0 */
    double ymin = DBL_MAX;
    for (uint32_t i = 0; i < nv; i++) ymin = fmin(ymin, work[3 * i + 1]);
    if (positions)
        for (uint32_t i = 0; i < nv; i++) {
            positions[3 * i] = (float)work[3 * i];
            positions[3 * i + 1] = (float)(work[3 * i + 1] - ymin);
            positions[3 * i + 2] = (float)work[3 * i + 2];
        }
    if (joints)
        for (int j = 0; j < MIM__NJ; j++) {
            joints[3 * j] = (float)P[j].x;
            joints[3 * j + 1] = (float)(P[j].y - ymin);
            joints[3 * j + 2] = (float)P[j].z;
        }
}

void mim_synth_destroy(mim_synth_t **sp)
{
    if (!sp || !*sp) return;
    mim_synth_t *s = *sp;
    mim__refine_free(&s->ref);
    free(s->faces), free(s->pose_name);
    free(s);
    *sp = NULL;
}

int mim_synth_create(mim_synth_t **out, const mim_synth_options_t *optp, mim_error_t *err)
{
    if (!out) return mim_error_set(err, MIM_EINVAL, "synth: no output pointer");
    *out = NULL;
    mim_synth_options_t opt = {0, 0, 0, 1, 0, 0, 0};
    if (optp) opt = *optp;
    if (!opt.subjects) opt.subjects = MIM_SYNTH_DEFAULT_SUBJECTS;
    if (!opt.poses) opt.poses = MIM_SYNTH_DEFAULT_POSES;
    if (!opt.vertices) opt.vertices = MIM_SYNTH_DEFAULT_VERTICES;
    if (opt.subjects > MIM_SYNTH_MAX_SUBJECTS)
        return mim_error_set(err, MIM_EINVAL, "synth: %u subjects, at most %u", opt.subjects, MIM_SYNTH_MAX_SUBJECTS);
    if (opt.poses > MIM_SYNTH_MAX_POSES)
        return mim_error_set(err, MIM_EINVAL, "synth: %u poses, at most %u", opt.poses, MIM_SYNTH_MAX_POSES);
    if (!(opt.slide_mm >= 0 && opt.slide_mm <= 50))
        return mim_error_set(err, MIM_EINVAL, "synth: a slide of %g mm, must be 0..50", opt.slide_mm);
    if (!(opt.tissue_mm >= 0 && opt.tissue_mm <= 50))
        return mim_error_set(err, MIM_EINVAL, "synth: soft tissue of %g mm, must be 0..50", opt.tissue_mm);
    if (!(opt.imitation_deg >= 0 && opt.imitation_deg <= 45))
        return mim_error_set(err, MIM_EINVAL, "synth: an imitation spread of %g degrees, must be 0..45",
                             opt.imitation_deg);
    if (opt.vertices < MIM_SYNTH_MIN_VERTICES || opt.vertices > MIM_SYNTH_MAX_VERTICES)
        return mim_error_set(err, MIM_EINVAL, "synth: %u vertices asked, must be %u..%u", opt.vertices,
                             MIM_SYNTH_MIN_VERTICES, MIM_SYNTH_MAX_VERTICES);
    mim_synth_t *s = calloc(1, sizeof *s);
    if (!s) return mim_error_set(err, MIM_ENOMEM, "synth: out of memory");
    s->opt = opt;
    int rc = mim__layout_choose(&s->lay, opt.vertices);
    if (rc) {
        mim_synth_destroy(&s);
        return mim_error_set(err, rc, "synth: no cage layout for %u vertices", opt.vertices);
    }

    /* the connectivity, decided on the reference subject */
    mim__subject_t ref;
    mim__subject_reference(&ref);
    mim__cage_t c;
    rc = mim__cage_build(&c, &s->lay, &ref);
    if (!rc) rc = mim__cage_orient(&c);
    if (!rc) rc = mim__refine_build(&s->ref, &c, s->lay.level);
    mim__cage_free(&c);
    if (rc) {
        mim_synth_destroy(&s);
        return mim_error_set(err, rc, "synth: cannot build the body cage: %s", mim_strerror(rc));
    }
    s->nv = s->ref.nv;
    uint32_t maxf = 0;
    for (uint32_t i = 0; i < s->ref.npoly; i++) maxf += s->ref.poly[4 * i + 3] == UINT32_MAX ? 1 : 2;
    s->faces = malloc((size_t)maxf * 3 * sizeof *s->faces);
    s->pose_name = malloc((size_t)opt.poses * sizeof *s->pose_name);
    mim__body_t b;
    rc = (!s->faces || !s->pose_name) ? MIM_ENOMEM : mim__body_eval(s, &ref, &b);
    if (rc) {
        mim_synth_destroy(&s);
        return mim_error_set(err, rc, "synth: out of memory");
    }
    s->nf = mim__triangulate(&s->ref, b.rest, s->faces);
    mim__landmarks_pick(&b, s->nv, s->landmark);
    mim__body_free(&b);

    for (uint32_t p = 0; p < opt.poses; p++) {
        const char *n = mim__pose_table_name(p);
        if (n) snprintf(s->pose_name[p], sizeof s->pose_name[p], "%s", n);
        else snprintf(s->pose_name[p], sizeof s->pose_name[p], "random%u", p);
    }
    *out = s;
    return 0;
}

uint32_t mim_synth_n_vertices(const mim_synth_t *s) { return s ? s->nv : 0; }
uint32_t mim_synth_n_faces(const mim_synth_t *s) { return s ? s->nf : 0; }
uint32_t mim_synth_n_subjects(const mim_synth_t *s) { return s ? s->opt.subjects : 0; }
uint32_t mim_synth_n_poses(const mim_synth_t *s) { return s ? s->opt.poses : 0; }
const uint32_t *mim_synth_faces(const mim_synth_t *s) { return s ? s->faces : NULL; }
uint32_t mim_synth_n_joints(const mim_synth_t *s) { return s ? MIM__NJ : 0; }

const char *mim_synth_joint_name(const mim_synth_t *s, uint32_t j)
{
    return s && j < MIM__NJ ? mim__joint_name[j] : NULL;
}

int mim_synth_joint_parent(const mim_synth_t *s, uint32_t j)
{
    return s && j < MIM__NJ ? mim__joint_parent[j] : -1;
}

const char *mim_synth_pose_name(const mim_synth_t *s, uint32_t pose)
{
    return s && pose < s->opt.poses ? s->pose_name[pose] : NULL;
}

void mim_synth_landmarks(const mim_synth_t *s, mim_landmark_map_t *map)
{
    if (!map) return;
    if (!s) {
        memset(map, 0, sizeof *map);
        return;
    }
    mim_landmarks_default(map, s->landmark, s->nv);
}

void mim_synth_file_name(uint32_t subject, uint32_t pose, char *buf, size_t size)
{
    if (buf && size) snprintf(buf, size, "synth_s%02u_p%02u.ply", subject, pose);
}

static int eval(const mim_synth_t *s, uint32_t subject, uint32_t pose, float *positions, float *joints)
{
    if (!s || subject >= s->opt.subjects || pose >= s->opt.poses) return MIM_EINVAL;
    mim__subject_t sub;
    mim__subject_make(&sub, s->opt.seed, subject);
    mim__body_t b;
    int rc = mim__body_eval(s, &sub, &b);
    if (rc) return rc;
    double *work = malloc((size_t)s->nv * 3 * sizeof *work);
    if (!work) {
        mim__body_free(&b);
        return MIM_ENOMEM;
    }
    mim__body_pose(s, &b, subject, pose, work, positions, joints);
    free(work);
    mim__body_free(&b);
    return 0;
}

int mim_synth_body(const mim_synth_t *s, uint32_t subject, uint32_t pose, float *positions)
{
    if (!positions) return MIM_EINVAL;
    return eval(s, subject, pose, positions, NULL);
}

int mim_synth_joints(const mim_synth_t *s, uint32_t subject, uint32_t pose, float *joints)
{
    if (!joints) return MIM_EINVAL;
    return eval(s, subject, pose, NULL, joints);
}
