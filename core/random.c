/* The one seeded random generator: splitmix64 (Steele, Lea, Flood 2014).
 * It gives the same stream on every machine and compiler, which keeps synth
 * datasets byte-identical for a seed and index builds reproducible. The
 * state is the caller's: nothing here is process-wide. */
#include "mim_core.h"

#include <math.h>

static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

void mim_rng_seed(mim_rng_t *r, uint64_t seed, uint64_t stream)
{
    r->s = mix64(seed ^ mix64(stream + 0x9e3779b97f4a7c15ULL));
}

uint64_t mim_rng_u64(mim_rng_t *r)
{
    r->s += 0x9e3779b97f4a7c15ULL;
    return mix64(r->s);
}

double mim_rng_unit(mim_rng_t *r)
{
    return (double)(mim_rng_u64(r) >> 11) * (1.0 / 9007199254740992.0);
}

uint64_t mim_rng_below(mim_rng_t *r, uint64_t n)
{
    if (n <= 1)
        return 0;
    /* rejection keeps every value equally likely (no modulo bias) */
    uint64_t limit = UINT64_MAX - UINT64_MAX % n, x;
    do
        x = mim_rng_u64(r);
    while (x >= limit);
    return x % n;
}

double mim_rng_gauss(mim_rng_t *r)
{
    /* Box-Muller; 1 - u keeps the logarithm's argument in (0, 1] */
    double u = 1.0 - mim_rng_unit(r), v = mim_rng_unit(r);
    return sqrt(-2.0 * log(u)) * cos(6.283185307179586 * v);
}
