// Polygon triangulation for the mesh readers: a convex polygon is fanned from its first
// corner, any other is ear-clipped in the plane of its Newell normal. Depends on core only.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "renderer/core/math.h"

namespace kdt {

/// Scratch arrays of triangulate_polygon, kept by the caller across polygons so that a run of
/// polygons allocates only when one is bigger than any before it.
struct PolygonScratch {
    std::vector<double> x, y;          // corners in the polygon's plane
    std::vector<uint32_t> prev, next;  // the ring of corners not yet clipped
    std::vector<uint8_t> reflex;       // corners whose turn does not agree (or is 0)
};

/// Steps of ear clipping (ear tests, laps) one polygon may take before the rest of
/// it is fanned: bounds the time a hostile polygon of millions of corners costs.
inline constexpr uint64_t kEarClipBudget = uint64_t(1) << 22;

/// Whether the quad (a, b, c, d) is convex: no turn disagrees with its Newell normal, the
/// cross product of its diagonals (a quad's edges turn once around when none disagrees).
/// A quad without area counts as convex. Inline: the readers test every quad with it before
/// anything else, and triangulate_polygon decides quads by it too.
inline bool quad_is_convex(const Vec3f& a, const Vec3f& b, const Vec3f& c, const Vec3f& d) {
    const Vec3d pa(a), pb(b), pc(c), pd(d);
    const Vec3d n = glm::cross(pc - pa, pd - pb);
    const Vec3d ab = pb - pa, bc = pc - pb, cd = pd - pc, da = pa - pd;
    return glm::dot(glm::cross(da, ab), n) >= 0.0 && glm::dot(glm::cross(ab, bc), n) >= 0.0 &&
           glm::dot(glm::cross(bc, cd), n) >= 0.0 && glm::dot(glm::cross(cd, da), n) >= 0.0;
}

/// Splits the polygon with corners `corners` (n >= 3, in order) into exactly n - 2 triangles
/// written to out[0 .. n - 2), as corner numbers 0 .. n - 1, each in the polygon's winding.
/// A convex polygon (every turn agrees with the Newell normal or is 0, and its edges turn
/// once around; quad_is_convex for a quad) gives the fan (0, k, k + 1), k = 1 .. n - 2, as
/// do one without area and one with a non-finite corner. Any other is ear-clipped (Eberly,
/// "Triangulation by Ear Clipping") in the plane of its Newell normal, so the triangles cover the
/// polygon exactly when it is simple; corners on a line are clipped as zero-area triangles. What is
/// left when no ear is found (a self-intersecting or badly non-planar polygon) or after
/// kEarClipBudget ear tests is fanned from its lowest remaining corner. Never throws but
/// std::bad_alloc (scratch growth).
/// Returns true when the result is the fan of the whole polygon.
bool triangulate_polygon(std::span<const Vec3f> corners, Vec3u* out, PolygonScratch& scratch);

}  // namespace kdt
