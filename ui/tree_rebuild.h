// Background kd-tree rebuilds for the viewer: request() queues a build of the current scene's
// mesh with new parameters; one thread builds the newest request (a request made during a
// build supersedes it: that build is cancelled, within a node's split) and hands back a
// snapshot with the new tree, which the viewer swaps in while the old tree keeps rendering
// meanwhile.
// Depends on renderer/render only.
#pragma once

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "renderer/render/snapshot.h"

namespace kdt::ui {

/// The nice value of the builder threads: below the UI thread's 0, above the render threads'
/// (render_worker.h kRenderNice).
constexpr int kBuildNice = 2;

struct RebuildResult {
    std::shared_ptr<const RenderSnapshot> snapshot;  ///< null when the build failed
    std::string error;                               ///< why it failed
    uint64_t request = 0;
    double seconds = 0.0;  ///< build wall time
};

class TreeRebuilder {
public:
    TreeRebuilder();
    TreeRebuilder(const TreeRebuilder&) = delete;
    TreeRebuilder& operator=(const TreeRebuilder&) = delete;
    ~TreeRebuilder();

    /// Queues a build of base's mesh with `params`; returns the request's number.
    uint64_t request(std::shared_ptr<const RenderSnapshot> base, const KdTreeParams& params);
    /// The result of the newest request once it is built (then cleared), else nullopt.
    std::optional<RebuildResult> take();
    /// Whether a request is queued or building.
    bool busy() const;
    /// Builds finished since the start, superseded ones included (lock-free): when it grows,
    /// take() may have a result.
    uint64_t finished() const { return finished_.load(); }

private:
    void run();

    mutable std::mutex mutex_;
    std::condition_variable wake_;
    std::shared_ptr<const RenderSnapshot> base_;
    KdTreeParams params_;
    uint64_t requested_ = 0, started_ = 0;
    bool building_ = false, quit_ = false;
    /// Set (under mutex_) by a newer request or the destructor; the build in flight reads it.
    std::atomic<bool> cancel_{false};
    std::optional<RebuildResult> result_;
    std::atomic<uint64_t> finished_{0};
    std::thread thread_;
};

}  // namespace kdt::ui
