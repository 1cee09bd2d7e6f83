// From render options to a render snapshot: loading the scene (or the built-in default
// scene), the environment and camera overrides, and the kd-tree from the tree cache. Shared by
// `kdtrace render`, the benches, the viewer and the MPI farm.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "renderer/render/render_options.h"
#include "renderer/render/snapshot.h"

namespace kdt {

struct Prepared {
    Scene scene;  ///< as loaded, with the overrides applied (meshes shared with the snapshot)
    std::shared_ptr<const RenderSnapshot> snapshot;
    double load_seconds = 0.0, tree_seconds = 0.0;
    bool tree_from_cache = false;
};

/// One-line messages (cache hits and writes); empty = stderr.
using PrepareLog = std::function<void(const std::string&)>;

/// Loads options.scene, applies its overrides and compiles the snapshot with the tree of
/// options.tree (from the cache when options.scene.use_cache). Validates the options first
/// (resolve() is the caller's). Throws kdt::Error for any bad input.
Prepared prepare_render(const RenderOptions& options, const PrepareLog& log = {});

/// The loaded scene with options.scene's overrides (environment file, mapping, intensity,
/// rotation, camera) applied; no snapshot.
Scene load_scene_with_overrides(const SceneOptions& options);

}  // namespace kdt
