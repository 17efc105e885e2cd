/* The reference reading of landmark frames (frames_reference.h). */
#include "frames_reference.h"

#include <jansson.h>
#include <stdlib.h>
#include <string.h>

int frames_reference(const char *text, uint32_t n, uint32_t max_missing, mim_landmark_frames_t *out)
{
    memset(out, 0, sizeof *out);
    json_t *root = json_loads(text, 0, NULL);
    if (!root) return -1;
    json_t *frames = json_object_get(root, "frames");
    size_t nf = frames ? json_array_size(frames) : 1;
    int any_or = 0, rc = !json_is_object(root) || (frames && (!nf || json_object_get(root, "landmarks") ||
                                                              json_object_get(root, "orientations")));
    for (size_t f = 0; f < nf && !rc; f++)
        any_or |= json_object_get(frames ? json_array_get(frames, f) : root, "orientations") != NULL;
    out->n_frames = (uint32_t)nf, out->n_landmarks = n;
    out->positions = calloc(nf * n * 3, sizeof(float));
    out->present = calloc(nf * n, 1);
    if (any_or) {
        out->orientations = calloc(nf * MIM_SEGMENTS * 4, sizeof(double));
        out->orient_present = calloc(nf * MIM_SEGMENTS, 1);
    }
    for (size_t f = 0; f < nf && !rc; f++) {
        json_t *fr = frames ? json_array_get(frames, f) : root, *o = json_object_get(fr, "orientations");
        rc = mim_landmark_array_parse(json_object_get(fr, "landmarks"), n, max_missing, "ref", (long)f,
                                      out->positions + f * n * 3, out->present + f * n, NULL);
        if (!rc && any_or) {
            json_t *none = json_object();
            rc = mim_orientations_parse(o ? o : none, "ref", (long)f, out->orientations + f * MIM_SEGMENTS * 4,
                                        out->orient_present + f * MIM_SEGMENTS, NULL);
            json_decref(none);
        }
    }
    json_decref(root);
    if (rc) mim_landmark_frames_free(out);
    return rc ? -1 : 0;
}

int frames_equal(const mim_landmark_frames_t *a, const mim_landmark_frames_t *b)
{
    size_t n = (size_t)a->n_frames * a->n_landmarks;
    if (a->n_frames != b->n_frames || a->n_landmarks != b->n_landmarks || memcmp(a->present, b->present, n))
        return 0;
    for (size_t i = 0; i < 3 * n; i++)
        if (!(a->positions[i] == b->positions[i] || (a->positions[i] != a->positions[i] && b->positions[i] != b->positions[i])))
            return 0;
    if (!a->orientations != !b->orientations) return 0;
    return !a->orientations ||
           (!memcmp(a->orient_present, b->orient_present, (size_t)a->n_frames * MIM_SEGMENTS) &&
            !memcmp(a->orientations, b->orientations, (size_t)a->n_frames * MIM_SEGMENTS * 4 * sizeof(double)));
}
