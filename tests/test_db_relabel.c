/* db/: mim_db_template_relabel gives a template another pose label and
 * keeps everything else (positions, content hash, source, subject,
 * dataset, the hash index: a put of the same positions still finds it),
 * and the store checks clean afterwards; no such id, a read transaction
 * and an aborted relabel change nothing. */
#include "mim_db.h"
#include "test_support.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char *dir;

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("relabel");
    return dir ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir);
    return 0;
}

enum { N = 500 };

static void positions(float *p, float seed)
{
    for (uint32_t i = 0; i < 3 * N; i++) p[i] = seed + 0.001f * (float)i;
}

static void say(void *ctx, const mim_db_problem_t *p)
{
    (void)ctx;
    print_message("problem: %s\n", p->message);
}

static void test_relabel(void **s)
{
    (void)s;
    char *store = ts_path(dir, "store");
    mim_db_t *db;
    mim_error_t err = {0};
    assert_int_equal(mim_db_open(&db, store, NULL, &err), 0);
    mim_db_txn_t *t;
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    uint32_t faces[] = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
    assert_int_equal(mim_db_topology_put(t, faces, 4, N, &err), 0);
    uint32_t lv[16];
    for (int i = 0; i < 16; i++) lv[i] = (uint32_t)i;
    mim_landmark_map_t lm;
    mim_landmarks_default(&lm, lv, N);
    assert_int_equal(mim_db_landmarks_put(t, &lm, &err), 0);
    static float p[2][3 * N];
    uint64_t ids[2];
    for (int i = 0; i < 2; i++) {
        positions(p[i], (float)i);
        mim_template_in_t in = {p[i], N, mim_db_content_hash(p[i], N), "/data/x.ply", "anna", "sit", "mh"};
        assert_int_equal(mim_db_template_put(t, &in, &ids[i], NULL, &err), 0);
    }
    assert_int_equal(mim_db_commit(&t, &err), 0);

    /* relabelled: the pose only */
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_template_relabel(t, ids[0], "wave", &err), 0);
    assert_int_equal(mim_db_template_relabel(t, 99, "wave", &err), MIM_ENOTFOUND);
    assert_non_null(strstr(err.msg, "template 99: not in the store"));
    assert_int_equal(mim_db_commit(&t, &err), 0);
    assert_int_equal(mim_db_begin(db, 0, &t, &err), 0);
    mim_template_view_t v;
    assert_int_equal(mim_db_template_get(t, ids[0], &v, &err), 0);
    assert_string_equal(v.pose, "wave");
    assert_string_equal(v.subject, "anna");
    assert_string_equal(v.source, "/data/x.ply");
    assert_string_equal(v.dataset, "mh");
    assert_int_equal(v.n_vertices, N);
    assert_memory_equal(v.positions, p[0], sizeof p[0]);
    assert_true(v.content_hash == mim_db_content_hash(p[0], N));
    assert_int_equal(mim_db_template_get(t, ids[1], &v, &err), 0);
    assert_string_equal(v.pose, "sit"); /* the other untouched */
    /* a read transaction cannot relabel */
    mim_error_clear(&err);
    assert_int_equal(mim_db_template_relabel(t, ids[1], "wave", &err), MIM_EINVAL);
    assert_non_null(strstr(err.msg, "needs a write transaction"));
    mim_db_abort(&t);

    /* an aborted relabel leaves the label; to none and back */
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_template_relabel(t, ids[1], "run", &err), 0);
    mim_db_abort(&t);
    assert_int_equal(mim_db_begin(db, 1, &t, &err), 0);
    assert_int_equal(mim_db_template_get(t, ids[1], &v, &err), 0);
    assert_string_equal(v.pose, "sit");
    assert_int_equal(mim_db_template_relabel(t, ids[1], NULL, &err), 0);
    assert_int_equal(mim_db_template_get(t, ids[1], &v, &err), 0);
    assert_string_equal(v.pose, "");
    /* the hash index still finds the relabelled content: no second copy */
    mim_template_in_t again = {p[0], N, mim_db_content_hash(p[0], N), "/other.ply", "bob", "x", NULL};
    uint64_t id;
    int existed = 0;
    assert_int_equal(mim_db_template_put(t, &again, &id, &existed, &err), 0);
    assert_int_equal(existed, 1);
    assert_int_equal(id, ids[0]);
    assert_int_equal(mim_db_commit(&t, &err), 0);

    mim_db_check_report_t rep;
    mim_db_check_options_t co = {.problem = say};
    assert_int_equal(mim_db_check(db, &co, &rep, &err), 0);
    assert_int_equal(rep.problems, 0);
    assert_int_equal(rep.templates, 2);
    mim_db_close(&db);
    free(store);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_relabel)};
    return cmocka_run_group_tests(tests, setup, teardown);
}
