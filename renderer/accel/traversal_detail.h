// Internal to the kd-tree queries (traversal.cpp, traversal_packet.cpp, traversal_stream.cpp,
// traversal_partition.cpp): the per-ray setup, the single-ray descent and pop, and the
// four-wide triangle and leaf tests they share, so all of them take exactly the same steps.
// Depends on accel/kdtree.h and geometry/intersect.h.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <immintrin.h>

// The SIMD paths (the packet traversal and the four-wide leaf test) need AVX2 and FMA;
// other builds trace one ray and one triangle at a time.
#if defined(__AVX2__) && defined(__FMA__)
#define KDT_SIMD_TRAVERSAL 1
#else
#define KDT_SIMD_TRAVERSAL 0
#endif

#include "renderer/accel/kdtree.h"
#include "renderer/geometry/intersect.h"

namespace kdt::detail {

constexpr int kStackSize = 68;  // one entry per level; trees are at most 64 deep

struct StackItem {
    uint32_t node;
    float t0, t1;
    uint32_t pad;  // 16 bytes: one shift to index
};

inline float lower_slack(float t) { return t - kIntervalSlack * std::fabs(t); }
inline float upper_slack(float t) { return t + kIntervalSlack * std::fabs(t); }

// Per-ray constants of the traversal and of the triangle test.
struct RayState {
    float org[4] = {}, inv[4] = {};  // lane 3 is padding (setup_ray stores SSE vectors)
    // Bit k is set if the ray runs toward -axis k: then the second child is near.
    uint32_t neg_bits = 0;
    float t_scale = 1.0f;  // internal t times t_scale = caller's t
    float tmin = 0.0f;     // the caller's tmin in internal units
    WatertightRay wr;
    uint32_t neg(int axis) const { return (neg_bits >> axis) & 1u; }
#if KDT_SIMD_TRAVERSAL
    // (kx, ky, kz, 3): picks a vertex's components in the watertight test's order, for the
    // four-wide leaf test (traversal.cpp).
    __m128i perm;
#endif
};

// Rejects non-finite or zero-direction rays and clips the interval to the root box.
// Directions with extreme magnitudes are rescaled by a power of two (exact), so
// 1 / d and the distances stay finite. Returns false on a certain miss; otherwise sets
// [t0, t1] (root box, internal units) and tmax (the caller's, internal units). The three
// axes are set up in one SSE vector each (origin, direction, 1 / d, slab distances); each
// lane computes what a scalar loop over the axes would, operation by operation.
inline bool setup_ray(const Ray& ray, const Bounds3f& bounds, RayState& rs, float& t0, float& t1,
                      float& tmax) {
    const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    const __m128 inf = _mm_set1_ps(kInfinity);
    // Lane 3 holds a 0 origin and a unit direction, which every step leaves finite.
    const __m128 o = _mm_setr_ps(ray.origin.x, ray.origin.y, ray.origin.z, 0.0f);
    __m128 d = _mm_setr_ps(ray.dir.x, ray.dir.y, ray.dir.z, 1.0f);
    const __m128 ad = _mm_and_ps(d, abs_mask);
    const int finite = _mm_movemask_ps(_mm_cmplt_ps(_mm_and_ps(o, abs_mask), inf)) &
                       _mm_movemask_ps(_mm_cmplt_ps(ad, inf));
    // !(tmin <= tmax) also rejects a NaN bound.
    if (finite != 0xf || !(ray.tmin <= ray.tmax) || bounds.empty()) return false;
    const float m =
        _mm_cvtss_f32(_mm_max_ss(_mm_max_ss(ad, _mm_shuffle_ps(ad, ad, 1)), _mm_movehl_ps(ad, ad)));
    if (!(m > 0.0f)) return false;
    t0 = ray.tmin;
    t1 = ray.tmax;
    if (m < 0x1p-40f || m > 0x1p40f) [[unlikely]] {
        int e;
        std::frexp(m, &e);
        alignas(16) float dk[4];
        _mm_store_ps(dk, d);
        for (int k = 0; k < 3; ++k) dk[k] = std::ldexp(dk[k], -e);
        d = _mm_load_ps(dk);
        rs.t_scale = std::ldexp(1.0f, -e);
        t0 = std::ldexp(t0, e);
        t1 = std::ldexp(t1, e);
    }
    rs.tmin = t0;
    tmax = t1;
    const __m128 zero = _mm_setzero_ps();
    const __m128 is_zero = _mm_cmpeq_ps(d, zero);
    // Zero components become -0 so that 1/d = -inf and neg agree on the sign.
    d = _mm_or_ps(d, _mm_and_ps(is_zero, _mm_set1_ps(-0.0f)));
    const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), d);
    _mm_storeu_ps(rs.org, o);
    _mm_storeu_ps(rs.inv, inv);
    rs.neg_bits = uint32_t(_mm_movemask_ps(d)) & 7u;
    // Slab test against the root box, conservative as intersect_box(); a zero component
    // hits iff the origin lies in the closed slab, and leaves the interval alone.
    const __m128 lower = _mm_setr_ps(bounds.lower.x, bounds.lower.y, bounds.lower.z, 0.0f);
    const __m128 upper = _mm_setr_ps(bounds.upper.x, bounds.upper.y, bounds.upper.z, 0.0f);
    const __m128 in_slab = _mm_and_ps(_mm_cmpge_ps(o, lower), _mm_cmple_ps(o, upper));
    if (_mm_movemask_ps(_mm_andnot_ps(in_slab, is_zero)) & 7) return false;
    const __m128 a = _mm_mul_ps(_mm_sub_ps(lower, o), inv);
    const __m128 b = _mm_mul_ps(_mm_sub_ps(upper, o), inv);
    // std::min(a, b) = b < a ? b : a = minps(b, a); std::max(a, b) = a < b ? b : a = maxps(b, a).
    const __m128 mn = _mm_min_ps(b, a), mx = _mm_max_ps(b, a);
    const __m128 slack = _mm_set1_ps(kIntervalSlack);
    const __m128 unused = _mm_or_ps(is_zero, _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, -1)));
    // t -/+ k |t|: k is a power of two, so the product is exact and an FMA (which the
    // compiler may contract this to) rounds alike.
    const __m128 lo = _mm_sub_ps(mn, _mm_mul_ps(slack, _mm_and_ps(mn, abs_mask)));
    const __m128 hi = _mm_add_ps(mx, _mm_mul_ps(slack, _mm_and_ps(mx, abs_mask)));
    const __m128 tn =
        _mm_or_ps(_mm_andnot_ps(unused, lo), _mm_and_ps(unused, _mm_set1_ps(-kInfinity)));
    const __m128 tf = _mm_or_ps(_mm_andnot_ps(unused, hi), _mm_and_ps(unused, inf));
    // In axis order, as the scalar loop: t0 = tn > t0 ? tn : t0 keeps t0 on NaN.
    alignas(16) float n4[4], f4[4], dk[4];
    _mm_store_ps(n4, tn);
    _mm_store_ps(f4, tf);
    for (int k = 0; k < 3; ++k) {
        t0 = n4[k] > t0 ? n4[k] : t0;
        t1 = f4[k] < t1 ? f4[k] : t1;
    }
    if (!(t0 <= t1)) return false;
    _mm_store_ps(dk, d);
    rs.wr.set(ray.origin, Vec3f(dk[0], dk[1], dk[2]));
#if KDT_SIMD_TRAVERSAL
    rs.perm = _mm_setr_epi32(rs.wr.kx, rs.wr.ky, rs.wr.kz, 3);
#endif
    return true;
}

// Tree arrays of a query.
struct TreeView {
    const KdNode* nodes;
    const uint32_t* indices;
    const Vec3f* positions;
    const Vec3u* triangles;  // the mesh's
    Bounds3f bounds;
    const Vec3u* reference_triangles;  // parallel to indices; null when the tree has none

    /// Vertex indices of reference i (an index into indices).
    const Vec3u& triangle_of(size_t i) const {
        return reference_triangles ? reference_triangles[i] : triangles[indices[i]];
    }
};

inline TreeView view_of(const KdTree& tree) {
    const auto& refs = tree.reference_triangles();
    return {
        tree.nodes().data(),          tree.indices().data(), tree.mesh().positions.data(),
        tree.mesh().triangles.data(), tree.bounds(),         refs.empty() ? nullptr : refs.data()};
}

#if KDT_SIMD_TRAVERSAL
/// The double-precision part of intersect_triangle() on four lanes, shared by the packet
/// test (four rays per half) and the leaf test (four triangles): the edge functions of the
/// sheared vertices, exact as there (products of floats are exact in double).
struct Edges4 {
    __m256d U, V, W;
};

/// Sets e from the sheared x, y of vertices a, b, c; returns the mask of lanes inside
/// (all edge functions of one sign, zero counting as either).
inline int edges4(__m256d ax, __m256d ay, __m256d bx, __m256d by, __m256d cx, __m256d cy,
                  Edges4& e) {
    e.U = _mm256_fmsub_pd(cx, by, _mm256_mul_pd(cy, bx));
    e.V = _mm256_fmsub_pd(ax, cy, _mm256_mul_pd(ay, cx));
    e.W = _mm256_fmsub_pd(bx, ay, _mm256_mul_pd(by, ax));
    const __m256d zero = _mm256_setzero_pd();
    const __m256d any_neg = _mm256_or_pd(
        _mm256_or_pd(_mm256_cmp_pd(e.U, zero, _CMP_LT_OQ), _mm256_cmp_pd(e.V, zero, _CMP_LT_OQ)),
        _mm256_cmp_pd(e.W, zero, _CMP_LT_OQ));
    const __m256d any_pos = _mm256_or_pd(
        _mm256_or_pd(_mm256_cmp_pd(e.U, zero, _CMP_GT_OQ), _mm256_cmp_pd(e.V, zero, _CMP_GT_OQ)),
        _mm256_cmp_pd(e.W, zero, _CMP_GT_OQ));
    return ~_mm256_movemask_pd(_mm256_and_pd(any_neg, any_pos)) & 0xf;
}

/// t, u, v of each lane from its edge functions and its vertices' sz * z (the explicit
/// FMAs of the scalar test); returns the mask of lanes with a non-zero determinant.
inline int solve4(const Edges4& e, __m256d za, __m256d zb, __m256d zc, __m128& t, __m128& u,
                  __m128& v) {
    const __m256d det = _mm256_add_pd(_mm256_add_pd(e.U, e.V), e.W);
    const int ok = ~_mm256_movemask_pd(_mm256_cmp_pd(det, _mm256_setzero_pd(), _CMP_EQ_OQ)) & 0xf;
    const __m256d T = _mm256_fmadd_pd(e.W, zc, _mm256_fmadd_pd(e.V, zb, _mm256_mul_pd(e.U, za)));
    const __m256d inv_det = _mm256_div_pd(_mm256_set1_pd(1.0), det);
    t = _mm256_cvtpd_ps(_mm256_mul_pd(T, inv_det));
    u = _mm256_cvtpd_ps(_mm256_mul_pd(e.V, inv_det));
    v = _mm256_cvtpd_ps(_mm256_mul_pd(e.W, inv_det));
    return ok;
}
#endif

#if KDT_SIMD_TRAVERSAL
#ifndef KDT_WIDE_LEAF_MIN
#define KDT_WIDE_LEAF_MIN 2
#endif

// Leaves with at least this many triangles are tested four at a time by the single-ray and
// the stream queries (from two up is fastest on the dragon; the macro lets a build measure
// other thresholds).
constexpr uint32_t kWideLeafMin = KDT_WIDE_LEAF_MIN;

// A vertex as (x, y, z, w) in the watertight test's order (kx, ky, kz): the masked load
// never reads past the vertex's 12 bytes.
inline __m128 load_vertex(const Vec3f& p, __m128i perm) {
    return _mm_permutevar_ps(_mm_maskload_ps(&p.x, _mm_setr_epi32(-1, -1, -1, 0)), perm);
}

// One vertex of four triangles, sheared as in intersect_triangle(): x, y, z per lane.
struct Vertex4 {
    __m128 x, y, z;
};

inline Vertex4 shear4(__m128 l0, __m128 l1, __m128 l2, __m128 l3, const WatertightRay& r) {
    const __m128 t0 = _mm_unpacklo_ps(l0, l1);  // x0 x1 y0 y1
    const __m128 t1 = _mm_unpacklo_ps(l2, l3);  // x2 x3 y2 y3
    const __m128 t2 = _mm_unpackhi_ps(l0, l1);  // z0 z1 w0 w1
    const __m128 t3 = _mm_unpackhi_ps(l2, l3);  // z2 z3 w2 w3
    Vertex4 v;
    v.z = _mm_sub_ps(_mm_movelh_ps(t2, t3), _mm_set1_ps(r.oz));
    // exact_fmsub(x - o, s, z) = fma(-s, z, x - o)
    v.x =
        _mm_fnmadd_ps(_mm_set1_ps(r.sx), v.z, _mm_sub_ps(_mm_movelh_ps(t0, t1), _mm_set1_ps(r.ox)));
    v.y =
        _mm_fnmadd_ps(_mm_set1_ps(r.sy), v.z, _mm_sub_ps(_mm_movehl_ps(t1, t0), _mm_set1_ps(r.oy)));
    return v;
}

// intersect_triangle() on four triangles at once, operation by operation (the same float
// shear, the same exact double edge functions, the same FMAs), so every lane's result is
// bit for bit the scalar test's. Returns the mask of lanes in `valid` that hit within
// [tmin, tmax], with their t, u, v.
inline int intersect4(const Vec3f* positions, const Vec3u* tri, int valid, const RayState& rs,
                      float tmax, float* t_out, float* u_out, float* v_out) {
    const WatertightRay& r = rs.wr;
    Vertex4 v[3];
    for (int k = 0; k < 3; ++k)
        v[k] = shear4(load_vertex(positions[tri[0][k]], rs.perm),
                      load_vertex(positions[tri[1][k]], rs.perm),
                      load_vertex(positions[tri[2][k]], rs.perm),
                      load_vertex(positions[tri[3][k]], rs.perm), r);
    Edges4 e;
    const int pass =
        edges4(_mm256_cvtps_pd(v[0].x), _mm256_cvtps_pd(v[0].y), _mm256_cvtps_pd(v[1].x),
               _mm256_cvtps_pd(v[1].y), _mm256_cvtps_pd(v[2].x), _mm256_cvtps_pd(v[2].y), e) &
        valid;
    if (!pass) return 0;
    const __m128 sz = _mm_set1_ps(r.sz);
    __m128 t, u, vb;
    const int ok =
        solve4(e, _mm256_cvtps_pd(_mm_mul_ps(sz, v[0].z)), _mm256_cvtps_pd(_mm_mul_ps(sz, v[1].z)),
               _mm256_cvtps_pd(_mm_mul_ps(sz, v[2].z)), t, u, vb);
    _mm_storeu_ps(t_out, t);
    _mm_storeu_ps(u_out, u);
    _mm_storeu_ps(v_out, vb);
    const __m128 in_range = _mm_and_ps(_mm_cmp_ps(t, _mm_set1_ps(rs.tmin), _CMP_GE_OQ),
                                       _mm_cmp_ps(t, _mm_set1_ps(tmax), _CMP_LE_OQ));
    return pass & ok & _mm_movemask_ps(in_range);
}

/// test_leaf() of the single-ray and stream queries four triangles at a time, on the closest
/// hit so far (best_*). The hits of a group, taken in order and each kept only if it is still
/// the closest, are exactly the scalar loop's: a later triangle at the same t wins, as it does
/// there. Adds the triangles tested (up to the hit for kAnyHit) to `tested`; true when
/// kAnyHit and one is hit. kDirect: the tree has reference triangles.
template <bool kAnyHit, bool kDirect>
inline bool test_leaf4(const KdNode node, const TreeView& tv, const RayState& rs, float& best_t,
                       float& best_u, float& best_v, uint32_t& best_prim, uint64_t& tested) {
    const uint32_t count = node.count();
    const uint32_t* ids = tv.indices + node.first;
    for (uint32_t i = 0; i < count; i += 4) {
        const uint32_t n = std::min(count - i, 4u);
        Vec3u tri[4];
        for (uint32_t j = 0; j < 4; ++j) {
            const uint32_t k = i + (j < n ? j : 0u);  // idle lanes repeat the first
            tri[j] = kDirect ? tv.reference_triangles[node.first + k] : tv.triangles[ids[k]];
        }
        alignas(16) float t[4], u[4], v[4];
        int hits = intersect4(tv.positions, tri, (1 << n) - 1, rs, best_t, t, u, v);
        if (!hits) continue;
        if (kAnyHit) {
            tested += i + uint32_t(__builtin_ctz(unsigned(hits))) + 1;
            return true;
        }
        do {
            const int j = __builtin_ctz(unsigned(hits));
            hits &= hits - 1;
            if (t[j] <= best_t) {
                best_t = t[j];
                best_u = u[j];
                best_v = v[j];
                best_prim = ids[i + j];
            }
        } while (hits);
    }
    tested += count;
    return false;
}

#endif

/// Tests the triangles of a leaf on the closest hit so far (best_*), as the single-ray and
/// the stream queries both do: four at a time from kWideLeafMin triangles up, one by one
/// below. Adds the triangles tested (up to the hit for kAnyHit) to `tested`; true when
/// kAnyHit and one is hit. kDirect: the tree has reference triangles (a run-time test here
/// costs the gain they bring).
template <bool kAnyHit, bool kDirect>
inline bool test_leaf(const KdNode node, const TreeView& tv, const RayState& rs, float& best_t,
                      float& best_u, float& best_v, uint32_t& best_prim, uint64_t& tested) {
    const uint32_t count = node.count();
#if KDT_SIMD_TRAVERSAL
    if (count >= kWideLeafMin)
        return test_leaf4<kAnyHit, kDirect>(node, tv, rs, best_t, best_u, best_v, best_prim,
                                            tested);
#endif
    const uint32_t* ids = tv.indices + node.first;
    const Vec3u* refs = kDirect ? tv.reference_triangles + node.first : nullptr;
    const Vec3f* positions = tv.positions;
    for (uint32_t i = 0; i < count; ++i) {
        const Vec3u tri = kDirect ? refs[i] : tv.triangles[ids[i]];
        float t, u, v;
        if (intersect_triangle(rs.wr, positions[tri.x], positions[tri.y], positions[tri.z], rs.tmin,
                               best_t, t, u, v)) {
            if (kAnyHit) {
                tested += i + 1;
                return true;
            }
            best_t = t;
            best_u = u;
            best_v = v;
            best_prim = ids[i];
        }
    }
    tested += count;
    return false;
}

// The path of the current node while a query records one (kPath): nodes[0..depth]. A stack
// entry keeps its node's depth, so a pop restores it; the entries above that depth are still
// the popped node's ancestors, since the stack is last in, first out.
struct PathRecord {
    uint32_t depth;
    uint32_t nodes[KdPath::kMaxLength];
};

// Descends from node idx to a leaf, pushing far children; returns the leaf and leaves idx
// at it, or an empty leaf when no child is left to enter. At each inner node: visit_near =
// !(ts < lower_slack(t0)), visit_far = !(ts > upper_slack(t1)), and a child that is an
// empty leaf is not visited at all (the node's word flags such children, so neither is
// read; on the dragon 7.4 of the 9.7 leaves a diffuse ray reaches are empty). Both: push
// the far child with [max(ts, t0), t1] and go near with t1 = min(ts, t1); near only: t1 =
// min(ts, t1); far only: t0 = max(ts, t0). A ray lying in the plane (origin on it, d = 0:
// t = 0 * inf = NaN) visits both sides, since a builder may reference a triangle that only
// touches the plane from either side: comparisons are written so that NaN means "visit",
// and max/min are SSE's maxss/minss, which return the second operand on NaN (so the
// interval stays [t0, t1]). The push is branch-free (the far child is always written, kept
// only when both sides are visited); the choice of the next node stays a branch, whose
// prediction lets the next fetch start before ts is known. The stack cannot overflow: a
// tree is checked to be at most 64 deep when it is made, and each level pushes at most one
// entry.
template <bool kCount, bool kPath = false>
inline KdNode descend(const KdNode* nodes, uint32_t& idx, const RayState& rs, float t0, float& t1,
                      StackItem*& top, uint64_t& visited, PathRecord* rec = nullptr) {
    KdNode node = nodes[idx];
    if (kCount) ++visited;
    __m128 vt0 = _mm_set_ss(t0);
    __m128 lo0 = _mm_set_ss(lower_slack(t0));
    __m128 vt1 = _mm_set_ss(t1);
    const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    const __m128 slack = _mm_set_ss(kIntervalSlack);
    const uint32_t neg_bits = rs.neg_bits;
    while (!node.is_leaf()) {
        const int axis = node.axis();
        const __m128 ts =
            _mm_mul_ss(_mm_sub_ss(_mm_load_ss(&node.split), _mm_load_ss(&rs.org[axis])),
                       _mm_load_ss(&rs.inv[axis]));
        // t1 + k |t1|: k is a power of two, so the product is exact and an FMA rounds alike.
        const __m128 hi1 = _mm_add_ss(vt1, _mm_mul_ss(slack, _mm_and_ps(vt1, abs_mask)));
        // The sign bit and the empty-child bits come from registers, so the next node's
        // address waits on no other load.
        const uint32_t first = node.child();
        const uint32_t neg = (neg_bits >> axis) & 1u;
        const uint32_t empty = node.empty_children();
        const uint32_t near_idx = first + neg;
        const uint32_t far_idx = first + 1u - neg;
        const bool visit_near = _mm_cvtsi128_si32(_mm_castps_si128(_mm_cmpnlt_ss(ts, lo0))) != 0;
        const bool go_near = visit_near & !((empty >> neg) & 1u);
        const bool go_far = !_mm_comigt_ss(ts, hi1) & !((empty >> (1u - neg)) & 1u);
        top->node = far_idx;
        const __m128 far_t0 = _mm_max_ss(ts, vt0);
        _mm_store_ss(&top->t0, far_t0);
        _mm_store_ss(&top->t1, vt1);
        if (kPath) top->pad = rec->depth + 1;
        top += int(go_near & go_far);
        if (go_near) {
            vt1 = _mm_min_ss(ts, vt1);
            idx = near_idx;
        } else if (go_far) {
            vt0 = far_t0;
            lo0 = _mm_sub_ss(vt0, _mm_mul_ss(slack, _mm_and_ps(vt0, abs_mask)));
            idx = far_idx;
        } else {
            return KdNode{};
        }
        if (kPath) rec->nodes[++rec->depth] = idx;
        node = nodes[idx];
        if (kCount) ++visited;
    }
    t1 = _mm_cvtss_f32(vt1);
    return node;
}

// Closest hit so far (the caller's tmax until something is hit).
struct BestHit {
    float t, u = 0.0f, v = 0.0f;
    uint32_t prim = Hit::kNoHit;
};

// detail::test_leaf() on the query's closest hit.
template <bool kAnyHit, bool kDirect>
inline bool test_leaf(const KdNode node, const TreeView& tv, const RayState& rs, BestHit& best,
                      uint64_t& tested) {
    return detail::test_leaf<kAnyHit, kDirect>(node, tv, rs, best.t, best.u, best.v, best.prim,
                                               tested);
}

// Next node front to back, skipping those that start beyond the closest hit. A hit beyond
// the current leaf does not end the search (the thesis's figure 3). False when none is left.
template <bool kPath = false>
inline bool pop(const StackItem* stack, StackItem*& top, float best_t, uint32_t& idx, float& t0,
                float& t1, PathRecord* rec = nullptr) {
    while (top > stack) {
        const StackItem& s = *--top;
        if (lower_slack(s.t0) <= best_t) {
            idx = s.node;
            t0 = s.t0;
            t1 = std::min(s.t1, best_t);
            if (kPath) {
                rec->depth = s.pad;
                rec->nodes[s.pad] = s.node;
            }
            return true;
        }
    }
    return false;
}

/// Rays per packet.
inline constexpr int kPacketSize = 8;

/// Traces rays[0, m), 1 <= m <= kPacketSize, as one SIMD packet when they are coherent
/// (same direction signs and dominant axis, nearly parallel, nearby origins) and returns
/// true; returns false, having traced nothing, otherwise (and always on builds without
/// KDT_SIMD_TRAVERSAL). Closest hits go to hits (any_hit false), any-hit results to occluded
/// (any_hit true). Every result is exactly the single-ray query's: each ray visits the same nodes
/// in the same order and runs the same triangle test.
bool trace_packet(const TreeView& tv, const Ray* rays, int m, bool any_hit, Hit* hits,
                  uint8_t* occluded, TraversalCounters* counters);

}  // namespace kdt::detail
