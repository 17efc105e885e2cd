/* The landmark map: which vertex carries each landmark and the left<->right
 * mirror table (DESIGN.md "Landmarks"; seed 000 §3.2 mirrors every training
 * sample through it). JSON through jansson, errors with line and column. */
#include "mim_core.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *const mim_landmark_default_names[MIM_LANDMARKS_DEFAULT_COUNT] = {
    "head",    "chest",   "pelvis",  "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist",
    "r_wrist", "l_hip",   "r_hip",   "l_knee",     "r_knee",     "l_ankle", "r_ankle", "spine",
};

const char *const mim_segment_names[MIM_SEGMENTS] = {
    "pelvis",     "chest",       "head",       "l_shoulder", "r_shoulder", "l_upperarm",
    "r_upperarm", "l_forearm",   "r_forearm",  "l_hand",     "r_hand",     "l_thigh",
    "r_thigh",    "l_shin",      "r_shin",     "l_foot",     "r_foot"};
static const int segment_parent[MIM_SEGMENTS] = {-1, 0, 1, 1, 1, 3, 4, 5, 6, 7, 8, 0, 0, 11, 12, 13, 14};
int mim_segment_parent(uint32_t s) { return s < MIM_SEGMENTS ? segment_parent[s] : -1; }
static const uint32_t default_mirror[MIM_LANDMARKS_DEFAULT_COUNT] = {0,  1,  2,  4,  3,  6,  5,  8,
                                                                     7,  10, 9,  12, 11, 14, 13, 15};

int mim_landmarks_find(const mim_landmark_map_t *map, const char *name)
{
    for (uint32_t i = 0; map && name && i < map->count; i++)
        if (!strcmp(map->names[i], name))
            return (int)i;
    return -1;
}

/* The landmark skeleton over the default names: child, parent; parents
 * come before their children. */
static const char *const skeleton[MIM_LANDMARK_BONES][2] = {
    {"spine", "pelvis"},          {"chest", "spine"},         {"head", "chest"},
    {"l_shoulder", "chest"},      {"r_shoulder", "chest"},    {"l_elbow", "l_shoulder"},
    {"r_elbow", "r_shoulder"},    {"l_wrist", "l_elbow"},     {"r_wrist", "r_elbow"},
    {"l_hip", "pelvis"},          {"r_hip", "pelvis"},        {"l_knee", "l_hip"},
    {"r_knee", "r_hip"},          {"l_ankle", "l_knee"},      {"r_ankle", "r_knee"},
};

int mim_landmark_skeleton(const mim_landmark_map_t *map, int child[MIM_LANDMARK_BONES],
                          int parent[MIM_LANDMARK_BONES], const char **missing)
{
    *missing = NULL;
    if (map->count != MIM_LANDMARKS_DEFAULT_COUNT) return MIM_EUNSUPPORTED;
    for (size_t k = 0; k < MIM_LANDMARK_BONES; k++) {
        child[k] = mim_landmarks_find(map, skeleton[k][0]);
        parent[k] = mim_landmarks_find(map, skeleton[k][1]);
        if (child[k] < 0 || parent[k] < 0) {
            *missing = child[k] < 0 ? skeleton[k][0] : skeleton[k][1];
            return MIM_EUNSUPPORTED;
        }
    }
    return 0;
}

void mim_landmarks_default(mim_landmark_map_t *map, const uint32_t vertices[MIM_LANDMARKS_DEFAULT_COUNT],
                           uint32_t topology_vertices)
{
    memset(map, 0, sizeof *map);
    map->count = MIM_LANDMARKS_DEFAULT_COUNT;
    map->topology_vertices = topology_vertices;
    for (uint32_t i = 0; i < MIM_LANDMARKS_DEFAULT_COUNT; i++) {
        snprintf(map->names[i], MIM_LANDMARK_NAME_MAX, "%s", mim_landmark_default_names[i]);
        map->vertex[i] = vertices[i];
        map->mirror[i] = default_mirror[i];
    }
}

int mim_landmarks_validate(const mim_landmark_map_t *map, uint32_t n_vertices, const char *origin,
                           mim_error_t *err)
{
    if (map->count < MIM_LANDMARKS_MIN || map->count > MIM_LANDMARKS_MAX)
        return mim_error_set(err, MIM_EFORMAT, "%s: landmark map has %u landmarks, needs %d..%d", origin,
                             map->count, MIM_LANDMARKS_MIN, MIM_LANDMARKS_MAX);
    for (uint32_t i = 0; i < map->count; i++) {
        if (map->mirror[i] >= map->count || map->mirror[map->mirror[i]] != i)
            return mim_error_set(err, MIM_EFORMAT,
                                 "%s: mirror table is not a pairing: mirror[%u] = %u", origin, i,
                                 map->mirror[i]);
        if (n_vertices && map->vertex[i] >= n_vertices)
            return mim_error_set(err, MIM_EINDEX,
                                 "%s: landmark '%s' is vertex %u, but the mesh has %u vertices", origin,
                                 map->names[i], map->vertex[i], n_vertices);
        for (uint32_t j = 0; j < i; j++)
            if (strcmp(map->names[i], map->names[j]) == 0)
                return mim_error_set(err, MIM_EFORMAT, "%s: landmark name '%s' appears twice", origin,
                                     map->names[i]);
    }
    if (n_vertices && map->topology_vertices && map->topology_vertices != n_vertices)
        return mim_error_set(err, MIM_ETOPOLOGY,
                             "%s: landmark map is for %u vertices, the mesh has %u", origin,
                             map->topology_vertices, n_vertices);
    return 0;
}

static int get_uint(json_t *v, uint32_t *out)
{
    if (!json_is_integer(v)) return -1;
    json_int_t x = json_integer_value(v);
    if (x < 0 || x > (json_int_t)UINT32_MAX) return -1;
    *out = (uint32_t)x;
    return 0;
}

int mim_landmarks_parse(mim_landmark_map_t *map, const char *text, size_t len, const char *origin,
                        mim_error_t *err)
{
    memset(map, 0, sizeof *map);
    json_error_t je;
    json_t *root = json_loadb(text, len, 0, &je);
    if (!root)
        return mim_error_set(err, MIM_EFORMAT, "%s:%d:%d: %s", origin, je.line, je.column, je.text);
    int rc = 0;
    json_t *lm = json_object_get(root, "landmarks");
    json_t *mirror = json_object_get(root, "mirror");
    json_t *tv = json_object_get(root, "topology_vertices");
    if (!json_is_object(root) || !json_is_array(lm)) {
        rc = mim_error_set(err, MIM_EFORMAT, "%s: expected an object with a \"landmarks\" array", origin);
        goto out;
    }
    size_t n = json_array_size(lm);
    if (n < MIM_LANDMARKS_MIN || n > MIM_LANDMARKS_MAX) {
        rc = mim_error_set(err, MIM_EFORMAT, "%s: %zu landmarks, needs %d..%d", origin, n, MIM_LANDMARKS_MIN,
                           MIM_LANDMARKS_MAX);
        goto out;
    }
    map->count = (uint32_t)n;
    if (tv && get_uint(tv, &map->topology_vertices)) {
        rc = mim_error_set(err, MIM_EFORMAT, "%s: \"topology_vertices\" must be a non-negative integer", origin);
        goto out;
    }
    for (size_t i = 0; i < n; i++) {
        json_t *e = json_array_get(lm, i);
        json_t *name = json_object_get(e, "name");
        if (!json_is_string(name) || json_string_length(name) == 0 ||
            json_string_length(name) >= MIM_LANDMARK_NAME_MAX) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s: landmark %zu needs a \"name\" of 1..%d characters", origin,
                               i, MIM_LANDMARK_NAME_MAX - 1);
            goto out;
        }
        snprintf(map->names[i], MIM_LANDMARK_NAME_MAX, "%s", json_string_value(name));
        if (get_uint(json_object_get(e, "vertex"), &map->vertex[i])) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s: landmark '%s' needs a non-negative integer \"vertex\"",
                               origin, map->names[i]);
            goto out;
        }
    }
    if (!mirror) {
        /* Without a table, pair l_X with r_X by name; others mirror to themselves. */
        for (uint32_t i = 0; i < map->count; i++) {
            map->mirror[i] = i;
            const char *nm = map->names[i];
            if ((nm[0] == 'l' || nm[0] == 'r') && nm[1] == '_') {
                char other[MIM_LANDMARK_NAME_MAX];
                snprintf(other, sizeof other, "%c%s", nm[0] == 'l' ? 'r' : 'l', nm + 1);
                for (uint32_t j = 0; j < map->count; j++)
                    if (strcmp(map->names[j], other) == 0) map->mirror[i] = j;
            }
        }
    } else {
        if (!json_is_array(mirror) || json_array_size(mirror) != n) {
            rc = mim_error_set(err, MIM_EFORMAT, "%s: \"mirror\" must be an array of %zu landmark indices", origin,
                               n);
            goto out;
        }
        for (size_t i = 0; i < n; i++)
            if (get_uint(json_array_get(mirror, i), &map->mirror[i])) {
                rc = mim_error_set(err, MIM_EFORMAT, "%s: mirror[%zu] must be a landmark index", origin, i);
                goto out;
            }
    }
    rc = mim_landmarks_validate(map, 0, origin, err);
out:
    json_decref(root);
    return rc;
}

int mim_landmarks_read(mim_landmark_map_t *map, const char *path, mim_error_t *err)
{
    char *buf;
    size_t len;
    mim_error_t e = {0};
    int rc = mim_file_read(path, 0, &buf, &len, &e);
    if (rc == MIM_EIO || rc == MIM_ENOMEM) return mim_error_set(err, rc, "%s", e.msg);
    /* Callers expect any open failure as MIM_ENOTFOUND, named as the landmark map. */
    if (rc) return mim_error_set(err, MIM_ENOTFOUND, "%s: cannot open landmark map: %s", path, mim_strerror(rc));
    rc = mim_landmarks_parse(map, buf, len, path, err);
    free(buf);
    return rc;
}

char *mim_landmarks_to_json(const mim_landmark_map_t *map)
{
    json_t *root = json_object();
    json_t *lm = json_array();
    json_t *mirror = json_array();
    json_object_set_new(root, "topology_vertices", json_integer(map->topology_vertices));
    for (uint32_t i = 0; i < map->count; i++) {
        json_array_append_new(lm, json_pack("{s:s, s:I}", "name", map->names[i], "vertex",
                                            (json_int_t)map->vertex[i]));
        json_array_append_new(mirror, json_integer(map->mirror[i]));
    }
    json_object_set_new(root, "landmarks", lm);
    json_object_set_new(root, "mirror", mirror);
    char *s = json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
    json_decref(root);
    return s;
}

int mim_landmarks_write(const mim_landmark_map_t *map, const char *path, mim_error_t *err)
{
    char *s = mim_landmarks_to_json(map);
    if (!s)
        return mim_error_set(err, MIM_ENOMEM, "%s: out of memory", path);
    mim_file_part_t parts[2] = {{s, strlen(s)}, {"\n", 1}};
    int rc = mim_file_write_atomic(path, parts, 2, err);
    free(s);
    return rc;
}
