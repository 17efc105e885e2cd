/* The body cage: a coarse polygon mesh made by "box modelling" rings of
 * vertices around each part, with skin weights per vertex.
 *
 *  - torso: rings of 2m from the crotch to the shoulders, vertex 0 on the
 *    front midline, m on the back midline, left (+X) half first;
 *  - legs: the torso's bottom ring and a chain of nc crotch vertices under
 *    it (midline, back to front) make two loops of m + 1 + nc (front
 *    midline F, the left half, back midline B, the crotch chain), each the
 *    first ring of a leg; the foot turns forward at the ankle;
 *  - arms: a b x a patch of torso quads on each side is removed; its
 *    boundary loop (2a + 2b = m vertices) is the arm's first ring;
 *  - neck and head: m pentagons join the torso's top ring (2m) to the neck;
 *  - ends (head, hands, feet): rings halve through pentagons down to <= 8,
 *    then a fan of triangles closes on a pole at the tip.
 * The topology depends only on the layout, never on the subject, so every
 * subject's cage has the same vertex and face lists; geometry is linear in
 * the key cross sections. Right-side parts are mirror images of the left. */
#include "synth_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct bld {
    mim__cage_t *c;
    const mim__layout_t *lay;
    const mim__skeleton_t *sk;
    const mim__shape_t *sh;
    int oom;
} bld_t;

enum { LEFT = 0, RIGHT = 1, MID = 2 };

static int grow(uint32_t **p, uint32_t *cap, uint32_t need)
{
    if (need <= *cap) return 0;
    uint32_t n = *cap ? *cap : 1024;
    while (n < need) n *= 2;
    uint32_t *q = realloc(*p, (size_t)n * sizeof *q);
    if (!q) return -1;
    *p = q;
    *cap = n;
    return 0;
}

/* A vertex at left-side position p; RIGHT stores its mirror image, MID puts
 * it exactly on the midline. Weights follow the part and ring position s. */
static uint32_t vtx(bld_t *b, mim_vec3 p, int side, int part, int ring, double s)
{
    mim__cage_t *c = b->c;
    if (b->oom) return 0;
    if (c->nv + 1 > c->cap_v) {
        uint32_t n = c->cap_v ? 2 * c->cap_v : 1024;
        double *np = realloc(c->pos, (size_t)n * 3 * sizeof *np);
        if (np) c->pos = np;
        uint8_t *nj = realloc(c->wj, (size_t)n * MIM__CW);
        if (nj) c->wj = nj;
        float *nw = realloc(c->ww, (size_t)n * MIM__CW * sizeof *nw);
        if (nw) c->ww = nw;
        if (!np || !nj || !nw) {
            b->oom = 1;
            return 0;
        }
        c->cap_v = n;
    }
    uint32_t i = c->nv++;
    if (side == MID) p.x = 0;
    c->pos[3 * i] = side == RIGHT ? -p.x : p.x;
    c->pos[3 * i + 1] = p.y;
    c->pos[3 * i + 2] = p.z;
    mim__weights(b->sk, b->sh, part, ring, s, p, side, c->wj + MIM__CW * i, c->ww + MIM__CW * i);
    return i;
}

static void face(bld_t *b, const uint32_t *v, uint32_t n)
{
    mim__cage_t *c = b->c;
    if (b->oom) return;
    if (grow(&c->fstart, &c->cap_f, c->nf + 2) || grow(&c->fv, &c->cap_c, c->ncorner + n)) {
        b->oom = 1;
        return;
    }
    if (c->nf == 0) c->fstart[0] = 0;
    memcpy(c->fv + c->ncorner, v, n * sizeof(uint32_t));
    c->ncorner += n;
    c->fstart[++c->nf] = c->ncorner;
}

static void quad(bld_t *b, uint32_t a, uint32_t q, uint32_t r, uint32_t s)
{
    uint32_t v[4] = {a, q, r, s};
    face(b, v, 4);
}

/* Quads between two rings of n vertices, ring a before ring b. */
static void bridge(bld_t *b, const uint32_t *ra, const uint32_t *rb, uint32_t n)
{
    for (uint32_t j = 0; j < n; j++) quad(b, ra[j], ra[(j + 1) % n], rb[(j + 1) % n], rb[j]);
}

/* Pentagons from a ring of 2n to a ring of n (vertex i over vertex 2i). */
static void halve(bld_t *b, const uint32_t *big, const uint32_t *small, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        uint32_t v[5] = {big[2 * i], big[2 * i + 1], big[(2 * i + 2) % (2 * n)], small[(i + 1) % n], small[i]};
        face(b, v, 5);
    }
}

/* Closes a ring (sampled from key k at angles psi) towards `tip`: halving
 * rings on a quarter-ellipse profile, then a triangle fan on a pole. */
static void cap(bld_t *b, uint32_t *ring, const double *psi_in, uint32_t n, const mim__key_t *k, mim_vec3 tip,
                int part, int side, int midline)
{
    uint32_t steps = 0;
    for (uint32_t t = n; t > 8 && t % 2 == 0; t /= 2) steps++;
    uint32_t *cur = malloc(n * sizeof *cur), *nxt = malloc(n * sizeof *nxt);
    double *psi = malloc(n * sizeof *psi);
    if (!cur || !nxt || !psi) {
        b->oom = 1;
        free(cur), free(nxt), free(psi);
        return;
    }
    memcpy(cur, ring, n * sizeof *cur);
    memcpy(psi, psi_in, n * sizeof *psi);
    mim_vec3 axis = mim_v3_sub(tip, k->c);
    double len = mim_v3_norm(axis);
    for (uint32_t st = 1; st <= steps; st++) {
        double q = (double)st / (steps + 1) * M_PI / 2;
        mim__key_t kk = *k;
        kk.c = mim_v3_add(k->c, mim_v3_scale(axis, sin(q)));
        kk.r1p *= cos(q), kk.r1n *= cos(q), kk.r2p *= cos(q), kk.r2n *= cos(q);
        kk.s = k->s + len * sin(q);
        uint32_t h = n / 2;
        for (uint32_t i = 0; i < h; i++) {
            psi[i] = psi[2 * i];
            int sd = side;
            double ang = psi[i];
            if (midline) { /* a midline part: build the right half as a mirror image */
                double sn = sin(ang);
                sd = fabs(sn) < 1e-9 ? MID : sn > 0 ? LEFT : RIGHT;
                if (sd == RIGHT) ang = 2 * M_PI - ang;
            }
            nxt[i] = vtx(b, mim__key_point(&kk, ang), sd, part, -1, kk.s);
        }
        halve(b, cur, nxt, h);
        memcpy(cur, nxt, h * sizeof *cur);
        n = h;
    }
    uint32_t pole = vtx(b, tip, midline ? MID : side, part, -1, k->s + len);
    for (uint32_t j = 0; j < n; j++) {
        uint32_t v[3] = {cur[j], cur[(j + 1) % n], pole};
        face(b, v, 3);
    }
    free(cur), free(nxt), free(psi);
}

static double smooth01(double e0, double e1, double x)
{
    double t = (x - e0) / (e1 - e0);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return t * t * (3 - 2 * t);
}

/* Angle of torso column k (0..m, left half): near the arm opening the
 * columns spread so the opening spans 2 phi around the side (90 deg). */
static double torso_angle(const mim__layout_t *lay, double phi, double beta, uint32_t k)
{
    double m = lay->m, c0 = lay->c0, b = lay->b, back = m - c0 - b;
    double uni = M_PI * k / m, pat;
    if (k <= lay->c0) pat = (M_PI / 2 - phi) * k / c0;
    else if (k <= lay->c0 + lay->b) pat = M_PI / 2 - phi + 2 * phi * (k - c0) / b;
    else pat = M_PI / 2 + phi + (M_PI / 2 - phi) * (k - c0 - b) / back;
    return uni + (pat - uni) * beta;
}

/* An angle brought into (-pi, pi]. */
static double wrap(double a)
{
    while (a > M_PI) a -= 2 * M_PI;
    while (a < -M_PI) a += 2 * M_PI;
    return a;
}

static void build(bld_t *b)
{
    const mim__layout_t *lay = b->lay;
    const mim__shape_t *sh = b->sh;
    const mim__part_t *torso = &sh->part[MIM__PART_TORSO], *head = &sh->part[MIM__PART_HEAD],
                      *arm = &sh->part[MIM__PART_ARM], *leg = &sh->part[MIM__PART_LEG];
    const uint32_t m = lay->m, T = 2 * m, L = lay->L, a = lay->a, bb = lay->b, c0 = lay->c0;
    const uint32_t r0 = lay->n_low, Rt = 1 + lay->n_low + a + lay->n_trap;
    const double H = b->sk->H;
    uint32_t *tor = malloc((size_t)Rt * T * sizeof *tor);
    uint32_t nmax = (L > m ? L : m) + 1;
    uint32_t *ra = malloc(nmax * sizeof *ra), *rb = malloc(nmax * sizeof *rb), *loop = malloc(nmax * sizeof *loop);
    double *psi = malloc(nmax * sizeof *psi), *psl = malloc(nmax * sizeof *psl);
    uint32_t *crotch = NULL;
    if (!tor || !ra || !rb || !loop || !psi || !psl) {
        b->oom = 1;
        goto out;
    }

    /* ---- torso rings ---- */
    const double s1 = torso->k[0].s, sa = torso->s_mark[0], st = torso->s_mark[1], sn = torso->s_mark[2];
    for (uint32_t r = 0; r < Rt; r++) {
        double s;
        if (r == 0) s = s1;
        else if (r <= r0) s = s1 + lay->u_low[r - 1] * (sa - s1);
        else if (r <= r0 + a) s = sa + (st - sa) * (r - r0) / a;
        else s = st + (sn - st) * (r - r0 - a) / (lay->n_trap + 1.0);
        double beta = smooth01(sa - 0.13 * H, sa - 0.01 * H, s);
        mim__key_t k;
        mim__key_at(torso, s, &k);
        for (uint32_t kk = 0; kk < T; kk++) {
            uint32_t col = kk <= m ? kk : T - kk;
            int side = (col == 0 || col == m) ? MID : kk < m ? LEFT : RIGHT;
            int removed = r > r0 && r < r0 + a && col > c0 && col < c0 + bb;
            if (removed) {
                tor[r * T + kk] = UINT32_MAX;
                continue;
            }
            mim_vec3 p;
            if (r == 0) { /* the crotch ring: two thigh loops */
                if (col == 0) p = sh->crotch_front;
                else if (col == m) p = sh->crotch_back;
                else p = mim__key_point(&sh->leg_loop, 1.5 * M_PI + (col + 1) * 2 * M_PI / L);
                tor[kk] = vtx(b, p, side, MIM__PART_LEG, 0, sh->leg_loop.s);
            } else {
                p = mim__key_point(&k, torso_angle(lay, sh->phi_patch, beta, col));
                tor[r * T + kk] = vtx(b, p, side, MIM__PART_TORSO, (int)r, s);
            }
        }
    }
    /* the crotch chain: a parabola from B through the crotch point C to F */
    crotch = malloc(lay->nc * sizeof *crotch);
    if (!crotch) {
        b->oom = 1;
        goto out;
    }
    {
        mim_vec3 P = mim_v3_sub(mim_v3_scale(sh->crotch, 2), mim_v3_scale(mim_v3_add(sh->crotch_back, sh->crotch_front), 0.5));
        for (uint32_t i = 0; i < lay->nc; i++) {
            double t = (i + 1.0) / (lay->nc + 1);
            mim_vec3 q = mim_v3_add(mim_v3_add(mim_v3_scale(sh->crotch_back, (1 - t) * (1 - t)), mim_v3_scale(P, 2 * t * (1 - t))),
                                    mim_v3_scale(sh->crotch_front, t * t));
            crotch[i] = vtx(b, q, MID, MIM__PART_LEG, 0, sh->leg_loop.s);
        }
    }
    for (uint32_t r = 0; r + 1 < Rt; r++)
        for (uint32_t kk = 0; kk < T; kk++) {
            uint32_t col = kk < m ? kk : T - 1 - kk; /* quad kk spans columns kk, kk+1 */
            if (r >= r0 && r < r0 + a && col >= c0 && col < c0 + bb) continue;
            quad(b, tor[r * T + kk], tor[r * T + (kk + 1) % T], tor[(r + 1) * T + (kk + 1) % T],
                 tor[(r + 1) * T + kk]);
        }

    /* ---- neck and head ---- */
    {
        const double s_end = head->k[head->n - 1].s;
        mim__key_t k;
        for (uint32_t r = 0; r < lay->n_head; r++) {
            double s = lay->u_head[r] * s_end;
            mim__key_at(head, s, &k);
            for (uint32_t n = 0; n < m; n++) {
                uint32_t col = n <= m / 2 ? n : m - n;
                int side = (col == 0 || 2 * col == m) ? MID : n < m / 2 ? LEFT : RIGHT;
                psi[n] = 2 * M_PI * col / m;
                rb[n] = vtx(b, mim__key_point(&k, psi[n]), side, MIM__PART_HEAD, (int)r, s);
            }
            if (r == 0) halve(b, tor + (Rt - 1) * T, rb, m);
            else bridge(b, ra, rb, m);
            memcpy(ra, rb, m * sizeof *ra);
        }
        for (uint32_t n = 0; n < m; n++) psi[n] = 2 * M_PI * n / m; /* full circle for the cap */
        cap(b, ra, psi, m, &k, head->tip, MIM__PART_HEAD, LEFT, 1);
    }

    /* ---- arms: left, then right as its mirror image ---- */
    {
        uint32_t n = 0;
        for (uint32_t c = c0; c <= c0 + bb; c++) loop[n++] = r0 * T + c;            /* bottom, front to back */
        for (uint32_t r = r0 + 1; r <= r0 + a; r++) loop[n++] = r * T + c0 + bb;   /* back, upwards */
        for (uint32_t c = c0 + bb; c-- > c0;) loop[n++] = (r0 + a) * T + c;        /* top, back to front */
        for (uint32_t r = r0 + a - 1; r > r0; r--) loop[n++] = r * T + c0;         /* front, downwards */
        /* angles of the loop seen along the arm (e1 up, e2 forward) */
        mim_vec3 cen = mim_v3(0, 0, 0);
        for (uint32_t j = 0; j < m; j++) {
            const double *q = b->c->pos + 3 * tor[loop[j]];
            cen = mim_v3_add(cen, mim_v3(q[0], q[1], q[2]));
        }
        cen = mim_v3_scale(cen, 1.0 / m);
        double turn = 0;
        for (uint32_t j = 0; j < m; j++) {
            const double *q = b->c->pos + 3 * tor[loop[j]];
            psl[j] = atan2(q[1] - cen.y, q[2] - cen.z);
            if (j) turn += wrap(psl[j] - psl[j - 1]);
        }
        double dir = turn > 0 ? 1 : -1, sx = 0, sy = 0;
        for (uint32_t j = 0; j < m; j++) {
            double d = psl[j] - dir * 2 * M_PI * j / m;
            sx += cos(d), sy += sin(d);
        }
        double psi0 = atan2(sy, sx);
        const double s_first = arm->k[0].s, s_end = arm->k[arm->n - 1].s;
        for (int side = LEFT; side <= RIGHT; side++) {
            for (uint32_t j = 0; j < m; j++) {
                uint32_t r = loop[j] / T, c = loop[j] % T;
                ra[j] = tor[r * T + (side == LEFT ? c : (T - c) % T)];
            }
            mim__key_t k;
            for (uint32_t r = 1; r <= lay->n_arm; r++) {
                double s = s_first + lay->u_arm[r - 1] * (s_end - s_first);
                mim__key_at(arm, s, &k);
                for (uint32_t j = 0; j < m; j++) {
                    double uni = psi0 + dir * 2 * M_PI * j / m;
                    psi[j] = r == 1 ? uni + 0.5 * wrap(psl[j] - uni) : uni;
                    rb[j] = vtx(b, mim__key_point(&k, psi[j]), side, MIM__PART_ARM, (int)r, s);
                }
                bridge(b, ra, rb, m);
                memcpy(ra, rb, m * sizeof *ra);
            }
            cap(b, ra, psi, m, &k, arm->tip, MIM__PART_ARM, side, 0);
        }
    }

    /* ---- legs ---- */
    {
        const double s_first = leg->k[0].s, s_end = leg->k[leg->n - 1].s;
        for (uint32_t j = 0; j < L; j++) psi[j] = 1.5 * M_PI + (j + 1) * 2 * M_PI / L;
        for (int side = LEFT; side <= RIGHT; side++) {
            ra[0] = tor[0];
            for (uint32_t j = 1; j < m; j++) ra[j] = tor[side == LEFT ? j : T - j];
            ra[m] = tor[m];
            for (uint32_t i = 0; i < lay->nc; i++) ra[m + 1 + i] = crotch[i];
            mim__key_t k;
            for (uint32_t r = 1; r <= lay->n_leg; r++) {
                double s = s_first + lay->u_leg[r - 1] * (s_end - s_first);
                mim__key_at(leg, s, &k);
                for (uint32_t j = 0; j < L; j++)
                    rb[j] = vtx(b, mim__key_point(&k, psi[j]), side, MIM__PART_LEG, (int)r, s);
                bridge(b, ra, rb, L);
                memcpy(ra, rb, L * sizeof *ra);
            }
            cap(b, ra, psi, L, &k, leg->tip, MIM__PART_LEG, side, 0);
        }
    }
out:
    free(tor), free(ra), free(rb), free(loop), free(psi), free(psl), free(crotch);
}

int mim__cage_build(mim__cage_t *c, const mim__layout_t *lay, const mim__subject_t *sub)
{
    memset(c, 0, sizeof *c);
    mim__skeleton_t sk;
    mim__shape_t sh;
    mim__skeleton_make(&sk, sub);
    mim__shape_make(&sh, sub, &sk);
    bld_t b = {c, lay, &sk, &sh, 0};
    build(&b);
    if (b.oom) {
        mim__cage_free(c);
        return MIM_ENOMEM;
    }
    return 0;
}

void mim__cage_free(mim__cage_t *c)
{
    free(c->pos), free(c->fstart), free(c->fv), free(c->wj), free(c->ww);
    memset(c, 0, sizeof *c);
}
