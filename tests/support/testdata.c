/* Test data generators: a closed polygon mesh and writers for every format
 * mimic reads, written here byte by byte so the readers are tested against
 * files that do not come from the library under test. */
#include "test_support.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void ts_sphere(ts_polymesh_t *m, uint32_t rings, uint32_t segs, float r)
{
    memset(m, 0, sizeof *m);
    m->n_vertices = 2 + (rings - 1) * segs;
    m->pos = malloc(sizeof(float) * 3 * m->n_vertices);
    m->n_polys = 2 * segs + (rings - 2) * segs;
    m->sizes = malloc(sizeof(uint32_t) * m->n_polys);
    m->idx = malloc(sizeof(uint32_t) * (6 * segs + 4 * (rings - 2) * segs));
    float *p = m->pos;
    *p++ = 0, *p++ = r, *p++ = 0; /* north pole: vertex 0 */
    for (uint32_t i = 1; i < rings; i++) {
        double th = M_PI * i / rings;
        for (uint32_t j = 0; j < segs; j++) {
            double ph = 2 * M_PI * j / segs;
            *p++ = (float)(r * sin(th) * cos(ph));
            *p++ = (float)(r * cos(th));
            *p++ = (float)(-r * sin(th) * sin(ph));
        }
    }
    *p++ = 0, *p++ = -r, *p++ = 0; /* south pole: last vertex */
    uint32_t south = m->n_vertices - 1, f = 0, k = 0;
#define RING(i, j) (1 + ((i) - 1) * segs + ((j) % segs))
    for (uint32_t j = 0; j < segs; j++) { /* counter-clockwise seen from outside */
        m->sizes[f++] = 3;
        m->idx[k++] = 0, m->idx[k++] = RING(1, j), m->idx[k++] = RING(1, j + 1);
    }
    for (uint32_t i = 1; i + 1 < rings; i++)
        for (uint32_t j = 0; j < segs; j++) {
            m->sizes[f++] = 4;
            m->idx[k++] = RING(i, j), m->idx[k++] = RING(i + 1, j), m->idx[k++] = RING(i + 1, j + 1),
            m->idx[k++] = RING(i, j + 1);
        }
    for (uint32_t j = 0; j < segs; j++) {
        m->sizes[f++] = 3;
        m->idx[k++] = south, m->idx[k++] = RING(rings - 1, j + 1), m->idx[k++] = RING(rings - 1, j);
    }
#undef RING
    m->n_idx = k;
}

void ts_polymesh_free(ts_polymesh_t *m)
{
    free(m->pos);
    free(m->sizes);
    free(m->idx);
    memset(m, 0, sizeof *m);
}

uint32_t ts_polymesh_triangles(const ts_polymesh_t *m)
{
    uint32_t t = 0;
    for (uint32_t f = 0; f < m->n_polys; f++) t += m->sizes[f] - 2;
    return t;
}

void ts_triangulate(const ts_polymesh_t *m, mim_mesh_t *out)
{
    mim_mesh_alloc(out, m->n_vertices, ts_polymesh_triangles(m));
    memcpy(out->positions, m->pos, sizeof(float) * 3 * m->n_vertices);
    uint32_t k = 0, t = 0;
    for (uint32_t f = 0; f < m->n_polys; f++) {
        for (uint32_t c = 2; c < m->sizes[f]; c++) {
            out->faces[3 * t] = m->idx[k];
            out->faces[3 * t + 1] = m->idx[k + c - 1];
            out->faces[3 * t + 2] = m->idx[k + c];
            t++;
        }
        k += m->sizes[f];
    }
}

/* Vertex lines "x y z", then polygon lines "k i1 .. ik": the body of OFF and ASCII PLY. */
static void write_text_body(FILE *f, const ts_polymesh_t *m)
{
    for (uint32_t v = 0; v < m->n_vertices; v++)
        fprintf(f, "%.9g %.9g %.9g\n", m->pos[3 * v], m->pos[3 * v + 1], m->pos[3 * v + 2]);
    for (uint32_t p = 0, k = 0; p < m->n_polys; k += m->sizes[p++]) {
        fprintf(f, "%u", m->sizes[p]);
        for (uint32_t c = 0; c < m->sizes[p]; c++) fprintf(f, " %u", m->idx[k + c]);
        fprintf(f, "\n");
    }
}

int ts_write_off(const char *path, const ts_polymesh_t *m)
{
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fprintf(f, "OFF\n%u %u 0\n", m->n_vertices, m->n_polys);
    write_text_body(f, m);
    return fclose(f);
}

static void ply_header(FILE *f, const ts_polymesh_t *m, const char *format)
{
    fprintf(f, "ply\nformat %s 1.0\ncomment test sphere\nelement vertex %u\nproperty float x\nproperty float y\n"
               "property float z\nelement face %u\nproperty list uchar int vertex_indices\nend_header\n",
            format, m->n_vertices, m->n_polys);
}

int ts_write_ply_ascii(const char *path, const ts_polymesh_t *m)
{
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    ply_header(f, m, "ascii");
    write_text_body(f, m);
    return fclose(f);
}

int ts_write_ply_binary(const char *path, const ts_polymesh_t *m)
{
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    ply_header(f, m, "binary_little_endian");
    fwrite(m->pos, sizeof(float), 3 * (size_t)m->n_vertices, f);
    for (uint32_t p = 0, k = 0; p < m->n_polys; k += m->sizes[p++]) {
        unsigned char n = (unsigned char)m->sizes[p];
        fwrite(&n, 1, 1, f);
        for (uint32_t c = 0; c < m->sizes[p]; c++) {
            int32_t i = (int32_t)m->idx[k + c];
            fwrite(&i, 4, 1, f);
        }
    }
    return fclose(f);
}

int ts_write_mesh_ply(const char *path, const mim_mesh_t *m)
{
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    fprintf(f, "ply\nformat binary_little_endian 1.0\nelement vertex %u\nproperty float x\nproperty float y\n"
               "property float z\nelement face %u\nproperty list uchar int vertex_indices\nend_header\n",
            m->n_vertices, m->n_faces);
    fwrite(m->positions, sizeof(float), 3 * (size_t)m->n_vertices, f);
    for (uint32_t t = 0; t < m->n_faces; t++) {
        unsigned char n = 3;
        fwrite(&n, 1, 1, f);
        fwrite(m->faces + 3 * (size_t)t, 4, 3, f);
    }
    return fclose(f);
}

int ts_write_obj(const char *path, const ts_polymesh_t *m)
{
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fprintf(f, "# test sphere\no sphere\n");
    for (uint32_t v = 0; v < m->n_vertices; v++)
        fprintf(f, "v %.9g %.9g %.9g\n", m->pos[3 * v], m->pos[3 * v + 1], m->pos[3 * v + 2]);
    for (uint32_t p = 0, k = 0; p < m->n_polys; k += m->sizes[p++]) {
        fprintf(f, "f");
        for (uint32_t c = 0; c < m->sizes[p]; c++) fprintf(f, " %u", m->idx[k + c] + 1);
        fprintf(f, "\n");
    }
    return fclose(f);
}

static void tri_normal(const float *a, const float *b, const float *c, float *n)
{
    float u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = u[1] * v[2] - u[2] * v[1], n[1] = u[2] * v[0] - u[0] * v[2], n[2] = u[0] * v[1] - u[1] * v[0];
    float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (l > 0) n[0] /= l, n[1] /= l, n[2] /= l;
}

int ts_write_stl_ascii(const char *path, const ts_polymesh_t *pm)
{
    mim_mesh_t m;
    ts_triangulate(pm, &m);
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fprintf(f, "solid sphere\n");
    for (uint32_t t = 0; t < m.n_faces; t++) {
        const float *a = m.positions + 3 * m.faces[3 * t], *b = m.positions + 3 * m.faces[3 * t + 1],
                    *c = m.positions + 3 * m.faces[3 * t + 2];
        float n[3];
        tri_normal(a, b, c, n);
        fprintf(f, "facet normal %g %g %g\n outer loop\n", n[0], n[1], n[2]);
        const float *vs[3] = {a, b, c};
        for (int i = 0; i < 3; i++) fprintf(f, "  vertex %.9g %.9g %.9g\n", vs[i][0], vs[i][1], vs[i][2]);
        fprintf(f, " endloop\nendfacet\n");
    }
    fprintf(f, "endsolid sphere\n");
    mim_mesh_free(&m);
    return fclose(f);
}

int ts_write_stl_binary(const char *path, const ts_polymesh_t *pm)
{
    mim_mesh_t m;
    ts_triangulate(pm, &m);
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    char header[80] = "binary STL test sphere";
    fwrite(header, 1, 80, f);
    uint32_t n = m.n_faces;
    fwrite(&n, 4, 1, f);
    for (uint32_t t = 0; t < m.n_faces; t++) {
        const float *v[3] = {m.positions + 3 * m.faces[3 * t], m.positions + 3 * m.faces[3 * t + 1],
                             m.positions + 3 * m.faces[3 * t + 2]};
        float nrm[3];
        tri_normal(v[0], v[1], v[2], nrm);
        fwrite(nrm, 4, 3, f);
        for (int i = 0; i < 3; i++) fwrite(v[i], 4, 3, f);
        uint16_t attr = 0;
        fwrite(&attr, 2, 1, f);
    }
    mim_mesh_free(&m);
    return fclose(f);
}

/* The glTF JSON for one indexed triangle primitive; uri NULL for GLB. */
static char *gltf_json(const mim_mesh_t *m, const char *uri)
{
    float mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v = 0; v < m->n_vertices; v++)
        for (int a = 0; a < 3; a++) {
            float x = m->positions[3 * v + a];
            mn[a] = x < mn[a] ? x : mn[a];
            mx[a] = x > mx[a] ? x : mx[a];
        }
    size_t pb = (size_t)m->n_vertices * 12, ib = (size_t)m->n_faces * 12;
    size_t cap = 2048 + (uri ? strlen(uri) : 0);
    char *s = malloc(cap);
    snprintf(s, cap,
             "{\"asset\":{\"version\":\"2.0\",\"generator\":\"mimic tests\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
             "\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1,\"mode\":4}]}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\",\"min\":[%.9g,%.9g,%.9g],"
             "\"max\":[%.9g,%.9g,%.9g]},{\"bufferView\":1,\"componentType\":5125,\"count\":%u,\"type\":\"SCALAR\"}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":%zu},{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}],"
             "\"buffers\":[{\"byteLength\":%zu%s%s%s}]}",
             m->n_vertices, mn[0], mn[1], mn[2], mx[0], mx[1], mx[2], m->n_faces * 3, pb, pb, ib, pb + ib,
             uri ? ",\"uri\":\"" : "", uri ? uri : "", uri ? "\"" : "");
    return s;
}

static unsigned char *gltf_bin(const mim_mesh_t *m, size_t *len)
{
    size_t pb = (size_t)m->n_vertices * 12, ib = (size_t)m->n_faces * 12;
    unsigned char *b = malloc(pb + ib);
    memcpy(b, m->positions, pb);
    memcpy(b + pb, m->faces, ib);
    *len = pb + ib;
    return b;
}

int ts_write_glb(const char *path, const ts_polymesh_t *pm)
{
    mim_mesh_t m;
    ts_triangulate(pm, &m);
    char *json = gltf_json(&m, NULL);
    size_t bl, jl = strlen(json);
    unsigned char *bin = gltf_bin(&m, &bl);
    size_t jpad = (jl + 3) & ~(size_t)3, bpad = (bl + 3) & ~(size_t)3;
    uint32_t total = (uint32_t)(12 + 8 + jpad + 8 + bpad), ver = 2, u;
    FILE *f = fopen(path, "wb");
    fwrite("glTF", 1, 4, f);
    fwrite(&ver, 4, 1, f);
    fwrite(&total, 4, 1, f);
    u = (uint32_t)jpad;
    fwrite(&u, 4, 1, f);
    fwrite("JSON", 1, 4, f);
    fwrite(json, 1, jl, f);
    for (size_t i = jl; i < jpad; i++) fputc(' ', f);
    u = (uint32_t)bpad;
    fwrite(&u, 4, 1, f);
    fwrite("BIN\0", 1, 4, f);
    fwrite(bin, 1, bl, f);
    for (size_t i = bl; i < bpad; i++) fputc(0, f);
    free(json);
    free(bin);
    mim_mesh_free(&m);
    return fclose(f);
}

static char *base64(const unsigned char *d, size_t n)
{
    static const char t[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    char *o = malloc(4 * ((n + 2) / 3) + 1), *p = o;
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)d[i] << 16 | (i + 1 < n ? (uint32_t)d[i + 1] << 8 : 0) | (i + 2 < n ? d[i + 2] : 0);
        *p++ = t[v >> 18 & 63];
        *p++ = t[v >> 12 & 63];
        *p++ = i + 1 < n ? t[v >> 6 & 63] : '=';
        *p++ = i + 2 < n ? t[v & 63] : '=';
    }
    *p = 0;
    return o;
}

int ts_write_gltf(const char *path, const ts_polymesh_t *pm)
{
    mim_mesh_t m;
    ts_triangulate(pm, &m);
    size_t bl;
    unsigned char *bin = gltf_bin(&m, &bl);
    char *b64 = base64(bin, bl);
    char *uri = malloc(strlen(b64) + 64);
    sprintf(uri, "data:application/octet-stream;base64,%s", b64);
    char *json = gltf_json(&m, uri);
    int rc = ts_write_file(path, json, strlen(json));
    free(json);
    free(uri);
    free(b64);
    free(bin);
    mim_mesh_free(&m);
    return rc;
}
