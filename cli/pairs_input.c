/* What every `mimic pairs` command reads: pose-pairs from two motion
 * files of one take (--pair/--truth/--prior A.bvh,B.bvh), with the root
 * translation kept (vest/'s joint motion), the 17 joints of each person
 * (sample/'s schemes or --joint-map) and the unit (guessed from the
 * person's size, or --unit). */
#include "pairs_input.h"

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

int mim_cli_pairs_read(const char *spec, const char *joint_map, double unit, uint32_t every, uint32_t offset,
                       double **frames, uint32_t *n_frames, char *msg, size_t size)
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
        }
    }
    *frames = out, *n_frames = count;
    rc = 0;
done:
    mim_vest_joint_motion_free(&ma);
    mim_vest_joint_motion_free(&mb);
    return rc;
}
