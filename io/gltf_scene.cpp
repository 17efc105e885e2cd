// tinygltf shim, the scene half (issue 28): every primitive of the scene,
// placed in the world, and the scene's rig over all its skins (mim_io.h,
// "a glTF scene"). Avatars come as exporters write them: several meshes
// and primitives, the body not first, props under a hand's bone, a root
// node scaling centimetres to metres, VRM humanoid maps. Everything the
// glTF 2.0 spec (3.7.3, 3.5) asks of skins and nodes is checked, as the
// file is untrusted: types, counts, index ranges, finite transforms, a
// node graph that is a forest. No C++ type or exception crosses into C.
#include "gltf_internal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <new>
#include <string>
#include <vector>

namespace mim_gltf {

namespace {

mat4 identity()
{
    mat4 m{};
    m[0] = m[5] = m[10] = m[15] = 1;
    return m;
}

mat4 mul(const mat4 &a, const mat4 &b)
{
    mat4 r{};
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[size_t(k * 4 + row)] * b[size_t(c * 4 + k)];
            r[size_t(c * 4 + row)] = s;
        }
    return r;
}

bool finite_all(const std::vector<double> &v)
{
    for (double x : v)
        if (!std::isfinite(x)) return false;
    return true;
}

// A node's local transform: its matrix, or T * R * S (glTF 2.0 3.5.3).
bool local_matrix(const tinygltf::Node &n, mat4 *out, std::string *why)
{
    if (!n.matrix.empty()) {
        if (n.matrix.size() != 16 || !finite_all(n.matrix)) return *why = "a matrix that is not 16 finite numbers", false;
        std::copy(n.matrix.begin(), n.matrix.end(), out->begin());
        return true;
    }
    double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    if (!n.translation.empty()) {
        if (n.translation.size() != 3 || !finite_all(n.translation)) return *why = "a bad translation", false;
        std::copy(n.translation.begin(), n.translation.end(), t);
    }
    if (!n.rotation.empty()) {
        if (n.rotation.size() != 4 || !finite_all(n.rotation)) return *why = "a bad rotation", false;
        double l = std::sqrt(n.rotation[0] * n.rotation[0] + n.rotation[1] * n.rotation[1] +
                             n.rotation[2] * n.rotation[2] + n.rotation[3] * n.rotation[3]);
        if (!(l > 1e-6)) return *why = "a rotation quaternion of length 0", false;
        for (int k = 0; k < 4; k++) q[k] = n.rotation[size_t(k)] / l; // exporters round
    }
    if (!n.scale.empty()) {
        if (n.scale.size() != 3 || !finite_all(n.scale)) return *why = "a bad scale", false;
        std::copy(n.scale.begin(), n.scale.end(), s);
    }
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    const double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                         2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                         2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    mat4 &m = *out;
    m = identity();
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < 3; r++) m[size_t(c * 4 + r)] = R[c * 3 + r] * s[c];
    m[12] = t[0], m[13] = t[1], m[14] = t[2];
    return true;
}

bool selected(const tinygltf::Model &m, int node, int mesh, const mim_io_read_options_t *opt, std::vector<int> *hits)
{
    if (!opt || !opt->n_meshes) return true;
    bool any = false;
    for (uint32_t k = 0; k < opt->n_meshes; k++) {
        const char *want = opt->meshes[k];
        if (!want) continue;
        if (m.meshes[size_t(mesh)].name == want || (node >= 0 && m.nodes[size_t(node)].name == want))
            (*hits)[k]++, any = true;
    }
    return any;
}

} // namespace

int walk_scene(const tinygltf::Model &m, const mim_io_read_options_t *opt, std::vector<placed> *out,
               std::vector<mat4> *node_world, std::string *msg)
{
    const size_t n = m.nodes.size();
    out->clear();
    node_world->assign(n, identity());
    std::vector<int> parent(n, -1);
    for (size_t i = 0; i < n; i++)
        for (int c : m.nodes[i].children) {
            if (c < 0 || size_t(c) >= n)
                return *msg = "node " + std::to_string(i) + " has child " + std::to_string(c) + ", not a node (" +
                              std::to_string(n) + " nodes)",
                       MIM_EFORMAT;
            if (parent[size_t(c)] >= 0 || size_t(c) == i)
                return *msg = "node " + std::to_string(c) + " has two parents: the node graph is not a forest",
                       MIM_EFORMAT;
            parent[size_t(c)] = int(i);
        }
    std::vector<char> is_joint(n, 0);
    for (const tinygltf::Skin &sk : m.skins)
        for (int j : sk.joints)
            if (j >= 0 && size_t(j) < n) is_joint[size_t(j)] = 1;

    std::vector<int> roots;
    int scene = m.defaultScene >= 0 && size_t(m.defaultScene) < m.scenes.size() ? m.defaultScene
                : m.scenes.empty()                                               ? -1
                                                                                 : 0;
    if (scene >= 0) {
        for (int r : m.scenes[size_t(scene)].nodes) {
            if (r < 0 || size_t(r) >= n)
                return *msg = "scene " + std::to_string(scene) + " lists node " + std::to_string(r) + ", not a node",
                       MIM_EFORMAT;
            roots.push_back(r);
        }
    } else {
        for (size_t i = 0; i < n; i++)
            if (parent[i] < 0) roots.push_back(int(i));
    }

    std::vector<int> hits(opt ? opt->n_meshes : 0, 0);
    std::vector<char> seen(n, 0);
    std::vector<int> bone(n, -1);
    bool any_mesh_node = false;
    // depth first, children in their order: a stack of (node, parent world's owner)
    std::vector<int> stack(roots.rbegin(), roots.rend());
    std::vector<char> is_root(n, 0);
    for (int r : roots) is_root[size_t(r)] = 1;
    while (!stack.empty()) {
        const int i = stack.back();
        stack.pop_back();
        if (seen[size_t(i)])
            return *msg = "node " + std::to_string(i) + " is reached twice: the node graph is not a forest",
                   MIM_EFORMAT;
        seen[size_t(i)] = 1;
        const tinygltf::Node &node = m.nodes[size_t(i)];
        mat4 local;
        std::string why;
        if (!local_matrix(node, &local, &why))
            return *msg = "node " + std::to_string(i) + " ('" + node.name + "') has " + why, MIM_EFORMAT;
        const int p = is_root[size_t(i)] ? -1 : parent[size_t(i)];
        (*node_world)[size_t(i)] = p >= 0 ? mul((*node_world)[size_t(p)], local) : local;
        bone[size_t(i)] = is_joint[size_t(i)] ? i : p >= 0 ? bone[size_t(p)] : -1;
        if (node.mesh >= 0) {
            if (size_t(node.mesh) >= m.meshes.size())
                return *msg = "node " + std::to_string(i) + " refers to mesh " + std::to_string(node.mesh) +
                              ", but there are " + std::to_string(m.meshes.size()) + " meshes",
                       MIM_EFORMAT;
            if (node.skin >= 0 && size_t(node.skin) >= m.skins.size())
                return *msg = "node " + std::to_string(i) + " refers to skin " + std::to_string(node.skin) +
                              ", but there are " + std::to_string(m.skins.size()) + " skins",
                       MIM_EFORMAT;
            any_mesh_node = true;
            if (selected(m, i, node.mesh, opt, &hits))
                for (size_t k = 0; k < m.meshes[size_t(node.mesh)].primitives.size(); k++)
                    out->push_back({i, node.mesh, int(k), (*node_world)[size_t(i)], node.skin,
                                    node.skin >= 0 ? -1 : bone[size_t(i)]});
        }
        for (size_t c = node.children.size(); c-- > 0;) stack.push_back(node.children[c]);
    }
    if (!any_mesh_node) // meshes without nodes: read as they are, in their order
        for (size_t k = 0; k < m.meshes.size(); k++)
            if (selected(m, -1, int(k), opt, &hits))
                for (size_t pr = 0; pr < m.meshes[k].primitives.size(); pr++)
                    out->push_back({-1, int(k), int(pr), identity(), -1, -1});
    for (size_t k = 0; k < hits.size(); k++)
        if (!hits[k] && opt->meshes[k]) {
            std::string names;
            for (const tinygltf::Mesh &me : m.meshes)
                if (!me.name.empty() && names.size() < 400) names += (names.empty() ? "'" : ", '") + me.name + "'";
            return *msg = std::string("no mesh or node named '") + opt->meshes[k] + "' in the scene (its meshes: " +
                          (names.empty() ? std::string("none named") : names) + ")",
                   MIM_ENOTFOUND;
        }
    return 0;
}

namespace {

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

// A name into a fixed field, cut before a character that does not fit
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

// A thrown failure of one part, with its code.
struct failure {
    int code;
    std::string msg;
};

std::string part_name(const tinygltf::Model &m, const placed &p)
{
    const std::string &mn = m.meshes[size_t(p.mesh)].name;
    return "mesh " + std::to_string(p.mesh) + (mn.empty() ? "" : " ('" + mn + "')") + " primitive " +
           std::to_string(p.primitive);
}

// A primitive's triangles (strips and fans unrolled), its vertex indices local.
std::vector<uint32_t> triangles(const tinygltf::Model &m, const tinygltf::Primitive &prim, uint32_t nv,
                                const std::string &name)
{
    std::string why;
    int code = 0;
    std::vector<uint32_t> idx;
    if (prim.indices >= 0) {
        if (size_t(prim.indices) >= m.accessors.size()) throw failure{MIM_EFORMAT, name + ": indices accessor out of range"};
        const tinygltf::Accessor &ia = m.accessors[size_t(prim.indices)];
        size_t isz = ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                     : ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                     : ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                                  : 0;
        if (!isz || ia.type != TINYGLTF_TYPE_SCALAR)
            throw failure{MIM_EFORMAT, name + ": indices are not unsigned scalars"};
        size_t istride = 0;
        const unsigned char *idata = accessor_data(m, prim.indices, isz, &istride, &why, &code);
        if (!idata) throw failure{code, name + ": indices: " + why};
        idx.resize(ia.count);
        for (size_t i = 0; i < ia.count; i++) idx[i] = read_index(idata + i * istride, ia.componentType);
    } else {
        idx.resize(nv);
        for (uint32_t i = 0; i < nv; i++) idx[i] = i;
    }
    std::vector<uint32_t> tris;
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        if (idx.size() % 3) throw failure{MIM_EFORMAT, name + ": triangle index count is not a multiple of 3"};
        tris.swap(idx);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 2; i < idx.size(); i++) {
            bool odd = i & 1;
            tris.insert(tris.end(), {idx[i - 2], odd ? idx[i] : idx[i - 1], odd ? idx[i - 1] : idx[i]});
        }
    } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
        for (size_t i = 2; i < idx.size(); i++) tris.insert(tris.end(), {idx[0], idx[i - 1], idx[i]});
    }
    for (size_t t = 0; t < tris.size(); t++)
        if (tris[t] >= nv)
            throw failure{MIM_EINDEX, name + ": triangle " + std::to_string(t / 3) + " refers to vertex " +
                                          std::to_string(tris[t]) + ", but it has only " + std::to_string(nv) +
                                          " vertices"};
    return tris;
}

// JOINTS_0 / WEIGHTS_0 of a skinned primitive, checked as the spec asks
// (3.7.3): indices into the skin's joints, weights >= 0 and finite, each
// vertex's normalised (the spec asks for a sum of 1; exporters round).
void skin_attributes(const tinygltf::Model &m, const tinygltf::Primitive &prim, uint32_t nv, int skin,
                     const std::string &name, std::vector<uint16_t> *J, std::vector<float> *W)
{
    auto jit = prim.attributes.find("JOINTS_0"), wit = prim.attributes.find("WEIGHTS_0");
    const tinygltf::Skin &sk = m.skins[size_t(skin)];
    const std::string skin_name = "skin " + std::to_string(skin);
    if (sk.joints.empty()) throw failure{MIM_EFORMAT, skin_name + " has no joints"};
    const uint32_t nj = uint32_t(std::min<size_t>(sk.joints.size(), UINT32_MAX));
    const int attr_index[2] = {jit->second, wit->second};
    const char *const attr_name[2] = {"JOINTS_0", "WEIGHTS_0"};
    const unsigned char *data[2];
    size_t stride[2], csize[2];
    int ctype[2];
    for (int i = 0; i < 2; i++) {
        const std::string an = name + ": " + attr_name[i];
        if (attr_index[i] < 0 || size_t(attr_index[i]) >= m.accessors.size())
            throw failure{MIM_EFORMAT, an + ": accessor " + std::to_string(attr_index[i]) + " does not exist (" +
                                           std::to_string(m.accessors.size()) + " accessors)"};
        const tinygltf::Accessor &a = m.accessors[size_t(attr_index[i])];
        int c = a.componentType;
        size_t cs = c == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ? 1 : c == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2 : 0;
        bool ok = a.type == TINYGLTF_TYPE_VEC4 &&
                  (i == 0 ? cs != 0 && !a.normalized
                          : c == TINYGLTF_COMPONENT_TYPE_FLOAT ? !a.normalized : cs != 0 && a.normalized);
        if (i == 1 && c == TINYGLTF_COMPONENT_TYPE_FLOAT) cs = 4;
        if (!ok)
            throw failure{MIM_EFORMAT, an + " is " + type_name(a.type) + " of " + component_name(c, a.normalized) +
                                           ", not VEC4 of " +
                                           (i == 0 ? "unsigned byte or unsigned short"
                                                   : "float or normalised unsigned byte or unsigned short")};
        if (a.count != nv)
            throw failure{MIM_EFORMAT, an + " has " + std::to_string(a.count) + " elements, POSITION " +
                                           std::to_string(nv)};
        std::string why;
        int code = 0;
        data[i] = accessor_data(m, attr_index[i], 4 * cs, &stride[i], &why, &code);
        if (!data[i]) throw failure{code, an + ": " + why};
        csize[i] = cs;
        ctype[i] = c;
    }
    J->resize(4 * size_t(nv));
    W->resize(4 * size_t(nv));
    const double scale = ctype[1] == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1.0 / 255.0
                         : ctype[1] == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 1.0 / 65535.0
                                                                              : 1.0;
    for (uint32_t v = 0; v < nv; v++) {
        const unsigned char *jp = data[0] + size_t(v) * stride[0], *wp = data[1] + size_t(v) * stride[1];
        double w[4], sum = 0;
        for (int k = 0; k < 4; k++) {
            uint32_t j = read_index(jp + size_t(k) * csize[0], ctype[0]);
            if (j >= nj)
                throw failure{MIM_EFORMAT, name + ": JOINTS_0: vertex " + std::to_string(v) + " refers to joint " +
                                               std::to_string(j) + ", but " + skin_name + " has " +
                                               std::to_string(nj) + " joints"};
            (*J)[4 * size_t(v) + size_t(k)] = uint16_t(j);
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
                throw failure{MIM_EFORMAT, name + ": WEIGHTS_0: vertex " + std::to_string(v) + " has weight " + num +
                                               ", not a finite number >= 0"};
            }
            sum += w[k];
        }
        for (int k = 0; k < 4; k++) (*W)[4 * size_t(v) + size_t(k)] = sum > 0 ? float(w[k] / sum) : 0.0f;
    }
}

// The skinning matrices of a skin: world(joint) * inverseBindMatrix (the
// identity where the skin gives none).
std::vector<mat4> joint_matrices(const tinygltf::Model &m, int skin, const std::vector<mat4> &world)
{
    const tinygltf::Skin &sk = m.skins[size_t(skin)];
    const std::string skin_name = "skin " + std::to_string(skin);
    if (sk.joints.empty()) throw failure{MIM_EFORMAT, skin_name + " has no joints"};
    if (sk.joints.size() > 65535) throw failure{MIM_EFORMAT, skin_name + " has too many joints"};
    for (size_t k = 0; k < sk.joints.size(); k++) {
        int node = sk.joints[k];
        if (node < 0 || size_t(node) >= m.nodes.size())
            throw failure{MIM_EFORMAT, skin_name + ": joint " + std::to_string(k) + " is node " + std::to_string(node) +
                                           ", not a valid node index (" + std::to_string(m.nodes.size()) + " nodes)"};
    }
    const unsigned char *ibm = nullptr;
    size_t stride = 0;
    if (sk.inverseBindMatrices >= 0) {
        if (size_t(sk.inverseBindMatrices) >= m.accessors.size())
            throw failure{MIM_EFORMAT, skin_name + ": inverseBindMatrices accessor out of range"};
        const tinygltf::Accessor &a = m.accessors[size_t(sk.inverseBindMatrices)];
        if (a.type != TINYGLTF_TYPE_MAT4 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT ||
            a.count < sk.joints.size())
            throw failure{MIM_EFORMAT, skin_name + ": inverseBindMatrices are not MAT4 float, one per joint"};
        std::string why;
        int code = 0;
        if (!(ibm = accessor_data(m, sk.inverseBindMatrices, 64, &stride, &why, &code)))
            throw failure{code, skin_name + ": inverseBindMatrices: " + why};
    }
    std::vector<mat4> out(sk.joints.size());
    for (size_t k = 0; k < sk.joints.size(); k++) {
        mat4 inv = identity();
        if (ibm) {
            float f[16];
            std::memcpy(f, ibm + k * stride, 64);
            for (int e = 0; e < 16; e++) {
                if (!std::isfinite(f[e]))
                    throw failure{MIM_EFORMAT, skin_name + ": inverseBindMatrix " + std::to_string(k) + " is not finite"};
                inv[size_t(e)] = f[e];
            }
        }
        out[k] = mul(world[size_t(sk.joints[k])], inv);
    }
    return out;
}

void transform(const mat4 &M, const float *p, double w, double *acc)
{
    for (int r = 0; r < 3; r++)
        acc[r] += w * (M[size_t(r)] * p[0] + M[size_t(4 + r)] * p[1] + M[size_t(8 + r)] * p[2] + M[size_t(12 + r)]);
}

// VRM's humanoid bone of each node (VRM 0.x: extensions.VRM.humanoid.humanBones
// [{bone, node}]; VRM 1.0: extensions.VRMC_vrm.humanoid.humanBones {bone: {node}}).
std::map<int, std::string> vrm_bones(const tinygltf::Model &m)
{
    std::map<int, std::string> out;
    auto v0 = m.extensions.find("VRM");
    if (v0 != m.extensions.end() && v0->second.IsObject()) {
        const tinygltf::Value &h = v0->second.Get("humanoid");
        const tinygltf::Value &bones = h.IsObject() ? h.Get("humanBones") : tinygltf::Value();
        for (size_t i = 0; bones.IsArray() && i < bones.ArrayLen(); i++) {
            const tinygltf::Value &b = bones.Get(int(i));
            if (!b.IsObject()) continue;
            const tinygltf::Value &name = b.Get("bone"), &node = b.Get("node");
            if (name.IsString() && node.IsNumber()) out[node.GetNumberAsInt()] = name.Get<std::string>();
        }
    }
    auto v1 = m.extensions.find("VRMC_vrm");
    if (v1 != m.extensions.end() && v1->second.IsObject()) {
        const tinygltf::Value &h = v1->second.Get("humanoid");
        const tinygltf::Value &bones = h.IsObject() ? h.Get("humanBones") : tinygltf::Value();
        for (const std::string &k : bones.Keys()) {
            const tinygltf::Value &b = bones.Get(k);
            const tinygltf::Value &node = b.IsObject() ? b.Get("node") : tinygltf::Value();
            if (node.IsNumber()) out[node.GetNumberAsInt()] = k;
        }
    }
    return out;
}

int skin_fail_nothrow(mim__raw_skin_t *s, int code, const char *msg) noexcept
{
    mim_io_skin_free(&s->skin);
    s->rc = code;
    std::snprintf(s->msg, sizeof s->msg, "%s", msg);
    return code;
}

int mesh_fail(mim__raw_mesh_t *out, int code, const std::string &msg)
{
    out->library_failed = 1;
    std::snprintf(out->library_msg, sizeof out->library_msg, "%s", msg.c_str());
    return code;
}

// The whole read: parts placed, and (skin not NULL) the rig over them.
int read_scene(const char *path, const mim_io_read_options_t *opt, mim__raw_mesh_t *out, mim__raw_skin_t *skin,
               std::vector<mim_io_part_t> *parts)
{
    tinygltf::Model m;
    std::string msg;
    int rc = load_model(path, &m, false, &msg);
    if (rc) return mesh_fail(out, rc, msg);
    std::vector<placed> pl;
    std::vector<mat4> world;
    if ((rc = walk_scene(m, opt, &pl, &world, &msg))) return mesh_fail(out, rc, msg);
    if (pl.empty()) return mesh_fail(out, MIM_EEMPTY, "no mesh primitive");
    if (pl.size() > MIM_IO_MAX_PARTS)
        return mesh_fail(out, MIM_EUNSUPPORTED, std::to_string(pl.size()) + " primitives, more than the " +
                                                    std::to_string(MIM_IO_MAX_PARTS) + " mimic reads");

    // The rig's joints: each skin's joint nodes, then the bones props hang on.
    std::map<int, std::string> vrm = vrm_bones(m);
    std::vector<int> joint_node;       // global joint -> node
    std::map<int, uint32_t> node_joint; // node -> global joint
    auto add_joint = [&](int node) {
        auto it = node_joint.find(node);
        if (it != node_joint.end()) return it->second;
        node_joint[node] = uint32_t(joint_node.size());
        joint_node.push_back(node);
        return uint32_t(joint_node.size() - 1);
    };
    std::map<int, std::vector<mat4>> skin_mats;
    std::string skin_err, unskinned_why;
    int skin_code = 0;

    std::vector<float> pos;
    std::vector<uint32_t> faces;
    std::vector<uint16_t> vj; // global joints, 4 per vertex
    std::vector<float> vw;
    for (const placed &p : pl) {
        const tinygltf::Primitive &prim = m.meshes[size_t(p.mesh)].primitives[size_t(p.primitive)];
        const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
        if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
            mode != TINYGLTF_MODE_TRIANGLE_FAN)
            continue; // points and lines are no surface to drive
        const std::string name = part_name(m, p);
        auto pos_it = prim.attributes.find("POSITION");
        if (pos_it == prim.attributes.end()) return mesh_fail(out, MIM_EFORMAT, name + " has no POSITION");
        if (pos_it->second < 0 || size_t(pos_it->second) >= m.accessors.size())
            return mesh_fail(out, MIM_EFORMAT, name + ": POSITION accessor out of range");
        const tinygltf::Accessor &pa = m.accessors[size_t(pos_it->second)];
        if (pa.type != TINYGLTF_TYPE_VEC3 || pa.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
            return mesh_fail(out, MIM_EUNSUPPORTED, name + ": POSITION is not float VEC3");
        std::string why;
        int code = 0;
        size_t pstride = 0;
        const unsigned char *pdata = accessor_data(m, pos_it->second, 12, &pstride, &why, &code);
        if (!pdata) return mesh_fail(out, code, name + ": POSITION: " + why);
        if (pa.count > UINT32_MAX - pos.size() / 3) return mesh_fail(out, MIM_EFORMAT, "too many vertices");
        const uint32_t nv = uint32_t(pa.count), base = uint32_t(pos.size() / 3);
        std::vector<uint32_t> tris;
        try {
            tris = triangles(m, prim, nv, name);
        } catch (const failure &f) {
            return mesh_fail(out, f.code, f.msg);
        }
        if (tris.size() / 3 > UINT32_MAX - faces.size() / 3) return mesh_fail(out, MIM_EFORMAT, "too many faces");

        // skinned: the skin places it; else its node, and a bone it hangs on
        std::vector<uint16_t> J;
        std::vector<float> W;
        const std::vector<mat4> *M = nullptr;
        const bool has_j = prim.attributes.count("JOINTS_0"), has_w = prim.attributes.count("WEIGHTS_0");
        const bool has_attrs = has_j && has_w;
        if (unskinned_why.empty() && (has_j || has_w) && (!has_attrs || p.skin < 0))
            unskinned_why = name + (!has_w ? " has JOINTS_0 but no WEIGHTS_0"
                                    : !has_j ? " has WEIGHTS_0 but no JOINTS_0"
                                             : " has JOINTS_0 and WEIGHTS_0, but its node has no skin (" +
                                                   std::to_string(m.skins.size()) + " skins in the file)");
        if (p.skin >= 0 && has_attrs && !skin_code) {
            try {
                auto it = skin_mats.find(p.skin);
                if (it == skin_mats.end()) it = skin_mats.emplace(p.skin, joint_matrices(m, p.skin, world)).first;
                skin_attributes(m, prim, nv, p.skin, name, &J, &W);
                M = &it->second;
            } catch (const failure &f) {
                skin_code = f.code, skin_err = f.msg;
            }
        }
        pos.resize(pos.size() + 3 * size_t(nv));
        vj.resize(pos.size() / 3 * 4, 0);
        vw.resize(pos.size() / 3 * 4, 0.0f);
        for (uint32_t v = 0; v < nv; v++) {
            float x[3];
            std::memcpy(x, pdata + size_t(v) * pstride, 12);
            double acc[3] = {0, 0, 0};
            double wsum = 0;
            if (M)
                for (int k = 0; k < 4; k++) {
                    float w = W[4 * size_t(v) + size_t(k)];
                    if (w > 0) transform((*M)[J[4 * size_t(v) + size_t(k)]], x, w, acc), wsum += w;
                }
            if (wsum == 0) transform(p.world, x, 1.0, acc);
            float *o = pos.data() + 3 * (size_t(base) + v);
            for (int c = 0; c < 3; c++) o[c] = float(acc[c]);
        }
        if (M) {
            const tinygltf::Skin &sk = m.skins[size_t(p.skin)];
            std::vector<uint32_t> g(sk.joints.size());
            for (size_t k = 0; k < sk.joints.size(); k++) g[k] = add_joint(sk.joints[k]);
            for (size_t e = 0; e < 4 * size_t(nv); e++) {
                vj[4 * size_t(base) + e] = uint16_t(g[J[e]]);
                vw[4 * size_t(base) + e] = W[e];
            }
        } else if (p.bone >= 0) {
            const uint16_t g = uint16_t(add_joint(p.bone));
            for (uint32_t v = 0; v < nv; v++) vj[4 * (size_t(base) + v)] = g, vw[4 * (size_t(base) + v)] = 1.0f;
        }
        for (uint32_t &t : tris) t += base;
        mim_io_part_t part;
        std::memset(&part, 0, sizeof part);
        const std::string &mn = m.meshes[size_t(p.mesh)].name;
        copy_name(part.name, !mn.empty() || p.node < 0 ? mn : m.nodes[size_t(p.node)].name);
        part.mesh = uint32_t(p.mesh), part.primitive = uint32_t(p.primitive), part.node = p.node;
        part.material = prim.material >= 0 && size_t(prim.material) < m.materials.size() ? prim.material : -1;
        part.first_vertex = base, part.n_vertices = nv;
        part.first_face = uint32_t(faces.size() / 3), part.n_faces = uint32_t(tris.size() / 3);
        parts->push_back(part);
        faces.insert(faces.end(), tris.begin(), tris.end());
    }
    if (parts->empty()) return mesh_fail(out, MIM_EUNSUPPORTED, "no triangle primitive: points or lines only");
    if (joint_node.size() > 65535) skin_code = MIM_EFORMAT, skin_err = "more than 65535 joints over all skins";

    const uint32_t nv = uint32_t(pos.size() / 3);
    rc = mim_mesh_alloc(&out->mesh, nv, uint32_t(faces.size() / 3));
    if (rc) return rc;
    std::memcpy(out->mesh.positions, pos.data(), pos.size() * sizeof(float));
    std::memcpy(out->mesh.faces, faces.data(), faces.size() * sizeof(uint32_t));
    out->n_polygons = faces.size() / 3;
    out->n_polygon_refs = faces.size();

    if (!skin) return 0;
    if (skin_code) return skin_fail_nothrow(skin, skin_code, skin_err.c_str()), 0;
    if (joint_node.empty())
        return skin_fail_nothrow(skin, MIM_ENOTFOUND,
                                 ("no skin: no primitive of the scene is skinned (a skin, JOINTS_0 and WEIGHTS_0) or "
                                  "placed under a joint" +
                                  (unskinned_why.empty() ? std::string(", and none has JOINTS_0 or WEIGHTS_0")
                                                         : ": " + unskinned_why))
                                     .c_str()),
               0;
    mim_io_skin_t *o = &skin->skin;
    const uint32_t nj = uint32_t(joint_node.size());
    o->joints = static_cast<uint16_t *>(std::malloc((vj.size() + 4) * sizeof *o->joints));
    o->weights = static_cast<float *>(std::malloc((vw.size() + 4) * sizeof *o->weights));
    o->names = static_cast<char(*)[MIM_IO_SKIN_NAME_MAX]>(std::calloc(nj, MIM_IO_SKIN_NAME_MAX));
    o->joint_positions = static_cast<float *>(std::malloc(3 * size_t(nj) * sizeof(float)));
    o->parent = static_cast<int32_t *>(std::malloc(size_t(nj) * sizeof(int32_t)));
    if (!o->joints || !o->weights || !o->names || !o->joint_positions || !o->parent)
        return skin_fail_nothrow(skin, MIM_ENOMEM, "out of memory for the skin"), 0;
    o->n_vertices = nv, o->n_joints = nj;
    std::memcpy(o->joints, vj.data(), vj.size() * sizeof *o->joints);
    std::memcpy(o->weights, vw.data(), vw.size() * sizeof *o->weights);
    std::vector<int> parent(m.nodes.size(), -1);
    for (size_t i = 0; i < m.nodes.size(); i++)
        for (int c : m.nodes[i].children) parent[size_t(c)] = int(i); // checked by walk_scene
    for (uint32_t j = 0; j < nj; j++) {
        const int node = joint_node[j];
        auto h = vrm.find(node);
        if (h != vrm.end()) o->from_vrm = 1;
        copy_name(o->names[j], h != vrm.end() ? h->second : m.nodes[size_t(node)].name);
        for (int c = 0; c < 3; c++) {
            const float x = float(world[size_t(node)][size_t(12 + c)]);
            if (!std::isfinite(x)) // transforms whose product overflows: no rig to place anything from
                return skin_fail_nothrow(skin, MIM_EFORMAT,
                                         ("joint " + std::to_string(j) + " ('" + m.nodes[size_t(node)].name +
                                          "') lies at a non-finite position: its nodes' transforms overflow")
                                             .c_str()),
                       0;
            o->joint_positions[3 * j + uint32_t(c)] = x;
        }
        int a = parent[size_t(node)];
        while (a >= 0 && !node_joint.count(a)) a = parent[size_t(a)];
        o->parent[j] = a >= 0 ? int32_t(node_joint[a]) : -1;
    }
    skin->rc = 0;
    skin->msg[0] = '\0';
    return 0;
}

} // namespace

} // namespace mim_gltf

extern "C" int mim__gltf_read(const char *path, const mim_io_read_options_t *opt, mim__raw_mesh_t *out,
                              mim__raw_skin_t *skin, mim_io_part_t **parts, uint32_t *n_parts)
{
    std::memset(out, 0, sizeof *out);
    out->first_bad_face = -1;
    if (parts) *parts = nullptr, *n_parts = 0;
    if (skin) {
        std::memset(skin, 0, sizeof *skin);
        mim_gltf::skin_fail_nothrow(skin, MIM_EFORMAT, "the skin was not read: the mesh could not be");
    }
    try {
        std::vector<mim_io_part_t> pv;
        int rc = mim_gltf::read_scene(path, opt, out, skin, &pv);
        if (!rc && parts) {
            *parts = static_cast<mim_io_part_t *>(std::malloc((pv.size() + 1) * sizeof **parts));
            if (!*parts) {
                mim_mesh_free(&out->mesh);
                return MIM_ENOMEM;
            }
            std::memcpy(*parts, pv.data(), pv.size() * sizeof **parts);
            *n_parts = uint32_t(pv.size());
        }
        if (rc) mim_mesh_free(&out->mesh);
        return rc;
    } catch (const std::bad_alloc &) {
        mim_mesh_free(&out->mesh);
        if (skin) mim_gltf::skin_fail_nothrow(skin, MIM_ENOMEM, "out of memory");
        return MIM_ENOMEM;
    } catch (const std::exception &e) {
        // no std::string here: building one may throw again
        mim_mesh_free(&out->mesh);
        if (skin) mim_gltf::skin_fail_nothrow(skin, MIM_EFORMAT, "the skin was not read: the mesh could not be");
        out->library_failed = 1;
        std::snprintf(out->library_msg, sizeof out->library_msg, "tinygltf: %s", e.what());
        return MIM_EFORMAT;
    } catch (...) {
        mim_mesh_free(&out->mesh);
        if (skin) mim_gltf::skin_fail_nothrow(skin, MIM_EFORMAT, "the skin was not read: the mesh could not be");
        out->library_failed = 1;
        std::snprintf(out->library_msg, sizeof out->library_msg, "tinygltf failed");
        return MIM_EFORMAT;
    }
}
