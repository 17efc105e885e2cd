/* A re-triangulated synth body as a foreign avatar: foreign_avatar.h. */
#include "foreign_avatar.h"

#include "mim_io.h"
#include "mim_synth.h"
#include "retriangulate.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int fail(int rc, char *why, size_t why_size, const char *fmt, const char *detail)
{
    if (why && why_size)
        snprintf(why, why_size, fmt, detail);
    return rc;
}

void fa_free(fa_avatar_t *a)
{
    if (a)
        mim_mesh_free(&a->mesh);
}

int fa_make(const fa_options_t *opt, fa_avatar_t *out, char *why, size_t why_size)
{
    memset(out, 0, sizeof *out);
    mim_synth_options_t so = {.subjects = opt->subjects ? opt->subjects : opt->subject + 1,
                              .poses = opt->pose + 1,
                              .vertices = opt->vertices ? opt->vertices : 2000,
                              .seed = opt->seed ? opt->seed : 1};
    mim_synth_t *syn = NULL;
    mim_error_t err = {0};
    int rc = mim_synth_create(&syn, &so, &err);
    if (rc)
        return fail(rc, why, why_size, "synth: %s", mim_error_text(&err));
    const uint32_t nb = mim_synth_n_vertices(syn), fb = mim_synth_n_faces(syn);
    const uint32_t copies = opt->copies > 1 ? opt->copies : 1;
    mim_mesh_t cur = {0};
    rc = mim_mesh_alloc(&cur, copies * nb, copies * fb);
    if (!rc)
        rc = mim_synth_body(syn, opt->subject, opt->pose, cur.positions);
    mim_landmark_map_t map;
    mim_synth_landmarks(syn, &map);
    if (!rc) {
        const uint32_t *faces = mim_synth_faces(syn);
        for (uint32_t c = 0; c < copies; c++) {
            for (uint32_t v = 0; v < nb; v++) /* the copies side by side, 1 m apart: not joined */
                for (int a = 0; a < 3; a++)
                    cur.positions[3 * ((size_t)c * nb + v) + a] =
                        cur.positions[3 * (size_t)v + a] + (a == 0 ? 1.0f * (float)c : 0.0f);
            for (size_t k = 0; k < 3 * (size_t)fb; k++)
                cur.faces[3 * (size_t)c * fb + k] = faces[k] + c * nb;
        }
    }
    mim_synth_destroy(&syn);
    if (rc) {
        mim_mesh_free(&cur);
        return fail(rc, why, why_size, "synth body: %s", "cannot make it");
    }
    out->body_vertices = nb;
    out->n_landmarks = map.count;
    for (uint32_t i = 0; i < map.count; i++) {
        memcpy(out->landmarks + 3 * i, cur.positions + 3 * (size_t)map.vertex[i], 3 * sizeof(float));
        out->landmark_vertex[i] = map.vertex[i]; /* subdivision keeps the original vertices' indices */
        snprintf(out->names[i], sizeof out->names[i], "%s", map.names[i]);
    }
    for (uint32_t s = 0; s < opt->subdivisions; s++) {
        mim_mesh_t next;
        if ((rc = rt_subdivide(&cur, &next))) {
            mim_mesh_free(&cur);
            return fail(rc, why, why_size, "%s", "rt_subdivide failed");
        }
        mim_mesh_free(&cur);
        cur = next;
    }
    if (opt->shuffle_seed) {
        mim_mesh_t next;
        uint32_t *new_of_old = malloc((size_t)cur.n_vertices * sizeof *new_of_old);
        rc = new_of_old ? rt_shuffle(&cur, opt->shuffle_seed, &next, new_of_old) : MIM_ENOMEM;
        if (!rc) {
            for (uint32_t i = 0; i < out->n_landmarks; i++)
                out->landmark_vertex[i] = new_of_old[out->landmark_vertex[i]];
            mim_mesh_free(&cur);
            cur = next;
        }
        free(new_of_old);
        if (rc) {
            mim_mesh_free(&cur);
            return fail(rc, why, why_size, "%s", "rt_shuffle failed");
        }
    }
    out->mesh = cur;
    return 0;
}

int fa_write(const fa_avatar_t *a, const char *path, const char *sidecar_path, int null_at, char *why,
             size_t why_size)
{
    mim_error_t err = {0};
    int rc = mim_io_write_mesh(path, &a->mesh, &err);
    if (rc)
        return fail(rc, why, why_size, "%s", mim_error_text(&err));
    if (!sidecar_path)
        return 0;
    FILE *f = fopen(sidecar_path, "w");
    if (!f)
        return fail(MIM_EIO, why, why_size, "cannot write %s", sidecar_path);
    fprintf(f, "{\"landmarks\": [");
    for (uint32_t i = 0; i < a->n_landmarks; i++) {
        const float *p = a->landmarks + 3 * i;
        if ((int)i == null_at)
            fprintf(f, "%snull", i ? ", " : "");
        else
            fprintf(f, "%s[%.9g, %.9g, %.9g]", i ? ", " : "", (double)p[0], (double)p[1], (double)p[2]);
    }
    fprintf(f, "]}\n");
    return fclose(f) ? fail(MIM_EIO, why, why_size, "cannot write %s", sidecar_path) : 0;
}
