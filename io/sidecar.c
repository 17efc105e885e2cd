/* The landmark file beside a mesh: scan.ply goes with
 * scan.landmarks.json, so that a folder of meshes can carry one landmark
 * file per mesh without a manifest. */
#include "mim_io.h"

#include <string.h>
#include <sys/stat.h>

int mim_io_landmarks_sidecar(const char *mesh_path, char *out, size_t size)
{
    if (!mesh_path || !out || size == 0)
        return MIM_EINVAL;
    const char *slash = strrchr(mesh_path, '/');
    const char *base = slash ? slash + 1 : mesh_path;
    const char *dot = strrchr(base, '.');
    /* A leading dot starts a hidden name, not an extension. */
    size_t stem = dot && dot != base ? (size_t)(dot - mesh_path) : strlen(mesh_path);
    static const char suffix[] = ".landmarks.json";
    if (size < sizeof suffix || stem > size - sizeof suffix) {
        out[0] = '\0';
        return MIM_EINVAL;
    }
    memcpy(out, mesh_path, stem);
    memcpy(out + stem, suffix, sizeof suffix);
    struct stat st;
    return stat(out, &st) == 0 && S_ISREG(st.st_mode);
}
