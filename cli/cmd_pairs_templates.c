/* placeholder: mimic pairs templates (being written) */
#include "commands.h"
#include <stdio.h>
int mim_cmd_pairs_templates(int argc, char **argv) { (void)argc, (void)argv; fprintf(stderr, "mimic pairs templates: not yet\n"); return 2; }
