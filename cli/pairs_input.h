/* Reading pose-pairs for the `mimic pairs` commands (pairs_input.c). */
#ifndef MIM_CLI_PAIRS_INPUT_H
#define MIM_CLI_PAIRS_INPUT_H

#include <stddef.h>
#include <stdint.h>

/* spec "A.bvh,B.bvh": frames offset, offset + every, ... of the take as
 * pose-pairs (34 x 3 doubles each, metres; malloc'd into *frames).
 * joint_map: a --joint-map file's text or NULL; unit: metres per unit, or
 * 0 to guess it. On failure -1 with one line in msg (no "mimic" prefix). */
int mim_cli_pairs_read(const char *spec, const char *joint_map, double unit, uint32_t every, uint32_t offset,
                       double **frames, uint32_t *n_frames, char *msg, size_t size);

#endif
