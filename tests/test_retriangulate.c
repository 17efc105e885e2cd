/* tests/support/retriangulate: the ground-truth re-triangulations that
 * register/ is measured with (subdivision, renumbering, quadric
 * decimation), on a hand-made octahedron and synth bodies. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "mim_core.h"
#include "mim_synth.h"
#include "retriangulate.h"
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- helpers ---- */

/* A synth body (subject 1, pose 3) as one mesh, its own copy of the faces. */
static void synth_mesh(uint32_t vertices, mim_mesh_t *m)
{
    mim_synth_options_t o = {.subjects = 2, .poses = 4, .vertices = vertices, .seed = 3};
    mim_synth_t *s = NULL;
    mim_error_t e = {0};
    int rc = mim_synth_create(&s, &o, &e);
    if (rc) fprintf(stderr, "synth: %s\n", mim_error_text(&e));
    assert_int_equal(rc, 0);
    assert_int_equal(mim_mesh_alloc(m, mim_synth_n_vertices(s), mim_synth_n_faces(s)), 0);
    memcpy(m->faces, mim_synth_faces(s), 3 * (size_t)m->n_faces * sizeof *m->faces);
    assert_int_equal(mim_synth_body(s, 1, 3, m->positions), 0);
    mim_synth_destroy(&s);
}

/* The octahedron of radius 1, outward-oriented: V 6, E 12, F 8. */
static void octahedron(mim_mesh_t *m)
{
    static const float p[18] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
    static const uint32_t f[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
    assert_int_equal(mim_mesh_alloc(m, 6, 8), 0);
    memcpy(m->positions, p, sizeof p);
    memcpy(m->faces, f, sizeof f);
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint64_t edge_key(uint32_t a, uint32_t b) { return (uint64_t)a << 32 | b; }

/* Number of undirected edges; fails unless the mesh is a closed, oriented
 * 2-manifold: every directed edge once and its reverse once (so every edge
 * is shared by exactly two faces, which agree on its direction), no
 * degenerate triangle, every vertex on a face and its faces one fan. */
static uint32_t check_closed_manifold(const mim_mesh_t *m)
{
    size_t nh = 3 * (size_t)m->n_faces;
    uint64_t *dir = malloc(nh * sizeof *dir);
    assert_non_null(dir);
    for (size_t c = 0; c < nh; c++) {
        uint32_t a = m->faces[c], b = m->faces[c - c % 3 + (c % 3 + 1) % 3];
        assert_true(a < m->n_vertices);
        if (a == b) fail_msg("face %zu is degenerate", c / 3);
        dir[c] = edge_key(a, b);
    }
    qsort(dir, nh, sizeof *dir, cmp_u64);
    for (size_t i = 1; i < nh; i++)
        if (dir[i] == dir[i - 1])
            fail_msg("directed edge %u-%u twice", (unsigned)(dir[i] >> 32), (unsigned)dir[i]);
    for (size_t i = 0; i < nh; i++) {
        uint64_t rev = edge_key((uint32_t)dir[i], (uint32_t)(dir[i] >> 32));
        if (!bsearch(&rev, dir, nh, sizeof *dir, cmp_u64))
            fail_msg("edge %u-%u on one face only", (unsigned)(dir[i] >> 32), (unsigned)dir[i]);
    }
    free(dir);

    /* one fan per vertex: following b -> c over the corners (a, b, c) at a
     * vertex visits all of them in one cycle */
    uint32_t *start = calloc((size_t)m->n_vertices + 1, sizeof *start);
    uint32_t *corner = malloc(nh * sizeof *corner);
    uint8_t *seen = calloc(nh, 1);
    assert_true(start && corner && seen);
    for (size_t c = 0; c < nh; c++) start[m->faces[c] + 1]++;
    for (uint32_t v = 0; v < m->n_vertices; v++) start[v + 1] += start[v];
    uint32_t *fill = malloc(((size_t)m->n_vertices + 1) * sizeof *fill);
    assert_non_null(fill);
    memcpy(fill, start, ((size_t)m->n_vertices + 1) * sizeof *fill);
    for (size_t c = 0; c < nh; c++) corner[fill[m->faces[c]]++] = (uint32_t)c;
    for (uint32_t v = 0; v < m->n_vertices; v++) {
        uint32_t deg = start[v + 1] - start[v];
        if (deg < 3) fail_msg("vertex %u is on %u faces", v, deg);
        uint32_t c = corner[start[v]], walked = 0;
        do {
            seen[c] = 1, walked++;
            uint32_t next = m->faces[c - c % 3 + (c % 3 + 2) % 3]; /* the corner before a: c of (a, b, c) */
            uint32_t k = start[v];
            for (; k < start[v + 1]; k++)
                if (m->faces[corner[k] - corner[k] % 3 + (corner[k] % 3 + 1) % 3] == next) break;
            assert_true(k < start[v + 1]);
            c = corner[k];
        } while (!seen[c] && walked <= deg);
        if (walked != deg) fail_msg("vertex %u: its %u faces are not one fan", v, deg);
    }
    free(start), free(corner), free(seen), free(fill);
    return m->n_faces * 3 / 2;
}

static int cmp_tri(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return 0;
}

/* Faces turned so that the smallest index comes first (orientation kept),
 * then sorted: two meshes with one face set give equal arrays. */
static uint32_t *canonical_faces(const uint32_t *faces, uint32_t nf, const uint32_t *rename)
{
    uint32_t *t = malloc(3 * (size_t)nf * sizeof *t);
    assert_non_null(t);
    for (size_t f = 0; f < nf; f++) {
        uint32_t v[3];
        for (int k = 0; k < 3; k++) v[k] = rename ? rename[faces[3 * f + k]] : faces[3 * f + k];
        int s = v[1] < v[0] && v[1] < v[2] ? 1 : v[2] < v[0] && v[2] < v[1] ? 2 : 0;
        for (int k = 0; k < 3; k++) t[3 * f + k] = v[(k + s) % 3];
    }
    qsort(t, nf, 3 * sizeof *t, cmp_tri);
    return t;
}

static double dist(const float *a, const float *b)
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* ---- subdivision ---- */

static void check_subdivided(const mim_mesh_t *in, const mim_mesh_t *out, uint32_t n_edges)
{
    assert_int_equal(out->n_vertices, in->n_vertices + n_edges);
    assert_int_equal(out->n_faces, 4 * in->n_faces);
    assert_memory_equal(out->positions, in->positions, 3 * (size_t)in->n_vertices * sizeof(float));
    assert_int_equal(check_closed_manifold(out), 2 * n_edges + 3 * in->n_faces);
    /* each face's corner triangles: original corner, then the midpoints of its two edges */
    for (uint32_t f = 0; f < in->n_faces; f++) {
        const uint32_t *t = in->faces + 3 * (size_t)f;
        for (int k = 0; k < 3; k++) {
            const uint32_t *o = out->faces + 12 * (size_t)f + 3 * k;
            uint32_t a = t[k], b = t[(k + 1) % 3];
            assert_int_equal(o[k], a); /* triangle k keeps corner k in place */
            uint32_t m = out->faces[12 * (size_t)f + 9 + k]; /* the middle triangle: ab, bc, ca */
            assert_true(m >= in->n_vertices);
            for (int c = 0; c < 3; c++)
                assert_float_equal(out->positions[3 * (size_t)m + c],
                                   0.5f * (in->positions[3 * (size_t)a + c] + in->positions[3 * (size_t)b + c]),
                                   1e-6);
        }
    }
}

static void test_subdivide_octahedron(void **state)
{
    (void)state;
    mim_mesh_t in = {0}, out = {0}, twice = {0};
    octahedron(&in);
    assert_int_equal(check_closed_manifold(&in), 12);
    assert_int_equal(rt_subdivide(&in, &out), 0);
    check_subdivided(&in, &out, 12);
    assert_int_equal(out.n_vertices, 18);
    assert_int_equal(out.n_faces, 32);
    /* again: V 18 + E 48 */
    assert_int_equal(rt_subdivide(&out, &twice), 0);
    check_subdivided(&out, &twice, 48);
    assert_int_equal(twice.n_vertices, 66);
    mim_mesh_free(&in), mim_mesh_free(&out), mim_mesh_free(&twice);
}

static void test_subdivide_body(void **state)
{
    (void)state;
    mim_mesh_t in = {0}, out = {0};
    synth_mesh(1500, &in);
    uint32_t e = check_closed_manifold(&in);
    assert_int_equal(rt_subdivide(&in, &out), 0);
    check_subdivided(&in, &out, e);
    /* a genus-0 surface stays one: V - E + F = 2 */
    assert_int_equal((int64_t)out.n_vertices - (int64_t)(out.n_faces * 3 / 2) + out.n_faces, 2);
    mim_mesh_free(&in), mim_mesh_free(&out);
}

/* ---- shuffle ---- */

static void test_shuffle(void **state)
{
    (void)state;
    mim_mesh_t in = {0}, out = {0}, again = {0}, other = {0};
    synth_mesh(1500, &in);
    uint32_t *nofo = malloc((size_t)in.n_vertices * sizeof *nofo);
    assert_non_null(nofo);
    assert_int_equal(rt_shuffle(&in, 42, &out, nofo), 0);
    assert_int_equal(out.n_vertices, in.n_vertices);
    assert_int_equal(out.n_faces, in.n_faces);
    /* a permutation, and the positions follow it exactly */
    uint8_t *hit = calloc(in.n_vertices, 1);
    assert_non_null(hit);
    uint32_t moved = 0;
    for (uint32_t i = 0; i < in.n_vertices; i++) {
        assert_true(nofo[i] < in.n_vertices);
        assert_false(hit[nofo[i]]);
        hit[nofo[i]] = 1;
        moved += nofo[i] != i;
        assert_memory_equal(out.positions + 3 * (size_t)nofo[i], in.positions + 3 * (size_t)i, 3 * sizeof(float));
    }
    assert_true(moved > in.n_vertices / 2);
    /* the same oriented faces up to renaming, in another order */
    uint32_t *a = canonical_faces(in.faces, in.n_faces, nofo), *b = canonical_faces(out.faces, out.n_faces, NULL);
    assert_memory_equal(a, b, 3 * (size_t)in.n_faces * sizeof *a);
    uint32_t same_place = 0;
    for (uint32_t f = 0; f < in.n_faces; f++) {
        uint32_t *t = in.faces + 3 * (size_t)f, *u = out.faces + 3 * (size_t)f;
        same_place += nofo[t[0]] == u[0] && nofo[t[1]] == u[1] && nofo[t[2]] == u[2];
    }
    assert_true(same_place < in.n_faces / 10);
    check_closed_manifold(&out);
    /* one seed, one result; another seed, another */
    assert_int_equal(rt_shuffle(&in, 42, &again, NULL), 0);
    assert_memory_equal(again.positions, out.positions, 3 * (size_t)in.n_vertices * sizeof(float));
    assert_memory_equal(again.faces, out.faces, 3 * (size_t)in.n_faces * sizeof(uint32_t));
    assert_int_equal(rt_shuffle(&in, 43, &other, NULL), 0);
    assert_memory_not_equal(other.positions, out.positions, 3 * (size_t)in.n_vertices * sizeof(float));
    free(a), free(b), free(hit), free(nofo);
    mim_mesh_free(&in), mim_mesh_free(&out), mim_mesh_free(&again), mim_mesh_free(&other);
}

/* ---- decimation ---- */

static void test_decimate_body(void **state)
{
    (void)state;
    mim_mesh_t in = {0}, out = {0};
    synth_mesh(7000, &in);
    check_closed_manifold(&in);
    uint32_t target = (uint32_t)(0.3 * in.n_vertices + 0.5), *orig = NULL;
    assert_int_equal(rt_decimate_map(&in, target, &out, &orig), 0);
    assert_non_null(orig);
    assert_true(fabs((double)out.n_vertices - target) <= 0.05 * target);
    check_closed_manifold(&out);
    /* the topology of the body is kept: genus 0 */
    assert_int_equal((int64_t)out.n_vertices - (int64_t)(out.n_faces * 3 / 2) + out.n_faces, 2);
    /* every kept vertex is an original one, where it was (half-edge
     * collapses), so within 2 cm of the nearest original vertex (brute force) */
    double worst = 0;
    for (uint32_t v = 0; v < out.n_vertices; v++) {
        assert_true(orig[v] < in.n_vertices);
        assert_memory_equal(out.positions + 3 * (size_t)v, in.positions + 3 * (size_t)orig[v], 3 * sizeof(float));
        double best = INFINITY;
        for (uint32_t u = 0; u < in.n_vertices; u++) {
            double d = dist(out.positions + 3 * (size_t)v, in.positions + 3 * (size_t)u);
            if (d < best) best = d;
        }
        if (best > worst) worst = best;
    }
    assert_true(worst <= 0.02);
    /* no two output vertices are one original vertex */
    uint8_t *hit = calloc(in.n_vertices, 1);
    assert_non_null(hit);
    for (uint32_t v = 0; v < out.n_vertices; v++) {
        assert_false(hit[orig[v]]);
        hit[orig[v]] = 1;
    }
    free(hit), free(orig);
    /* without the map: the same mesh */
    mim_mesh_t plain = {0};
    assert_int_equal(rt_decimate(&in, target, &plain), 0);
    assert_int_equal(plain.n_vertices, out.n_vertices);
    assert_memory_equal(plain.faces, out.faces, 3 * (size_t)out.n_faces * sizeof(uint32_t));
    mim_mesh_free(&plain), mim_mesh_free(&in), mim_mesh_free(&out);
}

static void test_decimate_keeps_small_target_and_drops_unused(void **state)
{
    (void)state;
    mim_mesh_t oct = {0}, in = {0}, out = {0};
    octahedron(&oct);
    /* the octahedron plus one vertex on no face */
    assert_int_equal(mim_mesh_alloc(&in, 7, 8), 0);
    memcpy(in.positions, oct.positions, 18 * sizeof(float));
    in.positions[18] = 5, in.positions[19] = 5, in.positions[20] = 5;
    memcpy(in.faces, oct.faces, 24 * sizeof(uint32_t));
    uint32_t *orig = NULL;
    assert_int_equal(rt_decimate_map(&in, 100, &out, &orig), 0);
    assert_int_equal(out.n_vertices, 6);
    assert_int_equal(out.n_faces, 8);
    check_closed_manifold(&out);
    for (uint32_t v = 0; v < 6; v++) assert_int_equal(orig[v], v);
    free(orig);
    mim_mesh_free(&out);
    /* down to a tetrahedron at most: still closed */
    assert_int_equal(rt_decimate(&oct, 4, &out), 0);
    assert_true(out.n_vertices >= 4 && out.n_vertices < 6);
    check_closed_manifold(&out);
    mim_mesh_free(&out), mim_mesh_free(&in), mim_mesh_free(&oct);
}

/* ---- bad input ---- */

static void test_bad_inputs(void **state)
{
    (void)state;
    mim_mesh_t oct = {0}, out = {0}, empty = {0};
    uint32_t dummy = 0, *orig = &dummy; /* must come back NULL */
    octahedron(&oct);
    assert_int_equal(rt_subdivide(NULL, &out), MIM_EINVAL);
    assert_int_equal(rt_subdivide(&oct, NULL), MIM_EINVAL);
    assert_int_equal(rt_subdivide(&empty, &out), MIM_EINVAL);
    assert_int_equal(rt_shuffle(&empty, 1, &out, NULL), MIM_EINVAL);
    assert_int_equal(rt_decimate(&empty, 10, &out), MIM_EINVAL);
    assert_int_equal(rt_decimate(&oct, 3, &out), MIM_EINVAL);
    assert_int_equal(rt_decimate(&oct, 4, NULL), MIM_EINVAL);
    oct.faces[5] = 6; /* past the vertex count */
    assert_int_equal(rt_subdivide(&oct, &out), MIM_EINVAL);
    assert_null(out.positions);
    assert_int_equal(rt_shuffle(&oct, 1, &out, NULL), MIM_EINVAL);
    assert_int_equal(rt_decimate_map(&oct, 4, &out, &orig), MIM_EINVAL);
    assert_null(orig);
    assert_null(out.positions);
    mim_mesh_free(&oct);

    /* an edge on three faces: OpenMesh cannot hold it */
    static const float p[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1};
    static const uint32_t f[9] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    mim_mesh_t fin = {0};
    assert_int_equal(mim_mesh_alloc(&fin, 5, 3), 0);
    memcpy(fin.positions, p, sizeof p);
    memcpy(fin.faces, f, sizeof f);
    assert_int_equal(rt_decimate(&fin, 4, &out), MIM_EINVAL);
    assert_null(out.positions);
    /* subdivision takes it: one midpoint for the shared edge */
    assert_int_equal(rt_subdivide(&fin, &out), 0);
    assert_int_equal(out.n_vertices, 5 + 7);
    mim_mesh_free(&out), mim_mesh_free(&fin);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_subdivide_octahedron),
        cmocka_unit_test(test_subdivide_body),
        cmocka_unit_test(test_shuffle),
        cmocka_unit_test(test_decimate_body),
        cmocka_unit_test(test_decimate_keeps_small_target_and_drops_unused),
        cmocka_unit_test(test_bad_inputs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
