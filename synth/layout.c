/* The cage layout: ring sizes and ring counts per body part, chosen so that
 * the final mesh has about the requested number of vertices with roughly
 * square faces.
 *
 * A part of perimeter P(s) sampled by rings of n vertices has faces of
 * width P/n; rows spaced alpha * P/n apart give faces of aspect alpha. The
 * number of rows of a part is then n/alpha * J with J = integral ds / P(s),
 * measured once on the reference subject. Rings sit at equal steps of that
 * integral, so slim parts (wrists, ankles) get closely spaced rings and wide
 * ones (thighs, chest) wider ones. For each ring size m we search the alpha
 * that best meets the budget and keep the (level, m) with alpha nearest 1. */
#include "synth_internal.h"

#include <math.h>
#include <string.h>

#define NSAMP 256

/* Integral of ds / perimeter over [s0, s1] of a part; cum (NSAMP+1) gets
 * the running integral at equal steps of s. */
static double density(const mim__part_t *p, double s0, double s1, double *cum)
{
    double acc = 0, prev = 0;
    mim__key_t k;
    for (int i = 0; i <= NSAMP; i++) {
        double s = s0 + (s1 - s0) * i / NSAMP;
        mim__key_at(p, s, &k);
        double f = 1.0 / mim__key_perimeter(&k);
        if (i) acc += 0.5 * (f + prev) * (s1 - s0) / NSAMP;
        prev = f;
        if (cum) cum[i] = acc;
    }
    return acc;
}

/* n positions u in [0, 1] (first 0, last 1) at equal steps of the integral. */
static void distribute(const mim__part_t *p, double s0, double s1, uint32_t n, double *u)
{
    double cum[NSAMP + 1];
    double total = density(p, s0, s1, cum);
    if (n == 1) {
        u[0] = 0;
        return;
    }
    int seg = 0;
    for (uint32_t i = 0; i < n; i++) {
        double target = total * i / (n - 1);
        while (seg < NSAMP - 1 && cum[seg + 1] < target) seg++;
        double span = cum[seg + 1] - cum[seg];
        double t = span > 0 ? (target - cum[seg]) / span : 0;
        if (t < 0) t = 0;
        if (t > 1) t = 1;
        u[i] = (seg + t) / NSAMP;
    }
    u[0] = 0;
    u[n - 1] = 1;
}

typedef struct {
    double j_low, j_trap, j_head, j_arm, j_leg;
} integrals_t;

static uint32_t cap_vertices(uint32_t n)
{
    uint32_t v = 0;
    while (n > 8 && n % 2 == 0) {
        n /= 2;
        v += n;
    }
    return v + 1;
}

static uint32_t cap_faces(uint32_t n, uint32_t *nonquad)
{
    uint32_t f = 0;
    while (n > 8 && n % 2 == 0) {
        f += n / 2;
        *nonquad += n / 2;
        n /= 2;
    }
    *nonquad += n;
    return f + n;
}

uint32_t mim__layout_count(const mim__layout_t *lay)
{
    uint64_t m = lay->m, L = lay->L, T = 2 * m;
    uint64_t Rt = 1 + lay->n_low + lay->a + lay->n_trap;
    uint32_t pent = (uint32_t)m, nq_cap_m = 0, nq_cap_L = 0;
    uint32_t cfm = cap_faces((uint32_t)m, &nq_cap_m), cfl = cap_faces((uint32_t)L, &nq_cap_L);
    uint64_t v0 = Rt * T - 2ull * (lay->a - 1) * (lay->b - 1) + lay->nc + lay->n_head * m + cap_vertices((uint32_t)m) +
                  2 * (lay->n_arm * m + cap_vertices((uint32_t)m)) + 2 * (lay->n_leg * L + cap_vertices((uint32_t)L));
    uint64_t f0 = (Rt - 1) * T - 2ull * lay->a * lay->b + m + (lay->n_head - 1) * m + cfm +
                  2 * (lay->n_arm * m + cfm) + 2 * (lay->n_leg * L + cfl);
    uint64_t v;
    if (lay->level == 0) {
        /* pentagons and larger get a centre vertex; triangles stay */
        uint32_t ncap_pent = 0;
        uint32_t n = (uint32_t)m;
        while (n > 8 && n % 2 == 0) ncap_pent += (n /= 2);
        uint32_t nl = 0, n2 = (uint32_t)L;
        while (n2 > 8 && n2 % 2 == 0) nl += (n2 /= 2);
        v = v0 + pent + 3ull * ncap_pent + 2ull * nl;
    } else {
        v = 2 * v0 + 2 * f0 - 2; /* V + E + F with E = V + F - 2 */
    }
    return v > UINT32_MAX ? UINT32_MAX : (uint32_t)v;
}

static uint32_t rows(double j, double n, double alpha, uint32_t min)
{
    double r = floor(j * n / alpha + 0.5);
    if (r < min) r = min;
    if (r > MIM__MAXRINGS - 2) r = MIM__MAXRINGS - 2;
    return (uint32_t)r;
}

static void fill_counts(mim__layout_t *lay, const integrals_t *in, int level, uint32_t m, double alpha)
{
    lay->level = level;
    lay->m = m;
    /* the crotch: nc midline vertices from the back to the front between the
     * thighs, about as far apart as the thigh ring's vertices (the crotch is
     * ~2/7 of the loop round the top of a thigh); odd, so L stays even */
    double c = (0.29 * (m + 1) - 1) / 0.71;
    lay->nc = 1 + 2 * (uint32_t)floor(fmax(0, (c - 1) / 2) + 0.5);
    lay->L = m + 1 + lay->nc;
    /* the arm opening is a b x a patch whose boundary loop is the arm's first
     * ring (2a + 2b = m); about square, as tall as the upper arm is thick */
    lay->b = (uint32_t)floor(m / 4.0 + 0.5);
    if (lay->b < 1) lay->b = 1;
    lay->a = m / 2 - lay->b;
    lay->c0 = (m - lay->b) / 2;
    lay->n_low = rows(in->j_low, 2.0 * m, alpha, 2) + 1;
    uint32_t trap_rows = rows(in->j_trap, 2.0 * m, alpha, 1);
    lay->n_trap = trap_rows - 1;
    lay->n_head = rows(in->j_head, m, alpha, 4) + 1;
    lay->n_arm = rows(in->j_arm, m, alpha, 9) + 1;
    lay->n_leg = rows(in->j_leg, lay->L, alpha, 10) + 1;
}

int mim__layout_choose(mim__layout_t *lay, uint32_t vertices)
{
    mim__subject_t sub;
    mim__skeleton_t sk;
    mim__shape_t local, *shp = &local;
    mim__subject_reference(&sub);
    mim__skeleton_make(&sk, &sub);
    mim__shape_make(shp, &sub, &sk);
    const mim__part_t *torso = &shp->part[MIM__PART_TORSO], *head = &shp->part[MIM__PART_HEAD],
                      *arm = &shp->part[MIM__PART_ARM], *leg = &shp->part[MIM__PART_LEG];
    integrals_t in;
    in.j_low = density(torso, torso->k[0].s, torso->s_mark[0], NULL);
    in.j_trap = density(torso, torso->s_mark[1], torso->s_mark[2], NULL);
    in.j_head = density(head, head->k[0].s, head->k[head->n - 1].s, NULL);
    in.j_arm = density(arm, arm->k[0].s, arm->k[arm->n - 1].s, NULL);
    in.j_leg = density(leg, leg->k[0].s, leg->k[leg->n - 1].s, NULL);

    double best_cost = INFINITY;
    mim__layout_t cand;
    memset(&cand, 0, sizeof cand);
    for (int level = 0; level <= 1; level++) {
        for (uint32_t m = 6; m <= 120; m += 2) {
            if (level == 0 && (m < 8 || vertices > 3000)) continue;
            /* V decreases with alpha: bisect in log(alpha) */
            double lo = log(0.35), hi = log(3.0);
            double best_a = 1, best_err = INFINITY;
            for (int it = 0; it < 40; it++) {
                double mid = 0.5 * (lo + hi);
                fill_counts(&cand, &in, level, m, exp(mid));
                double v = mim__layout_count(&cand);
                double e = fabs(v - vertices) / vertices;
                if (e < best_err || (e == best_err && fabs(mid) < fabs(log(best_a)))) {
                    best_err = e;
                    best_a = exp(mid);
                }
                if (v > vertices) lo = mid;
                else hi = mid;
            }
            double cost = fabs(log(best_a)) + 20 * fmax(0, best_err - 0.02) + (level == 0 ? 0.35 : 0) +
                          (level == 1 && m < 8 ? 0.25 : 0);
            if (cost < best_cost) {
                best_cost = cost;
                fill_counts(lay, &in, level, m, best_a);
            }
        }
    }
    if (!isfinite(best_cost)) return MIM_EINVAL;
    distribute(torso, torso->k[0].s, torso->s_mark[0], lay->n_low, lay->u_low);
    distribute(head, head->k[0].s, head->k[head->n - 1].s, lay->n_head, lay->u_head);
    distribute(arm, arm->k[0].s, arm->k[arm->n - 1].s, lay->n_arm, lay->u_arm);
    distribute(leg, leg->k[0].s, leg->k[leg->n - 1].s, lay->n_leg, lay->u_leg);
    return 0;
}
