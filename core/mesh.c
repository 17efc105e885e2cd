/* The mesh arrays type: allocation and release. */
#include "mim_core.h"

#include <stdlib.h>
#include <string.h>

int mim_mesh_alloc(mim_mesh_t *m, uint32_t n_vertices, uint32_t n_faces)
{
    if (!m) return MIM_EINVAL;
    memset(m, 0, sizeof *m);
    m->positions = malloc(sizeof(float) * 3 * (size_t)(n_vertices ? n_vertices : 1));
    m->faces = malloc(sizeof(uint32_t) * 3 * (size_t)(n_faces ? n_faces : 1));
    if (!m->positions || !m->faces) {
        mim_mesh_free(m);
        return MIM_ENOMEM;
    }
    m->n_vertices = n_vertices;
    m->n_faces = n_faces;
    return 0;
}

void mim_mesh_free(mim_mesh_t *m)
{
    if (!m) return;
    free(m->positions);
    free(m->faces);
    memset(m, 0, sizeof *m);
}
