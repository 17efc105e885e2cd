/* session/ internals shared between its files (not installed). */
#ifndef MIM_SESSION_INTERNAL_H
#define MIM_SESSION_INTERNAL_H

#include "mim_session.h"

/* Every template's landmark positions (count * map count * 3 floats, id
 * order) and subject labels, read from the store on first use and kept
 * until close (complete.c scans them). Thread-safe. */
int mim__session_landmark_table(mim_session_t *s, const float **lm, char *const **subjects, uint32_t *count,
                                mim_error_t *err);

#endif
