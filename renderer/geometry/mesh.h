// Indexed triangle meshes: the one geometry type kdtrace renders.
// Depends on core only.
#pragma once

#include <cmath>
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
    /// Whether a ray can ever hit triangle i: its indices are in range and distinct and its
    /// vertices finite. Trees need hold no other triangle (the watertight test never reports
    /// one with a repeated vertex).
    bool triangle_hittable(size_t i) const {
        const Vec3u& t = triangles[i];
        const size_t n = positions.size();
        return t.x < n && t.y < n && t.z < n && t.x != t.y && t.y != t.z && t.z != t.x &&
               is_finite(positions[t.x]) && is_finite(positions[t.y]) && is_finite(positions[t.z]);
    }
    /// 64-bit FNV-1a hash of positions and triangles (for cache validation).
    uint64_t content_hash() const;
};

/// Appends src to dst, offsetting indices. Attributes present in only one mesh are
/// dropped from the result.
void append_mesh(TriangleMesh& dst, const TriangleMesh& src);

/// Applies an affine transform to positions (and the inverse transpose to normals). A
/// transform with a negative determinant (a mirror) also reverses every triangle's winding,
/// so that faces seen from the front before are seen from the front after.
void transform_mesh(TriangleMesh& mesh, const Mat4f& world_from_object);

/// Angle-weighted vertex normals (Thürmer & Wüthrich 1998); degenerate triangles add nothing.
std::vector<Vec3f> compute_vertex_normals(const TriangleMesh& mesh);

/// (b - a) x (c - a) in double, whose length is twice the triangle's area: in float the
/// squared length overflows for edges beyond about 1e9 and underflows below about 1e-10,
/// so a normal normalised in float is lost at such scales.
inline Vec3d triangle_cross(const Vec3f& a, const Vec3f& b, const Vec3f& c) {
    return glm::cross(Vec3d(b) - Vec3d(a), Vec3d(c) - Vec3d(a));
}

/// Unit normal of the winding (a, b, c) at any scale; (0, 0, 0) for a degenerate triangle.
inline Vec3f triangle_normal(const Vec3f& a, const Vec3f& b, const Vec3f& c) {
    const Vec3d n = triangle_cross(a, b, c);
    const double len = glm::length(n);
    return len > 0.0 && std::isfinite(len) ? Vec3f(n / len) : Vec3f(0.0f);
}

/// A reordering of a mesh: new index i holds old index order[i].
struct MeshOrder {
    std::vector<uint32_t> triangles;  ///< old triangle index of each new triangle
    std::vector<uint32_t> vertices;   ///< old vertex index of each new vertex
};

/// An order that puts triangles close in space close in memory: triangles sorted (stably)
/// by the Morton code of their bounding-box centre on a 1024^3 grid over the mesh bounds,
/// vertices in order of first use (unused ones last, in their old order). Queries then touch
/// fewer cache lines and pages per kd-tree leaf. Deterministic; O(N) (radix sort).
MeshOrder spatial_order(const TriangleMesh& mesh);

/// out[i] = v[order[i]]: per-triangle or per-vertex data in the new order of a MeshOrder.
template <class T>
std::vector<T> permuted(const std::vector<T>& v, const std::vector<uint32_t>& order) {
    std::vector<T> out(order.size());
    for (size_t i = 0; i < order.size(); ++i) out[i] = v[order[i]];
    return out;
}

/// Reorders positions, normals, colors and triangles (with remapped indices) by `order`.
/// order must come from spatial_order(mesh) or be permutations of the same sizes.
void apply_order(TriangleMesh& mesh, const MeshOrder& order);

/// Splits every triangle into 4 by its edge midpoints, `levels` times (4^levels triangles
/// each). Shared edges get one shared midpoint so the result stays watertight. A result of
/// kMaxSubdividedTriangles or more is refused (kdt::Error) before anything is allocated.
TriangleMesh subdivide_mesh(const TriangleMesh& mesh, int levels);

/// The kd-tree builders take fewer than 2^30 triangles; 32-bit vertex indices stay valid.
inline constexpr uint64_t kMaxSubdividedTriangles = uint64_t(1) << 30;

/// Triangles of subdivide_mesh(mesh of `triangles`, levels), saturating at 2^63.
uint64_t subdivided_triangle_count(uint64_t triangles, int levels);

}  // namespace kdt
