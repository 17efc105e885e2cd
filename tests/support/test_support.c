/* Temp folders, files, and running the mimic binary for tests. */
#include "test_support.h"

#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *b = malloc((size_t)n + 1);
    size_t got = fread(b, 1, (size_t)n, f);
    fclose(f);
    b[got] = 0;
    if (len) *len = got;
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

int ts_run_mimic(char **out, char **err, const char *const *args)
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
    waitpid(pid, &status, 0);
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
