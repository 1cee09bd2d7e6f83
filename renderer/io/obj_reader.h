// Our own Wavefront OBJ reader: positions, normals and polygonal faces (fan-triangulated),
// read in one pass through io/file_reader; everything else (texture coordinates, lines,
// points, groups, materials, free-form geometry) is skipped. Depends on core, geometry and
// io/file_reader.
#pragma once

#include <cstddef>
#include <string>

#include "renderer/geometry/mesh.h"
#include "renderer/io/file_reader.h"
#include "renderer/io/mesh_io.h"

namespace kdt {

/// Reads a Wavefront OBJ file.
///
/// Statements: `v x y z [w | r g b [a]]` (extra values ignored), `vn x y z`, and `f` (or
/// `fo`) with corners `v`, `v/vt`, `v//vn` or `v/vt/vn`; indices are 1-based, negative ones
/// count back from the last vertex or normal defined so far, positive ones may point ahead.
/// Polygons become fans (v0, vi, vi+1); faces with repeated indices are kept and counted in
/// info->degenerate_faces. Comments (`#`, also after a statement), `\` line continuation (a
/// `\` ending the file continues onto nothing), LF, CRLF and CR line endings (mixed too), a
/// missing final newline and a UTF-8 byte order mark are accepted. Other statements starting with a
/// letter (vt, vp, l, p, o, g, s, usemtl, mtllib, ...) are ignored: materials are not used and no
/// other file is ever opened.
///
/// The file is read in 1 MiB blocks. A line longer than a block is read in pieces, holding
/// one value or corner at a time, so comments and skipped statements of any length cost no
/// memory and a polygon costs 4 bytes (8 with normals) per corner, not its text.
///
/// Vertices are split per distinct (position, normal) pair when every face corner names a
/// normal, otherwise the file's positions are used as they are and normals are dropped.
/// Non-finite positions are an error unless options.drop_invalid, which drops the faces
/// using them and the vertices themselves (indices are remapped), as for PLY; it also drops
/// faces of fewer than 3 corners (their indices unchecked). Both count in info->dropped_faces.
///
/// Throws kdt::Error naming the file, the line and the vertex, normal or face (numbered from
/// 1, as OBJ indices are: "vertex 1" is the first `v` line, "face 1" the first face) for: a file
/// that cannot be opened or is not a regular file, gzip input, a file without vertices, a line not
/// starting with a statement keyword or holding a NUL byte (binary data, UTF-16), malformed
/// numbers or corners, a value or corner of 1 MiB or more, index 0, indices out of range or
/// pointing before the first element, faces with fewer than 3 corners (without drop_invalid),
/// more than 2^32-1 vertices or normals.
TriangleMesh read_obj(const std::string& path, const MeshLoadOptions& options = {},
                      MeshLoadInfo* info = nullptr);

/// Same, from an open reader (file or memory; gzip input is refused).
TriangleMesh read_obj(FileReader& reader, const MeshLoadOptions& options = {},
                      MeshLoadInfo* info = nullptr);

/// Same, from `size` bytes in memory; `name` appears in error messages (tests, fuzzing).
TriangleMesh read_obj_memory(const void* data, size_t size, const std::string& name,
                             const MeshLoadOptions& options = {}, MeshLoadInfo* info = nullptr);

namespace obj {

/// Sets the block size later reads use (default 1 MiB, at least 1) and returns the previous
/// one. Tests and fuzzing only, not a user option: a small block makes small inputs take the
/// long-line path and cross block ends; the result (mesh or message) must not change. Not
/// thread-safe: to be called while no OBJ file is being read.
size_t set_block_bytes(size_t bytes);

}  // namespace obj

}  // namespace kdt
