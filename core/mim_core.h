/* mimic core: what every module shares and nothing else.
 * Error codes and mim_strerror, an error context with detail, the mesh
 * arrays type, reading and atomically writing files, the landmark map and
 * the landmark-array parser, the seeded random generator, hashing, small
 * vector/quaternion/matrix math, and the log and progress callbacks through
 * which libraries report (only cli/ prints).
 * Uses nothing of mimic. */
#ifndef MIM_CORE_H
#define MIM_CORE_H

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MIM_VERSION "0.1.0"

/* ---- errors: 0 on success, negative MIM_E* codes, or -errno ---- */
enum {
    MIM_OK = 0,
    MIM_EINVAL = -1000,  /* bad argument from the caller */
    MIM_ENOMEM,          /* allocation failed */
    MIM_EIO,             /* read or write failed */
    MIM_EFORMAT,         /* malformed file or record */
    MIM_ETRUNCATED,      /* file ends early */
    MIM_ENONFINITE,      /* NaN or infinite coordinate */
    MIM_EINDEX,          /* face index past the vertex count */
    MIM_EEMPTY,          /* mesh without vertices or faces */
    MIM_ETOPOLOGY,       /* connectivity differs from the store's */
    MIM_ESCHEMA,         /* store of another schema version */
    MIM_ESTORE,          /* store error (LMDB) */
    MIM_ENOTFOUND,       /* no such record or file */
    MIM_EUNSUPPORTED,    /* format or feature not supported */
    MIM_ENOLANDMARKS,    /* no landmark map where one is needed */
    MIM_ENOINDEX,        /* the store has no recognition index where one is needed */
    MIM_ELAST_
};

const char *mim_strerror(int err);

/* An error context keeps the first error and a one-line message with detail
 * (file, line, which vertex ...). Zero-initialise before use. */
typedef struct mim_error {
    int code;
    char msg[512];
} mim_error_t;

/* Records err (if none is recorded yet) and returns code, so callers can
 * write `return mim_error_set(e, MIM_EFORMAT, "%s: ...", path);`.
 * e may be NULL. */
int mim_error_set(mim_error_t *e, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
void mim_error_clear(mim_error_t *e);
/* The message if one was set, else mim_strerror(code). */
const char *mim_error_text(const mim_error_t *e);

/* ---- mesh arrays: triangles only, float32 positions ---- */
typedef struct mim_mesh {
    uint32_t n_vertices;
    uint32_t n_faces;
    float *positions; /* 3 * n_vertices, x y z */
    uint32_t *faces;  /* 3 * n_faces, counter-clockwise seen from outside */
} mim_mesh_t;

int mim_mesh_alloc(mim_mesh_t *m, uint32_t n_vertices, uint32_t n_faces);
void mim_mesh_free(mim_mesh_t *m); /* accepts a zeroed mesh; zeroes it */

/* ---- files ---- */
/* Reads a file into a NUL-terminated buffer (*text, malloc'd, the caller
 * frees; *len excludes the NUL). max_bytes 0 reads it all; otherwise at most
 * max_bytes, the head of a longer file (to refuse a longer file, ask for one
 * byte more than allowed and check *len). Errors, one line naming the path:
 * cannot open (-errno), read error (MIM_EIO), out of memory (MIM_ENOMEM). */
int mim_file_read(const char *path, size_t max_bytes, char **text, size_t *len, mim_error_t *err);
/* Writes the parts, one after the other, to path so that path holds either
 * its old content or the whole new one, whatever fails or crashes: a
 * temporary beside it (PATH.tmp.PID.N), fsync, rename over path, fsync of
 * the folder. Safe to call from many threads. On failure the temporary is
 * removed. Errors, one line naming the path and the system's reason:
 * MIM_EIO (cannot create, write, sync or rename), MIM_ENOMEM. */
typedef struct mim_file_part {
    const void *data;
    size_t size;
} mim_file_part_t;
int mim_file_write_atomic(const char *path, const mim_file_part_t *parts, size_t n_parts, mim_error_t *err);
/* fsync of path (a file, or a folder for the names in it), and of the
 * folder that holds path (so that a rename into it survives a crash as
 * the file's bytes do). 0 or an errno; a file system that cannot sync a
 * folder counts as done. */
int mim_file_sync(const char *path);
int mim_file_sync_folder(const char *path);

/* ---- landmark map: which vertex is each landmark, and the mirror table ----
 * File format (DESIGN.md, schemas/landmarks.schema.json):
 * {"topology_vertices": N, "landmarks": [{"name": "head", "vertex": 412}, ...],
 *  "mirror": [0, 1, 2, 4, 3, ...]}
 * Any map with >= 4 landmarks and a mirror table (an involution) works. */
#define MIM_LANDMARKS_MIN 4
#define MIM_LANDMARKS_MAX 64
#define MIM_LANDMARK_NAME_MAX 32
#define MIM_LANDMARKS_DEFAULT_COUNT 16

typedef struct mim_landmark_map {
    uint32_t count;
    uint32_t topology_vertices;
    char names[MIM_LANDMARKS_MAX][MIM_LANDMARK_NAME_MAX];
    uint32_t vertex[MIM_LANDMARKS_MAX];
    uint32_t mirror[MIM_LANDMARKS_MAX]; /* mirror[i]: landmark i seen left<->right */
} mim_landmark_map_t;

/* head, chest, pelvis, l_shoulder, r_shoulder, l_elbow, r_elbow, l_wrist,
 * r_wrist, l_hip, r_hip, l_knee, r_knee, l_ankle, r_ankle, spine */
extern const char *const mim_landmark_default_names[MIM_LANDMARKS_DEFAULT_COUNT];
/* The 17 body segments of the vest (one sensor each; vest/ numbers them
 * in this order): pelvis, chest, head, l_shoulder, r_shoulder, l_upperarm,
 * r_upperarm, l_forearm, r_forearm, l_hand, r_hand, l_thigh, r_thigh,
 * l_shin, r_shin, l_foot, r_foot. Orientations in landmark frames are
 * keyed by these names. */
#define MIM_SEGMENTS 17
extern const char *const mim_segment_names[MIM_SEGMENTS];
/* A segment's parent in the body's tree (parents have lower ids); -1 for
 * the pelvis and out of range. */
int mim_segment_parent(uint32_t s);
/* The index of the landmark called name in map, or -1. */
int mim_landmarks_find(const mim_landmark_map_t *map, const char *name);
/* The landmark skeleton (landmarks.c): the 16 default landmarks as a tree
 * of 15 bones rooted at the pelvis (pelvis-spine-chest-head,
 * chest-shoulder-elbow-wrist, pelvis-hip-knee-ankle), each bone a child
 * landmark and its parent as map indices, parents before children. 0, or
 * MIM_EUNSUPPORTED when the map is not the 16 default landmarks (*missing
 * then names the first one it lacks; NULL when its count is not 16). */
#define MIM_LANDMARK_BONES 15
int mim_landmark_skeleton(const mim_landmark_map_t *map, int child[MIM_LANDMARK_BONES],
                          int parent[MIM_LANDMARK_BONES], const char **missing);
/* Fills the 16 default names and their mirror table with the given vertices. */
void mim_landmarks_default(mim_landmark_map_t *map, const uint32_t vertices[MIM_LANDMARKS_DEFAULT_COUNT],
                           uint32_t topology_vertices);
/* Parse from text; origin names the source in messages ("path" or "store"). */
int mim_landmarks_parse(mim_landmark_map_t *map, const char *text, size_t len, const char *origin,
                        mim_error_t *err);
int mim_landmarks_read(mim_landmark_map_t *map, const char *path, mim_error_t *err);
/* Serialise as JSON text (malloc'd, NUL-terminated; caller frees). */
char *mim_landmarks_to_json(const mim_landmark_map_t *map);
/* Writes the JSON and a newline atomically (mim_file_write_atomic). */
int mim_landmarks_write(const mim_landmark_map_t *map, const char *path, mim_error_t *err);
/* Checks count, mirror involution, vertices < n_vertices (if n_vertices > 0). */
int mim_landmarks_validate(const mim_landmark_map_t *map, uint32_t n_vertices, const char *origin,
                           mim_error_t *err);

/* ---- landmark frames: tracked landmark positions, one frame or a batch ----
 * File format (schemas/landmark-frames.schema.json), in landmark map order:
 * {"frames": [{"landmarks": [[x, y, z] | null, ...]}, ...]} or, for one
 * frame, {"landmarks": [...]}. null marks a lost landmark. A frame may add
 * "orientations": {"pelvis": [x, y, z, w] | null, ...}, keyed by
 * mim_segment_names (any subset; null: the sensor is lost). */
typedef struct mim_landmark_frames {
    uint32_t n_frames, n_landmarks;
    float *positions; /* n_frames * n_landmarks * 3; NaN where missing */
    uint8_t *present; /* n_frames * n_landmarks: 1 present, 0 missing (null) */
    /* A frame's optional "orientations" (issue 17): per vest segment
     * (MIM_SEGMENTS, mim_segment_names order) the rotation from the avatar's
     * rest mesh to the pose, in the avatar's frame. NULL when no frame has
     * any. orientations: n_frames * MIM_SEGMENTS * 4 doubles (x y z w),
     * identity where not given; orient_present: n_frames * MIM_SEGMENTS,
     * 1 given, 0 null or absent (a frame without the object: all 0). */
    double *orientations;
    uint8_t *orient_present;
} mim_landmark_frames_t;
/* Errors, one line each: malformed JSON with file:line:column
 * (MIM_EFORMAT); a frame whose landmark count differs from n_landmarks, a
 * coordinate that is not a number, or more than max_missing nulls in a
 * frame (MIM_EFORMAT, naming the frame and landmark); a number that is not
 * a finite float (MIM_ENONFINITE); a frame that is no body
 * (mim_landmarks_check, MIM_EFORMAT); bad orientations
 * (mim_orientations_parse's errors), or "orientations" in a frame without
 * "landmarks" or beside "frames" (MIM_EFORMAT); a file that cannot be
 * opened (MIM_ENOTFOUND/MIM_EIO). The text is read as a stream: memory is
 * one frame (and, for _read and _parse, the frames gathered: 13 bytes a
 * landmark), never a tree of the text. JSON is taken as jansson takes it
 * (strict RFC 8259), except that members other than "frames",
 * "landmarks" and "orientations" are checked for syntax only (two
 * members of such a name are not an error) and a number may have at most
 * 512 characters. The first error stops the reading.
 * mim_landmark_frames_read (and _scan_file) takes at most
 * MIM_LANDMARK_FRAMES_MAX_BYTES (64 MiB, about 100 000 frames of 16
 * landmarks: half an hour at 60 Hz); a longer file (or stream) is refused
 * with a message naming its size and the limit (MIM_EUNSUPPORTED): split
 * it. On error *out is left empty. */
#define MIM_LANDMARK_FRAMES_MAX_BYTES ((size_t)64 << 20)
int mim_landmark_frames_read(const char *path, uint32_t n_landmarks, uint32_t max_missing,
                             mim_landmark_frames_t *out, mim_error_t *err);
int mim_landmark_frames_parse(const char *text, size_t len, const char *origin, uint32_t n_landmarks,
                              uint32_t max_missing, mim_landmark_frames_t *out, mim_error_t *err);
/* The same frames one at a time: fn has each as soon as it is read and
 * checked, in order (the pointers are valid during the call), so that a
 * batch of any length takes the memory of one frame. A nonzero return
 * from fn stops the scan and is returned (fn records its error in err).
 * Frames before an error in the text have been handed out: a caller that
 * answers all or nothing waits for the scan's 0. */
typedef struct mim_landmark_frame {
    uint32_t index;               /* from 0, in the text's order */
    uint32_t n_landmarks;
    const float *positions;       /* n_landmarks * 3; NaN where missing */
    const uint8_t *present;       /* n_landmarks: 1 present, 0 null */
    const double *orientations;   /* MIM_SEGMENTS * 4 as in mim_landmark_frames_t; NULL: the frame has none */
    const uint8_t *orient_present; /* MIM_SEGMENTS; NULL with orientations */
} mim_landmark_frame_t;
typedef int (*mim_landmark_frame_fn)(void *user, const mim_landmark_frame_t *frame, mim_error_t *err);
int mim_landmark_frames_scan(const char *text, size_t len, const char *origin, uint32_t n_landmarks,
                             uint32_t max_missing, mim_landmark_frame_fn fn, void *user, mim_error_t *err);
int mim_landmark_frames_scan_file(const char *path, uint32_t n_landmarks, uint32_t max_missing,
                                  mim_landmark_frame_fn fn, void *user, mim_error_t *err);
void mim_landmark_frames_free(mim_landmark_frames_t *f); /* accepts NULL and an empty set */

/* A landmark file for one mesh (landmark_file.c), of either form: a
 * landmark MAP (MIM_LANDMARK_FILE_MAP: it has "topology_vertices", or its
 * landmarks are {"name", "vertex"} objects), parsed into map as
 * mim_landmarks_parse does and holding n_landmarks landmarks; or ONE frame
 * of landmark POSITIONS (MIM_LANDMARK_FILE_POSITIONS: {"landmarks":
 * [[x, y, z], ...]} or {"frames": [one frame]}), n_landmarks of them, all
 * present, into positions (3 * n_landmarks floats). Only the output of the
 * kind found is written. Errors, one line naming path: malformed JSON
 * (path:line:column, MIM_EFORMAT); more than one frame ("PATH: 3 frames: a
 * landmark file for one mesh holds one"); a null landmark, named when
 * n_landmarks is 16 ("PATH: landmark 3 (l_shoulder) is missing:
 * registration needs all of them"); a map of another count; then the map's
 * and the frames parser's errors; a file over
 * MIM_LANDMARK_FRAMES_MAX_BYTES (MIM_EUNSUPPORTED); one that cannot be
 * opened (MIM_ENOTFOUND/MIM_EIO); MIM_EINVAL for bad arguments. */
typedef enum { MIM_LANDMARK_FILE_MAP = 1, MIM_LANDMARK_FILE_POSITIONS = 2 } mim_landmark_file_kind_t;
int mim_landmark_file_read(const char *path, uint32_t n_landmarks, mim_landmark_file_kind_t *kind,
                           mim_landmark_map_t *map, float *positions, mim_error_t *err);

/* One landmark array, [[x, y, z] | null, ...] (a jansson value: the
 * landmark-frames files, vest UDP datagrams), into positions (3 * n floats,
 * NaN where null) and present (n: 1 present, 0 null). Messages begin with
 * origin, then ": frame F" when frame >= 0, and name the landmark and
 * coordinate. Errors: not an array of n entries, an entry that is not
 * [x, y, z] or null, a coordinate that is not a number, more than
 * max_missing nulls (MIM_EFORMAT); a number that is not a finite float
 * (MIM_ENONFINITE); landmarks that are no body (mim_landmarks_check below:
 * MIM_EFORMAT). On error positions and present are partly written. */
struct json_t;
int mim_landmark_array_parse(const struct json_t *array, uint32_t n, uint32_t max_missing, const char *origin,
                             long frame, float *positions, uint8_t *present, mim_error_t *err);
/* One "orientations" object (a jansson value: landmark frames, vest UDP
 * datagrams) into q (MIM_SEGMENTS * 4 doubles x y z w, mim_segment_names
 * order, normalised; identity where null or absent) and have (MIM_SEGMENTS:
 * 1 given). Messages begin as mim_landmark_array_parse's and name the
 * segment. Errors: not an object, a key that is no segment name, a value
 * neither null nor [x, y, z, w] of numbers, a norm off 1 by more than
 * MIM_ORIENT_UNIT_TOL (MIM_EFORMAT); a number that is not finite
 * (MIM_ENONFINITE). On error q and have are partly written. */
#define MIM_ORIENT_UNIT_TOL 1e-3
int mim_orientations_parse(const struct json_t *obj, const char *origin, long frame, double *q, uint8_t *have,
                           mim_error_t *err);

/* ---- plausibility: what a body and a landmark skeleton can be (plausible.c) ----
 * The one statement of the range; positions are in metres.
 * - A body fits in a 10 m box: its positions span at most
 *   MIM_PLAUSIBLE_BOX_M along each axis (3e38 among a body's coordinates,
 *   or a mesh in millimetres, is outside it).
 * - It lies within MIM_PLAUSIBLE_REACH_M (1 km) of the origin, where
 *   float32 still resolves 0.1 mm.
 * - It is not a point: its positions span at least
 *   MIM_PLAUSIBLE_MIN_SPAN_M (10 mm) along the widest axis.
 * - Coordinates are finite.
 * Landmarks follow the same rules over the present ones (nulls are left
 * out; a frame without any passes: a vest may lose them all), with the
 * minimum span asked of 3 or more present landmarks (two may touch), and
 * no two present landmarks at one point: the pose descriptor's angles are
 * between the segments joining landmarks, and a segment of length zero has
 * no direction (16 identical landmarks leave no angle at all).
 * Meshes are checked where a body enters (ingest, the session's avatar),
 * not by the readers, which read any mesh; landmarks in
 * mim_landmark_array_parse, which every landmark input goes through.
 * Both return 0, or MIM_ENONFINITE / MIM_EFORMAT (MIM_EEMPTY: no
 * vertices) with one line: "origin: vertex 12: coordinate y = 3e+38
 * outside the 10 m box a body fits in (...)", "origin: frame 3: landmarks
 * span 0.0 mm: not a body (at least 10 mm)". present may be NULL (all
 * present); frame < 0 leaves ": frame F" out. */
#define MIM_PLAUSIBLE_BOX_M 10.0
#define MIM_PLAUSIBLE_REACH_M 1000.0
#define MIM_PLAUSIBLE_MIN_SPAN_M 0.01
int mim_body_check(const float *positions, uint32_t n, const char *origin, mim_error_t *err);
int mim_landmarks_check(const float *positions, const uint8_t *present, uint32_t n, const char *origin, long frame,
                        mim_error_t *err);

/* ---- random numbers: one seeded generator, explicit state (random.c) ---- */
typedef struct mim_rng {
    uint64_t s;
} mim_rng_t;
/* Seeds r for stream `stream` of seed: streams of one seed are independent,
 * so each item (a subject, a fold, a chain) can draw from its own. */
void mim_rng_seed(mim_rng_t *r, uint64_t seed, uint64_t stream);
uint64_t mim_rng_u64(mim_rng_t *r);
double mim_rng_unit(mim_rng_t *r);               /* uniform in [0, 1) */
uint64_t mim_rng_below(mim_rng_t *r, uint64_t n); /* uniform in [0, n); 0 for n <= 1 */
double mim_rng_gauss(mim_rng_t *r);              /* standard normal */

/* ---- hashing: 64-bit, fast, stable across runs and machines ---- */
uint64_t mim_hash64(const void *data, size_t len, uint64_t seed);

/* ---- small vector and quaternion math (double) ---- */
typedef struct { double x, y, z; } mim_vec3;
typedef struct { double x, y, z, w; } mim_quat; /* unit quaternion */

static inline mim_vec3 mim_v3(double x, double y, double z) { mim_vec3 r = {x, y, z}; return r; }
static inline mim_vec3 mim_v3_add(mim_vec3 a, mim_vec3 b) { return mim_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline mim_vec3 mim_v3_sub(mim_vec3 a, mim_vec3 b) { return mim_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline mim_vec3 mim_v3_scale(mim_vec3 a, double s) { return mim_v3(a.x * s, a.y * s, a.z * s); }
static inline double mim_v3_dot(mim_vec3 a, mim_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline mim_vec3 mim_v3_cross(mim_vec3 a, mim_vec3 b)
{
    return mim_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
double mim_v3_norm(mim_vec3 a);
mim_vec3 mim_v3_normalize(mim_vec3 a); /* zero vector stays zero */
static inline mim_vec3 mim_v3_lerp(mim_vec3 a, mim_vec3 b, double t)
{
    return mim_v3(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, a.z + (b.z - a.z) * t);
}

mim_quat mim_quat_identity(void);
mim_quat mim_quat_axis_angle(mim_vec3 axis, double radians);
/* The shortest-arc rotation that turns direction a onto direction b (their
 * lengths do not matter; identity when either is zero). */
mim_quat mim_quat_between(mim_vec3 a, mim_vec3 b);
mim_quat mim_quat_mul(mim_quat a, mim_quat b); /* a then... : rotates by b first, then a */
mim_quat mim_quat_normalize(mim_quat q);
mim_vec3 mim_quat_rotate(mim_quat q, mim_vec3 v);

/* ---- signed coordinate axes (axis.c): a motion file's up axis ---- */
/* An axis is +x 1, +y 2, +z 3, -x -1, -y -2, -z -3 (0: none). */
/* "x", "+x", "-z", ... (either case) into *axis: 0, or -1. */
int mim_axis_parse(const char *s, int *axis);
/* "+x" ... "-z", or "none". */
const char *mim_axis_name(int axis);
/* The signed axis nearest to v, or 0 when v is zero or its largest
 * component is under min_share of its length (no clear axis). */
int mim_axis_snap(mim_vec3 v, double min_share);
/* Turns the point p (a file's coordinates) so that the file's `up` axis
 * becomes +y: a quarter turn about x for +z (x, y, z -> x, z, -y) and -z
 * (x, -z, y), about z for +x (-y, x, z) and -x (y, -x, z), a half turn
 * about x for -y (x, -y, -z); +y as it is. Exact: only swaps and signs. */
void mim_axis_stand_up(int up, double p[3]);

/* Rotation matrices are 9 doubles, column-major: m[3 * c + r] is row r of
 * column c, so the columns are the images of the x, y and z axes (a local
 * frame f1 f2 f3 stored one column after the other).
 * mim_quat_from_matrix: the unit quaternion of a rotation matrix (Shepperd's
 * method: it branches on the largest diagonal term, accurate for every
 * rotation). */
mim_quat mim_quat_from_matrix(const double m[9]);

/* Horn's closed form (J. Opt. Soc. Am. A 4(4), 1987): the rotation that
 * best turns centred points x onto centred points y (least squares),
 * given M[r][c] = sum x_r y_c. Its unit quaternion is the top eigenvector
 * of a symmetric 4 x 4 matrix made of M (Newton's method on its
 * characteristic polynomial, cyclic Jacobi rotations where its top
 * eigenvalues nearly meet; no library), so it is a rotation by
 * construction, never a reflection. The identity when M is not finite. */
mim_quat mim_quat_best_rotation(const double M[3][3]);

/* The rotation matrix of a unit quaternion. Inline: transfer's morph turns
 * a quaternion into a frame per vertex per frame. */
static inline void mim_quat_to_matrix(mim_quat q, double m[9])
{
    double x = q.x, y = q.y, z = q.z, w = q.w;
    m[0] = 1 - 2 * (y * y + z * z), m[1] = 2 * (x * y + z * w), m[2] = 2 * (x * z - y * w);
    m[3] = 2 * (x * y - z * w), m[4] = 1 - 2 * (x * x + z * z), m[5] = 2 * (y * z + x * w);
    m[6] = 2 * (x * z + y * w), m[7] = 2 * (y * z - x * w), m[8] = 1 - 2 * (x * x + y * y);
}

/* v turned by the rotation of q / |q| (q not zero): v + w t + u x t with
 * t = 2 (u x v) / |q|^2, u the vector part. A blend of unit quaternions
 * turns vectors so without being normalised: a division, no square root.
 * Inline for the per-vertex loops of transfer's drives. */
static inline mim_vec3 mim_quat_rotate_unnormalized(mim_quat q, mim_vec3 v)
{
    const double s = 2.0 / (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    const double tx = s * (q.y * v.z - q.z * v.y), ty = s * (q.z * v.x - q.x * v.z), tz = s * (q.x * v.y - q.y * v.x);
    return mim_v3(v.x + q.w * tx + (q.y * tz - q.z * ty), v.y + q.w * ty + (q.z * tx - q.x * tz),
                  v.z + q.w * tz + (q.x * ty - q.y * tx));
}

/* Spherical interpolation along the shorter arc, renormalised; linear when
 * the two are within ~1.8 degrees (sin of the angle is too small to divide
 * by). Inline for the same hot path as mim_quat_to_matrix. */
static inline mim_quat mim_quat_slerp(mim_quat a, mim_quat b, double t)
{
    double d = a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w, sb = 1.0;
    if (d < 0.0) /* q and -q are one rotation: take the short way */
        d = -d, sb = -1.0;
    double wa, wb;
    if (d > 0.9995) {
        wa = 1.0 - t, wb = t;
    } else {
        double th = acos(d), s = sin(th);
        wa = sin((1.0 - t) * th) / s, wb = sin(t * th) / s;
    }
    wb *= sb;
    mim_quat r = {wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z, wa * a.w + wb * b.w};
    double inv = 1.0 / sqrt(r.x * r.x + r.y * r.y + r.z * r.z + r.w * r.w);
    r.x *= inv, r.y *= inv, r.z *= inv, r.w *= inv;
    return r;
}

/* ---- time ---- */
double mim_now(void); /* monotonic seconds */

/* ---- log and progress: libraries report through callbacks, cli/ prints ----
 * Libraries never write to stdout or stderr; their options take these
 * callbacks (NULL: quiet) and hand them what a user should hear. */
enum { MIM_LOG_ERROR = 0, MIM_LOG_WARN = 1, MIM_LOG_INFO = 2 };
/* msg is one line without a newline or prefix, valid during the call. A
 * library may call it from its own threads (serve's vest loop, ...). */
typedef void (*mim_log_fn)(void *ctx, int level, const char *msg);
/* Formats one line and hands it to fn; nothing when fn is NULL. */
void mim_log_emit(mim_log_fn fn, void *ctx, int level, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* Progress on long work: BEGIN once (done 0), STEP as work gets done, END
 * once (also after a failure). total is 0 when unknown. Rate limiting is
 * the callback's business: a STEP may come for every item. */
enum { MIM_PROGRESS_BEGIN, MIM_PROGRESS_STEP, MIM_PROGRESS_END };
typedef void (*mim_progress_fn)(void *ctx, int phase, const char *label, uint64_t done, uint64_t total);

/* One run of progress reporting: set fn and ctx (fn NULL: quiet), then
 * begin, update, end; begin keeps fn and ctx. Updates outside begin..end
 * and a second end call nothing. */
typedef struct mim_progress {
    mim_progress_fn fn;
    void *ctx;
    const char *label;
    uint64_t total; /* 0 when unknown */
    uint64_t done;
    int active;     /* between begin and end */
} mim_progress_t;
void mim_progress_begin(mim_progress_t *p, const char *label, uint64_t total);
void mim_progress_update(mim_progress_t *p, uint64_t done);
void mim_progress_end(mim_progress_t *p);

#ifdef __cplusplus
}
#endif
#endif
