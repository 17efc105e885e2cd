/* session/ internals shared between its files (not installed). */
#ifndef MIM_SESSION_INTERNAL_H
#define MIM_SESSION_INTERNAL_H

#include "mim_session.h"

/* Every template's landmark positions (count * map count * 3 floats, id
 * order), subject labels and ids (ascending; ids may be NULL), read from
 * the store on first use and kept until close (complete.c scans them;
 * relative transfer finds references in them). Thread-safe. */
int mim__session_landmark_table(mim_session_t *s, const float **lm, char *const **subjects, const uint64_t **ids,
                                uint32_t *count, mim_error_t *err);

#endif
