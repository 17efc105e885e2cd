/* mimic ingest: dataset discovery and labels, and the ingest pipeline that
 * puts meshes (read through io/) into the template store. */
#ifndef MIM_INGEST_H
#define MIM_INGEST_H

#include "mim_core.h"
#include "mim_db.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- discovery ---- */
typedef struct mim_file_list {
    char **paths; /* sorted; owned */
    size_t count;
    /* Entries found while walking that give no file to read, one line each
     * naming the path, sorted: */
    char **failed;  /* input lost: "PATH: dangling symlink to TARGET", a
                       folder that cannot be listed or nests too deep */
    size_t n_failed;
    char **skipped; /* nothing lost: "PATH: symlink loop (already walked as
                       OTHER), skipped", a link that resolves to itself */
    size_t n_skipped;
} mim_file_list_t;
/* Files given as files are kept whatever their extension (so a bad one is
 * reported); folders are walked recursively for known mesh extensions,
 * following symlinks, each real folder (device and inode) once: a link
 * back to a folder already walked, or to one that holds the folder given,
 * is a loop and skipped; a dangling link is failed. Errors (the walk could
 * not run): a folder given that cannot be listed, out of memory. */
int mim_discover(char *const *paths, size_t n, mim_file_list_t *out, mim_error_t *err);
void mim_file_list_free(mim_file_list_t *l);
/* landmarks.json beside the dataset: in a folder PATH, or beside a file PATH. */
int mim_discover_landmarks(char *const *paths, size_t n, char *out, size_t size);

/* ---- labels ---- */
#define MIM_LABEL_MAX 64
typedef struct mim_labels {
    char subject[MIM_LABEL_MAX]; /* "" when none */
    char pose[MIM_LABEL_MAX];
} mim_labels_t;
/* Labels from a recognised file-name layout: FAUST tr_reg_NNN (subject NNN/10,
 * pose NNN%10), SCAPE meshNNN (subject 0, pose NNN), mimic synth and
 * mh-bodies NAME_sSS_pPP. Returns 1 if the name was recognised. */
int mim_labels_from_name(const char *path, mim_labels_t *out);

typedef struct mim_manifest mim_manifest_t;
/* CSV with a header naming at least the columns file, subject, pose; file is
 * relative to the manifest's folder. */
int mim_manifest_load(mim_manifest_t **out, const char *path, mim_error_t *err);
void mim_manifest_free(mim_manifest_t **m);
/* 1 if the manifest has a row for path (matched by real path, then by name). */
int mim_manifest_lookup(const mim_manifest_t *m, const char *path, mim_labels_t *out);

/* ---- the pipeline ---- */
typedef struct mim_ingest_options {
    const char *landmarks_path; /* NULL: landmarks.json beside the dataset */
    const char *manifest_path;  /* NULL: labels from file names */
    uint32_t batch;             /* templates per transaction; 0 means 64 */
    uint32_t threads;           /* reader threads; 0 means the number of cores */
    int quiet;                  /* no per-file messages */
    /* Each rejected file (unless quiet) and notes, one line each, on the
     * calling thread; NULL: quiet. */
    mim_log_fn log;
    void *log_ctx;
    mim_progress_fn progress;   /* files done of files found (label "ingest"); NULL: none */
    void *progress_ctx;
} mim_ingest_options_t;

typedef struct mim_ingest_report {
    uint64_t files;      /* files considered */
    uint64_t added;      /* new templates */
    uint64_t duplicates; /* content already in the store */
    uint64_t failed;     /* files rejected, dangling symlinks (each reported through the log callback) */
    uint64_t skipped;    /* symlink loops left out (each reported as a warning); not in files */
    uint64_t templates;  /* templates in the store afterwards */
    double seconds;
} mim_ingest_report_t;

/* Reads the files on `threads` threads, checks each against the store's
 * connectivity and that it is a body (mim_body_check: a 10 m box, not a
 * point), and commits them in batches. Bad files are reported (opt->log)
 * and skipped. Returns 0 unless the ingest could not run at all
 * (store error, no landmark map for an empty store); per-file failures are
 * in report. */
int mim_ingest_run(mim_db_t *db, char *const *paths, size_t n_paths, const mim_ingest_options_t *opt,
                   mim_ingest_report_t *report, mim_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
