/* Helpers shared by the store tests: store_support.h. */
#include "store_support.h"

#include <fcntl.h>
#include <jansson.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

char *st_dir, *st_data, *st_good, *st_data_b; /* a synth dataset, its store (indexed), a dataset of another connectivity */

/* ---- running mimic: the raw wait status, so a signal is seen as one ----
 * Not ts_run_mimic (test_support.h): it folds a signal into 128 + N, where
 * st_exit_code must see the signal itself (a SIGBUS or SIGSEGV on a damaged
 * store fails the test as one); it cannot set MIMIC_MAP_SIZE or a file size
 * limit (st_run_env, for the full map and file); and it waits, where two
 * ingests must race (st_spawn). */
pid_t st_spawn(const st_run_env_t *env, const char *out, const char *err, const char *const *args)
{
    pid_t pid = fork();
    if (pid == 0) {
        int fo = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644), fe = open(err, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fo, 1), dup2(fe, 2);
        if (env && env->map_size) setenv("MIMIC_MAP_SIZE", env->map_size, 1);
        else unsetenv("MIMIC_MAP_SIZE");
        setenv("MIMIC_PROGRESS", "0", 1);
        if (env && env->fsize) {
            signal(SIGXFSZ, SIG_IGN); /* kept across exec: writes past the limit fail with EFBIG */
            struct rlimit rl = {env->fsize, env->fsize};
            setrlimit(RLIMIT_FSIZE, &rl);
        }
        int n = 0;
        while (args[n]) n++;
        char **argv = calloc((size_t)n + 2, sizeof *argv);
        argv[0] = (char *)ts_mimic_bin();
        for (int i = 0; i < n; i++) argv[i + 1] = (char *)args[i];
        execv(argv[0], argv);
        _exit(127);
    }
    return pid;
}

/* Runs mimic; returns the wait status; out and err are the captured streams. */
int st_run_env(const st_run_env_t *env, char **out, char **err, const char *const *args)
{
    char *tmp = ts_tempdir("run"), *o = ts_path(tmp, "out"), *e = ts_path(tmp, "err");
    pid_t pid = st_spawn(env, o, e, args);
    int status = 0;
    waitpid(pid, &status, 0);
    char *so = ts_read_file(o, NULL), *se = ts_read_file(e, NULL);
    if (out) *out = so;
    else free(so);
    if (err) *err = se;
    else free(se);
    ts_rmtree(tmp);
    free(o), free(e), free(tmp);
    return status;
}
int st_run(char **out, char **err, const char *const *args) { return st_run_env(NULL, out, err, args); }

/* The exit code of a normal exit; fails the test on a signal (SIGBUS...). */
int st_exit_code(int status, const char *what)
{
    if (WIFSIGNALED(status)) fprintf(stderr, "%s: killed by signal %d\n", what, WTERMSIG(status));
    assert_true(WIFEXITED(status));
    return WEXITSTATUS(status);
}

int st_count_lines(const char *s)
{
    int n = 0;
    for (; s && *s; s++) n += *s == '\n';
    return n;
}

/* One line on stderr, "mimic CMD: store damaged: ..." naming the store. */
void st_assert_damaged_line(const char *cmd, const char *store, const char *errs)
{
    char want[64];
    snprintf(want, sizeof want, "mimic %s: store damaged: ", cmd);
    if (!errs || st_count_lines(errs) != 1 || strncmp(errs, want, strlen(want)) || !strstr(errs, store))
        fprintf(stderr, "want one line '%s... %s ...', got: %s\n", want, store, errs ? errs : "(nothing)");
    assert_int_equal(st_count_lines(errs), 1);
    assert_memory_equal(errs, want, strlen(want));
    assert_non_null(strstr(errs, store));
}

int st_setup(void **state)
{
    (void)state;
    st_dir = ts_tempdir("store");
    st_data = ts_path(st_dir, "bodies");
    st_good = ts_path(st_dir, "good");
    st_data_b = ts_path(st_dir, "other");
    const char *synth[] = {"synth", "--out", st_data, "--subjects", "2", "--poses", "3", "--vertices", "1500", NULL};
    const char *synth_b[] = {"synth", "--out", st_data_b, "--subjects", "1", "--poses", "2", "--vertices", "900", NULL};
    const char *ingest[] = {"ingest", "--store", st_good, st_data, NULL};
    const char *index[] = {"index", "--store", st_good, "--features", "20", NULL};
    const char *const *steps[] = {synth, synth_b, ingest, index};
    for (int i = 0; i < 4; i++) {
        char *out = NULL, *err = NULL;
        int st = st_run(&out, &err, steps[i]);
        if (!WIFEXITED(st) || WEXITSTATUS(st)) fprintf(stderr, "setup step %d: %s%s\n", i, out, err);
        free(out), free(err);
        if (!WIFEXITED(st) || WEXITSTATUS(st)) return -1;
    }
    return 0;
}

int st_teardown(void **state)
{
    (void)state;
    ts_rmtree(st_dir);
    free(st_dir), free(st_data), free(st_good), free(st_data_b);
    return 0;
}

/* A copy of the good store's data.mdb (no lock file), keep bytes of it. */
char *st_copy_store(const char *name, size_t keep)
{
    char *d = ts_path(st_dir, name), *src = ts_path(st_good, "data.mdb"), *dst = ts_path(d, "data.mdb");
    mkdir(d, 0755);
    size_t len = 0;
    char *bytes = ts_read_file(src, &len);
    assert_non_null(bytes);
    assert_int_equal(ts_write_file(dst, bytes, keep < len ? keep : len), 0);
    free(bytes), free(src), free(dst);
    return d;
}

size_t st_good_size(void)
{
    struct stat st;
    char *p = ts_path(st_good, "data.mdb");
    assert_int_equal(stat(p, &st), 0);
    free(p);
    return (size_t)st.st_size;
}

/* Every command that opens the store refuses the damaged one in one line,
 * exit 2, no signal, and ingest leaves data.mdb as it was. */
void st_assert_refused(const char *store)
{
    char *file = ts_path(store, "data.mdb");
    size_t before_len = 0, after_len = 0;
    char *before = ts_read_file(file, &before_len);
    const char *info[] = {"info", "--store", store, NULL};
    const char *check[] = {"store", "check", "--store", store, NULL};
    const char *list[] = {"list", "--store", store, "--json", NULL};
    const char *ingest[] = {"ingest", "--store", store, st_data, NULL};
    struct {
        const char *cmd;
        const char *const *args;
    } runs[] = {{"info", info}, {"store check", check}, {"list", list}, {"ingest", ingest}};
    for (size_t i = 0; i < sizeof runs / sizeof *runs; i++) {
        char *out = NULL, *err = NULL;
        int code = st_exit_code(st_run(&out, &err, runs[i].args), runs[i].cmd);
        if (code != 2) fprintf(stderr, "%s on %s: exit %d\n%s%s", runs[i].cmd, store, code, out, err);
        assert_int_equal(code, 2);
        st_assert_damaged_line(runs[i].cmd, store, err);
        free(out), free(err);
    }
    char *after = ts_read_file(file, &after_len);
    assert_int_equal(after_len, before_len); /* never written to */
    assert_memory_equal(after, before, before_len);
    free(before), free(after), free(file);
}

void st_begin_read(const char *store, mim_db_t **db, mim_db_txn_t **t)
{
    mim_error_t err = {0};
    mim_db_options_t ro = {.read_only = 1};
    assert_int_equal(mim_db_open(db, store, &ro, &err), 0);
    assert_int_equal(mim_db_begin(*db, 0, t, &err), 0);
}

float *st_template_positions(const char *store, uint64_t id, size_t *bytes)
{
    mim_db_t *db;
    mim_db_txn_t *t;
    mim_template_view_t v;
    st_begin_read(store, &db, &t);
    assert_int_equal(mim_db_template_get(t, id, &v, NULL), 0);
    *bytes = 12 * (size_t)v.n_vertices;
    float *pos = malloc(*bytes);
    assert_non_null(pos);
    memcpy(pos, v.positions, *bytes);
    mim_db_abort(&t);
    mim_db_close(&db);
    return pos;
}

/* The offset in data.mdb of n bytes equal to p (asserts they are there once). */
size_t st_find_bytes(const char *store, const void *p, size_t n)
{
    char *file = ts_path(store, "data.mdb");
    size_t len = 0;
    char *b = ts_read_file(file, &len);
    char *hit = memmem(b, len, p, n);
    assert_non_null(hit);
    assert_null(memmem(hit + 1, len - (size_t)(hit - b) - 1, p, n));
    size_t off = (size_t)(hit - b);
    free(b), free(file);
    return off;
}

void st_flip_byte(const char *store, size_t off)
{
    char *file = ts_path(store, "data.mdb");
    int fd = open(file, O_RDWR);
    unsigned char c;
    assert_int_equal(pread(fd, &c, 1, (off_t)off), 1);
    c ^= 0x10;
    assert_int_equal(pwrite(fd, &c, 1, (off_t)off), 1);
    close(fd);
    free(file);
}

/* `mimic store check` exits 1 and has a line for the record. */
void st_assert_check_finds(const char *store, const char *line, uint64_t id, const char *table)
{
    char *out = NULL, *err = NULL;
    const char *check[] = {"store", "check", "--store", store, NULL};
    int code = st_exit_code(st_run(&out, &err, check), "store check");
    if (code != 1 || !strstr(out, line)) fprintf(stderr, "store check: exit %d\n%s%s", code, out, err);
    assert_int_equal(code, 1);
    char want[512];
    snprintf(want, sizeof want, "store damaged: %s: %s\n", store, line);
    assert_non_null(strstr(out, want));
    assert_non_null(strstr(out, "1 problem\n"));
    free(out), free(err);
    const char *json[] = {"store", "check", "--store", store, "--json", NULL};
    assert_int_equal(st_exit_code(st_run(&out, &err, json), "store check --json"), 1);
    json_error_t je;
    json_t *j = json_loads(out, 0, &je);
    assert_non_null(j);
    assert_false(json_is_true(json_object_get(j, "clean")));
    json_t *p = json_array_get(json_object_get(j, "problems"), 0);
    assert_string_equal(json_string_value(json_object_get(p, "table")), table);
    if (id) assert_int_equal(json_integer_value(json_object_get(p, "id")), id);
    else assert_true(json_is_null(json_object_get(p, "id")));
    json_decref(j);
    free(out), free(err);
}
