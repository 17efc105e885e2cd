/* Pose-dependent soft tissue (issue 29): real bodies are not skinned by
 * one shared rig. Their surface bulges and sags its own way in each pose
 * (muscle, fat, clothing, a scan's noise), so one subject's change of
 * surface from rest to a pose is not another's. Each (subject, pose) here
 * gets TISSUE_BUMPS smooth bulges along the surface normal: Gaussian
 * bumps centred on random vertices (chosen on the rest mesh, so a bump
 * stays on its part of the body), radius TISSUE_RADIUS_MIN..MAX, heights
 * Gaussian of standard deviation tissue_mm; seeded by subject and pose,
 * the rest pose included. mim_synth_options_t's tissue_mm 0: none.
 *
 * A store of real bodies holds scans registered onto one connectivity,
 * whose vertices sit up to centimetres off their true places along the
 * surface (bench/RESULTS.md "Registration": 11-17 mm mean at the wrists):
 * slide_mm moves them so, each (subject, pose) its own smooth field along
 * the surface (bumps of the same kind, each with a random direction,
 * projected onto the tangent plane). */
#include "synth_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TISSUE_BUMPS 24
#define TISSUE_RADIUS_MIN 0.04 /* metres */
#define TISSUE_RADIUS_MAX 0.12

void mim__tissue_apply(const mim_synth_t *s, const double *rest, uint32_t subject, uint32_t pose, double *pos)
{
    const double sigma = s->opt.tissue_mm * 1e-3, slide = s->opt.slide_mm * 1e-3;
    if (!(sigma > 0) && !(slide > 0)) return;
    const uint32_t nv = s->nv;
    double *nrm = calloc(3 * (size_t)nv, sizeof *nrm);
    if (!nrm) return; /* the body without tissue: never fails a pose */
    for (uint32_t f = 0; f < s->nf; f++) {
        const uint32_t *t = s->faces + 3 * (size_t)f;
        const double *a = pos + 3 * (size_t)t[0], *b = pos + 3 * (size_t)t[1], *c = pos + 3 * (size_t)t[2];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++) nrm[3 * (size_t)t[k] + d] += n[d];
    }
    mim_rng_t r;
    mim_rng_seed(&r, s->opt.seed, 0x7155E00000000ULL + ((uint64_t)subject << 24) + pose);
    uint32_t centre[TISSUE_BUMPS];
    double radius[TISSUE_BUMPS], height[TISSUE_BUMPS], dir[TISSUE_BUMPS][3];
    for (int k = 0; k < TISSUE_BUMPS; k++) {
        centre[k] = (uint32_t)(mim_rng_unit(&r) * nv) % nv;
        radius[k] = TISSUE_RADIUS_MIN + (TISSUE_RADIUS_MAX - TISSUE_RADIUS_MIN) * mim_rng_unit(&r);
        height[k] = sigma * mim_rng_gauss(&r);
        for (int d = 0; d < 3; d++) dir[k][d] = slide * mim_rng_gauss(&r);
    }
    for (uint32_t i = 0; i < nv; i++) {
        const double *x = rest + 3 * (size_t)i;
        double h = 0, t[3] = {0, 0, 0};
        for (int k = 0; k < TISSUE_BUMPS; k++) {
            const double *c = rest + 3 * (size_t)centre[k];
            double d2 = (x[0] - c[0]) * (x[0] - c[0]) + (x[1] - c[1]) * (x[1] - c[1]) + (x[2] - c[2]) * (x[2] - c[2]);
            if (d2 >= 9 * radius[k] * radius[k]) continue;
            const double g = exp(-0.5 * d2 / (radius[k] * radius[k]));
            h += height[k] * g;
            for (int d = 0; d < 3; d++) t[d] += dir[k][d] * g;
        }
        double *n = nrm + 3 * (size_t)i, l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(l > 0)) continue;
        const double u[3] = {n[0] / l, n[1] / l, n[2] / l}, tn = t[0] * u[0] + t[1] * u[1] + t[2] * u[2];
        for (int d = 0; d < 3; d++) pos[3 * (size_t)i + d] += h * u[d] + (t[d] - tn * u[d]);
    }
    free(nrm);
}
