// Ray-primitive tests as free functions: the watertight ray-triangle test (Woop, Benthin,
// Wald 2013), a conservative ray-box slab test (Ize 2013), and triangle-box clipping for
// builders. Depends on core only. Everything here is allocation-free and never throws.
#pragma once

#include <cmath>
#include <cstdint>

#include "renderer/core/math.h"

namespace kdt {

/// a - b * c with the same rounding in every inlined copy: the compiler may contract
/// a - b * c into an FMA in one copy and not in another, which would let a vertex shared by
/// two triangles transform differently in each and open a crack (Woop et al. 2013, sec. 3).
inline float exact_fmsub(float a, float b, float c) {
#ifdef __FMA__
    return std::fma(-b, c, a);
#else
    return a - b * c;  // no FMA instruction, so no contraction either
#endif
}

/// Per-ray constants of the watertight test: the ray is translated to the origin, its
/// dominant axis becomes z and a shear maps the direction to (0, 0, 1). The origin is
/// kept in the permuted order (ox = origin[kx], ...) so the test indexes each vertex once.
struct WatertightRay {
    int kx = 0, ky = 1, kz = 2;
    float ox = 0.0f, oy = 0.0f, oz = 0.0f;
    float sx = 0.0f, sy = 0.0f, sz = 1.0f;

    WatertightRay() = default;
    /// dir must be finite and non-zero (callers reject other rays up front).
    WatertightRay(const Vec3f& org, const Vec3f& dir) { set(org, dir); }

    /// Sets the constants in place (a traversal's per-ray setup calls this rather than
    /// assigning a temporary, which compilers copy with a slow `rep movs`).
    void set(const Vec3f& org, const Vec3f& dir) {
        Vec3f a = glm::abs(dir);
        kz = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
        kx = kz == 2 ? 0 : kz + 1;
        ky = kx == 2 ? 0 : kx + 1;
        // Swap to keep the winding; the test is two-sided, but u, v keep their meaning.
        if (component(dir, kz) < 0.0f) {
            int tmp = kx;
            kx = ky;
            ky = tmp;
        }
        ox = component(org, kx);
        oy = component(org, ky);
        oz = component(org, kz);
        sx = component(dir, kx) / component(dir, kz);
        sy = component(dir, ky) / component(dir, kz);
        sz = 1.0f / component(dir, kz);
    }
};

/// Watertight, two-sided ray-triangle test (Woop, Benthin, Wald 2013). Edge functions are
/// evaluated in double, where the products of two floats are exact, so their signs are
/// exact: a ray through a shared edge or vertex of a closed mesh is reported by at least
/// one of the triangles. On a hit with tmin <= t <= tmax writes t and the barycentrics
/// u, v of vertices b and c and returns true; otherwise leaves them untouched. Degenerate
/// (zero-area or edge-on) triangles never hit.
inline bool intersect_triangle(const WatertightRay& r, const Vec3f& a, const Vec3f& b,
                               const Vec3f& c, float tmin, float tmax, float& t, float& u,
                               float& v) {
    const float az = component(a, r.kz) - r.oz;
    const float bz = component(b, r.kz) - r.oz;
    const float cz = component(c, r.kz) - r.oz;
    const float ax = exact_fmsub(component(a, r.kx) - r.ox, r.sx, az);
    const float ay = exact_fmsub(component(a, r.ky) - r.oy, r.sy, az);
    const float bx = exact_fmsub(component(b, r.kx) - r.ox, r.sx, bz);
    const float by = exact_fmsub(component(b, r.ky) - r.oy, r.sy, bz);
    const float cx = exact_fmsub(component(c, r.kx) - r.ox, r.sx, cz);
    const float cy = exact_fmsub(component(c, r.ky) - r.oy, r.sy, cz);
    // Products of floats are exact in double; one rounding per difference keeps the sign.
    const double U = double(cx) * double(by) - double(cy) * double(bx);
    const double V = double(ax) * double(cy) - double(ay) * double(cx);
    const double W = double(bx) * double(ay) - double(by) * double(ax);
    // Outside when the signs differ: (U < 0 || V < 0 || W < 0) && (U > 0 || V > 0 || W > 0),
    // written with min and max so it costs one (mostly taken) branch. U, V, W are finite.
    if (std::min(std::min(U, V), W) < 0.0 && std::max(std::max(U, V), W) > 0.0) return false;
    const double det = U + V + W;
    if (det == 0.0) return false;
    // Explicit FMAs: the same rounding in every inlined copy and in the SIMD packet test.
    const double T =
        std::fma(W, double(r.sz * cz), std::fma(V, double(r.sz * bz), U * double(r.sz * az)));
    const double inv_det = 1.0 / det;
    const float tt = float(T * inv_det);
    if (!(tt >= tmin && tt <= tmax)) return false;
    t = tt;
    u = float(V * inv_det);
    v = float(W * inv_det);
    return true;
}

/// Convenience overload for one-off tests (builds the per-ray constants each call).
/// Rays with a zero or non-finite direction never hit.
inline bool intersect_triangle(const Ray& ray, const Vec3f& a, const Vec3f& b, const Vec3f& c,
                               float& t, float& u, float& v) {
    if (!is_finite(ray.dir) || !is_finite(ray.origin) || ray.dir == Vec3f(0.0f)) return false;
    return intersect_triangle(WatertightRay(ray.origin, ray.dir), a, b, c, ray.tmin, ray.tmax, t, u,
                              v);
}

/// Relative slack of the conservative interval tests: a few ulps of the computed distances
/// (each of (p - o) * (1 / d) carries at most 3 roundings; Ize 2013 uses 1 + 2 gamma(3)).
inline constexpr float kIntervalSlack = 1.0f / (1 << 20);

/// Conservative slab test against a closed box: clips [t0, t1] (in: the ray interval) to
/// the box, widened by kIntervalSlack so rays through edges and corners are never lost.
/// inv_dir = 1 / dir per component. Zero direction components are handled exactly (the
/// ray hits iff its origin lies in the closed slab). Returns false on a miss.
inline bool intersect_box(const Vec3f& origin, const Vec3f& dir, const Vec3f& inv_dir,
                          const Bounds3f& box, float& t0, float& t1) {
    for (int k = 0; k < 3; ++k) {
        if (dir[k] == 0.0f) {
            if (!(origin[k] >= box.lower[k] && origin[k] <= box.upper[k])) return false;
            continue;
        }
        float tn = (box.lower[k] - origin[k]) * inv_dir[k];
        float tf = (box.upper[k] - origin[k]) * inv_dir[k];
        if (tn > tf) std::swap(tn, tf);
        tn -= kIntervalSlack * std::fabs(tn);
        tf += kIntervalSlack * std::fabs(tf);
        // Written so that a NaN never widens the interval.
        t0 = tn > t0 ? tn : t0;
        t1 = tf < t1 ? tf : t1;
    }
    return t0 <= t1;
}

/// Overload taking a Ray; the interval starts as [ray.tmin, ray.tmax].
inline bool intersect_box(const Ray& ray, const Bounds3f& box, float& t0, float& t1) {
    t0 = ray.tmin;
    t1 = ray.tmax;
    return intersect_box(ray.origin, ray.dir, 1.0f / ray.dir, box, t0, t1);
}

/// Bounds of the part of triangle (a, b, c) inside the closed box (Sutherland-Hodgman
/// clipping against the six planes, in double). Empty when they do not overlap. The result
/// is widened outward by one float ulp so it always contains the exact clipped triangle;
/// it never exceeds the box itself. For "perfect split" builders (Wald & Havran 2006).
Bounds3f clip_triangle_bounds(const Vec3f& a, const Vec3f& b, const Vec3f& c, const Bounds3f& box);

/// True if the closed triangle and the closed box overlap, decided by clip_triangle_bounds():
/// may say true for a near miss (within an ulp), never false for an overlap.
bool triangle_overlaps_box(const Vec3f& a, const Vec3f& b, const Vec3f& c, const Bounds3f& box);

}  // namespace kdt
