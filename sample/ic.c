/* Interaction coordinates (seed 002, Section 4.3): the Delaunay edges of a
 * pose-pair's 34 joints: delaunay.c's where it proves its answer (most
 * pose-pairs in 3D), else qhull's (reentrant library). The IC vectors
 * themselves (u_ij = J_j - J_i) are taken from the joints when compared
 * (distance.c). */
#include "internal.h"

#include <libqhull_r/qhull_ra.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *const mim_sample_joint_names[MIM_PAIR_PERSON_JOINTS] = {
    "head",    "chest", "pelvis", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
    "l_hip",   "r_hip", "l_knee", "r_knee",     "l_ankle",    "r_ankle", "spine",   "neck"};

int mim_sample_joint_index(const char *name)
{
    for (int j = 0; name && j < MIM_PAIR_PERSON_JOINTS; j++)
        if (!strcmp(mim_sample_joint_names[j], name)) return j;
    return -1;
}

/* Joints closer than this (metres, or the 2D units) count as one point. */
#define SAME_POINT 1e-9

static void add_edge(uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS], uint32_t a, uint32_t b)
{
    if (a == b) return;
    if (a > b) {
        uint32_t t = a;
        a = b, b = t;
    }
    have[a][b] = 1;
}

/* The edges found among the distinct joints, a merged joint taking its
 * first's edges and one to it, sorted into out. */
static int edges_out(uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS], const uint32_t *rep, mim_ic_t *out)
{
    for (uint32_t i = 0; i < MIM_PAIR_JOINTS; i++) {
        if (rep[i] == i) continue;
        add_edge(have, i, rep[i]);
        for (uint32_t j = 0; j < MIM_PAIR_JOINTS; j++)
            if (j != i && (have[rep[i] < j ? rep[i] : j][rep[i] < j ? j : rep[i]])) add_edge(have, i, j);
    }
    for (uint32_t a = 0; a < MIM_PAIR_JOINTS; a++)
        for (uint32_t b = a + 1; b < MIM_PAIR_JOINTS; b++)
            if (have[a][b]) out->edge[out->n_edges][0] = (uint8_t)a, out->edge[out->n_edges][1] = (uint8_t)b, out->n_edges++;
    return 0;
}

int mim__joints_finite(const double *joints, int dim, mim_error_t *err)
{
    for (uint32_t i = 0; i < (uint32_t)dim * MIM_PAIR_JOINTS; i++)
        if (!isfinite(joints[i]))
            return mim_error_set(err, MIM_ENONFINITE, "interaction coordinates: joint %u (%s of person %c) is not finite",
                                 i / dim, mim_sample_joint_names[(i / dim) % MIM_PAIR_PERSON_JOINTS],
                                 i / dim < MIM_PAIR_PERSON_JOINTS ? 'A' : 'B');
    return 0;
}

/* qhull's answer, or first delaunay.c's where it proves its own (fast). */
static int build(const double *joints, int dim, int fast, mim_ic_t *out, mim_error_t *err)
{
    if (!joints || !out || (dim != 2 && dim != 3))
        return mim_error_set(err, MIM_EINVAL, "interaction coordinates: dimension %d (2 or 3)", dim);
    memset(out, 0, sizeof *out);
    out->dim = dim;
    int rc = mim__joints_finite(joints, dim, err);
    if (rc) return rc;
    /* distinct points: rep[i] is the first joint at joint i's place */
    uint32_t rep[MIM_PAIR_JOINTS], uniq[MIM_PAIR_JOINTS], n_uniq = 0;
    for (uint32_t i = 0; i < MIM_PAIR_JOINTS; i++) {
        rep[i] = i;
        for (uint32_t j = 0; j < i && rep[i] == i; j++) {
            double d2 = 0;
            for (int c = 0; c < dim; c++) d2 += (joints[dim * i + c] - joints[dim * j + c]) * (joints[dim * i + c] - joints[dim * j + c]);
            if (d2 <= SAME_POINT * SAME_POINT) rep[i] = rep[j];
        }
        if (rep[i] == i) uniq[n_uniq++] = i;
    }
    if (n_uniq < (uint32_t)dim + 1)
        return mim_error_set(err, MIM_EFORMAT, "interaction coordinates: only %u distinct joints", n_uniq);
    coordT pts[3 * MIM_PAIR_JOINTS];
    for (uint32_t k = 0; k < n_uniq; k++)
        for (int c = 0; c < dim; c++) pts[dim * k + c] = joints[dim * uniq[k] + c];
    uint8_t have[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS];
    memset(have, 0, sizeof have);
    if (fast && dim == 3) {
        uint8_t found[MIM_PAIR_JOINTS][MIM_PAIR_JOINTS] = {{0}};
        if (!mim__delaunay3_edges(pts, n_uniq, found)) {
            for (uint32_t a = 0; a < n_uniq; a++)
                for (uint32_t b = a + 1; b < n_uniq; b++)
                    if (found[a][b]) add_edge(have, uniq[a], uniq[b]);
            return edges_out(have, rep, out);
        }
    }

    /* qhull reports into a FILE: a memory stream, so that nothing reaches
     * stderr and its reason can go into the message */
    char *msg = NULL;
    size_t msg_len = 0;
    FILE *errf = open_memstream(&msg, &msg_len);
    if (!errf) return mim_error_set(err, MIM_ENOMEM, "interaction coordinates: out of memory");
    qhT qh_qh, *qh = &qh_qh;
    qh_zero(qh, errf);
    char flags[] = "qhull d Qt Qbb Qz";
    int exit_code = qh_new_qhull(qh, dim, (int)n_uniq, pts, False, flags, NULL, errf);
    if (exit_code && dim == 3) {
        /* Flat input (two people in one plane, a T-pose seen from the
         * front): joggle it (QJ). qhull's generator is its own (qh_rand,
         * state in qh), so this stays deterministic and global state
         * untouched; the edges found join joints that are neighbours in
         * the plane. */
        qh_freeqhull(qh, !qh_ALL);
        int cl, tl;
        qh_memfreeshort(qh, &cl, &tl);
        qh_zero(qh, errf);
        char joggle[] = "qhull d Qbb QJ";
        exit_code = qh_new_qhull(qh, dim, (int)n_uniq, pts, False, joggle, NULL, errf);
    }
    if (!exit_code) {
        facetT *facet;
        vertexT *vertex, **vertexp;
        FORALLfacets {
            if (facet->upperdelaunay) continue;
            uint32_t ids[4], nv = 0;
            FOREACHvertex_(facet->vertices) {
                int id = qh_pointid(qh, vertex->point);
                if (id >= 0 && id < (int)n_uniq && nv < 4) ids[nv++] = uniq[id];
            }
            for (uint32_t a = 0; a < nv; a++)
                for (uint32_t b = a + 1; b < nv; b++) add_edge(have, ids[a], ids[b]);
        }
    }
    qh_freeqhull(qh, !qh_ALL);
    int curlong, totlong;
    qh_memfreeshort(qh, &curlong, &totlong);
    fclose(errf);
    if (exit_code) {
        /* the first line of qhull's report */
        char *line = msg ? msg : "";
        while (*line == '\n' || *line == ' ') line++;
        char *end = strchr(line, '\n');
        int rc = mim_error_set(err, MIM_EFORMAT, "interaction coordinates: the joints span no %s (qhull: %.*s)",
                               dim == 2 ? "triangle" : "tetrahedron", end ? (int)(end - line) : (int)strlen(line), line);
        free(msg);
        return rc;
    }
    free(msg);
    return edges_out(have, rep, out);
}

int mim_ic_build(const double *joints, int dim, mim_ic_t *out, mim_error_t *err) { return build(joints, dim, 1, out, err); }

int mim__ic_build_qhull(const double *joints, int dim, mim_ic_t *out, mim_error_t *err)
{
    return build(joints, dim, 0, out, err);
}
