// Internal to the kd-tree queries (traversal.cpp, traversal_packet.cpp): per-ray setup
// shared by the single-ray and the packet traversal, so both take exactly the same steps.
// Depends on accel/kdtree.h and geometry/intersect.h.
#pragma once

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
    float org[3], inv[3];
    uint32_t neg[3];       // 1 if the ray runs toward -axis: then the second child is near
    float t_scale = 1.0f;  // internal t times t_scale = caller's t
    float tmin = 0.0f;     // the caller's tmin in internal units
    WatertightRay wr;
#if KDT_SIMD_TRAVERSAL
    // (kx, ky, kz, 3): picks a vertex's components in the watertight test's order, for the
    // four-wide leaf test (traversal.cpp).
    __m128i perm;
#endif
};

// Rejects non-finite or zero-direction rays and clips the interval to the root box.
// Directions with extreme magnitudes are rescaled by a power of two (exact), so
// 1 / d and the distances stay finite. Returns false on a certain miss; otherwise sets
// [t0, t1] (root box, internal units) and tmax (the caller's, internal units).
inline bool setup_ray(const Ray& ray, const Bounds3f& bounds, RayState& rs, float& t0, float& t1,
                      float& tmax) {
    if (!is_finite(ray.origin) || !is_finite(ray.dir) || std::isnan(ray.tmin) ||
        std::isnan(ray.tmax) || !(ray.tmin <= ray.tmax) || bounds.empty())
        return false;
    float d[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
    const float m = std::max(std::fabs(d[0]), std::max(std::fabs(d[1]), std::fabs(d[2])));
    if (!(m > 0.0f)) return false;
    t0 = ray.tmin;
    t1 = ray.tmax;
    if (m < 0x1p-40f || m > 0x1p40f) [[unlikely]] {
        int e;
        std::frexp(m, &e);
        for (float& dk : d) dk = std::ldexp(dk, -e);
        rs.t_scale = std::ldexp(1.0f, -e);
        t0 = std::ldexp(t0, e);
        t1 = std::ldexp(t1, e);
    }
    rs.tmin = t0;
    tmax = t1;
    const float org[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
    const float lower[3] = {bounds.lower.x, bounds.lower.y, bounds.lower.z};
    const float upper[3] = {bounds.upper.x, bounds.upper.y, bounds.upper.z};
    bool hit = true;
    for (int k = 0; k < 3; ++k) {
        // Zero components become -0 so that 1/d = -inf and neg agree on the sign.
        const float dk = d[k] == 0.0f ? -0.0f : d[k];
        d[k] = dk;
        rs.org[k] = org[k];
        rs.inv[k] = 1.0f / dk;
        rs.neg[k] = std::signbit(dk) ? 1u : 0u;
        // Slab test against the root box, conservative as intersect_box(); a zero
        // component hits iff the origin lies in the closed slab.
        if (dk == 0.0f) {
            hit &= org[k] >= lower[k] && org[k] <= upper[k];
            continue;
        }
        const float a = (lower[k] - org[k]) * rs.inv[k];
        const float b = (upper[k] - org[k]) * rs.inv[k];
        const float tn = lower_slack(std::min(a, b)), tf = upper_slack(std::max(a, b));
        t0 = tn > t0 ? tn : t0;
        t1 = tf < t1 ? tf : t1;
    }
    if (!hit || !(t0 <= t1)) return false;
    rs.wr.set(ray.origin, Vec3f(d[0], d[1], d[2]));
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
