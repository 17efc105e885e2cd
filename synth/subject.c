/* Subject shape parameters from (seed, subject index).
 *
 * Core's seeded generator (mim_rng_*, splitmix64) gives the same stream on
 * every machine and compiler, which keeps the datasets byte-identical for a
 * seed. Each subject draws from its own stream (seed, index), so subject k
 * does not depend on how many subjects are made. */
#include "synth_internal.h"

#include <math.h>

/* The average adult the connectivity and landmarks are designed on. */
void mim__subject_reference(mim__subject_t *sub)
{
    sub->height = 1.74;
    sub->masc = 0.5;
    sub->weight = 0.4;
    sub->leg = sub->arm = 1.0;
    sub->shoulder = sub->hip = 1.0;
    sub->girth = sub->limb = 1.0;
    sub->belly = sub->chest = 1.0;
    sub->head = 1.0;
}

#define HEIGHT_MIN 1.52
#define HEIGHT_MAX 1.93

void mim__subject_make(mim__subject_t *sub, uint64_t seed, uint32_t index)
{
    /* Statures follow a golden-ratio sequence from a seeded start, so any few
     * consecutive subjects are well spread (>= 6 cm apart for the first 4). */
    mim_rng_t r;
    mim_rng_seed(&r, seed, 0x5eedu);
    double start = mim_rng_unit(&r);
    double g = start + (double)index * 0.6180339887498949;
    g -= floor(g);
    sub->height = HEIGHT_MIN + (HEIGHT_MAX - HEIGHT_MIN) * g;

    mim_rng_seed(&r, seed, 0x100000000ULL + index);
    double u[12];
    for (int i = 0; i < 12; i++) u[i] = mim_rng_unit(&r);
    /* taller people are a little more often masculine, not always */
    sub->masc = fmin(1.0, fmax(0.0, 0.75 * u[0] + 0.25 * g + 0.05));
    sub->weight = u[1];
    sub->leg = 0.955 + 0.09 * u[2];
    sub->arm = 0.955 + 0.09 * u[3];
    sub->shoulder = (0.93 + 0.13 * sub->masc) * (0.97 + 0.06 * u[4]);
    sub->hip = (1.07 - 0.12 * sub->masc) * (0.97 + 0.06 * u[5]);
    sub->girth = 0.9 + 0.24 * sub->weight + 0.04 * (u[6] - 0.5);
    sub->limb = (0.92 + 0.1 * u[7]) * (0.93 + 0.17 * sub->weight);
    sub->belly = 0.85 + 0.55 * sub->weight * sub->weight + 0.1 * u[8];
    sub->chest = 0.95 + 0.12 * (1.0 - sub->masc) * u[9] + 0.06 * u[10];
    sub->head = 0.96 + 0.08 * u[11];
}
