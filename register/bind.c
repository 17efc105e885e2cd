/* Binding a foreign avatar to its registered proxy (mim_register.h).
 *
 * Each avatar vertex p is bound to its closest point q on the proxy at
 * rest: the triangle, q's barycentric coordinates, and p - q in a local
 * frame at q. The frame's normal is the barycentric blend of the proxy's
 * vertex normals (smooth across triangles, so that neighbouring avatar
 * vertices bound to different triangles move together), its tangent the
 * triangle's first edge made orthogonal to that normal. Posing the proxy
 * moves q and turns the frame; the offset rides along. The avatar stays
 * close to its proxy (registration closes the distance to below a
 * millimetre or so), so the offsets are small and mostly normal. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Area-weighted vertex normals (3 * n floats, unit) of a mesh. */
static void vertex_normals(const uint32_t *faces, uint32_t nf, const float *pos, uint32_t n, float *nrm)
{
    memset(nrm, 0, (size_t)3 * n * sizeof *nrm);
    for (uint32_t f = 0; f < nf; f++) {
        const uint32_t *v = faces + 3 * f;
        const float *a = pos + 3 * v[0], *b = pos + 3 * v[1], *c = pos + 3 * v[2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int c3 = 0; c3 < 3; c3++)
                nrm[3 * v[k] + c3] += cr[c3];
    }
    for (uint32_t i = 0; i < n; i++) {
        float *q = nrm + 3 * i, l2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2], inv = l2 > 0 ? 1.0f / sqrtf(l2) : 0.0f;
        q[0] *= inv, q[1] *= inv, q[2] *= inv;
    }
}

/* The point at (u, v) on the triangle of corners a, b, c (vertex normals
 * na, nb, nc) and the local frame there: t, bt, n. */
static inline void local_frame(const float *a, const float *b, const float *c, const float *na, const float *nb,
                               const float *nc, float u, float v, float q[3], float t[3], float bt[3], float n[3])
{
    float w = 1.0f - u - v;
    for (int k = 0; k < 3; k++) {
        q[k] = w * a[k] + u * b[k] + v * c[k];
        n[k] = w * na[k] + u * nb[k] + v * nc[k];
        t[k] = b[k] - a[k];
    }
    /* one division per normalisation: this runs per avatar vertex per frame */
    float l2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2], inv = l2 > 0 ? 1.0f / sqrtf(l2) : 0.0f;
    n[0] *= inv, n[1] *= inv, n[2] *= inv;
    float d = t[0] * n[0] + t[1] * n[1] + t[2] * n[2];
    for (int k = 0; k < 3; k++)
        t[k] -= d * n[k];
    l2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2], inv = l2 > 0 ? 1.0f / sqrtf(l2) : 0.0f;
    t[0] *= inv, t[1] *= inv, t[2] *= inv;
    bt[0] = n[1] * t[2] - n[2] * t[1], bt[1] = n[2] * t[0] - n[0] * t[2], bt[2] = n[0] * t[1] - n[1] * t[0];
}

void mim_reg_binding_free(mim_reg_binding_t *b)
{
    if (!b) return;
    free(b->proxy_rest), free(b->vertex), free(b->face), free(b->bary), free(b->offset);
    memset(b, 0, sizeof *b);
}

static int binding_alloc(mim_reg_binding_t *b, uint32_t n, uint32_t np, uint32_t nf)
{
    memset(b, 0, sizeof *b);
    b->n_vertices = n, b->n_proxy_vertices = np, b->n_proxy_faces = nf;
    b->proxy_rest = malloc((size_t)3 * np * sizeof *b->proxy_rest);
    b->vertex = malloc((size_t)n * sizeof *b->vertex);
    b->face = malloc((size_t)n * sizeof *b->face);
    b->bary = malloc((size_t)2 * n * sizeof *b->bary);
    b->offset = malloc((size_t)3 * n * sizeof *b->offset);
    if (b->proxy_rest && b->vertex && b->face && b->bary && b->offset) return 0;
    mim_reg_binding_free(b);
    return MIM_ENOMEM;
}

int mim_reg_bind(const mim_mesh_t *proxy, const mim_mesh_t *avatar, mim_reg_binding_t *out, mim_error_t *err)
{
    if (!out) return mim_error_set(err, MIM_EINVAL, "binding: no output");
    memset(out, 0, sizeof *out);
    if (!proxy || !avatar || !avatar->positions || !avatar->n_vertices)
        return mim_error_set(err, MIM_EINVAL, "binding: needs a proxy and an avatar");
    for (size_t i = 0; i < (size_t)3 * avatar->n_vertices; i++)
        if (!isfinite(avatar->positions[i]))
            return mim_error_set(err, MIM_ENONFINITE, "binding: avatar vertex %zu is not finite", i / 3);
    mim__reg_surface_t s;
    int rc = mim__reg_surface_open(&s, proxy, 0, "proxy", err);
    if (rc) return rc;
    mim__reg_hit_t *hits = malloc((size_t)avatar->n_vertices * sizeof *hits);
    float *nrm = malloc((size_t)3 * proxy->n_vertices * sizeof *nrm);
    uint32_t *start = NULL;
    if (!hits || !nrm || binding_alloc(out, avatar->n_vertices, proxy->n_vertices, proxy->n_faces)) {
        rc = mim_error_set(err, MIM_ENOMEM, "binding: out of memory");
        goto done;
    }
    if ((rc = mim__reg_surface_closest(&s, avatar->positions, avatar->n_vertices, hits, err))) goto done;
    memcpy(out->proxy_rest, proxy->positions, (size_t)3 * proxy->n_vertices * sizeof *out->proxy_rest);
    vertex_normals(proxy->faces, proxy->n_faces, proxy->positions, proxy->n_vertices, nrm);
    /* entries in triangle order (a counting sort, stable in vertex order) */
    start = calloc((size_t)proxy->n_faces + 1, sizeof *start);
    if (!start) {
        rc = mim_error_set(err, MIM_ENOMEM, "binding: out of memory");
        goto done;
    }
    for (uint32_t i = 0; i < avatar->n_vertices; i++)
        start[hits[i].face + 1]++;
    for (uint32_t f = 0; f < proxy->n_faces; f++)
        start[f + 1] += start[f];
    for (uint32_t i = 0; i < avatar->n_vertices; i++)
        out->vertex[start[hits[i].face]++] = i;
    for (uint32_t k = 0; k < avatar->n_vertices; k++) {
        const uint32_t i = out->vertex[k];
        const mim__reg_hit_t *h = hits + i;
        float q[3], t[3], bt[3], n[3];
        const uint32_t *fv = proxy->faces + 3 * (size_t)h->face;
        local_frame(proxy->positions + 3 * (size_t)fv[0], proxy->positions + 3 * (size_t)fv[1],
                    proxy->positions + 3 * (size_t)fv[2], nrm + 3 * (size_t)fv[0], nrm + 3 * (size_t)fv[1],
                    nrm + 3 * (size_t)fv[2], h->u, h->v, q, t, bt, n);
        const float *p = avatar->positions + 3 * (size_t)i;
        float d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
        out->face[k] = h->face;
        out->bary[2 * k] = h->u, out->bary[2 * k + 1] = h->v;
        out->offset[3 * k] = d[0] * t[0] + d[1] * t[1] + d[2] * t[2];
        out->offset[3 * k + 1] = d[0] * bt[0] + d[1] * bt[1] + d[2] * bt[2];
        out->offset[3 * k + 2] = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
    }
done:
    if (rc) mim_reg_binding_free(out);
    free(hits), free(nrm), free(start);
    mim__reg_surface_close(&s);
    return rc;
}

void mim_reg_binding_apply(const mim_reg_binding_t *b, const uint32_t *proxy_faces, const float *proxy_positions,
                           float *work, float *out)
{
    vertex_normals(proxy_faces, b->n_proxy_faces, proxy_positions, b->n_proxy_vertices, work);
    /* entries come in triangle order: each triangle's corners are read once */
    for (uint32_t e = 0; e < b->n_vertices;) {
        const uint32_t f = b->face[e], *fv = proxy_faces + 3 * (size_t)f;
        const float *pa = proxy_positions + 3 * (size_t)fv[0], *pb = proxy_positions + 3 * (size_t)fv[1],
                    *pc = proxy_positions + 3 * (size_t)fv[2];
        const float *na = work + 3 * (size_t)fv[0], *nb = work + 3 * (size_t)fv[1], *nc = work + 3 * (size_t)fv[2];
        for (; e < b->n_vertices && b->face[e] == f; e++) {
            float q[3], t[3], bt[3], n[3];
            local_frame(pa, pb, pc, na, nb, nc, b->bary[2 * e], b->bary[2 * e + 1], q, t, bt, n);
            const float *o = b->offset + 3 * (size_t)e;
            float *x = out + 3 * (size_t)b->vertex[e];
            for (int k = 0; k < 3; k++)
                x[k] = q[k] + o[0] * t[k] + o[1] * bt[k] + o[2] * n[k];
        }
    }
}

/* ---- the cached form: "MRB2", u32 n, n_proxy_vertices, n_proxy_faces,
 * then proxy_rest (3 np floats), vertex (n u32), face (n u32), bary (2 n
 * floats), offset (3 n floats), in the host's byte order (the store is one
 * machine's) ---- */
static const char MAGIC[4] = {'M', 'R', 'B', '2'};
#define HEADER 16u

int mim_reg_binding_encode(const mim_reg_binding_t *b, void **blob, size_t *len, mim_error_t *err)
{
    size_t n = b->n_vertices, np = b->n_proxy_vertices;
    size_t size = HEADER + 4 * (3 * np + 7 * n);
    unsigned char *p = malloc(size);
    if (!p) return mim_error_set(err, MIM_ENOMEM, "binding: out of memory");
    memcpy(p, MAGIC, 4);
    uint32_t h[3] = {b->n_vertices, b->n_proxy_vertices, b->n_proxy_faces};
    memcpy(p + 4, h, sizeof h);
    size_t o = HEADER;
    memcpy(p + o, b->proxy_rest, 12 * np), o += 12 * np;
    memcpy(p + o, b->vertex, 4 * n), o += 4 * n;
    memcpy(p + o, b->face, 4 * n), o += 4 * n;
    memcpy(p + o, b->bary, 8 * n), o += 8 * n;
    memcpy(p + o, b->offset, 12 * n);
    *blob = p, *len = size;
    return 0;
}

int mim_reg_binding_decode(const void *blob, size_t len, uint32_t n_proxy_vertices, uint32_t n_proxy_faces,
                           mim_reg_binding_t *out, mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    const unsigned char *p = blob;
    uint32_t h[3];
    if (!p || len < HEADER || memcmp(p, MAGIC, 4))
        return mim_error_set(err, MIM_EFORMAT, "binding: not a binding record");
    memcpy(h, p + 4, sizeof h);
    if (h[1] != n_proxy_vertices || h[2] != n_proxy_faces)
        return mim_error_set(err, MIM_EFORMAT, "binding: made for a proxy of %u vertices and %u faces, not %u and %u",
                             h[1], h[2], n_proxy_vertices, n_proxy_faces);
    size_t n = h[0], np = h[1];
    if (!n || len != HEADER + 4 * (3 * np + 7 * n))
        return mim_error_set(err, MIM_EFORMAT, "binding: %zu bytes do not hold %zu avatar vertices", len, n);
    if (binding_alloc(out, h[0], h[1], h[2])) return mim_error_set(err, MIM_ENOMEM, "binding: out of memory");
    size_t o = HEADER;
    memcpy(out->proxy_rest, p + o, 12 * np), o += 12 * np;
    memcpy(out->vertex, p + o, 4 * n), o += 4 * n;
    memcpy(out->face, p + o, 4 * n), o += 4 * n;
    memcpy(out->bary, p + o, 8 * n), o += 8 * n;
    memcpy(out->offset, p + o, 12 * n);
    for (size_t i = 0; i < 3 * np; i++)
        if (!isfinite(out->proxy_rest[i])) goto bad;
    uint8_t *seen = calloc(n, 1);
    if (!seen) {
        mim_reg_binding_free(out);
        return mim_error_set(err, MIM_ENOMEM, "binding: out of memory");
    }
    for (size_t i = 0; i < n; i++) {
        uint32_t v = out->vertex[i];
        int dup = v >= n || seen[v];
        if (!dup) seen[v] = 1;
        if (dup || out->face[i] >= n_proxy_faces || (i && out->face[i] < out->face[i - 1])) {
            free(seen);
            goto bad;
        }
    }
    free(seen);
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 2; k++)
            if (!isfinite(out->bary[2 * i + k])) goto bad;
        for (int k = 0; k < 3; k++)
            if (!isfinite(out->offset[3 * i + k])) goto bad;
    }
    return 0;
bad:
    mim_reg_binding_free(out);
    return mim_error_set(err, MIM_EFORMAT, "binding: a field is out of range");
}
