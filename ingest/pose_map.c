/* Pose maps (mimic index --pose-map): which poses of different datasets
 * are one pose class. A CSV whose header names dataset, pose and class;
 * each row puts that dataset's pose into that class. Unmapped poses stay
 * their dataset's own (mim_db_labels_qualify). */
#include "mim_ingest.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    char *dataset, *pose, *cls;
    size_t line;
} pose_entry_t;

struct mim_pose_map {
    pose_entry_t *e;
    size_t n, cap;
    const char *path;
};

static pose_entry_t *find(const mim_pose_map_t *m, const char *dataset, const char *pose)
{
    for (size_t i = 0; i < m->n; i++)
        if (!strcmp(m->e[i].dataset, dataset) && !strcmp(m->e[i].pose, pose)) return &m->e[i];
    return NULL;
}

static int pose_row(void *ctx, const char *const *f, size_t lineno, mim_error_t *err)
{
    mim_pose_map_t *m = ctx;
    if (!mim_ingest_dataset_valid(f[0]))
        return mim_error_set(err, MIM_EFORMAT, "%s:%zu: '%s' is not a dataset name (letters, digits, '.', '_', '-')",
                             m->path, lineno, f[0]);
    if (!f[1][0] || !f[2][0])
        return mim_error_set(err, MIM_EFORMAT, "%s:%zu: the pose and the class must not be empty", m->path, lineno);
    const pose_entry_t *was = find(m, f[0], f[1]);
    if (was && strcmp(was->cls, f[2]))
        return mim_error_set(err, MIM_EFORMAT, "%s:%zu: %s pose %s is class %s on line %zu and %s here", m->path,
                             lineno, f[0], f[1], was->cls, was->line, f[2]);
    if (was) return 0;
    if (m->n == m->cap) {
        size_t cap = m->cap ? 2 * m->cap : 64;
        pose_entry_t *ne = realloc(m->e, cap * sizeof *ne);
        if (!ne) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", m->path);
        m->e = ne, m->cap = cap;
    }
    pose_entry_t *e = &m->e[m->n];
    e->dataset = strdup(f[0]), e->pose = strdup(f[1]), e->cls = strdup(f[2]), e->line = lineno;
    m->n++;
    if (!e->dataset || !e->pose || !e->cls) return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", m->path);
    return 0;
}

int mim_pose_map_load(mim_pose_map_t **out, const char *path, mim_error_t *err)
{
    *out = NULL;
    mim_pose_map_t *m = calloc(1, sizeof *m);
    if (!m) return mim_error_set(err, MIM_ENOMEM, "out of memory");
    m->path = path;
    static const char *const columns[] = {"dataset", "pose", "class"};
    int rc = mim_csv_read(path, "pose map", columns, 3, pose_row, m, err);
    if (rc) {
        mim_pose_map_free(&m);
        return rc;
    }
    m->path = NULL; /* the caller's string need not outlive the load */
    *out = m;
    return 0;
}

void mim_pose_map_free(mim_pose_map_t **pm)
{
    mim_pose_map_t *m = pm ? *pm : NULL;
    if (!m) return;
    for (size_t i = 0; i < m->n; i++) free(m->e[i].dataset), free(m->e[i].pose), free(m->e[i].cls);
    free(m->e);
    free(m);
    *pm = NULL;
}

size_t mim_pose_map_size(const mim_pose_map_t *m)
{
    return m ? m->n : 0;
}

const char *mim_pose_map_class(const mim_pose_map_t *m, const char *dataset, const char *pose)
{
    if (!m || !dataset || !pose) return NULL;
    const pose_entry_t *e = find(m, dataset, pose);
    return e ? e->cls : NULL;
}
