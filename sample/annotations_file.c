/* 2D pose-pair annotations and their cameras as JSON
 * (schemas/pair-annotations.schema.json, schemas/pair-cameras.schema.json):
 * built and read here, once. */
#include "internal.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

json_t *mim__pairs_joint_labels(void)
{
    json_t *names = json_array();
    char name[48];
    for (int i = 0; i < MIM_PAIR_JOINTS; i++) {
        snprintf(name, sizeof name, "%c.%s", i < MIM_PAIR_PERSON_JOINTS ? 'A' : 'B',
                 mim_sample_joint_names[i % MIM_PAIR_PERSON_JOINTS]);
        json_array_append_new(names, json_string(name));
    }
    return names;
}

char *mim_pairs_annotations_json(const mim_pairs_annotations_t *a, const char *const *takes, uint32_t n_takes)
{
    json_t *list = json_array(), *tk = json_array();
    for (uint32_t t = 0; t < n_takes; t++)
        if (json_array_append_new(tk, json_string(takes[t]))) { /* a name that is not UTF-8 */
            json_decref(list), json_decref(tk);
            return NULL;
        }
    for (uint32_t i = 0; i < a->n; i++) {
        json_t *pts = json_array();
        const double *p = a->points + (size_t)i * 2 * MIM_PAIR_JOINTS;
        for (int j = 0; j < MIM_PAIR_JOINTS; j++) json_array_append_new(pts, json_pack("[f, f]", p[2 * j], p[2 * j + 1]));
        json_t *one = json_pack("{s:I, s:I, s:I}", "take", (json_int_t)a->take[i], "frame", (json_int_t)a->frame[i],
                                "view", (json_int_t)a->view[i]);
        if (a->shot && a->shot[i] != MIM_PAIRS_NO_SHOT) json_object_set_new(one, "shot", json_integer(a->shot[i]));
        json_object_set_new(one, "points", pts);
        json_array_append_new(list, one);
    }
    json_t *root = json_pack("{s:s, s:o, s:[I, I], s:o, s:o}", "format", "mimic pair annotations 1", "joints",
                             mim__pairs_joint_labels(), "image", (json_int_t)a->width, (json_int_t)a->height, "takes", tk,
                             "annotations", list);
    char *txt = root ? json_dumps(root, JSON_COMPACT | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(7)) : NULL;
    json_decref(root);
    return txt;
}

char *mim_pairs_cameras_json(const mim_pairs_annotations_t *a, const mim_pairs_camera_t *cams)
{
    json_t *list = json_array();
    for (uint32_t i = 0; i < a->n; i++) {
        const mim_pairs_camera_t *c = &cams[i];
        json_t *R = json_array();
        for (int k = 0; k < 9; k++) json_array_append_new(R, json_real(c->R[k]));
        json_array_append_new(list, json_pack("{s:I, s:I, s:I, s:[f, f, f], s:o, s:f, s:[f, f], s:[I, I]}", "take",
                                              (json_int_t)a->take[i], "frame", (json_int_t)a->frame[i], "view",
                                              (json_int_t)a->view[i], "position", c->position[0], c->position[1],
                                              c->position[2], "rotation", R, "focal_px", c->focal_px, "center", c->cx,
                                              c->cy, "image", (json_int_t)c->width, (json_int_t)c->height));
    }
    json_t *root = json_pack("{s:s, s:o}", "format", "mimic pair cameras 1", "cameras", list);
    char *txt = root ? json_dumps(root, JSON_INDENT(1) | JSON_PRESERVE_ORDER) : NULL;
    json_decref(root);
    return txt;
}

void mim_pairs_annotations_free(mim_pairs_annotations_t *a)
{
    if (!a) return;
    free(a->take), free(a->frame), free(a->view), free(a->shot), free(a->points);
    memset(a, 0, sizeof *a);
}

int mim_pairs_annotations_parse(const char *text, size_t len, const char *origin, mim_pairs_annotations_t *out,
                                mim_error_t *err)
{
    memset(out, 0, sizeof *out);
    if (!origin) origin = "annotations";
    if (!text) return mim_error_set(err, MIM_EINVAL, "%s: no text", origin);
    json_error_t je;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
    if (!root) return mim_error_set(err, MIM_EFORMAT, "%s:%d:%d: %s", origin, je.line, je.column, je.text);
    int rc = 0;
    const char *fmt = json_string_value(json_object_get(root, "format"));
    json_t *names = json_object_get(root, "joints"), *img = json_object_get(root, "image"),
           *list = json_object_get(root, "annotations"), *takes = json_object_get(root, "takes");
    json_t *ref = mim__pairs_joint_labels();
    if (!fmt || strcmp(fmt, "mimic pair annotations 1"))
        rc = mim_error_set(err, MIM_EFORMAT, "%s: not mimic pair annotations (\"format\" is not \"mimic pair annotations 1\")", origin);
    else if (!json_equal(names, ref))
        rc = mim_error_set(err, MIM_EFORMAT, "%s: \"joints\" must name the 34 joints A.head ... B.neck in order", origin);
    else if (!json_is_array(img) || json_array_size(img) != 2 || !json_is_integer(json_array_get(img, 0)) ||
             !json_is_integer(json_array_get(img, 1)) || json_integer_value(json_array_get(img, 0)) < 1 ||
             json_integer_value(json_array_get(img, 1)) < 1 || json_integer_value(json_array_get(img, 0)) > 100000 ||
             json_integer_value(json_array_get(img, 1)) > 100000)
        rc = mim_error_set(err, MIM_EFORMAT, "%s: \"image\" must be [width, height] in pixels (1..100000)", origin);
    else if (!json_is_array(takes) || !json_array_size(takes))
        rc = mim_error_set(err, MIM_EFORMAT, "%s: \"takes\" must list the takes annotated", origin);
    else if (!json_is_array(list) || !json_array_size(list))
        rc = mim_error_set(err, MIM_EEMPTY, "%s: no annotations", origin);
    else if (json_array_size(list) > MIM_PAIRS_ANNOTATIONS_MAX)
        rc = mim_error_set(err, MIM_EUNSUPPORTED, "%s: %zu annotations, more than %u", origin, json_array_size(list),
                           MIM_PAIRS_ANNOTATIONS_MAX);
    json_decref(ref);
    if (!rc) {
        size_t n = json_array_size(list);
        out->width = (uint32_t)json_integer_value(json_array_get(img, 0));
        out->height = (uint32_t)json_integer_value(json_array_get(img, 1));
        out->take = malloc(n * sizeof *out->take), out->frame = malloc(n * sizeof *out->frame);
        out->view = malloc(n * sizeof *out->view), out->shot = malloc(n * sizeof *out->shot);
        out->points = malloc(n * 2 * MIM_PAIR_JOINTS * sizeof *out->points);
        if (!out->take || !out->frame || !out->view || !out->shot || !out->points)
            rc = mim_error_set(err, MIM_ENOMEM, "%s: out of memory for %zu annotations", origin, n);
        for (size_t i = 0; i < n && !rc; i++) {
            json_t *a = json_array_get(list, i), *pts = json_object_get(a, "points");
            json_t *t = json_object_get(a, "take"), *f = json_object_get(a, "frame"), *v = json_object_get(a, "view");
            if (!json_is_integer(t) || !json_is_integer(f) || !json_is_integer(v) || json_integer_value(t) < 0 ||
                json_integer_value(f) < 0 || json_integer_value(v) < 0 || json_integer_value(t) > 1000000000 ||
                json_integer_value(f) > 1000000000 || json_integer_value(v) > 1000000000 ||
                (size_t)json_integer_value(t) >= json_array_size(takes)) {
                rc = mim_error_set(err, MIM_EFORMAT, "%s: annotation %zu: \"take\" (an index into \"takes\"), \"frame\" and \"view\" must be whole numbers",
                                   origin, i);
                break;
            }
            if (!json_is_array(pts) || json_array_size(pts) != MIM_PAIR_JOINTS) {
                rc = mim_error_set(err, MIM_EFORMAT, "%s: annotation %zu: \"points\" must hold %d [u, v]", origin, i,
                                   MIM_PAIR_JOINTS);
                break;
            }
            out->take[i] = (uint32_t)json_integer_value(t), out->frame[i] = (uint32_t)json_integer_value(f);
            out->view[i] = (uint32_t)json_integer_value(v);
            json_t *sh = json_object_get(a, "shot");
            if (sh && (!json_is_integer(sh) || json_integer_value(sh) < 0 || json_integer_value(sh) >= MIM_PAIRS_NO_SHOT)) {
                rc = mim_error_set(err, MIM_EFORMAT, "%s: annotation %zu: \"shot\" must be a whole number", origin, i);
                break;
            }
            out->shot[i] = sh ? (uint32_t)json_integer_value(sh) : MIM_PAIRS_NO_SHOT;
            double *dst = out->points + i * 2 * MIM_PAIR_JOINTS;
            for (int j = 0; j < MIM_PAIR_JOINTS && !rc; j++) {
                json_t *uv = json_array_get(pts, (size_t)j);
                if (!json_is_array(uv) || json_array_size(uv) != 2 || !json_is_number(json_array_get(uv, 0)) ||
                    !json_is_number(json_array_get(uv, 1))) {
                    rc = mim_error_set(err, MIM_EFORMAT, "%s: annotation %zu: joint %d is not [u, v]", origin, i, j);
                    break;
                }
                for (int c = 0; c < 2; c++) {
                    double x = json_number_value(json_array_get(uv, (size_t)c));
                    if (!isfinite(x) || fabs(x) > 1e7)
                        rc = mim_error_set(err, MIM_ENONFINITE, "%s: annotation %zu: joint %d: %g is not a pixel coordinate",
                                           origin, i, j, x);
                    dst[2 * j + c] = x;
                }
            }
            out->n++;
        }
    }
    json_decref(root);
    if (rc) mim_pairs_annotations_free(out);
    return rc;
}
