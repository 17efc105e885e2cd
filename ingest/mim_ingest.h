/* mimic ingest: dataset discovery and labels, and the ingest pipeline that
 * puts meshes (read through io/) into the template store. */
#ifndef MIM_INGEST_H
#define MIM_INGEST_H

#include "mim_core.h"
#include "mim_db.h"
#include "mim_register.h"

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
/* Datasets: a template's subject and pose are its dataset's own (one
 * dataset's subject "0" is not another's). A name is 1..MIM_INGEST_DATASET_MAX
 * of A-Z a-z 0-9 . _ - (not "." or ".."). */
#define MIM_INGEST_DATASET_MAX 64
int mim_ingest_dataset_valid(const char *name);
/* The dataset a file found from the ingest's PATH arguments belongs to by
 * default: the folder it was ingested from (the argument's own name when
 * the file was found under it, else the folder that holds the file), its
 * real path's last component with other characters made '_'. */
void mim_ingest_dataset_of(char *const *args, size_t n_args, const char *file, char *out, size_t size);

/* CSV tables (csv.c): the header line names the columns (any order, more
 * allowed); each later row's fields of `columns`, in that order, go to row
 * (a non-zero return stops the read and is returned). Errors name the file
 * and line: MIM_EFORMAT, or -errno when it cannot be opened (`what` names
 * the table in messages: "manifest", "pose map"). */
typedef int (*mim_csv_row_fn)(void *ctx, const char *const *fields, size_t lineno, mim_error_t *err);
int mim_csv_read(const char *path, const char *what, const char *const *columns, int n_columns, mim_csv_row_fn row,
                 void *ctx, mim_error_t *err);

/* Pose maps (pose_map.c): a CSV of dataset, pose, class; each row makes
 * that dataset's pose a member of that pose class, so that poses of
 * different datasets form one class only where the user says so. A pair
 * mapped to two classes, an empty pose or class, or a bad dataset name is
 * MIM_EFORMAT naming the line. The lookup is NULL for an unmapped pose.
 * (A linear lookup: maps hold tens to hundreds of rows.) */
typedef struct mim_pose_map mim_pose_map_t;
int mim_pose_map_load(mim_pose_map_t **out, const char *path, mim_error_t *err);
void mim_pose_map_free(mim_pose_map_t **m);
size_t mim_pose_map_size(const mim_pose_map_t *m);
const char *mim_pose_map_class(const mim_pose_map_t *m, const char *dataset, const char *pose);

typedef struct mim_manifest mim_manifest_t;
/* CSV with a header naming at least the columns file, subject, pose; file is
 * relative to the manifest's folder. */
int mim_manifest_load(mim_manifest_t **out, const char *path, mim_error_t *err);
void mim_manifest_free(mim_manifest_t **m);
/* 1 if the manifest has a row for path (matched by real path, then by name). */
int mim_manifest_lookup(const mim_manifest_t *m, const char *path, mim_labels_t *out);

/* ---- meshes of another connectivity (foreign.c; issue 13) ---- */
/* The caller's hash of a mesh (its faces and positions): how a registered
 * source is recognised again, and an avatar's binding found in the cache. */
uint64_t mim_ingest_mesh_hash(const mim_mesh_t *m);

typedef struct mim_ingest_landmark_sources {
    /* (c) a file the user gave for this mesh: a landmark map of its
     * connectivity, or its landmark positions (one frame, in the store
     * map's order). NULL: none. */
    const char *landmarks_path;
    /* (a) a landmark map that came with the dataset: used for a mesh whose
     * vertex count is its topology_vertices. NULL: none. */
    const mim_landmark_map_t *dataset_map;
    const char *dataset_map_path; /* names it in messages */
    const char *option;           /* the command's option for (c), named when none exists; NULL: "--landmarks" */
} mim_ingest_landmark_sources_t;
/* The landmarks of a foreign mesh (3 * store_map->count floats, in the
 * store map's order), from the first that exists of: (c) the file given;
 * (b) NAME.landmarks.json beside NAME.ext (mim_io_landmarks_sidecar), a
 * map or positions; (a) the dataset's map of this connectivity; (d) a
 * built-in map of a connectivity mimic knows by its faces
 * (mim_reg_known_map: SMPL's, for FAUST and every SMPL-family mesh). A
 * map's landmarks are matched to the store's by name. how (may be NULL
 * with how_size 0) gets where they came from. Errors, one line naming the
 * files: MIM_ENOLANDMARKS when none exists, a file's own errors, a map of
 * another vertex count (MIM_ETOPOLOGY) or without a landmark the store
 * needs (MIM_EFORMAT), missing or implausible positions. */
int mim_ingest_foreign_landmarks(const char *mesh_path, const mim_mesh_t *mesh,
                                 const mim_ingest_landmark_sources_t *src, const mim_landmark_map_t *store_map,
                                 float *out, char *how, size_t how_size, mim_error_t *err);

/* The nearest templates to a landmark frame (3 * map count floats), found
 * by the caller (through the store's index: query/ is not ingest's to
 * use): up to k ids, nearest first, into ids and their count into *n; 0,
 * or an error with its message. Called from many threads at once. */
typedef int (*mim_ingest_nearest_fn)(void *ctx, const float *landmarks, uint32_t k, uint64_t *ids, uint32_t *n,
                                     mim_error_t *err);

/* The template registration starts from: of the MIM_INGEST_CANDIDATES
 * nearest that nearest gives (the index's: the frame's pose class, by
 * angles that do not see proportions), the one whose landmarks (map's, in
 * db) a similarity brings nearest to the frame's (mim_reg_likest: the body
 * most like it; bench/RESULTS.md "Canonical proportions for the angles").
 * 0 and *id, or nearest's error, the store's, MIM_ENOTFOUND for no
 * candidate. */
#define MIM_INGEST_CANDIDATES 8u
int mim_ingest_start_template(mim_db_t *db, const mim_landmark_map_t *map, mim_ingest_nearest_fn nearest, void *ctx,
                              const float *landmarks, uint64_t *id, mim_error_t *err);

/* A registrar: the store's connectivity and landmark map, the caller's
 * nearest-template function, and a pool of registration contexts (one per
 * thread registering at a time). Errors: the store's, MIM_ENOTFOUND for an
 * empty store, MIM_ENOLANDMARKS. opt may be NULL (defaults). */
typedef struct mim_ingest_registrar mim_ingest_registrar_t;
int mim_ingest_registrar_open(mim_ingest_registrar_t **out, mim_db_t *db, mim_ingest_nearest_fn nearest,
                              void *nearest_ctx, const mim_reg_options_t *opt, mim_error_t *err);
void mim_ingest_registrar_close(mim_ingest_registrar_t **r); /* accepts NULL; nulls */
const mim_landmark_map_t *mim_ingest_registrar_map(const mim_ingest_registrar_t *r);
const mim_xfer_topology_t *mim_ingest_registrar_topology(const mim_ingest_registrar_t *r);
const uint32_t *mim_ingest_registrar_faces(const mim_ingest_registrar_t *r, uint32_t *n_faces);
/* Registers the store's connectivity onto mesh (mim_reg_run) from the
 * nearest template to its landmarks: writes 3 * n floats (the store's
 * vertex count) to out, the report, and the template it started from.
 * Thread-safe. */
int mim_ingest_register_mesh(mim_ingest_registrar_t *r, const mim_mesh_t *mesh, const float *landmarks,
                             const char *origin, float *out, mim_reg_report_t *report, uint64_t *template_id,
                             mim_error_t *err);

/* ---- the pipeline ---- */
/* Fills map (and *name) and returns 1 when the connectivity is known, 0
 * when not: mim_reg_known_map's contract. */
typedef int (*mim_ingest_known_map_fn)(const uint32_t *faces, uint32_t n_faces, uint32_t n_vertices,
                                       mim_landmark_map_t *map, const char **name);
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
    /* --register: a mesh of another connectivity than the store's is
     * registered onto it (NULL: such a mesh is refused). Its landmarks
     * come from mim_ingest_foreign_landmarks with landmarks_path (when it
     * is a map of that connectivity) or the landmarks.json beside the
     * dataset as (a). A registration whose surface distance p95 is over
     * max_distance_mm is refused with the figures. */
    mim_ingest_registrar_t *registrar;
    double max_distance_mm;     /* 0: MIM_INGEST_DEFAULT_MAX_DISTANCE_MM */
    /* The maps of known connectivities an empty store takes its landmark
     * map from when no file is given or beside the meshes: NULL, the
     * built-in ones (mim_reg_known_map). */
    mim_ingest_known_map_fn known_map;
    /* The dataset of every template added (mim_ingest_dataset_valid);
     * NULL: each file's folder (mim_ingest_dataset_of). */
    const char *dataset;
} mim_ingest_options_t;
#define MIM_INGEST_DEFAULT_MAX_DISTANCE_MM 15.0

typedef struct mim_ingest_report {
    uint64_t files;      /* files considered */
    uint64_t added;      /* new templates */
    uint64_t duplicates; /* content already in the store */
    uint64_t failed;     /* files rejected, dangling symlinks (each reported through the log callback) */
    uint64_t skipped;    /* symlink loops left out (each reported as a warning); not in files */
    uint64_t registered; /* of added: made by registering a mesh of another connectivity */
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
