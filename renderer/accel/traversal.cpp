// Closest-hit and any-hit queries: iterative, stack-based, front-to-back kd-tree traversal
// with the ray interval clipped at each split (Havran's TA_rec_B family; the thesis's
// section 5.3.1 in iterative form), and the watertight triangle test in the leaves.
//
// Robustness: planes are crossed at t = (split - o) / d, computed in float. Decisions that
// skip a child compare against the current interval widened by kIntervalSlack, so a child
// the ray really touches is never skipped; together with the builder's closed
// classification (triangles touching a plane are on both sides) no hit can slip between
// leaves. A hit beyond the current leaf does not end the search (the thesis's figure 3):
// the search ends when every remaining node starts beyond the closest hit.
//
// Speed: the hot state of a ray (node, interval, stack pointer) lives in locals so it stays
// in registers, and the stack push and interval update of the descent are branch-free. The
// batch queries trace coherent groups of rays as SIMD packets (traversal_packet.cpp).
#include <algorithm>
#include <cmath>

#include <immintrin.h>

#include "renderer/accel/kdtree.h"
#include "renderer/accel/traversal_detail.h"
#include "renderer/geometry/intersect.h"

namespace kdt {
namespace {

using detail::BestHit;
using detail::descend;
using detail::kStackSize;
using detail::lower_slack;
using detail::PathRecord;
using detail::pop;
using detail::RayState;
using detail::setup_ray;
using detail::StackItem;
using detail::test_leaf;
using detail::TreeView;
using detail::upper_slack;
using detail::view_of;

// What walk_path() found.
enum class Walk { invalid, reached, missed };

// The rest of a path the ray leaves at start[i]: missed if it is a path of the tree,
// invalid otherwise (a path is taken whole or not at all).
inline Walk check_rest(const KdNode* nodes, const uint32_t* start, uint32_t i, uint32_t length) {
    for (; i + 1 < length; ++i) {
        const KdNode node = nodes[start[i]];
        if (node.is_leaf() || start[i + 1] - node.child() > 1u) return Walk::invalid;
    }
    return Walk::missed;
}

// Walks down a caller's path start[0, length) instead of descending: at each level the
// descent's own decision (same slack, same interval updates) says whether the ray meets
// the path's child and the other one; the other is pushed when the ray meets it, and the
// walk goes on into the path's child whatever its side. So the stack and the path's node
// together cover every node the ray meets, and the query's result is the descent's (the
// search accepts any hit in [tmin, best] and ends on interval starts, not on order). The
// nodes of the path are read as independent loads: no step waits for the one before (on
// one-bounce diffuse rays from the dragon's primary hits, 6% faster than descending).
// reached: idx and [t0, t1] are the path's last node and the ray's interval in it; missed:
// the ray does not meet that node (the stack holds the rest); invalid: not a path of this
// tree, nothing usable pushed.
template <bool kCount, bool kPath>
inline Walk walk_path(const KdNode* nodes, const uint32_t* start, uint32_t length,
                      const RayState& rs, float& t0, float& t1, StackItem*& top, uint32_t& idx,
                      uint64_t& visited, PathRecord* rec) {
    if (length == 0 || length > KdPath::kMaxLength || start[0] != 0) return Walk::invalid;
    const uint32_t neg_bits = rs.neg_bits;
    for (uint32_t i = 0; i + 1 < length; ++i) {
        const KdNode node = nodes[start[i]];
        const uint32_t next = start[i + 1];
        const uint32_t first = node.child();
        // A child index is in range once its parent is (the tree checked every inner node).
        if (node.is_leaf() || next - first > 1u) return Walk::invalid;
        if (kCount) ++visited;
        if (kPath) rec->nodes[i] = start[i];
        const int axis = node.axis();
        const float ts = (node.split - rs.org[axis]) * rs.inv[axis];
        const uint32_t neg = (neg_bits >> axis) & 1u;
        const uint32_t empty = node.empty_children();
        const bool visit_near = !(ts < lower_slack(t0));
        const bool visit_far = !(ts > upper_slack(t1));
        // min / max as the descent's minss / maxss: on NaN (a ray in the plane) t0 and t1
        // stay.
        const float lo = ts > t0 ? ts : t0, hi = ts < t1 ? ts : t1;
        // Which side the path takes is as likely one as the other for diffuse rays, so the
        // step selects instead of branching on it: the far child is the other when the
        // path goes near, the near child when it goes far.
        const uint32_t side = next - first;
        const bool path_near = side == neg;
        const bool visit_path = path_near ? visit_near : visit_far;
        const bool visit_other = path_near ? visit_far : visit_near;
        top->node = first + 1u - side;
        top->t0 = path_near ? lo : t0;
        top->t1 = path_near ? t1 : hi;
        top->pad = i + 1;
        top += int(visit_other & !((empty >> (1u - side)) & 1u));
        if (!visit_path) [[unlikely]]
            return check_rest(nodes, start, i + 1, length);
        t0 = path_near ? t0 : lo;
        t1 = path_near ? hi : t1;
    }
    idx = start[length - 1];
    if (kPath) {
        rec->depth = length - 1;
        rec->nodes[length - 1] = idx;
    }
    return Walk::reached;
}

inline void write_hit(const BestHit& best, float t_scale, Hit& hit) {
    hit.t = best.t * t_scale;
    hit.u = best.u;
    hit.v = best.v;
    hit.prim = best.prim;
}

// One ray to the end. Returns true on an any-hit (kAnyHit) or when a closest hit exists.
// kFrom: begin by walking the caller's path start[0, length) (walk_path) instead of at the
// root. kPath: record the path of each node, and copy it to *leaf whenever the closest hit
// changes, so *leaf ends as the path of the leaf where the hit was found.
template <bool kAnyHit, bool kCount, bool kDirect, bool kPath, bool kFrom>
bool trace_one(const TreeView& tv, const Ray& ray, Hit* hit, TraversalCounters* counters,
               const uint32_t* start, uint32_t length, KdPath* leaf) {
    RayState rs;
    float t0, t1;
    BestHit best;
    if (!setup_ray(ray, tv.bounds, rs, t0, t1, best.t)) return false;
    StackItem stack[kStackSize];
    StackItem* top = stack;
    uint32_t idx = 0;
    uint64_t visited = 0, tested = 0;
    PathRecord rec;
    if (kPath) {
        rec.depth = 0;
        rec.nodes[0] = 0;
    }
    bool go = true;
    if (kFrom) {
        const float root_t0 = t0, root_t1 = t1;
        const Walk w =
            walk_path<kCount, kPath>(tv.nodes, start, length, rs, t0, t1, top, idx, visited, &rec);
        if (w == Walk::invalid) {  // from the root, as a query without a path
            top = stack;
            idx = 0;
            t0 = root_t0;
            t1 = root_t1;
            visited = 0;
            if (kPath) rec.depth = 0;
        } else if (w == Walk::missed) {
            go = pop<kPath>(stack, top, best.t, idx, t0, t1, &rec);
        }
    }
    bool any = false;
    while (go) {
        const KdNode node = descend<kCount, kPath>(tv.nodes, idx, rs, t0, t1, top, visited, &rec);
        const BestHit before = best;
        if (test_leaf<kAnyHit, kDirect>(node, tv, rs, best, tested)) {
            any = true;
            break;
        }
        if constexpr (kPath) {
            if (best.prim != before.prim || best.t != before.t) {
                leaf->length = rec.depth + 1;
                std::copy(rec.nodes, rec.nodes + rec.depth + 1, leaf->nodes);
            }
        }
        go = pop<kPath>(stack, top, best.t, idx, t0, t1, &rec);
    }
    if (kCount) {
        counters->nodes_visited += visited;
        counters->triangles_tested += tested;
    }
    if (kAnyHit) return any;
    if (best.prim == Hit::kNoHit) return false;
    write_hit(best, rs.t_scale, *hit);
    return true;
}

template <bool kAnyHit, bool kPath = false, bool kFrom = false>
bool trace(const TreeView& tv, const Ray& ray, Hit* hit, TraversalCounters* counters,
           const uint32_t* start = nullptr, uint32_t length = 0, KdPath* leaf = nullptr) {
    if (tv.reference_triangles)
        return counters ? trace_one<kAnyHit, true, true, kPath, kFrom>(tv, ray, hit, counters,
                                                                       start, length, leaf)
                        : trace_one<kAnyHit, false, true, kPath, kFrom>(tv, ray, hit, nullptr,
                                                                        start, length, leaf);
    return counters ? trace_one<kAnyHit, true, false, kPath, kFrom>(tv, ray, hit, counters, start,
                                                                    length, leaf)
                    : trace_one<kAnyHit, false, false, kPath, kFrom>(tv, ray, hit, nullptr, start,
                                                                     length, leaf);
}

}  // namespace

bool KdTree::intersect(const Ray& ray, Hit& hit, TraversalCounters* counters) const {
    hit = Hit{};
    if (!mesh_) return false;
    const TreeView tv = view_of(*this);
    return trace<false>(tv, ray, &hit, counters);
}

bool KdTree::occluded(const Ray& ray, TraversalCounters* counters) const {
    if (!mesh_) return false;
    const TreeView tv = view_of(*this);
    return trace<true>(tv, ray, nullptr, counters);
}

bool KdTree::intersect(const Ray& ray, Hit& hit, KdPath& leaf, TraversalCounters* counters) const {
    hit = Hit{};
    leaf.length = 0;
    if (!mesh_) return false;
    const TreeView tv = view_of(*this);
    return trace<false, true>(tv, ray, &hit, counters, nullptr, 0, &leaf);
}

bool KdTree::intersect_from(const uint32_t* start, uint32_t length, const Ray& ray, Hit& hit,
                            KdPath* leaf, TraversalCounters* counters) const {
    hit = Hit{};
    if (leaf) leaf->length = 0;
    if (!mesh_) return false;
    const TreeView tv = view_of(*this);
    if (!start) length = 0;  // invalid: traced from the root
    if (leaf) return trace<false, true, true>(tv, ray, &hit, counters, start, length, leaf);
    return trace<false, false, true>(tv, ray, &hit, counters, start, length, nullptr);
}

bool KdTree::occluded_from(const uint32_t* start, uint32_t length, const Ray& ray,
                           TraversalCounters* counters) const {
    if (!mesh_) return false;
    const TreeView tv = view_of(*this);
    if (!start) length = 0;
    return trace<true, false, true>(tv, ray, nullptr, counters, start, length, nullptr);
}

void KdTree::intersect(const Ray* rays, size_t count, Hit* hits,
                       TraversalCounters* counters) const {
    for (size_t i = 0; i < count; ++i) hits[i] = Hit{};
    if (!mesh_) return;
    const TreeView tv = view_of(*this);
    for (size_t i = 0; i < count; i += detail::kPacketSize) {
        const int m = int(std::min<size_t>(detail::kPacketSize, count - i));
        if (detail::trace_packet(tv, rays + i, m, false, hits + i, nullptr, counters)) continue;
        for (int j = 0; j < m; ++j) trace<false>(tv, rays[i + j], &hits[i + j], counters);
    }
}

void KdTree::occluded(const Ray* rays, size_t count, uint8_t* occluded,
                      TraversalCounters* counters) const {
    for (size_t i = 0; i < count; ++i) occluded[i] = 0;
    if (!mesh_) return;
    const TreeView tv = view_of(*this);
    for (size_t i = 0; i < count; i += detail::kPacketSize) {
        const int m = int(std::min<size_t>(detail::kPacketSize, count - i));
        if (detail::trace_packet(tv, rays + i, m, true, nullptr, occluded + i, counters)) continue;
        for (int j = 0; j < m; ++j)
            occluded[i + j] = trace<true>(tv, rays[i + j], nullptr, counters) ? 1 : 0;
    }
}

}  // namespace kdt
