// From a scene path (or the built-in default scene) to a render snapshot: loading, the
// environment override, and the kd-tree from the tree cache. Shared by `kdtrace render`,
// `kdtrace bench converge` and the viewer.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "renderer/render/snapshot.h"

namespace kdt {

struct PrepareOptions {
    std::string scene_path;   ///< .json scene or model file; empty = make_default_scene()
    std::string env_file;     ///< replaces the scene's environment map when non-empty
    std::string env_mapping;  ///< "latlong" or "angular" (with env_file); empty = latlong
    std::optional<float> env_intensity;  ///< replaces the intensity (finite, >= 0)
    float env_rotation_degrees = 0.0f;   ///< added to the scene's rotation
    std::optional<CameraDesc> camera;    ///< replaces the scene's camera when set
    int width = 640, height = 480;
    KdTreeParams tree;
    bool use_cache = true;  ///< kd-tree cache (get_or_build_kdtree)
    std::string cache_dir;  ///< empty = next to the scene file, else the default cache dir
    bool drop_invalid = false;
    std::function<void(const std::string&)> log;  ///< one-line messages; empty = stderr
};

struct Prepared {
    Scene scene;  ///< as loaded (meshes shared with the snapshot)
    std::shared_ptr<const RenderSnapshot> snapshot;
    double load_seconds = 0.0, tree_seconds = 0.0;
    bool tree_from_cache = false;
};

/// Loads and compiles; throws kdt::Error for any bad input.
Prepared prepare_render(const PrepareOptions& options);

}  // namespace kdt
