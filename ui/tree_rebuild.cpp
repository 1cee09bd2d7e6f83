#include "ui/tree_rebuild.h"

#include <sys/resource.h>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"

namespace kdt::ui {

TreeRebuilder::TreeRebuilder() : thread_([this] { run(); }) {}

TreeRebuilder::~TreeRebuilder() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        quit_ = true;
        cancel_ = true;  // a build in flight stops within its current node's split
    }
    wake_.notify_all();
    thread_.join();
}

uint64_t TreeRebuilder::request(std::shared_ptr<const RenderSnapshot> base,
                                const KdTreeParams& params) {
    std::lock_guard<std::mutex> lock(mutex_);
    base_ = std::move(base);
    params_ = params;
    result_.reset();                // an older result is superseded
    if (building_) cancel_ = true;  // and so is a build in flight
    wake_.notify_all();
    return ++requested_;
}

std::optional<RebuildResult> TreeRebuilder::take() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<RebuildResult> r = std::move(result_);
    result_.reset();
    return r;
}

bool TreeRebuilder::busy() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return building_ || started_ != requested_;
}

void TreeRebuilder::run() {
    // The builder's OpenMP pool inherits this thread's nice value (Linux: per thread).
    setpriority(PRIO_PROCESS, 0, kBuildNice);
    for (;;) {
        std::shared_ptr<const RenderSnapshot> base;
        KdTreeParams params;
        uint64_t id = 0;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [&] { return quit_ || started_ != requested_; });
            if (quit_) return;
            base = base_;
            params = params_;
            id = started_ = requested_;
            building_ = true;
            cancel_ = false;
        }
        RebuildResult r;
        r.request = id;
        Timer timer;
        try {
            r.snapshot = with_tree(*base, build_kdtree(base->scene->mesh, params, &cancel_));
        } catch (const BuildCancelled&) {
            // Only a newer request or the destructor cancels: this result would be dropped.
        } catch (const Error& e) {
            r.error = e.what();
        }
        r.seconds = timer.seconds();
        std::lock_guard<std::mutex> lock(mutex_);
        building_ = false;
        if (id == requested_) result_ = std::move(r);  // else a newer request supersedes it
        ++finished_;
    }
}

}  // namespace kdt::ui
