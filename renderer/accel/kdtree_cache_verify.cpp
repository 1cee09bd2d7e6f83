// check_kdtree_complete(), declared in kdtree_cache.h: the proof a tree cache file gives
// before it is trusted (a checksum proves only that the bytes were not damaged).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "renderer/accel/kdtree_cache.h"
#include "renderer/core/error.h"

namespace kdt {
namespace {

// A convex polygon: a triangle clipped by axis-aligned planes. Each plane adds at most one
// vertex, and only the planes of the node's box can cut (three pairs), so 3 + 6 suffice.
struct Polygon {
    static constexpr int kMax = 10;
    Vec3d v[kMax];
    int n = 0;
};

// The part of `in` with x[axis] <= s (keep_below) or >= s, computed in double.
Polygon clip(const Polygon& in, int axis, double s, bool keep_below) {
    Polygon out;
    for (int i = 0; i < in.n; ++i) {
        const Vec3d& a = in.v[i];
        const Vec3d& b = in.v[(i + 1) % in.n];
        const double da = keep_below ? s - a[axis] : a[axis] - s;
        const double db = keep_below ? s - b[axis] : b[axis] - s;
        if (da >= 0.0 && out.n < Polygon::kMax) out.v[out.n++] = a;
        if ((da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0)) {
            Vec3d p = a + (b - a) * (da / (da - db));
            p[axis] = s;  // exactly on the plane, whatever the rounding
            if (out.n < Polygon::kMax) out.v[out.n++] = p;
        }
    }
    return out;
}

struct Work {
    uint32_t node;
    Polygon poly;
};
constexpr uint32_t kNoNode = 0xffffffffu;

}  // namespace

void check_kdtree_complete(const KdTree& tree, const std::string& name) {
    const std::vector<KdNode>& nodes = tree.nodes();
    const std::vector<uint32_t>& indices = tree.indices();
    const TriangleMesh& mesh = tree.mesh();
    const Bounds3f& bounds = tree.bounds();
    auto fail = [&](int64_t node, const std::string& message) {
        throw Error(ErrorLocation{name, "node", node},
                    message + "; the tree is incomplete for its mesh");
    };
    if (nodes.empty()) fail(-1, "no nodes");

    // 1. Splits inside their node's closed box (boxes from the root's down, depth-first).
    if (!bounds.empty()) {
        struct Box {
            uint32_t node;
            Bounds3f box;
        };
        std::vector<Box> stack{{0, bounds}};
        while (!stack.empty()) {
            const Box b = stack.back();
            stack.pop_back();
            const KdNode& n = nodes[b.node];
            if (n.is_leaf()) continue;
            const int a = n.axis();
            if (!(n.split >= b.box.lower[a] && n.split <= b.box.upper[a])) {
                fail(b.node, "split " + std::to_string(n.split) + " on axis " + "xyz"[a] +
                                 " outside the node's box [" + std::to_string(b.box.lower[a]) +
                                 ", " + std::to_string(b.box.upper[a]) + "]");
            }
            Box lo = {n.child(), b.box}, hi = {n.child() + 1, b.box};
            lo.box.upper[a] = n.split;
            hi.box.lower[a] = n.split;
            stack.push_back(hi);
            stack.push_back(lo);
        }
    }

    // 2. Each leaf's references, sorted, for membership tests (the tree's order is kept).
    std::vector<uint32_t> sorted = indices;
    for (const KdNode& n : nodes) {
        if (n.is_leaf() && n.count() > 1)
            std::sort(sorted.begin() + n.first, sorted.begin() + n.first + n.count());
    }

    // 3. Every hittable triangle descends, as its clipped polygon, into each child it
    // reaches beyond the tolerance, and must be in every leaf it arrives at. Rounding in a
    // builder's (float) clipping is far below the tolerance, which scales with the scene.
    double magnitude = 0.0;
    for (int a = 0; a < 3 && !bounds.empty(); ++a)
        magnitude = std::max(
            {magnitude, std::fabs(double(bounds.lower[a])), std::fabs(double(bounds.upper[a]))});
    const double tol = std::ldexp(magnitude, -20);
    const int64_t count = int64_t(mesh.triangle_count());
    // The lowest failing triangle and its leaf, packed (triangle << 32 | node) so that one
    // atomic minimum keeps the pair whatever the threads (triangle indices fit 32 bits, as
    // in the tree's index array).
    constexpr uint64_t kNoBad = std::numeric_limits<uint64_t>::max();
    std::atomic<uint64_t> first_bad{kNoBad};
#pragma omp parallel
    {
        std::vector<Work> stack;
#pragma omp for schedule(dynamic, 4096)
        for (int64_t t = 0; t < count; ++t) {
            if (uint64_t(t) > first_bad.load(std::memory_order_relaxed) >> 32) continue;
            if (!mesh.triangle_hittable(size_t(t))) continue;
            const Vec3u& tri = mesh.triangles[size_t(t)];
            Work w{0, {}};
            w.poly.n = 3;
            for (int k = 0; k < 3; ++k) w.poly.v[k] = Vec3d(mesh.positions[tri[k]]);
            stack.assign(1, w);
            while (!stack.empty()) {
                Work cur = stack.back();
                stack.pop_back();
                // Down through the nodes the polygon lies on one side of (most of them),
                // without copying it; it is split only where it straddles a plane.
                for (;;) {
                    const KdNode& n = nodes[cur.node];
                    if (n.is_leaf()) break;
                    const int a = n.axis();
                    const double s = double(n.split);
                    double lo = cur.poly.v[0][a], hi = lo;
                    for (int k = 1; k < cur.poly.n; ++k) {
                        lo = std::min(lo, cur.poly.v[k][a]);
                        hi = std::max(hi, cur.poly.v[k][a]);
                    }
                    const bool below = lo<s - tol, above = hi> s + tol;
                    if (below && above) {
                        stack.push_back({n.child() + 1, clip(cur.poly, a, s, false)});
                        cur.poly = clip(cur.poly, a, s, true);
                        cur.node = n.child();
                    } else if (below) {
                        // A sliver beyond the plane (thinner than the tolerance) is cut off:
                        // it may reach far along the other axes, outside this child's box.
                        if (hi > s) cur.poly = clip(cur.poly, a, s, true);
                        cur.node = n.child();
                    } else if (above) {
                        if (lo < s) cur.poly = clip(cur.poly, a, s, false);
                        cur.node = n.child() + 1;
                    } else {
                        cur.node = kNoNode;  // within the tolerance of the plane: either side
                        break;
                    }
                }
                if (cur.node == kNoNode) continue;
                const KdNode& leaf = nodes[cur.node];
                const uint32_t* begin = sorted.data() + leaf.first;
                if (!std::binary_search(begin, begin + leaf.count(), uint32_t(t))) {
                    // The lowest failing triangle is reported, whatever the threads.
                    const uint64_t bad = uint64_t(t) << 32 | cur.node;
                    uint64_t seen = first_bad.load();
                    while (bad < seen && !first_bad.compare_exchange_weak(seen, bad)) {
                    }
                    break;
                }
            }
        }
    }
    if (const uint64_t bad = first_bad.load(); bad != kNoBad) {
        fail(int64_t(bad & 0xffffffffu), "triangle " + std::to_string(bad >> 32) +
                                             " reaches into this leaf but is not referenced by it");
    }
}

}  // namespace kdt
