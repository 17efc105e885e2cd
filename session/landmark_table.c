/* Every template's landmarks, subjects, poses and ids, read from the store
 * once per store (a fork uses its base's): completion (complete.c) scans
 * them, relative transfer (relative.c) finds its references in them and
 * asks whether the store's subjects take a pose alike. */
#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    mim_session_t *s;
    mim_error_t *err;
    char **datasets; /* each template's, to qualify the subjects as the index does */
    uint32_t cap;
} table_fill_t;

static int table_add(const mim_template_view_t *v, void *user)
{
    table_fill_t *f = user;
    mim_session_t *s = f->s;
    const uint32_t L = s->map.count;
    if (v->n_vertices != s->mesh.n_vertices) return 0; /* not the store's connectivity: not a body to compare */
    if (s->table_count == s->table_cap) {
        uint32_t cap = s->table_cap ? 2 * s->table_cap : 256;
        float *lm = realloc(s->table_lm, (size_t)cap * L * 3 * sizeof *lm);
        if (lm) s->table_lm = lm;
        char **sub = realloc(s->table_subject, cap * sizeof *sub);
        if (sub) s->table_subject = sub;
        char **pose = realloc(s->table_pose, cap * sizeof *pose);
        if (pose) s->table_pose = pose;
        uint64_t *id = realloc(s->table_id, cap * sizeof *id);
        if (id) s->table_id = id;
        if (!lm || !sub || !pose || !id) return mim_error_set(f->err, MIM_ENOMEM, "completion: out of memory");
        s->table_cap = cap;
    }
    for (uint32_t l = 0; l < L; l++)
        memcpy(s->table_lm + ((size_t)s->table_count * L + l) * 3, v->positions + 3 * (size_t)s->map.vertex[l],
               3 * sizeof(float));
    if (f->cap < s->table_cap) {
        char **d = realloc(f->datasets, s->table_cap * sizeof *d);
        if (!d) return mim_error_set(f->err, MIM_ENOMEM, "completion: out of memory");
        f->datasets = d, f->cap = s->table_cap;
    }
    if (!(f->datasets[s->table_count] = strdup(v->dataset)))
        return mim_error_set(f->err, MIM_ENOMEM, "completion: out of memory");
    s->table_subject[s->table_count] = strdup(v->subject);
    s->table_pose[s->table_count] = strdup(v->pose);
    if (!s->table_subject[s->table_count] || !s->table_pose[s->table_count]) {
        free(f->datasets[s->table_count]), free(s->table_subject[s->table_count]), free(s->table_pose[s->table_count]);
        return mim_error_set(f->err, MIM_ENOMEM, "completion: out of memory");
    }
    s->table_id[s->table_count] = v->id;
    s->table_count++;
    return 0;
}

int mim__session_landmark_table(mim_session_t *s, const float **lm, char *const **subjects, const uint64_t **ids,
                                uint32_t *count, mim_error_t *err)
{
    if (s->base) /* one table for every session of a store */
        s = s->base;
    pthread_mutex_lock(&s->table_lock);
    int rc = 0;
    if (s->table_failed.code) {
        /* a store that failed once is not read again on every frame */
        rc = mim_error_set(err, s->table_failed.code, "%s", s->table_failed.msg);
    } else if (!s->table_built) {
        mim_db_txn_t *t = NULL;
        table_fill_t f = {s, &s->table_failed, NULL, 0};
        if (!(rc = mim_db_begin(s->db, 0, &t, &s->table_failed)))
            rc = mim_db_template_each(t, table_add, &f, &s->table_failed);
        mim_db_abort(&t);
        /* subjects as the index names them: a dataset's own where there are several */
        if (!rc && (mim_db_labels_qualify(s->table_count, (const char *const *)f.datasets, s->table_subject, NULL) ||
                    mim_db_labels_qualify(s->table_count, (const char *const *)f.datasets, s->table_pose, NULL)))
            rc = mim_error_set(&s->table_failed, MIM_ENOMEM, "completion: out of memory");
        for (uint32_t i = 0; i < s->table_count; i++) free(f.datasets[i]);
        free(f.datasets);
        s->table_built = !rc;
        if (rc) {
            if (!s->table_failed.code) mim_error_set(&s->table_failed, rc, "completion: %s", mim_strerror(rc));
            rc = mim_error_set(err, rc, "%s", s->table_failed.msg);
            for (uint32_t i = 0; i < s->table_count; i++) free(s->table_subject[i]), free(s->table_pose[i]);
            s->table_count = 0;
        }
    }
    *lm = s->table_lm, *subjects = s->table_subject, *count = s->table_count;
    if (ids) *ids = s->table_id;
    pthread_mutex_unlock(&s->table_lock);
    return rc;
}

double mim__session_store_spread(mim_session_t *s)
{
    const float *lm;
    char *const *subjects;
    uint32_t count;
    mim_error_t err = {0};
    if (mim__session_landmark_table(s, &lm, &subjects, NULL, &count, &err))
        return NAN; /* unread: the references' gate alone decides (and cannot find any) */
    if (s->base)
        s = s->base;
    pthread_mutex_lock(&s->table_lock);
    if (!s->spread_known) {
        s->pose_spread = mim_session_pose_spread(s->table_count, s->map.count, s->table_lm,
                                                 (const char *const *)s->table_subject,
                                                 (const char *const *)s->table_pose);
        s->spread_known = 1;
    }
    const double spread = s->pose_spread;
    pthread_mutex_unlock(&s->table_lock);
    return spread;
}
