// Stream queries (traversal_stream.h): K rays in flight per thread.
//
// A diffuse ray's descent is a chain of about 47 dependent node steps on the dragon, each
// waiting on its load and on a hard-to-predict branch. Each of K lanes here holds one ray's
// whole traversal state (interval, stack, closest hit). Two modes:
// - octets (AVX2 builds, K a multiple of 8): eight lanes take their descent steps together
//   in SIMD registers (eight independent node loads per step, no branch on the child
//   choice); lanes at a leaf drop out for the leaf test and pop, and rejoin at their next
//   node; K / 8 octets alternate so that prefetched nodes arrive.
// - round-robin (other K): each visit of a lane descends its ray to a leaf in registers,
//   prefetches the leaf's records, on the next visit their vertices, then tests it, so the
//   leaf loads of K rays overlap.
//
// Exactness: every decision and every float operation is the single-ray traversal's
// (traversal.cpp: descend(), test_leaf(), pop()), in the same order per ray: the same
// slack, the same min/max on NaN, the same leaf test (detail::test_leaf()), the same search
// end (a hit beyond the current leaf does not end it; every remaining node must start beyond
// the closest hit).
// Only the interleaving of different rays differs, and rays share nothing.
#include "renderer/accel/traversal_stream.h"

#include <algorithm>
#include <cmath>
#include <cstring>

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

// Traversal work of a whole stream, counted as the single-ray traversal counts it: every
// node whose word is read, every triangle tested (an any-hit query stops at its first hit).
struct StreamCounts {
    uint64_t nodes = 0, triangles = 0;
};

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
    KdNode leaf;  // the leaf being tested
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

// A leaf's triangle records: vertex indices beside the leaf's indices, or the indices.
inline void prefetch_records(const TreeView& tv, const KdNode leaf) {
    if (tv.reference_triangles)
        prefetch_range(tv.reference_triangles + leaf.first, leaf.count() * sizeof(Vec3u));
    else
        prefetch_range(tv.indices + leaf.first, leaf.count() * sizeof(uint32_t));
}

// The vertices of a leaf's triangles, once their records are in hand.
inline void prefetch_vertices(const TreeView& tv, const KdNode leaf) {
    for (uint32_t k = 0; k < leaf.count(); ++k) {
        const Vec3u& tri = tv.triangle_of(leaf.first + k);
        prefetch(tv.positions + tri.x);
        prefetch(tv.positions + tri.y);
        prefetch(tv.positions + tri.z);
    }
}

// The ray's result into the caller's arrays (hits were cleared to misses beforehand).
template <bool kAnyHit>
inline void write_result(const Lane& l, Hit* hits, uint8_t* occluded) {
    if (kAnyHit) {
        occluded[l.ray] = l.best_prim != Hit::kNoHit ? 1 : 0;
    } else if (l.best_prim != Hit::kNoHit) {
        Hit& h = hits[l.ray];
        h.t = l.best_t * l.rs.t_scale;
        h.u = l.best_u;
        h.v = l.best_v;
        h.prim = l.best_prim;
    }
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
inline bool descend(const TreeView& tv, Lane& l, StreamCounts& counts) {
    const KdNode* nodes = tv.nodes;
    const RayState& rs = l.rs;
    uint32_t idx = l.idx;
    float t0 = l.t0, t1 = l.t1;
    for (;;) {
        const KdNode node = nodes[idx];
        ++counts.nodes;
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
            prefetch_records(tv, node);
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

// detail::test_leaf() on the lane's leaf and closest hit.
template <bool kAnyHit, bool kDirect>
inline bool test_leaf(const TreeView& tv, Lane& l, StreamCounts& counts) {
    return detail::test_leaf<kAnyHit, kDirect>(l.leaf, tv, l.rs, l.best_t, l.best_u, l.best_v,
                                               l.best_prim, counts.triangles);
}

// One visit of a lane; false when its ray is done (for kAnyHit: done with a hit when
// l.best_prim was set to 0, without one otherwise).
template <bool kAnyHit, bool kDirect>
inline bool advance(const TreeView& tv, Lane& l, StreamCounts& counts) {
    switch (l.phase) {
        case Phase::descend:
            return descend(tv, l, counts);
        case Phase::leaf_refs: {
            prefetch_vertices(tv, l.leaf);
            l.phase = Phase::leaf_vertices;
            return true;
        }
        case Phase::leaf_vertices:
            if (test_leaf<kAnyHit, kDirect>(tv, l, counts)) {
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
void trace_stream(const TreeView& tv, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
                  StreamCounts& counts) {
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
            if (advance<kAnyHit, kDirect>(tv, l, counts)) {
                ++j;
                continue;
            }
            write_result<kAnyHit>(l, hits, occluded);
            if (refill(l)) {
                ++j;
                continue;
            }
            order[j] = order[--active];
        }
    }
}

#if KDT_SIMD_TRAVERSAL
// Eight lanes whose descent steps run side by side in AVX2 registers (one lane per
// element): each step loads the eight current nodes and decides every lane's next node
// with the same float operations, in the same order, as descend() does for one ray. Lanes
// at a leaf, or whose subtree is done, leave the vector step for the leaf test and
// pop, and rejoin it at their next node.
struct Octet {
    alignas(32) uint32_t idx[8];
    alignas(32) float t0[8];
    alignas(32) float t1[8];
    alignas(32) float org[3][8];
    alignas(32) float inv[3][8];
    alignas(32) uint32_t neg_bits[8];
    uint32_t vector_mask = 0;  // lanes in the vector step
    uint32_t live_mask = 0;    // lanes with a ray
    Lane lanes[8];

    // Copies lane j's node and interval into the vector step.
    void enter(int j) {
        const Lane& l = lanes[j];
        idx[j] = l.idx;
        t0[j] = l.t0;
        t1[j] = l.t1;
        vector_mask |= 1u << j;
    }
    void set_ray(int j) {
        const Lane& l = lanes[j];
        for (int k = 0; k < 3; ++k) {
            org[k][j] = l.rs.org[k];
            inv[k][j] = l.rs.inv[k];
        }
        neg_bits[j] = l.rs.neg_bits;
    }
};

// One descent step of the octet's vector lanes: the loads of the eight nodes, then per
// lane descend()'s operations (maxps / minps keep t0 / t1 on NaN as maxss / minss do; the
// slack products are exact, so no FMA contraction can differ). Lanes that reach a leaf
// leave the vector step with l.leaf set, their records prefetched; returns the mask of
// lanes that enter neither child (they pop).
inline uint32_t octet_step(const TreeView& tv, Octet& o, StreamCounts& counts) {
    counts.nodes += uint32_t(__builtin_popcount(o.vector_mask));
    const __m256i lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    const __m256i active = _mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32(int(o.vector_mask)), lane_bits), lane_bits);
    const __m256i vidx = _mm256_load_si256(reinterpret_cast<const __m256i*>(o.idx));
    // Eight 8-byte loads and two permutes, not two 32-bit gathers (5% faster diffuse rays on
    // this AMD machine, docs/performance.md). Every lane's idx is a node of the tree (lanes
    // outside the step keep their last one), so each load is valid; inactive lanes are
    // zeroed, as masked gathers would leave them.
    auto node64 = [&](int j) {
        long long v;
        std::memcpy(&v, tv.nodes + o.idx[j], 8);
        return v;
    };
    const __m256i lo = _mm256_setr_epi64x(node64(0), node64(1), node64(2), node64(3));
    const __m256i hi = _mm256_setr_epi64x(node64(4), node64(5), node64(6), node64(7));
    // (w0 s0 w1 s1 | w2 s2 w3 s3) -> (w0 w1 w2 w3 | s0 s1 s2 s3)
    const __m256i deint = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
    const __m256i a = _mm256_permutevar8x32_epi32(lo, deint);
    const __m256i b = _mm256_permutevar8x32_epi32(hi, deint);
    const __m256i word = _mm256_and_si256(_mm256_permute2x128_si256(a, b, 0x20), active);
    const __m256i second = _mm256_and_si256(_mm256_permute2x128_si256(a, b, 0x31), active);
    const __m256 split = _mm256_castsi256_ps(second);
    const __m256i three = _mm256_set1_epi32(3), one = _mm256_set1_epi32(1);
    const __m256i axis = _mm256_and_si256(word, three);
    const __m256i is_leaf = _mm256_cmpeq_epi32(axis, three);
    const __m256 ax1 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(axis, one));
    const __m256 ax2 = _mm256_castsi256_ps(_mm256_cmpeq_epi32(axis, _mm256_set1_epi32(2)));
    auto pick = [&](const float(*v)[8]) {
        return _mm256_blendv_ps(_mm256_blendv_ps(_mm256_load_ps(v[0]), _mm256_load_ps(v[1]), ax1),
                                _mm256_load_ps(v[2]), ax2);
    };
    const __m256 ts = _mm256_mul_ps(_mm256_sub_ps(split, pick(o.org)), pick(o.inv));
    const __m256 t0 = _mm256_load_ps(o.t0), t1 = _mm256_load_ps(o.t1);
    const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    const __m256 slack = _mm256_set1_ps(kIntervalSlack);
    const __m256 lo0 = _mm256_sub_ps(t0, _mm256_mul_ps(slack, _mm256_and_ps(t0, abs_mask)));
    const __m256 hi1 = _mm256_add_ps(t1, _mm256_mul_ps(slack, _mm256_and_ps(t1, abs_mask)));
    const __m256i neg = _mm256_and_si256(
        _mm256_srlv_epi32(_mm256_load_si256(reinterpret_cast<const __m256i*>(o.neg_bits)), axis),
        one);
    const __m256i empty = _mm256_srli_epi32(word, 2);
    const __m256i first = _mm256_srli_epi32(word, 4);
    const __m256i near_idx = _mm256_add_epi32(first, neg);
    const __m256i far_idx = _mm256_sub_epi32(_mm256_add_epi32(first, one), neg);
    const __m256i near_empty = _mm256_and_si256(_mm256_srlv_epi32(empty, neg), one);
    const __m256i far_empty =
        _mm256_and_si256(_mm256_srlv_epi32(empty, _mm256_sub_epi32(one, neg)), one);
    const __m256i zero = _mm256_setzero_si256();
    // !(ts < lo0) and !(ts > hi1), true on NaN as there; never into an empty child.
    const __m256i go_near =
        _mm256_and_si256(_mm256_cmpeq_epi32(near_empty, zero),
                         _mm256_castps_si256(_mm256_cmp_ps(ts, lo0, _CMP_NLT_UQ)));
    const __m256i go_far =
        _mm256_and_si256(_mm256_cmpeq_epi32(far_empty, zero),
                         _mm256_castps_si256(_mm256_cmp_ps(ts, hi1, _CMP_NGT_UQ)));
    const __m256 far_t0 = _mm256_max_ps(ts, t0);  // ts > t0 ? ts : t0
    const __m256 near_t1 = _mm256_min_ps(ts, t1);
    const __m256i inner = _mm256_andnot_si256(is_leaf, active);
    const uint32_t both = uint32_t(_mm256_movemask_ps(
        _mm256_castsi256_ps(_mm256_and_si256(inner, _mm256_and_si256(go_near, go_far)))));
    const __m256i moves = _mm256_and_si256(inner, _mm256_or_si256(go_near, go_far));
    const __m256i to_near = _mm256_and_si256(inner, go_near);
    const __m256i to_far = _mm256_andnot_si256(go_near, moves);
    // Far children of lanes that visit both: pushed, as descend() does.
    if (both) {
        alignas(32) uint32_t far_a[8];
        alignas(32) float ft0[8];
        _mm256_store_si256(reinterpret_cast<__m256i*>(far_a), far_idx);
        _mm256_store_ps(ft0, far_t0);
        for (uint32_t m = both; m; m &= m - 1) {
            const int j = __builtin_ctz(m);
            Lane& l = o.lanes[j];
            StackItem& top = l.stack[l.depth++];
            top.node = far_a[j];
            top.t0 = ft0[j];
            top.t1 = o.t1[j];
        }
    }
    const __m256i new_idx =
        _mm256_blendv_epi8(_mm256_blendv_epi8(vidx, far_idx, to_far), near_idx, to_near);
    _mm256_store_si256(reinterpret_cast<__m256i*>(o.idx), new_idx);
    _mm256_store_ps(o.t0, _mm256_blendv_ps(t0, far_t0, _mm256_castsi256_ps(to_far)));
    _mm256_store_ps(o.t1, _mm256_blendv_ps(t1, near_t1, _mm256_castsi256_ps(to_near)));
    const uint32_t moved = uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(moves)));
    for (uint32_t m = moved; m; m &= m - 1) prefetch(tv.nodes + o.idx[__builtin_ctz(m)]);
    const uint32_t leaves =
        uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_and_si256(is_leaf, active))));
    for (uint32_t m = leaves; m; m &= m - 1) {
        const int j = __builtin_ctz(m);
        Lane& l = o.lanes[j];
        l.idx = o.idx[j];
        l.leaf = tv.nodes[l.idx];
        l.t0 = o.t0[j];
        l.t1 = o.t1[j];
        o.vector_mask &= ~(1u << j);
        prefetch_records(tv, l.leaf);
    }
    // Inner lanes that enter neither child pop.
    return o.vector_mask & ~moved & ~leaves;
}

// Traces rays[0, count) with kGroups octets, visited in turn: while one octet steps, the
// nodes the others prefetched arrive. A lane whose ray is done takes the next ray.
template <bool kAnyHit, int kGroups>
void trace_octets(const TreeView& tv, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
                  StreamCounts& counts) {
    Octet octets[kGroups];
    size_t next = 0;
    auto finish = [&](const Lane& l) { write_result<kAnyHit>(l, hits, occluded); };
    // Lane j of o takes the next ray that meets the tree, or leaves the octet.
    auto refill = [&](Octet& o, int j) {
        while (next < count) {
            const size_t i = next++;
            if (start(tv, rays[i], uint32_t(i), o.lanes[j])) {
                o.set_ray(j);
                o.enter(j);
                o.live_mask |= 1u << j;
                return;
            }
        }
        o.live_mask &= ~(1u << j);
        o.vector_mask &= ~(1u << j);
    };
    // Lane j of o pops its next node into the vector step, or its ray is done.
    auto pop_or_finish = [&](Octet& o, int j) {
        Lane& l = o.lanes[j];
        if (pop(l)) {
            prefetch(tv.nodes + l.idx);
            o.enter(j);
            return;
        }
        finish(l);
        o.vector_mask &= ~(1u << j);
        refill(o, j);
    };
    uint32_t any_live = 0;
    for (Octet& o : octets) {
        for (int j = 0; j < 8; ++j) {
            o.idx[j] = 0;
            o.t0[j] = o.t1[j] = 0.0f;
            refill(o, j);
        }
        any_live |= o.live_mask;
    }
    while (any_live) {
        any_live = 0;
        for (Octet& o : octets) {
            if (o.vector_mask) {
                for (uint32_t m = octet_step(tv, o, counts); m; m &= m - 1)
                    pop_or_finish(o, __builtin_ctz(m));
            }
            // Lanes outside the vector step have just reached a leaf: tested at once (their
            // records were prefetched by the step; leaving the test for a later round, after
            // prefetching the vertices too, was slower: docs/performance.md).
            for (uint32_t m = o.live_mask & ~o.vector_mask; m; m &= m - 1) {
                const int j = __builtin_ctz(m);
                Lane& l = o.lanes[j];
                const bool hit = tv.reference_triangles ? test_leaf<kAnyHit, true>(tv, l, counts)
                                                        : test_leaf<kAnyHit, false>(tv, l, counts);
                if (hit) {
                    l.best_prim = 0;
                    finish(l);
                    refill(o, j);
                    continue;
                }
                pop_or_finish(o, j);  // also for the root as an empty leaf
            }
            any_live |= o.live_mask;
        }
    }
}
#endif

// Lane counts as kStreamLaneChoices lists them. On AVX2 builds multiples of eight run as
// octets (the scalar round-robin was slower at every such count), other counts round-robin.
template <bool kAnyHit, bool kDirect>
void dispatch_lanes(const TreeView& tv, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
                    int lanes, StreamCounts& counts) {
#if KDT_SIMD_TRAVERSAL
    if (lanes >= 8) {
        if (lanes < 16)
            trace_octets<kAnyHit, 1>(tv, rays, count, hits, occluded, counts);
        else if (lanes < 24)
            trace_octets<kAnyHit, 2>(tv, rays, count, hits, occluded, counts);
        else if (lanes < 32)
            trace_octets<kAnyHit, 3>(tv, rays, count, hits, occluded, counts);
        else
            trace_octets<kAnyHit, 4>(tv, rays, count, hits, occluded, counts);
        return;
    }
#endif
    if (lanes < 4)
        trace_stream<kAnyHit, kDirect, 1>(tv, rays, count, hits, occluded, counts);
    else if (lanes < 8)
        trace_stream<kAnyHit, kDirect, 4>(tv, rays, count, hits, occluded, counts);
    else if (lanes < 16)
        trace_stream<kAnyHit, kDirect, 8>(tv, rays, count, hits, occluded, counts);
    else if (lanes < 24)
        trace_stream<kAnyHit, kDirect, 16>(tv, rays, count, hits, occluded, counts);
    else if (lanes < 32)
        trace_stream<kAnyHit, kDirect, 24>(tv, rays, count, hits, occluded, counts);
    else
        trace_stream<kAnyHit, kDirect, 32>(tv, rays, count, hits, occluded, counts);
}

template <bool kAnyHit>
void dispatch(const KdTree& tree, const Ray* rays, size_t count, Hit* hits, uint8_t* occluded,
              int lanes, TraversalCounters* counters) {
    const TreeView tv = detail::view_of(tree);
    StreamCounts counts;
    if (tv.reference_triangles)
        dispatch_lanes<kAnyHit, true>(tv, rays, count, hits, occluded, lanes, counts);
    else
        dispatch_lanes<kAnyHit, false>(tv, rays, count, hits, occluded, lanes, counts);
    if (counters) {
        counters->nodes_visited += counts.nodes;
        counters->triangles_tested += counts.triangles;
    }
}

}  // namespace

void intersect_stream(const KdTree& tree, const Ray* rays, size_t count, Hit* hits, int lanes,
                      TraversalCounters* counters) {
    for (size_t i = 0; i < count; ++i) hits[i] = Hit{};
    if (tree.nodes().empty() || tree.mesh_ptr() == nullptr) return;
    dispatch<false>(tree, rays, count, hits, nullptr, lanes, counters);
}

void occluded_stream(const KdTree& tree, const Ray* rays, size_t count, uint8_t* occluded,
                     int lanes, TraversalCounters* counters) {
    for (size_t i = 0; i < count; ++i) occluded[i] = 0;
    if (tree.nodes().empty() || tree.mesh_ptr() == nullptr) return;
    dispatch<true>(tree, rays, count, nullptr, occluded, lanes, counters);
}

}  // namespace kdt
