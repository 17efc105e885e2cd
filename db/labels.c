/* Labels in a store of several datasets (issue 30): a template's subject
 * and pose are its dataset's own, so that one dataset's subject "0" is not
 * another's, and a pose class never merges two datasets' poses unless the
 * user maps them (mimic index --pose-map). Where a store holds one dataset
 * the labels stay as they are. */
#include "mim_db.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int mim_db_datasets_several(uint32_t n, const char *const *datasets)
{
    for (uint32_t i = 1; i < n; i++)
        if (strcmp(datasets[i] ? datasets[i] : "", datasets[0] ? datasets[0] : "")) return 1;
    return 0;
}

int mim_db_labels_qualify(uint32_t n, const char *const *datasets, char **labels, const unsigned char *keep)
{
    if (!mim_db_datasets_several(n, datasets)) return 0;
    for (uint32_t i = 0; i < n; i++) {
        const char *d = datasets[i] ? datasets[i] : "";
        if ((keep && keep[i]) || !d[0] || !labels[i] || !labels[i][0]) continue;
        size_t len = strlen(d) + 1 + strlen(labels[i]) + 1;
        char *q = malloc(len);
        if (!q) return MIM_ENOMEM;
        snprintf(q, len, "%s/%s", d, labels[i]);
        free(labels[i]);
        labels[i] = q;
    }
    return 0;
}
