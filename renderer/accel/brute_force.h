// The reference the kd-tree is checked against: every triangle, the same watertight test.
// Used by the tests and by `kdtrace bench kdtree`; never by rendering.
#pragma once

#include "renderer/accel/kdtree.h"
#include "renderer/geometry/mesh.h"

namespace kdt {

/// Closest hit over all triangles with the same watertight test the tree uses. Non-finite
/// rays and a zero direction miss.
Hit brute_force_hit(const TriangleMesh& mesh, const Ray& ray);

}  // namespace kdt
