/* Argument helpers shared by the subcommands. */
#include "args.h"

#include "mim_session.h"
#include "mim_vest_kinematics.h"
#include "output.h"

#include <errno.h>
#include <math.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int mim_cli_number(const char *cmd, const char *name, const char *text, uint64_t lo, uint64_t hi, uint64_t *out)
{
    int ok = text && *text >= '0' && *text <= '9';
    if (ok) {
        errno = 0;
        char *end;
        unsigned long long v = strtoull(text, &end, 10);
        ok = !errno && !*end && v >= lo && v <= hi;
        if (ok) *out = v;
    }
    if (!ok)
        fprintf(stderr, "mimic %s: --%s '%s' is not a number in %" PRIu64 "..%" PRIu64 "\n", cmd, name, text ? text : "",
                lo, hi);
    return ok ? 0 : -1;
}

int mim_cli_real(const char *cmd, const char *name, const char *text, double lo, double hi, int lo_open,
                 const char *what, double *out)
{
    char *end = NULL;
    errno = 0;
    double v = text && *text ? strtod(text, &end) : NAN;
    int ok = !errno && end && end != text && !*end && isfinite(v) && (lo_open ? v > lo : v >= lo) && v <= hi;
    if (!ok) {
        if (what)
            fprintf(stderr, "mimic %s: --%s '%s' %s\n", cmd, name, text ? text : "", what);
        else
            fprintf(stderr, "mimic %s: --%s '%s' is not a number in %g..%g%s\n", cmd, name, text ? text : "", lo, hi,
                    lo_open ? " (above the first)" : "");
        return -1;
    }
    *out = v;
    return 0;
}

int mim_cli_key_rate(const char *cmd, const char *text, double *out)
{
    if (!strcmp(text, "auto")) {
        *out = 0.0;
        return 0;
    }
    return mim_cli_real(cmd, "key-rate", text, 0.0, 1000.0, 1, "is neither auto nor a rate in (0, 1000] Hz", out);
}

int mim_cli_listen(const char *cmd, const char *listen)
{
    const char *colon = strrchr(listen, ':');
    if (!colon || colon == listen || !colon[1] || strspn(colon + 1, "0123456789") != strlen(colon + 1)) {
        fprintf(stderr, "mimic %s: --listen '%s' is not HOST:PORT (e.g. 127.0.0.1:8080)\n", cmd, listen);
        return -1;
    }
    return (int)(colon - listen);
}

int mim_cli_template_id(const char *cmd, const char *name, const char *text, uint64_t *id)
{
    int ok = text && *text >= '0' && *text <= '9';
    if (ok) {
        errno = 0;
        char *end;
        unsigned long long v = strtoull(text, &end, 10);
        ok = !errno && !*end && v >= 1;
        if (ok) *id = v;
    }
    if (!ok)
        fprintf(stderr, "mimic %s: --%s '%s' is not a template id (a number from mimic list)\n", cmd, name,
                text ? text : "");
    return ok ? 0 : -1;
}

int mim_cli_on_off(const char *cmd, const char *name, const char *text, int *out)
{
    if (text && (!strcmp(text, "on") || !strcmp(text, "off"))) {
        *out = !strcmp(text, "on");
        return 0;
    }
    fprintf(stderr, "mimic %s: --%s '%s': use on or off\n", cmd, name, text ? text : "");
    return -1;
}

int mim_cli_template_ids(const char *cmd, const char *name, const char *text, uint64_t *ids, uint32_t max,
                         uint32_t *n)
{
    char buf[1024];
    *n = 0;
    if (!text || strlen(text) >= sizeof buf) {
        fprintf(stderr, "mimic %s: --%s: the list is too long\n", cmd, name);
        return -1;
    }
    snprintf(buf, sizeof buf, "%s", text);
    char *save = NULL;
    for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        if (*n == max) {
            fprintf(stderr, "mimic %s: --%s: more than %u template ids\n", cmd, name, max);
            return -1;
        }
        if (mim_cli_template_id(cmd, name, tok, &ids[*n])) return -1;
        ++*n;
    }
    if (!*n || text[strlen(text) - 1] == ',' || text[0] == ',' || strstr(text, ",,")) {
        fprintf(stderr, "mimic %s: --%s '%s' is not a list of template ids (ID,ID,...)\n", cmd, name, text);
        return -1;
    }
    return 0;
}

int mim_cli_drive(const char *cmd, const char *text, int *drive)
{
    if ((*drive = mim_session_drive_parse(text)) >= 0)
        return 0;
    fprintf(stderr, "mimic %s: --drive '%s' is not auto, template, orientation or skeleton\n", cmd, text);
    return -1;
}

int mim_cli_pose(const char *cmd, const char *name, const char *text, int *pose)
{
    if (!strcmp(text, "rest"))
        *pose = MIM_VEST_POSE_REST;
    else if (!strcmp(text, "t") || !strcmp(text, "T"))
        *pose = MIM_VEST_POSE_T;
    else if (!strcmp(text, "a") || !strcmp(text, "A"))
        *pose = MIM_VEST_POSE_A;
    else {
        fprintf(stderr, "mimic %s: --%s '%s' is not rest, t or a\n", cmd, name, text);
        return -1;
    }
    return 0;
}

mim_db_options_t mim_cli_db_options(int read_only)
{
    /* the one place the environment reaches the store: libraries take options */
    const char *env = getenv("MIMIC_MAP_SIZE");
    uint64_t map = 0;
    if (env && *env >= '0' && *env <= '9') {
        char *end = NULL;
        errno = 0;
        unsigned long long v = strtoull(env, &end, 10);
        if (!errno && !*end)
            map = v;
    }
    /* a read-write open of an older store migrates it: the user sees it */
    return (mim_db_options_t){.map_size = map, .read_only = read_only, .progress = mim_cli_progress,
                              .log = mim_cli_log};
}

int mim_cli_avatar_option(const char *cmd, int c, const char *arg, mim_cli_avatar_t *a)
{
    if (c == MIM_CLI_OPT_AVATAR_MESH) {
        if (a->n_meshes >= MIM_CLI_AVATAR_MESHES_MAX) {
            fprintf(stderr, "mimic %s: --avatar-mesh: at most %d meshes\n", cmd, MIM_CLI_AVATAR_MESHES_MAX);
            return -1;
        }
        if (!*arg) {
            fprintf(stderr, "mimic %s: --avatar-mesh: an empty name\n", cmd);
            return -1;
        }
        a->meshes[a->n_meshes++] = arg;
        return 1;
    }
    if (c == MIM_CLI_OPT_MAX_DISTANCE)
        return mim_cli_real(cmd, "max-distance-mm", arg, 0.0, 1000.0, 1, "is not a distance in (0, 1000] mm",
                            &a->max_distance_mm)
                   ? -1
                   : 1;
    return 0;
}

void mim_cli_session_options(mim_session_options_t *so, const mim_cli_avatar_t *avatar)
{
    *so = (mim_session_options_t){.map_size = mim_cli_db_options(1).map_size, .log = mim_cli_log};
    if (avatar) {
        so->avatar_landmarks = avatar->landmarks;
        so->avatar_meshes = avatar->meshes, so->n_avatar_meshes = avatar->n_meshes;
        so->max_distance_mm = avatar->max_distance_mm;
    }
}
