/* Refinement of the cage as a fixed linear stencil, and triangulation.
 *
 * One level of Catmull-Clark subdivision (Catmull and Clark 1978): face
 * points are face centroids, edge points average the edge's ends and its two
 * face points, and a vertex of valence n moves to (Q + 2R + (n - 3) S) / n
 * (Q: mean of the adjacent face points, R: mean of the incident edge
 * midpoints, S: the vertex). Every output is a fixed linear combination of
 * cage vertices, so the stencil is built once and applied to any subject's
 * cage positions and skin weights. Output vertex i < cage.nv is the cage
 * vertex i's point, then one point per edge, then one per face. Level 0
 * keeps the cage and fans faces of 5+ sides around their centroid. */
#include "synth_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    double *acc;      /* dense accumulator over cage vertices */
    uint32_t *touched;
    uint32_t nt;
    mim__refine_t *r;
    uint32_t nnz, cap;
    int oom;
} stb_t;

static void add(stb_t *b, uint32_t v, double w)
{
    if (b->acc[v] == 0) b->touched[b->nt++] = v;
    b->acc[v] += w;
    if (b->acc[v] == 0) b->acc[v] = 1e-300; /* keep it marked as touched */
}

static void add_face(stb_t *b, const mim__cage_t *c, uint32_t f, double w)
{
    uint32_t s = c->fstart[f], n = c->fstart[f + 1] - s;
    for (uint32_t i = 0; i < n; i++) add(b, c->fv[s + i], w / n);
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

/* Moves the accumulated combination into row `row` of the stencil. */
static void emit(stb_t *b, uint32_t row)
{
    mim__refine_t *r = b->r;
    if (b->nnz + b->nt > b->cap) {
        uint32_t n = b->cap ? b->cap : 4096;
        while (n < b->nnz + b->nt) n *= 2;
        uint32_t *c = realloc(r->st_col, (size_t)n * sizeof *c);
        if (c) r->st_col = c;
        double *w = realloc(r->st_w, (size_t)n * sizeof *w);
        if (w) r->st_w = w;
        if (!c || !w) {
            b->oom = 1;
            b->nt = 0;
            return;
        }
        b->cap = n;
    }
    qsort(b->touched, b->nt, sizeof *b->touched, cmp_u32);
    for (uint32_t i = 0; i < b->nt; i++) {
        uint32_t v = b->touched[i];
        r->st_col[b->nnz] = v;
        r->st_w[b->nnz++] = b->acc[v];
        b->acc[v] = 0;
    }
    b->nt = 0;
    r->st_start[row + 1] = b->nnz;
}

void mim__refine_free(mim__refine_t *r)
{
    free(r->st_start), free(r->st_col), free(r->st_w), free(r->poly);
    memset(r, 0, sizeof *r);
}

static int level0(mim__refine_t *r, const mim__cage_t *c, stb_t *b)
{
    uint32_t big = 0, ntri = 0;
    for (uint32_t f = 0; f < c->nf; f++) {
        uint32_t n = c->fstart[f + 1] - c->fstart[f];
        if (n >= 5) big++, ntri += n;
    }
    r->nv = c->nv + big;
    r->npoly = c->nf - big + ntri;
    r->st_start = calloc((size_t)r->nv + 1, sizeof *r->st_start);
    r->poly = malloc((size_t)r->npoly * 4 * sizeof *r->poly);
    if (!r->st_start || !r->poly) return MIM_ENOMEM;
    for (uint32_t v = 0; v < c->nv; v++) {
        add(b, v, 1.0);
        emit(b, v);
    }
    uint32_t next = c->nv, np = 0;
    for (uint32_t f = 0; f < c->nf; f++) {
        uint32_t s = c->fstart[f], n = c->fstart[f + 1] - s;
        if (n < 5) {
            for (uint32_t i = 0; i < 4; i++) r->poly[4 * np + i] = i < n ? c->fv[s + i] : UINT32_MAX;
            np++;
            continue;
        }
        add_face(b, c, f, 1.0);
        emit(b, next);
        for (uint32_t i = 0; i < n; i++) {
            uint32_t *q = r->poly + 4 * np++;
            q[0] = next, q[1] = c->fv[s + i], q[2] = c->fv[s + (i + 1) % n], q[3] = UINT32_MAX;
        }
        next++;
    }
    return b->oom ? MIM_ENOMEM : 0;
}

static int level1(mim__refine_t *r, const mim__cage_t *c, stb_t *b)
{
    mim__edges_t e;
    int rc = mim__edges_build(&e, c);
    if (rc) return rc;
    uint32_t V0 = c->nv, E = e.ne, F = c->nf;
    r->nv = V0 + E + F;
    r->npoly = c->ncorner;
    r->st_start = calloc((size_t)r->nv + 1, sizeof *r->st_start);
    r->poly = malloc((size_t)r->npoly * 4 * sizeof *r->poly);
    /* corners around each vertex (counting sort keeps corner order) */
    uint32_t *vstart = calloc((size_t)V0 + 1, sizeof *vstart), *vcorner = malloc((size_t)c->ncorner * sizeof *vcorner);
    if (!r->st_start || !r->poly || !vstart || !vcorner) {
        rc = MIM_ENOMEM;
        goto out;
    }
    for (uint32_t k = 0; k < c->ncorner; k++) vstart[c->fv[k] + 1]++;
    for (uint32_t v = 0; v < V0; v++) vstart[v + 1] += vstart[v];
    {
        uint32_t *fill = malloc((size_t)V0 * sizeof *fill);
        if (!fill) {
            rc = MIM_ENOMEM;
            goto out;
        }
        memcpy(fill, vstart, (size_t)V0 * sizeof *fill);
        for (uint32_t k = 0; k < c->ncorner; k++) vcorner[fill[c->fv[k]]++] = k;
        free(fill);
    }
    /* vertex points */
    for (uint32_t v = 0; v < V0; v++) {
        uint32_t n = vstart[v + 1] - vstart[v];
        for (uint32_t i = vstart[v]; i < vstart[v + 1]; i++) {
            uint32_t k = vcorner[i], ed = e.corner_edge[k];
            add_face(b, c, e.corner_face[k], 1.0 / ((double)n * n));               /* Q / n */
            uint32_t other = e.ev[2 * ed] == v ? e.ev[2 * ed + 1] : e.ev[2 * ed];
            add(b, v, 1.0 / ((double)n * n));                                       /* 2R / n */
            add(b, other, 1.0 / ((double)n * n));
        }
        add(b, v, (n - 3.0) / n);
        emit(b, v);
    }
    /* edge points */
    for (uint32_t k = 0; k < E; k++) {
        add(b, e.ev[2 * k], 0.25);
        add(b, e.ev[2 * k + 1], 0.25);
        add_face(b, c, e.corner_face[e.ecorner[2 * k]], 0.25);
        add_face(b, c, e.corner_face[e.ecorner[2 * k + 1]], 0.25);
        emit(b, V0 + k);
    }
    /* face points */
    for (uint32_t f = 0; f < F; f++) {
        add_face(b, c, f, 1.0);
        emit(b, V0 + E + f);
    }
    /* one quad per corner: vertex, next edge, face, previous edge */
    for (uint32_t f = 0; f < F; f++) {
        uint32_t s = c->fstart[f], n = c->fstart[f + 1] - s;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t *q = r->poly + 4 * (s + i);
            q[0] = c->fv[s + i];
            q[1] = V0 + e.corner_edge[s + i];
            q[2] = V0 + E + f;
            q[3] = V0 + e.corner_edge[s + (i + n - 1) % n];
        }
    }
    rc = b->oom ? MIM_ENOMEM : 0;
out:
    free(vstart), free(vcorner);
    mim__edges_free(&e);
    return rc;
}

int mim__refine_build(mim__refine_t *r, const mim__cage_t *c, int level)
{
    memset(r, 0, sizeof *r);
    stb_t b = {calloc(c->nv, sizeof(double)), malloc((size_t)c->nv * sizeof(uint32_t)), 0, r, 0, 0, 0};
    int rc = (!b.acc || !b.touched) ? MIM_ENOMEM : level == 0 ? level0(r, c, &b) : level1(r, c, &b);
    free(b.acc), free(b.touched);
    if (rc) mim__refine_free(r);
    return rc;
}

void mim__refine_apply(const mim__refine_t *r, const double *in, double *out, int dim)
{
    for (uint32_t i = 0; i < r->nv; i++) {
        double acc[4] = {0, 0, 0, 0};
        for (uint32_t k = r->st_start[i]; k < r->st_start[i + 1]; k++) {
            const double *p = in + (size_t)dim * r->st_col[k];
            double w = r->st_w[k];
            for (int d = 0; d < dim; d++) acc[d] += w * p[d];
        }
        for (int d = 0; d < dim; d++) out[(size_t)dim * i + d] = acc[d];
    }
}

/* Largest corner cosine of triangle abc (smaller is better shaped). */
static double worst_cos(const double *pos, uint32_t a, uint32_t b, uint32_t c)
{
    const uint32_t v[3] = {a, b, c};
    double worst = -1;
    for (int i = 0; i < 3; i++) {
        const double *p = pos + 3 * v[i], *q = pos + 3 * v[(i + 1) % 3], *s = pos + 3 * v[(i + 2) % 3];
        double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, w[3] = {s[0] - p[0], s[1] - p[1], s[2] - p[2]};
        double nu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]), nw = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        double cs = (nu > 0 && nw > 0) ? (u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) / (nu * nw) : 1;
        if (cs > worst) worst = cs;
    }
    return worst;
}

uint32_t mim__triangulate(const mim__refine_t *r, const double *pos, uint32_t *faces)
{
    uint32_t nf = 0;
    for (uint32_t i = 0; i < r->npoly; i++) {
        const uint32_t *q = r->poly + 4 * i;
        uint32_t *t = faces + 3 * nf;
        if (q[3] == UINT32_MAX) {
            t[0] = q[0], t[1] = q[1], t[2] = q[2];
            nf++;
            continue;
        }
        double ca = fmax(worst_cos(pos, q[0], q[1], q[2]), worst_cos(pos, q[0], q[2], q[3]));
        double cb = fmax(worst_cos(pos, q[0], q[1], q[3]), worst_cos(pos, q[1], q[2], q[3]));
        if (ca <= cb) {
            t[0] = q[0], t[1] = q[1], t[2] = q[2], t[3] = q[0], t[4] = q[2], t[5] = q[3];
        } else {
            t[0] = q[0], t[1] = q[1], t[2] = q[3], t[3] = q[1], t[4] = q[2], t[5] = q[3];
        }
        nf += 2;
    }
    return nf;
}
