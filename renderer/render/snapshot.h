// The immutable render snapshot: a Scene compiled into what rendering reads (world-space
// merged triangles, per-triangle instance ids, shading normals, materials, kd-tree,
// environment light, camera). An edit builds a new snapshot and swaps it in.
// Depends on scene, accel, light, integrator, camera.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "renderer/accel/kdtree.h"
#include "renderer/camera/camera.h"
#include "renderer/integrator/trace_scene.h"
#include "renderer/scene/scene.h"

namespace kdt {

/// Builds (or fetches from a cache) the kd-tree over the merged world-space mesh.
using TreeBuildFn = std::function<std::shared_ptr<const KdTree>(std::shared_ptr<const TriangleMesh>,
                                                                const KdTreeParams&)>;

struct SnapshotOptions {
    int width = 640, height = 480;  ///< film size in pixels
    KdTreeParams tree;              ///< kd-tree parameters
    TreeBuildFn build_tree;         ///< empty = build_kdtree()
    /// Replaces the scene's environment when set (tests, `--env` after loading).
    std::shared_ptr<const EnvironmentLight> env;
};

struct RenderSnapshot {
    TraceScene scene;
    Camera camera;
    CameraDesc camera_desc;  ///< as given by the scene, for metadata
    EnvironmentDesc environment;
    std::string scene_name;
    KdTreeParams tree_params;
    double build_seconds = 0.0;  ///< wall time of compile_snapshot (tree included)
};

/// Merges all instances (applying world_from_object), computes angle-weighted normals for
/// smooth instances without file normals, builds the tree and the environment light.
/// Throws kdt::Error for instances without a loaded mesh, bad materials, a bad camera or
/// environment.
std::shared_ptr<const RenderSnapshot> compile_snapshot(const Scene& scene,
                                                       const SnapshotOptions& options);

/// Same, from an already assembled TraceScene (tests, generated geometry): builds the tree
/// if scene.tree is null.
std::shared_ptr<const RenderSnapshot> compile_snapshot(TraceScene scene, const Camera& camera,
                                                       const SnapshotOptions& options = {});

}  // namespace kdt
