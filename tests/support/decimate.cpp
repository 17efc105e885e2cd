// Quadric decimation for ground-truth meshes (retriangulate.h): OpenMesh's
// Decimater with ModQuadricT (Garland and Heckbert 1997) as the priority and
// ModNormalFlippingT as a veto, so that no triangle turns over. The
// Decimater collapses half-edges: every vertex it keeps is an original one,
// at its original position, which is what makes the result ground truth.
// No C++ type or exception crosses into C.
#include "retriangulate.h"

// OpenMesh's VectorT leaves its elements uninitialised by design, which
// GCC's -Wmaybe-uninitialized reports (with -O2) inside the property
// containers of a mesh kernel: a false positive in OpenMesh's code, so it is
// silenced for this file only.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <streambuf>
#include <vector>

namespace {

struct Traits : OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec3d Normal;
};
typedef OpenMesh::TriMesh_ArrayKernelT<Traits> Mesh;

// OpenMesh reports on its global streams (a complex edge in add_face, a
// missing normal): the caller is told by the return code instead. As io/'s
// shims do, those streams get, once, a buffer that drops everything.
class NullBuffer : public std::streambuf {
protected:
    int overflow(int c) override { return traits_type::not_eof(c); }
    std::streamsize xsputn(const char *, std::streamsize n) override { return n; }
};

void quiet_openmesh()
{
    static std::once_flag once;
    std::call_once(once, [] {
        static NullBuffer sink;
        omerr().rdbuf(&sink);
        omlog().rdbuf(&sink);
        omout().rdbuf(&sink);
    });
}

int decimate(const mim_mesh_t *in, std::uint32_t target, mim_mesh_t *out, std::uint32_t **orig_of_new)
{
    Mesh mesh;
    mesh.request_vertex_status();
    mesh.request_edge_status();
    mesh.request_face_status();
    OpenMesh::VPropHandleT<std::uint32_t> orig;
    mesh.add_property(orig);
    mesh.reserve(in->n_vertices, 3 * size_t(in->n_faces) / 2, in->n_faces);
    std::vector<Mesh::VertexHandle> vh(in->n_vertices);
    for (std::uint32_t v = 0; v < in->n_vertices; v++) {
        const float *p = in->positions + 3 * size_t(v);
        vh[v] = mesh.add_vertex(Mesh::Point(p[0], p[1], p[2]));
        mesh.property(orig, vh[v]) = v;
    }
    for (std::uint32_t f = 0; f < in->n_faces; f++) {
        const std::uint32_t *t = in->faces + 3 * size_t(f);
        // a complex (non-manifold) edge or vertex, or a degenerate triangle
        if (!mesh.add_face(vh[t[0]], vh[t[1]], vh[t[2]]).is_valid()) return MIM_EINVAL;
    }
    // vertices on no face first, so that the target counts only the others
    for (Mesh::VertexHandle v : mesh.vertices())
        if (mesh.is_isolated(v)) mesh.delete_vertex(v, false);
    mesh.garbage_collection();

    if (target < mesh.n_vertices()) {
        OpenMesh::Decimater::DecimaterT<Mesh> dec(mesh);
        OpenMesh::Decimater::ModQuadricT<Mesh>::Handle quadric;
        OpenMesh::Decimater::ModNormalFlippingT<Mesh>::Handle flipping;
        dec.add(quadric);
        dec.add(flipping);
        dec.module(quadric).unset_max_err(); // priority only: the target decides
        if (!dec.initialize()) return MIM_EUNSUPPORTED;
        dec.decimate_to(target);
        mesh.garbage_collection();
    }

    size_t nv = mesh.n_vertices(), nf = mesh.n_faces();
    int rc = mim_mesh_alloc(out, std::uint32_t(nv), std::uint32_t(nf));
    if (rc) return rc;
    std::uint32_t *map = nullptr;
    if (orig_of_new) {
        map = static_cast<std::uint32_t *>(std::malloc((nv ? nv : 1) * sizeof *map));
        if (!map) {
            mim_mesh_free(out);
            return MIM_ENOMEM;
        }
    }
    for (Mesh::VertexHandle v : mesh.vertices()) {
        const Mesh::Point &p = mesh.point(v);
        size_t i = size_t(v.idx());
        for (int k = 0; k < 3; k++) out->positions[3 * i + k] = float(p[k]);
        if (map) map[i] = mesh.property(orig, v);
    }
    for (Mesh::FaceHandle f : mesh.faces()) {
        size_t i = 3 * size_t(f.idx()), k = 0;
        for (Mesh::VertexHandle v : mesh.fv_range(f)) out->faces[i + k++] = std::uint32_t(v.idx());
    }
    if (orig_of_new) *orig_of_new = map;
    return 0;
}

} // namespace

extern "C" int rt_decimate_map(const mim_mesh_t *in, std::uint32_t target_vertices, mim_mesh_t *out,
                               std::uint32_t **orig_of_new)
{
    if (orig_of_new) *orig_of_new = nullptr;
    if (!out) return MIM_EINVAL;
    std::memset(out, 0, sizeof *out);
    if (!in || !in->n_vertices || !in->n_faces || !in->positions || !in->faces || target_vertices < 4)
        return MIM_EINVAL;
    // OpenMesh's handles are ints
    if (in->n_vertices > std::uint32_t(INT32_MAX) || in->n_faces > std::uint32_t(INT32_MAX) / 3)
        return MIM_EUNSUPPORTED;
    for (size_t k = 0; k < 3 * size_t(in->n_faces); k++)
        if (in->faces[k] >= in->n_vertices) return MIM_EINVAL;
    int rc;
    try {
        quiet_openmesh();
        rc = decimate(in, target_vertices, out, orig_of_new);
    } catch (const std::bad_alloc &) {
        rc = MIM_ENOMEM;
    } catch (...) {
        rc = MIM_EUNSUPPORTED;
    }
    if (rc) {
        mim_mesh_free(out);
        if (orig_of_new) {
            std::free(*orig_of_new);
            *orig_of_new = nullptr;
        }
    }
    return rc;
}

extern "C" int rt_decimate(const mim_mesh_t *in, std::uint32_t target_vertices, mim_mesh_t *out)
{
    return rt_decimate_map(in, target_vertices, out, nullptr);
}
