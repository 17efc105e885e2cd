// tinygltf shim: reads the first primitive of the first mesh of a glTF or
// GLB file into plain arrays, and on request its skin (JOINTS_0, WEIGHTS_0
// and the names of the skin's joint nodes) from the same parse. POSITION
// is taken as stored, which for a skinned mesh is its bind pose; node
// transforms are not applied. Every accessor range is checked against its
// buffer before it is read, because the file is untrusted. No C++ type or
// exception crosses into C.
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
int load_model(const char *path, tinygltf::Model *model, mim__raw_mesh_t *out)
{
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(skip_image, nullptr);
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

// The first primitive of the first mesh, triangulated, into out->mesh.
int read_mesh(const tinygltf::Model &model, mim__raw_mesh_t *out)
{
    if (model.meshes.empty() || model.meshes[0].primitives.empty()) return fail(out, MIM_EEMPTY, "no mesh primitive");
    const tinygltf::Primitive &prim = model.meshes[0].primitives[0];
    auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) return fail(out, MIM_EFORMAT, "first primitive has no POSITION");
    const tinygltf::Accessor &pa = model.accessors.at(size_t(pos_it->second));
    if (pa.type != TINYGLTF_TYPE_VEC3 || pa.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
        return fail(out, MIM_EUNSUPPORTED, "POSITION is not float VEC3");
    std::string why;
    int code = 0;
    size_t pstride = 0;
    const unsigned char *pdata = accessor_data(model, pos_it->second, 12, &pstride, &why, &code);
    if (!pdata) return fail(out, code, "POSITION: " + why);
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
        const unsigned char *idata = accessor_data(model, prim.indices, isz, &istride, &why, &code);
        if (!idata) return fail(out, code, "indices: " + why);
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
}

// ---- the skin of that primitive ----

int skin_fail_nothrow(mim__raw_skin_t *s, int code, const char *msg) noexcept
{
    mim_io_skin_free(&s->skin);
    s->rc = code;
    std::snprintf(s->msg, sizeof s->msg, "%s", msg);
    return code;
}

int skin_fail(mim__raw_skin_t *s, int code, const std::string &msg) { return skin_fail_nothrow(s, code, msg.c_str()); }

std::string type_name(int type)
{
    switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "type " + std::to_string(type);
    }
}

std::string component_name(int c, bool normalized)
{
    std::string n = normalized ? "normalised " : "";
    switch (c) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return n + "byte";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return n + "unsigned byte";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return n + "short";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return n + "unsigned short";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return n + "unsigned int";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return n + "float";
    default: return "component type " + std::to_string(c);
    }
}

// A node name into a fixed field, cut before a character that does not fit
// whole (UTF-8) and at an embedded NUL.
void copy_name(char *dst, const std::string &src)
{
    size_t n = std::min(src.find('\0'), src.size());
    if (n > MIM_IO_SKIN_NAME_MAX - 1) {
        n = MIM_IO_SKIN_NAME_MAX - 1;
        while (n > 0 && (static_cast<unsigned char>(src[n]) & 0xC0) == 0x80) n--; // src[n] continues a character
    }
    std::memcpy(dst, src.data(), n);
    dst[n] = '\0';
}

// JOINTS_0 / WEIGHTS_0 of the primitive and the joint names of its skin:
// the skin of the first node that instantiates mesh 0 with one, else
// skins[0] (a file may hold skins but no node that says which). JOINTS_1 /
// WEIGHTS_1 (a fifth influence and more) are ignored. Everything the
// glTF 2.0 spec (3.7.3) requires of these is checked, as the file is
// untrusted: types, counts, index ranges, weights >= 0 and finite.
int read_skin(const tinygltf::Model &m, uint32_t nv, mim__raw_skin_t *s)
{
    const tinygltf::Primitive &prim = m.meshes[0].primitives[0];
    auto jit = prim.attributes.find("JOINTS_0"), wit = prim.attributes.find("WEIGHTS_0");
    bool has_j = jit != prim.attributes.end(), has_w = wit != prim.attributes.end();
    if (!has_j || !has_w)
        return skin_fail(s, MIM_ENOTFOUND,
                         !has_j && !has_w ? "no skin: the first primitive has no JOINTS_0 and no WEIGHTS_0"
                         : !has_j         ? "no skin: the first primitive has WEIGHTS_0 but no JOINTS_0"
                                          : "no skin: the first primitive has JOINTS_0 but no WEIGHTS_0");
    int si = -1;
    for (size_t n = 0; n < m.nodes.size() && si < 0; n++) {
        const tinygltf::Node &node = m.nodes[n];
        if (node.mesh != 0 || node.skin < 0) continue;
        if (size_t(node.skin) >= m.skins.size())
            return skin_fail(s, MIM_EFORMAT, "node " + std::to_string(n) + " refers to skin " +
                                                 std::to_string(node.skin) + ", but there are " +
                                                 std::to_string(m.skins.size()) + " skins");
        si = node.skin;
    }
    if (si < 0) {
        if (m.skins.empty()) return skin_fail(s, MIM_ENOTFOUND, "no skin: JOINTS_0 and WEIGHTS_0 but no skins");
        si = 0;
    }
    const tinygltf::Skin &sk = m.skins[size_t(si)];
    const std::string skin_name = "skin " + std::to_string(si);
    if (sk.joints.empty()) return skin_fail(s, MIM_EFORMAT, skin_name + " has no joints");
    if (sk.joints.size() > UINT32_MAX) return skin_fail(s, MIM_EFORMAT, skin_name + " has too many joints");
    const uint32_t nj = uint32_t(sk.joints.size());
    for (uint32_t k = 0; k < nj; k++) {
        int node = sk.joints[k];
        if (node < 0 || size_t(node) >= m.nodes.size())
            return skin_fail(s, MIM_EFORMAT, skin_name + ": joint " + std::to_string(k) + " is node " +
                                                 std::to_string(node) + ", not a valid node index (" +
                                                 std::to_string(m.nodes.size()) + " nodes)");
    }

    // The two accessors: their types first, then their data, range-checked.
    const int attr_index[2] = {jit->second, wit->second};
    const char *const attr_name[2] = {"JOINTS_0", "WEIGHTS_0"};
    const unsigned char *data[2];
    size_t stride[2], csize[2];
    int ctype[2];
    for (int i = 0; i < 2; i++) {
        const std::string an = attr_name[i];
        if (attr_index[i] < 0 || size_t(attr_index[i]) >= m.accessors.size())
            return skin_fail(s, MIM_EFORMAT, an + ": accessor " + std::to_string(attr_index[i]) + " does not exist (" +
                                                 std::to_string(m.accessors.size()) + " accessors)");
        const tinygltf::Accessor &a = m.accessors[size_t(attr_index[i])];
        int c = a.componentType;
        size_t cs = c == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ? 1 : c == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2 : 0;
        bool ok = a.type == TINYGLTF_TYPE_VEC4 &&
                  (i == 0 ? cs != 0 && !a.normalized
                          : c == TINYGLTF_COMPONENT_TYPE_FLOAT ? !a.normalized : cs != 0 && a.normalized);
        if (i == 1 && c == TINYGLTF_COMPONENT_TYPE_FLOAT) cs = 4;
        if (!ok)
            return skin_fail(s, MIM_EFORMAT, an + " is " + type_name(a.type) + " of " +
                                                 component_name(c, a.normalized) + ", not VEC4 of " +
                                                 (i == 0 ? "unsigned byte or unsigned short"
                                                         : "float or normalised unsigned byte or unsigned short"));
        if (a.count != nv)
            return skin_fail(s, MIM_EFORMAT, an + " has " + std::to_string(a.count) + " elements, POSITION " +
                                                 std::to_string(nv));
        std::string why;
        int code = 0;
        data[i] = accessor_data(m, attr_index[i], 4 * cs, &stride[i], &why, &code);
        if (!data[i]) return skin_fail(s, code, an + ": " + why);
        csize[i] = cs;
        ctype[i] = c;
    }

    mim_io_skin_t *o = &s->skin;
    const size_t n4 = 4 * size_t(nv) + 4; // + 4: never malloc(0)
    o->joints = static_cast<uint16_t *>(std::malloc(n4 * sizeof *o->joints));
    o->weights = static_cast<float *>(std::malloc(n4 * sizeof *o->weights));
    o->names = static_cast<char(*)[MIM_IO_SKIN_NAME_MAX]>(std::calloc(nj, MIM_IO_SKIN_NAME_MAX));
    if (!o->joints || !o->weights || !o->names) return skin_fail(s, MIM_ENOMEM, "out of memory for the skin");
    o->n_vertices = nv;
    o->n_joints = nj;
    const double scale = ctype[1] == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1.0 / 255.0
                         : ctype[1] == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 1.0 / 65535.0
                                                                              : 1.0;
    for (uint32_t v = 0; v < nv; v++) {
        const unsigned char *jp = data[0] + size_t(v) * stride[0], *wp = data[1] + size_t(v) * stride[1];
        double w[4], sum = 0;
        for (int k = 0; k < 4; k++) {
            uint32_t j = read_index(jp + size_t(k) * csize[0], ctype[0]);
            if (j >= nj)
                return skin_fail(s, MIM_EFORMAT, "JOINTS_0: vertex " + std::to_string(v) + " refers to joint " +
                                                     std::to_string(j) + ", but " + skin_name + " has " +
                                                     std::to_string(nj) + " joints");
            o->joints[4 * size_t(v) + size_t(k)] = uint16_t(j);
            if (ctype[1] == TINYGLTF_COMPONENT_TYPE_FLOAT) {
                float f;
                std::memcpy(&f, wp + 4 * size_t(k), 4);
                w[k] = f;
            } else {
                w[k] = read_index(wp + size_t(k) * csize[1], ctype[1]) * scale;
            }
            if (!std::isfinite(w[k]) || w[k] < 0) {
                char num[32];
                std::snprintf(num, sizeof num, "%g", w[k]);
                return skin_fail(s, MIM_EFORMAT, "WEIGHTS_0: vertex " + std::to_string(v) + " has weight " + num +
                                                     ", not a finite number >= 0");
            }
            sum += w[k];
        }
        // The spec asks for a sum of 1; exporters round, and normalised integers rarely sum exactly.
        for (int k = 0; k < 4; k++) o->weights[4 * size_t(v) + size_t(k)] = sum > 0 ? float(w[k] / sum) : 0.0f;
    }
    for (uint32_t k = 0; k < nj; k++) copy_name(o->names[k], m.nodes[size_t(sk.joints[k])].name);
    s->rc = 0;
    s->msg[0] = '\0';
    return 0;
}

} // namespace

extern "C" int mim__gltf_read(const char *path, mim__raw_mesh_t *out, mim__raw_skin_t *skin)
{
    std::memset(out, 0, sizeof *out);
    out->first_bad_face = -1;
    if (skin) {
        std::memset(skin, 0, sizeof *skin);
        skin_fail_nothrow(skin, MIM_EFORMAT, "the skin was not read: the mesh could not be");
    }
    try {
        tinygltf::Model model;
        int rc = load_model(path, &model, out);
        if (!rc) rc = read_mesh(model, out);
        if (!rc && skin) read_skin(model, out->mesh.n_vertices, skin);
        return rc;
    } catch (const std::bad_alloc &) {
        mim_mesh_free(&out->mesh);
        if (skin) skin_fail_nothrow(skin, MIM_ENOMEM, "out of memory");
        return MIM_ENOMEM;
    } catch (const std::exception &e) {
        // no std::string here: building one may throw again
        mim_mesh_free(&out->mesh);
        if (skin) skin_fail_nothrow(skin, MIM_EFORMAT, "the skin was not read: the mesh could not be");
        out->library_failed = 1;
        std::snprintf(out->library_msg, sizeof out->library_msg, "tinygltf: %s", e.what());
        return MIM_EFORMAT;
    } catch (...) {
        mim_mesh_free(&out->mesh);
        if (skin) skin_fail_nothrow(skin, MIM_EFORMAT, "the skin was not read: the mesh could not be");
        out->library_failed = 1;
        std::snprintf(out->library_msg, sizeof out->library_msg, "tinygltf failed");
        return MIM_EFORMAT;
    }
}
