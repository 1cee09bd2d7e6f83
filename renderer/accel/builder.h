// Internal interface between build_kdtree() and the two builders.
// Builders see triangle bounds and clipping only; they never trace rays.
#pragma once

#include <cmath>
#include <vector>

#include "renderer/accel/kdtree.h"

namespace kdt {

/// A finished build: nodes in depth-first order with adjacent children (node 0 = root),
/// leaf triangle indices, the root box, and statistics (filled by finalize_stats()).
struct KdBuildOutput {
    Bounds3f bounds;
    std::vector<KdNode> nodes;
    std::vector<uint32_t> indices;
    KdTreeStats stats;
};

/// The thesis's builder (section 5.2.2): candidates cut-off left/right, spatial middle,
/// median vertex and terminate, under the Szécsi cost with the f(n) correction.
KdBuildOutput build_thesis_tree(const TriangleMesh& mesh, const KdTreeParams& params);

/// Wald & Havran 2006 O(N log N) SAH builder with perfect splits.
KdBuildOutput build_sah_tree(const TriangleMesh& mesh, const KdTreeParams& params);

/// The thesis's f(n): n for n <= n0, (n - n0)^(1 + log2 q) + n0 otherwise.
inline float thesis_f(float n, float q, int n0) {
    if (n <= float(n0)) return n;
    return std::pow(n - float(n0), 1.0f + std::log2(q)) + float(n0);
}

/// Fills out.stats from the node array (counts, leaf sizes, depth histogram, bytes).
/// Split-kind counters and build_seconds are left as the builder set them.
void finalize_stats(KdBuildOutput& out, size_t triangle_count);

}  // namespace kdt
