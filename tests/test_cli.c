/* The mimic binary end to end: --help everywhere, usage errors, ingest exit
 * status and messages, info and list output (text and JSON), and the demo
 * path synth -> ingest -> info. */
#include "test_support.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static char *dir;

static int setup(void **state)
{
    (void)state;
    dir = ts_tempdir("cli");
    return dir ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    ts_rmtree(dir);
    free(dir);
    return 0;
}

static int run(char **out, char **err, const char *const *args) { return ts_run_mimic(out, err, args); }

static int count_lines(const char *s)
{
    int n = 0;
    for (; s && *s; s++) n += *s == '\n';
    return n;
}

static void test_help(void **s)
{
    (void)s;
    const char *cmds[] = {"synth", "ingest", "info", "list"};
    for (int i = 0; i < 4; i++) {
        char *out, *err;
        const char *args[] = {cmds[i], "--help", NULL};
        assert_int_equal(run(&out, &err, args), 0);
        assert_non_null(strstr(out, "usage: mimic"));
        assert_non_null(strstr(out, cmds[i]));
        assert_string_equal(err, "");
        free(out), free(err);
    }
    char *out, *err;
    const char *top[] = {"--help", NULL};
    assert_int_equal(run(&out, &err, top), 0);
    for (int i = 0; i < 4; i++) assert_non_null(strstr(out, cmds[i]));
    free(out), free(err);
    const char *unknown[] = {"frobnicate", NULL};
    assert_int_equal(run(&out, &err, unknown), 2);
    assert_non_null(strstr(err, "unknown command 'frobnicate'"));
    free(out), free(err);
}

static void test_usage_errors(void **s)
{
    (void)s;
    struct { const char *args[14]; const char *phrase; } cases[] = {
        {{"ingest", "x.ply", NULL}, "--store DIR is required"},
        {{"ingest", "--store", "/tmp/never-made", NULL}, "no PATH given"},
        {{"ingest", "--store", "s", "--batch", "zero", NULL}, "--batch 'zero' is not a number in 1..1000000"},
        {{"info", NULL}, "--store DIR is required"},
        {{"index", "--store", "s", "--noise", "2", NULL}, "mimic index: --noise '2' is not a number in 0..1"},
        {{"index", "--store", "s", "--proportions", "tall", NULL}, "mimic index: --proportions 'tall': use canonical or body"},
        {{"index", "--store", "s", "--discriminants", "2", NULL}, "mimic index: --discriminants '2' is not a number in 0..1"},
        {{"index", "--store", "s", "--discriminants", "x", NULL}, "mimic index: --discriminants 'x' is not a number in 0..1"},
        {{"index", "--store", "s", "--shape-noise", "2", NULL}, "mimic index: --shape-noise '2' is not a number in 0..1"},
        {{"index", "--store", "s", "--shape-noise", "-1", NULL}, "mimic index: --shape-noise '-1' is not a number in 0..1"},
        {{"index", "--store", "s", "--augment", "0", NULL}, "mimic index: --augment '0' is not a number in 1..64"},
        {{"list", "--bogus", NULL}, "unknown or incomplete option '--bogus'"},
        {{"info", "--store", "/nonexistent/store", NULL}, "/nonexistent/store"},
        /* the shared option kinds of cli/args.c, one case each */
        {{"serve", "--store", "s", "--avatar", "1", "--vest-pose", "q", NULL}, "mimic serve: --vest-pose 'q' is not rest, t or a"},
        {{"vest", "replay", "--pose", "z", "x.rec", NULL}, "mimic vest replay: --pose 'z' is not rest, t or a"},
        {{"demo", "--duration", "0", NULL}, "mimic demo: --duration '0' is not a number of seconds in (0, 86400]"},
        {{"vest", "record", "--device", "udp:127.0.0.1:9", "--duration", "-1", "-o", "x", NULL},
         "mimic vest record: --duration '-1' is not a number in 0.001..1e+07"},
        {{"vest", "simulate", "--motion", "demo", "--rate", "nan", "--out", "x", NULL},
         "mimic vest simulate: --rate 'nan' is not a number in 1..2000"},
        {{"transfer", "--store", "s", "--avatar", "1", "--template", "0", "-o", "o.ply", NULL},
         "mimic transfer: --template '0' is not a template id (a number from mimic list)"},
        {{"morph", "--store", "s", "--avatar", "1", "--keys", "1,x", "--frames-between", "1", "-o", "o.glb", NULL},
         "mimic morph: --keys 'x' is not a template id (a number from mimic list)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char *out, *err;
        assert_int_equal(run(&out, &err, cases[i].args), 2);
        if (!strstr(err, cases[i].phrase)) fprintf(stderr, "got: %s\n", err);
        assert_non_null(strstr(err, cases[i].phrase));
        assert_int_equal(count_lines(err), 1); /* one line that says what and where */
        free(out), free(err);
    }
}

/* spheres sharing one connectivity, two of them bad */
static char *make_dataset(void)
{
    char *d = ts_path(dir, "data");
    mkdir(d, 0755);
    for (int i = 0; i < 6; i++) {
        ts_polymesh_t m;
        ts_sphere(&m, 10, 12, 0.3f + 0.02f * (float)i);
        char fn[64];
        snprintf(fn, sizeof fn, "tr_reg_%03d.ply", 10 + i);
        char *p = ts_path(d, fn);
        ts_write_ply_binary(p, &m);
        free(p);
        ts_polymesh_free(&m);
    }
    char *p = ts_path(d, "zz_empty.obj");
    ts_write_file(p, "# nothing\n", 10);
    free(p);
    p = ts_path(d, "zz_cut.ply");
    ts_polymesh_t m;
    ts_sphere(&m, 10, 12, 1.0f);
    ts_write_ply_binary(p, &m);
    ts_truncate(p, 500);
    ts_polymesh_free(&m);
    free(p);
    p = ts_path(d, "landmarks.json");
    const char *lm = "{\"landmarks\":[{\"name\":\"top\",\"vertex\":0},{\"name\":\"l_a\",\"vertex\":4},"
                     "{\"name\":\"r_a\",\"vertex\":10},{\"name\":\"bottom\",\"vertex\":109}]}";
    ts_write_file(p, lm, strlen(lm));
    free(p);
    return d;
}

static void test_ingest_info_list(void **s)
{
    (void)s;
    char *data = make_dataset();
    char *store = ts_path(dir, "store");
    char *out, *err;
    const char *ingest[] = {"ingest", "--store", store, data, NULL};
    assert_int_equal(run(&out, &err, ingest), 1); /* some files failed */
    assert_non_null(strstr(out, "6 added"));
    assert_non_null(strstr(out, "2 failed"));
    assert_non_null(strstr(err, "zz_empty.obj: empty mesh"));
    assert_non_null(strstr(err, "zz_cut.ply: truncated"));
    assert_int_equal(count_lines(err), 2);
    free(out), free(err);

    const char *info[] = {"info", "--store", store, "--json", NULL};
    assert_int_equal(run(&out, &err, info), 0);
    json_error_t je;
    json_t *j = json_loads(out, 0, &je);
    assert_non_null(j);
    assert_true(json_is_integer(json_object_get(j, "templates")));
    assert_int_equal(json_integer_value(json_object_get(j, "templates")), 6);
    assert_int_equal(json_integer_value(json_object_get(j, "schema_version")), 4); /* schemas/store-version */
    /* FAUST naming: tr_reg_010..015 are subject 1, poses 0..5 */
    json_t *subjects = json_object_get(j, "subjects");
    assert_int_equal(json_integer_value(json_object_get(subjects, "1")), 6);
    assert_int_equal(json_object_size(json_object_get(j, "poses")), 6);
    json_t *conn = json_object_get(j, "connectivity");
    assert_int_equal(json_integer_value(json_object_get(conn, "vertices")), 2 + 9 * 12);
    assert_int_equal(json_array_size(json_object_get(json_object_get(j, "landmarks"), "landmarks")), 4);
    assert_true(json_integer_value(json_object_get(json_object_get(j, "size"), "disk_bytes")) > 0);
    json_decref(j);
    free(out), free(err);

    const char *list[] = {"list", "--store", store, "--pose", "3", "--json", NULL};
    assert_int_equal(run(&out, &err, list), 0);
    j = json_loads(out, 0, &je);
    assert_true(json_is_array(j));
    assert_int_equal(json_array_size(j), 1);
    json_t *row = json_array_get(j, 0);
    assert_true(json_is_integer(json_object_get(row, "id")));
    assert_string_equal(json_string_value(json_object_get(row, "subject")), "1");
    assert_string_equal(json_string_value(json_object_get(row, "pose")), "3");
    assert_non_null(strstr(json_string_value(json_object_get(row, "source")), "tr_reg_013.ply"));
    json_decref(j);
    free(out), free(err);

    const char *text[] = {"list", "--store", store, "--subject", "1", NULL};
    assert_int_equal(run(&out, &err, text), 0);
    assert_int_equal(count_lines(out), 7); /* header + 6 rows */
    free(out), free(err);

    /* a second run adds nothing and succeeds once the bad files are gone */
    char *p = ts_path(data, "zz_empty.obj");
    remove(p);
    free(p);
    p = ts_path(data, "zz_cut.ply");
    remove(p);
    free(p);
    assert_int_equal(run(&out, &err, ingest), 0);
    assert_non_null(strstr(out, "0 added, 6 already stored, 0 failed"));
    free(out), free(err), free(store), free(data);
}

/* The demo's path: synth -> ingest -> info, labels from the synth names. */
/* The exit-status table (docs/reference.md): a store that will not open is "the command
 * could not run" (2) for every command that takes --store, with one line
 * that names the store. */
static void test_store_open_exit_status(void **s)
{
    (void)s;
    char *file = ts_path(dir, "not-a-store"), *missing = ts_path(dir, "no-such-store");
    FILE *f = fopen(file, "w");
    assert_non_null(f);
    fputs("x\n", f);
    fclose(f);
    const char *stores[] = {file, missing};
    for (int k = 0; k < 2; k++) {
        const char *st = stores[k];
        const char *cases[][16] = {
            {"info", "--store", st, NULL},
            {"list", "--store", st, NULL},
            {"index", "--store", st, NULL},
            {"query", "--store", st, "--landmarks", "x.json", NULL},
            {"transfer", "--store", st, "--avatar", "1", "--template", "2", "-o", "o.ply", NULL},
            {"morph", "--store", st, "--avatar", "1", "--keys", "1,2", "--frames-between", "1", "-o", "o.glb", NULL},
            {"serve", "--store", st, "--avatar", "1", "--listen", "127.0.0.1:0", NULL},
            {"ingest", "--store", st, "nothing-to-read", NULL},
            {"pairs", "templates", "--store", st, "--samples", "s.jsonl", "--avatar", "1", NULL},
            {"complete", "--store", st, "--landmarks", "x.json", NULL},
            {"store", "check", "--store", st, NULL},
            {"store", "copy", st, "copy-dst", NULL},
        };
        for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
            if (k == 1 && !strcmp(cases[c][0], "ingest"))
                continue; /* ingest creates a missing store */
            char *out = NULL, *err = NULL;
            int rc = run(&out, &err, cases[c]);
            if (rc != 2 || !strstr(err, st) || count_lines(err) != 1)
                fail_msg("mimic %s %s --store %s: exit %d, stderr '%s' (wanted 2 and one line naming the store)",
                         cases[c][0], cases[c][1], st, rc, err);
            free(out), free(err);
        }
    }
    free(file), free(missing);
}

static void test_synth_ingest_info(void **s)
{
    (void)s;
    char *data = ts_path(dir, "synth");
    char *store = ts_path(dir, "synth_store");
    char *out, *err;
    const char *synth[] = {"synth", "--out", data, "--subjects", "2", "--poses", "3", "--vertices", "3000", NULL};
    assert_int_equal(run(&out, &err, synth), 0);
    free(out), free(err);
    const char *ingest[] = {"ingest", "--store", store, data, NULL};
    assert_int_equal(run(&out, &err, ingest), 0);
    assert_non_null(strstr(out, "6 added"));
    free(out), free(err);
    const char *info[] = {"info", "--store", store, "--json", NULL};
    assert_int_equal(run(&out, &err, info), 0);
    json_t *j = json_loads(out, 0, NULL);
    assert_int_equal(json_integer_value(json_object_get(j, "templates")), 6);
    assert_int_equal(json_object_size(json_object_get(j, "subjects")), 2);
    assert_int_equal(json_object_size(json_object_get(j, "poses")), 3);
    json_t *lms = json_object_get(json_object_get(j, "landmarks"), "landmarks");
    assert_int_equal(json_array_size(lms), 16);
    assert_string_equal(json_string_value(json_object_get(json_array_get(lms, 15), "name")), "spine");
    json_decref(j);
    free(out), free(err), free(store), free(data);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help),
        cmocka_unit_test(test_usage_errors),
        cmocka_unit_test(test_ingest_info_list),
        cmocka_unit_test(test_store_open_exit_status),
        cmocka_unit_test(test_synth_ingest_info),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
