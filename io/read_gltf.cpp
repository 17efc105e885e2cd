// tinygltf shim, the loading half: parses a glTF or GLB file under the
// guard below, and locates accessor data with every range checked against
// its buffer, because the file is untrusted. gltf_scene.cpp walks the
// scene; write_gltf.cpp re-reads an avatar to keep its look.
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
#include "gltf_internal.hpp"

#include <tiny_gltf.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace mim_gltf {

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

// The image's bytes as they are in the file (PNG, JPEG, ...), undecoded:
// what a writer that keeps the avatar's look embeds again.
bool keep_image(tinygltf::Image *image, const int, std::string *, std::string *, int, int, const unsigned char *bytes,
                int size, void *)
{
    if (size < 0) return false;
    image->image.assign(bytes, bytes + size);
    image->as_is = true;
    return true;
}

int fail(std::string *msg, int code, const std::string &why)
{
    *msg = why;
    return code;
}

} // namespace

// Locates accessor data; returns nullptr, with a message and a code, when
// the accessor cannot be read: MIM_EFORMAT for a dangling index,
// MIM_EUNSUPPORTED for a sparse accessor, MIM_ETRUNCATED for data past the
// end of its view or buffer.
const unsigned char *accessor_data(const tinygltf::Model &m, int index, size_t elem_size, size_t *stride,
                                   std::string *why, int *code)
{
    *code = MIM_EFORMAT;
    if (index < 0 || size_t(index) >= m.accessors.size()) {
        *why = "accessor index out of range";
        return nullptr;
    }
    const tinygltf::Accessor &a = m.accessors[size_t(index)];
    if (a.sparse.isSparse) {
        *code = MIM_EUNSUPPORTED;
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
    *code = MIM_ETRUNCATED;
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
    *code = 0;
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

// The file, parsed by tinygltf under the guard (see the top). Returns 0,
// or a code with the reason in out (as the mesh's failure).
int load_model(const char *path, tinygltf::Model *model, bool images, std::string *out)
{
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(images ? keep_image : skip_image, nullptr);
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
    char *raw_bytes = nullptr;
    size_t len = 0;
    mim_error_t rerr = {};
    int rrc = mim_file_read(path, 0, &raw_bytes, &len, &rerr);
    if (rrc) return fail(out, rrc == MIM_ENOMEM ? MIM_ENOMEM : MIM_EIO, rerr.msg);
    std::unique_ptr<char, void (*)(void *)> bytes(raw_bytes, std::free); // freed on every way out
    if (len > UINT_MAX) return fail(out, MIM_EUNSUPPORTED, "larger than 4 GiB");
    bool ok = glb ? loader.LoadBinaryFromMemory(model, &err, &warn, reinterpret_cast<unsigned char *>(bytes.get()),
                                                unsigned(len), guard.root)
                  : loader.LoadASCIIFromString(model, &err, &warn, bytes.get(), unsigned(len), guard.root);
    if (!guard.refused.empty()) return fail(out, MIM_EUNSUPPORTED, guard.refused);
    if (!ok) {
        for (char &c : err)
            if (c == '\n' || c == '\r') c = ' ';
        while (!err.empty() && err.back() == ' ') err.pop_back();
        return fail(out, MIM_EFORMAT, "tinygltf: " + (err.empty() ? std::string("cannot parse") : err));
    }
    return 0;
}

} // namespace mim_gltf
