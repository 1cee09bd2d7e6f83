// Internals shared by the files of the SAH kd-tree builder (sah_builder.cpp drives,
// sah_binned.cpp splits the top levels by binned SAH, sah_sweep.cpp sweeps the subtrees):
// references, the build context, the split-area ratios and the hand-over between phases.
// Not for use outside renderer/accel/sah_*.cpp. Depends on core, geometry and the builder.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "renderer/accel/sah_builder.h"

namespace kdt::sah_detail {

/// A triangle reference: its conservative box inside the current node, and the triangle.
struct Ref {
    Ref() {}  // left uninitialised: reference buffers are resized before being written
    Ref(const Bounds3f& b, uint32_t t) : box(b), tri(t) {}
    union {  // no default member initialisers run on resize
        Bounds3f box;
    };
    uint32_t tri;
};

constexpr uint32_t kMaxRefs = 1u << 30;  // local indices and leaf counts have 30 bits

// ---------------------------------------------------------------------------------------
// The reference budget. The SAH keeps splitting a node whose triangles all overlap (a soup
// of large triangles in one plane, say) because each split lowers the expected cost a
// little, yet nearly every reference lands in both children: left alone, such a node's
// references double at every level down to the maximum depth (a 290 KB PLY of 10,000 such
// triangles took three minutes and then ran out of 8 GB). So each node has a budget of
// leaf references for its whole subtree: the root SahTuning::ref_budget_per_triangle per
// triangle; a split is made only if its children's references fit (N_L + N_R <= budget),
// and the two share the budget in proportion to N_L and N_R. The tree then never holds
// more than that many references per triangle, nor does any level of the build. The rule
// looks only at a node's own counts and the path above it, so the tree stays the same for
// any thread count. A split always fits while budget >= 2 N; with the default budget the
// dragon and its coarser versions get exactly the trees they got without one.

/// True when a split with n_left and n_right references fits `budget`.
inline bool fits_budget(size_t n_left, size_t n_right, double budget) {
    return double(n_left) + double(n_right) <= budget;
}

/// The share of `budget` of a child with n_child references, of a split with n_left and
/// n_right.
inline double child_budget(double budget, size_t n_child, size_t n_left, size_t n_right) {
    const double sum = double(n_left) + double(n_right);
    return sum > 0.0 ? budget * (double(n_child) / sum) : budget;
}

enum Side : uint8_t { kBoth = 0, kLeft = 1, kRight = 2 };

/// Which side of the plane `split` on `axis` a reference goes to; planar references lying
/// in the plane go to `planar_side`. Compares against exactly the float stored in the node.
inline Side classify(const Bounds3f& box, int axis, float split, Side planar_side) {
    const float lo = box.lower[axis], hi = box.upper[axis];
    if (hi <= split && lo < split) return kLeft;
    if (lo >= split && hi > split) return kRight;
    if (lo == split && hi == split) return planar_side;
    return kBoth;
}

// ---------------------------------------------------------------------------------------
// Build context shared by all tasks.

struct Context {
    const TriangleMesh* mesh = nullptr;
    KdTreeParams params;
    SahTuning tuning;
    const std::atomic<bool>* cancel = nullptr;  // build_kdtree()'s
    int max_depth = 0;
    std::vector<float> f_table;   // thesis_f(n) for small n
    size_t workspace_budget = 0;  // bytes a thread's workspace keeps between subtrees
    ScratchMeter meter;

    float f(size_t n) const {
        return n < f_table.size() ? f_table[n] : thesis_f(float(n), params.q, params.n0);
    }
    float leaf_cost(size_t n) const { return params.intersect_cost * f(n); }
    /// SAH cost of a split (Wald & Havran 2006, eq. 2 with the empty-space bonus lambda),
    /// with the thesis's f(n) in place of n.
    float split_cost(float p_left, float p_right, size_t n_left, size_t n_right) const {
        float c = params.intersect_cost * (p_left * f(n_left) + p_right * f(n_right));
        if (n_left == 0 || n_right == 0) c *= 1.0f - params.empty_bonus;
        return params.traversal_cost + c;
    }
    /// Clips reference r to `child`; false when nothing of the triangle is left in it.
    bool clip(const Ref& r, const Bounds3f& child, Ref& out) const {
        const Vec3u& t = mesh->triangles[r.tri];
        Bounds3f b;
        if (!clip_triangle_to_box(mesh->positions[t.x], mesh->positions[t.y], mesh->positions[t.z],
                                  child, b)) {
            return false;
        }
        // Both boxes are conservative, so is their intersection.
        b.lower = glm::max(b.lower, r.box.lower);
        b.upper = glm::min(b.upper, r.box.upper);
        if (b.empty()) return false;
        out.box = b;
        out.tri = r.tri;
        return true;
    }
};

/// A finished subtree in local depth-first order: node 0 is its root, child indices and
/// leaf offsets are local.
struct Subtree {
    explicit Subtree(ScratchMeter* m)
        : nodes(MeteredAllocator<KdNode>(m)), indices(MeteredAllocator<uint32_t>(m)) {}
    MeteredVector<KdNode> nodes;
    MeteredVector<uint32_t> indices;
    uint64_t splits = 0;
};

/// The binned top of the tree: inner nodes, each ending in a swept subtree.
struct TopNode {
    explicit TopNode(ScratchMeter* m) : sub(m) {}
    int axis = -1;  // -1: `sub` holds the subtree
    float split = 0.0f;
    std::unique_ptr<TopNode> child[2];
    Subtree sub;
};

/// A node of the binned phase. References never clipped so far are stored as bare triangle
/// indices (their bounds lie inside the node and are read from the mesh), which keeps the
/// top levels' scratch at about 4 bytes per triangle; clipped ones carry their box.
struct TopJob {
    TopJob(Context& c, TopNode& t, const Bounds3f& b, int d)
        : ctx(c),
          node(t),
          whole(MeteredAllocator<uint32_t>(&c.meter)),
          clipped(MeteredAllocator<Ref>(&c.meter)),
          counts(MeteredAllocator<uint32_t>(&c.meter)),
          box(b),
          depth(d) {}
    size_t size() const { return whole.size() + clipped.size(); }
    Context& ctx;
    TopNode& node;
    MeteredVector<uint32_t> whole;
    MeteredVector<Ref> clipped;
    /// Bin counts of the references over `box` (Binner::add layout), when the parent
    /// counted them while classifying; empty otherwise.
    MeteredVector<uint32_t> counts;
    Bounds3f box;
    int depth;
    double budget = 0.0;  ///< leaf references this subtree may hold (see fits_budget())
};

// Surface areas of the two sides of a split plane relative to the box's (the probabilities
// of the SAH), in double: products of float extents overflow float above extents of about
// 1e19 and underflow below about 1e-19, and an infinite or zero area left a whole model
// in one leaf.
class SplitAreas {
public:
    explicit SplitAreas(const Bounds3f& box) : lower_(box.lower), ext_(Vec3d(box.upper) - lower_) {
        const double area = 2.0 * (ext_.x * ext_.y + ext_.y * ext_.z + ext_.z * ext_.x);
        valid_ = area > 0.0 && std::isfinite(area);
        const double inv_area = valid_ ? 1.0 / area : 0.0;
        // Per split axis, what the sweep's inner loop needs, scaled by 2 / SA(box).
        for (int k = 0; k < 3; ++k) {
            const double d1 = ext_[(k + 1) % 3], d2 = ext_[(k + 2) % 3];
            cross_[k] = 2.0 * d1 * d2 * inv_area;
            sum_[k] = 2.0 * (d1 + d2) * inv_area;
        }
    }
    bool valid() const { return valid_; }
    /// SA(left) / SA(box) and SA(right) / SA(box) for the plane at p on axis k.
    void ratios(int k, float p, float& p_left, float& p_right) const {
        const double x = double(p) - lower_[k];
        p_left = float(cross_[k] + x * sum_[k]);
        p_right = float(cross_[k] + (ext_[k] - x) * sum_[k]);
    }

private:
    Vec3d lower_, ext_;
    double cross_[3] = {}, sum_[3] = {};
    bool valid_ = false;
};

// ---------------------------------------------------------------------------------------
// The hand-over from the binned phase to the exact sweep (sah_sweep.cpp).

// Scratch bytes a thread's workspace may keep between two subtrees: 4 MB, or 8 bytes per
// triangle for small meshes. A sweep of 2048 references fills about 1-3 MB of slots; below
// that every other subtree re-allocated them all. The build's peak is at assembly, after the
// workspaces are gone.
constexpr size_t kWorkspaceBudget = size_t(4) << 20;
constexpr size_t kWorkspaceBytesPerTriangle = 8;

/// Per-thread buffers of the sweep, reused by every subtree the thread sweeps.
struct Workspace;
struct WorkspaceDeleter {
    void operator()(Workspace* ws) const;
};
using WorkspacePtr = std::unique_ptr<Workspace, WorkspaceDeleter>;
WorkspacePtr make_workspace(ScratchMeter* meter);

/// Sweeps the subtree over `refs` (taken over: the vector is left empty) into `out`, drops
/// the growth slack of `out`, and trims `ws` when it holds more than ctx.workspace_budget.
void sweep_subtree(const Context& ctx, Workspace& ws, MeteredVector<Ref>& refs, const Bounds3f& box,
                   int depth, double budget, Subtree& out);

/// Splits `root` by binned SAH down to sweep_threshold references, then sweeps every
/// subtree on its own OpenMP task, on `threads` threads; the result hangs off root->node.
void build_top(Context& ctx, std::unique_ptr<TopJob> root, int threads);

}  // namespace kdt::sah_detail
