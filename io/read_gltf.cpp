// tinygltf shim: reads the first primitive of the first mesh of a glTF or
// GLB file into plain arrays. POSITION is taken as stored, which for a
// skinned mesh is its bind pose; node transforms are not applied. Every
// accessor range is checked against its buffer before it is read, because
// the file is untrusted. No C++ type or exception crosses into C.
//
// External files (buffer and image URIs that are not data: URIs) are read
// only from the folder that holds the glTF file and below it. tinygltf
// 2.7 (Debian) percent-decodes such a URI, joins it to the base folder we
// give it, and tries that, then the same name relative to the current
// directory, through its FsCallbacks (FileExists, then ReadWholeFile). The
// guard sits in those callbacks, where the path is final whatever way the
// JSON spelled it: an absolute path, a scheme (file:, http:, a data: URI
// tinygltf does not decode), a path whose `..` climb out of the folder, a
// symlink whose real path (realpath) lies outside it, a NUL byte, or
// anything but a regular file is refused, and the read fails with one line.
// The current-directory fallback is never taken.
#include "read_shim.h"

#include <tiny_gltf.h>

#include <cctype>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace {

// The folder external files may come from, and the first refusal.
struct fs_guard {
    std::string root;    // real path of the glTF file's folder
    std::string prefix;  // root with a trailing '/': how tinygltf joins a URI to it
    std::string refused; // one line, or empty
};

void refuse(fs_guard *g, const std::string &uri, const std::string &why)
{
    if (!g->refused.empty()) return;
    std::string shown = uri.size() > 120 ? uri.substr(0, 120) + "..." : uri;
    g->refused = "external file '" + shown + "' refused: it " + why +
                 " (glTF buffers and images must be data: URIs or files in the glTF file's folder)";
}

bool has_scheme(const std::string &u)
{
    // RFC 3986: ALPHA *( ALPHA / DIGIT / "+" / "-" / "." ) ":"
    if (u.empty() || !std::isalpha(static_cast<unsigned char>(u[0]))) return false;
    for (size_t i = 1; i < u.size(); i++) {
        unsigned char c = static_cast<unsigned char>(u[i]);
        if (c == ':') return true;
        if (!std::isalnum(c) && c != '+' && c != '-' && c != '.') return false;
    }
    return false;
}

// Whether tinygltf may read `path` (a URI joined to the base folder).
// Returns 1 and the real path when allowed; 0 when there is no such file;
// -1 when refused (recorded in g).
int judge(fs_guard *g, const std::string &path, std::string *real)
{
    if (path.compare(0, g->prefix.size(), g->prefix) != 0)
        return 0; // tinygltf's fallback to the current directory: never
    const std::string uri = path.substr(g->prefix.size());
    if (uri.empty()) return 0;
    if (uri.find('\0') != std::string::npos) return refuse(g, uri.c_str(), "holds a NUL byte"), -1;
    if (uri[0] == '/') return refuse(g, uri, "is an absolute path"), -1;
    if (has_scheme(uri))
        return refuse(g, uri, "is a URI with the scheme '" + uri.substr(0, uri.find(':') + 1) + "'"), -1;
    long depth = 0; // lexically, before any symlink: a/../.. climbs out
    for (size_t at = 0; at <= uri.size();) {
        size_t end = uri.find('/', at);
        if (end == std::string::npos) end = uri.size();
        std::string part = uri.substr(at, end - at);
        if (part == "..") {
            if (--depth < 0) return refuse(g, uri, "leaves the glTF file's folder"), -1;
        } else if (!part.empty() && part != ".") {
            depth++;
        }
        at = end + 1;
    }
    char buf[PATH_MAX];
    if (!::realpath(path.c_str(), buf)) return 0; // no such file: tinygltf says "File not found"
    std::string r(buf);
    if (r.compare(0, g->prefix.size(), g->prefix) != 0)
        return refuse(g, uri, "resolves to " + r + ", outside the glTF file's folder"), -1;
    struct stat st;
    if (::stat(buf, &st) != 0) return 0;
    if (!S_ISREG(st.st_mode)) return refuse(g, uri, "is not a regular file"), -1;
    *real = r;
    return 1;
}

bool guarded_exists(const std::string &path, void *ud)
{
    std::string real;
    return judge(static_cast<fs_guard *>(ud), path, &real) == 1;
}

std::string guarded_expand(const std::string &path, void *) { return path; } // no ~ or $VAR expansion

bool guarded_read(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *ud)
{
    fs_guard *g = static_cast<fs_guard *>(ud);
    std::string real;
    if (judge(g, path, &real) != 1) {
        if (err) *err += g->refused.empty() ? "not found" : g->refused;
        return false;
    }
    // the real path, its last step not a symlink: what was judged is what is read
    int fd = ::open(real.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
    struct stat st;
    if (fd < 0 || ::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        if (err) *err += std::string("cannot open: ") + std::strerror(errno);
        if (fd >= 0) ::close(fd);
        return false;
    }
    out->resize(size_t(st.st_size));
    size_t done = 0;
    while (done < out->size()) {
        ssize_t n = ::read(fd, out->data() + done, out->size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        done += size_t(n);
    }
    ::close(fd);
    out->resize(done);
    return true;
}

bool refuse_write(std::string *err, const std::string &, const std::vector<unsigned char> &, void *)
{
    if (err) *err += "writing is not allowed while reading";
    return false;
}

bool skip_image(tinygltf::Image *, const int, std::string *, std::string *, int, int, const unsigned char *, int,
                void *)
{
    return true; // images play no part in a template mesh
}

int fail(mim__raw_mesh_t *out, int code, const std::string &msg)
{
    out->library_failed = 1;
    std::snprintf(out->library_msg, sizeof out->library_msg, "%s", msg.c_str());
    return code;
}

// Locates accessor data; returns nullptr (with a message) when out of range.
const unsigned char *accessor_data(const tinygltf::Model &m, int index, size_t elem_size, size_t *stride,
                                   std::string *why)
{
    if (index < 0 || size_t(index) >= m.accessors.size()) {
        *why = "accessor index out of range";
        return nullptr;
    }
    const tinygltf::Accessor &a = m.accessors[size_t(index)];
    if (a.sparse.isSparse) {
        *why = "sparse accessors are not supported";
        return nullptr;
    }
    if (a.bufferView < 0 || size_t(a.bufferView) >= m.bufferViews.size()) {
        *why = "accessor without a valid bufferView";
        return nullptr;
    }
    const tinygltf::BufferView &bv = m.bufferViews[size_t(a.bufferView)];
    if (bv.buffer < 0 || size_t(bv.buffer) >= m.buffers.size()) {
        *why = "bufferView without a valid buffer";
        return nullptr;
    }
    const std::vector<unsigned char> &buf = m.buffers[size_t(bv.buffer)].data;
    size_t st = bv.byteStride ? bv.byteStride : elem_size;
    if (st < elem_size) {
        *why = "byteStride smaller than the element";
        return nullptr;
    }
    // The last element must end inside the view, and the view inside the buffer.
    if (bv.byteOffset > buf.size() || bv.byteLength > buf.size() - bv.byteOffset) {
        *why = "bufferView runs past the end of its buffer (truncated file?)";
        return nullptr;
    }
    if (a.count > 0) {
        if (a.byteOffset > bv.byteLength || (a.count - 1) > (bv.byteLength - a.byteOffset) / st ||
            (a.count - 1) * st + elem_size > bv.byteLength - a.byteOffset) {
            *why = "accessor runs past the end of its bufferView (truncated file?)";
            return nullptr;
        }
    }
    *stride = st;
    return buf.data() + bv.byteOffset + a.byteOffset;
}

uint32_t read_index(const unsigned char *p, int component)
{
    switch (component) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return *p;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t v;
        std::memcpy(&v, p, 2);
        return v;
    }
    default: {
        uint32_t v;
        std::memcpy(&v, p, 4);
        return v;
    }
    }
}

} // namespace

extern "C" int mim__gltf_read(const char *path, mim__raw_mesh_t *out)
{
    std::memset(out, 0, sizeof *out);
    out->first_bad_face = -1;
    char *bytes = nullptr;
    try {
        tinygltf::TinyGLTF loader;
        loader.SetImageLoader(skip_image, nullptr);
        tinygltf::Model model;
        std::string err, warn, p(path);
        bool glb = p.size() >= 4 && (p.compare(p.size() - 4, 4, ".glb") == 0 || p.compare(p.size() - 4, 4, ".GLB") == 0);
        // external files only from the folder that holds the file (see the top)
        fs_guard guard;
        size_t slash = p.find_last_of('/');
        std::string dir = slash == std::string::npos ? "." : slash == 0 ? "/" : p.substr(0, slash);
        char real[PATH_MAX];
        if (!::realpath(dir.c_str(), real))
            return fail(out, MIM_EIO, std::string("cannot resolve its folder: ") + std::strerror(errno));
        guard.root = real;
        guard.prefix = guard.root == "/" ? guard.root : guard.root + "/";
        tinygltf::FsCallbacks fs;
        fs.FileExists = guarded_exists;
        fs.ExpandFilePath = guarded_expand;
        fs.ReadWholeFile = guarded_read;
        fs.WriteWholeFile = refuse_write;
        fs.user_data = &guard;
        loader.SetFsCallbacks(fs);
        // the file itself is read here, so every read tinygltf makes is an external one
        size_t len = 0;
        mim_error_t rerr = {};
        int rrc = mim_file_read(path, 0, &bytes, &len, &rerr);
        if (rrc) return fail(out, rrc == MIM_ENOMEM ? MIM_ENOMEM : MIM_EIO, rerr.msg);
        if (len > UINT_MAX) {
            std::free(bytes);
            return fail(out, MIM_EUNSUPPORTED, "larger than 4 GiB");
        }
        bool ok = glb ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<unsigned char *>(bytes),
                                                    unsigned(len), guard.root)
                      : loader.LoadASCIIFromString(&model, &err, &warn, bytes, unsigned(len), guard.root);
        std::free(bytes);
        bytes = nullptr;
        if (!guard.refused.empty()) return fail(out, MIM_EUNSUPPORTED, guard.refused);
        if (!ok) {
            for (char &c : err)
                if (c == '\n' || c == '\r') c = ' ';
            while (!err.empty() && err.back() == ' ') err.pop_back();
            return fail(out, MIM_EFORMAT, "tinygltf: " + (err.empty() ? std::string("cannot parse") : err));
        }
        if (model.meshes.empty() || model.meshes[0].primitives.empty()) return fail(out, MIM_EEMPTY, "no mesh primitive");
        const tinygltf::Primitive &prim = model.meshes[0].primitives[0];
        auto pos_it = prim.attributes.find("POSITION");
        if (pos_it == prim.attributes.end()) return fail(out, MIM_EFORMAT, "first primitive has no POSITION");
        const tinygltf::Accessor &pa = model.accessors.at(size_t(pos_it->second));
        if (pa.type != TINYGLTF_TYPE_VEC3 || pa.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
            return fail(out, MIM_EUNSUPPORTED, "POSITION is not float VEC3");
        std::string why;
        size_t pstride = 0;
        const unsigned char *pdata = accessor_data(model, pos_it->second, 12, &pstride, &why);
        if (!pdata) return fail(out, MIM_ETRUNCATED, "POSITION: " + why);
        if (pa.count > UINT32_MAX) return fail(out, MIM_EFORMAT, "too many vertices");
        uint32_t nv = uint32_t(pa.count);

        std::vector<uint32_t> idx;
        if (prim.indices >= 0) {
            const tinygltf::Accessor &ia = model.accessors.at(size_t(prim.indices));
            size_t isz = ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                         : ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                         : ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                                      : 0;
            if (!isz || ia.type != TINYGLTF_TYPE_SCALAR) return fail(out, MIM_EFORMAT, "indices are not unsigned scalars");
            size_t istride = 0;
            const unsigned char *idata = accessor_data(model, prim.indices, isz, &istride, &why);
            if (!idata) return fail(out, MIM_ETRUNCATED, "indices: " + why);
            idx.resize(ia.count);
            for (size_t i = 0; i < ia.count; i++) idx[i] = read_index(idata + i * istride, ia.componentType);
        } else {
            idx.resize(nv);
            for (uint32_t i = 0; i < nv; i++) idx[i] = i;
        }

        // Triangles from the primitive's mode (strips and fans unrolled).
        std::vector<uint32_t> tris;
        int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
        if (mode == TINYGLTF_MODE_TRIANGLES) {
            if (idx.size() % 3) return fail(out, MIM_EFORMAT, "triangle index count is not a multiple of 3");
            tris = idx;
        } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
            for (size_t i = 2; i < idx.size(); i++) {
                bool odd = i & 1;
                tris.push_back(idx[i - 2]);
                tris.push_back(odd ? idx[i] : idx[i - 1]);
                tris.push_back(odd ? idx[i - 1] : idx[i]);
            }
        } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
            for (size_t i = 2; i < idx.size(); i++) {
                tris.push_back(idx[0]);
                tris.push_back(idx[i - 1]);
                tris.push_back(idx[i]);
            }
        } else {
            return fail(out, MIM_EUNSUPPORTED, "primitive mode is points or lines, not triangles");
        }
        if (tris.size() / 3 > UINT32_MAX) return fail(out, MIM_EFORMAT, "too many faces");

        int rc = mim_mesh_alloc(&out->mesh, nv, uint32_t(tris.size() / 3));
        if (rc) return rc;
        for (uint32_t i = 0; i < nv; i++) std::memcpy(out->mesh.positions + 3 * size_t(i), pdata + size_t(i) * pstride, 12);
        if (!tris.empty()) std::memcpy(out->mesh.faces, tris.data(), tris.size() * sizeof(uint32_t));
        out->n_polygons = tris.size() / 3;
        out->n_polygon_refs = tris.size();
        for (size_t t = 0; t < tris.size(); t++)
            if (tris[t] >= nv) {
                out->first_bad_face = int64_t(t / 3);
                out->bad_index = tris[t];
                break;
            }
        return 0;
    } catch (const std::bad_alloc &) {
        std::free(bytes);
        mim_mesh_free(&out->mesh);
        return MIM_ENOMEM;
    } catch (const std::exception &e) {
        std::free(bytes);
        mim_mesh_free(&out->mesh);
        return fail(out, MIM_EFORMAT, std::string("tinygltf: ") + e.what());
    } catch (...) {
        std::free(bytes);
        mim_mesh_free(&out->mesh);
        return fail(out, MIM_EFORMAT, "tinygltf failed");
    }
}
