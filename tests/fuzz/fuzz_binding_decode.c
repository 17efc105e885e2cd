/* libFuzzer harness: an avatar binding as the store's cache keeps it
 * (register/bind.c, mim_reg_binding_decode). The store checksums the
 * record, but a binding made for another proxy, or by a damaged writer,
 * must still be refused, never trusted: a decoded binding is applied to a
 * small proxy, which reads every face and vertex it names. The input's
 * first byte picks the proxy's size so that the counts can match. */
#include "mim_register.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    /* a strip of triangles over np vertices: nf = np - 2 */
    uint32_t np = 3 + data[0] % 32, nf = np - 2;
    uint32_t faces[3 * 32];
    float pos[3 * 35];
    for (uint32_t f = 0; f < nf; f++)
        faces[3 * f] = f, faces[3 * f + 1] = f + 1, faces[3 * f + 2] = f + 2;
    for (uint32_t v = 0; v < np; v++)
        pos[3 * v] = (float)v, pos[3 * v + 1] = (float)(v % 2), pos[3 * v + 2] = 0.0f;
    mim_reg_binding_t b;
    if (mim_reg_binding_decode(data + 1, size - 1, np, nf, &b, NULL) == 0) {
        float work[3 * 35];
        float *out = malloc(3 * (size_t)b.n_vertices * sizeof *out);
        if (out) mim_reg_binding_apply(&b, faces, pos, work, out);
        free(out);
        mim_reg_binding_free(&b);
    }
    return 0;
}
