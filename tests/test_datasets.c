/* Datasets that join a store without surprises (issue 30 item 2), end to
 * end through the mimic command: two synth datasets whose file names give
 * the same subject and pose labels ("0".."2", "0".."3") go into one store;
 * each template keeps its dataset (by default its folder), subjects stay
 * apart per dataset, pose classes merge only through --pose-map, and the
 * index warns about classes of one template. */
#include "test_support.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char *dir, *set_a, *set_b, *set_c, *store;

static int run_quiet(const char *const *args)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc) fprintf(stderr, "%s", e ? e : "");
    free(o), free(e);
    return rc;
}

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("datasets");
    set_a = ts_path(dir, "setA"), set_b = ts_path(dir, "setB"), set_c = ts_path(dir, "lonely");
    store = ts_path(dir, "store");
    const char *a[] = {"synth", "--out", set_a, "--subjects", "3", "--poses", "4", "--vertices", "1500", NULL};
    const char *b[] = {"synth", "--out", set_b, "--subjects", "2", "--poses", "4", "--vertices", "1500", "--seed", "7", NULL};
    const char *c[] = {"synth", "--out", set_c, "--subjects", "1", "--poses", "2", "--vertices", "1500", "--seed", "9", NULL};
    return run_quiet(a) || run_quiet(b) || run_quiet(c);
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir), free(set_a), free(set_b), free(set_c), free(store);
    return 0;
}

static json_t *run_json(const char *const *args, char **err_out)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc) fail_msg("mimic %s: exit %d: %s", args[0], rc, e ? e : "");
    json_error_t je;
    json_t *j = json_loads(o, 0, &je);
    if (!j) fail_msg("mimic %s: not JSON: %s", args[0], o);
    free(o);
    if (err_out) *err_out = e;
    else free(e);
    return j;
}

static void test_datasets_apart(void **state)
{
    (void)state;
    const char *ing[] = {"ingest", "--store", store, set_a, set_b, NULL};
    assert_int_equal(run_quiet(ing), 0);
    /* every template has its folder as dataset; no (dataset, subject) is shared */
    const char *list[] = {"list", "--store", store, "--json", NULL};
    json_t *rows = run_json(list, NULL);
    assert_int_equal(json_array_size(rows), 20);
    size_t i;
    json_t *r;
    uint32_t in_a = 0, in_b = 0;
    json_array_foreach(rows, i, r) {
        const char *ds = json_string_value(json_object_get(r, "dataset"));
        assert_non_null(ds);
        in_a += !strcmp(ds, "setA"), in_b += !strcmp(ds, "setB");
    }
    assert_int_equal(in_a, 12);
    assert_int_equal(in_b, 8);
    json_decref(rows);
    const char *info[] = {"info", "--store", store, "--json", NULL};
    json_t *in = run_json(info, NULL);
    json_t *subjects = json_object_get(in, "subjects"), *datasets = json_object_get(in, "datasets");
    assert_int_equal(json_integer_value(json_object_get(datasets, "setA")), 12);
    assert_int_equal(json_integer_value(json_object_get(datasets, "setB")), 8);
    assert_int_equal(json_object_size(subjects), 5); /* 3 + 2 people, not 3 */
    assert_int_equal(json_integer_value(json_object_get(subjects, "setA/0")), 4);
    assert_int_equal(json_integer_value(json_object_get(subjects, "setB/0")), 4);
    assert_null(json_object_get(subjects, "0"));
    json_decref(in);

    /* the index: each dataset's poses its own (8 classes), said so */
    const char *ix[] = {"index", "--store", store, "--json", NULL};
    json_t *j = run_json(ix, NULL);
    assert_int_equal(json_integer_value(json_object_get(j, "classes")), 8);
    assert_int_equal(json_integer_value(json_object_get(j, "datasets")), 2);
    assert_int_equal(json_integer_value(json_object_get(j, "mapped_templates")), 0);
    assert_int_equal(json_integer_value(json_object_get(j, "single_template_classes")), 0);
    json_decref(j);

    /* a pose map merges them: 4 classes, every template mapped */
    char *pm = ts_path(dir, "poses.csv");
    const char *csv = "dataset,pose,class\n# the same designed poses\nsetA,0,rest\nsetB,0,rest\nsetA,1,tpose\n"
                      "setB,1,tpose\nsetA,2,arms_up\nsetB,2,arms_up\nsetA,3,walk\nsetB,3,walk\n";
    ts_write_file(pm, csv, strlen(csv));
    const char *ixm[] = {"index", "--store", store, "--pose-map", pm, "--json", NULL};
    j = run_json(ixm, NULL);
    assert_int_equal(json_integer_value(json_object_get(j, "classes")), 4);
    assert_int_equal(json_integer_value(json_object_get(j, "mapped_templates")), 20);
    json_decref(j);

    /* a dataset of one subject in two poses: two classes of one template, warned */
    const char *ing_c[] = {"ingest", "--store", store, "--dataset", "scans-2", set_c, NULL};
    assert_int_equal(run_quiet(ing_c), 0);
    char *e = NULL;
    j = run_json(ixm, &e);
    assert_int_equal(json_integer_value(json_object_get(j, "classes")), 6);
    assert_int_equal(json_integer_value(json_object_get(j, "datasets")), 3);
    assert_int_equal(json_integer_value(json_object_get(j, "single_template_classes")), 2);
    assert_non_null(strstr(e, "warning: 2 of 6 pose classes have one template (scans-2/0, scans-2/1)"));
    assert_non_null(strstr(e, "--pose-map"));
    assert_int_equal(strchr(e, '\n')[1], '\0');
    json_decref(j);
    free(e);
    const char *list_c[] = {"list", "--store", store, "--json", NULL};
    rows = run_json(list_c, NULL);
    assert_string_equal(json_string_value(json_object_get(json_array_get(rows, 20), "dataset")), "scans-2");
    json_decref(rows);
    free(pm);
}

/* Bad names and maps: one line, exit 2, nothing written. */
static void test_bad_input(void **state)
{
    (void)state;
    char *o, *e;
    const char *dots[] = {"ingest", "--store", store, "--dataset", "..", set_c, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, dots), 2);
    assert_non_null(strstr(e, "--dataset '..'"));
    free(o), free(e);
    const char *slash[] = {"ingest", "--store", store, "--dataset", "a/b", set_c, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, slash), 2);
    assert_non_null(strstr(e, "--dataset 'a/b': a name is 1 to 64 of the letters, digits"));
    assert_int_equal(strchr(e, '\n')[1], '\0');
    free(o), free(e);
    char *pm = ts_path(dir, "bad.csv");
    const char *csv = "dataset,pose,class\nsetA,1,a\nsetA,1,b\n";
    ts_write_file(pm, csv, strlen(csv));
    const char *ix[] = {"index", "--store", store, "--pose-map", pm, NULL};
    assert_int_equal(ts_run_mimic(&o, &e, ix), 2);
    assert_non_null(strstr(e, "bad.csv:3: setA pose 1 is class a on line 2 and b here"));
    free(o), free(e);
    const char *hdr = "data,pose,class\n";
    ts_write_file(pm, hdr, strlen(hdr));
    assert_int_equal(ts_run_mimic(&o, &e, ix), 2);
    assert_non_null(strstr(e, "bad.csv:1: header must name the columns dataset, pose and class"));
    free(o), free(e), free(pm);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_datasets_apart),
        cmocka_unit_test(test_bad_input),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
