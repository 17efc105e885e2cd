/* The sampled-templates tests' fixture (pairs_support.h). */
#include "pairs_support.h"

#include "mim_io.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int tp_joint(const char *name)
{
    const int j = mim_sample_joint_index(name);
    if (j < 0) fail_msg("no joint %s", name);
    return j;
}

void tp_turn(double p[TP_J][3], const char *about, char axis, double a, const char *const *names)
{
    const double *c0 = p[tp_joint(about)];
    const double c[3] = {c0[0], c0[1], c0[2]}, ca = cos(a), sa = sin(a);
    for (; *names; names++) {
        double *q = p[tp_joint(*names)], x = q[0] - c[0], y = q[1] - c[1], z = q[2] - c[2], u, v;
        if (axis == 'x') u = y * ca - z * sa, v = y * sa + z * ca, y = u, z = v;
        else if (axis == 'y') u = x * ca + z * sa, v = -x * sa + z * ca, x = u, z = v;
        else u = x * ca - y * sa, v = x * sa + y * ca, x = u, y = v;
        q[0] = c[0] + x, q[1] = c[1] + y, q[2] = c[2] + z;
    }
}

void tp_place(double p[TP_J][3], double a, double dx, double dz)
{
    for (int j = 0; j < TP_J; j++) {
        double x = p[j][0], z = p[j][2];
        p[j][0] = cos(a) * x + sin(a) * z + dx;
        p[j][2] = -sin(a) * x + cos(a) * z + dz;
    }
}

void tp_landmarks_of(const mim_landmark_map_t *map, double p[TP_J][3], float *out)
{
    for (uint32_t l = 0; l < map->count; l++)
        for (int c = 0; c < 3; c++) out[3 * l + c] = (float)p[tp_joint(map->names[l])][c];
}

int tp_synth_store(const char *dir, char **bodies, char **store, mim_landmark_map_t *map, double rest[TP_J][3])
{
    *bodies = ts_path(dir, "bodies");
    *store = ts_path(dir, "store");
    const char *synth[] = {"synth", "--out", *bodies, "--subjects", "3", "--poses", "4", "--vertices", "1500", NULL};
    const char *ingest[] = {"ingest", "--store", *store, *bodies, NULL};
    const char *index[] = {"index", "--store", *store, NULL};
    int rc = ts_run_mimic(NULL, NULL, synth);
    if (!rc) rc = ts_run_mimic(NULL, NULL, ingest);
    if (!rc) rc = ts_run_mimic(NULL, NULL, index);
    char *lm = ts_path(*bodies, "landmarks.json"), *ply = ts_path(*bodies, "synth_s00_p00.ply");
    mim_mesh_t m = {0};
    if (!rc) rc = mim_landmarks_read(map, lm, NULL);
    if (!rc) rc = mim_io_read_mesh(ply, &m, NULL);
    if (!rc) {
        for (uint32_t l = 0; l < map->count; l++)
            for (int c = 0; c < 3; c++) rest[tp_joint(map->names[l])][c] = m.positions[3 * (size_t)map->vertex[l] + c];
        const int neck = tp_joint("neck"), head = tp_joint("head"), chest = tp_joint("chest");
        for (int c = 0; c < 3; c++) rest[neck][c] = 0.5 * (rest[head][c] + rest[chest][c]);
    }
    mim_mesh_free(&m);
    free(lm), free(ply);
    return rc;
}

char *tp_copy_store(const char *dir, const char *store, const char *name)
{
    char *to = ts_path(dir, name), *src = ts_path(store, "data.mdb"), *dst = ts_path(to, "data.mdb");
    char cmd[PATH_MAX + 16];
    snprintf(cmd, sizeof cmd, "mkdir -p '%s'", to);
    assert_int_equal(system(cmd), 0);
    size_t len = 0;
    char *bytes = ts_read_file(src, &len);
    assert_non_null(bytes);
    assert_int_equal(ts_write_file(dst, bytes, len), 0);
    free(bytes), free(src), free(dst);
    return to;
}

void tp_begin_read(const char *store, mim_db_t **db, mim_db_txn_t **t)
{
    mim_db_options_t o = {.read_only = 1};
    *db = NULL, *t = NULL;
    assert_int_equal(mim_db_open(db, store, &o, NULL), 0);
    assert_int_equal(mim_db_begin(*db, 0, t, NULL), 0);
}

void tp_template_encoded(mim_db_txn_t *t, uint64_t id, mim_template_view_t *v)
{
    mim_db_encoding_t e;
    assert_int_equal(mim_db_template_get(t, id, v, NULL), 0);
    assert_int_equal(mim_db_encoding_get(t, id, &e, NULL), 0);
    assert_int_equal(e.n_vertices, v->n_vertices);
}

void tp_make_people(double rest[TP_J][3], double people[TP_PEOPLE][TP_J][3])
{
    for (int k = 0; k < TP_PEOPLE; k++) memcpy(people[k], rest, sizeof(double) * 3 * TP_J);
    tp_turn(people[0], "l_shoulder", 'x', -1.4, (const char *[]){"l_elbow", "l_wrist", NULL});
    tp_turn(people[1], "r_hip", 'x', -1.2, (const char *[]){"r_knee", "r_ankle", NULL});
    tp_place(people[1], M_PI, 1.5, 0.3);
    tp_turn(people[2], "r_shoulder", 'x', -2.2, (const char *[]){"r_elbow", "r_wrist", NULL});
    tp_turn(people[2], "l_elbow", 'x', -1.5, (const char *[]){"l_wrist", NULL});
    tp_turn(people[3], "l_knee", 'x', 1.3, (const char *[]){"l_ankle", NULL});
    tp_turn(people[3], "l_shoulder", 'z', 2.0, (const char *[]){"l_elbow", "l_wrist", NULL});
    tp_place(people[3], M_PI / 2, -1.4, 0.2);
}
