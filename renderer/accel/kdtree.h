// The kd-tree: parameters, the compact node layout, and closest-hit / any-hit queries.
// Depends on core and geometry. Builders live in thesis_builder.* and sah_builder.*,
// traversal in traversal.*, cache files in kdtree_cache.*.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/core/fields.h"
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
    float q = 0.98f;               ///< in (0, 1]
    int n0 = 5;                    ///< >= 0
    int max_depth = 0;             ///< 0..64; 0 = automatic (8 + 1.3 log2 N)
    bool use_median_split = true;  ///< thesis builder: candidate "median vertex"
    bool use_center_split = true;  ///< thesis builder: candidate "spatial middle"
    bool use_cutoff_split = true;  ///< thesis builder: candidates "cut off empty space"
    float traversal_cost = 4.0f;   ///< SAH builder: cost of one inner node relative to ...
    float intersect_cost = 1.0f;   ///< ... one ray-triangle test
    float empty_bonus = 0.2f;      ///< SAH builder: cost reduction for cutting off empty space
    // The SAH defaults are the flat optimum of traversal speed on the dragon with the fewest
    // nodes and references (the settings compared: docs/performance.md).
    int threads = 0;  ///< 0 = OpenMP default
    /// Thesis builder: evaluate the candidates on x, y and z and keep the cheapest, instead
    /// of alternating x, y, z by depth as the thesis did (false = the thesis's rule).
    bool thesis_all_axes = false;
};

/// Closest hit of a query. prim == kNoHit on a miss.
struct Hit {
    static constexpr uint32_t kNoHit = 0xffffffffu;
    float t = kInfinity;
    float u = 0.0f, v = 0.0f;  ///< barycentrics of vertices 1 and 2 of the triangle
    uint32_t prim = kNoHit;
    bool valid() const { return prim != kNoHit; }
};

/// The nodes from the root to one node of a tree: nodes[0] is the root (0), each next one a
/// child of the one before, nodes[length - 1] the node itself. intersect() can report the
/// path to the leaf where it found its hit; a ray that starts there (a bounce, a shadow ray)
/// can then begin at that leaf instead of descending from the root again.
struct KdPath {
    static constexpr uint32_t kMaxLength = 65;  ///< trees are at most 64 levels deep
    uint32_t length = 0;                        ///< 0: no path
    uint32_t nodes[kMaxLength];
};

/// Per-ray cost counters for heat maps and benchmarks, accumulated by the queries.
struct TraversalCounters {
    uint64_t nodes_visited = 0;
    uint64_t triangles_tested = 0;
};

}  // namespace kdt

namespace kdt {

/// One 8-byte node. word & 3 is the split axis (0, 1, 2) or 3 for a leaf.
/// Inner: word >> 4 is the index of the first child; the second child follows it
/// (children adjacent, depth-first order); `split` is the plane position. Bits 2 and 3 are
/// set when the first or the second child is an empty leaf, so the descent skips such a
/// child without reading it: KdTree derives them from the children (builders and cache
/// files need not set them, and cannot make them lie).
/// Leaf: word >> 2 is the triangle count; `first` indexes KdTree::indices().
/// Builder contract the traversal relies on: a child references every triangle that meets
/// its closed box outside the split plane; a triangle meeting it only within the plane may go
/// to either side (or both). Rays lying in a split plane visit both children.
struct KdNode {
    uint32_t word = 3;
    union {
        float split;
        uint32_t first = 0;
    };

    /// Nodes a tree can have: an inner node's child index has 28 bits.
    static constexpr uint64_t kMaxNodes = uint64_t(1) << 28;

    bool is_leaf() const { return (word & 3u) == 3u; }
    /// A leaf without triangles: the traversal never enters one (one compare of the word).
    bool is_empty_leaf() const { return word == 3u; }
    int axis() const { return int(word & 3u); }
    uint32_t child() const { return word >> 4; }
    /// Inner: bit 0 set if the first child is an empty leaf, bit 1 if the second is.
    uint32_t empty_children() const { return (word >> 2) & 3u; }
    uint32_t count() const { return word >> 2; }

    static KdNode make_leaf(uint32_t count, uint32_t first_index) {
        KdNode n;
        n.word = (count << 2) | 3u;
        n.first = first_index;
        return n;
    }
    /// first_child < kMaxNodes; the empty-child bits start clear.
    static KdNode make_inner(int axis, float split_pos, uint32_t first_child) {
        KdNode n;
        n.word = (first_child << 4) | uint32_t(axis);
        n.split = split_pos;
        return n;
    }
    void set_empty_children(uint32_t bits) { word = (word & ~0xcu) | ((bits & 3u) << 2); }
};
static_assert(sizeof(KdNode) == 8, "kd-tree nodes are 8 bytes");

/// What a build produced, as the thesis's tables report it.
struct KdTreeStats {
    uint64_t nodes = 0, leaves = 0, empty_leaves = 0;
    uint64_t references = 0;  ///< triangle indices stored in leaves
    double refs_per_triangle = 0.0;
    double mean_leaf_size = 0.0;  ///< over non-empty leaves
    uint32_t max_leaf_size = 0;
    uint32_t max_depth_reached = 0;
    std::vector<uint64_t> depth_histogram;  ///< leaves per depth
    uint64_t median_splits = 0, center_splits = 0, cutoff_splits = 0, sah_splits = 0;
    uint64_t bytes = 0;  ///< nodes + indices + any per-triangle data
    double bytes_per_triangle = 0.0;
    double build_seconds = 0.0;
    /// Estimate of build memory at its peak: the builder's scratch, or the final arrays
    /// (nodes, indices, reference triangles) when they take more.
    uint64_t peak_build_bytes = 0;
};

/// Whether a tree stores each reference's vertex indices (KdTree::reference_triangles()).
/// They never change a hit, only speed: within_budget is what every tool uses; always and
/// never let a benchmark compare trees with the same leaf data.
enum class LeafVertexIndices : uint8_t { within_budget, always, never };

/// An immutable kd-tree over one mesh. Shares ownership of the mesh it was built on.
class KdTree {
public:
    KdTree() = default;
    KdTree(std::shared_ptr<const TriangleMesh> mesh, Bounds3f bounds, std::vector<KdNode> nodes,
           std::vector<uint32_t> indices, KdTreeParams params, KdTreeStats stats,
           LeafVertexIndices leaf_vertex_indices = LeafVertexIndices::within_budget);

    const TriangleMesh& mesh() const { return *mesh_; }
    const std::shared_ptr<const TriangleMesh>& mesh_ptr() const { return mesh_; }
    const Bounds3f& bounds() const { return bounds_; }
    const std::vector<KdNode>& nodes() const { return nodes_; }
    const std::vector<uint32_t>& indices() const { return indices_; }
    const KdTreeParams& params() const { return params_; }
    const KdTreeStats& stats() const { return stats_; }
    /// Memory budget of a tree's acceleration data: the per-reference vertex indices are
    /// stored only when nodes, indices and they fit it together.
    static constexpr uint64_t kMaxBytesPerTriangle = 32;
    /// The vertex indices of each reference, parallel to indices() (or empty, over the
    /// budget): a leaf's triangles are read in sequence, without first fetching each one's
    /// record from the mesh.
    const std::vector<Vec3u>& reference_triangles() const { return reference_triangles_; }

    /// Closest hit in [ray.tmin, ray.tmax]. Returns false and leaves hit.prim == kNoHit on
    /// a miss; never throws or allocates. Non-finite rays miss.
    bool intersect(const Ray& ray, Hit& hit, TraversalCounters* counters = nullptr) const;
    /// Any hit in [ray.tmin, ray.tmax] (shadow rays).
    bool occluded(const Ray& ray, TraversalCounters* counters = nullptr) const;

    /// intersect(), also setting `leaf` to the path to the leaf where the hit was found
    /// (length 0 on a miss). Slightly slower than intersect(): each step records its node.
    bool intersect(const Ray& ray, Hit& hit, KdPath& leaf,
                   TraversalCounters* counters = nullptr) const;
    /// Closest hit of a ray that starts in or near the node at the end of `start` (nodes
    /// start[0..length), from the root; typically the path intersect() gave for the hit the
    /// ray leaves from). Instead of descending from the root, the query walks down the given
    /// path, which it reads as independent loads, setting aside the other child at each
    /// level wherever the ray meets it, and then goes on from that node. The result is
    /// intersect()'s for any path (same t; among triangles hit at exactly the same t the
    /// reported one may differ): a path far from the origin only costs time, and one that is
    /// not a path of this tree (a node out of range, not a child of the one before, not
    /// starting at the root) is ignored. If `leaf` is given, it receives the path of the new
    /// hit, as from intersect(); it may be the start path itself (one path, updated from
    /// bounce to bounce).
    bool intersect_from(const uint32_t* start, uint32_t length, const Ray& ray, Hit& hit,
                        KdPath* leaf = nullptr, TraversalCounters* counters = nullptr) const;
    bool intersect_from(const KdPath& start, const Ray& ray, Hit& hit, KdPath* leaf = nullptr,
                        TraversalCounters* counters = nullptr) const {
        return intersect_from(start.nodes, start.length, ray, hit, leaf, counters);
    }
    /// occluded() for a ray that starts in or near the node at the end of `start`.
    bool occluded_from(const uint32_t* start, uint32_t length, const Ray& ray,
                       TraversalCounters* counters = nullptr) const;
    bool occluded_from(const KdPath& start, const Ray& ray,
                       TraversalCounters* counters = nullptr) const {
        return occluded_from(start.nodes, start.length, ray, counters);
    }
    /// Batch closest hits: hits[i] is exactly what intersect(rays[i], hits[i]) gives (and
    /// the counters sum alike). Each group of 8 consecutive coherent rays (nearly parallel,
    /// nearby origins, like a camera's) is traced as one AVX2 packet, about 3x faster per
    /// ray; other groups go ray by ray, as fast as single calls.
    void intersect(const Ray* rays, size_t count, Hit* hits,
                   TraversalCounters* counters = nullptr) const;
    /// Batch any-hit queries: occluded[i] = 1 exactly when occluded(rays[i]) is true.
    void occluded(const Ray* rays, size_t count, uint8_t* occluded,
                  TraversalCounters* counters = nullptr) const;

private:
    std::shared_ptr<const TriangleMesh> mesh_;
    Bounds3f bounds_;
    std::vector<KdNode> nodes_;
    std::vector<uint32_t> indices_;
    std::vector<Vec3u> reference_triangles_;
    KdTreeParams params_;
    KdTreeStats stats_;
};

/// What build_kdtree() throws when its cancel flag was set during the build: the build was
/// abandoned, and nothing of it is kept.
class BuildCancelled : public Error {
public:
    BuildCancelled() : Error("kd-tree build cancelled") {}
};

/// Builds a tree with params.builder. Throws kdt::Error for out-of-range parameters. Another
/// thread may set *cancel to stop the build early: every node still to be decided becomes an
/// empty leaf at once and BuildCancelled is thrown instead of a tree (a node in the middle of
/// its split finishes it first, at most a pass over its triangles: well under a second on
/// 14M triangles).
std::shared_ptr<const KdTree> build_kdtree(std::shared_ptr<const TriangleMesh> mesh,
                                           const KdTreeParams& params,
                                           const std::atomic<bool>* cancel = nullptr);

/// Deepest tree the traversal's stack holds (one entry per level).
inline constexpr int kMaxTreeDepth = 64;

/// Leaf sizes kdtree_leaf_warning() lets pass: a root leaf of up to kRootLeafTriangles, other
/// leaves of up to kLargeLeafTriangles (each raised to 4 n0 when that is larger). The builders'
/// defaults stay well within them on the Stanford dragon and its coarser scans (largest
/// leaves: SAH 26-33, thesis 40-347, the latter with no parameter to blame).
inline constexpr uint32_t kRootLeafTriangles = 64;
inline constexpr uint32_t kLargeLeafTriangles = 128;

/// A one-line warning when the largest leaf of `tree` holds far more triangles than its
/// parameters intend, else empty: when the root is a leaf of more than kRootLeafTriangles
/// (whatever the cause), or a leaf holds more than kLargeLeafTriangles for a cause the user
/// can change. The causes, checked in this order: a thesis builder with neither median nor
/// spatial-middle split candidates (cut-off planes alone stop at a tight box), q below 0.9 (f(n)
/// then grows as n^(1 + log2 q), so a split rarely pays; at q 0.5 never), the depth limit reached,
/// an SAH traversal cost above the leaf's cost, an SAH intersection cost whose product with the
/// leaf's f(n) overflows float, a thesis builder (one axis per depth) at a leaf whose box is
/// flat along that axis; for a root leaf without any of these, triangles that no plane
/// separates. The message says what to try.
std::string kdtree_leaf_warning(const KdTree& tree);

/// The depth limit of KdTreeParams::max_depth = 0 for a tree over `triangles` triangles:
/// 8 + 1.3 log2 N, at most kMaxTreeDepth.
inline int automatic_max_depth(size_t triangles) {
    const double n = double(triangles > 0 ? triangles : 1);
    return std::min(kMaxTreeDepth, int(8.0 + 1.3 * std::log2(n)));
}

/// KdTreeParams as data (renderer/core/fields.h): name, flag, help and range of every field;
/// the defaults are KdTreeParams's initialisers.
std::span<const Field<KdTreeParams>> kd_tree_fields();

/// Whether `params.builder` reads the field of kd_tree_fields() named `name`: the
/// split-candidate switches and --all-axes are the thesis builder's, the SAH costs the SAH
/// builder's; the other fields both builders'. A field a builder does not read cannot change
/// its tree.
bool kd_tree_field_applies(const KdTreeParams& params, std::string_view name);

/// Checks parameters against kd_tree_fields(); throws kdt::Error naming the bad one
/// ("tree.q must be in (0, 1] (got 1.5)").
void validate(const KdTreeParams& params);

}  // namespace kdt
