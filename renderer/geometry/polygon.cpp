#include "renderer/geometry/polygon.h"

#include <algorithm>
#include <cmath>

namespace kdt {
namespace {

void fan(uint32_t n, Vec3u* out) {
    for (uint32_t k = 1; k + 1 < n; ++k) out[k - 1] = Vec3u(0, k, k + 1);
}

// Newell's normal: twice the polygon's vector area, pointing to the side from which the
// corners run counter-clockwise. Summed about corner 0, which keeps it accurate for a small
// polygon far from the origin.
Vec3d newell_normal(std::span<const Vec3f> c) {
    const Vec3d o(c[0]);
    Vec3d sum(0.0);
    Vec3d a = Vec3d(c[1]) - o;
    for (size_t k = 2; k < c.size(); ++k) {
        const Vec3d b = Vec3d(c[k]) - o;
        sum += glm::cross(a, b);
        a = b;
    }
    return sum;
}

// A unit vector perpendicular to n (n non-zero).
Vec3d perpendicular(const Vec3d& n) {
    const Vec3d m = glm::abs(n);
    Vec3d axis(0.0);
    axis[m.x <= m.y && m.x <= m.z ? 0 : (m.y <= m.z ? 1 : 2)] = 1.0;
    return glm::normalize(glm::cross(n, axis));
}

// Convex seen along n: no turn disagrees with n, and the edge directions go around once, so
// their component along a direction u in the plane changes sign at most twice (a pentagram
// turns the same way at every corner but goes around twice: four changes).
// Edges of no length (repeated corners) are skipped: the turn across one is the turn from
// the edge before it to the edge after it.
bool is_convex(std::span<const Vec3f> c, const Vec3d& n) {
    const size_t count = c.size();
    const Vec3d u = perpendicular(n);
    auto edge = [&](size_t i) { return Vec3d(c[i + 1 == count ? 0 : i + 1]) - Vec3d(c[i]); };
    Vec3d e_prev(0.0);
    for (size_t i = count; i-- > 0 && e_prev == Vec3d(0.0);) e_prev = edge(i);
    int first = 0, last = 0, changes = 0;
    for (size_t i = 0; i < count; ++i) {
        const Vec3d e = edge(i);
        if (e == Vec3d(0.0)) continue;
        if (glm::dot(glm::cross(e_prev, e), n) < 0.0) return false;
        const double d = glm::dot(e, u);
        const int s = (d > 0.0) - (d < 0.0);
        if (s != 0) {
            if (first == 0)
                first = s;
            else if (s != last)
                ++changes;
            last = s;
        }
        e_prev = e;
    }
    if (first != last) ++changes;
    return changes <= 2;
}

// Ear clipping of the polygon projected onto the plane of n (unit (u, v, n) right-handed,
// so the polygon runs counter-clockwise there). Each clip emits (previous, ear, next) in
// ring order, keeping the winding; an ear is a convex corner whose triangle holds no
// reflex corner (inside or on its boundary). Only reflex corners can lie in a convex
// corner's triangle when the polygon is simple, so only they are tested.
void ear_clip(std::span<const Vec3f> c, const Vec3d& normal, Vec3u* out, PolygonScratch& s) {
    const uint32_t n = uint32_t(c.size());
    const Vec3d nn = glm::normalize(normal);
    const Vec3d u = perpendicular(nn);
    const Vec3d v = glm::cross(nn, u);
    const Vec3d o(c[0]);
    s.x.resize(n);
    s.y.resize(n);
    s.prev.resize(n);
    s.next.resize(n);
    s.reflex.resize(n);
    double* x = s.x.data();
    double* y = s.y.data();
    uint32_t* prev = s.prev.data();
    uint32_t* next = s.next.data();
    uint8_t* reflex = s.reflex.data();
    for (uint32_t i = 0; i < n; ++i) {
        const Vec3d d = Vec3d(c[i]) - o;
        x[i] = glm::dot(d, u);
        y[i] = glm::dot(d, v);
        prev[i] = i == 0 ? n - 1 : i - 1;
        next[i] = i + 1 == n ? 0 : i + 1;
    }
    // Twice the signed area of (a, b, p): positive when p lies left of a -> b.
    auto area2 = [&](uint32_t a, uint32_t b, uint32_t p) {
        return (x[b] - x[a]) * (y[p] - y[a]) - (y[b] - y[a]) * (x[p] - x[a]);
    };
    auto turn = [&](uint32_t b) { return area2(prev[b], b, next[b]); };
    for (uint32_t i = 0; i < n; ++i) reflex[i] = !(turn(i) > 0.0);

    // Every step below spends one unit: laps, ear tests and the search for a corner without
    // area alike, so no input can make the loop run longer than the budget.
    uint64_t budget = kEarClipBudget;
    bool out_of_budget = false;
    auto spend = [&] {
        if (budget == 0) {
            out_of_budget = true;
            return false;
        }
        --budget;
        return true;
    };
    auto same_point = [&](uint32_t p, uint32_t q) { return x[p] == x[q] && y[p] == y[q]; };
    auto is_ear = [&](uint32_t b) {
        if (reflex[b]) return false;
        const uint32_t a = prev[b], e = next[b];
        for (uint32_t p = next[e]; p != a; p = next[p]) {
            if (!spend()) return false;
            if (!reflex[p] || same_point(p, a) || same_point(p, b) || same_point(p, e)) continue;
            if (area2(a, b, p) >= 0.0 && area2(b, e, p) >= 0.0 && area2(e, a, p) >= 0.0)
                return false;
        }
        return true;
    };
    uint32_t t = 0, remaining = n;
    auto clip = [&](uint32_t b) {
        const uint32_t a = prev[b], e = next[b];
        out[t++] = Vec3u(a, b, e);
        next[a] = e;
        prev[e] = a;
        --remaining;
        reflex[a] = !(turn(a) > 0.0);
        reflex[e] = !(turn(e) > 0.0);
    };

    uint32_t ear = 0, stop = 0;
    while (remaining > 3 && spend()) {
        if (is_ear(ear)) {
            const uint32_t e = next[ear];
            clip(ear);
            ear = stop = next[e];
            continue;
        }
        ear = next[ear];
        if (ear != stop) continue;
        // A whole lap without an ear: clip a corner without area (on a line through its
        // neighbours, or repeating one), which leaves the rest's area as it was.
        uint32_t b = ear;
        do {
            if (turn(b) == 0.0 || !spend()) break;
            b = next[b];
        } while (b != ear);
        if (out_of_budget || turn(b) != 0.0) break;  // none: self-intersecting or non-planar
        const uint32_t e = next[b];
        clip(b);
        ear = stop = e;
    }
    // Fan what is left from its lowest corner (the last triangle when all went well).
    uint32_t first = ear;
    for (uint32_t p = next[ear]; p != ear; p = next[p]) first = std::min(first, p);
    for (uint32_t b = next[first]; next[b] != first; b = next[b])
        out[t++] = Vec3u(first, b, next[b]);
}

}  // namespace

bool triangulate_polygon(std::span<const Vec3f> corners, Vec3u* out, PolygonScratch& scratch) {
    const uint32_t n = uint32_t(corners.size());
    if (n <= 3) {
        fan(n, out);
        return true;
    }
    if (n == 4 && quad_is_convex(corners[0], corners[1], corners[2], corners[3])) {
        fan(n, out);
        return true;
    }
    const Vec3d normal = newell_normal(corners);
    const double len2 = glm::dot(normal, normal);
    // No area, or a non-finite corner: no plane to clip in.
    if (!(len2 > 0.0) || !std::isfinite(len2) || (n > 4 && is_convex(corners, normal))) {
        fan(n, out);
        return true;
    }
    ear_clip(corners, normal, out, scratch);
    return false;
}

}  // namespace kdt
