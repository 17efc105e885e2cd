/* The annotations as the likelihood's evidence (seed 002 Sections 4.2-4.3
 * and 5.2): each annotation once normalised (pairs2d.c), triangulated for
 * its interaction coordinates, given its view in the pair's local frame
 * (eq. 4, view_estimate.c) and its motion differentials of eq. 12 towards
 * the next frame of its shot. Built once; read by every chain. */
#include "internal.h"
#include "mim_sample_mcmc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct item {
    double pts[2 * MIM_PAIR_JOINTS]; /* normalised */
    double dir[3];                   /* the view, a unit vector in the local frame */
    mim_ic_t ic;
    float vel2[MIM_PAIRS_GROUPS]; /* squared differentials; -1 where none */
    uint32_t shot, frame;
} item_t;

struct mim_pairs_evidence {
    uint32_t n;
    item_t *item;
    float (*sc)[MIM_PAIR_JOINTS][MIM__SC2_BINS]; /* shape contexts, for the shape density only */
    double *views;                                /* psi, phi per item */
};

uint32_t mim_pairs_evidence_count(const mim_pairs_evidence_t *e) { return e->n; }
const double *mim_pairs_evidence_views(const mim_pairs_evidence_t *e) { return e->views; }

/* For the likelihood (likelihood.c). */
const double *mim__evidence_points(const mim_pairs_evidence_t *e, uint32_t i) { return e->item[i].pts; }
const double *mim__evidence_dir(const mim_pairs_evidence_t *e, uint32_t i) { return e->item[i].dir; }
const mim_ic_t *mim__evidence_ic(const mim_pairs_evidence_t *e, uint32_t i) { return &e->item[i].ic; }
const float *mim__evidence_sc(const mim_pairs_evidence_t *e, uint32_t i) { return e->sc ? &e->sc[i][0][0] : NULL; }

static double angle2(const double *p, int a, int b)
{
    return atan2(p[2 * b + 1] - p[2 * a + 1], p[2 * b] - p[2 * a]);
}

/* |change| of a 2D line's angle between two annotations, wrapped; NaN
 * when the line has no length in either. */
static double turn(const double *p, const double *q, int a, int b)
{
    double lp = hypot(p[2 * b] - p[2 * a], p[2 * b + 1] - p[2 * a + 1]);
    double lq = hypot(q[2 * b] - q[2 * a], q[2 * b + 1] - q[2 * a + 1]);
    if (lp < 1e-6 || lq < 1e-6) return NAN;
    double d = remainder(angle2(q, a, b) - angle2(p, a, b), 2 * M_PI);
    return fabs(d);
}

enum { CHEST = 1, PELVIS = 2, NECK = 16 };

/* eq. 12's differentials of p towards its shot's next frame q: per
 * rotation, the turn of the joint's bones (the mean over its children);
 * a root's, the turn of its pelvis-to-neck line; B's translation, the
 * move of B's pelvis relative to A's (unit RMS radius). */
static void differentials(const double *p, const double *q, float vel2[MIM_PAIRS_GROUPS])
{
    for (int g = 0; g < MIM_PAIRS_GROUPS; g++) vel2[g] = -1;
    for (int person = 0; person < 2; person++) {
        int o = person * MIM_PAIR_PERSON_JOINTS;
        for (int r = 0; r < MIM_PAIRS_ROT; r++) {
            int k = mim_pairs_rot_joint[r];
            double sum = 0;
            int cnt = 0;
            if (r == 0) {
                double t = turn(p, q, o + PELVIS, o + NECK);
                if (isfinite(t)) sum = t, cnt = 1;
            } else
                for (int c = 0; c < MIM_PAIR_PERSON_JOINTS; c++) {
                    if (mim_pairs_parent[c] != k) continue;
                    double t = turn(p, q, o + k, o + c);
                    if (isfinite(t)) sum += t, cnt++;
                }
            if (cnt) vel2[person * MIM_PAIRS_ROT + r] = (float)((sum / cnt) * (sum / cnt));
        }
    }
    int a = PELVIS, b = MIM_PAIR_PERSON_JOINTS + PELVIS;
    double dx = (q[2 * b] - q[2 * a]) - (p[2 * b] - p[2 * a]), dy = (q[2 * b + 1] - q[2 * a + 1]) - (p[2 * b + 1] - p[2 * a + 1]);
    vel2[MIM_PAIRS_GROUP_TRANS(1)] = (float)(dx * dx + dy * dy);
}

static int by_shot_frame(const void *x, const void *y)
{
    const item_t *a = x, *b = y;
    if (a->shot != b->shot) return a->shot < b->shot ? -1 : 1;
    return a->frame < b->frame ? -1 : a->frame > b->frame;
}

int mim_pairs_evidence_build(const mim_pairs_annotations_t *ann, const mim_pairs_torso_t *torso, mim_pairs_density_t density,
                             mim_pairs_evidence_t **out, uint32_t *dropped, mim_progress_t *progress, mim_error_t *err)
{
    *out = NULL;
    if (dropped) *dropped = 0;
    mim_pairs_evidence_t *e = calloc(1, sizeof *e);
    if (!e || !(e->item = malloc((size_t)(ann->n ? ann->n : 1) * sizeof *e->item))) {
        free(e);
        return mim_error_set(err, MIM_ENOMEM, "annotations: out of memory for %u", ann->n);
    }
    mim_progress_t quiet = {0};
    if (!progress) progress = &quiet;
    mim_progress_begin(progress, "annotations", ann->n);
    for (uint32_t i = 0; i < ann->n; i++) {
        if ((i & 255) == 0) mim_progress_update(progress, i);
        item_t *it = &e->item[e->n];
        const double *uv = ann->points + (size_t)i * 2 * MIM_PAIR_JOINTS;
        double psi, phi;
        mim_error_t ic_err = {0};
        if (!mim_pairs2d_normalise(uv, it->pts) ||
            mim_pairs_annotation_view(torso, uv, ann->width, ann->height, &psi, &phi) ||
            mim_ic_build(it->pts, 2, &it->ic, &ic_err)) {
            if (dropped) (*dropped)++;
            continue;
        }
        it->dir[0] = sin(phi) * cos(psi), it->dir[1] = cos(phi), it->dir[2] = sin(phi) * sin(psi);
        it->shot = ann->shot ? ann->shot[i] : MIM_PAIRS_NO_SHOT, it->frame = ann->frame[i];
        e->n++;
    }
    mim_progress_end(progress);
    if (!e->n) {
        mim_pairs_evidence_free(&e);
        return mim_error_set(err, MIM_EEMPTY, "annotations: no annotation has a view that can be estimated (two torsos apart)");
    }
    /* eq. 12: consecutive frames of a shot (photos have no next frame) */
    qsort(e->item, e->n, sizeof *e->item, by_shot_frame);
    for (uint32_t i = 0; i < e->n; i++) {
        item_t *it = &e->item[i];
        for (int g = 0; g < MIM_PAIRS_GROUPS; g++) it->vel2[g] = -1;
        if (it->shot == MIM_PAIRS_NO_SHOT) continue;
        if (i + 1 < e->n && e->item[i + 1].shot == it->shot) differentials(it->pts, e->item[i + 1].pts, it->vel2);
        else if (i > 0 && e->item[i - 1].shot == it->shot) differentials(e->item[i - 1].pts, it->pts, it->vel2);
    }
    e->views = malloc((size_t)e->n * 2 * sizeof *e->views);
    if (density == MIM_DENSITY_SHAPE) e->sc = malloc((size_t)e->n * sizeof *e->sc);
    if (!e->views || (density == MIM_DENSITY_SHAPE && !e->sc)) {
        mim_pairs_evidence_free(&e);
        return mim_error_set(err, MIM_ENOMEM, "annotations: out of memory for %u", ann->n);
    }
    for (uint32_t i = 0; i < e->n; i++) {
        const double *d = e->item[i].dir;
        e->views[2 * i] = atan2(d[2], d[0]), e->views[2 * i + 1] = acos(fmax(-1.0, fmin(1.0, d[1])));
        if (e->sc) mim__pairs2d_shape_contexts(e->item[i].pts, e->sc[i]);
    }
    *out = e;
    return 0;
}

void mim_pairs_evidence_free(mim_pairs_evidence_t **e)
{
    if (!e || !*e) return;
    free((*e)->item), free((*e)->sc), free((*e)->views);
    free(*e);
    *e = NULL;
}

void mim_pairs_velocity(const mim_pairs_evidence_t *e, const uint32_t *nearest, uint32_t m, double rms_radius,
                        double out[MIM_PAIRS_GROUPS])
{
    for (int g = 0; g < MIM_PAIRS_GROUPS; g++) {
        double sum = 0;
        uint32_t cnt = 0;
        for (uint32_t i = 0; i < m; i++) {
            if (nearest[i] >= e->n) continue;
            float v = e->item[nearest[i]].vel2[g];
            if (v >= 0) sum += v, cnt++;
        }
        /* eq. 12: the mean over the members of D* that have a next frame */
        out[g] = cnt ? sum / cnt : 0.0;
        if (g >= MIM_PAIRS_GROUP_TRANS(0)) out[g] *= rms_radius * rms_radius;
    }
}
