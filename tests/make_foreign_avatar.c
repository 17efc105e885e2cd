/* A foreign avatar for tests/viewer_test.mjs (support/foreign_avatar.h):
 *
 *   make_foreign_avatar OUT.ply [--vertices N] [--seed S] [--subject K]
 *                       [--subdivisions D] [--shuffle SEED]
 *
 * writes OUT.ply (a synth body of seed S, subject K, at rest, subdivided D
 * times and shuffled) and OUT.landmarks.json beside it (its landmark
 * positions, the sidecar mimic looks for), and prints
 * {"vertices": N, "faces": F} on stdout. Exit status 0, or 1 with why. */
#include "foreign_avatar.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
    fa_options_t o = {.vertices = 2000, .seed = 7, .subdivisions = 1, .shuffle_seed = 11};
    const char *out = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        unsigned long long v = i + 1 < argc ? strtoull(argv[i + 1], NULL, 10) : 0;
        if (!strcmp(a, "--vertices") && i + 1 < argc) o.vertices = (uint32_t)v, i++;
        else if (!strcmp(a, "--seed") && i + 1 < argc) o.seed = v, i++;
        else if (!strcmp(a, "--subject") && i + 1 < argc) o.subject = (uint32_t)v, i++;
        else if (!strcmp(a, "--subdivisions") && i + 1 < argc) o.subdivisions = (uint32_t)v, i++;
        else if (!strcmp(a, "--shuffle") && i + 1 < argc) o.shuffle_seed = v, i++;
        else if (a[0] != '-' && !out) out = a;
        else {
            fprintf(stderr, "make_foreign_avatar: unexpected argument '%s'\n", a);
            return 1;
        }
    }
    const char *dot = out ? strrchr(out, '.') : NULL, *slash = out ? strrchr(out, '/') : NULL;
    if (!out || !dot || (slash && dot < slash)) {
        fprintf(stderr, "usage: make_foreign_avatar OUT.ply [--vertices N] [--seed S] [--subject K] "
                        "[--subdivisions D] [--shuffle SEED]\n");
        return 1;
    }
    char sidecar[4096];
    snprintf(sidecar, sizeof sidecar, "%.*s.landmarks.json", (int)(dot - out), out);
    fa_avatar_t av;
    char why[512];
    if (fa_make(&o, &av, why, sizeof why) || fa_write(&av, out, sidecar, -1, why, sizeof why)) {
        fprintf(stderr, "make_foreign_avatar: %s\n", why);
        fa_free(&av);
        return 1;
    }
    printf("{\"vertices\": %u, \"faces\": %u}\n", av.mesh.n_vertices, av.mesh.n_faces);
    fa_free(&av);
    return 0;
}
