#include "renderer/geometry/intersect.h"

#include <array>

namespace kdt {
namespace {

using Vec3dd = glm::dvec3;

// A convex polygon of at most 3 + 6 vertices (each plane adds at most one).
struct Polygon {
    std::array<Vec3dd, 10> v;
    int n = 0;
};

// Keeps the part of `in` with sign * (p[axis] - pos) >= 0.
void clip_plane(const Polygon& in, Polygon& out, int axis, double pos, double sign) {
    out.n = 0;
    if (in.n == 0) return;
    for (int i = 0; i < in.n; ++i) {
        const Vec3dd& p = in.v[i];
        const Vec3dd& q = in.v[(i + 1) % in.n];
        const double dp = sign * (p[axis] - pos), dq = sign * (q[axis] - pos);
        if (dp >= 0.0) out.v[out.n++] = p;
        if ((dp > 0.0 && dq < 0.0) || (dp < 0.0 && dq > 0.0)) {
            const double s = dp / (dp - dq);
            Vec3dd x = p + s * (q - p);
            x[axis] = pos;  // exactly on the plane
            out.v[out.n++] = x;
        }
    }
}

}  // namespace

Bounds3f clip_triangle_bounds(const Vec3f& a, const Vec3f& b, const Vec3f& c, const Bounds3f& box) {
    Bounds3f result;
    if (box.empty()) return result;
    Polygon p0, p1;
    p0.v[0] = Vec3dd(a);
    p0.v[1] = Vec3dd(b);
    p0.v[2] = Vec3dd(c);
    p0.n = 3;
    for (int k = 0; k < 3; ++k) {
        clip_plane(p0, p1, k, double(box.lower[k]), 1.0);
        clip_plane(p1, p0, k, double(box.upper[k]), -1.0);
    }
    if (p0.n == 0) return result;
    Vec3dd lo(p0.v[0]), hi(p0.v[0]);
    for (int i = 1; i < p0.n; ++i) {
        lo = glm::min(lo, p0.v[i]);
        hi = glm::max(hi, p0.v[i]);
    }
    for (int k = 0; k < 3; ++k) {
        // Round outward (the double-to-float conversion rounds to nearest), then keep it
        // inside the box, which is exact.
        float l = float(lo[k]), h = float(hi[k]);
        if (double(l) > lo[k]) l = std::nextafter(l, -kInfinity);
        if (double(h) < hi[k]) h = std::nextafter(h, kInfinity);
        l = std::nextafter(l, -kInfinity);
        h = std::nextafter(h, kInfinity);
        result.lower[k] = std::max(l, box.lower[k]);
        result.upper[k] = std::min(h, box.upper[k]);
    }
    return result;
}

bool triangle_overlaps_box(const Vec3f& a, const Vec3f& b, const Vec3f& c, const Bounds3f& box) {
    return !clip_triangle_bounds(a, b, c, box).empty();
}

}  // namespace kdt
