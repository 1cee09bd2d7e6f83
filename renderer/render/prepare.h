// From render options to a render snapshot: loading the scene (or the built-in default
// scene), the environment and camera overrides, and the kd-tree from the tree cache. Shared by
// `kdtrace render`, the benches, the viewer and the MPI farm.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
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

/// Where a prepared tree came from, for summary lines: " (cached)", " (from FILE)" for a tree
/// file given by options (scene.tree_file), or "" for a tree built now.
std::string tree_source_text(const Prepared& prepared, const SceneOptions& options);

/// One-line messages (cache hits and writes, the scene file's warnings); empty = stderr.
using PrepareLog = std::function<void(const std::string&)>;

/// The stages of prepare_render, in the order it runs them.
enum class PrepareStage : uint8_t { reading, environment, tree };
inline constexpr std::array<const char*, 3> kPrepareStageNames = {"reading file", "environment",
                                                                  "building/loading tree"};

/// Optional hooks of prepare_render for a viewer loading in the background. Both are called
/// on the calling thread; empty ones are skipped.
struct PrepareHooks {
    std::function<void(PrepareStage)> stage;  ///< at the start of each stage
    /// Polled before each stage (a stage in flight runs to its end): true makes
    /// prepare_render throw kdt::Error("... cancelled") without doing the rest.
    std::function<bool()> cancelled;
    /// Set by another thread, stops the tree stage's build in flight (build_kdtree()'s
    /// `cancel`): prepare_render then throws BuildCancelled.
    const std::atomic<bool>* cancel_build = nullptr;
};

/// Loads options.scene, applies its overrides and compiles the snapshot with the tree of
/// options.tree (from the cache when options.scene.use_cache). Validates the options first
/// (resolve() is the caller's). Throws kdt::Error for any bad input.
Prepared prepare_render(const RenderOptions& options, const PrepareLog& log = {},
                        const PrepareHooks& hooks = {});

/// `camera` with the camera overrides of `options` applied: camera, then eye, target, up and
/// vfov_degrees, each when set.
CameraDesc with_camera_overrides(CameraDesc camera, const SceneOptions& options);

/// Where with_camera_overrides() takes a camera part from: a key of the session file
/// (options.session_camera.file) that gave it, or else `other`.
struct CameraPartSource {
    enum class Kind { session, flag, view, scene };
    Kind kind = Kind::scene;
    std::string key;    ///< session: "/scene/eye", "/scene/camera/up", "/scene/camera"
    std::string other;  ///< flag: "--eye" (or --target, --up); view: "the view"; scene: "the
                        ///< built-in scene" or "the scene file x.json"; session: empty
};

/// The source of camera part `part` (0 eye, 1 target, 2 up) of `options`' overrides over the
/// scene's camera: an override equal to the session's part is the session's, any other is
/// the flag's; a camera equal to the session's camera object is that object's, any other
/// is a view's.
CameraPartSource camera_part_source(const SceneOptions& options, size_t part);

/// Throws the kdt::Error of a camera that `scene_camera` (the scene's) with the overrides of
/// `options` cannot make when a part a session file gave (options.session_camera) is to
/// blame, naming the file, its keys and where the other parts to blame came from: "s.json:
/// /scene/eye: eye and target coincide (target from the scene file x.json)"; a part that
/// --eye, --target or --up gave is "from --eye", one of a view's camera "from the view".
/// Returns otherwise (make_camera() then reports any problem, without a file to name).
void check_session_camera(const CameraDesc& scene_camera, const SceneOptions& options);

/// The loaded scene with options.scene's overrides (environment file, mapping, intensity,
/// rotation, camera) applied, the camera after check_session_camera(); no snapshot. The scene
/// file's warnings go to `log` (empty = stderr).
Scene load_scene_with_overrides(const SceneOptions& options, const PrepareLog& log = {});

}  // namespace kdt
