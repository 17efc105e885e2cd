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

/* POSITION's min and max, as glTF requires them. */
static void gltf_bounds(const mim_mesh_t *m, float mn[3], float mx[3])
{
    for (int a = 0; a < 3; a++) mn[a] = INFINITY, mx[a] = -INFINITY;
    for (uint32_t v = 0; v < m->n_vertices; v++)
        for (int a = 0; a < 3; a++) {
            float x = m->positions[3 * v + a];
            mn[a] = x < mn[a] ? x : mn[a];
            mx[a] = x > mx[a] ? x : mx[a];
        }
}

/* The glTF JSON for one indexed triangle primitive; uri NULL for GLB. */
static char *gltf_json(const mim_mesh_t *m, const char *uri)
{
    float mn[3], mx[3];
    gltf_bounds(m, mn, mx);
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

/* A GLB file: the header, the JSON chunk (padded with spaces), the BIN
 * chunk (padded with zeros). */
static int write_glb_file(const char *path, const char *json, const unsigned char *bin, size_t bl)
{
    size_t jl = strlen(json);
    size_t jpad = (jl + 3) & ~(size_t)3, bpad = (bl + 3) & ~(size_t)3;
    uint32_t total = (uint32_t)(12 + 8 + jpad + 8 + bpad), ver = 2, u;
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
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
    return fclose(f);
}

int ts_write_glb(const char *path, const ts_polymesh_t *pm)
{
    mim_mesh_t m;
    ts_triangulate(pm, &m);
    char *json = gltf_json(&m, NULL);
    size_t bl;
    unsigned char *bin = gltf_bin(&m, &bl);
    int rc = write_glb_file(path, json, bin, bl);
    free(json);
    free(bin);
    mim_mesh_free(&m);
    return rc;
}

/* A JSON string literal (quotes, backslashes and control characters escaped). */
static void json_string(FILE *f, const char *s)
{
    fputc('"', f);
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        if (*p == '"' || *p == '\\') fprintf(f, "\\%c", *p);
        else if (*p < 0x20) fprintf(f, "\\u%04x", *p);
        else fputc(*p, f);
    }
    fputc('"', f);
}

int ts_write_skinned_glb(const char *path, const mim_mesh_t *m, const char *const *joint_names, uint32_t n_joints,
                         const uint16_t *joints, const float *weights, int weight_type)
{
    const int joints_u8 = (weight_type & TS_SKIN_JOINTS_U8) != 0;
    weight_type &= ~TS_SKIN_JOINTS_U8;
    if (n_joints == 0 || weight_type < 0 || weight_type > 2) return -1;
    const size_t nv = m->n_vertices, n4 = 4 * nv;
    const size_t wsize[3] = {4, 1, 2}, jsize = joints_u8 ? 1 : 2;
    /* four tightly packed views, each a multiple of 4 bytes long: positions,
     * indices, JOINTS_0, WEIGHTS_0 */
    size_t len[4] = {12 * nv, 12 * (size_t)m->n_faces, n4 * jsize, n4 * wsize[weight_type]}, off[4], bl = 0;
    for (int i = 0; i < 4; i++) off[i] = bl, bl += len[i];
    unsigned char *bin = calloc(1, bl + 4);
    if (!bin) return -1;
    memcpy(bin + off[0], m->positions, len[0]);
    memcpy(bin + off[1], m->faces, len[1]);
    for (size_t i = 0; i < n4; i++) {
        if (joints_u8) bin[off[2] + i] = (unsigned char)joints[i];
        else memcpy(bin + off[2] + 2 * i, &joints[i], 2);
        float w = weights[i];
        if (weight_type == 0) {
            memcpy(bin + off[3] + 4 * i, &w, 4);
        } else if (weight_type == 1) {
            bin[off[3] + i] = (unsigned char)lrintf(w * 255.0f);
        } else {
            uint16_t q = (uint16_t)lrintf(w * 65535.0f);
            memcpy(bin + off[3] + 2 * i, &q, 2);
        }
    }

    float mn[3], mx[3];
    gltf_bounds(m, mn, mx);
    char *json = NULL;
    size_t jl = 0;
    FILE *f = open_memstream(&json, &jl);
    if (!f) {
        free(bin);
        return -1;
    }
    /* node 0 the skinned mesh; nodes 1..n_joints the joints, all children of
     * the first (a skin's joints need a common root) */
    fprintf(f, "{\"asset\":{\"version\":\"2.0\",\"generator\":\"mimic tests\"},\"scene\":0,"
               "\"scenes\":[{\"nodes\":[0,1]}],\"nodes\":[{\"name\":\"skinned\",\"mesh\":0,\"skin\":0}");
    for (uint32_t j = 0; j < n_joints; j++) {
        fprintf(f, ",{");
        if (joint_names && joint_names[j]) {
            fprintf(f, "\"name\":");
            json_string(f, joint_names[j]);
        }
        if (j == 0 && n_joints > 1) {
            fprintf(f, "%s\"children\":[", joint_names && joint_names[j] ? "," : "");
            for (uint32_t c = 2; c <= n_joints; c++) fprintf(f, "%s%u", c > 2 ? "," : "", c);
            fprintf(f, "]");
        }
        fprintf(f, "}");
    }
    fprintf(f, "],\"skins\":[{\"joints\":[");
    for (uint32_t j = 0; j < n_joints; j++) fprintf(f, "%s%u", j ? "," : "", j + 1);
    static const int wtype[3] = {5126, 5121, 5123};
    fprintf(f,
            "]}],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"JOINTS_0\":2,\"WEIGHTS_0\":3},"
            "\"indices\":1,\"mode\":4}]}],"
            "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\","
            "\"min\":[%.9g,%.9g,%.9g],\"max\":[%.9g,%.9g,%.9g]},"
            "{\"bufferView\":1,\"componentType\":5125,\"count\":%u,\"type\":\"SCALAR\"},"
            "{\"bufferView\":2,\"componentType\":%d,\"count\":%u,\"type\":\"VEC4\"},"
            "{\"bufferView\":3,\"componentType\":%d,%s\"count\":%u,\"type\":\"VEC4\"}],\"bufferViews\":[",
            m->n_vertices, (double)mn[0], (double)mn[1], (double)mn[2], (double)mx[0], (double)mx[1], (double)mx[2],
            3 * m->n_faces, joints_u8 ? 5121 : 5123, m->n_vertices, wtype[weight_type],
            weight_type ? "\"normalized\":true," : "", m->n_vertices);
    for (int i = 0; i < 4; i++)
        fprintf(f, "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":%d}", i ? "," : "", off[i], len[i],
                i == 1 ? 34963 : 34962);
    fprintf(f, "],\"buffers\":[{\"byteLength\":%zu}]}", bl);
    int rc = fclose(f);
    if (rc == 0) rc = write_glb_file(path, json, bin, bl);
    free(json);
    free(bin);
    return rc;
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
