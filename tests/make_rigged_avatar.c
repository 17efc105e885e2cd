/* A rigged glTF avatar (support/rigged_avatar.h):
 *
 *   make_rigged_avatar OUT.glb [--vertices N] [--seed S] [--subject K]
 *                      [--names mixamo|blender|vrm0|vrm1|none] [--tpose]
 *                      [--seams] [--flat] [--rings-first] [--shells] [--prop]
 *                      [--cm] [--fists] [--texture] [--two-primitives] [--all]
 *
 * --all turns on seams, rings-first, shells, prop, cm, fists, texture and
 * two-primitives (with Mixamo names unless --names says otherwise). Prints
 * {"vertices": N, "primitives": P} on stdout. Exit status 0, or 1 with a
 * one-line reason on stderr. */
#include "rigged_avatar.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int number(const char *s, unsigned long long max, unsigned long long *out)
{
    char *end;
    errno = 0;
    if (!s || !*s || *s == '-') return -1;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || *end || v > max) return -1;
    *out = v;
    return 0;
}

int main(int argc, char **argv)
{
    static const char *const schemes[] = {"mixamo", "blender", "vrm0", "vrm1", "none"};
    ra_options_t o = {0};
    const char *out = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
        unsigned long long v = 0;
        if (!strcmp(a, "--vertices") || !strcmp(a, "--seed") || !strcmp(a, "--subject")) {
            if (number(val, a[2] == 's' && a[3] == 'e' ? UINT64_MAX : UINT32_MAX, &v)) {
                fprintf(stderr, "make_rigged_avatar: %s needs a number, not '%s'\n", a, val ? val : "");
                return 1;
            }
            if (!strcmp(a, "--vertices"))
                o.vertices = (uint32_t)v;
            else if (!strcmp(a, "--seed"))
                o.seed = v;
            else
                o.subject = (uint32_t)v;
            i++;
        } else if (!strcmp(a, "--names")) {
            int k = 0;
            while (k < 5 && (!val || strcmp(val, schemes[k]))) k++;
            if (k == 5) {
                fprintf(stderr, "make_rigged_avatar: --names takes mixamo, blender, vrm0, vrm1 or none, not '%s'\n",
                        val ? val : "");
                return 1;
            }
            o.names = (ra_names_t)k;
            i++;
        } else if (!strcmp(a, "--tpose"))
            o.tpose = 1;
        else if (!strcmp(a, "--seams"))
            o.split_seams = 1;
        else if (!strcmp(a, "--flat"))
            o.flat = 1;
        else if (!strcmp(a, "--rings-first"))
            o.joint_rings_first = 1;
        else if (!strcmp(a, "--shells"))
            o.shells = 1;
        else if (!strcmp(a, "--prop"))
            o.prop = 1;
        else if (!strcmp(a, "--cm"))
            o.centimetres = 1;
        else if (!strcmp(a, "--fists"))
            o.fists = 1;
        else if (!strcmp(a, "--texture"))
            o.texture = 1;
        else if (!strcmp(a, "--two-primitives"))
            o.two_primitives = 1;
        else if (!strcmp(a, "--all"))
            o.split_seams = o.joint_rings_first = o.shells = o.prop = o.centimetres = o.fists = o.texture =
                o.two_primitives = 1;
        else if (a[0] != '-' && !out)
            out = a;
        else {
            fprintf(stderr, "make_rigged_avatar: unexpected argument '%s'\n", a);
            return 1;
        }
    }
    if (!out) {
        fprintf(stderr, "usage: make_rigged_avatar OUT.glb [--vertices N] [--seed S] [--subject K] "
                        "[--names mixamo|blender|vrm0|vrm1|none] [--tpose] [--seams] [--flat] [--rings-first] "
                        "[--shells] [--prop] [--cm] [--fists] [--texture] [--two-primitives] [--all]\n");
        return 1;
    }
    ra_avatar_info_t info;
    char why[512];
    if (ra_write(&o, out, &info, why, sizeof why)) {
        fprintf(stderr, "make_rigged_avatar: %s\n", why);
        return 1;
    }
    printf("{\"vertices\": %u, \"primitives\": %u}\n", info.n_vertices, info.n_primitives);
    ra_info_free(&info);
    return 0;
}
