/* What every `mimic pairs` command reads: pose-pairs from two motion
 * files of one take (--pair/--truth/--prior A.bvh,B.bvh), with the root
 * translation kept (vest/'s joint motion), the 17 joints of each person
 * (sample/'s schemes or --joint-map) and the unit (guessed from the
 * person's size, or --unit). */
#include "pairs_input.h"

#include "args.h"

#include "mim_sample.h"
#include "mim_vest_motion.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Joint j of frame f of motion m. */
static const float *joint_at(const mim_vest_joint_motion_t *m, uint32_t f, int32_t j)
{
    return m->positions + 3 * ((size_t)f * m->n_joints + (size_t)j);
}

static int person(const char *path, const char *joint_map, double unit, mim_vest_joint_motion_t *m,
                  int32_t map[MIM_PAIR_PERSON_JOINTS], double *scale, char *msg, size_t size)
{
    mim_error_t err = {0};
    const char *scheme = NULL, *unit_name = NULL;
    if (mim_vest_joint_motion_read_bvh(m, path, &err) ||
        mim_pair_joint_map((const char(*)[64])m->name, m->n_joints, joint_map, path, map, &scheme, &err)) {
        snprintf(msg, size, "%s", mim_error_text(&err));
        return -1;
    }
    if (unit > 0) {
        *scale = unit;
        return 0;
    }
    /* the size of the person in the first frame: head to the middle of the ankles */
    const float *h = joint_at(m, 0, map[0]), *la = joint_at(m, 0, map[13]), *ra = joint_at(m, 0, map[14]);
    double d2 = 0;
    for (int c = 0; c < 3; c++) d2 += (h[c] - 0.5 * (la[c] + ra[c])) * (h[c] - 0.5 * (la[c] + ra[c]));
    if (mim_pair_unit_guess(sqrt(d2), scale, &unit_name)) {
        snprintf(msg, size, "%s: cannot tell the unit: the person spans %.3g units from head to ankles; give --unit "
                            "(metres per unit)", path, sqrt(d2));
        return -1;
    }
    return 0;
}

/* The take's up axis: given, or each person's (mim_vest_joint_motion_up:
 * head above the ankles), which must agree. 0, or -1 with msg. */
static int take_up(const char *a, const char *b, const mim_vest_joint_motion_t *ma, const int32_t *map_a,
                   const mim_vest_joint_motion_t *mb, const int32_t *map_b, mim_cli_up_t *up, char *msg, size_t size)
{
    if (up->axis) {
        up->how = "given";
        return 0;
    }
    int rest_a, rest_b;
    int ua = mim_vest_joint_motion_up(ma, map_a[0], map_a[13], map_a[14], &rest_a);
    int ub = mim_vest_joint_motion_up(mb, map_b[0], map_b[13], map_b[14], &rest_b);
    if (!ua || !ub) {
        snprintf(msg, size, "%s: cannot tell which way is up (neither its rest pose nor its frames stand the head "
                            "above the feet along one axis); give --up x|y|z|-x|-y|-z", ua ? b : a);
        return -1;
    }
    if (ua != ub) {
        snprintf(msg, size, "%s is %s up and %s %s up: give --up", a, mim_axis_name(ua), b, mim_axis_name(ub));
        return -1;
    }
    up->axis = ua;
    up->how = rest_a && rest_b ? "found from the rest pose" : "found from the frames";
    return 0;
}

int mim_cli_pairs_read(const char *spec, const char *joint_map, double unit, mim_cli_up_t *up, uint32_t every,
                       uint32_t offset, double **frames, uint32_t *n_frames, char *msg, size_t size)
{
    char a[4096], *b;
    snprintf(a, sizeof a, "%s", spec);
    if (!(b = strchr(a, ',')) || strchr(b + 1, ',') || b == a || !b[1]) {
        snprintf(msg, size, "'%s': give two motion files of one take, A.bvh,B.bvh", spec);
        return -1;
    }
    *b++ = 0;
    mim_vest_joint_motion_t ma = {0}, mb = {0};
    int32_t map_a[MIM_PAIR_PERSON_JOINTS], map_b[MIM_PAIR_PERSON_JOINTS];
    double sa = 0, sb = 0;
    int rc = -1;
    if (person(a, joint_map, unit, &ma, map_a, &sa, msg, size) || person(b, joint_map, unit, &mb, map_b, &sb, msg, size))
        goto done;
    if (ma.n_frames != mb.n_frames) {
        snprintf(msg, size, "%s and %s: %u and %u frames: the two people of one take have as many", a, b, ma.n_frames,
                 mb.n_frames);
        goto done;
    }
    if (fabs(ma.frame_time - mb.frame_time) > 1e-6 * ma.frame_time) {
        snprintf(msg, size, "%s and %s: frame times %g s and %g s: one take has one rate", a, b, ma.frame_time,
                 mb.frame_time);
        goto done;
    }
    if (fabs(sa - sb) > 1e-9 * sa) {
        snprintf(msg, size, "%s and %s: the units differ (%g and %g m per unit): give --unit", a, b, sa, sb);
        goto done;
    }
    if (take_up(a, b, &ma, map_a, &mb, map_b, up, msg, size))
        goto done;
    uint32_t step = every ? every : 1, count = offset < ma.n_frames ? (ma.n_frames - offset + step - 1) / step : 0;
    if (!count) {
        snprintf(msg, size, "%s: %u frames, none from frame %u on", a, ma.n_frames, offset);
        goto done;
    }
    double *out = malloc((size_t)count * 3 * MIM_PAIR_JOINTS * sizeof *out);
    if (!out) {
        snprintf(msg, size, "out of memory for %u pose-pairs", count);
        goto done;
    }
    for (uint32_t k = 0; k < count; k++) {
        uint32_t f = offset + k * step;
        double *dst = out + (size_t)k * 3 * MIM_PAIR_JOINTS;
        for (int j = 0; j < MIM_PAIR_PERSON_JOINTS; j++) {
            const float *pa = joint_at(&ma, f, map_a[j]), *pb = joint_at(&mb, f, map_b[j]);
            for (int c = 0; c < 3; c++)
                dst[3 * j + c] = pa[c] * sa, dst[3 * (j + MIM_PAIR_PERSON_JOINTS) + c] = pb[c] * sb;
            mim_axis_stand_up(up->axis, dst + 3 * j); /* mimic's y up */
            mim_axis_stand_up(up->axis, dst + 3 * (j + MIM_PAIR_PERSON_JOINTS));
        }
    }
    *frames = out, *n_frames = count;
    rc = 0;
done:
    mim_vest_joint_motion_free(&ma);
    mim_vest_joint_motion_free(&mb);
    return rc;
}

int mim_cli_takes_option(mim_cli_takes_t *t, int c, const char *arg)
{
    switch (c) {
    case 'p':
        if (t->n == MIM_CLI_MAX_TAKES) {
            fprintf(stderr, "mimic %s: at most %d takes\n", t->cmd, MIM_CLI_MAX_TAKES);
            return -1;
        }
        t->spec[t->n++] = arg;
        return 1;
    case 'e': return mim_cli_number(t->cmd, "every", arg, 1, 1000000, &t->every) ? -1 : 1;
    case 'k': return mim_cli_number(t->cmd, "offset", arg, 0, 100000000, &t->offset) ? -1 : 1;
    case 'm': t->map_path = arg; return 1;
    case 'u':
        return mim_cli_real(t->cmd, "unit", arg, 0.0, 1000.0, 1, "is not a number of metres per unit", &t->unit) ? -1 : 1;
    case MIM_CLI_OPT_UP:
        if (mim_axis_parse(arg, &t->up)) {
            fprintf(stderr, "mimic %s: --up '%s': give x, y, z, -x, -y or -z\n", t->cmd, arg);
            return -1;
        }
        return 1;
    default: return 0;
    }
}

int mim_cli_takes_begin(mim_cli_takes_t *t)
{
    mim_error_t err = {0};
    size_t len;
    if (!t->map_path || !mim_file_read(t->map_path, 1 << 20, &t->map_text, &len, &err)) return 0;
    fprintf(stderr, "mimic %s: %s\n", t->cmd, mim_error_text(&err));
    return 1;
}

int mim_cli_takes_read(const mim_cli_takes_t *t, int i, double **frames, uint32_t *n)
{
    char msg[1024];
    mim_cli_up_t up = {t->up, NULL};
    if (!mim_cli_pairs_read(t->spec[i], t->map_text, t->unit, &up, (uint32_t)t->every, (uint32_t)t->offset, frames, n,
                            msg, sizeof msg)) {
        if (!t->up && up.axis != 2) /* a take turned upright: say which way was taken, and how to change it */
            fprintf(stderr, "mimic %s: %s: %s is up (%s; --up to change)\n", t->cmd, t->spec[i], mim_axis_name(up.axis),
                    up.how);
        return 0;
    }
    fprintf(stderr, "mimic %s: %s\n", t->cmd, msg);
    return -1;
}

int mim_cli_takes_read_all(const mim_cli_takes_t *t, double **frames, uint32_t *n)
{
    *frames = NULL, *n = 0;
    for (int i = 0; i < t->n; i++) {
        double *fr = NULL;
        uint32_t nf = 0;
        if (mim_cli_takes_read(t, i, &fr, &nf)) {
            free(*frames), *frames = NULL, *n = 0;
            return -1;
        }
        double *grown = realloc(*frames, (size_t)(*n + nf) * 3 * MIM_PAIR_JOINTS * sizeof *grown);
        if (!grown) {
            free(fr), free(*frames), *frames = NULL, *n = 0;
            fprintf(stderr, "mimic %s: out of memory\n", t->cmd);
            return -1;
        }
        memcpy(grown + (size_t)*n * 3 * MIM_PAIR_JOINTS, fr, (size_t)nf * 3 * MIM_PAIR_JOINTS * sizeof *fr);
        *frames = grown, *n += nf;
        free(fr);
    }
    return 0;
}

int mim_cli_samples_read(const char *cmd, const char *path, mim_pairs_samples_t *s)
{
    mim_error_t err = {0};
    char *text = NULL;
    size_t len;
    const int rc = mim_file_read(path, 0, &text, &len, &err) || mim_pairs_samples_parse(text, len, path, s, &err);
    if (rc) fprintf(stderr, "mimic %s: %s\n", cmd, mim_error_text(&err));
    free(text);
    return rc ? -1 : 0;
}

int mim_cli_pairs_write(const char *cmd, const char *path, const void *text, size_t len)
{
    mim_error_t err = {0};
    mim_file_part_t part = {text, len};
    if (!mim_file_write_atomic(path, &part, 1, &err)) return 0;
    fprintf(stderr, "mimic %s: %s\n", cmd, mim_error_text(&err));
    return -1;
}

int mim_cli_pairs_write_samples(const char *cmd, const char *path, const double *joints, const double *log_density,
                                uint32_t n)
{
    /* the whole file in memory, then written atomically: nothing half-written */
    char *buf = NULL, *h = mim_pairs_jsonl_header();
    size_t len = 0;
    FILE *mem = open_memstream(&buf, &len);
    int ok = mem && h && fprintf(mem, "%s\n", h) > 0;
    for (uint32_t i = 0; ok && i < n; i++) {
        char *line = mim_pairs_jsonl_line(joints + (size_t)i * 3 * MIM_PAIR_JOINTS, log_density ? log_density[i] : NAN);
        ok = line && fprintf(mem, "%s\n", line) > 0;
        free(line);
    }
    if (mem) fclose(mem);
    free(h);
    if (!ok) {
        free(buf);
        fprintf(stderr, "mimic %s: out of memory for %u pose-pairs\n", cmd, n);
        return -1;
    }
    int rc = mim_cli_pairs_write(cmd, path, buf, len);
    free(buf);
    return rc;
}
