/* libFuzzer harness: mim_io_read_mesh on arbitrary bytes. The first byte picks
 * the file extension, the rest is the file. Every input must give either a
 * mesh whose face indices are all in range and coordinates finite, or an
 * error with a message; never a crash, leak or sanitizer report. The same
 * for mim_io_read_skin (a glTF's JOINTS_0/WEIGHTS_0) and mim_io_read_scene
 * (a glTF scene's parts tile its vertices and faces, each face in its part;
 * the seed glb_rigged_scene is a rigged two-mesh VRM 0 scene in centimetres
 * with a prop under a bone). */
#include "mim_io.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const ext[] = {"off", "ply", "obj", "stl", "gltf", "glb"};
    if (size < 1) return 0;
    char path[128];
    snprintf(path, sizeof path, "/tmp/mimic-fuzz-%d.%s", (int)getpid(), ext[data[0] % 6]);
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    fwrite(data + 1, 1, size - 1, f);
    fclose(f);
    mim_mesh_t m;
    mim_error_t err = {0};
    int rc = mim_io_read_mesh(path, &m, &err);
    if (rc == 0) {
        for (uint32_t i = 0; i < 3 * m.n_faces; i++)
            if (m.faces[i] >= m.n_vertices) abort();
        for (uint32_t i = 0; i < 3 * m.n_vertices; i++)
            if (!isfinite(m.positions[i])) abort();
        mim_mesh_free(&m);
    } else if (!err.msg[0] && rc != MIM_ENOMEM) {
        abort(); /* every rejection explains itself */
    }
    /* the skin of the same bytes (glTF/GLB): joints in range, weights finite */
    mim_io_skin_t sk;
    mim_error_t serr = {0};
    rc = mim_io_read_skin(path, &sk, &serr);
    if (rc == 0) {
        for (size_t i = 0; i < 4 * (size_t)sk.n_vertices; i++)
            if (sk.joints[i] >= sk.n_joints || !(sk.weights[i] >= 0 && sk.weights[i] <= 1)) abort();
        mim_io_skin_free(&sk);
    } else if (!serr.msg[0] && rc != MIM_ENOMEM) {
        abort();
    }
    mim_io_scene_t sc;
    mim_error_t cerr = {0};
    rc = mim_io_read_scene(path, NULL, &sc, &cerr);
    if (rc == 0) {
        uint32_t v = 0, fc = 0;
        for (uint32_t k = 0; k < sc.n_parts; k++) {
            const mim_io_part_t *p = sc.parts + k;
            if (p->first_vertex != v || p->first_face != fc) abort();
            for (uint32_t t = 3 * p->first_face; t < 3 * (p->first_face + p->n_faces); t++)
                if (sc.mesh.faces[t] < p->first_vertex || sc.mesh.faces[t] >= p->first_vertex + p->n_vertices) abort();
            v += p->n_vertices, fc += p->n_faces;
        }
        if (v != sc.mesh.n_vertices || fc != sc.mesh.n_faces) abort();
        if (sc.skin_rc == 0)
            for (size_t i = 0; i < 3 * (size_t)sc.skin.n_joints; i++)
                if (isnan(sc.skin.joint_positions[i])) abort();
        mim_io_scene_free(&sc);
    } else if (!cerr.msg[0] && rc != MIM_ENOMEM) {
        abort();
    }
    remove(path);
    return 0;
}
