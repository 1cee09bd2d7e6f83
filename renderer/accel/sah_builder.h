// Internals of the SAH kd-tree builder (Wald & Havran 2006) exposed for tests and tuning:
// the phase thresholds and the conservative triangle-box clipping it relies on.
// Depends on core, geometry and the builder interface.
#pragma once

#include <cstdint>

#include "renderer/accel/builder.h"

namespace kdt {

/// Knobs of the SAH builder that are not part of KdTreeParams: where the binned top levels
/// hand over to the exact event sweep, and how the work is split into OpenMP tasks.
struct SahTuning {
    uint32_t sweep_threshold = 2048;  ///< nodes with more references are split by binned SAH
    int bins = 64;                    ///< bins per axis in the binned phase (>= 2)
    uint32_t task_threshold = 8192;   ///< binned nodes with more references spawn a task
    /// Leaf references the whole tree may hold per triangle (the reference budget,
    /// sah_internal.h). No scanned mesh comes near it at any depth the automatic limit
    /// allows; it stops meshes of large overlapping triangles from doubling their
    /// references at every level.
    double ref_budget_per_triangle = 256.0;
};

/// build_sah_tree() with explicit tuning (tests use tiny thresholds to exercise both phases)
/// and `cancel` as for build_kdtree().
KdBuildOutput build_sah_tree(const TriangleMesh& mesh, const KdTreeParams& params,
                             const SahTuning& tuning, const std::atomic<bool>* cancel = nullptr);

/// Conservative bounds of triangle (a, b, c) clipped to the closed box [lower, upper]
/// (Sutherland-Hodgman in double, rounded outward to float, intersected with the box).
/// Returns false when the triangle does not touch the box.
bool clip_triangle_to_box(const Vec3f& a, const Vec3f& b, const Vec3f& c, const Bounds3f& box,
                          Bounds3f& clipped);

}  // namespace kdt
