// tinygltf shim: reads the first primitive of the first mesh of a glTF or
// GLB file into plain arrays. POSITION is taken as stored, which for a
// skinned mesh is its bind pose; node transforms are not applied. Every
// accessor range is checked against its buffer before it is read, because
// the file is untrusted. No C++ type or exception crosses into C.
#include "read_shim.h"

#include <tiny_gltf.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

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
    try {
        tinygltf::TinyGLTF loader;
        loader.SetImageLoader(skip_image, nullptr);
        tinygltf::Model model;
        std::string err, warn, p(path);
        bool glb = p.size() >= 4 && (p.compare(p.size() - 4, 4, ".glb") == 0 || p.compare(p.size() - 4, 4, ".GLB") == 0);
        bool ok = glb ? loader.LoadBinaryFromFile(&model, &err, &warn, p) : loader.LoadASCIIFromFile(&model, &err, &warn, p);
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
        mim_mesh_free(&out->mesh);
        return MIM_ENOMEM;
    } catch (const std::exception &e) {
        mim_mesh_free(&out->mesh);
        return fail(out, MIM_EFORMAT, std::string("tinygltf: ") + e.what());
    } catch (...) {
        mim_mesh_free(&out->mesh);
        return fail(out, MIM_EFORMAT, "tinygltf failed");
    }
}
