/* placeholder: mimic pairs sample (being written) */
#include "commands.h"
#include <stdio.h>
int mim_cmd_pairs_sample(int argc, char **argv) { (void)argc, (void)argv; fprintf(stderr, "mimic pairs sample: not yet\n"); return 2; }
