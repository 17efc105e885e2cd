/* The uniform unnormalised Laplacian of a connectivity (seed 000, Section
 * 3.1: l_ii = deg(v_i), l_ij = -1 for v_j in the one-ring N_1(v_i)). It is
 * kept as the sorted one-ring adjacency: L is symmetric and its values are
 * implied, so applying it needs no matrix. */
#include "internal.h"

#include <stdlib.h>
#include <math.h>
#include <string.h>

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

int mim_xfer_topology_open(mim_xfer_topology_t **out, uint32_t n_vertices, const uint32_t *faces,
                           uint32_t n_faces, mim_error_t *err)
{
    if (!out)
        return mim_error_set(err, MIM_EINVAL, "transfer: NULL topology handle");
    *out = NULL;
    if (!faces || n_vertices == 0 || n_faces == 0)
        return mim_error_set(err, MIM_EINVAL, "transfer: empty connectivity (%u vertices, %u faces)",
                             n_vertices, n_faces);
    for (uint32_t f = 0; f < n_faces; f++) {
        const uint32_t *t = faces + 3 * (size_t)f;
        for (int k = 0; k < 3; k++)
            if (t[k] >= n_vertices)
                return mim_error_set(err, MIM_EINDEX, "transfer: face %u has vertex %u, past %u vertices",
                                     f, t[k], n_vertices);
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
            return mim_error_set(err, MIM_EFORMAT, "transfer: face %u repeats a vertex (%u %u %u)", f,
                                 t[0], t[1], t[2]);
    }
    mim_xfer_topology_t *t = calloc(1, sizeof *t);
    uint32_t *cnt = calloc((size_t)n_vertices + 1, sizeof *cnt);
    uint32_t *tmp = malloc(6 * (size_t)n_faces * sizeof *tmp);
    if (t) {
        t->faces = malloc(3 * (size_t)n_faces * sizeof *t->faces);
        t->adj_start = calloc((size_t)n_vertices + 1, sizeof *t->adj_start);
    }
    if (!t || !cnt || !tmp || !t->faces || !t->adj_start) {
        free(cnt);
        free(tmp);
        mim_xfer_topology_close(&t);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory for %u vertices", n_vertices);
    }
    t->n = n_vertices;
    t->n_faces = n_faces;
    memcpy(t->faces, faces, 3 * (size_t)n_faces * sizeof *faces);
    /* every face gives each corner its two other corners; duplicates removed below */
    for (uint32_t f = 0; f < 3 * n_faces; f++)
        cnt[faces[f] + 1] += 2;
    for (uint32_t v = 0; v < n_vertices; v++)
        cnt[v + 1] += cnt[v];
    uint32_t *fill = malloc(((size_t)n_vertices + 1) * sizeof *fill);
    if (!fill) {
        free(cnt);
        free(tmp);
        mim_xfer_topology_close(&t);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory for %u vertices", n_vertices);
    }
    memcpy(fill, cnt, ((size_t)n_vertices + 1) * sizeof *fill);
    for (uint32_t f = 0; f < n_faces; f++) {
        const uint32_t *c = faces + 3 * (size_t)f;
        for (int k = 0; k < 3; k++) {
            uint32_t v = c[k];
            tmp[fill[v]++] = c[(k + 1) % 3];
            tmp[fill[v]++] = c[(k + 2) % 3];
        }
    }
    free(fill);
    uint32_t w = 0;
    for (uint32_t v = 0; v < n_vertices; v++) {
        uint32_t b = cnt[v], e = cnt[v + 1];
        qsort(tmp + b, e - b, sizeof *tmp, cmp_u32);
        t->adj_start[v] = w;
        for (uint32_t k = b; k < e; k++)
            if (k == b || tmp[k] != tmp[k - 1])
                tmp[w++] = tmp[k];
    }
    t->adj_start[n_vertices] = w;
    free(cnt);
    /* shrink to fit; keep the larger block if the shrink fails */
    uint32_t *shrunk = realloc(tmp, (w ? w : 1) * sizeof *tmp);
    t->adj = shrunk ? shrunk : tmp;
    /* incident faces per vertex, in face order */
    t->vf_start = calloc((size_t)n_vertices + 1, sizeof *t->vf_start);
    t->vf = malloc(3 * (size_t)n_faces * sizeof *t->vf);
    if (!t->vf_start || !t->vf) {
        mim_xfer_topology_close(&t);
        return mim_error_set(err, MIM_ENOMEM, "transfer: out of memory for %u faces", n_faces);
    }
    for (uint32_t f = 0; f < 3 * n_faces; f++)
        t->vf_start[faces[f] + 1]++;
    for (uint32_t v = 0; v < n_vertices; v++)
        t->vf_start[v + 1] += t->vf_start[v];
    for (uint32_t f = 0, k = 0; f < n_faces; f++)
        for (int c = 0; c < 3; c++, k++)
            t->vf[t->vf_start[faces[k]]++] = f;
    for (uint32_t v = n_vertices; v > 0; v--)
        t->vf_start[v] = t->vf_start[v - 1];
    t->vf_start[0] = 0;
    *out = t;
    return 0;
}

void mim_xfer_topology_close(mim_xfer_topology_t **tp)
{
    if (!tp || !*tp)
        return;
    mim_xfer_topology_t *t = *tp;
    free(t->faces);
    free(t->adj_start);
    free(t->adj);
    free(t->vf_start);
    free(t->vf);
    free(t);
    *tp = NULL;
}

uint32_t mim_xfer_topology_n_vertices(const mim_xfer_topology_t *t) { return t ? t->n : 0; }

const uint32_t *mim_xfer_topology_faces(const mim_xfer_topology_t *t, uint32_t *n_faces)
{
    *n_faces = t ? t->n_faces : 0;
    return t ? t->faces : NULL;
}

const uint32_t *mim_xfer_neighbors(const mim_xfer_topology_t *t, uint32_t v, uint32_t *count)
{
    if (!t || v >= t->n) {
        if (count)
            *count = 0;
        return NULL;
    }
    if (count)
        *count = t->adj_start[v + 1] - t->adj_start[v];
    return t->adj + t->adj_start[v];
}

void mim_xfer_laplacian_apply(const mim_xfer_topology_t *t, const double *x, double *y)
{
    for (uint32_t i = 0; i < t->n; i++) {
        uint32_t b = t->adj_start[i], e = t->adj_start[i + 1];
        double d = (double)(e - b);
        double sx = d * x[3 * (size_t)i], sy = d * x[3 * (size_t)i + 1], sz = d * x[3 * (size_t)i + 2];
        for (uint32_t k = b; k < e; k++) {
            const double *p = x + 3 * (size_t)t->adj[k];
            sx -= p[0];
            sy -= p[1];
            sz -= p[2];
        }
        y[3 * (size_t)i] = sx;
        y[3 * (size_t)i + 1] = sy;
        y[3 * (size_t)i + 2] = sz;
    }
}

int mim_xfer_check_mesh(const mim_xfer_topology_t *t, const mim_mesh_t *m, const char *origin,
                        mim_error_t *err)
{
    if (!origin)
        origin = "mesh";
    if (!t || !m || !m->positions || !m->faces)
        return mim_error_set(err, MIM_EINVAL, "transfer: %s: NULL mesh or connectivity", origin);
    if (m->n_vertices != t->n || m->n_faces != t->n_faces)
        return mim_error_set(err, MIM_ETOPOLOGY,
                             "%s: %u vertices and %u faces, the connectivity has %u and %u", origin,
                             m->n_vertices, m->n_faces, t->n, t->n_faces);
    for (uint32_t f = 0; f < t->n_faces; f++)
        if (memcmp(m->faces + 3 * (size_t)f, t->faces + 3 * (size_t)f, 3 * sizeof *t->faces))
            return mim_error_set(err, MIM_ETOPOLOGY, "%s: face %u differs from the connectivity's", origin, f);
    for (size_t i = 0; i < 3 * (size_t)t->n; i++)
        if (!isfinite(m->positions[i]))
            return mim_error_set(err, MIM_ENONFINITE, "%s: vertex %zu has a non-finite coordinate", origin,
                                 i / 3);
    return 0;
}
