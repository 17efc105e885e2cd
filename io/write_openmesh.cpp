// OpenMesh writer shim: encodes a triangle mesh as PLY (binary
// little-endian), OBJ or OFF with OpenMesh's writers, into memory; write.c
// puts the bytes on disk. A custom exporter hands the writers the arrays
// directly (as the reader's importer does in ingest/openmesh_shim.cpp), so
// every face is written exactly as given: a half-edge TriMesh would refuse
// non-manifold faces. No C++ type or exception crosses into C.
#include "openmesh_streams.h"
#include "write_shim.h"

#include <OpenMesh/Core/IO/exporter/BaseExporter.hh>
#include <OpenMesh/Core/IO/writer/OBJWriter.hh>
#include <OpenMesh/Core/IO/writer/OFFWriter.hh>
#include <OpenMesh/Core/IO/writer/PLYWriter.hh>
#include <OpenMesh/Core/Mesh/BaseKernel.hh>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <sstream>
#include <string>
#include <vector>

namespace {

using namespace OpenMesh;
using namespace OpenMesh::IO;

// The colour and status queries of one kind of element: mimic writes
// neither (the exporter's has_*_colors() and has_*_status() stay false).
#define NO_COLORS_OR_STATUS(Handle)                                                                 \
    Vec3uc color(Handle) const override { return Vec3uc(0, 0, 0); }                                 \
    Vec4uc colorA(Handle) const override { return Vec4uc(0, 0, 0, 0); }                             \
    Vec3ui colori(Handle) const override { return Vec3ui(0, 0, 0); }                                \
    Vec4ui colorAi(Handle) const override { return Vec4ui(0, 0, 0, 0); }                            \
    Vec3f colorf(Handle) const override { return Vec3f(0, 0, 0); }                                  \
    Vec4f colorAf(Handle) const override { return Vec4f(0, 0, 0, 0); }                              \
    Attributes::StatusInfo status(Handle) const override { return Attributes::StatusInfo(); }

// Positions and triangles of a mim_mesh_t; everything else is absent.
class ArrayExporter : public BaseExporter {
public:
    explicit ArrayExporter(const mim_mesh_t *m) : m_(m) {}

    Vec3f point(VertexHandle v) const override
    {
        const float *p = m_->positions + 3 * size_t(v.idx());
        return Vec3f(p[0], p[1], p[2]);
    }
    Vec3d pointd(VertexHandle v) const override
    {
        Vec3f p = point(v);
        return Vec3d(p[0], p[1], p[2]);
    }
    bool is_point_double() const override { return false; }
    Vec3f normal(VertexHandle) const override { return Vec3f(0, 0, 0); }
    Vec3d normald(VertexHandle) const override { return Vec3d(0, 0, 0); }
    bool is_normal_double() const override { return false; }
    NO_COLORS_OR_STATUS(VertexHandle)
    Vec2f texcoord(VertexHandle) const override { return Vec2f(0, 0); }
    Vec2f texcoord(HalfedgeHandle) const override { return Vec2f(0, 0); }

    unsigned int get_vhandles(FaceHandle f, std::vector<VertexHandle> &vh) const override
    {
        const std::uint32_t *t = m_->faces + 3 * size_t(f.idx());
        vh.clear();
        for (int k = 0; k < 3; k++) vh.push_back(VertexHandle(int(t[k])));
        return 3;
    }
    HalfedgeHandle getHeh(FaceHandle, VertexHandle) const override { return HalfedgeHandle(); }
    unsigned int get_face_texcoords(std::vector<Vec2f> &tc) const override
    {
        tc.clear();
        return 0;
    }
    Vec3f normal(FaceHandle) const override { return Vec3f(0, 0, 0); }
    Vec3d normald(FaceHandle) const override { return Vec3d(0, 0, 0); }
    NO_COLORS_OR_STATUS(FaceHandle)
    NO_COLORS_OR_STATUS(EdgeHandle)

    // Half-edge queries serve only the OM format, which mimic does not write.
    int get_halfedge_id(VertexHandle) override { return -1; }
    int get_halfedge_id(FaceHandle) override { return -1; }
    int get_next_halfedge_id(HalfedgeHandle) override { return -1; }
    int get_to_vertex_id(HalfedgeHandle) override { return -1; }
    int get_face_id(HalfedgeHandle) override { return -1; }
    Attributes::StatusInfo status(HalfedgeHandle) const override { return Attributes::StatusInfo(); }

    // The PLY writer lists the kernel's custom properties in its header
    // whatever the options: an empty kernel has none.
    const BaseKernel *kernel() override
    {
        static const BaseKernel empty;
        return &empty;
    }

    size_t n_vertices() const override { return m_->n_vertices; }
    size_t n_faces() const override { return m_->n_faces; }
    size_t n_edges() const override { return 0; }
    bool is_triangle_mesh() const override { return true; }

private:
    const mim_mesh_t *m_;
};
#undef NO_COLORS_OR_STATUS

// The writers are process-wide singletons; one encode at a time.
std::mutex write_mutex;

// 9 significant digits print every float32 so that it reads back exactly.
const std::streamsize kFloatDigits = 9;

} // namespace

extern "C" int mim__openmesh_encode(const mim_mesh_t *mesh, const char *format, mim__bytes_t *out, char *msg,
                                    size_t msg_size)
{
    out->data = nullptr;
    out->size = 0;
    try {
        mim__openmesh_quiet();
        const BaseWriter *writer = nullptr;
        Options opt;
        if (!std::strcmp(format, "ply")) {
            writer = &PLYWriter();
            opt += Options::Binary;
            opt += Options::LSB;
        } else if (!std::strcmp(format, "obj")) {
            writer = &OBJWriter();
        } else if (!std::strcmp(format, "off")) {
            writer = &OFFWriter();
        } else {
            std::snprintf(msg, msg_size, "no OpenMesh writer for \"%s\"", format);
            return MIM_EINVAL;
        }
        ArrayExporter exporter(mesh);
        std::ostringstream os(std::ios::out | std::ios::binary);
        bool ok;
        {
            std::lock_guard<std::mutex> lock(write_mutex);
            ok = writer->write(os, exporter, opt, kFloatDigits);
        }
        if (!ok || !os) {
            std::snprintf(msg, msg_size, "OpenMesh's %s writer failed", format);
            return MIM_EIO;
        }
        std::string s = os.str();
        return mim__bytes_copy(out, s.data(), s.size());
    } catch (const std::bad_alloc &) {
        std::free(out->data);
        out->data = nullptr;
        return MIM_ENOMEM;
    } catch (const std::exception &e) {
        std::free(out->data);
        out->data = nullptr;
        std::snprintf(msg, msg_size, "OpenMesh: %s", e.what());
        return MIM_EIO;
    } catch (...) {
        std::free(out->data);
        out->data = nullptr;
        std::snprintf(msg, msg_size, "OpenMesh failed");
        return MIM_EIO;
    }
}
