/* The 17 joints of a person in a pose-pair (mim_sample_joint_names) found
 * among a motion file's joints by name: the naming schemes mimic knows,
 * or a user's map. A joint's position is where its bone starts, so each
 * entry names the bone that starts at that place (the shoulder is where
 * the upper arm starts). */
#include "mim_sample.h"

#include <jansson.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

typedef struct scheme {
    const char *name;
    /* per joint, in mim_sample_joint_names order: alternatives split by '|' */
    const char *joint[MIM_PAIR_PERSON_JOINTS];
} scheme_t;

static const scheme_t schemes[] = {
    {"CMU/Biovision",
     {"Head", "Spine1", "Hips", "LeftArm", "RightArm", "LeftForeArm", "RightForeArm", "LeftHand", "RightHand",
      "LeftUpLeg", "RightUpLeg", "LeftLeg", "RightLeg", "LeftFoot", "RightFoot", "Spine", "Neck|Neck1"}},
    {"MakeHuman",
     {"head", "spine01", "root", "upperarm01.L", "upperarm01.R", "lowerarm01.L", "lowerarm01.R", "wrist.L", "wrist.R",
      "upperleg01.L", "upperleg01.R", "lowerleg01.L", "lowerleg01.R", "foot.L", "foot.R", "spine03", "neck01"}},
    {"ASF",
     {"head", "thorax", "root", "lhumerus", "rhumerus", "lradius", "rradius", "lwrist", "rwrist", "lfemur", "rfemur",
      "ltibia", "rtibia", "lfoot", "rfoot", "upperback|lowerback", "lowerneck"}},
    {"short lower-case",
     {"head", "chest|thorax|upperback", "root|pelvis|hips", "lshoulder", "rshoulder", "lelbow", "relbow", "lwrist",
      "rwrist", "lhip", "rhip", "lknee", "rknee", "lankle", "rankle", "spine|lowerback|upperback",
      "lowerneck|neck"}},
};

static int find(const char (*names)[64], uint32_t n, const char *alternatives)
{
    char buf[256];
    snprintf(buf, sizeof buf, "%s", alternatives);
    for (char *save = NULL, *a = strtok_r(buf, "|", &save); a; a = strtok_r(NULL, "|", &save))
        for (uint32_t j = 0; j < n; j++)
            if (!strcasecmp(names[j], a)) return (int)j;
    return -1;
}

int mim_pair_joint_map(const char (*names)[64], uint32_t n, const char *custom_json, const char *origin,
                       int32_t out[MIM_PAIR_PERSON_JOINTS], const char **scheme, mim_error_t *err)
{
    if (!origin) origin = "motion";
    if (custom_json) {
        json_error_t je;
        json_t *root = json_loads(custom_json, JSON_REJECT_DUPLICATES, &je);
        if (!root || !json_is_object(root)) {
            json_decref(root);
            return mim_error_set(err, MIM_EFORMAT, "joint map:%d:%d: %s", je.line, je.column,
                                 root ? "not an object of joint names" : je.text);
        }
        int rc = 0;
        for (int k = 0; k < MIM_PAIR_PERSON_JOINTS && !rc; k++) {
            json_t *v = json_object_get(root, mim_sample_joint_names[k]);
            if (!json_is_string(v))
                rc = mim_error_set(err, MIM_EFORMAT, "joint map: no \"%s\" (a joint name of %s)", mim_sample_joint_names[k],
                                   origin);
            else if ((out[k] = find(names, n, json_string_value(v))) < 0)
                rc = mim_error_set(err, MIM_ENOTFOUND, "joint map: \"%s\" is \"%s\", which %s does not have",
                                   mim_sample_joint_names[k], json_string_value(v), origin);
        }
        json_decref(root);
        if (!rc && scheme) *scheme = "joint map";
        return rc;
    }
    /* the scheme that finds the most joints; all 17 or an error naming the missing */
    int best = -1, best_found = -1, missing = 0;
    for (size_t s = 0; s < sizeof schemes / sizeof *schemes; s++) {
        int found = 0, first_missing = -1;
        for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++) {
            if (find(names, n, schemes[s].joint[k]) >= 0) found++;
            else if (first_missing < 0) first_missing = k;
        }
        if (found > best_found) best_found = found, best = (int)s, missing = first_missing;
    }
    if (best_found < MIM_PAIR_PERSON_JOINTS)
        return mim_error_set(err, MIM_ENOTFOUND,
                             "%s: joints not recognised: closest to the %s scheme, but no %s joint (%s); give "
                             "--joint-map FILE.json",
                             origin, schemes[best].name, schemes[best].joint[missing], mim_sample_joint_names[missing]);
    for (int k = 0; k < MIM_PAIR_PERSON_JOINTS; k++) out[k] = find(names, n, schemes[best].joint[k]);
    if (scheme) *scheme = schemes[best].name;
    return 0;
}

/* The unit of a motion file from the size of a person in it: the span from
 * the head to the middle of the ankles, in the file's units. Motion files
 * do not say their unit; these ranges do not overlap for an adult
 * (head-to-ankle 0.8 to 2.5 m). */
int mim_pair_unit_guess(double span, double *metres_per_unit, const char **name)
{
    static const struct {
        double lo, hi, scale;
        const char *name;
    } units[] = {
        {0.8, 2.5, 1.0, "metres"},
        {14.0, 45.0, 0.0254 / 0.45, "CMU ASF units (0.0254/0.45 m)"},
        {45.0, 100.0, 0.0254, "inches"},
        {100.0, 250.0, 0.01, "centimetres"},
        {800.0, 2500.0, 0.001, "millimetres"},
    };
    for (size_t k = 0; k < sizeof units / sizeof *units; k++)
        if (span >= units[k].lo && span <= units[k].hi) {
            *metres_per_unit = units[k].scale;
            if (name) *name = units[k].name;
            return 0;
        }
    return MIM_ENOTFOUND;
}
