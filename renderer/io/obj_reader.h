// OBJ loading through tinyobjloader (Debian libtinyobjloader-dev): triangulated faces,
// per-vertex normals when every corner has one. Depends on core, geometry, tinyobjloader.
#pragma once

#include <cstddef>
#include <string>

#include "renderer/geometry/mesh.h"
#include "renderer/io/mesh_io.h"

namespace kdt {

/// Reads a Wavefront OBJ file. Polygons are triangulated by tinyobjloader; vertices are
/// split per distinct (position, normal) pair when the file has normals, otherwise the
/// file's positions are used as they are. Missing files, parse errors, faces with out of
/// range indices and non-finite positions (unless options.drop_invalid) throw kdt::Error.
/// Materials are not used: `mtllib` lines are ignored and no other file is ever opened.
TriangleMesh read_obj(const std::string& path, const MeshLoadOptions& options = {},
                      MeshLoadInfo* info = nullptr);

/// Same, from `size` bytes in memory; `name` appears in error messages (tests, fuzzing).
TriangleMesh read_obj_memory(const void* data, size_t size, const std::string& name,
                             const MeshLoadOptions& options = {}, MeshLoadInfo* info = nullptr);

}  // namespace kdt
