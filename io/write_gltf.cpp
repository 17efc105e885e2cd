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

#include <tiny_gltf.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
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

int add_indices(tinygltf::Model &m, const mim_mesh_t *mesh)
{
    size_t n = 3 * size_t(mesh->n_faces);
    tinygltf::Accessor a;
    a.type = TINYGLTF_TYPE_SCALAR;
    a.count = n;
    if (mesh->n_vertices <= 65535u) { // largest index 65534
        std::vector<std::uint16_t> idx(n);
        for (size_t i = 0; i < n; i++) idx[i] = std::uint16_t(mesh->faces[i]);
        a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
        a.bufferView = add_view(m, idx.data(), n * 2, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    } else {
        a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
        a.bufferView = add_view(m, mesh->faces, n * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
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

        tinygltf::Primitive prim;
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        prim.indices = add_indices(m, mesh);
        prim.attributes["POSITION"] = add_float_accessor(m, in->positions, nv, 3, TINYGLTF_TYPE_VEC3,
                                                         TINYGLTF_TARGET_ARRAY_BUFFER, true);
        prim.attributes["NORMAL"] = add_float_accessor(m, in->normals, nv, 3, TINYGLTF_TYPE_VEC3,
                                                       TINYGLTF_TARGET_ARRAY_BUFFER, false);

        // Morph targets: displacements from frame 0 (glTF 2.0, 3.7.2.2).
        std::vector<float> d(stride);
        tinygltf::Value::Array target_names;
        for (size_t f = 1; f < nf; f++) {
            std::map<std::string, int> target;
            const float *p = in->positions + f * stride, *p0 = in->positions;
            for (size_t i = 0; i < stride; i++) d[i] = p[i] - p0[i];
            target["POSITION"] = add_float_accessor(m, d.data(), nv, 3, TINYGLTF_TYPE_VEC3,
                                                    TINYGLTF_TARGET_ARRAY_BUFFER, true);
            const float *q = in->normals + f * stride, *q0 = in->normals;
            for (size_t i = 0; i < stride; i++) d[i] = q[i] - q0[i];
            target["NORMAL"] = add_float_accessor(m, d.data(), nv, 3, TINYGLTF_TYPE_VEC3,
                                                  TINYGLTF_TARGET_ARRAY_BUFFER, false);
            prim.targets.push_back(target);
            target_names.push_back(tinygltf::Value(frame_name(in->names, uint32_t(f))));
        }

        tinygltf::Mesh gm;
        gm.name = in->names && in->names[0] ? in->names[0] : "mimic";
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
        node.mesh = 0;
        m.nodes.push_back(node);
        tinygltf::Scene scene;
        scene.nodes.push_back(0);
        m.scenes.push_back(scene);
        m.defaultScene = 0;

        if (nf > 1) {
            // Keyframe i sets target i-1 to 1 and every other to 0.
            const size_t nt = nf - 1;
            std::vector<float> w(nf * nt, 0.0f);
            for (size_t i = 1; i < nf; i++) w[i * nt + (i - 1)] = 1.0f;
            tinygltf::AnimationSampler s;
            s.input = add_float_accessor(m, in->times, nf, 1, TINYGLTF_TYPE_SCALAR, 0, true);
            s.output = add_float_accessor(m, w.data(), nf * nt, 1, TINYGLTF_TYPE_SCALAR, 0, false);
            s.interpolation = "LINEAR";
            tinygltf::AnimationChannel c;
            c.sampler = 0;
            c.target_node = 0;
            c.target_path = "weights";
            tinygltf::Animation anim;
            anim.name = "mimic";
            anim.samplers.push_back(s);
            anim.channels.push_back(c);
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
