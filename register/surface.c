/* The target surface of a registration: the checks a mesh must pass to be
 * registered onto, and closest points on its triangles (not only its
 * vertices: a coarse scan's triangles are centimetres wide). Nearest
 * vertices come from FLANN's single kd-tree, searched exactly, so the
 * answer is the same on every run. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct edge_rec {
    uint32_t a, b; /* a < b */
    uint32_t slot; /* 3 * face + k */
} edge_rec_t;

static int edge_cmp(const void *x, const void *y)
{
    const edge_rec_t *p = x, *q = y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    if (p->b != q->b) return p->b < q->b ? -1 : 1;
    return p->slot < q->slot ? -1 : p->slot > q->slot;
}

static uint32_t uf_find(uint32_t *p, uint32_t x)
{
    while (p[x] != x)
        x = p[x] = p[p[x]];
    return x;
}

/* Edge use (boundary flags) and the manifold and connectivity checks. */
static int edges_and_pieces(const mim_mesh_t *m, uint8_t *edge_boundary, uint8_t *vertex_boundary, int check,
                            const char *origin, mim_error_t *err)
{
    size_t ne = (size_t)3 * m->n_faces;
    edge_rec_t *e = malloc(ne * sizeof *e);
    uint32_t *parent = malloc((size_t)m->n_vertices * sizeof *parent);
    uint8_t *used = calloc(m->n_vertices, 1);
    int rc = 0;
    if (!e || !parent || !used) {
        rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
        goto done;
    }
    for (uint32_t f = 0; f < m->n_faces; f++)
        for (uint32_t k = 0; k < 3; k++) {
            uint32_t a = m->faces[3 * f + k], b = m->faces[3 * f + (k + 1) % 3];
            e[3 * f + k] = (edge_rec_t){a < b ? a : b, a < b ? b : a, 3 * f + k};
        }
    qsort(e, ne, sizeof *e, edge_cmp);
    for (size_t i = 0; i < ne;) {
        size_t j = i + 1;
        while (j < ne && e[j].a == e[i].a && e[j].b == e[i].b)
            j++;
        if (check == 1 && j - i > 2) {
            rc = mim_error_set(err, MIM_ETOPOLOGY, "%s: non-manifold: edge %u-%u is shared by %zu triangles",
                               origin, e[i].a, e[i].b, j - i);
            goto done;
        }
        if (j - i == 1) {
            edge_boundary[e[i].slot] = 1;
            vertex_boundary[e[i].a] = vertex_boundary[e[i].b] = 1;
        }
        i = j;
    }
    if (check != 1) /* 0: trusted; 2: an avatar's pieces and shells (any edge use, any piece count) */
        goto done;
    for (uint32_t v = 0; v < m->n_vertices; v++)
        parent[v] = v;
    for (uint32_t f = 0; f < m->n_faces; f++)
        for (uint32_t k = 0; k < 3; k++) {
            uint32_t v = m->faces[3 * f + k];
            used[v] = 1;
            uint32_t a = uf_find(parent, v), b = uf_find(parent, m->faces[3 * f]);
            if (a != b) parent[a] = b;
        }
    uint32_t pieces = 0;
    for (uint32_t v = 0; v < m->n_vertices; v++) {
        if (!used[v]) {
            rc = mim_error_set(err, MIM_ETOPOLOGY, "%s: vertex %u is on no triangle", origin, v);
            goto done;
        }
        pieces += uf_find(parent, v) == v;
    }
    if (pieces > 1) {
        /* Count the largest piece for the message. */
        uint32_t *size = calloc(m->n_vertices, sizeof *size), largest = 0;
        if (size) {
            for (uint32_t v = 0; v < m->n_vertices; v++)
                if (++size[uf_find(parent, v)] > largest) largest = size[uf_find(parent, v)];
            free(size);
        }
        rc = mim_error_set(err, MIM_ETOPOLOGY,
                           "%s: disconnected: %u pieces (the largest has %u of %u vertices); registration needs "
                           "one piece",
                           origin, pieces, largest, m->n_vertices);
    }
done:
    free(e), free(parent), free(used);
    return rc;
}

int mim_reg_target_check(const mim_mesh_t *target, const char *origin, mim_error_t *err)
{
    mim__reg_surface_t s;
    int rc = mim__reg_surface_open(&s, target, 1, origin, err);
    if (!rc) mim__reg_surface_close(&s);
    return rc;
}

int mim__reg_surface_open(mim__reg_surface_t *s, const mim_mesh_t *m, int check, const char *origin,
                          mim_error_t *err)
{
    memset(s, 0, sizeof *s);
    if (!origin) origin = "target";
    if (!m || !m->positions || !m->faces || m->n_vertices < 3 || m->n_faces < 1)
        return mim_error_set(err, MIM_EEMPTY, "%s: no triangles to register onto", origin);
    int rc;
    for (uint32_t f = 0; f < m->n_faces; f++)
        for (int k = 0; k < 3; k++)
            if (m->faces[3 * f + k] >= m->n_vertices)
                return mim_error_set(err, MIM_EINDEX, "%s: triangle %u: vertex %u past the %u vertices", origin, f,
                                     m->faces[3 * f + k], m->n_vertices);
    if (check && (rc = mim_body_check(m->positions, m->n_vertices, origin, err)))
        return rc;
    s->n = m->n_vertices, s->nf = m->n_faces, s->faces = m->faces;
    s->pos = malloc((size_t)3 * s->n * sizeof *s->pos);
    s->fnormal = malloc((size_t)3 * s->nf * sizeof *s->fnormal);
    s->sphere = malloc((size_t)4 * s->nf * sizeof *s->sphere);
    s->vf_start = calloc((size_t)s->n + 1, sizeof *s->vf_start);
    s->vf = malloc((size_t)3 * s->nf * sizeof *s->vf);
    s->edge_boundary = calloc((size_t)3 * s->nf, 1);
    s->vertex_boundary = calloc(s->n, 1);
    if (!s->pos || !s->fnormal || !s->sphere || !s->vf_start || !s->vf || !s->edge_boundary || !s->vertex_boundary) {
        mim__reg_surface_close(s);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
    }
    memcpy(s->pos, m->positions, (size_t)3 * s->n * sizeof *s->pos);
    if ((rc = edges_and_pieces(m, s->edge_boundary, s->vertex_boundary, check, origin, err))) {
        mim__reg_surface_close(s);
        return rc;
    }
    for (uint32_t f = 0; f < s->nf; f++)
        for (int k = 0; k < 3; k++)
            s->vf_start[s->faces[3 * f + k] + 1]++;
    for (uint32_t v = 0; v < s->n; v++)
        s->vf_start[v + 1] += s->vf_start[v];
    uint32_t *fill = malloc((size_t)s->n * sizeof *fill);
    if (!fill) {
        mim__reg_surface_close(s);
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", origin);
    }
    memcpy(fill, s->vf_start, (size_t)s->n * sizeof *fill);
    for (uint32_t f = 0; f < s->nf; f++) {
        const float *a = s->pos + 3 * s->faces[3 * f], *b = s->pos + 3 * s->faces[3 * f + 1],
                    *c = s->pos + 3 * s->faces[3 * f + 2];
        mim_vec3 nrm = mim_v3_normalize(mim_v3_cross(mim_v3(b[0] - a[0], b[1] - a[1], b[2] - a[2]),
                                                     mim_v3(c[0] - a[0], c[1] - a[1], c[2] - a[2])));
        s->fnormal[3 * f] = (float)nrm.x, s->fnormal[3 * f + 1] = (float)nrm.y, s->fnormal[3 * f + 2] = (float)nrm.z;
        float *sp = s->sphere + 4 * f, r2 = 0.0f;
        for (int k = 0; k < 3; k++)
            sp[k] = (a[k] + b[k] + c[k]) / 3.0f;
        for (int k = 0; k < 3; k++) {
            const float *q = k == 0 ? a : k == 1 ? b : c;
            float d2 = (q[0] - sp[0]) * (q[0] - sp[0]) + (q[1] - sp[1]) * (q[1] - sp[1]) + (q[2] - sp[2]) * (q[2] - sp[2]);
            if (d2 > r2) r2 = d2;
        }
        sp[3] = sqrtf(r2) * 1.0001f + 1e-7f;
        for (int k = 0; k < 3; k++)
            s->vf[fill[s->faces[3 * f + k]]++] = f;
    }
    free(fill);
    s->params = DEFAULT_FLANN_PARAMETERS;
    s->params.algorithm = FLANN_INDEX_KDTREE_SINGLE;
    s->params.leaf_max_size = 10;
    s->params.checks = FLANN_CHECKS_UNLIMITED;
    s->params.eps = 0.0f;
    s->params.cores = 1;
    s->params.log_level = FLANN_LOG_NONE;
    s->params.random_seed = 0; /* no srand (index/model.c says why) */
    float speedup = 0.0f;
    s->index = flann_build_index_float(s->pos, (int)s->n, 3, &speedup, &s->params);
    if (!s->index) {
        mim__reg_surface_close(s);
        return mim_error_set(err, MIM_EUNSUPPORTED, "%s: FLANN could not build the closest-point tree", origin);
    }
    return 0;
}

void mim__reg_surface_close(mim__reg_surface_t *s)
{
    if (s->index) flann_free_index_float(s->index, &s->params);
    free(s->pos), free(s->fnormal), free(s->sphere), free(s->vf_start), free(s->vf), free(s->edge_boundary), free(s->vertex_boundary);
    memset(s, 0, sizeof *s);
}

/* Closest point on triangle abc to p (Ericson, Real-Time Collision
 * Detection, 5.1.5): barycentric (u, v) of b and c, and the region: 0
 * inside, 1..3 vertex a, b, c, 4..6 edge ab, bc, ca. */
static int closest_on_triangle(const double p[3], const double a[3], const double b[3], const double c[3], double *u,
                               double *v)
{
    double ab[3], ac[3], ap[3];
    for (int k = 0; k < 3; k++)
        ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    double d1 = ab[0] * ap[0] + ab[1] * ap[1] + ab[2] * ap[2], d2 = ac[0] * ap[0] + ac[1] * ap[1] + ac[2] * ap[2];
    if (d1 <= 0 && d2 <= 0) return *u = 0, *v = 0, 1;
    double bp[3];
    for (int k = 0; k < 3; k++)
        bp[k] = p[k] - b[k];
    double d3 = ab[0] * bp[0] + ab[1] * bp[1] + ab[2] * bp[2], d4 = ac[0] * bp[0] + ac[1] * bp[1] + ac[2] * bp[2];
    if (d3 >= 0 && d4 <= d3) return *u = 1, *v = 0, 2;
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return *u = d1 / (d1 - d3), *v = 0, 4;
    double cp[3];
    for (int k = 0; k < 3; k++)
        cp[k] = p[k] - c[k];
    double d5 = ab[0] * cp[0] + ab[1] * cp[1] + ab[2] * cp[2], d6 = ac[0] * cp[0] + ac[1] * cp[1] + ac[2] * cp[2];
    if (d6 >= 0 && d5 <= d6) return *u = 0, *v = 1, 3;
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return *u = 0, *v = d2 / (d2 - d6), 6;
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return *u = 1 - w, *v = w, 5;
    }
    double den = 1.0 / (va + vb + vc);
    *u = vb * den, *v = vc * den;
    return 0;
}

int mim__reg_surface_closest(const mim__reg_surface_t *s, const float *queries, uint32_t nq, mim__reg_hit_t *hits,
                             mim_error_t *err)
{
    int k = s->n < MIM__REG_KNN ? (int)s->n : MIM__REG_KNN;
    int *ind = malloc((size_t)nq * k * sizeof *ind);
    float *dist = malloc((size_t)nq * k * sizeof *dist);
    if (!ind || !dist) {
        free(ind), free(dist);
        return mim_error_set(err, MIM_ENOMEM, "closest points: out of memory");
    }
    struct FLANNParameters p = s->params;
    if (flann_find_nearest_neighbors_index_float(s->index, (float *)queries, (int)nq, ind, dist, k, &p) != 0) {
        free(ind), free(dist);
        return mim_error_set(err, MIM_EUNSUPPORTED, "closest points: FLANN search failed");
    }
    for (uint32_t q = 0; q < nq; q++) {
        double pq[3] = {queries[3 * q], queries[3 * q + 1], queries[3 * q + 2]};
        mim__reg_hit_t best = {.d2 = INFINITY};
        int best_region = 0;
        for (int j = 0; j < k; j++) {
            int vtx = ind[(size_t)q * k + j];
            if (vtx < 0 || (uint32_t)vtx >= s->n) continue;
            for (uint32_t i = s->vf_start[vtx]; i < s->vf_start[vtx + 1]; i++) {
                uint32_t f = s->vf[i];
                /* No point of the triangle is nearer than its sphere allows. */
                const float *sp = s->sphere + 4 * f;
                double dc = sqrt((pq[0] - sp[0]) * (pq[0] - sp[0]) + (pq[1] - sp[1]) * (pq[1] - sp[1]) +
                                 (pq[2] - sp[2]) * (pq[2] - sp[2])) - sp[3];
                if (dc > 0 && dc * dc >= best.d2) continue;
                const uint32_t *fv = s->faces + 3 * f;
                double a[3], b[3], c[3], u, v;
                for (int t = 0; t < 3; t++)
                    a[t] = s->pos[3 * fv[0] + t], b[t] = s->pos[3 * fv[1] + t], c[t] = s->pos[3 * fv[2] + t];
                int region = closest_on_triangle(pq, a, b, c, &u, &v);
                double d2 = 0, pt[3];
                for (int t = 0; t < 3; t++) {
                    pt[t] = (1 - u - v) * a[t] + u * b[t] + v * c[t];
                    d2 += (pt[t] - pq[t]) * (pt[t] - pq[t]);
                }
                if (d2 < best.d2) {
                    best = (mim__reg_hit_t){f, {(float)pt[0], (float)pt[1], (float)pt[2]}, (float)u, (float)v, d2, 0};
                    best_region = region;
                }
            }
        }
        if (best.d2 < INFINITY) {
            const uint32_t *fv = s->faces + 3 * best.face;
            if (best_region >= 1 && best_region <= 3) best.boundary = s->vertex_boundary[fv[best_region - 1]];
            else if (best_region >= 4) best.boundary = s->edge_boundary[3 * best.face + (best_region - 4)];
        }
        hits[q] = best;
    }
    free(ind), free(dist);
    return 0;
}

int mim_reg_surface_distance(const mim_mesh_t *target, const float *points, uint32_t n, double *dist,
                             mim_error_t *err)
{
    if (!points || !dist) return mim_error_set(err, MIM_EINVAL, "surface distance: no points");
    mim__reg_surface_t s;
    int rc = mim__reg_surface_open(&s, target, 1, "target", err);
    if (rc) return rc;
    mim__reg_hit_t *hits = malloc((size_t)(n ? n : 1) * sizeof *hits);
    if (!hits) rc = mim_error_set(err, MIM_ENOMEM, "surface distance: out of memory");
    if (!rc && n) rc = mim__reg_surface_closest(&s, points, n, hits, err);
    for (uint32_t i = 0; !rc && i < n; i++)
        dist[i] = sqrt(hits[i].d2);
    free(hits);
    mim__reg_surface_close(&s);
    return rc;
}
