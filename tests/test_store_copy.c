/* mimic store copy (issue 16): a compacted snapshot of a store, also while
 * another process writes to it, made whole or not at all. */
#include "test_support.h"

#include <dirent.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

static char *dir, *bodies, *more, *store;

static int run(const char *const *args, char **out, char **err)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (out) *out = o; else free(o);
    if (err) *err = e; else free(e);
    return rc;
}

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("store-copy");
    bodies = ts_path(dir, "bodies"), more = ts_path(dir, "more"), store = ts_path(dir, "store");
    const char *s1[] = {"synth", "--out", bodies, "--subjects", "3", "--poses", "4", "--vertices", "1500", NULL};
    const char *s2[] = {"synth", "--out", more, "--subjects", "4", "--poses", "6", "--vertices", "1500", "--seed", "9", NULL};
    const char *ingest[] = {"ingest", "--store", store, bodies, NULL};
    const char *index[] = {"index", "--store", store, NULL};
    return run(s1, NULL, NULL) || run(s2, NULL, NULL) || run(ingest, NULL, NULL) || run(index, NULL, NULL);
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir), free(bodies), free(more), free(store);
    return 0;
}

static json_t *json_of(const char *text)
{
    json_error_t je;
    json_t *j = json_loads(text, 0, &je);
    if (!j) fail_msg("not JSON: %s", text);
    return j;
}

/* store check on a copy: clean; its template count */
static json_int_t checked(const char *path)
{
    char *o;
    const char *check[] = {"store", "check", path, "--json", NULL};
    assert_int_equal(run(check, &o, NULL), 0);
    json_t *j = json_of(o);
    assert_true(json_is_true(json_object_get(j, "clean")));
    json_int_t n = json_integer_value(json_object_get(json_object_get(j, "checked"), "templates"));
    json_decref(j);
    free(o);
    return n;
}

/* no temporary directory of a copy is left in dir */
static void no_leftovers(void)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    while ((e = readdir(d)))
        if (strstr(e->d_name, ".copy-")) fail_msg("left behind: %s", e->d_name);
    closedir(d);
}

static void test_copy(void **state)
{
    (void)state;
    char *dst = ts_path(dir, "copy"), *o, *e;
    const char *cp[] = {"store", "copy", store, dst, "--json", NULL};
    assert_int_equal(run(cp, &o, NULL), 0);
    json_t *j = json_of(o);
    assert_int_equal(json_integer_value(json_object_get(j, "templates")), 12);
    assert_true(json_integer_value(json_object_get(j, "bytes")) <= json_integer_value(json_object_get(j, "source_bytes")));
    json_decref(j);
    free(o);
    assert_int_equal(checked(dst), 12);
    /* the same templates */
    const char *l1[] = {"list", "--store", store, "--json", NULL}, *l2[] = {"list", "--store", dst, "--json", NULL};
    char *a, *b;
    assert_int_equal(run(l1, &a, NULL), 0);
    assert_int_equal(run(l2, &b, NULL), 0);
    assert_string_equal(a, b);
    free(a), free(b);
    /* bad use: one line each, nothing written */
    assert_int_equal(run(cp, NULL, &e), 1);
    assert_non_null(strstr(e, "exists: a copy goes to a new directory"));
    free(e);
    char *none = ts_path(dir, "no-such-store"), *dst2 = ts_path(dir, "copy2");
    const char *missing[] = {"store", "copy", none, dst2, NULL};
    assert_int_equal(run(missing, NULL, &e), 2);
    assert_non_null(strstr(e, "no-such-store"));
    free(e);
    const char *one[] = {"store", "copy", store, NULL};
    assert_int_equal(run(one, NULL, &e), 2);
    assert_non_null(strstr(e, "give SRC and DST"));
    free(e);
    char *deep = ts_path(dir, "no/such/folder/copy");
    const char *nodir[] = {"store", "copy", store, deep, NULL};
    assert_int_equal(run(nodir, NULL, &e), 1);
    assert_non_null(strstr(e, "cannot make the copy's directory"));
    free(e);
    assert_true(access(dst2, F_OK) != 0);
    no_leftovers();
    free(dst), free(none), free(dst2), free(deep);
}

/* Copies taken while another process ingests into the store in small
 * batches: each is a store as some commit left it (clean, a template count
 * between before and after), and the last one after the ingest has all. */
static void test_copy_live(void **state)
{
    (void)state;
    const json_int_t before = checked(store);
    pid_t p = fork();
    assert_true(p >= 0);
    if (p == 0) {
        const char *ingest[] = {"ingest", "--store", store, "--batch", "2", more, NULL};
        _exit(run(ingest, NULL, NULL) ? 1 : 0);
    }
    json_int_t seen_min = INT64_MAX, seen_max = 0;
    for (int k = 0; k < 6; k++) {
        char name[32];
        snprintf(name, sizeof name, "live%d", k);
        char *dst = ts_path(dir, name);
        const char *cp[] = {"store", "copy", store, dst, NULL};
        assert_int_equal(run(cp, NULL, NULL), 0);
        json_int_t n = checked(dst);
        assert_true(n >= before && n <= before + 24);
        if (n < seen_min) seen_min = n;
        if (n > seen_max) seen_max = n;
        free(dst);
    }
    int st = 0;
    assert_int_equal(waitpid(p, &st, 0), p);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    char *last = ts_path(dir, "after");
    const char *cp[] = {"store", "copy", store, last, NULL};
    assert_int_equal(run(cp, NULL, NULL), 0);
    assert_int_equal(checked(last), before + 24);
    print_message("live copies held %lld to %lld templates (ingest from %lld to %lld)\n", (long long)seen_min,
                  (long long)seen_max, (long long)before, (long long)before + 24);
    no_leftovers();
    free(last);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_copy),
        cmocka_unit_test(test_copy_live),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
