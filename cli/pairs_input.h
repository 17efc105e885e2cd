/* Reading pose-pairs for the `mimic pairs` commands (pairs_input.c). */
#ifndef MIM_CLI_PAIRS_INPUT_H
#define MIM_CLI_PAIRS_INPUT_H

#include "mim_sample.h"

#include <stddef.h>
#include <stdint.h>

/* A take's up axis (mim_axis_*): given (--up), or 0 to find it; then the
 * axis taken and how ("given", "found from the rest pose", "... frames"). */
typedef struct mim_cli_up {
    int axis;
    const char *how;
} mim_cli_up_t;
/* --up's option code (long only) */
#define MIM_CLI_OPT_UP 0x101

/* spec "A.bvh,B.bvh": frames offset, offset + every, ... of the take as
 * pose-pairs (34 x 3 doubles each, metres, turned so that the take's up
 * axis is +y; malloc'd into *frames). joint_map: a --joint-map file's
 * text or NULL; unit: metres per unit, or 0 to guess it; up: in and out,
 * as above. On failure -1 with one line in msg (no "mimic" prefix). */
int mim_cli_pairs_read(const char *spec, const char *joint_map, double unit, mim_cli_up_t *up, uint32_t every,
                       uint32_t offset, double **frames, uint32_t *n_frames, char *msg, size_t size);

/* What every pairs command takes: the takes (--pair, --truth or --prior
 * A,B), which of their frames (--every, --offset), and how to read them
 * (--joint-map, --unit, --up). Parsed and read here, once. */
#define MIM_CLI_MAX_TAKES 64
typedef struct mim_cli_takes {
    const char *cmd; /* "pairs coverage" ... */
    const char *spec[MIM_CLI_MAX_TAKES];
    int n;
    uint64_t every, offset;
    double unit;
    int up; /* --up (mim_axis_*), 0: found per take */
    const char *map_path;
    char *map_text;
} mim_cli_takes_t;

/* Option c with its argument, when it is one of the above ('p' a take,
 * 'e' every, 'k' offset, 'm' joint map, 'u' unit, MIM_CLI_OPT_UP up): 1
 * taken, -1 after printing a usage error, 0 not one of them. */
int mim_cli_takes_option(mim_cli_takes_t *t, int c, const char *arg);
/* Reads the joint map, if one was given: 0, or 1 after printing. */
int mim_cli_takes_begin(mim_cli_takes_t *t);
/* The chosen frames of take i as pose-pairs (mim_cli_pairs_read): 0, or
 * -1 after printing. */
int mim_cli_takes_read(const mim_cli_takes_t *t, int i, double **frames, uint32_t *n);
/* Every chosen frame of every take, one after the other: 0, or -1 after
 * printing. */
int mim_cli_takes_read_all(const mim_cli_takes_t *t, double **frames, uint32_t *n);
/* A samples file (schemas/pair-samples.md) into *s: 0, or -1 after
 * printing "mimic CMD: why" (unreadable, malformed: the parser's one line). */
int mim_cli_samples_read(const char *cmd, const char *path, mim_pairs_samples_t *s);
/* text to path, atomically (nothing half-written): 0, or -1 after printing
 * "mimic CMD: why". */
int mim_cli_pairs_write(const char *cmd, const char *path, const void *text, size_t len);

/* n pose-pairs (34 x 3 each) and their log densities (NULL: none) as a
 * samples file (schemas/pair-samples.md), written atomically: 0, or -1
 * after printing. */
int mim_cli_pairs_write_samples(const char *cmd, const char *path, const double *joints, const double *log_density,
                                uint32_t n);

#endif
