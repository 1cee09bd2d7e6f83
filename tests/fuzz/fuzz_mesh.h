// What the mesh fuzz targets share: one read's outcome, and bitwise mesh comparison for the
// targets that read an input two ways and require the same result.
#pragma once

#include <cstring>
#include <string>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/io/mesh_io.h"

namespace kdt::fuzz {

/// What one read gave: the mesh and its load info, or the error's message.
struct ReadResult {
    TriangleMesh mesh;
    MeshLoadInfo info;
    std::string error;  // empty when it loaded
};

/// Runs read(&info); a kdt::Error becomes the message (an empty one is a bug).
template <typename F>
ReadResult result_of(F&& read) {
    ReadResult r;
    try {
        r.mesh = read(&r.info);
    } catch (const Error& e) {
        r.error = e.what();
        if (r.error.empty()) __builtin_trap();
    }
    return r;
}

template <typename T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

/// The same positions, triangles, normals and colours, bit for bit.
inline bool same_mesh(const TriangleMesh& a, const TriangleMesh& b) {
    return same_bytes(a.positions, b.positions) && same_bytes(a.triangles, b.triangles) &&
           same_bytes(a.normals, b.normals) && same_bytes(a.colors, b.colors);
}

}  // namespace kdt::fuzz
