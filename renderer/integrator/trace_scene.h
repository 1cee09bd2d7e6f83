// What the path tracer reads: world-space triangles with per-triangle instance ids,
// per-vertex shading normals, materials, the kd-tree and the environment light.
// Immutable once built and shared by all threads. Built by renderer/render/snapshot.*.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "renderer/accel/kdtree.h"
#include "renderer/light/environment.h"
#include "renderer/material/material.h"

namespace kdt {

/// Per-instance shading data: its material and flat or smooth shading.
struct ShadingInstance {
    Material material;
    bool smooth = true;  ///< interpolate TraceScene::normals (else the geometric normal)
};

struct TraceScene {
    std::shared_ptr<const TriangleMesh> mesh;  ///< world space, all instances merged
    std::vector<Vec3f> normals;  ///< per vertex (unit); meaningful for smooth instances
    std::vector<uint32_t> triangle_instance;  ///< instance index of each triangle
    std::vector<ShadingInstance> instances;
    std::shared_ptr<const KdTree> tree;  ///< built over *mesh
    std::shared_ptr<const EnvironmentLight> env;
};

}  // namespace kdt
