// OpenMesh shim: reads OFF, PLY, OBJ and STL through OpenMesh's IO readers
// into plain arrays. A custom importer receives the readers' vertices and
// polygons directly, so faces are kept exactly as the file lists them (a
// half-edge mesh would silently drop non-manifold faces) and bad indices can
// be reported instead of dereferenced. No C++ type or exception crosses into C.
//
// OpenMesh's readers keep per-file state in members of their singleton
// instances, so two threads must never share one: each read borrows a set of
// reader objects from a pool. A reader registers itself with the IOManager
// when constructed and never unregisters, so pooled sets live as long as the
// process (at most one per concurrent reader thread).
#include "openmesh_streams.h"
#include "read_shim.h"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/IO/reader/OBJReader.hh>
#include <OpenMesh/Core/IO/reader/OFFReader.hh>
#include <OpenMesh/Core/IO/reader/PLYReader.hh>
#include <OpenMesh/Core/IO/reader/STLReader.hh>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <vector>

namespace {

using namespace OpenMesh;
using namespace OpenMesh::IO;

class ArrayImporter : public BaseImporter {
public:
    std::vector<float> points;
    std::vector<std::uint32_t> tris;
    std::uint64_t n_polygons = 0, n_refs = 0;
    std::int64_t first_bad_face = -1;
    std::uint64_t bad_index = 0;

    VertexHandle add_vertex(const Vec3f &p) override
    {
        points.push_back(p[0]);
        points.push_back(p[1]);
        points.push_back(p[2]);
        return VertexHandle(int(points.size() / 3 - 1));
    }
    VertexHandle add_vertex(const Vec3d &p) override { return add_vertex(Vec3f(float(p[0]), float(p[1]), float(p[2]))); }
    VertexHandle add_vertex() override { return add_vertex(Vec3f(0, 0, 0)); }
    HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
    FaceHandle add_face(const VHandles &idx) override
    {
        std::uint64_t f = n_polygons++;
        n_refs += idx.size();
        std::uint64_t nv = points.size() / 3;
        for (const VertexHandle &h : idx) {
            if (h.idx() < 0 || std::uint64_t(h.idx()) >= nv) {
                if (first_bad_face < 0) {
                    first_bad_face = std::int64_t(f);
                    bad_index = std::uint64_t(std::uint32_t(h.idx()));
                }
            }
        }
        // Fan triangulation of the polygon (exact for convex polygons).
        for (size_t k = 2; k < idx.size(); k++) {
            tris.push_back(std::uint32_t(idx[0].idx()));
            tris.push_back(std::uint32_t(idx[k - 1].idx()));
            tris.push_back(std::uint32_t(idx[k].idx()));
        }
        return FaceHandle(int(f));
    }
    FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f> &) override {}
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f> &) override {}
    void set_face_texindex(FaceHandle, int) override {}
    void set_point(VertexHandle v, const Vec3f &p) override
    {
        if (v.idx() >= 0 && size_t(v.idx()) * 3 + 2 < points.size()) {
            points[size_t(v.idx()) * 3 + 0] = p[0];
            points[size_t(v.idx()) * 3 + 1] = p[1];
            points[size_t(v.idx()) * 3 + 2] = p[2];
        }
    }
    void set_halfedge(VertexHandle, HalfedgeHandle) override {}
    void set_normal(VertexHandle, const Vec3f &) override {}
    void set_normal(VertexHandle, const Vec3d &) override {}
    void set_color(VertexHandle, const Vec3uc &) override {}
    void set_color(VertexHandle, const Vec4uc &) override {}
    void set_color(VertexHandle, const Vec3f &) override {}
    void set_color(VertexHandle, const Vec4f &) override {}
    void set_texcoord(VertexHandle, const Vec2f &) override {}
    void set_status(VertexHandle, const Attributes::StatusInfo &) override {}
    void set_next(HalfedgeHandle, HalfedgeHandle) override {}
    void set_face(HalfedgeHandle, FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(HalfedgeHandle, const Vec2f &) override {}
    void set_texcoord(VertexHandle, const Vec3f &) override {}
    void set_texcoord(HalfedgeHandle, const Vec3f &) override {}
    void set_status(HalfedgeHandle, const Attributes::StatusInfo &) override {}
    void set_color(EdgeHandle, const Vec3uc &) override {}
    void set_color(EdgeHandle, const Vec4uc &) override {}
    void set_color(EdgeHandle, const Vec3f &) override {}
    void set_color(EdgeHandle, const Vec4f &) override {}
    void set_status(EdgeHandle, const Attributes::StatusInfo &) override {}
    void set_normal(FaceHandle, const Vec3f &) override {}
    void set_normal(FaceHandle, const Vec3d &) override {}
    void set_color(FaceHandle, const Vec3uc &) override {}
    void set_color(FaceHandle, const Vec4uc &) override {}
    void set_color(FaceHandle, const Vec3f &) override {}
    void set_color(FaceHandle, const Vec4f &) override {}
    void set_status(FaceHandle, const Attributes::StatusInfo &) override {}
    void add_texture_information(int, std::string) override {}
    void reserve(unsigned int nv, unsigned int, unsigned int nf) override
    {
        // Header counts are untrusted: cap what we reserve up front.
        points.reserve(size_t(nv < (1u << 22) ? nv : (1u << 22)) * 3);
        tris.reserve(size_t(nf < (1u << 22) ? nf : (1u << 22)) * 3);
    }
    size_t n_vertices() const override { return points.size() / 3; }
    size_t n_faces() const override { return size_t(n_polygons); }
    size_t n_edges() const override { return 0; }
};

struct ReaderSet {
    _PLYReader_ ply;
    _OFFReader_ off;
    _OBJReader_ obj;
    _STLReader_ stl;
};

std::mutex pool_mutex;
std::vector<ReaderSet *> pool;

ReaderSet *acquire_readers()
{
    std::lock_guard<std::mutex> lock(pool_mutex);
    if (pool.empty()) return new ReaderSet(); // registration happens under the lock
    ReaderSet *r = pool.back();
    pool.pop_back();
    return r;
}

void release_readers(ReaderSet *r)
{
    std::lock_guard<std::mutex> lock(pool_mutex);
    pool.push_back(r);
}

BaseReader *pick(ReaderSet *r, const char *format)
{
    if (!std::strcmp(format, "ply")) return &r->ply;
    if (!std::strcmp(format, "off")) return &r->off;
    if (!std::strcmp(format, "obj")) return &r->obj;
    if (!std::strcmp(format, "stl")) return &r->stl;
    return nullptr;
}

} // namespace

extern "C" int mim__openmesh_read(const char *path, const char *format, mim__raw_mesh_t *out)
{
    std::memset(out, 0, sizeof *out);
    out->first_bad_face = -1;
    try {
        mim__openmesh_quiet();
        ArrayImporter imp;
        Options opt;
        ReaderSet *readers = acquire_readers();
        BaseReader *reader = pick(readers, format);
        bool ok = false;
        try {
            // As the IOManager does: can_u_read parses the header into the
            // reader's state (the OFF reader depends on it), then read.
            ok = reader && reader->can_u_read(path) && reader->read(path, imp, opt);
        } catch (...) {
            release_readers(readers);
            throw;
        }
        release_readers(readers);
        out->library_failed = !ok;
        if (!ok) std::snprintf(out->library_msg, sizeof out->library_msg, "OpenMesh could not parse it");
        size_t nv = imp.points.size() / 3, nt = imp.tris.size() / 3;
        if (nv > UINT32_MAX || nt > UINT32_MAX) return MIM_EFORMAT;
        int rc = mim_mesh_alloc(&out->mesh, std::uint32_t(nv), std::uint32_t(nt));
        if (rc) return rc;
        if (nv) std::memcpy(out->mesh.positions, imp.points.data(), nv * 3 * sizeof(float));
        if (nt) std::memcpy(out->mesh.faces, imp.tris.data(), nt * 3 * sizeof(std::uint32_t));
        out->n_polygons = imp.n_polygons;
        out->n_polygon_refs = imp.n_refs;
        out->first_bad_face = imp.first_bad_face;
        out->bad_index = imp.bad_index;
        return 0;
    } catch (const std::bad_alloc &) {
        mim_mesh_free(&out->mesh);
        return MIM_ENOMEM;
    } catch (const std::exception &e) {
        mim_mesh_free(&out->mesh);
        out->library_failed = 1;
        std::snprintf(out->library_msg, sizeof out->library_msg, "OpenMesh: %s", e.what());
        return MIM_EFORMAT;
    } catch (...) {
        mim_mesh_free(&out->mesh);
        out->library_failed = 1;
        std::snprintf(out->library_msg, sizeof out->library_msg, "OpenMesh failed");
        return MIM_EFORMAT;
    }
}

extern "C" void mim__raw_mesh_free(mim__raw_mesh_t *r)
{
    if (r) mim_mesh_free(&r->mesh);
}
