/* The Delaunay tetrahedra of a few points in 3D, for the interaction
 * coordinates' edges (ic.c), in a fraction of qhull's time: Bowyer-Watson
 * (each point in turn removes the tetrahedra whose circumsphere holds it
 * and joins itself to the hole's faces), started inside a tetrahedron far
 * around the points. It answers only when its answer is proven, with a
 * margin far above double rounding (TOL of a bound on each determinant's
 * products, of its degree in lengths: the same at any scale), to be the
 * one Delaunay tetrahedralisation of the points:
 *
 * - every tetrahedron ever made is positively oriented, so that each hole
 *   was star-shaped from its point (a ray from it crosses only faces that
 *   face away) and the tetrahedra always tile the outer one;
 * - every face between two tetrahedra of the points themselves is locally
 *   Delaunay (the far vertex of each outside the other's circumsphere),
 *   and every other face of theirs is a face of the points' convex hull
 *   (every point on its inner side): they tile the hull, and a tiling
 *   locally Delaunay everywhere is Delaunay;
 * - every point is a vertex.
 *
 * Otherwise (five points nearly on a sphere, four nearly on a plane, or a
 * hull tetrahedron whose circumsphere reaches the outer vertices) it
 * declines, and qhull decides: its answer is the same wherever this one
 * answers, as no choice was near (tests/test_delaunay.c), and where the
 * points are far from the origin for their size, qhull's lifting has lost
 * the digits that decide and this answer is the exact one. It declined 91
 * of 100 000 sampled pose-pairs, and answered the rest in 53 us each
 * against qhull's 135 (bench/RESULTS.md). */
#include "internal.h"

#include <math.h>
#include <string.h>

#define MAXP (MIM_PAIR_JOINTS + 4) /* the points, then the outer tetrahedron's */
#define MAXT 512 /* tetrahedra at once, live or freed (227 at most seen over 120 000 sets of 34) */
#define TOL 1e-10
#define FAR 1e4 /* the outer vertices' distance, in radii of the points */
#define PAIRED ((int16_t)MAXT) /* an edge_owner: both faces on the edge found */

typedef struct tet {
    double centre[3], r2; /* its circumsphere (rounded: for the holes, which the proof checks) */
    uint8_t v[4];
    int16_t nb[4];  /* the tetrahedron across the face opposite v[i], or -1 */
    uint8_t dead;
    uint8_t mark; /* while a hole is found: IN_HOLE, or OUTSIDE once tried */
} tet_t;
enum { IN_HOLE = 1, OUTSIDE = 2 };

typedef struct mesh {
    double p[MAXP][3];
    tet_t t[MAXT];
    int n_t, n_free;
    int16_t free_list[MAXT];
    uint32_t n; /* the points (not the outer vertices) */
} mesh_t;

static double norm2(const double *u) { return u[0] * u[0] + u[1] * u[1] + u[2] * u[2]; }

/* Whether a determinant is positive with margin, given the square of its
 * Hadamard bound (no square root on the way). */
static int clear(double det, double bound2) { return det > 0 && det * det > TOL * TOL * bound2; }

/* det[b - a; c - a; d - a] (positive: a, b, c, d positively oriented);
 * bound2, unless NULL: its Hadamard bound |b - a| |c - a| |d - a|, squared */
static double orient(const double *a, const double *b, const double *c, const double *d, double *bound2)
{
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]},
                 w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    if (bound2) *bound2 = norm2(u) * norm2(v) * norm2(w);
    return u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0]);
}

/* Positive when e is inside the circumsphere of a positively oriented
 * a, b, c, d: minus det[x - e, |x - e|^2] over its rows x = a, b, c, d;
 * bound2: the square of |r_a| |r_b| |r_c| |r_d| max |r|, r = x - e, which
 * bounds each of the determinant's 24 products (three coordinates from
 * three rows, the fourth row's squared length), as the Hadamard bound
 * does orient's: of the determinant's degree in lengths, so that the
 * margin is the same at any scale. */
static double inside(const double *a, const double *b, const double *c, const double *d, const double *e, double *bound2)
{
    const double *x[4] = {a, b, c, d};
    double r[4][4], h = 1, most = 0;
    for (int i = 0; i < 4; i++) {
        for (int k = 0; k < 3; k++) r[i][k] = x[i][k] - e[k];
        r[i][3] = norm2(r[i]);
        h *= r[i][3], most = fmax(most, r[i][3]);
    }
    *bound2 = h * most;
    /* by the first two rows' 2x2 minors */
    const double m01 = r[0][0] * r[1][1] - r[0][1] * r[1][0], m02 = r[0][0] * r[1][2] - r[0][2] * r[1][0],
                 m03 = r[0][0] * r[1][3] - r[0][3] * r[1][0], m12 = r[0][1] * r[1][2] - r[0][2] * r[1][1],
                 m13 = r[0][1] * r[1][3] - r[0][3] * r[1][1], m23 = r[0][2] * r[1][3] - r[0][3] * r[1][2];
    const double n01 = r[2][0] * r[3][1] - r[2][1] * r[3][0], n02 = r[2][0] * r[3][2] - r[2][2] * r[3][0],
                 n03 = r[2][0] * r[3][3] - r[2][3] * r[3][0], n12 = r[2][1] * r[3][2] - r[2][2] * r[3][1],
                 n13 = r[2][1] * r[3][3] - r[2][3] * r[3][1], n23 = r[2][2] * r[3][3] - r[2][3] * r[3][2];
    return -(m01 * n23 - m02 * n13 + m03 * n12 + m12 * n03 - m13 * n02 + m23 * n01);
}

/* Tetrahedron t's vertices reordered by an even permutation (the same
 * orientation) so that its i-th comes first. */
static const int even[4][4] = {{0, 1, 2, 3}, {1, 0, 3, 2}, {2, 3, 0, 1}, {3, 2, 1, 0}};

/* The orientation of tetrahedron t with its i-th vertex replaced by point q. */
static double orient_with(const mesh_t *m, const tet_t *t, int i, int q)
{
    const double *x[4];
    for (int k = 0; k < 4; k++) x[k] = m->p[k == i ? q : t->v[k]];
    return orient(x[0], x[1], x[2], x[3], NULL);
}

static int tet_new(mesh_t *m)
{
    if (m->n_free) return m->free_list[--m->n_free];
    return m->n_t < MAXT ? m->n_t++ : -1;
}

/* Each made tetrahedron positively oriented, with margin: taken from
 * its lowest vertex (a point before an outer vertex, whose distances
 * would make the bound loose). Sets its circumsphere: with u, v, w its
 * edges from that vertex, the centre is that vertex plus
 * (|u|^2 v x w + |v|^2 w x u + |w|^2 u x v) / (2 u . v x w). */
static int shaped(mesh_t *m, tet_t *t)
{
    int low = 0;
    for (int i = 1; i < 4; i++)
        if (t->v[i] < t->v[low]) low = i;
    const int *e = even[low];
    const double *a = m->p[t->v[e[0]]], *b = m->p[t->v[e[1]]], *c = m->p[t->v[e[2]]], *d = m->p[t->v[e[3]]];
    double bound2;
    const double det = orient(a, b, c, d, &bound2);
    if (!clear(det, bound2)) return 0;
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]},
                 w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    const double vw[3] = {v[1] * w[2] - v[2] * w[1], v[2] * w[0] - v[0] * w[2], v[0] * w[1] - v[1] * w[0]},
                 wu[3] = {w[1] * u[2] - w[2] * u[1], w[2] * u[0] - w[0] * u[2], w[0] * u[1] - w[1] * u[0]},
                 uv[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double lu = norm2(u), lv = norm2(v), lw = norm2(w), half = 0.5 / det;
    double x[3];
    for (int k = 0; k < 3; k++) x[k] = (lu * vw[k] + lv * wu[k] + lw * uv[k]) * half, t->centre[k] = a[k] + x[k];
    t->r2 = norm2(x);
    return 1;
}

/* Whether the face of tetrahedron t opposite its i-th vertex is a face of
 * the points' convex hull: every point off it on that vertex's side, with
 * margin. With f1, f2, f3 the face in the order even[i] gives it, the
 * orientation of (q, f1, f2, f3) is (f3 - f1) x (f2 - f1) . (q - f1). */
static int hull_face(const mesh_t *m, const tet_t *t, int i)
{
    const double *f1 = m->p[t->v[even[i][1]]], *f2 = m->p[t->v[even[i][2]]], *f3 = m->p[t->v[even[i][3]]];
    const double u[3] = {f2[0] - f1[0], f2[1] - f1[1], f2[2] - f1[2]}, w[3] = {f3[0] - f1[0], f3[1] - f1[1], f3[2] - f1[2]};
    const double nrm[3] = {w[1] * u[2] - w[2] * u[1], w[2] * u[0] - w[0] * u[2], w[0] * u[1] - w[1] * u[0]};
    const double face2 = norm2(u) * norm2(w);
    for (uint32_t q = 0; q < m->n; q++) {
        if (q == t->v[even[i][1]] || q == t->v[even[i][2]] || q == t->v[even[i][3]]) continue;
        const double d[3] = {m->p[q][0] - f1[0], m->p[q][1] - f1[1], m->p[q][2] - f1[2]};
        if (!clear(nrm[0] * d[0] + nrm[1] * d[1] + nrm[2] * d[2], face2 * norm2(d))) return 0;
    }
    return 1;
}

/* The tetrahedron holding point q, walked to from tetrahedron s: across
 * any face q is beyond. */
static int locate(const mesh_t *m, int s, int q)
{
    for (int step = 0; step < MAXT && s >= 0; step++) {
        const tet_t *t = &m->t[s];
        int next = -2;
        for (int i = 0; i < 4 && next == -2; i++)
            if (orient_with(m, t, i, q) < 0) next = t->nb[i];
        if (next == -2) return s;
        s = next;
    }
    return -1;
}

/* Inserts point q (Bowyer-Watson) from the tetrahedron s holding it;
 * returns a new tetrahedron, or -1 (declined). */
static int insert(mesh_t *m, int s, int q)
{
    int16_t hole[MAXT], made[MAXT];
    int n_hole = 0, n_made = 0;
    /* the hole: the tetrahedra whose circumsphere holds q, connected to s */
    int16_t tried[MAXT];
    int n_tried = 0;
    hole[n_hole++] = (int16_t)s, m->t[s].mark = IN_HOLE;
    for (int h = 0; h < n_hole; h++)
        for (int i = 0; i < 4; i++) {
            const int u = m->t[hole[h]].nb[i];
            if (u < 0 || m->t[u].mark) continue;
            tet_t *t = &m->t[u];
            const double dx = m->p[q][0] - t->centre[0], dy = m->p[q][1] - t->centre[1], dz = m->p[q][2] - t->centre[2];
            if (dx * dx + dy * dy + dz * dz < t->r2) hole[n_hole++] = (int16_t)u, t->mark = IN_HOLE;
            else tried[n_tried++] = (int16_t)u, t->mark = OUTSIDE;
        }
    for (int x = 0; x < n_tried; x++) m->t[tried[x]].mark = 0;
    /* q joined to each face of the hole's boundary; the new tetrahedra meet
     * across the faces through q, found by the boundary edge they share */
    int16_t edge_owner[MAXP][MAXP];
    int8_t edge_face[MAXP][MAXP];
    memset(edge_owner, 0xff, sizeof edge_owner);
    int ok = 1;
    for (int h = 0; h < n_hole && ok; h++) {
        const tet_t old = m->t[hole[h]];
        for (int i = 0; i < 4 && ok; i++) {
            const int out = old.nb[i];
            if (out >= 0 && m->t[out].mark == IN_HOLE) continue;
            const int k = tet_new(m);
            if (k < 0) {
                ok = 0;
                break;
            }
            tet_t *t = &m->t[k];
            memcpy(t->v, old.v, sizeof t->v);
            t->v[i] = (uint8_t)q, t->dead = 0, t->mark = 0;
            t->nb[i] = (int16_t)out;
            if (out >= 0)
                for (int j = 0; j < 4; j++)
                    if (m->t[out].nb[j] == hole[h]) m->t[out].nb[j] = (int16_t)k;
            made[n_made++] = (int16_t)k;
            if (!shaped(m, t)) ok = 0;
            for (int f = 0; f < 4; f++) {
                if (f == i) continue;
                /* the face opposite v[f] holds q and the boundary edge without v[f] */
                int e[2], ne = 0;
                for (int x = 0; x < 4; x++)
                    if (x != i && x != f) e[ne++] = t->v[x];
                const int a = e[0] < e[1] ? e[0] : e[1], b = e[0] < e[1] ? e[1] : e[0];
                if (edge_owner[a][b] == PAIRED) {
                    ok = 0; /* a third face on one edge: the hole was not a ball */
                } else if (edge_owner[a][b] < 0) {
                    edge_owner[a][b] = (int16_t)k, edge_face[a][b] = (int8_t)f, t->nb[f] = -1;
                } else {
                    const int o = edge_owner[a][b];
                    t->nb[f] = (int16_t)o, m->t[o].nb[edge_face[a][b]] = (int16_t)k;
                    edge_owner[a][b] = PAIRED;
                }
            }
        }
    }
    for (int h = 0; h < n_hole; h++) {
        m->t[hole[h]].dead = 1, m->t[hole[h]].mark = 0;
        m->free_list[m->n_free++] = hole[h];
    }
    /* a face through q met by one new tetrahedron only: the hole was not a ball */
    for (int x = 0; x < n_made && ok; x++)
        for (int f = 0; f < 4; f++)
            if (m->t[made[x]].nb[f] < 0 && m->t[made[x]].v[f] != q) ok = 0;
    return ok && n_made ? made[0] : -1;
}

/* A live tetrahedron of the points alone (no outer vertex). */
static int real(const mesh_t *m, int k)
{
    if (k < 0 || m->t[k].dead) return 0;
    for (int i = 0; i < 4; i++)
        if (m->t[k].v[i] >= m->n) return 0;
    return 1;
}

/* The proof of the header, on the tetrahedra of the points alone. */
static int proven(const mesh_t *m)
{
    uint8_t vertex[MAXP] = {0};
    for (int k = 0; k < m->n_t; k++) {
        if (!real(m, k)) continue;
        const tet_t *t = &m->t[k];
        for (int i = 0; i < 4; i++) {
            vertex[t->v[i]] = 1;
            const int u = t->nb[i];
            if (!real(m, u)) {
                if (!hull_face(m, t, i)) return 0;
                continue;
            }
            if (u < k) continue; /* each face between two once */
            int far = -1;
            for (int j = 0; j < 4; j++)
                if (m->t[u].nb[j] == k) far = m->t[u].v[j];
            if (far < 0) return 0;
            double bound2;
            const double in = inside(m->p[t->v[0]], m->p[t->v[1]], m->p[t->v[2]], m->p[t->v[3]], m->p[far], &bound2);
            if (!clear(-in, bound2)) return 0;
        }
    }
    for (uint32_t q = 0; q < m->n; q++)
        if (!vertex[q]) return 0;
    return 1;
}

int mim__delaunay3_edges(const double *pts, uint32_t n, uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS])
{
    if (n < 4 || n > MIM_PAIR_JOINTS) return -1;
    mesh_t mesh, *m = &mesh;
    m->n = n, m->n_t = 0, m->n_free = 0;
    double c[3] = {0, 0, 0}, r = 0;
    for (uint32_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) c[k] += pts[3 * i + k] / n;
    for (uint32_t i = 0; i < n; i++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) m->p[i][k] = pts[3 * i + k], d2 += (pts[3 * i + k] - c[k]) * (pts[3 * i + k] - c[k]);
        r = fmax(r, sqrt(d2));
    }
    if (!(r > 0) || !isfinite(r)) return -1;
    /* the outer tetrahedron: a regular one, its inner sphere FAR radii */
    static const double dir[4][3] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
    for (int v = 0; v < 4; v++)
        for (int k = 0; k < 3; k++) m->p[n + v][k] = c[k] + 3 * FAR * r * dir[v][k];
    tet_t *t0 = &m->t[m->n_t++];
    *t0 = (tet_t){.v = {(uint8_t)(n + 1), (uint8_t)n, (uint8_t)(n + 2), (uint8_t)(n + 3)}, .nb = {-1, -1, -1, -1}};
    if (!shaped(m, t0)) return -1; /* dir's order (first two swapped) is positive */
    int at = 0;
    for (uint32_t q = 0; q < n; q++) {
        const int s = locate(m, at, (int)q);
        if (s < 0 || (at = insert(m, s, (int)q)) < 0) return -1;
    }
    if (!proven(m)) return -1;
    for (int k = 0; k < m->n_t; k++) {
        if (!real(m, k)) continue;
        const uint8_t *v = m->t[k].v;
        for (int a = 0; a < 4; a++)
            for (int b = 0; b < 4; b++)
                if (v[a] < v[b]) have[v[a]][v[b]] = 1;
    }
    return 0;
}
