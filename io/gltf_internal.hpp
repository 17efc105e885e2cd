// What io/'s tinygltf shims share (C++ only, internal to io/): loading a
// file under the guard (read_gltf.cpp), checked accessor data, and the
// walk of a scene into placed primitives (gltf_scene.cpp), so that the
// reader and the writer that keeps an avatar's look see the same parts in
// the same order.
#ifndef MIM_IO_GLTF_INTERNAL_HPP
#define MIM_IO_GLTF_INTERNAL_HPP

#include "read_shim.h"

#include <tiny_gltf.h>

#include <array>
#include <string>
#include <vector>

namespace mim_gltf {

// Parses path (external files only from its folder). images: keep each
// image's bytes undecoded in Image::image (as_is), else skip them.
// Returns 0 or a MIM_E* code with one line in *msg.
int load_model(const char *path, tinygltf::Model *model, bool images, std::string *msg);

// The bytes of accessor `index` whose elements are elem_size bytes, and
// its stride; nullptr with why and a code (MIM_EFORMAT, MIM_EUNSUPPORTED
// for sparse, MIM_ETRUNCATED) when it cannot be read.
const unsigned char *accessor_data(const tinygltf::Model &m, int index, size_t elem_size, size_t *stride,
                                   std::string *why, int *code);
uint32_t read_index(const unsigned char *p, int component);

typedef std::array<double, 16> mat4; // column-major, as glTF

// One primitive of the scene, as the walk meets it.
struct placed {
    int node;        // -1: a mesh no node instantiates (read untransformed)
    int mesh, primitive;
    mat4 world;      // the node's world transform (identity without a node)
    int skin;        // the node's skin, -1: none
    int bone;        // the nearest ancestor node that is some skin's joint, -1: none
};

// The primitives of the default scene (else scene 0, else the root nodes),
// depth first, filtered by opt (mesh or node names). Returns 0, or a code
// with one line in *msg (a node graph that is not a forest, a bad
// transform, a selected name found nowhere).
int walk_scene(const tinygltf::Model &m, const mim_io_read_options_t *opt, std::vector<placed> *out,
               std::vector<mat4> *node_world, std::string *msg);

} // namespace mim_gltf

#endif
