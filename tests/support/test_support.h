/* Shared helpers for mimic's tests: temp folders, running the mimic binary,
 * and test data generators (meshes in every format, corrupted variants). */
#ifndef MIM_TEST_SUPPORT_H
#define MIM_TEST_SUPPORT_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "mim_core.h"

/* A fresh folder under $TMPDIR (or /tmp); removed by ts_rmtree. */
char *ts_tempdir(const char *tag);
void ts_rmtree(const char *path);
/* Joins dir and name into a static-lifetime-free malloc'd string. */
char *ts_path(const char *dir, const char *name);

/* Runs `$MIMIC_BIN args...` (args is a shell-free argv, NULL-terminated).
 * Captures stdout and stderr (malloc'd, NUL-terminated; may be NULL args). */
int ts_run_mimic(char **out, char **err, const char *const *args);
/* Runs mimic, fails the test unless it exits `want`; returns its stdout
 * (malloc'd) and, when err is not NULL, its stderr (malloc'd, else freed). */
char *ts_mimic_expect(int want, char **err, const char *const *args);
/* The same, and the peak resident size of the mimic process in KiB (its
 * ru_maxrss; the fork's copy of this process counts too, so compare two
 * runs from the same state). */
int ts_run_mimic_peak(char **out, char **err, const char *const *args, long *peak_kib);
const char *ts_mimic_bin(void);
/* ../shared/data beside the project ($MIMIC_SHARED_DATA overrides). */
const char *ts_shared_data(void);

/* The Khronos glTF validator (npm gltf-validator, which build.sh installs):
 * available = node and the package are there (else prints why, for a skip);
 * validate asserts zero errors and zero warnings for the file. */
int ts_gltf_validator_available(void);
/* Runs a shell command; its stdout (malloc'd) and exit status. */
char *ts_run_capture(const char *cmd, int *status);
void ts_gltf_validate(const char *path);

/* Reads a whole file (malloc'd, NUL-terminated); NULL if it cannot. */
char *ts_read_file(const char *path, size_t *len);
int ts_write_file(const char *path, const void *data, size_t len);
/* Shortens a file to `keep` bytes. */
int ts_truncate(const char *path, size_t keep);

/* ---- test meshes ---- */
/* A closed lat-long sphere of radius r: triangle fans at the poles, quads
 * elsewhere (so readers must triangulate). Polygons are returned as a flat
 * index list with per-polygon sizes. */
typedef struct ts_polymesh {
    uint32_t n_vertices, n_polys;
    float *pos;        /* 3 * n_vertices */
    uint32_t *sizes;   /* n_polys */
    uint32_t *idx;     /* sum of sizes */
    uint32_t n_idx;
} ts_polymesh_t;
void ts_sphere(ts_polymesh_t *m, uint32_t rings, uint32_t segments, float r);
void ts_polymesh_free(ts_polymesh_t *m);
/* Number of triangles after fan triangulation. */
uint32_t ts_polymesh_triangles(const ts_polymesh_t *m);
/* A triangle-only copy (fan triangulation), as mim_io_read_mesh returns it. */
void ts_triangulate(const ts_polymesh_t *m, mim_mesh_t *out);

int ts_write_off(const char *path, const ts_polymesh_t *m);
int ts_write_ply_ascii(const char *path, const ts_polymesh_t *m);
int ts_write_ply_binary(const char *path, const ts_polymesh_t *m);
int ts_write_obj(const char *path, const ts_polymesh_t *m);
int ts_write_stl_ascii(const char *path, const ts_polymesh_t *m);  /* triangles */
int ts_write_stl_binary(const char *path, const ts_polymesh_t *m); /* triangles */
/* glTF 2.0: a GLB, or a .gltf with the buffer embedded as a data URI. */
int ts_write_glb(const char *path, const ts_polymesh_t *m);
int ts_write_gltf(const char *path, const ts_polymesh_t *m);
/* A skinned GLB, written by hand: one mesh with one primitive (POSITION
 * with min/max, indices, JOINTS_0, WEIGHTS_0), node 0 the mesh with skin 0,
 * nodes 1..n_joints the joints (named joint_names[j]; a NULL array or
 * entry: no name), the first of them the parent of the others, and skin 0
 * with those joints (no inverseBindMatrices). joints and weights hold 4 per
 * vertex and are written as given (bad values too, for hostile tests).
 * weight_type: 0 float, 1 normalised unsigned byte, 2 normalised unsigned
 * short (w * 255 resp. w * 65535, rounded); OR TS_SKIN_JOINTS_U8 for
 * JOINTS_0 as unsigned byte (else unsigned short). JSON layout (for tests
 * that patch it): the JOINTS_0 accessor is written
 * {"bufferView":2,"componentType":5123,"count":N,... and skin 0 as
 * "skins":[{"joints":[1,2,...]}]. Returns 0 or -1. */
#define TS_SKIN_JOINTS_U8 16
int ts_write_skinned_glb(const char *path, const mim_mesh_t *m, const char *const *joint_names, uint32_t n_joints,
                         const uint16_t *joints, const float *weights, int weight_type);
/* Writes a triangle mesh as binary PLY (as mimic synth does). */
int ts_write_mesh_ply(const char *path, const mim_mesh_t *m);

#endif
