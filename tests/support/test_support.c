/* Temp folders, files, and running the mimic binary for tests. */
#include "test_support.h"

#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

char *ts_tempdir(const char *tag)
{
    const char *base = getenv("TMPDIR");
    char tmpl[4096];
    snprintf(tmpl, sizeof tmpl, "%s/mimic-%s-XXXXXX", base && *base ? base : "/tmp", tag);
    char *d = mkdtemp(tmpl);
    return d ? strdup(d) : NULL;
}

static int rm_one(const char *p, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)st, (void)flag, (void)ftw;
    return remove(p);
}

void ts_rmtree(const char *path)
{
    if (path && getenv("MIMIC_KEEP_TEST_DIRS") == NULL) nftw(path, rm_one, 16, FTW_DEPTH | FTW_PHYS);
}

char *ts_path(const char *dir, const char *name)
{
    size_t n = strlen(dir) + strlen(name) + 2;
    char *p = malloc(n);
    snprintf(p, n, "%s/%s", dir, name);
    return p;
}

const char *ts_mimic_bin(void)
{
    const char *b = getenv("MIMIC_BIN");
    return b && *b ? b : MIMIC_BIN_DEFAULT;
}

char *ts_read_file(const char *path, size_t *len)
{
    char *b;
    size_t n;
    if (mim_file_read(path, 0, &b, &n, NULL)) return NULL;
    if (len) *len = n;
    return b;
}

int ts_write_file(const char *path, const void *data, size_t len)
{
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    size_t w = fwrite(data, 1, len, f);
    return (fclose(f) == 0 && w == len) ? 0 : -1;
}

int ts_truncate(const char *path, size_t keep) { return truncate(path, (off_t)keep); }

int ts_run_mimic(char **out, char **err, const char *const *args) { return ts_run_mimic_peak(out, err, args, NULL); }

char *ts_mimic_expect(int want, char **err, const char *const *args)
{
    char *o = NULL, *e = NULL;
    int rc = ts_run_mimic(&o, &e, args);
    if (rc != want) fail_msg("mimic %s %s: exit %d, not %d: %s", args[0], args[1] ? args[1] : "", rc, want, e ? e : "");
    if (err) *err = e;
    else free(e);
    return o;
}

int ts_run_mimic_peak(char **out, char **err, const char *const *args, long *peak_kib)
{
    char *dir = ts_tempdir("run");
    char *o = ts_path(dir, "out"), *e = ts_path(dir, "err");
    pid_t pid = fork();
    if (pid == 0) {
        int fo = open(o, O_WRONLY | O_CREAT | O_TRUNC, 0644), fe = open(e, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fo, 1);
        dup2(fe, 2);
        int n = 0;
        while (args[n]) n++;
        char **argv = calloc((size_t)n + 2, sizeof *argv);
        argv[0] = (char *)ts_mimic_bin();
        for (int i = 0; i < n; i++) argv[i + 1] = (char *)args[i];
        execv(argv[0], argv);
        execvp(argv[0], argv);
        _exit(127);
    }
    int status = 0;
    struct rusage ru = {0};
    wait4(pid, &status, 0, &ru);
    if (peak_kib) *peak_kib = ru.ru_maxrss;
    if (out) *out = ts_read_file(o, NULL);
    if (err) *err = ts_read_file(e, NULL);
    ts_rmtree(dir);
    free(o);
    free(e);
    free(dir);
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

const char *ts_shared_data(void)
{
    const char *d = getenv("MIMIC_SHARED_DATA");
    return d && *d ? d : MIMIC_SHARED_DATA_DEFAULT;
}

/* ---- the Khronos glTF validator (npm gltf-validator, installed by build.sh) ---- */
char *ts_run_capture(const char *cmd, int *status)
{
    FILE *f = popen(cmd, "r");
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    if (!f || !buf) {
        if (f)
            pclose(f);
        free(buf);
        *status = -1;
        return strdup("");
    }
    size_t got;
    while ((got = fread(buf + len, 1, cap - len - 1, f)) > 0) {
        len += got;
        if (len + 1 == cap) {
            char *nb = realloc(buf, cap * 2);
            if (!nb)
                break;
            buf = nb, cap *= 2;
        }
    }
    buf[len] = 0;
    int st = pclose(f);
    *status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return buf;
}

int ts_gltf_validator_available(void)
{
    int st;
    char *v = ts_run_capture("node --version 2>/dev/null", &st);
    int node = st == 0 && v[0] == 'v';
    free(v);
    char *pkg = ts_path(MIMIC_SOURCE_DIR, "node_modules/gltf-validator/package.json");
    struct stat sb;
    int installed = stat(pkg, &sb) == 0;
    free(pkg);
    if (!node || !installed) {
        print_message("skipping the glTF validator: %s (./build.sh installs it with npm ci when npm is present)\n",
                      !node ? "node is not installed" : "node_modules/gltf-validator is missing");
        return 0;
    }
    return 1;
}

void ts_gltf_validate(const char *path)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "node '%s/tests/gltf_validate.mjs' --strict '%s' 2>&1", MIMIC_SOURCE_DIR, path);
    int st;
    char *out = ts_run_capture(cmd, &st);
    if (st != 0)
        fprintf(stderr, "%s", out);
    assert_int_equal(st, 0);
    assert_non_null(strstr(out, ": 0 errors, 0 warnings"));
    free(out);
}
