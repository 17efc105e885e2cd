/* Helpers shared by the store tests (test_store_damage, test_store_write):
 * running mimic with the raw wait status, the fixture (a synth dataset, its
 * indexed store, a dataset of another connectivity), copies of that store,
 * and finding and flipping a record's bytes in data.mdb. */
#ifndef MIM_STORE_SUPPORT_H
#define MIM_STORE_SUPPORT_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "mim_db.h"
#include "test_support.h"

/* The fixture, made by st_setup and removed by st_teardown (a cmocka group
 * setup and teardown): a folder, a synth dataset in it, its store (indexed),
 * and a dataset of another connectivity. */
extern char *st_dir, *st_data, *st_good, *st_data_b;
int st_setup(void **state);
int st_teardown(void **state);

/* ---- running mimic: the raw wait status, so a signal is seen as one ---- */
typedef struct {
    const char *map_size;  /* MIMIC_MAP_SIZE, or NULL */
    unsigned long fsize;   /* RLIMIT_FSIZE in bytes (SIGXFSZ ignored), or 0 */
} st_run_env_t;

/* Starts mimic with args (env may be NULL), its stdout and stderr to the
 * files out and err; returns its pid, for waitpid. */
pid_t st_spawn(const st_run_env_t *env, const char *out, const char *err, const char *const *args);
/* Runs mimic; returns the wait status; out and err are the captured streams. */
int st_run_env(const st_run_env_t *env, char **out, char **err, const char *const *args);
int st_run(char **out, char **err, const char *const *args);
/* The exit code of a normal exit; fails the test on a signal (SIGBUS...). */
int st_exit_code(int status, const char *what);
int st_count_lines(const char *s);
/* One line on stderr, "mimic CMD: store damaged: ..." naming the store. */
void st_assert_damaged_line(const char *cmd, const char *store, const char *errs);

/* ---- the fixture's store ---- */
/* A copy of the good store's data.mdb (no lock file), keep bytes of it. */
char *st_copy_store(const char *name, size_t keep);
size_t st_good_size(void);
/* Every command that opens the store refuses the damaged one in one line,
 * exit 2, no signal, and ingest leaves data.mdb as it was. */
void st_assert_refused(const char *store);

/* ---- reading a store ---- */
/* Opens store read-only and begins a read transaction (asserts both). */
void st_begin_read(const char *store, mim_db_t **db, mim_db_txn_t **t);
/* A copy of template id's positions (malloc'd; *bytes gets their size):
 * the bytes to find in data.mdb to damage that record. */
float *st_template_positions(const char *store, uint64_t id, size_t *bytes);

/* ---- a damaged record ---- */
/* The offset in data.mdb of n bytes equal to p (asserts they are there once). */
size_t st_find_bytes(const char *store, const void *p, size_t n);
/* Flips one bit of the byte at off in data.mdb. */
void st_flip_byte(const char *store, size_t off);
/* `mimic store check` exits 1 and has a line for the record. */
void st_assert_check_finds(const char *store, const char *line, uint64_t id, const char *table);

#endif
