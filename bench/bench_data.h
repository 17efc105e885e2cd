/* What the bench programs share: statistics of repeated timings, pooled
 * per-vertex errors, and the two body datasets with ground truth (synth
 * generated in the run, and ../shared/data/mh-bodies when present). */
#ifndef MIM_BENCH_DATA_H
#define MIM_BENCH_DATA_H

#include "mim_core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct bench_dataset {
    const char *name;
    uint32_t n, n_faces, subjects, poses;
    uint32_t *faces;
    mim_landmark_map_t map;
    float **pos; /* [s * poses + p], 3 * n floats */
} bench_dataset_t;

/* The 1-minute load average (/proc/loadavg), -1 when unknown: printed
 * beside figures measured on a shared machine. */
double bench_load_average(void);

/* Median of v[0..k) (sorts v), and the q-quantile (0..1). */
double bench_median(double *v, int k);
double bench_quantile(double *v, int k, double q);

/* Per-vertex errors in mm pooled over many meshes: the sum for the mean and
 * a histogram of 0.01 mm bins up to 2 m for the p95 (larger errors fall in
 * the last bin). */
#define BENCH_ERR_BINS 200000
typedef struct bench_err {
    double sum;
    uint64_t count;
    uint32_t *hist;
} bench_err_t;
int bench_err_init(bench_err_t *e); /* 0, or -1 out of memory */
void bench_err_free(bench_err_t *e);
void bench_err_add_mm(bench_err_t *e, double mm);
/* Adds |x_i - truth_i| (metres in, mm pooled) of n vertices; e_mm (n, may
 * be NULL) gets each vertex's error in mm. */
void bench_err_add(bench_err_t *e, const float *x, const float *truth, uint32_t n, double *e_mm);
double bench_err_mean(const bench_err_t *e);
double bench_err_p95(const bench_err_t *e);
/* synth: subjects x poses at about `vertices` vertices (seed 1). */
int bench_load_synth(bench_dataset_t *d, uint32_t subjects, uint32_t poses, uint32_t vertices);
/* The imitation set (issue 29): the same subjects, each taking each pose
 * its own way (mim_synth_options_t's imitation_deg, sigma_deg per joint
 * axis), named "imitation"; sigma 0 is synth itself. */
int bench_load_imitation(bench_dataset_t *d, uint32_t subjects, uint32_t poses, uint32_t vertices, double sigma_deg);
/* How far the same pose lies between two subjects: over every pose but
 * the rest and every pair of subjects, the landmark sets rigidly aligned,
 * the angle between each bone of the landmark skeleton: the rms over all
 * (degrees) and the 10th and 90th percentiles of the pairs' rms. 0, or -1
 * (no pair, or not the default landmarks). */
int bench_pose_spread(const bench_dataset_t *d, double *rms, double *p10, double *p90);
/* The imitation spread per joint axis that gives the same pose across
 * subjects about 11 degrees rms per bone (bench_pose_spread on it). */
#define BENCH_IMITATION_DEG 3.5
/* (The environment's BENCH_SEED draws the imitation set with another seed,
 * BENCH_TISSUE_MM and BENCH_SLIDE_MM change its tissue and slide: for
 * calibration and for checking a default on other draws only.) */
/* and their pose-dependent soft tissue (mim_synth_options_t's tissue_mm) */
#define BENCH_TISSUE_MM 4.0
/* and the registration error of a store of scans (slide_mm: 22 mm slides its vertices 18 mm on
 * average, as registering re-meshed real scans does: 17.4 mm mean on held-out scans) */
#define BENCH_SLIDE_MM 22.0
/* mh-bodies: 8 x 12 PLY files from dir; 1 when the folder is absent. */
int bench_load_mh(bench_dataset_t *d, const char *dir);
void bench_dataset_free(bench_dataset_t *d);
/* The mh-bodies folder: $MIMIC_SHARED_DATA/mh-bodies, else the source
 * tree's sibling ../shared/data/mh-bodies. */
const char *bench_mh_dir(char *buf, size_t size);

/* Body regions the accuracy benches report by: a vertex's region is its
 * heaviest segment's (mim_segment_names order): head; hands; feet; torso
 * (pelvis, chest, shoulders); limbs (upper arms, forearms, thighs, shins). */
enum { BENCH_REGION_HEAD, BENCH_REGION_HANDS, BENCH_REGION_FEET, BENCH_REGION_TORSO, BENCH_REGION_LIMBS, BENCH_REGIONS };
extern const char *const bench_region_names[BENCH_REGIONS];
int bench_region_of_segment(uint32_t segment);

/* The options every body-set bench takes: --vertices N (synth, default
 * 7000), --mh DIR, --no-mh, --imitation DEG (default
 * BENCH_IMITATION_DEG), --no-imitation. */
typedef struct bench_sets {
    uint32_t vertices;
    const char *mh;
    int no_mh;
    double imitation_deg;
    char mh_buf[4096];
} bench_sets_t;
void bench_sets_init(bench_sets_t *s);
/* Takes argv[*i] (and its value) if it is one of those; 1 if taken. */
int bench_sets_arg(bench_sets_t *s, int argc, char **argv, int *i);
/* Runs fn on synth (subjects x poses), on the imitation set of the same
 * subjects unless --no-imitation, then on mh-bodies unless --no-mh
 * (a line says when it is absent). 0, or 1 when loading or fn failed. */
typedef int (*bench_set_fn)(const bench_dataset_t *d, void *user);
int bench_sets_run(bench_sets_t *s, uint32_t subjects, uint32_t poses, bench_set_fn fn, void *user);

#ifdef __cplusplus
}
#endif
#endif
