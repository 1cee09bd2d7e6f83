// Indexed triangle meshes: the one geometry type kdtrace renders.
// Depends on core only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "renderer/core/math.h"

namespace kdt {

/// An indexed triangle mesh. normals and colors are either empty or one per vertex.
/// Triangles index positions; winding is counter-clockwise seen from the front.
struct TriangleMesh {
    std::vector<Vec3f> positions;
    std::vector<Vec3f> normals;  ///< per-vertex shading normals from the file, may be empty
    std::vector<Vec3f> colors;   ///< per-vertex linear RGB in [0,1], may be empty
    std::vector<Vec3u> triangles;

    size_t vertex_count() const { return positions.size(); }
    size_t triangle_count() const { return triangles.size(); }
    /// Bytes held by the arrays (size, not capacity).
    size_t memory_bytes() const;
    /// Bounds of all vertices referenced or not; empty for an empty mesh.
    Bounds3f bounds() const;
    /// Bounds of triangle i.
    Bounds3f triangle_bounds(size_t i) const {
        const Vec3u& t = triangles[i];
        Bounds3f b;
        b.extend(positions[t.x]);
        b.extend(positions[t.y]);
        b.extend(positions[t.z]);
        return b;
    }
    /// 64-bit FNV-1a hash of positions and triangles (for cache validation).
    uint64_t content_hash() const;
};

/// Appends src to dst, offsetting indices. Attributes present in only one mesh are
/// dropped from the result.
void append_mesh(TriangleMesh& dst, const TriangleMesh& src);

/// Applies an affine transform to positions (and the inverse transpose to normals).
void transform_mesh(TriangleMesh& mesh, const Mat4f& world_from_object);

/// Angle-weighted vertex normals (Thürmer & Wüthrich 1998); degenerate triangles add nothing.
std::vector<Vec3f> compute_vertex_normals(const TriangleMesh& mesh);

/// Splits every triangle into 4 by its edge midpoints, `levels` times (4^levels triangles
/// each). Shared edges get one shared midpoint so the result stays watertight.
TriangleMesh subdivide_mesh(const TriangleMesh& mesh, int levels);

}  // namespace kdt
