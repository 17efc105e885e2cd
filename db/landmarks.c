/* The store's landmark map, kept as the same JSON a landmark file holds. */
#include "internal.h"

#include <stdlib.h>
#include <string.h>

int mim_db_landmarks_get(mim_db_txn_t *t, mim_landmark_map_t *out, mim_error_t *err)
{
    MDB_val k = {3, "map"}, v;
    int rc = mdb_get(t->txn, t->db->dbi[DBI_LANDMARKS], &k, &v);
    if (rc == MDB_NOTFOUND) return MIM_ENOTFOUND;
    if (rc) return mim__db_fail(err, rc, "store landmarks");
    return mim_landmarks_parse(out, v.mv_data, v.mv_size, "store landmark map", err);
}

int mim_db_landmarks_put(mim_db_txn_t *t, const mim_landmark_map_t *map, mim_error_t *err)
{
    char *json = mim_landmarks_to_json(map);
    if (!json) return MIM_ENOMEM;
    MDB_val k = {3, "map"}, v = {strlen(json), json};
    int rc = mdb_put(t->txn, t->db->dbi[DBI_LANDMARKS], &k, &v, 0);
    free(json);
    return rc ? mim__db_fail(err, rc, "store landmarks") : 0;
}
