/* Body-part cross sections ("keys") of one subject, built on its skeleton.
 *
 * Each part (torso, head with neck, left arm with hand, left leg with foot)
 * is a list of keys along the part: a centre, two axes and four radii (one per
 * side, so the calf can bulge backwards and the chin forwards). Rings of the
 * cage sample the keys at any position; the radii and centres are
 * interpolated with monotone-limited cubic Hermite curves so that a finer
 * cage does not show the keys as kinks. Dimensions are fractions of stature
 * (adult anthropometric averages, e.g. neck circumference 0.22 H, waist
 * 0.46 H, calf 0.22 H), scaled by the subject's width and girth multipliers. */
#include "synth_internal.h"

#include <math.h>
#include <string.h>

static mim__key_t key(double s, mim_vec3 c, mim_vec3 e1, mim_vec3 e2, double r1p, double r1n, double r2p,
                      double r2n, double p)
{
    mim__key_t k = {s, c, mim_v3_normalize(e1), mim_v3_normalize(e2), r1p, r1n, r2p, r2n, p};
    return k;
}

static void push(mim__part_t *p, mim__key_t k)
{
    if (p->n < MIM__MAXKEYS) p->k[p->n++] = k;
}

/* s of each key = distance along the polyline of centres (from s0). */
static void arclength(mim__part_t *p, double s0)
{
    double s = s0;
    for (int i = 0; i < p->n; i++) {
        if (i) s += mim_v3_norm(mim_v3_sub(p->k[i].c, p->k[i - 1].c));
        p->k[i].s = s;
    }
}

/* Point on the segment a-b at height y (clamped). */
static mim_vec3 at_y(mim_vec3 a, mim_vec3 b, double y)
{
    double t = (a.y == b.y) ? 0 : (y - a.y) / (b.y - a.y);
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    return mim_v3_lerp(a, b, t);
}

static void make_torso(mim__shape_t *sh, const mim__subject_t *sub, const mim__skeleton_t *sk)
{
    mim__part_t *p = &sh->part[MIM__PART_TORSO];
    double H = sk->H;
    double yh = sk->j[MIM__J_PELVIS].y, yn = sk->j[MIM__J_NECK].y;
    /* heights are given for the reference proportions (hip 0.515, C7 0.834)
     * and stretched to this subject's torso */
#define TY(f) (yh + ((f) - 0.515) / (0.834 - 0.515) * (yn - yh))
    /* girth widens the torso less than it deepens it; at the arm opening the
     * width follows the shoulder joint, so the arm always leaves the torso
     * inside its first ring */
    double hw = H * (1 + 0.5 * (sub->girth - 1)), sw = sub->shoulder, hp = sub->hip, g = H * sub->girth;
    double wb = 0.5 * (sw + hp);
    double xs = sk->j[MIM__J_LUARM].x * (1 + 0.12 * (sub->girth - 1)) / H;
    mim_vec3 X = mim_v3(1, 0, 0), Z = mim_v3(0, 0, 1);
    const struct {
        double y, hw, df, db, zc, p;
    } t[] = {
        /* y       half width              front depth                  back depth  z centre  p */
        {0.527, 0.101 * hp,  0.050,                          0.063, -0.004, 2.4}, /* hips, buttocks */
        {0.565, 0.093 * hp,  0.051 * sub->belly,             0.054, -0.001, 2.3}, /* iliac crest */
        {0.610, 0.082 * wb,  0.053 * sub->belly,             0.046, 0.002,  2.2}, /* waist */
        {0.655, 0.086 * sw,  0.055 * (0.5 * sub->belly + 0.5 * sub->chest), 0.050, 0.002, 2.2},
        {0.705, 0.092 * sw,  0.061 * sub->chest,             0.056, 0.000,  2.3}, /* chest */
        {0.748, 0.92 * xs,   0.058 * sub->chest,             0.057, -0.001, 2.5}, /* armpit */
        {0.790, 0.93 * xs,   0.051,                          0.055, -0.003, 2.5},
        {0.826, 0.91 * xs,   0.040,                          0.047, -0.005, 2.4}, /* shoulder top */
        {0.843, 0.62 * xs,   0.036,                          0.041, -0.009, 2.1}, /* trapezius */
    };
    p->n = 0;
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
        double y = TY(t[i].y), w = i >= 5 ? H * t[i].hw : t[i].hw * hw;
        push(p, key(y, mim_v3(0, y, t[i].zc * H), X, Z, w, w, t[i].df * g, t[i].db * g, t[i].p));
    }
    /* the last torso key is the neck base, the same ring as the head's first */
    double yb = TY(0.855), rn = 0.036 * H * (0.5 + 0.5 * sub->girth);
    push(p, key(yb, mim_v3(0, yb, -0.010 * H), X, Z, rn, rn, rn * 0.97, rn * 0.97, 2.0));
    /* along the torso s is height up to the shoulder top, then the slope
     * length over the trapezius (the rings there shrink inwards) */
    for (int i = 1; i < p->n; i++) {
        double dy = p->k[i].c.y - p->k[i - 1].c.y, dx = p->k[i].r1p - p->k[i - 1].r1p;
        p->k[i].s = p->k[i - 1].s + (i >= p->n - 2 ? sqrt(dx * dx + dy * dy) : dy);
    }
    p->s_mark[0] = p->k[5].s; /* armpit */
    p->s_mark[1] = p->k[7].s; /* shoulder top */
    p->s_mark[2] = p->k[p->n - 1].s;
#undef TY
}

static void make_head(mim__shape_t *sh, const mim__subject_t *sub, const mim__skeleton_t *sk)
{
    mim__part_t *p = &sh->part[MIM__PART_HEAD];
    double H = sk->H, yn = sk->j[MIM__J_NECK].y, hd = sub->head;
#define HY(f) (yn + ((f) - 0.834) / (1.0 - 0.834) * (H - yn))
    mim_vec3 X = mim_v3(1, 0, 0), Z = mim_v3(0, 0, 1);
    double rn = 0.036 * H * (0.5 + 0.5 * sub->girth), hs = H * hd;
    const struct {
        double y, zc, rx, rzp, rzn;
    } t[] = {
        /* head length 0.112 H, breadth 0.09 H; the face sits forwards of the neck */
        {0.867, -0.008, 0.030, 0.031, 0.031}, /* neck */
        {0.880, -0.004, 0.032, 0.037, 0.032}, /* under the chin */
        {0.891, 0.007, 0.038, 0.047, 0.040},  /* jaw, chin */
        {0.906, 0.010, 0.042, 0.050, 0.048},  /* mouth */
        {0.926, 0.008, 0.045, 0.052, 0.055},  /* nose, cheekbones */
        {0.946, 0.006, 0.046, 0.050, 0.057},  /* eyes */
        {0.966, 0.004, 0.044, 0.046, 0.054},  /* forehead */
        {0.982, 0.002, 0.037, 0.038, 0.045},
        {0.993, 0.000, 0.026, 0.027, 0.032},  /* crown */
    };
    p->n = 0;
    double yb = HY(0.855);
    push(p, key(yb, mim_v3(0, yb, -0.010 * H), X, Z, rn, rn, rn * 0.97, rn * 0.97, 2.0));
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
        double y = HY(t[i].y);
        double r = i == 0 ? rn / (0.036 * H) : hd; /* neck follows girth, head its size */
        push(p, key(y, mim_v3(0, y, t[i].zc * hs), X, Z, t[i].rx * H * r, t[i].rx * H * r, t[i].rzp * H * r,
                    t[i].rzn * H * r, 2.0));
    }
    arclength(p, 0);
    p->tip = mim_v3(0, H - 0.0005 * H, -0.002 * hs);
#undef HY
}

static void make_arm(mim__shape_t *sh, const mim__subject_t *sub, const mim__skeleton_t *sk)
{
    mim__part_t *p = &sh->part[MIM__PART_ARM];
    double H = sk->H, lr = H * sub->limb, hr = H * (0.5 + 0.5 * sub->limb);
    mim_vec3 S = sk->j[MIM__J_LUARM], d = mim__arm_dir(), lat = mim__arm_lat(), Z = mim_v3(0, 0, 1);
    double ua = sk->ua, fa = sk->fa, w = ua + fa;
    const struct {
        double t, up, tilt, r1p, r1n, r2p, r2n, p;
        int hand;
    } t[] = {
        /* along the arm  offset  tilt  outer  inner  front  back */
        {0.012 * H, 0.006 * H, 0.55, 0.034, 0.026, 0.032, 0.033, 2.0, 0}, /* deltoid */
        {0.050 * H, 0.002 * H, 0.15, 0.030, 0.027, 0.028, 0.029, 2.0, 0},
        {0.090 * H, 0, 0, 0.026, 0.025, 0.027, 0.027, 2.0, 0},   /* biceps */
        {ua - 0.035 * H, 0, 0, 0.021, 0.021, 0.021, 0.022, 2.0, 0},
        {ua, 0, 0, 0.021, 0.019, 0.019, 0.021, 2.0, 0},           /* elbow */
        {ua + 0.035 * H, 0, 0, 0.023, 0.021, 0.021, 0.021, 2.0, 0}, /* forearm muscles */
        {ua + 0.080 * H, 0, 0, 0.019, 0.018, 0.018, 0.018, 2.0, 0},
        {w - 0.020 * H, 0, 0, 0.012, 0.012, 0.016, 0.016, 2.2, 1},
        {w, 0, 0, 0.0105, 0.0105, 0.0165, 0.0165, 2.3, 1},         /* wrist */
        {w + 0.030 * H, 0, 0, 0.011, 0.012, 0.025, 0.025, 2.6, 1},  /* palm */
        {w + 0.058 * H, 0, 0, 0.009, 0.009, 0.025, 0.024, 2.6, 1},  /* knuckles */
        {w + 0.080 * H, 0, 0, 0.007, 0.007, 0.021, 0.020, 2.4, 1},  /* fingers */
        {w + 0.097 * H, 0, 0, 0.0055, 0.0055, 0.015, 0.014, 2.2, 1},
    };
    p->n = 0;
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
        double r = t[i].hand ? hr : lr;
        mim_vec3 c = mim_v3_add(mim_v3_add(S, mim_v3_scale(d, t[i].t)), mim_v3_scale(lat, t[i].up));
        mim_vec3 e1 = mim_v3_add(mim_v3_scale(lat, 1 - t[i].tilt), mim_v3_scale(mim_v3(0, 1, 0), t[i].tilt));
        mim__key_t k = key(t[i].t, c, e1, Z, t[i].r1p * r, t[i].r1n * r, t[i].r2p * r, t[i].r2n * r, t[i].p);
        k.s = t[i].t;
        push(p, k);
    }
    p->tip = mim_v3_add(S, mim_v3_scale(d, w + sk->hand * 0.985));
    p->s_mark[0] = 0;      /* shoulder joint */
    p->s_mark[1] = ua;     /* elbow */
    p->s_mark[2] = w;      /* wrist */
}

static void make_leg(mim__shape_t *sh, const mim__subject_t *sub, const mim__skeleton_t *sk)
{
    mim__part_t *p = &sh->part[MIM__PART_LEG];
    double H = sk->H, lr = H * sub->limb, gr = H * sqrt(sub->limb * sub->girth);
    mim_vec3 Jh = sk->j[MIM__J_LTHIGH], Jk = sk->j[MIM__J_LSHIN], Ja = sk->j[MIM__J_LFOOT];
    mim_vec3 X = mim_v3(1, 0, 0), Z = mim_v3(0, 0, 1);
    double yk = Jk.y, ya = Ja.y;
    p->n = 0;
    /* thigh and shank: rings on the bone lines, e1 outwards, e2 forwards */
    const struct {
        double y, r1p, r1n, r2p, r2n;
        int top;
    } t[] = {
        {sk->y_crotch - 0.022 * H, 0.057, 0.045, 0.050, 0.055, 1}, /* under the gluteal fold */
        {0.5 * (Jh.y + yk), 0.047, 0.043, 0.047, 0.046, 1},        /* mid thigh */
        {yk + 0.055 * H, 0.036, 0.036, 0.038, 0.034, 0},
        {yk, 0.031, 0.032, 0.034, 0.031, 0},                        /* knee */
        {yk - 0.040 * H, 0.031, 0.031, 0.031, 0.034, 0},
        {yk - 0.085 * H, 0.033, 0.033, 0.029, 0.043, 0},            /* calf */
        {yk - 0.150 * H, 0.025, 0.025, 0.024, 0.029, 0},
        {ya + 0.045 * H, 0.020, 0.020, 0.021, 0.021, 0},
        {ya + 0.006 * H, 0.023, 0.022, 0.022, 0.025, 0},            /* ankle */
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
        mim_vec3 c = t[i].y > yk ? at_y(Jh, Jk, t[i].y) : at_y(Jk, Ja, t[i].y);
        if (t[i].y < ya + 0.01 * H) c = mim_v3(Ja.x, t[i].y, Ja.z);
        double r = t[i].top ? gr : lr;
        /* heavy thighs may touch but never cross the midline */
        double inner = fmin(t[i].r1n * r, c.x - 0.008 * H);
        push(p, key(0, c, X, Z, t[i].r1p * r, inner, t[i].r2p * r, t[i].r2n * r, 2.0));
    }
    /* the foot: the tube turns forward, e2 goes from the front of the shin
     * to the top of the foot and -e2 from the Achilles tendon to the sole */
    const struct {
        double beta, dx, y, z, r1p, r1n, r2p, r2n, p;
    } f[] = {
        {40, 0.000, 0.026, 0.012, 0.026, 0.024, 0.024, 0.036, 2.3}, /* heel */
        {75, 0.002, 0.024, 0.045, 0.029, 0.026, 0.021, 0.023, 2.8}, /* arch */
        {88, 0.004, 0.017, 0.085, 0.031, 0.028, 0.014, 0.016, 3.0}, /* ball */
        {90, 0.005, 0.013, 0.106, 0.026, 0.024, 0.009, 0.011, 2.6}, /* toes */
    };
    for (size_t i = 0; i < sizeof f / sizeof f[0]; i++) {
        double b = f[i].beta * M_PI / 180;
        mim_vec3 c = mim_v3(Ja.x + f[i].dx * H, f[i].y * H, Ja.z + f[i].z * H);
        double r = H * (0.6 + 0.4 * sub->limb);
        push(p, key(0, c, X, mim_v3(0, sin(b), cos(b)), f[i].r1p * r, f[i].r1n * r, f[i].r2p * r, f[i].r2n * r,
                    f[i].p));
    }
    arclength(p, 0);
    p->tip = sk->toe_tip;
    p->s_mark[1] = p->k[3].s; /* knee */
    p->s_mark[2] = p->k[8].s; /* ankle */

    /* where the thigh leaves the torso: a ring tilted up towards the hip */
    double yl = sk->y_crotch + 0.014 * H;
    mim_vec3 cl = at_y(Jh, Jk, yl);
    double tl = 14 * M_PI / 180;
    sh->leg_loop = key(0, cl, mim_v3(cos(tl), sin(tl), 0), Z, 0.064 * H * sub->hip * sub->girth,
                       fmin(0.05 * gr, cl.x - 0.006 * H), 0.052 * gr, 0.060 * gr, 2.3);
    sh->leg_loop.s = -mim_v3_norm(mim_v3_sub(cl, p->k[0].c));
    p->s_mark[0] = sh->leg_loop.s - (Jh.y - yl); /* hip joint, above the loop */
    double gc = H * sub->girth;
    sh->crotch_front = mim_v3(0, sk->y_crotch + 0.020 * H, 0.040 * gc * sub->belly);
    sh->crotch_back = mim_v3(0, sk->y_crotch + 0.014 * H, -0.047 * gc);
    sh->crotch = mim_v3(0, sk->y_crotch - 0.006 * H, -0.004 * H);
}

void mim__shape_make(mim__shape_t *sh, const mim__subject_t *sub, const mim__skeleton_t *sk)
{
    memset(sh, 0, sizeof *sh);
    make_torso(sh, sub, sk);
    make_head(sh, sub, sk);
    make_arm(sh, sub, sk);
    make_leg(sh, sub, sk);
    sh->phi_patch = 36.0 * M_PI / 180.0;
}

/* Hermite tangent at key i for one scalar, limited so curves do not
 * overshoot between keys (zero at local extrema, as Fritsch-Carlson). */
static double tangent(const mim__part_t *p, int i, const double *v)
{
    int n = p->n;
    if (n < 2) return 0;
    if (i == 0) return (v[1] - v[0]) / (p->k[1].s - p->k[0].s);
    if (i == n - 1) return (v[n - 1] - v[n - 2]) / (p->k[n - 1].s - p->k[n - 2].s);
    double h0 = p->k[i].s - p->k[i - 1].s, h1 = p->k[i + 1].s - p->k[i].s;
    double d0 = (v[i] - v[i - 1]) / h0, d1 = (v[i + 1] - v[i]) / h1;
    if (d0 * d1 <= 0) return 0;
    double m = (d0 * h1 + d1 * h0) / (h0 + h1);
    double lim = 3 * fmin(fabs(d0), fabs(d1));
    return fabs(m) > lim ? copysign(lim, m) : m;
}

#define NSCAL 16
static void key_scalars(const mim__key_t *k, double *v)
{
    double t[NSCAL] = {k->c.x, k->c.y, k->c.z, k->e1.x, k->e1.y, k->e1.z, k->e2.x, k->e2.y,
                       k->e2.z, k->r1p, k->r1n, k->r2p, k->r2n, k->p, 0, 0};
    memcpy(v, t, sizeof t);
}

void mim__key_at(const mim__part_t *p, double s, mim__key_t *out)
{
    int n = p->n;
    if (s <= p->k[0].s || n == 1) {
        *out = p->k[0];
        out->s = s;
        return;
    }
    if (s >= p->k[n - 1].s) {
        *out = p->k[n - 1];
        out->s = s;
        return;
    }
    int i = 0;
    while (i < n - 2 && s > p->k[i + 1].s) i++;
    double h = p->k[i + 1].s - p->k[i].s, t = (s - p->k[i].s) / h;
    double h00 = (1 + 2 * t) * (1 - t) * (1 - t), h10 = t * (1 - t) * (1 - t), h01 = t * t * (3 - 2 * t),
           h11 = t * t * (t - 1);
    double r[NSCAL];
    double col[MIM__MAXKEYS];
    double a[NSCAL], b[NSCAL];
    key_scalars(&p->k[i], a);
    key_scalars(&p->k[i + 1], b);
    for (int c = 0; c < 14; c++) {
        for (int j = 0; j < n; j++) {
            double v[NSCAL];
            key_scalars(&p->k[j], v);
            col[j] = v[c];
        }
        r[c] = h00 * a[c] + h10 * h * tangent(p, i, col) + h01 * b[c] + h11 * h * tangent(p, i + 1, col);
    }
    out->s = s;
    out->c = mim_v3(r[0], r[1], r[2]);
    /* axes: orthonormalise, keeping e2 */
    mim_vec3 e2 = mim_v3_normalize(mim_v3(r[6], r[7], r[8]));
    mim_vec3 e1 = mim_v3(r[3], r[4], r[5]);
    e1 = mim_v3_normalize(mim_v3_sub(e1, mim_v3_scale(e2, mim_v3_dot(e1, e2))));
    out->e1 = e1;
    out->e2 = e2;
    out->r1p = r[9];
    out->r1n = r[10];
    out->r2p = r[11];
    out->r2n = r[12];
    out->p = r[13];
}

static double spow(double t, double e) { return t < 0 ? -pow(-t, e) : pow(t, e); }

mim_vec3 mim__key_point(const mim__key_t *k, double psi)
{
    double u = sin(psi), v = cos(psi), e = 2.0 / k->p;
    double a = (u >= 0 ? k->r1p : k->r1n) * spow(u, e);
    double b = (v >= 0 ? k->r2p : k->r2n) * spow(v, e);
    return mim_v3_add(k->c, mim_v3_add(mim_v3_scale(k->e1, a), mim_v3_scale(k->e2, b)));
}

double mim__key_perimeter(const mim__key_t *k)
{
    double a = 0.5 * (k->r1p + k->r1n), b = 0.5 * (k->r2p + k->r2n);
    return M_PI * (3 * (a + b) - sqrt((3 * a + b) * (a + 3 * b)));
}
