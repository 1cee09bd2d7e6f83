// SIMD packet traversal (AVX2): eight coherent rays walk the kd-tree together (Wald 2004,
// "Realtime Ray Tracing and Interactive Global Illumination", ch. 7), one node fetch and one
// decision per packet instead of per ray, and the watertight triangle test runs on all
// eight lanes at once.
//
// Exactness: each lane takes exactly the steps of the single-ray traversal (traversal.cpp)
// and computes the same floating-point operations in the same order, so its hit is
// bitwise the single-ray hit. A lane visits a child exactly when the single-ray decision
// would; a node is visited when any active lane needs it, the other lanes are masked. The
// descent: visit_near = !(ts < lower_slack(t0)), visit_far = !(ts > upper_slack(t1)), the
// far child pushed with [max(ts, t0), t1] when both are visited, the near child taken with
// t1 = min(ts, t1). The pop: an entry is taken by a lane when lower_slack(t0) <= its
// closest hit, with t1 = min(t1, closest hit). The triangle test mirrors
// intersect_triangle() operation by operation (float shear with explicit FMAs, edge
// functions and t in double, explicit FMAs for t).
#include "renderer/accel/traversal_detail.h"

namespace kdt::detail {

#if !KDT_SIMD_TRAVERSAL

bool trace_packet(const TreeView&, const Ray*, int, bool, Hit*, uint8_t*, TraversalCounters*) {
    return false;
}

#else

namespace {

// Rays form a packet when their directions are within about 1.1 degrees of the first
// ray's and their origins within 1e-3 of the scene diagonal of its origin: camera rays
// through one pixel or neighbouring pixels, not diffuse bounces.
constexpr float kCoherentCos = 0.9998f;
constexpr float kCoherentOrigin = 1e-3f;

// Per-lane constants of a packet (structure of arrays) and the constants all lanes share.
struct Packet {
    __m256 org[3], inv[3];
    __m256 ox, oy, oz, sx, sy, sz;  // watertight test: permuted origin and shear
    __m256 tmin;
    int kx, ky, kz;
    uint32_t neg[3];
};

inline __m256 abs8(__m256 v) { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), v); }
inline __m256 lower_slack8(__m256 t) {
    // t - k |t|: k is a power of two, so the product is exact and an FMA rounds alike.
    return _mm256_fnmadd_ps(_mm256_set1_ps(kIntervalSlack), abs8(t), t);
}
inline __m256 upper_slack8(__m256 t) {
    return _mm256_fmadd_ps(_mm256_set1_ps(kIntervalSlack), abs8(t), t);
}

// Cheap pre-check on the raw rays (no setup): nearly parallel, nearby origins.
bool roughly_coherent(const Ray* rays, int m, const Bounds3f& bounds) {
    const Vec3f d0 = rays[0].dir, o0 = rays[0].origin;
    const float l0 = glm::dot(d0, d0);
    const Vec3f ext = bounds.extent();
    const float max_dist2 = kCoherentOrigin * kCoherentOrigin * glm::dot(ext, ext);
    for (int i = 1; i < m; ++i) {
        const Vec3f d = rays[i].dir;
        const float c = glm::dot(d, d0);
        // Written so that NaN fails: such rays go the single-ray way.
        if (!(c > 0.0f && c * c >= kCoherentCos * kCoherentCos * l0 * glm::dot(d, d))) return false;
        const Vec3f o = rays[i].origin - o0;
        if (!(glm::dot(o, o) <= max_dist2)) return false;
    }
    return true;
}

// Lanes 4h .. 4h + 3 of v widened to double.
inline __m256d half_pd(__m256 v, int h) {
    return _mm256_cvtps_pd(h == 0 ? _mm256_castps256_ps128(v) : _mm256_extractf128_ps(v, 1));
}

// The watertight test of intersect_triangle() on eight lanes. Returns the mask of lanes in
// `active` that hit in [tmin, best_t], with their t, u, v.
inline int intersect8(const Packet& p, const Vec3f& a, const Vec3f& b, const Vec3f& c, int active,
                      __m256 best_t, __m256& t_out, __m256& u_out, __m256& v_out) {
    const __m256 az = _mm256_sub_ps(_mm256_set1_ps(component(a, p.kz)), p.oz);
    const __m256 bz = _mm256_sub_ps(_mm256_set1_ps(component(b, p.kz)), p.oz);
    const __m256 cz = _mm256_sub_ps(_mm256_set1_ps(component(c, p.kz)), p.oz);
    // exact_fmsub(x - o, s, z) = fma(-s, z, x - o)
    auto shear = [](float x, __m256 o, __m256 s, __m256 z) {
        return _mm256_fnmadd_ps(s, z, _mm256_sub_ps(_mm256_set1_ps(x), o));
    };
    const __m256 ax = shear(component(a, p.kx), p.ox, p.sx, az);
    const __m256 ay = shear(component(a, p.ky), p.oy, p.sy, az);
    const __m256 bx = shear(component(b, p.kx), p.ox, p.sx, bz);
    const __m256 by = shear(component(b, p.ky), p.oy, p.sy, bz);
    const __m256 cx = shear(component(c, p.kx), p.ox, p.sx, cz);
    const __m256 cy = shear(component(c, p.ky), p.oy, p.sy, cz);
    // Edge functions and t, u, v in double, four lanes per half.
    Edges4 e[2];
    int pass = 0;
    for (int h = 0; h < 2; ++h) {
        auto half = [h](__m256 v) { return half_pd(v, h); };
        pass |= edges4(half(ax), half(ay), half(bx), half(by), half(cx), half(cy), e[h]) << (4 * h);
    }
    pass &= active;
    if (!pass) return 0;
    __m128 t4[2], u4[2], v4[2];
    int ok = 0;
    for (int h = 0; h < 2; ++h) {
        auto half = [h](__m256 v) { return half_pd(v, h); };
        ok |= solve4(e[h], half(_mm256_mul_ps(p.sz, az)), half(_mm256_mul_ps(p.sz, bz)),
                     half(_mm256_mul_ps(p.sz, cz)), t4[h], u4[h], v4[h])
              << (4 * h);
    }
    t_out = _mm256_set_m128(t4[1], t4[0]);
    u_out = _mm256_set_m128(u4[1], u4[0]);
    v_out = _mm256_set_m128(v4[1], v4[0]);
    const __m256 in_range = _mm256_and_ps(_mm256_cmp_ps(t_out, p.tmin, _CMP_GE_OQ),
                                          _mm256_cmp_ps(t_out, best_t, _CMP_LE_OQ));
    return pass & ok & _mm256_movemask_ps(in_range);
}

inline __m256 lanes_mask(int m) {
    const __m256i bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    return _mm256_castsi256_ps(
        _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(m), bits), bits));
}

template <bool kAnyHit>
void run_packet(const TreeView& tv, const Packet& p, int active, __m256 t0, __m256 t1,
                __m256& best_t, __m256& best_u, __m256& best_v, __m256i& best_prim, int& hit_lanes,
                uint64_t& visited, uint64_t& tested) {
    alignas(32) __m256 stack_t0[kStackSize];
    alignas(32) __m256 stack_t1[kStackSize];
    uint32_t stack_node[kStackSize];
    int stack_mask[kStackSize];
    int sp = 0;
    uint32_t idx = 0;
    int done = 0;  // any-hit lanes that are finished
    for (;;) {
        KdNode node = tv.nodes[idx];
        visited += uint64_t(__builtin_popcount(unsigned(active)));
        while (!node.is_leaf()) {
            const int axis = node.axis();
            const __m256 ts =
                _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(node.split), p.org[axis]), p.inv[axis]);
            const int vn = _mm256_movemask_ps(_mm256_cmp_ps(ts, lower_slack8(t0), _CMP_NLT_UQ));
            const int vf = _mm256_movemask_ps(_mm256_cmp_ps(ts, upper_slack8(t1), _CMP_NGT_UQ));
            const uint32_t near_child = node.child() + p.neg[axis];
            const uint32_t far_child = node.child() + 1u - p.neg[axis];
            // As in the single-ray descent, empty children are not entered.
            const uint32_t empty = node.empty_children();
            const int near_lanes = ((empty >> p.neg[axis]) & 1u) ? 0 : active & vn;
            const int far_lanes = ((empty >> (1u - p.neg[axis])) & 1u) ? 0 : active & (vf | ~vn);
            if (!far_lanes && !near_lanes) {
                node = KdNode{};  // no lane enters a child: straight to the stack
                break;
            } else if (!far_lanes) {
                t1 = _mm256_min_ps(ts, t1);
                active = near_lanes;
                idx = near_child;
            } else if (!near_lanes) {
                t0 = _mm256_max_ps(ts, t0);
                active = far_lanes;
                idx = far_child;
            } else {
                stack_node[sp] = far_child;
                stack_mask[sp] = far_lanes;
                stack_t0[sp] = _mm256_max_ps(ts, t0);
                stack_t1[sp] = t1;
                ++sp;
                t1 = _mm256_min_ps(ts, t1);
                active = near_lanes;
                idx = near_child;
            }
            node = tv.nodes[idx];
            visited += uint64_t(__builtin_popcount(unsigned(active)));
        }
        const uint32_t count = node.count();
        const uint32_t* ids = tv.indices + node.first;
        for (uint32_t i = 0; i < count && active; ++i) {
            tested += uint64_t(__builtin_popcount(unsigned(active)));
            const uint32_t prim = ids[i];
            const Vec3u tri = tv.triangle_of(node.first + i);
            __m256 t, u, v;
            const int hit = intersect8(p, tv.positions[tri.x], tv.positions[tri.y],
                                       tv.positions[tri.z], active, best_t, t, u, v);
            if (!hit) continue;
            if (kAnyHit) {
                done |= hit;
                active &= ~hit;
                continue;
            }
            const __m256 m = lanes_mask(hit);
            best_t = _mm256_blendv_ps(best_t, t, m);
            best_u = _mm256_blendv_ps(best_u, u, m);
            best_v = _mm256_blendv_ps(best_v, v, m);
            best_prim = _mm256_castps_si256(
                _mm256_blendv_ps(_mm256_castsi256_ps(best_prim),
                                 _mm256_castsi256_ps(_mm256_set1_epi32(int(prim))), m));
        }
        // Next entry that some lane still needs.
        bool next = false;
        while (sp > 0) {
            --sp;
            const __m256 s0 = stack_t0[sp];
            const int lanes =
                stack_mask[sp] & ~done &
                _mm256_movemask_ps(_mm256_cmp_ps(lower_slack8(s0), best_t, _CMP_LE_OQ));
            if (!lanes) continue;
            idx = stack_node[sp];
            t0 = s0;
            t1 = _mm256_min_ps(best_t, stack_t1[sp]);
            active = lanes;
            next = true;
            break;
        }
        if (!next) break;
    }
    hit_lanes = done;
}

// Eight consecutive rays (struct Ray is 32 bytes: origin, tmin, dir, tmax) as eight
// vectors: ox, oy, oz, tmin, dx, dy, dz, tmax.
inline void load_transposed(const Ray* rays, __m256 out[8]) {
    static_assert(sizeof(Ray) == 8 * sizeof(float), "Ray is origin, tmin, dir, tmax");
    __m256 r[8], t[8], u[8];
    const float* base = reinterpret_cast<const float*>(rays);
    for (int i = 0; i < 8; ++i) r[i] = _mm256_loadu_ps(base + 8 * i);
    for (int i = 0; i < 8; i += 2) {
        t[i] = _mm256_unpacklo_ps(r[i], r[i + 1]);
        t[i + 1] = _mm256_unpackhi_ps(r[i], r[i + 1]);
    }
    for (int i = 0; i < 8; i += 4) {
        u[i] = _mm256_shuffle_ps(t[i], t[i + 2], 0x44);
        u[i + 1] = _mm256_shuffle_ps(t[i], t[i + 2], 0xee);
        u[i + 2] = _mm256_shuffle_ps(t[i + 1], t[i + 3], 0x44);
        u[i + 3] = _mm256_shuffle_ps(t[i + 1], t[i + 3], 0xee);
    }
    for (int i = 0; i < 4; ++i) {
        out[i] = _mm256_permute2f128_ps(u[i], u[i + 4], 0x20);
        out[i + 4] = _mm256_permute2f128_ps(u[i], u[i + 4], 0x31);
    }
}

// setup_ray() on eight lanes at once, operation by operation, for a full packet of rays.
// Returns false when the packet must go the single-ray way (a lane needs the rescaling of
// extreme directions, the lanes differ in direction signs or dominant axis, or they are
// not coherent); otherwise fills p, the lanes' intervals and tmax, and `active` (the lanes
// whose setup succeeded).
bool setup_packet8(const Ray* rays, const Bounds3f& bounds, Packet& p, __m256& t0, __m256& t1,
                   __m256& tmax, int& active) {
    __m256 v[8];
    load_transposed(rays, v);
    __m256 org[3] = {v[0], v[1], v[2]}, d[3] = {v[4], v[5], v[6]};
    const __m256 inf = _mm256_set1_ps(kInfinity), zero = _mm256_setzero_ps();
    // Finite origin and direction, tmin <= tmax (neither NaN).
    __m256 ok = _mm256_cmp_ps(v[3], v[7], _CMP_LE_OQ);
    for (int k = 0; k < 3; ++k) {
        ok = _mm256_and_ps(ok, _mm256_cmp_ps(abs8(org[k]), inf, _CMP_LT_OQ));
        ok = _mm256_and_ps(ok, _mm256_cmp_ps(abs8(d[k]), inf, _CMP_LT_OQ));
    }
    const __m256 mag = _mm256_max_ps(abs8(d[0]), _mm256_max_ps(abs8(d[1]), abs8(d[2])));
    ok = _mm256_and_ps(ok, _mm256_cmp_ps(mag, zero, _CMP_GT_OQ));
    int valid = _mm256_movemask_ps(ok);
    if (!valid) {
        active = 0;
        return true;
    }
    const __m256 extreme = _mm256_or_ps(_mm256_cmp_ps(mag, _mm256_set1_ps(0x1p-40f), _CMP_LT_OQ),
                                        _mm256_cmp_ps(mag, _mm256_set1_ps(0x1p40f), _CMP_GT_OQ));
    if (valid & _mm256_movemask_ps(extreme)) return false;
    // Coherence against the first valid lane.
    const __m256i ref = _mm256_set1_epi32(__builtin_ctz(unsigned(valid)));
    __m256 rd[3], ro[3];
    for (int k = 0; k < 3; ++k) {
        rd[k] = _mm256_permutevar8x32_ps(d[k], ref);
        ro[k] = _mm256_permutevar8x32_ps(org[k], ref);
    }
    auto dot3 = [](const __m256* a, const __m256* b) {
        return _mm256_fmadd_ps(a[2], b[2], _mm256_fmadd_ps(a[1], b[1], _mm256_mul_ps(a[0], b[0])));
    };
    const __m256 c = dot3(d, rd);
    const __m256 need = _mm256_mul_ps(_mm256_set1_ps(kCoherentCos * kCoherentCos),
                                      _mm256_mul_ps(dot3(rd, rd), dot3(d, d)));
    __m256 coherent = _mm256_and_ps(_mm256_cmp_ps(c, zero, _CMP_GT_OQ),
                                    _mm256_cmp_ps(_mm256_mul_ps(c, c), need, _CMP_GE_OQ));
    __m256 od[3];
    for (int k = 0; k < 3; ++k) od[k] = _mm256_sub_ps(org[k], ro[k]);
    const Vec3f ext = bounds.extent();
    const float max_dist2 = kCoherentOrigin * kCoherentOrigin * glm::dot(ext, ext);
    coherent =
        _mm256_and_ps(coherent, _mm256_cmp_ps(dot3(od, od), _mm256_set1_ps(max_dist2), _CMP_LE_OQ));
    if ((_mm256_movemask_ps(coherent) & valid) != valid) return false;
    // Zero components become -0 (so 1/d = -inf and the sign agree); common signs.
    for (int k = 0; k < 3; ++k) {
        d[k] = _mm256_blendv_ps(d[k], _mm256_set1_ps(-0.0f), _mm256_cmp_ps(d[k], zero, _CMP_EQ_OQ));
        const int signs = _mm256_movemask_ps(d[k]) & valid;
        if (signs != 0 && signs != valid) return false;
        p.neg[k] = signs ? 1u : 0u;
        p.org[k] = org[k];
        p.inv[k] = _mm256_div_ps(_mm256_set1_ps(1.0f), d[k]);
    }
    // Slab test against the root box, as setup_ray(): std::min(a, b) = b < a ? b : a.
    t0 = v[3];
    t1 = v[7];
    p.tmin = v[3];
    tmax = v[7];
    const float lower[3] = {bounds.lower.x, bounds.lower.y, bounds.lower.z};
    const float upper[3] = {bounds.upper.x, bounds.upper.y, bounds.upper.z};
    for (int k = 0; k < 3; ++k) {
        const __m256 lo = _mm256_set1_ps(lower[k]), hi = _mm256_set1_ps(upper[k]);
        const __m256 is_zero = _mm256_cmp_ps(d[k], zero, _CMP_EQ_OQ);
        const __m256 in_slab = _mm256_and_ps(_mm256_cmp_ps(org[k], lo, _CMP_GE_OQ),
                                             _mm256_cmp_ps(org[k], hi, _CMP_LE_OQ));
        ok = _mm256_and_ps(ok, _mm256_or_ps(_mm256_andnot_ps(is_zero, ok), in_slab));
        const __m256 a = _mm256_mul_ps(_mm256_sub_ps(lo, org[k]), p.inv[k]);
        const __m256 b = _mm256_mul_ps(_mm256_sub_ps(hi, org[k]), p.inv[k]);
        const __m256 mn = _mm256_blendv_ps(a, b, _mm256_cmp_ps(b, a, _CMP_LT_OQ));
        const __m256 mx = _mm256_blendv_ps(a, b, _mm256_cmp_ps(a, b, _CMP_LT_OQ));
        const __m256 tn = lower_slack8(mn), tf = upper_slack8(mx);
        t0 = _mm256_blendv_ps(_mm256_max_ps(tn, t0), t0, is_zero);
        t1 = _mm256_blendv_ps(_mm256_min_ps(tf, t1), t1, is_zero);
    }
    ok = _mm256_and_ps(ok, _mm256_cmp_ps(t0, t1, _CMP_LE_OQ));
    active = _mm256_movemask_ps(ok);
    if (!active) return true;
    // The watertight test's permutation: kz = the dominant axis (ties as WatertightRay).
    const __m256 ax = abs8(d[0]), ay = abs8(d[1]), az = abs8(d[2]);
    const int xy = _mm256_movemask_ps(_mm256_cmp_ps(ax, ay, _CMP_GE_OQ));
    const int xz = _mm256_movemask_ps(_mm256_cmp_ps(ax, az, _CMP_GE_OQ));
    const int yz = _mm256_movemask_ps(_mm256_cmp_ps(ay, az, _CMP_GE_OQ));
    const int z0 = xy & xz, z1 = ~xy & yz;
    int kz;
    if ((z0 & active) == active)
        kz = 0;
    else if ((z1 & active) == active)
        kz = 1;
    else if (((z0 | z1) & active) == 0)
        kz = 2;
    else
        return false;
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    if (p.neg[kz]) std::swap(kx, ky);
    p.kx = kx;
    p.ky = ky;
    p.kz = kz;
    p.ox = org[kx];
    p.oy = org[ky];
    p.oz = org[kz];
    p.sx = _mm256_div_ps(d[kx], d[kz]);
    p.sy = _mm256_div_ps(d[ky], d[kz]);
    p.sz = _mm256_div_ps(_mm256_set1_ps(1.0f), d[kz]);
    return true;
}

// Setup of a partial packet (m < 8 rays, the end of a batch) lane by lane with
// setup_ray(); false when the rays are not coherent or differ in signs or dominant axis.
bool setup_packet_lanes(const TreeView& tv, const Ray* rays, int m, Packet& p, __m256& t0v,
                        __m256& t1v, __m256& tmaxv, int& active, float* t_scale) {
    if (!roughly_coherent(rays, m, tv.bounds)) return false;
    alignas(32) float org[3][8], inv[3][8], wo[3][8], sh[3][8], tmin[8], t0[8], t1[8], tmax[8];
    active = 0;
    int ref = -1;
    RayState first;
    for (int i = 0; i < kPacketSize; ++i) {
        RayState rs;
        float a = 0.0f, b = -1.0f, tm = 0.0f;
        const bool ok = i < m && setup_ray(rays[i], tv.bounds, rs, a, b, tm);
        if (ok) {
            if (ref < 0) {
                ref = i;
                first = rs;
            } else if (rs.wr.kx != first.wr.kx || rs.wr.ky != first.wr.ky ||
                       rs.wr.kz != first.wr.kz || rs.neg_bits != first.neg_bits) {
                return false;  // the lanes would need different child orders or shears
            }
            active |= 1 << i;
        }
        for (int k = 0; k < 3; ++k) {
            org[k][i] = rs.org[k];
            inv[k][i] = rs.inv[k];
        }
        wo[0][i] = rs.wr.ox;
        wo[1][i] = rs.wr.oy;
        wo[2][i] = rs.wr.oz;
        sh[0][i] = rs.wr.sx;
        sh[1][i] = rs.wr.sy;
        sh[2][i] = rs.wr.sz;
        tmin[i] = rs.tmin;
        t0[i] = a;
        t1[i] = b;
        tmax[i] = tm;
        t_scale[i] = rs.t_scale;
    }
    for (int k = 0; k < 3; ++k) {
        p.org[k] = _mm256_load_ps(org[k]);
        p.inv[k] = _mm256_load_ps(inv[k]);
        p.neg[k] = first.neg(k);
    }
    p.ox = _mm256_load_ps(wo[0]);
    p.oy = _mm256_load_ps(wo[1]);
    p.oz = _mm256_load_ps(wo[2]);
    p.sx = _mm256_load_ps(sh[0]);
    p.sy = _mm256_load_ps(sh[1]);
    p.sz = _mm256_load_ps(sh[2]);
    p.tmin = _mm256_load_ps(tmin);
    p.kx = first.wr.kx;
    p.ky = first.wr.ky;
    p.kz = first.wr.kz;
    t0v = _mm256_load_ps(t0);
    t1v = _mm256_load_ps(t1);
    tmaxv = _mm256_load_ps(tmax);
    return true;
}

}  // namespace

bool trace_packet(const TreeView& tv, const Ray* rays, int m, bool any_hit, Hit* hits,
                  uint8_t* occluded, TraversalCounters* counters) {
    if (m < 2 || tv.bounds.empty()) return false;
    Packet p;
    __m256 t0, t1, tmax;
    int active = 0;
    float t_scale[8] = {1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f};
    if (m == kPacketSize) {
        if (!setup_packet8(rays, tv.bounds, p, t0, t1, tmax, active)) return false;
    } else if (!setup_packet_lanes(tv, rays, m, p, t0, t1, tmax, active, t_scale)) {
        return false;
    }
    if (!active) return true;  // every ray misses the root box (outputs are misses)
    __m256 best_t = tmax, best_u = _mm256_setzero_ps(), best_v = _mm256_setzero_ps();
    __m256i best_prim = _mm256_set1_epi32(int(Hit::kNoHit));
    int hit_lanes = 0;
    uint64_t visited = 0, tested = 0;
    if (any_hit)
        run_packet<true>(tv, p, active, t0, t1, best_t, best_u, best_v, best_prim, hit_lanes,
                         visited, tested);
    else
        run_packet<false>(tv, p, active, t0, t1, best_t, best_u, best_v, best_prim, hit_lanes,
                          visited, tested);
    if (counters) {
        counters->nodes_visited += visited;
        counters->triangles_tested += tested;
    }
    if (any_hit) {
        for (int i = 0; i < m; ++i) occluded[i] = (hit_lanes >> i) & 1;
        return true;
    }
    alignas(32) float bt[8], bu[8], bv[8];
    alignas(32) uint32_t bp[8];
    _mm256_store_ps(bt, best_t);
    _mm256_store_ps(bu, best_u);
    _mm256_store_ps(bv, best_v);
    _mm256_store_si256(reinterpret_cast<__m256i*>(bp), best_prim);
    for (int i = 0; i < m; ++i) {
        if (bp[i] == Hit::kNoHit) continue;
        hits[i].t = bt[i] * t_scale[i];
        hits[i].u = bu[i];
        hits[i].v = bv[i];
        hits[i].prim = bp[i];
    }
    return true;
}

#endif  // KDT_SIMD_TRAVERSAL

}  // namespace kdt::detail
