// The kd-tree: parameters, the compact node layout, and closest-hit / any-hit queries.
// Depends on core and geometry. Builders live in thesis_builder.* and sah_builder.*,
// traversal in traversal.*, cache files in kdtree_cache.*.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "renderer/core/math.h"
#include "renderer/geometry/mesh.h"

namespace kdt {

enum class KdBuilder : uint8_t { thesis, sah };
/// One table of names for CLI flags, ImGui widgets and cache headers.
inline constexpr std::array<const char*, 2> kKdBuilderNames = {"thesis", "sah"};

/// Parameters of both builders. q and n0 define the thesis's f(n) correction
/// (f(n) = n for n <= n0, (n - n0)^(1 + log2 q) + n0 otherwise); q = 1 is the linear cost.
struct KdTreeParams {
    KdBuilder builder = KdBuilder::sah;
    float q = 0.98f;              ///< in (0, 1]
    int n0 = 5;                   ///< >= 0
    int max_depth = 0;            ///< 0..64; 0 = automatic (8 + 1.3 log2 N)
    bool use_median_split = true; ///< thesis builder: candidate "median vertex"
    bool use_center_split = true; ///< thesis builder: candidate "spatial middle"
    bool use_cutoff_split = true; ///< thesis builder: candidates "cut off empty space"
    float traversal_cost = 1.0f;  ///< SAH builder: cost of one inner node relative to ...
    float intersect_cost = 1.5f;  ///< ... one ray-triangle test
    float empty_bonus = 0.2f;     ///< SAH builder: cost reduction for cutting off empty space
    int threads = 0;              ///< 0 = OpenMP default
};

/// Closest hit of a query. prim == kNoHit on a miss.
struct Hit {
    static constexpr uint32_t kNoHit = 0xffffffffu;
    float t = kInfinity;
    float u = 0.0f, v = 0.0f;  ///< barycentrics of vertices 1 and 2 of the triangle
    uint32_t prim = kNoHit;
    bool valid() const { return prim != kNoHit; }
};

/// Per-ray cost counters for heat maps and benchmarks, accumulated by the queries.
struct TraversalCounters {
    uint64_t nodes_visited = 0;
    uint64_t triangles_tested = 0;
};

}  // namespace kdt
