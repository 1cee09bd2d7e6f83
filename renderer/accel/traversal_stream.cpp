// Stream queries (traversal_stream.h): K rays in flight per thread, software-pipelined.
//
// A diffuse ray's descent is a chain of dependent node loads (about 47 on the dragon) over a
// tree that does not fit in cache, so a single ray mostly waits. Here each of K lanes holds
// one ray's whole traversal state (interval, stack, closest hit); the lanes are visited
// round-robin, and each visit advances its ray until it needs memory that is not yet in
// hand: a leaf's triangle records, their vertices, the node popped from its stack. That
// access is prefetched and the visit moves on to the next lane, so the loads of K rays are
// in flight together.
//
// Exactness: every decision and every float operation is the single-ray traversal's
// (traversal.cpp: descend(), test_leaf(), pop()), in the same order per ray: the same
// slack, the same min/max on NaN, the same triangle test (the scalar watertight test, which
// the four-wide leaf test there matches bit for bit), the same search end (a hit beyond the
// current leaf does not end it; every remaining node must start beyond the closest hit).
// Only the interleaving of different rays differs, and rays share nothing.
#include "renderer/accel/traversal_stream.h"

#include <algorithm>
#include <cmath>

#include <immintrin.h>

#include "renderer/accel/traversal_detail.h"
#include "renderer/geometry/intersect.h"

namespace kdt {
namespace {

using detail::kStackSize;
using detail::lower_slack;
using detail::RayState;
using detail::StackItem;
using detail::TreeView;
using detail::upper_slack;

// What a lane does on its next visit.
enum class Phase : uint8_t {
    descend,       // nodes[idx] has been prefetched
    leaf_refs,     // the leaf's triangle records have been prefetched
    leaf_vertices  // the leaf's vertices have been prefetched
};

// One ray in flight: its constants, interval, stack and closest hit so far.
struct Lane {
    RayState rs;
    float t0, t1;  // the ray's interval in node idx (internal units)
    float best_t, best_u, best_v;
    uint32_t best_prim;
    uint32_t idx;    // current node
    uint32_t depth;  // stack entries in use
    uint32_t ray;    // index of the ray in the caller's array
    Phase phase;
    KdNode leaf;  // the leaf being tested (phases leaf_*)
    StackItem stack[kStackSize];
};

inline void prefetch(const void* p) { _mm_prefetch(static_cast<const char*>(p), _MM_HINT_T0); }

// Prefetches [p, p + bytes): its first and last cache lines (records of a leaf span at most
// a few lines; the middle ones of longer leaves arrive by the hardware's adjacent-line
// prefetch or are waited for).
inline void prefetch_range(const void* p, size_t bytes) {
    const char* c = static_cast<const char*>(p);
    prefetch(c);
    prefetch(c + bytes - 1);
}

// pop() of traversal.cpp: the next stacked node front to back, skipping those that start
// beyond the closest hit. False when none is left.
inline bool pop(Lane& l) {
    while (l.depth > 0) {
        const StackItem& s = l.stack[--l.depth];
        if (lower_slack(s.t0) <= l.best_t) {
            l.idx = s.node;
            l.t0 = s.t0;
            l.t1 = std::min(s.t1, l.best_t);
            return true;
        }
    }
    return false;
}

// Starts ray i in lane l; false when the ray misses the tree's box (or is not finite), and
// then the lane is unchanged apart from its constants.
inline bool start(const TreeView& tv, const Ray& ray, uint32_t i, Lane& l) {
    float tmax;
    l.rs.t_scale = 1.0f;  // setup_ray() sets it only for rays it rescales
    if (!detail::setup_ray(ray, tv.bounds, l.rs, l.t0, l.t1, tmax)) return false;
    l.best_t = tmax;
    l.best_u = l.best_v = 0.0f;
    l.best_prim = Hit::kNoHit;
    l.idx = 0;
    l.depth = 0;
    l.ray = i;
    l.phase = Phase::descend;
    return true;
}

// Descends from nodes[l.idx] as descend() of traversal.cpp does, in registers, to a leaf
// with triangles (phase leaf_refs, its records prefetched) or, when the ray leaves the
// subtree without reaching one, to the next stacked node (prefetched). Returns false when
// the ray is done (nothing left on its stack). Ending a visit at every node whose cache
// line differs from the last one's, or at every node, was slower (docs/performance.md).
inline bool descend(const TreeView& tv, Lane& l) {
    const KdNode* nodes = tv.nodes;
    const RayState& rs = l.rs;
    uint32_t idx = l.idx;
    float t0 = l.t0, t1 = l.t1;
    for (;;) {
        const KdNode node = nodes[idx];
        if (node.is_leaf()) {
            l.idx = idx;
            l.t0 = t0;
            l.t1 = t1;
            if (node.count() == 0) {  // only a root can be an empty leaf the ray enters
                if (!pop(l)) return false;
                prefetch(nodes + l.idx);
                return true;
            }
            l.leaf = node;
            l.phase = Phase::leaf_refs;
            if (tv.reference_triangles)
                prefetch_range(tv.reference_triangles + node.first, node.count() * sizeof(Vec3u));
            else
                prefetch_range(tv.indices + node.first, node.count() * sizeof(uint32_t));
            return true;
        }
        const int axis = node.axis();
        // As descend(): (split - o) * (1 / d), then the slack-widened comparisons; a NaN
        // (ray in the plane) visits both sides.
        const __m128 ts_v = _mm_mul_ss(_mm_sub_ss(_mm_set_ss(node.split), _mm_set_ss(rs.org[axis])),
                                       _mm_set_ss(rs.inv[axis]));
        const __m128 t0_v = _mm_set_ss(t0), t1_v = _mm_set_ss(t1);
        const float ts = _mm_cvtss_f32(ts_v);
        const uint32_t first = node.child();
        const uint32_t neg = rs.neg(axis);
        const uint32_t empty = node.empty_children();
        const uint32_t near_idx = first + neg;
        const uint32_t far_idx = first + 1u - neg;
        const bool go_near = !(ts < lower_slack(t0)) & !((empty >> neg) & 1u);
        const bool go_far = !(ts > upper_slack(t1)) & !((empty >> (1u - neg)) & 1u);
        const float far_t0 = _mm_cvtss_f32(_mm_max_ss(ts_v, t0_v));
        StackItem& top = l.stack[l.depth];
        top.node = far_idx;
        top.t0 = far_t0;
        top.t1 = t1;
        l.depth += uint32_t(go_near & go_far);
        // A branch, as in descend(): its prediction lets the next node's load start before
        // ts is known (selecting without a branch was slower there and here).
        if (go_near) {
            t1 = _mm_cvtss_f32(_mm_min_ss(ts_v, t1_v));
            idx = near_idx;
        } else if (go_far) {
            t0 = far_t0;
            idx = far_idx;
        } else {
            if (!pop(l)) return false;
            prefetch(nodes + l.idx);
            return true;
        }
    }
}

// The vertex indices of the leaf's reference k.
template <bool kDirect>
inline const Vec3u& reference(const TreeView& tv, const KdNode leaf, uint32_t k) {
    return kDirect ? tv.reference_triangles[leaf.first + k]
                   : tv.triangles[tv.indices[leaf.first + k]];
}

// test_leaf() of traversal.cpp on the lane's leaf, triangle by triangle; true when kAnyHit
// and one is hit.
template <bool kAnyHit, bool kDirect>
inline bool test_leaf(const TreeView& tv, Lane& l) {
    const KdNode leaf = l.leaf;
    const uint32_t count = leaf.count();
    const Vec3f* p = tv.positions;
    for (uint32_t k = 0; k < count; ++k) {
        const Vec3u tri = reference<kDirect>(tv, leaf, k);
        float t, u, v;
        if (intersect_triangle(l.rs.wr, p[tri.x], p[tri.y], p[tri.z], l.rs.tmin, l.best_t, t, u,
                               v)) {
            if (kAnyHit) return true;
            l.best_t = t;
            l.best_u = u;
            l.best_v = v;
            l.best_prim = tv.indices[leaf.first + k];
        }
    }
    return false;
}

// One visit of a lane; false when its ray is done (for kAnyHit: done with a hit when
// l.best_prim was set to 0, without one otherwise).
template <bool kAnyHit, bool kDirect>
inline bool advance(const TreeView& tv, Lane& l) {
    switch (l.phase) {
        case Phase::descend:
            return descend(tv, l);
        case Phase::leaf_refs: {
            const KdNode leaf = l.leaf;
            for (uint32_t k = 0; k < leaf.count(); ++k) {
                const Vec3u& tri = reference<kDirect>(tv, leaf, k);
                prefetch(tv.positions + tri.x);
                prefetch(tv.positions + tri.y);
                prefetch(tv.positions + tri.z);
            }
            l.phase = Phase::leaf_vertices;
            return true;
        }
        case Phase::leaf_vertices:
            if (test_leaf<kAnyHit, kDirect>(tv, l)) {
                l.best_prim = 0;
                return false;
            }
            l.phase = Phase::descend;
            if (!pop(l)) return false;
            prefetch(tv.nodes + l.idx);
            return true;
    }
    return false;
}

// Traces rays[0, count) with K lanes: a lane whose ray is done takes the next ray; when no
// ray is left, the lane is dropped from the round.
template <bool kAnyHit, bool kDirect, int K>
void trace_stream(const TreeView& tv, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded) {
    Lane lanes[K];
    int order[K];  // the lanes in the round, in visiting order
    size_t next = 0;
    // Puts the next ray that meets the tree into lane l; false when none is left.
    auto refill = [&](Lane& l) {
        while (next < count) {
            const size_t i = next++;
            if (start(tv, rays[i], uint32_t(i), l)) return true;
        }
        return false;
    };
    int active = 0;
    for (int k = 0; k < K && refill(lanes[k]); ++k) order[active++] = k;
    while (active > 0) {
        for (int j = 0; j < active;) {
            Lane& l = lanes[order[j]];
            if (advance<kAnyHit, kDirect>(tv, l)) {
                ++j;
                continue;
            }
            if (kAnyHit) {
                occluded[l.ray] = l.best_prim != Hit::kNoHit ? 1 : 0;
            } else if (l.best_prim != Hit::kNoHit) {
                Hit& h = hits[l.ray];
                h.t = l.best_t * l.rs.t_scale;
                h.u = l.best_u;
                h.v = l.best_v;
                h.prim = l.best_prim;
            }
            if (refill(l)) {
                ++j;
                continue;
            }
            order[j] = order[--active];
        }
    }
}

template <bool kAnyHit, bool kDirect>
void dispatch_lanes(const TreeView& tv, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
                    int lanes) {
    if (lanes <= 2)
        trace_stream<kAnyHit, kDirect, 1>(tv, rays, count, hits, occluded);
    else if (lanes <= 6)
        trace_stream<kAnyHit, kDirect, 4>(tv, rays, count, hits, occluded);
    else if (lanes <= 10)
        trace_stream<kAnyHit, kDirect, 8>(tv, rays, count, hits, occluded);
    else if (lanes <= 14)
        trace_stream<kAnyHit, kDirect, 12>(tv, rays, count, hits, occluded);
    else
        trace_stream<kAnyHit, kDirect, 16>(tv, rays, count, hits, occluded);
}

template <bool kAnyHit>
void dispatch(const KdTree& tree, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
              int lanes) {
    const TreeView tv = detail::view_of(tree);
    if (tv.reference_triangles)
        dispatch_lanes<kAnyHit, true>(tv, rays, count, hits, occluded, lanes);
    else
        dispatch_lanes<kAnyHit, false>(tv, rays, count, hits, occluded, lanes);
}

}  // namespace

void intersect_stream(const KdTree& tree, const Ray* rays, size_t count, Hit* hits, int lanes) {
    for (size_t i = 0; i < count; ++i) hits[i] = Hit{};
    if (tree.nodes().empty() || tree.mesh_ptr() == nullptr) return;
    dispatch<false>(tree, rays, count, hits, nullptr, lanes);
}

void occluded_stream(const KdTree& tree, const Ray* rays, size_t count, uint8_t* occluded,
                     int lanes) {
    for (size_t i = 0; i < count; ++i) occluded[i] = 0;
    if (tree.nodes().empty() || tree.mesh_ptr() == nullptr) return;
    dispatch<true>(tree, rays, count, nullptr, occluded, lanes);
}

}  // namespace kdt
