// Loading triangle meshes from files: PLY (ascii, binary little/big endian, optionally
// gzip-compressed) and OBJ, chosen by file content and extension. The only module that
// touches files. Depends on core and geometry.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "renderer/geometry/mesh.h"

namespace kdt {

struct MeshLoadOptions {
    /// Drop faces using non-finite vertices, and faces of fewer than 3 indices, instead of
    /// failing.
    bool drop_invalid = false;
    bool keep_normals = true;  ///< keep per-vertex normals when the file has them
    bool keep_colors = true;   ///< keep per-vertex colours when the file has them
    /// Threads parsing ascii PLY: 1 = one (default; on the shared 2-core machine two were
    /// slower in wall time), 2 = two, 0 = two when the machine has them.
    int threads = 1;
};

/// What a load found, for `kdtrace info` and reports.
struct MeshLoadInfo {
    std::string format;    ///< "ply", "obj"
    std::string encoding;  ///< "ascii", "binary_little_endian", "binary_big_endian", "text"
    bool gzip = false;
    uint64_t file_bytes = 0;  ///< bytes of file data parsed (uncompressed)
    /// Bytes taken from the file (inflated bytes for gzip), parsed or read ahead. PLY sets
    /// this and array_bytes also when the load fails after its header.
    uint64_t input_bytes_read = 0;
    uint64_t array_bytes = 0;   ///< bytes the mesh arrays had allocated (their capacity)
    uint64_t source_faces = 0;  ///< polygons in the file
    /// With drop_invalid: faces dropped for non-finite vertices or fewer than 3 indices.
    uint64_t dropped_faces = 0;
    uint64_t degenerate_faces = 0;  ///< faces with repeated indices (kept)
    /// Problems of the file that are not errors (a PLY version other than 1.0), one line
    /// each naming the file and where, without a "warning: " prefix.
    std::vector<std::string> warnings;
    double seconds = 0.0;
};

enum class MeshFormat : uint8_t { unknown, ply, obj };

/// Format of a mesh file by content (a stream starting with "ply", gzip or not), else by
/// extension (.obj, .ply, .ply.gz). Throws kdt::Error when the file cannot be opened.
MeshFormat detect_mesh_format(const std::string& path);

/// Loads any supported mesh file. Throws kdt::Error with file name, element, index and
/// line or byte offset on any malformed input; never crashes on hostile files.
TriangleMesh load_mesh(const std::string& path, const MeshLoadOptions& options = {},
                       MeshLoadInfo* info = nullptr);

}  // namespace kdt
