// `kdtrace bench kdtree`: where the best tree's traversal time goes. Work per ray from the
// compiled-in counters, and the ray anatomy: the single-ray query replayed with finer counts
// (first descent, first leaf, leaves entered, empty children skipped).
#include <algorithm>
#include <string>
#include <vector>

#include "app/bench/bench_kdtree.h"
#include "renderer/accel/traversal_detail.h"
#include "renderer/core/error.h"

namespace kdt::app::kdtree_bench {
namespace {

// Where a ray's traversal work goes: the single-ray query's steps (traversal.cpp's descend,
// leaf test and pop, same decisions and slack), replayed with finer counts. The totals are
// checked against the query's own counters, so the split describes the real traversal.
struct RayAnatomy {
    uint64_t first_descent = 0;  ///< inner nodes visited before the first leaf
    uint64_t first_leaf_tests = 0;
    uint64_t leaves = 0;            ///< leaves entered
    uint64_t empty_skipped = 0;     ///< empty children the descent decided not to enter
    uint64_t nodes = 0, tests = 0;  ///< totals, as TraversalCounters count them
};

void add_anatomy(const KdTree& tree, const Ray& ray, RayAnatomy& a) {
    using detail::lower_slack;
    using detail::upper_slack;
    detail::RayState rs;
    float t0, t1, best_t;
    if (!detail::setup_ray(ray, tree.bounds(), rs, t0, t1, best_t)) return;
    const TriangleMesh& mesh = tree.mesh();
    const std::vector<KdNode>& nodes = tree.nodes();
    struct Item {
        uint32_t node;
        float t0, t1;
    };
    Item stack[detail::kStackSize];
    int sp = 0;
    uint32_t idx = 0;
    bool first = true;
    for (;;) {
        KdNode node = nodes[idx];
        ++a.nodes;
        bool skipped = false;
        while (!node.is_leaf()) {
            if (first) ++a.first_descent;
            const int axis = node.axis();
            const float ts = (node.split - rs.org[axis]) * rs.inv[axis];
            const uint32_t near_child = node.child() + rs.neg(axis);
            const uint32_t far_child = node.child() + 1u - rs.neg(axis);
            const bool visit_near = !(ts < lower_slack(t0));
            const bool visit_far = !(ts > upper_slack(t1));
            // The flags in the node's word, as the descent reads them.
            const bool near_empty = (node.empty_children() >> rs.neg(axis)) & 1u;
            const bool far_empty = (node.empty_children() >> (1u - rs.neg(axis))) & 1u;
            a.empty_skipped +=
                uint64_t(visit_near && near_empty) + uint64_t(visit_far && far_empty);
            const bool go_near = visit_near && !near_empty, go_far = visit_far && !far_empty;
            const float far_t0 = ts > t0 ? ts : t0;
            if (go_near && go_far) stack[sp++] = {far_child, far_t0, t1};
            if (go_near) {
                t1 = ts < t1 ? ts : t1;
                idx = near_child;
            } else if (go_far) {
                t0 = far_t0;
                idx = far_child;
            } else {
                node = KdNode{};  // no child to enter: straight to the stack
                skipped = true;
                break;
            }
            node = nodes[idx];
            ++a.nodes;
        }
        if (!skipped) ++a.leaves;
        for (uint32_t i = 0; i < node.count(); ++i) {
            const Vec3u t = mesh.triangles[tree.indices()[node.first + i]];
            float tt, u, v;
            if (intersect_triangle(rs.wr, mesh.positions[t.x], mesh.positions[t.y],
                                   mesh.positions[t.z], rs.tmin, best_t, tt, u, v))
                best_t = tt;
        }
        a.tests += node.count();
        if (first) a.first_leaf_tests += node.count();
        first = false;
        bool next = false;
        while (sp > 0 && !next) {
            const Item& s = stack[--sp];
            if (lower_slack(s.t0) <= best_t) {
                idx = s.node;
                t0 = s.t0;
                t1 = std::min(s.t1, best_t);
                next = true;
            }
        }
        if (!next) break;
    }
}

/// The counted work of one ray set; no anatomy for rays that start from a leaf path.
struct Counted {
    TraversalCounters c;
    RayAnatomy a;
    uint64_t hits = 0;
    size_t rays = 0;
    bool anatomy = false;
};

// From the hit's leaf, the walked path's nodes count as visited and there is no first
// descent to replay.
Counted count_rays(const KdTree& tree, const std::vector<Ray>& rays, const LeafPaths* from_leaf) {
    Counted w;
    w.rays = rays.size();
    w.anatomy = !from_leaf;
    for (const Ray& r : rays) {
        Hit h;
        if (from_leaf) {
            const auto [start, length] = from_leaf->start_of(r);
            w.hits += tree.intersect_from(start, length, r, h, nullptr, &w.c);
        } else {
            w.hits += tree.intersect(r, h, &w.c);
            add_anatomy(tree, r, w.a);
        }
    }
    if (w.anatomy && (w.a.nodes != w.c.nodes_visited || w.a.tests != w.c.triangles_tested))
        throw Error(ErrorLocation{"bench kdtree"},
                    "internal: the ray anatomy replay disagrees with the traversal "
                    "counters (" +
                        std::to_string(w.a.nodes) + " / " + std::to_string(w.a.tests) +
                        " against " + std::to_string(w.c.nodes_visited) + " / " +
                        std::to_string(w.c.triangles_tested) + ")");
    return w;
}

std::vector<std::string> work_row(const char* name, const Counted& w, double seconds, int threads) {
    // Means over no rays, and the time per node of rays that visited none, are "-".
    const double n = double(w.rays);
    const double ns = quotient(seconds * double(threads) * 1e9, n);
    const double nodes = quotient(double(w.c.nodes_visited), n);
    auto per_ray = [&](uint64_t v) {
        return w.anatomy ? fmt("%.1f", quotient(double(v), n)) : "-";
    };
    return {name,
            fmt("%.1f", nodes),
            fmt("%.1f", quotient(double(w.c.triangles_tested), n)),
            fmt("%.1f", quotient(100.0 * double(w.hits), n)),
            fmt("%.0f", ns),
            fmt("%.2f", quotient(ns, nodes)),
            per_ray(w.a.first_descent),
            per_ray(w.a.first_leaf_tests),
            per_ray(w.a.leaves),
            per_ray(w.a.empty_skipped)};
}

}  // namespace

Table work_table(const Context& ctx, const RowResult& best, const RaySets& rays,
                 const LeafPaths& paths, const std::vector<Engine>& engines) {
    const KdTree& tree = *best.tree;
    Table tc;
    tc.name = "cost";
    tc.title = "Work per ray of the best tree (row " + best.config.id +
               "), from the traversal counters (one extra untimed pass)";
    tc.header = {"rays",
                 "nodes visited / ray",
                 "triangles tested / ray",
                 "hit %",
                 "ns / ray (1 thread equiv.)",
                 "ns / node visited",
                 "inner nodes before the first leaf",
                 "tests in the first leaf",
                 "leaves / ray",
                 "empty leaves skipped / ray"};
    // One counted pass per ray set: the batch queries visit exactly the same nodes per ray,
    // counted per lane, so their rows share it.
    const Counted cp = count_rays(tree, rays.primary, nullptr);
    const Counted cd = count_rays(tree, rays.diffuse, nullptr);
    const int threads = ctx.threads;
    tc.rows.push_back(work_row("primary", cp, median(engines[0].primary_s), threads));
    tc.rows.push_back(work_row("diffuse", cd, median(engines[0].diffuse_s), threads));
    tc.rows.push_back(work_row("primary, batch", cp, median(engines[1].primary_s), threads));
    tc.rows.push_back(work_row("diffuse, batch", cd, median(engines[1].diffuse_s), threads));
    tc.rows.push_back(work_row("diffuse, from the hit's leaf",
                               count_rays(tree, rays.diffuse, &paths), median(engines[2].diffuse_s),
                               threads));
    return tc;
}

}  // namespace kdt::app::kdtree_bench
