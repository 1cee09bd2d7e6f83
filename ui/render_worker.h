// The viewer's render thread: runs RenderSession passes progressively until a stop condition
// holds, and restarts on any change (camera, parameters, snapshot, heat map) with a preview at
// 1/preview_divisor of the resolution first, the pass in flight cancelled. A new tree alone
// (set_snapshot with the heat map off) shows the same picture, so it skips the preview. The
// render threads run at a lower OS priority than the UI and the tree builder (Linux nice).
// The UI thread calls the setters and reads stats() and the session's published image; no GL
// here. Depends on renderer/render only.
#pragma once

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "renderer/render/render_options.h"
#include "renderer/render/session.h"

namespace kdt::ui {

/// The nice value of the render threads (Linux: per thread; 0 is the UI's). Against the tree
/// builder's kBuildNice the render threads get about 1/8 of a contended core (the kernel's
/// weights 110 and 820), against the UI about 1/10.
constexpr int kRenderNice = 10;

/// What the render thread reports, read by the UI under the worker's lock.
struct WorkerStats {
    uint64_t restarts = 0;  ///< grows with every change
    int full_passes = 0;    ///< full-resolution passes since the last change
    double spp = 0.0;       ///< mean samples per pixel at full resolution
    double seconds = 0.0;   ///< time spent in full-resolution passes since the last change
    double mrays_per_second = 0.0;
    double mean_error = 0.0;  ///< Film::mean_relative_error after the last pass
    double nodes_per_ray = 0.0, triangles_per_ray = 0.0;
    bool done = false;  ///< a stop condition holds; the thread idles
    bool paused = false;
    std::string error;  ///< why the last environment change failed ("" = none)
    /// Why rendering stopped since the last change ("" = it did not): an error on the render
    /// thread (a camera it cannot build, memory); the thread idles until the next change.
    std::string render_error;
    std::vector<std::pair<double, double>> error_curve;  ///< (seconds, mean error) per pass
};

class RenderWorker {
public:
    /// Starts the thread. `stop` with no condition set renders until the per-pixel cap.
    RenderWorker(std::shared_ptr<const RenderSnapshot> snapshot, const TraceParams& trace,
                 const FilmParams& film, const StopConditions& stop, int preview_divisor = 4);
    RenderWorker(const RenderWorker&) = delete;
    RenderWorker& operator=(const RenderWorker&) = delete;
    ~RenderWorker();

    void set_camera(const CameraDesc& camera);
    /// The scene and tree of `snapshot`, seen through the current camera. With the heat map
    /// off, the restart renders at full resolution at once: the picture on screen is already
    /// that of the new tree's scene, and a preview would only blur it.
    void set_snapshot(std::shared_ptr<const RenderSnapshot> snapshot);
    /// Throws kdt::Error (and changes nothing) for invalid parameters.
    void set_params(const TraceParams& trace, const FilmParams& film, const StopConditions& stop);
    void set_heat_map(bool on);
    /// Turns the normals and depth layers (RenderSession::set_aov) on or off, with a restart.
    void set_aov(bool on);
    /// Replaces the environment light; it is built on the render thread (a failure goes to
    /// WorkerStats::error and the old light stays) and kept across later snapshots.
    void set_environment(const EnvironmentDesc& desc);
    void set_paused(bool paused);

    /// The session, for copy_image() and inspect() (thread-safe calls only).
    const RenderSession& session() const { return *session_; }
    WorkerStats stats() const;
    /// Full-resolution passes completed since the worker started (never reset; lock-free):
    /// when it grows, the session's image holds a pass more.
    uint64_t completed_passes() const { return completed_passes_.load(); }
    /// Grows (lock-free) whenever something the UI shows from the worker may have changed on
    /// the worker's side: a preview, a completed pass, pause, an environment change. Not at a
    /// restart: the caller of the setter knows of that one.
    uint64_t updates() const { return updates_.load(); }
    /// Errors the render thread caught (never reset; lock-free): when it grows, stats() has
    /// the latest in render_error.
    uint64_t failures() const { return failures_.load(); }
    /// Copies the image of the last finished preview pass into `out` when it is another one
    /// than out holds (compared by out.version; out.generation is the WorkerStats::restarts
    /// count of the change it shows); returns whether it copied. The session's own
    /// image of the next, full-resolution pass replaces it only once that pass is complete.
    bool copy_preview(FilmImage& out) const;
    /// The latest snapshot given (the base of a tree rebuild) and the current camera.
    std::shared_ptr<const RenderSnapshot> snapshot() const;
    CameraDesc camera() const;
    int width() const { return width_; }
    int height() const { return height_; }

private:
    void run();
    /// run()'s loop until quit; throws what a pass or a restart throws.
    void render_loop();
    /// `preview`: the restart begins with a preview pass (any restart asking for one since
    /// the thread last took a restart gets it).
    void restart_locked(bool preview = true);
    /// On the render thread at a restart: builds a requested environment and puts the
    /// snapshot, with the environment in force, into the session.
    void apply_scene_changes();
    Camera full_camera_locked() const;

    const int width_, height_, preview_divisor_;
    std::unique_ptr<RenderSession> session_;
    std::thread thread_;

    mutable std::mutex mutex_;
    std::condition_variable wake_;
    std::shared_ptr<const RenderSnapshot> snapshot_;
    CameraDesc camera_;
    TraceParams trace_;
    FilmParams film_;
    StopConditions stop_;
    bool restart_ = true, paused_ = false, quit_ = false;
    bool preview_wanted_ = true;  ///< a pending restart asked for a preview
    bool heat_map_ = false;
    bool snapshot_changed_ = false;  ///< snapshot_ is not yet in the session
    std::optional<EnvironmentDesc> env_request_;
    std::shared_ptr<const EnvironmentLight> env_;  ///< set by set_environment, else null
    EnvironmentDesc env_desc_;
    WorkerStats stats_;
    FilmImage preview_;  ///< version: a count of previews
    std::atomic<uint64_t> completed_passes_{0}, updates_{0}, failures_{0};
};

}  // namespace kdt::ui
