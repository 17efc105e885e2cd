// tinygltf writer shim: encodes one mesh, or a sequence of its poses as
// morph targets with a "weights" animation (seed 000, Section 3.5: the
// player blends linearly between consecutive key poses), as a GLB in
// memory; write.c checks the input before and puts the bytes on disk after.
//
// Layout, chosen so that the Khronos validator reports nothing: one buffer;
// one bufferView per accessor, each starting on a 4-byte boundary, tightly
// packed (no byteStride needed); ELEMENT_ARRAY_BUFFER for the indices,
// ARRAY_BUFFER for vertex attributes, no target for animation data; min/max
// on every POSITION accessor (base and targets) and on the sampler input.
// Indices are UNSIGNED_SHORT when every index fits below 65535 (the
// primitive-restart value, which glTF forbids), else UNSIGNED_INT.
// No C++ type or exception crosses into C.
#include "write_shim.h"
#include "gltf_internal.hpp"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <new>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace {

// Appends raw bytes to the buffer as a new bufferView; returns its index.
int add_view(tinygltf::Model &m, const void *data, size_t size, int target)
{
    std::vector<unsigned char> &buf = m.buffers[0].data;
    while (buf.size() % 4) buf.push_back(0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = buf.size();
    v.byteLength = size;
    v.target = target;
    const unsigned char *p = static_cast<const unsigned char *>(data);
    buf.insert(buf.end(), p, p + size);
    m.bufferViews.push_back(v);
    return int(m.bufferViews.size() - 1);
}

// A float accessor over n elements of `comps` components, with min/max when
// asked (computed from the very floats written, as the validator checks).
int add_float_accessor(tinygltf::Model &m, const float *data, size_t n, int comps, int type, int target,
                       bool minmax)
{
    tinygltf::Accessor a;
    a.bufferView = add_view(m, data, n * size_t(comps) * sizeof(float), target);
    a.byteOffset = 0;
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.type = type;
    a.count = n;
    if (minmax) {
        a.minValues.assign(size_t(comps), std::numeric_limits<double>::infinity());
        a.maxValues.assign(size_t(comps), -std::numeric_limits<double>::infinity());
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < comps; c++) {
                double v = data[i * size_t(comps) + size_t(c)];
                a.minValues[size_t(c)] = std::min(a.minValues[size_t(c)], v);
                a.maxValues[size_t(c)] = std::max(a.maxValues[size_t(c)], v);
            }
    }
    m.accessors.push_back(a);
    return int(m.accessors.size() - 1);
}

// The part's triangles, its vertex indices local to it.
int add_indices(tinygltf::Model &m, const mim_mesh_t *mesh, const mim_io_part_t &part)
{
    size_t n = 3 * size_t(part.n_faces);
    const uint32_t *f = mesh->faces + 3 * size_t(part.first_face);
    tinygltf::Accessor a;
    a.type = TINYGLTF_TYPE_SCALAR;
    a.count = n;
    if (part.n_vertices <= 65535u) { // largest index 65534
        std::vector<std::uint16_t> idx(n);
        for (size_t i = 0; i < n; i++) idx[i] = std::uint16_t(f[i] - part.first_vertex);
        a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
        a.bufferView = add_view(m, idx.data(), n * 2, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    } else {
        std::vector<std::uint32_t> idx(n);
        for (size_t i = 0; i < n; i++) idx[i] = f[i] - part.first_vertex;
        a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
        a.bufferView = add_view(m, idx.data(), n * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    }
    m.accessors.push_back(a);
    return int(m.accessors.size() - 1);
}

std::string frame_name(const char *const *names, uint32_t i)
{
    if (names && names[i]) return names[i];
    return "frame " + std::to_string(i);
}

int fail(char *msg, size_t msg_size, int code, const std::string &why)
{
    std::snprintf(msg, msg_size, "%s", why.c_str());
    return code;
}

// ---- the avatar's look (issue 28) ----

// One component of an accessor element as a float (normalised integers
// to [0, 1] or [-1, 1], as glTF 2.0 3.11 defines them).
float component(const unsigned char *p, int type, bool normalized)
{
    switch (type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float f;
        std::memcpy(&f, p, 4);
        return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0f : float(p[0]);
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
        float v = float(int8_t(p[0]));
        return normalized ? std::max(v / 127.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? v / 65535.0f : float(v);
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? std::max(v / 32767.0f, -1.0f) : float(v);
    }
    default: return 0.0f;
    }
}

// What a source file gives the output: its model (images kept as bytes)
// and its parts' primitives, in the order the reader met them.
struct look_source {
    tinygltf::Model model;
    std::vector<mim_gltf::placed> placed;
};

bool load_look(const char *path, const mim_io_read_options_t *ro, uint32_t n_parts, look_source *ls)
{
    std::string why;
    std::vector<mim_gltf::mat4> world;
    if (mim_gltf::load_model(path, &ls->model, true, &why) ||
        mim_gltf::walk_scene(ls->model, ro, &ls->placed, &world, &why))
        return false;
    // the reader skips points and lines; so does the look
    std::vector<mim_gltf::placed> tri;
    for (const mim_gltf::placed &p : ls->placed) {
        int mode = ls->model.meshes[size_t(p.mesh)].primitives[size_t(p.primitive)].mode;
        if (mode < 0 || mode == TINYGLTF_MODE_TRIANGLES || mode == TINYGLTF_MODE_TRIANGLE_STRIP ||
            mode == TINYGLTF_MODE_TRIANGLE_FAN)
            tri.push_back(p);
    }
    ls->placed.swap(tri);
    for (const tinygltf::Image &im : ls->model.images)
        if (!im.as_is || im.image.empty()) return false; // an image we cannot embed: no look at all
    return ls->placed.size() == n_parts;
}

std::string sniff_mime(const std::vector<unsigned char> &b)
{
    if (b.size() >= 8 && !std::memcmp(b.data(), "\x89PNG", 4)) return "image/png";
    if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8) return "image/jpeg";
    if (b.size() >= 12 && !std::memcmp(b.data(), "RIFF", 4) && !std::memcmp(b.data() + 8, "WEBP", 4)) return "image/webp";
    return "image/png";
}

// Samplers, textures, materials and images (embedded) into m; the
// extensions they use into used.
void copy_look(const tinygltf::Model &src, tinygltf::Model &m, std::set<std::string> *used)
{
    m.samplers = src.samplers;
    m.textures = src.textures;
    m.materials = src.materials;
    for (const tinygltf::Image &s : src.images) {
        tinygltf::Image im;
        im.name = s.name;
        im.mimeType = s.mimeType.empty() ? sniff_mime(s.image) : s.mimeType;
        im.bufferView = add_view(m, s.image.data(), s.image.size(), 0);
        m.images.push_back(im);
    }
    for (const tinygltf::Texture &t : m.textures)
        for (const auto &e : t.extensions) used->insert(e.first);
    for (const tinygltf::Material &mat : m.materials) {
        for (const auto &e : mat.extensions) used->insert(e.first);
        for (const auto *ti : {&mat.pbrMetallicRoughness.baseColorTexture, &mat.pbrMetallicRoughness.metallicRoughnessTexture,
                               &mat.emissiveTexture})
            for (const auto &e : ti->extensions) used->insert(e.first);
        for (const auto &e : mat.normalTexture.extensions) used->insert(e.first);
        for (const auto &e : mat.occlusionTexture.extensions) used->insert(e.first);
    }
}

// The source primitive's TEXCOORD_n and COLOR_n, as float accessors.
void copy_attributes(const tinygltf::Model &src, const tinygltf::Primitive &sp, uint32_t nv, tinygltf::Model &m,
                     tinygltf::Primitive *prim)
{
    for (const auto &at : sp.attributes) {
        const std::string &name = at.first;
        if (name.rfind("TEXCOORD_", 0) != 0 && name.rfind("COLOR_", 0) != 0) continue;
        if (at.second < 0 || size_t(at.second) >= src.accessors.size()) continue;
        const tinygltf::Accessor &a = src.accessors[size_t(at.second)];
        const int comps = tinygltf::GetNumComponentsInType(uint32_t(a.type));
        const int csize = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
        if (comps < 2 || comps > 4 || csize <= 0 || a.count != nv) continue;
        size_t stride = 0;
        std::string why;
        int code = 0;
        const unsigned char *d = mim_gltf::accessor_data(src, at.second, size_t(comps * csize), &stride, &why, &code);
        if (!d) continue;
        std::vector<float> f(size_t(nv) * size_t(comps));
        for (size_t v = 0; v < nv; v++)
            for (int c = 0; c < comps; c++)
                f[v * size_t(comps) + size_t(c)] = component(d + v * stride + size_t(c * csize), a.componentType, a.normalized);
        for (float &x : f)
            if (!std::isfinite(x)) x = 0; // the validator, and every player, wants finite data
        prim->attributes[name] =
            add_float_accessor(m, f.data(), nv, comps, a.type, TINYGLTF_TARGET_ARRAY_BUFFER, false);
    }
}

} // namespace

extern "C" int mim__gltf_encode(const mim__gltf_frames_t *in, mim__bytes_t *out, char *msg, size_t msg_size)
{
    out->data = nullptr;
    out->size = 0;
    try {
        const mim_mesh_t *mesh = in->mesh;
        const size_t nv = mesh->n_vertices, nf = size_t(in->n_frames), stride = 3 * nv;
        tinygltf::Model m;
        m.asset.version = "2.0";
        m.asset.generator = "mimic " MIM_VERSION;
        m.buffers.resize(1);

        mim_io_part_t whole;
        std::memset(&whole, 0, sizeof whole);
        whole.node = whole.material = -1, whole.n_vertices = mesh->n_vertices, whole.n_faces = mesh->n_faces;
        const mim_io_part_t *parts = in->parts && in->n_parts ? in->parts : &whole;
        const uint32_t np = in->parts && in->n_parts ? in->n_parts : 1;
        std::unique_ptr<look_source> look;
        std::set<std::string> used;
        if (in->look) {
            look.reset(new look_source);
            if (load_look(in->look, in->look_read, np, look.get())) copy_look(look->model, m, &used);
            else look.reset();
        }
        // a look of no materials is none to keep
        if (in->look_kept) *in->look_kept = look != nullptr && !look->model.materials.empty();

        tinygltf::Value::Array target_names;
        for (size_t f = 1; f < nf; f++) target_names.push_back(tinygltf::Value(frame_name(in->names, uint32_t(f))));
        tinygltf::Scene scene;
        for (uint32_t k = 0; k < np; k++) {
            const mim_io_part_t &part = parts[k];
            const size_t pv = part.n_vertices, base = 3 * size_t(part.first_vertex);
            tinygltf::Primitive prim;
            prim.mode = TINYGLTF_MODE_TRIANGLES;
            prim.indices = add_indices(m, mesh, part);
            prim.attributes["POSITION"] = add_float_accessor(m, in->positions + base, pv, 3, TINYGLTF_TYPE_VEC3,
                                                             TINYGLTF_TARGET_ARRAY_BUFFER, true);
            prim.attributes["NORMAL"] = add_float_accessor(m, in->normals + base, pv, 3, TINYGLTF_TYPE_VEC3,
                                                           TINYGLTF_TARGET_ARRAY_BUFFER, false);
            if (look) {
                const mim_gltf::placed &pl = look->placed[k];
                const tinygltf::Primitive &sp =
                    look->model.meshes[size_t(pl.mesh)].primitives[size_t(pl.primitive)];
                copy_attributes(look->model, sp, part.n_vertices, m, &prim);
                if (sp.material >= 0 && size_t(sp.material) < m.materials.size()) prim.material = sp.material;
            }
            // Morph targets: displacements from frame 0 (glTF 2.0, 3.7.2.2).
            std::vector<float> d(3 * pv);
            for (size_t f = 1; f < nf; f++) {
                std::map<std::string, int> target;
                const float *p = in->positions + f * stride + base, *p0 = in->positions + base;
                for (size_t i = 0; i < 3 * pv; i++) d[i] = p[i] - p0[i];
                target["POSITION"] =
                    add_float_accessor(m, d.data(), pv, 3, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, true);
                const float *q = in->normals + f * stride + base, *q0 = in->normals + base;
                for (size_t i = 0; i < 3 * pv; i++) d[i] = q[i] - q0[i];
                target["NORMAL"] =
                    add_float_accessor(m, d.data(), pv, 3, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, false);
                prim.targets.push_back(target);
            }
            tinygltf::Mesh gm;
            gm.name = part.name[0] ? std::string(part.name)
                      : np == 1   ? (in->names && in->names[0] ? in->names[0] : "mimic")
                                  : "part " + std::to_string(k);
            gm.primitives.push_back(prim);
            if (nf > 1) {
                gm.weights.assign(nf - 1, 0.0);
                tinygltf::Value::Object extras;
                extras["targetNames"] = tinygltf::Value(target_names);
                gm.extras = tinygltf::Value(extras);
            }
            m.meshes.push_back(gm);
            tinygltf::Node node;
            node.name = gm.name;
            node.mesh = int(k);
            m.nodes.push_back(node);
            scene.nodes.push_back(int(k));
        }
        m.scenes.push_back(scene);
        m.defaultScene = 0;
        for (const std::string &e : used) {
            m.extensionsUsed.push_back(e);
            if (look && std::find(look->model.extensionsRequired.begin(), look->model.extensionsRequired.end(), e) !=
                            look->model.extensionsRequired.end())
                m.extensionsRequired.push_back(e);
        }

        if (nf > 1) {
            // Keyframe i sets target i-1 to 1 and every other to 0, on every part's node.
            const size_t nt = nf - 1;
            std::vector<float> w(nf * nt, 0.0f);
            for (size_t i = 1; i < nf; i++) w[i * nt + (i - 1)] = 1.0f;
            tinygltf::Animation anim;
            anim.name = "mimic";
            const int input = add_float_accessor(m, in->times, nf, 1, TINYGLTF_TYPE_SCALAR, 0, true);
            const int output = add_float_accessor(m, w.data(), nf * nt, 1, TINYGLTF_TYPE_SCALAR, 0, false);
            for (uint32_t k = 0; k < np; k++) {
                tinygltf::AnimationSampler s;
                s.input = input, s.output = output;
                s.interpolation = "LINEAR";
                tinygltf::AnimationChannel c;
                c.sampler = int(k);
                c.target_node = int(k);
                c.target_path = "weights";
                anim.samplers.push_back(s);
                anim.channels.push_back(c);
            }
            m.animations.push_back(anim);
        }
        while (m.buffers[0].data.size() % 4) m.buffers[0].data.push_back(0);
        if (m.buffers[0].data.size() > std::numeric_limits<std::uint32_t>::max() - (1u << 20))
            return fail(msg, msg_size, MIM_EINVAL, "too large for a GLB (over 4 GiB)");

        tinygltf::TinyGLTF writer;
        std::ostringstream os(std::ios::out | std::ios::binary);
        if (!writer.WriteGltfSceneToStream(&m, os, false, true) || !os)
            return fail(msg, msg_size, MIM_EIO, "tinygltf could not encode the GLB");
        std::string s = os.str();
        return mim__bytes_copy(out, s.data(), s.size());
    } catch (const std::bad_alloc &) {
        return MIM_ENOMEM;
    } catch (const std::exception &e) {
        // e.g. a frame name that is not UTF-8 (the JSON library refuses it)
        return fail(msg, msg_size, MIM_EINVAL, std::string("tinygltf: ") + e.what());
    } catch (...) {
        return fail(msg, msg_size, MIM_EIO, "tinygltf failed");
    }
}
