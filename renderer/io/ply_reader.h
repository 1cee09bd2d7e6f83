// Our own PLY reader: ascii, binary_little_endian and binary_big_endian, every scalar type
// and alias, any property order, unknown elements and properties skipped, polygons
// triangulated as fans, gzip read transparently. One pass: plain files of 1 MiB and more are
// mapped and read through a sliding window, other input through a block buffer; ascii lines
// are parsed whole from byte-class masks, on one thread or two. Bad input throws kdt::Error
// with file, element, index and line or byte offset. Depends on core, geometry and
// io/file_reader.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include "renderer/geometry/mesh.h"
#include "renderer/io/file_reader.h"
#include "renderer/io/mesh_io.h"

namespace kdt {

enum class PlyEncoding : uint8_t { ascii, binary_little_endian, binary_big_endian };
inline constexpr std::array<const char*, 3> kPlyEncodingNames = {"ascii", "binary_little_endian",
                                                                 "binary_big_endian"};

/// Reads a PLY file (plain or gzip-compressed).
///
/// Vertex element "vertex": x, y, z required (any scalar type); nx, ny, nz kept as normals
/// and red, green, blue (also r/g/b, diffuse_red/...) kept as colours when all three are
/// present. Integer colours are divided by their type's maximum (uchar by 255), float
/// colours kept as given (linear, no sRGB conversion). Face element "face": the list
/// "vertex_indices" (or "vertex_index"); polygons become fans (v0, vi, vi+1). Faces with
/// repeated indices are kept and counted in info->degenerate_faces. Other elements and
/// properties, lists included, are skipped. Header lines with an unknown keyword are ignored
/// like comments (old Blender exporters write a bare "Created by ..." line).
/// Extra data after the last element: trailing bytes of binary files are ignored (some
/// writers pad or add a footer) with a warning in info->warnings naming the file, the byte
/// offset and how many follow (for gzip, up to "more than 65536"), since they may also be data
/// that counts too small leave out; one line end (LF, CRLF) or one blank is ignored silently.
/// Non-blank text within 64 KiB after the last ascii element is an error: text is never
/// padding, so it means the header's counts do not match the data (what lies further is not
/// read).
/// Counts are checked before anything is allocated: input of known size must be able to hold
/// them, gzip input within the inflation limit (io/file_reader.h), and its arrays grow
/// as its data arrives, so memory follows the data, not the header. Running out of memory is
/// an Error naming the file and element.
/// Non-finite vertex coordinates are an error unless options.drop_invalid, which drops the
/// faces using them and the vertices themselves (indices are remapped); so are faces of fewer
/// than 3 indices, which it drops (both counted in info->dropped_faces). CR-only line ends
/// (old Mac) are refused by name: lines end at LF (CRLF included).
TriangleMesh read_ply(const std::string& path, const MeshLoadOptions& options = {},
                      MeshLoadInfo* info = nullptr);

/// Same, from an open reader (file, gzip or memory).
TriangleMesh read_ply(FileReader& reader, const MeshLoadOptions& options = {},
                      MeshLoadInfo* info = nullptr);

/// Same, from `size` bytes in memory; `name` appears in error messages (tests, fuzzing).
TriangleMesh read_ply_memory(const void* data, size_t size, const std::string& name,
                             const MeshLoadOptions& options = {}, MeshLoadInfo* info = nullptr);

}  // namespace kdt
