/* sample/ internals shared between its files (not installed). */
#ifndef MIM_SAMPLE_INTERNAL_H
#define MIM_SAMPLE_INTERNAL_H

#include "mim_sample.h"

#include <jansson.h>

/* The 34 joint labels of the files, "A.head" ... "B.neck", as a JSON
 * array (a new reference; NULL when out of memory): the samples' header
 * and the annotations name their joints with it, and their readers check
 * against it. */
json_t *mim__pairs_joint_labels(void);

#endif
