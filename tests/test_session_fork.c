/* session/: forks (issue 16), the sessions of one process on one store:
 * each fork has its own avatar and factor, and shares the store, index,
 * connectivity and completion table with its base; forks transfer on
 * threads of their own at once and give what they give alone. */
#include "test_support.h"

#include "mim_session.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

static char *dir, *store;
static mim_session_t *base;

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("session-fork");
    char *bodies = ts_path(dir, "bodies");
    store = ts_path(dir, "store");
    const char *steps[][10] = {
        {"synth", "--out", bodies, "--subjects", "2", "--poses", "12", "--vertices", "1500", NULL},
        {"ingest", "--store", store, bodies, NULL},
        {"index", "--store", store, NULL},
    };
    int rc = 0;
    for (int i = 0; !rc && i < 3; i++) {
        char *o = NULL, *e = NULL;
        rc = ts_run_mimic(&o, &e, steps[i]);
        free(o), free(e);
    }
    free(bodies);
    mim_error_t err = {0};
    if (!rc) rc = mim_session_open(&base, store, NULL, &err);
    if (!rc) rc = mim_session_load_avatar(base, "1", &err);
    if (rc) fprintf(stderr, "setup: %s\n", mim_error_text(&err));
    return rc;
}

static int teardown(void **state)
{
    (void)state;
    mim_session_close(&base);
    ts_rmtree(dir);
    free(dir), free(store);
    return 0;
}

typedef struct job {
    mim_session_t *s;
    uint64_t template_id;
    float *out;
    int rc;
} job_t;

static void *transfer_job(void *arg)
{
    job_t *j = arg;
    mim_session_request_t req = {.template_id = j->template_id};
    mim_error_t err = {0};
    for (int i = 0; i < 5 && !j->rc; i++) /* several, so that the two threads overlap */
        j->rc = mim_session_transfer(j->s, &req, j->out, NULL, &err);
    return NULL;
}

static double max_diff(const float *a, const float *b, size_t n)
{
    double worst = 0.0;
    for (size_t i = 0; i < n; i++)
        worst = fmax(worst, fabs((double)a[i] - b[i]));
    return worst;
}

static void test_fork_shares_the_store(void **state)
{
    (void)state;
    mim_error_t err = {0};
    mim_session_t *f = NULL, *ff = NULL;
    assert_int_equal(mim_session_fork(&f, base, NULL, &err), 0);
    assert_false(mim_session_has_avatar(f));
    assert_ptr_equal(mim_session_query(f), mim_session_query(base));
    assert_ptr_equal(mim_session_topology(f), mim_session_topology(base));
    assert_string_equal(mim_session_store(f), mim_session_store(base));
    assert_int_equal(mim_session_load_avatar(f, "13", &err), 0); /* subject 2 at rest */
    assert_string_equal(mim_session_avatar(f), "template 13");
    assert_string_equal(mim_session_avatar(base), "template 1"); /* the base keeps its own */
    assert_int_not_equal(mim_session_load_avatar(f, "2", &err), 0); /* one avatar a session, as for any */
    assert_int_equal(mim_session_fork(&ff, f, NULL, &err), 0); /* of a fork: the same store */
    assert_ptr_equal(mim_session_query(ff), mim_session_query(base));
    assert_int_not_equal(mim_session_load_avatar(ff, "99999", &err), 0);
    mim_session_close(&ff);
    assert_null(ff);

    const uint32_t n = mim_session_mesh(base)->n_vertices;
    assert_int_equal(mim_session_mesh(f)->n_vertices, n);
    float *alone_b = malloc(3 * (size_t)n * sizeof(float)), *alone_f = malloc(3 * (size_t)n * sizeof(float));
    float *both_b = malloc(3 * (size_t)n * sizeof(float)), *both_f = malloc(3 * (size_t)n * sizeof(float));
    /* alone, one after the other */
    job_t jb = {base, 20, alone_b, 0}, jf = {f, 20, alone_f, 0};
    transfer_job(&jb), transfer_job(&jf);
    assert_int_equal(jb.rc, 0);
    assert_int_equal(jf.rc, 0);
    /* two bodies in one pose: the avatars differ, so do their poses */
    print_message("the two avatars in template 20's pose differ by up to %.1f mm\n",
                  1e3 * max_diff(alone_b, alone_f, 3 * (size_t)n));
    assert_true(max_diff(alone_b, alone_f, 3 * (size_t)n) > 1e-3);
    /* at once, on two threads */
    job_t tb = {base, 20, both_b, 0}, tf = {f, 20, both_f, 0};
    pthread_t t1, t2;
    assert_int_equal(pthread_create(&t1, NULL, transfer_job, &tb), 0);
    assert_int_equal(pthread_create(&t2, NULL, transfer_job, &tf), 0);
    pthread_join(t1, NULL), pthread_join(t2, NULL);
    assert_int_equal(tb.rc, 0);
    assert_int_equal(tf.rc, 0);
    assert_true(max_diff(alone_b, both_b, 3 * (size_t)n) < 1e-6);
    assert_true(max_diff(alone_f, both_f, 3 * (size_t)n) < 1e-6);

    /* completion reads the base's table */
    const mim_landmark_map_t *map = mim_session_map(f);
    float lm[3 * MIM_LANDMARKS_MAX], out[3 * MIM_LANDMARKS_MAX];
    uint8_t present[MIM_LANDMARKS_MAX], done[MIM_LANDMARKS_MAX];
    assert_int_equal(mim_session_template(f, 20, alone_b, NULL, NULL, 0, &err), 0);
    for (uint32_t l = 0; l < map->count; l++) {
        memcpy(lm + 3 * l, alone_b + 3 * (size_t)map->vertex[l], 3 * sizeof(float));
        present[l] = l != 0;
    }
    assert_int_equal(mim_session_complete(f, lm, present, NULL, out, done, &err), 0);
    assert_int_equal(done[0], 1);
    mim_session_close(&f);
    free(alone_b), free(alone_f), free(both_b), free(both_f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fork_shares_the_store),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
