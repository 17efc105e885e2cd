/* What the command line shows of the libraries' work: their log lines and
 * progress, through the callbacks of mim_core.h. The one place that turns
 * them into text on stderr. */
#ifndef MIM_CLI_OUTPUT_H
#define MIM_CLI_OUTPUT_H

#include "mim_core.h"

/* A mim_log_fn: "mimic: MSG" as one line on stderr, after ending a progress
 * line being drawn. Safe from any thread; ctx and level are not used. */
void mim_cli_log(void *ctx, int level, const char *msg);
/* The same line for the cli's own notes. */
void mim_cli_logf(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* A mim_progress_fn: one terminal line, "LABEL: DONE/TOTAL (P%) R/s ETA Ns"
 * (or "LABEL: DONE R/s" when the total is unknown), redrawn at most ~8
 * times a second and once more with a newline at the end. Drawn when
 * stderr is a terminal, unless MIMIC_PROGRESS=1 forces it on or =0 off.
 * One progress line at a time (stderr has one); ctx is not used. */
void mim_cli_progress(void *ctx, int phase, const char *label, uint64_t done, uint64_t total);

#endif
