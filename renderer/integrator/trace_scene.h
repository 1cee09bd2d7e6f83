// What the path tracer reads: world-space triangles with per-triangle instance ids,
// per-vertex shading normals, materials, the kd-tree and the environment light.
// Immutable once built and shared by all threads. Built by renderer/render/snapshot.*.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "renderer/accel/kdtree.h"
#include "renderer/light/distribution.h"
#include "renderer/light/environment.h"
#include "renderer/material/material.h"

namespace kdt {

/// Per-instance shading data: its material and flat or smooth shading.
struct ShadingInstance {
    Material material;
    bool smooth = true;  ///< interpolate TraceScene::normals (else the geometric normal)
};

/// The emissive triangles, for next-event estimation of area lights: a triangle is picked in
/// proportion to its area times its mean emitted radiance, then a uniform point on it, so the
/// area density of a point on triangle i is mean(emission_i) / total.
struct EmitterTable {
    std::vector<uint32_t> triangles;  ///< emissive triangles of non-zero, finite area
    Distribution1D dist;              ///< over `triangles`
    double total = 0.0;               ///< sum of area * mean(emission)
    bool empty() const { return triangles.empty() || !(total > 0.0); }
};

/// triangle_instance as runs of consecutive triangles (merged meshes are one run per
/// instance), so that shading finds a hit's instance in a few cached words instead of a
/// likely cache miss in a 4-bytes-per-triangle array.
struct InstanceRuns {
    static constexpr size_t kMaxRuns = 8;  ///< more runs: look up triangle_instance instead
    std::vector<uint32_t> first;           ///< first triangle of each run, ascending from 0
    std::vector<uint32_t> instance;        ///< the instance of each run
};

struct TraceScene {
    std::shared_ptr<const TriangleMesh> mesh;  ///< world space, all instances merged
    std::vector<Vec3f> normals;  ///< per vertex (unit); meaningful for smooth instances
    std::vector<uint32_t> triangle_instance;  ///< instance index of each triangle
    std::vector<ShadingInstance> instances;
    std::shared_ptr<const KdTree> tree;  ///< built over *mesh
    std::shared_ptr<const EnvironmentLight> env;
    EmitterTable emitters;  ///< built by build_emitter_table(); empty = no area-light NEE
    /// Built by build_instance_runs() from triangle_instance (at most kMaxRuns runs);
    /// empty = instance_of() reads triangle_instance.
    InstanceRuns runs;

    /// Instance index of triangle prim; equals triangle_instance[prim].
    uint32_t instance_of(uint32_t prim) const {
        const size_t n = runs.first.size();
        if (n == 0) return triangle_instance[prim];
        size_t i = n - 1;
        while (runs.first[i] > prim) --i;  // runs.first[0] == 0
        return runs.instance[i];
    }
};

/// The emitter table of a scene whose mesh, triangle_instance and instances are set.
EmitterTable build_emitter_table(const TraceScene& scene);

/// The runs of scene.triangle_instance; none when it has more than InstanceRuns::kMaxRuns.
InstanceRuns build_instance_runs(const TraceScene& scene);

}  // namespace kdt
