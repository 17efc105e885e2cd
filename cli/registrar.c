/* What --register and mimic register share: the store's index and a
 * registrar that starts each registration from the nearest template. */
#include "args.h"
#include "mim_ingest.h"
#include "mim_query.h"

#include <stdio.h>

int mim_cli_registrar_open(mim_db_t *db, const char *cmd, mim_query_t **q, mim_ingest_registrar_t **r)
{
    mim_error_t err = {0};
    int rc = mim_query_open(q, db, &err);
    if (rc == MIM_ENOTFOUND) {
        fprintf(stderr,
                "mimic %s: %s: registration starts from the nearest template, and the store has no index: run mimic "
                "index --store %s\n",
                cmd, mim_db_path(db), mim_db_path(db));
        return 2;
    }
    if (!rc) rc = mim_ingest_registrar_open(r, db, mim_query_nearest, *q, NULL, &err);
    if (rc) {
        fprintf(stderr, "mimic %s: %s\n", cmd, mim_error_text(&err));
        mim_query_close(q);
        return 2;
    }
    return 0;
}
