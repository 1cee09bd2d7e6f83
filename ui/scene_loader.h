// Background loading for the viewer: a scene, a model or the built-in default scene (read,
// environment, kd-tree: prepare_render) or a light probe, on a thread of its own, so that the
// window keeps drawing. A newer request cancels an older one at its next stage boundary (a
// stage in flight, e.g. a tree build, runs to its end) and the older result is dropped. Also
// the material edit of a loaded snapshot. Depends on renderer/render only (no GL).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "renderer/render/prepare.h"

namespace kdt::ui {

enum class LoadKind : uint8_t { scene, probe };

/// What to load: kind scene runs prepare_render(options); kind probe builds the environment
/// light of `environment` (its file is the probe).
struct LoadRequest {
    LoadKind kind = LoadKind::scene;
    RenderOptions options;
    EnvironmentDesc environment;
    /// The file as the user named it, for messages ("" = the built-in default scene).
    std::string path;
};

struct LoadResult {
    uint64_t request = 0;
    LoadRequest what;
    std::optional<Prepared> prepared;               ///< kind scene, when it loaded
    std::shared_ptr<const EnvironmentLight> probe;  ///< kind probe, when it loaded
    std::string error;                              ///< why it failed ("" = it loaded)
    std::vector<std::string> log;                   ///< prepare_render's messages
    double seconds = 0.0;                           ///< wall time of the load
};

/// The request in flight, for a progress bar.
struct LoadProgress {
    bool busy = false;     ///< a request is queued or loading
    bool started = false;  ///< its first stage has begun (else it is queued)
    PrepareStage stage = PrepareStage::reading;
    std::string path;      ///< of the newest request, also once it is done
    double seconds = 0.0;  ///< since the request
};

class SceneLoader {
public:
    SceneLoader();
    SceneLoader(const SceneLoader&) = delete;
    SceneLoader& operator=(const SceneLoader&) = delete;
    /// Cancels a tree build in flight, waits for any other stage in flight, then joins.
    ~SceneLoader();

    /// Queues `request`, superseding (cancelling) any older one at its next stage boundary,
    /// or within its tree build; returns its number (1, 2, ...).
    uint64_t request(LoadRequest request);
    /// The result of the newest request once it is done (then cleared), else nullopt.
    std::optional<LoadResult> take();
    LoadProgress progress() const;
    bool busy() const;
    /// Requests that stopped at a stage boundary because a newer one came (for tests).
    int cancelled_count() const;

private:
    void run();
    LoadResult load(const LoadRequest& request, uint64_t id);

    mutable std::mutex mutex_;
    std::condition_variable wake_;
    LoadRequest next_;
    uint64_t requested_ = 0, started_ = 0;
    bool loading_ = false, stage_started_ = false, quit_ = false;
    /// Set (under mutex_) by a newer request or the destructor; a tree build in flight reads it.
    std::atomic<bool> cancel_build_{false};
    PrepareStage stage_ = PrepareStage::reading;
    std::chrono::steady_clock::time_point requested_at_{};
    int cancelled_ = 0;
    std::optional<LoadResult> result_;
    std::thread thread_;
};

/// The file types the viewer opens, by extension (case-insensitive): .ply, .ply.gz, .obj and
/// .json are scenes (as `kdtrace render` takes them), .hdr, .exr and .pfm are light probes.
/// nullopt for anything else.
std::optional<LoadKind> load_kind_of(const std::string& path);

/// The same snapshot with instance i's material compiled from materials[i] (the mesh, tree
/// and environment are shared; the shading arrays are copied). Throws kdt::Error for a bad
/// material or a count that is not the snapshot's instance count.
std::shared_ptr<const RenderSnapshot> with_materials(const RenderSnapshot& snapshot,
                                                     const std::vector<MaterialDesc>& materials);

}  // namespace kdt::ui
