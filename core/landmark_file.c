/* A landmark file beside one mesh, in either of its two forms: a landmark
 * MAP naming the mesh's vertex of each landmark (landmarks.c's format,
 * with "topology_vertices") or ONE frame of landmark POSITIONS on it
 * (landmark_frames.c's format). Registration takes either. The kind is
 * told from the JSON's shape, then the file's text goes to the parser of
 * that kind, so each format keeps one parser and one set of messages. */
#include "mim_core.h"

#include <errno.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* MIM_LANDMARK_FILE_MAP or _POSITIONS, or an error: malformed JSON (with
 * line and column), or a positions file of more than one frame (refused
 * here, before the frames parser would read and check every frame). */
static int classify(const char *path, const char *text, size_t len, mim_error_t *err)
{
    json_error_t je;
    json_t *root = json_loadb(text, len, 0, &je);
    if (!root)
        return mim_error_set(err, MIM_EFORMAT, "%s:%d:%d: %s", path, je.line, je.column, je.text);
    json_t *lm = json_object_get(root, "landmarks");
    json_t *frames = json_object_get(root, "frames");
    /* A map's landmarks are objects ({"name", "vertex"}); a frame's are
     * [x, y, z] or null: a map without "topology_vertices" is still one. */
    int is_map = json_object_get(root, "topology_vertices") || json_is_object(json_array_get(lm, 0));
    size_t nf = json_array_size(frames);
    json_decref(root);
    if (!is_map && nf > 1)
        return mim_error_set(err, MIM_EFORMAT, "%s: %zu frames: a landmark file for one mesh holds one", path, nf);
    return is_map ? MIM_LANDMARK_FILE_MAP : MIM_LANDMARK_FILE_POSITIONS;
}

static int read_map(const char *path, const char *text, size_t len, uint32_t n, mim_landmark_map_t *map,
                    mim_error_t *err)
{
    int rc = mim_landmarks_parse(map, text, len, path, err);
    if (rc)
        return rc;
    if (map->count != n)
        return mim_error_set(err, MIM_EFORMAT, "%s: landmark map has %u landmarks, %u expected", path, map->count,
                             n);
    return 0;
}

static int read_positions(const char *path, const char *text, size_t len, uint32_t n, float *positions,
                          mim_error_t *err)
{
    mim_landmark_frames_t f;
    /* All nulls pass the parser, so that the first one is named below. */
    int rc = mim_landmark_frames_parse(text, len, path, n, n, &f, err);
    if (rc)
        return rc;
    for (uint32_t i = 0; i < n && !rc; i++) {
        if (f.present[i])
            continue;
        if (n == MIM_LANDMARKS_DEFAULT_COUNT)
            rc = mim_error_set(err, MIM_EFORMAT, "%s: landmark %u (%s) is missing: registration needs all of them",
                               path, i, mim_landmark_default_names[i]);
        else
            rc = mim_error_set(err, MIM_EFORMAT, "%s: landmark %u is missing: registration needs all of them", path,
                               i);
    }
    if (!rc)
        memcpy(positions, f.positions, (size_t)n * 3 * sizeof(float));
    mim_landmark_frames_free(&f);
    return rc;
}

int mim_landmark_file_read(const char *path, uint32_t n_landmarks, mim_landmark_file_kind_t *kind,
                           mim_landmark_map_t *map, float *positions, mim_error_t *err)
{
    if (!path || !kind || !map || !positions || n_landmarks < MIM_LANDMARKS_MIN ||
        n_landmarks > MIM_LANDMARKS_MAX)
        return mim_error_set(err, MIM_EINVAL, "landmark file: bad arguments (%u landmarks)", n_landmarks);
    /* The frames reader's cap; a regular file is measured before reading. */
    const size_t cap = MIM_LANDMARK_FRAMES_MAX_BYTES;
    struct stat st;
    if (stat(path, &st) == 0 && S_ISREG(st.st_mode) && (uint64_t)st.st_size > cap)
        return mim_error_set(err, MIM_EUNSUPPORTED, "%s: %llu bytes, more than the %zu MiB a landmark file may have",
                             path, (unsigned long long)st.st_size, cap >> 20);
    char *text;
    size_t len;
    mim_error_t e = {0};
    int rc = mim_file_read(path, cap + 1, &text, &len, &e);
    if (rc == MIM_EIO || rc == MIM_ENOMEM)
        return mim_error_set(err, rc, "%s", e.msg);
    if (rc)
        return mim_error_set(err, rc == -ENOENT ? MIM_ENOTFOUND : MIM_EIO, "%s", e.msg);
    if (len > cap) /* a pipe or a growing file */
        rc = mim_error_set(err, MIM_EUNSUPPORTED, "%s: more than the %zu MiB a landmark file may have", path,
                           cap >> 20);
    else if ((rc = classify(path, text, len, err)) > 0) {
        *kind = (mim_landmark_file_kind_t)rc;
        rc = rc == MIM_LANDMARK_FILE_MAP ? read_map(path, text, len, n_landmarks, map, err)
                                         : read_positions(path, text, len, n_landmarks, positions, err);
    }
    free(text);
    return rc;
}
