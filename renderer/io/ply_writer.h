// Writes triangle meshes as PLY in any of the three encodings (for tests, benchmarks and
// converting the ASCII dragon to binary). Depends on core, geometry, zlib.
#pragma once

#include <string>

#include "renderer/geometry/mesh.h"
#include "renderer/io/ply_reader.h"

namespace kdt {

/// Writes `mesh` to `path`: vertex x, y, z as float, then nx, ny, nz (float) when the mesh
/// has normals and red, green, blue (float, linear as stored) when it has colours; faces
/// as "list uchar uint vertex_indices". ASCII floats use the shortest representation that
/// reads back exactly, so every encoding round-trips bit for bit. A path ending in ".gz"
/// is gzip-compressed. Throws kdt::Error when the file cannot be written.
void write_ply(const std::string& path, const TriangleMesh& mesh, PlyEncoding encoding);

}  // namespace kdt
