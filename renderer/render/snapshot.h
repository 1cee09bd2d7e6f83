// The immutable render snapshot: a Scene compiled into what rendering reads (world-space
// merged triangles, per-triangle instance ids, shading normals, materials, kd-tree,
// environment light, camera). An edit builds a new snapshot and swaps it in; the scene data is
// shared, so a snapshot with another camera or another tree costs no copy of the geometry.
// Depends on scene, accel, light, integrator, camera.
#pragma once

#include <memory>
#include <string>

#include "renderer/accel/kdtree.h"
#include "renderer/camera/camera.h"
#include "renderer/integrator/trace_scene.h"
#include "renderer/scene/scene.h"

namespace kdt {

struct SnapshotOptions {
    int width = 640, height = 480;  ///< film size in pixels
    KdTreeParams tree;              ///< kd-tree parameters, when the tree is built here
    /// Replaces the scene's environment when set (tests, `--env` after loading).
    std::shared_ptr<const EnvironmentLight> env;
};

struct RenderSnapshot {
    /// Never null in a compiled snapshot; shared by snapshots that differ in camera only.
    std::shared_ptr<const TraceScene> scene;
    Camera camera;
    CameraDesc camera_desc;  ///< as given by the scene, for metadata
    EnvironmentDesc environment;
    std::string scene_name;
    KdTreeParams tree_params;
    double build_seconds = 0.0;  ///< wall time of compile_snapshot (tree included)
};

/// The camera of a scene's CameraDesc for a width x height film; throws kdt::Error for a bad
/// image size, field of view or view direction.
Camera make_camera(const CameraDesc& camera, int width, int height);

/// Merges all instances (applying world_from_object, each instance's triangles in spatial
/// order) into one world-space mesh with per-triangle instance ids and, when any instance is
/// smooth, angle-weighted normals for smooth instances without file normals. No tree and no
/// environment yet. Throws kdt::Error for instances without a loaded mesh, bad materials,
/// vertices that overflow under their transform or out-of-range indices.
TraceScene merge_instances(const Scene& scene);

/// merge_instances(), then the environment light and the tree (built here with
/// options.tree).
/// Throws kdt::Error for instances without a loaded mesh, bad materials, a bad camera or
/// environment.
std::shared_ptr<const RenderSnapshot> compile_snapshot(const Scene& scene,
                                                       const SnapshotOptions& options);

/// Same, from an already assembled TraceScene (tests, generated geometry): builds the tree
/// if scene.tree is null.
std::shared_ptr<const RenderSnapshot> compile_snapshot(TraceScene scene, const Camera& camera,
                                                       const SnapshotOptions& options = {});

/// The same snapshot seen through `camera`: shares the scene (no geometry is copied).
std::shared_ptr<const RenderSnapshot> with_camera(const RenderSnapshot& snapshot,
                                                  const Camera& camera);

/// The same snapshot with another kd-tree over the same mesh: copies the per-triangle shading
/// arrays (not the mesh); throws kdt::Error when the tree was built over another mesh.
std::shared_ptr<const RenderSnapshot> with_tree(const RenderSnapshot& snapshot,
                                                std::shared_ptr<const KdTree> tree);

/// The same snapshot under another environment light (`desc` describes it, for metadata):
/// copies the per-triangle shading arrays (not the mesh or the tree).
std::shared_ptr<const RenderSnapshot> with_environment(const RenderSnapshot& snapshot,
                                                       std::shared_ptr<const EnvironmentLight> env,
                                                       const EnvironmentDesc& desc);

}  // namespace kdt
