/* Welding the split vertices of an avatar (mim_register.h, issue 28).
 *
 * Exporters split a vertex wherever its UV or normal jumps (a seam, a
 * hard edge; every vertex of a flat-shaded model), writing copies at one
 * place. Each position is snapped to a grid of cell tol; copies land in
 * one cell, and a sort by cell puts them side by side. Two points closer
 * than tol that fall either side of a cell wall stay apart: exporters
 * write copies bitwise equal, so that costs nothing in practice. */
#include "mim_register.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int64_t key[3];
    uint32_t v;
} cell_t;

static int cell_cmp(const void *pa, const void *pb)
{
    const cell_t *a = pa, *b = pb;
    for (int k = 0; k < 3; k++)
        if (a->key[k] != b->key[k]) return a->key[k] < b->key[k] ? -1 : 1;
    return a->v < b->v ? -1 : a->v > b->v;
}

int mim_reg_weld(const mim_mesh_t *in, double tol, mim_mesh_t *out, uint32_t *map, mim_error_t *err)
{
    if (!in || !out || !map || !in->positions || !in->faces)
        return mim_error_set(err, MIM_EINVAL, "weld: needs a mesh, an output and a map");
    memset(out, 0, sizeof *out);
    if (!(tol > 0)) tol = MIM_REG_WELD_TOL;
    const uint32_t n = in->n_vertices;
    cell_t *c = malloc(((size_t)n + 1) * sizeof *c);
    if (!c) return mim_error_set(err, MIM_ENOMEM, "weld: out of memory");
    for (uint32_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            double q = floor((double)in->positions[3 * (size_t)i + k] / tol + 0.5);
            c[i].key[k] = isfinite(q) && fabs(q) < 4e18 ? (int64_t)q : (int64_t)i; /* a NaN welds with nothing */
        }
        c[i].v = i;
    }
    qsort(c, n, sizeof *c, cell_cmp);
    uint32_t nw = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (i && memcmp(c[i].key, c[i - 1].key, sizeof c[i].key)) nw++;
        map[c[i].v] = n ? nw : 0;
    }
    nw = n ? nw + 1 : 0;
    /* the welded vertex sits where its first copy (lowest index) does */
    uint32_t nf = 0;
    for (uint32_t f = 0; f < in->n_faces; f++) {
        const uint32_t *t = in->faces + 3 * (size_t)f;
        if (t[0] >= n || t[1] >= n || t[2] >= n) {
            free(c);
            return mim_error_set(err, MIM_EINVAL, "weld: triangle %u refers to a vertex past %u", f, n);
        }
        uint32_t a = map[t[0]], b = map[t[1]], d = map[t[2]];
        nf += a != b && b != d && a != d;
    }
    int rc = mim_mesh_alloc(out, nw, nf);
    if (rc) {
        free(c);
        return mim_error_set(err, MIM_ENOMEM, "weld: out of memory");
    }
    for (uint32_t i = n; i-- > 0;)
        memcpy(out->positions + 3 * (size_t)map[i], in->positions + 3 * (size_t)i, 3 * sizeof(float));
    nf = 0;
    for (uint32_t f = 0; f < in->n_faces; f++) {
        const uint32_t *t = in->faces + 3 * (size_t)f;
        uint32_t a = map[t[0]], b = map[t[1]], d = map[t[2]];
        if (a == b || b == d || a == d) continue;
        out->faces[3 * (size_t)nf] = a, out->faces[3 * (size_t)nf + 1] = b, out->faces[3 * (size_t)nf + 2] = d;
        nf++;
    }
    free(c);
    return 0;
}

static uint32_t root_of(uint32_t *p, uint32_t x)
{
    while (p[x] != x) x = p[x] = p[p[x]];
    return x;
}

int64_t mim_reg_pieces(const mim_mesh_t *m)
{
    uint32_t *p = malloc(((size_t)m->n_vertices + 1) * sizeof *p);
    if (!p) return MIM_ENOMEM;
    for (uint32_t i = 0; i < m->n_vertices; i++) p[i] = i;
    for (uint32_t f = 0; f < m->n_faces; f++)
        for (int k = 1; k < 3; k++) {
            uint32_t a = root_of(p, m->faces[3 * (size_t)f]), b = root_of(p, m->faces[3 * (size_t)f + k]);
            if (a != b) p[a] = b;
        }
    int64_t n = 0;
    for (uint32_t i = 0; i < m->n_vertices; i++) n += root_of(p, i) == i;
    free(p);
    return n;
}
