/* Ground-truth re-triangulations for register/ (retriangulate.h): midpoint
 * subdivision and random renumbering. Decimation is in decimate.cpp. */
#include "retriangulate.h"

#include <math.h>

#include <stdlib.h>
#include <string.h>

/* in is a triangle mesh whose faces index its vertices. */
static int check_mesh(const mim_mesh_t *in)
{
    if (!in || !in->n_vertices || !in->n_faces || !in->positions || !in->faces)
        return MIM_EINVAL;
    for (size_t k = 0; k < 3 * (size_t)in->n_faces; k++)
        if (in->faces[k] >= in->n_vertices)
            return MIM_EINVAL;
    return 0;
}

typedef struct half_edge {
    uint64_t key; /* smaller vertex << 32 | larger vertex */
    uint32_t corner; /* 3 * face + k: the edge from corner k to corner k + 1 */
} half_edge_t;

static int cmp_half_edge(const void *a, const void *b)
{
    const half_edge_t *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return x->corner < y->corner ? -1 : x->corner > y->corner;
}

int rt_subdivide(const mim_mesh_t *in, mim_mesh_t *out)
{
    if (out)
        memset(out, 0, sizeof *out);
    if (!out)
        return MIM_EINVAL;
    int rc = check_mesh(in);
    if (rc)
        return rc;
    if (in->n_faces > UINT32_MAX / 4)
        return MIM_EUNSUPPORTED;
    size_t nh = 3 * (size_t)in->n_faces;
    half_edge_t *he = malloc(nh * sizeof *he);
    uint32_t *mid = malloc(nh * sizeof *mid); /* midpoint vertex of each corner's edge */
    if (!he || !mid) {
        free(he), free(mid);
        return MIM_ENOMEM;
    }
    for (size_t c = 0; c < nh; c++) {
        uint64_t a = in->faces[c], b = in->faces[c - c % 3 + (c % 3 + 1) % 3];
        he[c].key = a < b ? a << 32 | b : b << 32 | a;
        he[c].corner = (uint32_t)c;
    }
    /* sorting brings the half-edges of one edge together: one midpoint each */
    qsort(he, nh, sizeof *he, cmp_half_edge);
    uint64_t nv = in->n_vertices;
    for (size_t i = 0; i < nh; i++) {
        if (i == 0 || he[i].key != he[i - 1].key)
            nv++;
        mid[he[i].corner] = (uint32_t)(nv - 1);
    }
    if (nv > UINT32_MAX) {
        free(he), free(mid);
        return MIM_EUNSUPPORTED;
    }
    rc = mim_mesh_alloc(out, (uint32_t)nv, 4 * in->n_faces);
    if (rc) {
        free(he), free(mid);
        return rc;
    }
    memcpy(out->positions, in->positions, 3 * (size_t)in->n_vertices * sizeof *out->positions);
    for (size_t i = 0; i < nh; i++) {
        if (i > 0 && he[i].key == he[i - 1].key)
            continue;
        uint32_t a = (uint32_t)(he[i].key >> 32), b = (uint32_t)he[i].key, m = mid[he[i].corner];
        for (int k = 0; k < 3; k++)
            out->positions[3 * (size_t)m + k] =
                (float)(0.5 * ((double)in->positions[3 * (size_t)a + k] + (double)in->positions[3 * (size_t)b + k]));
    }
    for (size_t f = 0; f < in->n_faces; f++) {
        const uint32_t *t = in->faces + 3 * f;
        uint32_t a = t[0], b = t[1], c = t[2];
        uint32_t ab = mid[3 * f], bc = mid[3 * f + 1], ca = mid[3 * f + 2];
        uint32_t *o = out->faces + 12 * f;
        /* three corner triangles and the middle one, all as a b c turns */
        o[0] = a, o[1] = ab, o[2] = ca;
        o[3] = ab, o[4] = b, o[5] = bc;
        o[6] = ca, o[7] = bc, o[8] = c;
        o[9] = ab, o[10] = bc, o[11] = ca;
    }
    free(he), free(mid);
    return 0;
}

/* A uniformly random permutation of 0..n-1 (Fisher-Yates). */
static void random_permutation(uint32_t *p, uint32_t n, mim_rng_t *r)
{
    for (uint32_t i = 0; i < n; i++)
        p[i] = i;
    for (uint32_t i = n; i > 1; i--) {
        uint32_t j = (uint32_t)mim_rng_below(r, i), t = p[i - 1];
        p[i - 1] = p[j], p[j] = t;
    }
}

int rt_shuffle(const mim_mesh_t *in, uint64_t seed, mim_mesh_t *out, uint32_t *new_of_old)
{
    if (out)
        memset(out, 0, sizeof *out);
    if (!out)
        return MIM_EINVAL;
    int rc = check_mesh(in);
    if (rc)
        return rc;
    uint32_t nv = in->n_vertices, nf = in->n_faces;
    uint32_t *old_of_new = malloc((size_t)nv * sizeof *old_of_new);
    uint32_t *nofo = malloc((size_t)nv * sizeof *nofo);
    uint32_t *face_order = malloc((size_t)nf * sizeof *face_order);
    if (!old_of_new || !nofo || !face_order || (rc = mim_mesh_alloc(out, nv, nf))) {
        free(old_of_new), free(nofo), free(face_order);
        return rc ? rc : MIM_ENOMEM;
    }
    /* one stream each for the vertex order, the face order and the corners */
    mim_rng_t rv, rf, rc3;
    mim_rng_seed(&rv, seed, 0);
    mim_rng_seed(&rf, seed, 1);
    mim_rng_seed(&rc3, seed, 2);
    random_permutation(old_of_new, nv, &rv);
    random_permutation(face_order, nf, &rf);
    for (uint32_t v = 0; v < nv; v++) {
        nofo[old_of_new[v]] = v;
        memcpy(out->positions + 3 * (size_t)v, in->positions + 3 * (size_t)old_of_new[v], 3 * sizeof(float));
    }
    for (uint32_t f = 0; f < nf; f++) {
        const uint32_t *t = in->faces + 3 * (size_t)face_order[f];
        uint32_t s = (uint32_t)mim_rng_below(&rc3, 3); /* a cyclic turn keeps the orientation */
        for (uint32_t k = 0; k < 3; k++)
            out->faces[3 * (size_t)f + k] = nofo[t[(k + s) % 3]];
    }
    if (new_of_old)
        memcpy(new_of_old, nofo, (size_t)nv * sizeof *nofo);
    free(old_of_new), free(nofo), free(face_order);
    return 0;
}

/* ---- measuring a registration against the truth ---- */
static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int rt_correspondence(const float *a, const float *b, uint32_t count, double *mean_mm, double *p95_mm)
{
    double *d = malloc((count ? count : 1) * sizeof *d), sum = 0;
    if (!d) return MIM_ENOMEM;
    for (uint32_t i = 0; i < count; i++) {
        double s = 0;
        for (int c = 0; c < 3; c++) s += ((double)a[3 * i + c] - b[3 * i + c]) * ((double)a[3 * i + c] - b[3 * i + c]);
        d[i] = 1000.0 * sqrt(s), sum += d[i];
    }
    qsort(d, count, sizeof *d, cmp_double);
    *mean_mm = count ? sum / count : 0, *p95_mm = count ? d[(size_t)floor(0.95 * (count - 1))] : 0;
    free(d);
    return 0;
}

int rt_target(const mim_mesh_t *truth, int how, uint64_t seed, mim_mesh_t *target)
{
    mim_mesh_t mid = {0};
    memset(target, 0, sizeof *target);
    int rc = how == 0 ? rt_subdivide(truth, &mid) : rt_decimate(truth, (uint32_t)(0.4 * truth->n_vertices), &mid);
    if (!rc) rc = rt_shuffle(&mid, seed, target, NULL);
    mim_mesh_free(&mid);
    return rc;
}

void rt_tetrahedron(float *pos, uint32_t *faces, uint32_t base, float x0)
{
    const float p[12] = {0, 0, 0, 0.5f, 0, 0, 0, 1.6f, 0, 0, 0, 0.3f};
    for (int i = 0; i < 12; i++) pos[i] = p[i] + (i % 3 == 0 ? x0 : 0);
    const uint32_t t[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    for (int i = 0; i < 12; i++) faces[i] = t[i] + base;
}
