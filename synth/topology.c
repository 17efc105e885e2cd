/* Edges of the cage and a consistent outward orientation of its faces.
 *
 * The builder writes faces ring by ring without caring which way round they
 * go (mirrored parts come out reversed); here a breadth-first walk over
 * faces flips each neighbour that runs a shared edge the same way, and the
 * sign of the enclosed volume decides outward. Every edge must have exactly
 * two faces, or the cage is not a closed manifold (MIM_ETOPOLOGY). */
#include "synth_internal.h"

#include <stdlib.h>
#include <string.h>

typedef struct {
    uint32_t lo, hi, corner;
} hedge_t;

static int cmp_hedge(const void *pa, const void *pb)
{
    const hedge_t *a = pa, *b = pb;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi) return a->hi < b->hi ? -1 : 1;
    return a->corner < b->corner ? -1 : a->corner > b->corner;
}

void mim__edges_free(mim__edges_t *e)
{
    free(e->ev), free(e->ecorner), free(e->corner_edge), free(e->corner_face);
    memset(e, 0, sizeof *e);
}

int mim__edges_build(mim__edges_t *e, const mim__cage_t *c)
{
    memset(e, 0, sizeof *e);
    uint32_t nc = c->ncorner;
    hedge_t *h = malloc((size_t)nc * sizeof *h);
    e->corner_edge = malloc((size_t)nc * sizeof *e->corner_edge);
    e->corner_face = malloc((size_t)nc * sizeof *e->corner_face);
    e->ev = malloc((size_t)nc * sizeof *e->ev);          /* 2 per edge, nc / 2 edges */
    e->ecorner = malloc((size_t)nc * sizeof *e->ecorner); /* the two corners of each edge */
    if (!h || !e->corner_edge || !e->corner_face || !e->ev || !e->ecorner) {
        free(h);
        mim__edges_free(e);
        return MIM_ENOMEM;
    }
    for (uint32_t f = 0; f < c->nf; f++) {
        uint32_t s = c->fstart[f], n = c->fstart[f + 1] - s;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t a = c->fv[s + i], b = c->fv[s + (i + 1) % n];
            h[s + i].lo = a < b ? a : b;
            h[s + i].hi = a < b ? b : a;
            h[s + i].corner = s + i;
            e->corner_face[s + i] = f;
        }
    }
    qsort(h, nc, sizeof *h, cmp_hedge);
    uint32_t ne = 0;
    for (uint32_t i = 0; i < nc;) {
        uint32_t k = i;
        while (k < nc && h[k].lo == h[i].lo && h[k].hi == h[i].hi) k++;
        if (k - i != 2 || h[i].lo == h[i].hi) {
            free(h);
            mim__edges_free(e);
            return MIM_ETOPOLOGY;
        }
        e->ev[2 * ne] = h[i].lo;
        e->ev[2 * ne + 1] = h[i].hi;
        e->ecorner[2 * ne] = h[i].corner;
        e->ecorner[2 * ne + 1] = h[i + 1].corner;
        e->corner_edge[h[i].corner] = ne;
        e->corner_edge[h[i + 1].corner] = ne;
        ne++;
        i = k;
    }
    e->ne = ne;
    free(h);
    return 0;
}

static void reverse_face(mim__cage_t *c, uint32_t f)
{
    uint32_t s = c->fstart[f], n = c->fstart[f + 1] - s;
    for (uint32_t i = 1, j = n - 1; i < j; i++, j--) {
        uint32_t t = c->fv[s + i];
        c->fv[s + i] = c->fv[s + j];
        c->fv[s + j] = t;
    }
}

/* Does corner k (edge from fv[k] to the next) run from a to b? */
static int runs_forward(const mim__cage_t *c, const mim__edges_t *e, uint32_t k)
{
    uint32_t f = e->corner_face[k], s = c->fstart[f], n = c->fstart[f + 1] - s;
    return c->fv[k] < c->fv[s + (k - s + 1) % n];
}

int mim__cage_orient(mim__cage_t *c)
{
    mim__edges_t e;
    int rc = mim__edges_build(&e, c);
    if (rc) return rc;
    uint8_t *flip = calloc(c->nf, 1), *seen = calloc(c->nf, 1);
    uint32_t *queue = malloc((size_t)c->nf * sizeof *queue);
    if (!flip || !seen || !queue) {
        rc = MIM_ENOMEM;
        goto out;
    }
    for (uint32_t start = 0; start < c->nf; start++) {
        if (seen[start]) continue;
        uint32_t qh = 0, qt = 0;
        queue[qt++] = start;
        seen[start] = 1;
        while (qh < qt) {
            uint32_t f = queue[qh++], s = c->fstart[f], n = c->fstart[f + 1] - s;
            for (uint32_t i = 0; i < n; i++) {
                uint32_t k = s + i, ed = e.corner_edge[k];
                uint32_t other = e.ecorner[2 * ed] == k ? e.ecorner[2 * ed + 1] : e.ecorner[2 * ed];
                uint32_t g = e.corner_face[other];
                int same = runs_forward(c, &e, k) == runs_forward(c, &e, other);
                uint8_t want = (uint8_t)(flip[f] ^ (same ? 1 : 0));
                if (!seen[g]) {
                    seen[g] = 1;
                    flip[g] = want;
                    queue[qt++] = g;
                } else if (flip[g] != want) {
                    rc = MIM_ETOPOLOGY; /* not orientable */
                    goto out;
                }
            }
        }
    }
    for (uint32_t f = 0; f < c->nf; f++)
        if (flip[f]) reverse_face(c, f);
    /* outward: positive signed volume (fan of each face from its first corner) */
    double vol = 0;
    for (uint32_t f = 0; f < c->nf; f++) {
        uint32_t s = c->fstart[f], n = c->fstart[f + 1] - s;
        const double *p0 = c->pos + 3 * c->fv[s];
        for (uint32_t i = 1; i + 1 < n; i++) {
            const double *p1 = c->pos + 3 * c->fv[s + i], *p2 = c->pos + 3 * c->fv[s + i + 1];
            vol += p0[0] * (p1[1] * p2[2] - p1[2] * p2[1]) - p0[1] * (p1[0] * p2[2] - p1[2] * p2[0]) +
                   p0[2] * (p1[0] * p2[1] - p1[1] * p2[0]);
        }
    }
    if (vol < 0)
        for (uint32_t f = 0; f < c->nf; f++) reverse_face(c, f);
out:
    free(flip), free(seen), free(queue);
    mim__edges_free(&e);
    return rc;
}
