#include "ui/render_worker.h"

#include <sys/resource.h>

#include <algorithm>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/render/settings.h"

namespace kdt::ui {

RenderWorker::RenderWorker(std::shared_ptr<const RenderSnapshot> snapshot, const TraceParams& trace,
                           const FilmParams& film, const StopConditions& stop, int preview_divisor)
    : width_(snapshot->camera.width),
      height_(snapshot->camera.height),
      preview_divisor_(std::max(preview_divisor, 1)),
      snapshot_(snapshot),
      camera_(snapshot->camera_desc),
      trace_(trace),
      film_(film),
      stop_(stop) {
    validate(stop);
    session_ = std::make_unique<RenderSession>(snapshot, trace, film);
    thread_ = std::thread([this] { run(); });
}

RenderWorker::~RenderWorker() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        quit_ = true;
    }
    session_->cancel();
    wake_.notify_all();
    thread_.join();
}

void RenderWorker::restart_locked(bool preview) {
    // No updates_ here: the caller's own frame shows the change, and frames drawn for it
    // would only take the cores from the preview.
    preview_wanted_ = preview || (restart_ && preview_wanted_);
    restart_ = true;
    ++stats_.restarts;
    stats_.done = false;
    // Reset here, not when the thread takes the restart: a reader never sees the new restart
    // count with the old change's passes.
    stats_.full_passes = 0;
    stats_.spp = stats_.seconds = stats_.mean_error = 0.0;
    stats_.error_curve.clear();
    stats_.render_error.clear();
    session_->cancel();
    wake_.notify_all();
}

void RenderWorker::set_camera(const CameraDesc& camera) {
    std::lock_guard<std::mutex> lock(mutex_);
    camera_ = camera;
    restart_locked();
}

void RenderWorker::set_snapshot(std::shared_ptr<const RenderSnapshot> snapshot) {
    if (!snapshot) return;
    std::lock_guard<std::mutex> lock(mutex_);
    snapshot_ = std::move(snapshot);
    snapshot_changed_ = true;
    restart_locked(heat_map_);
}

void RenderWorker::set_params(const TraceParams& trace, const FilmParams& film,
                              const StopConditions& stop) {
    validate(stop);
    session_->set_params(trace, film);  // validates before it queues anything
    std::lock_guard<std::mutex> lock(mutex_);
    trace_ = trace;
    film_ = film;
    stop_ = stop;
    restart_locked();
}

void RenderWorker::set_environment(const EnvironmentDesc& desc) {
    std::lock_guard<std::mutex> lock(mutex_);
    env_request_ = desc;
    restart_locked();
}

void RenderWorker::apply_scene_changes() {
    std::shared_ptr<const RenderSnapshot> snap, base;
    std::optional<EnvironmentDesc> request;
    std::shared_ptr<const EnvironmentLight> env;
    EnvironmentDesc desc;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!snapshot_changed_ && !env_request_) return;
        snap = base = snapshot_;
        request = env_request_;
        env_request_.reset();
        env = env_;
        desc = env_desc_;
    }
    std::string error;
    if (request) {
        try {
            env = make_environment_light(*request);  // may read a file: not under the lock
            desc = *request;
        } catch (const Error& e) {
            error = e.what();
        }
    }
    // A snapshot from a tree rebuild started before the environment changed gets it too.
    if (env && snap->scene->env != env) snap = with_environment(*snap, env, desc);
    std::lock_guard<std::mutex> lock(mutex_);
    // A newer snapshot (a scene or tree swapped in while the environment loaded) is kept and
    // given the environment; the one read above is out of date.
    if (snapshot_ != base) {
        snap = snapshot_;
        if (env && snap->scene->env != env) snap = with_environment(*snap, env, desc);
    }
    snapshot_ = snap;
    snapshot_changed_ = false;
    env_ = env;
    env_desc_ = desc;
    if (request) stats_.error = error;
    ++updates_;
    session_->set_snapshot(snap);
}

void RenderWorker::set_heat_map(bool on) {
    session_->set_heat_map(on);
    std::lock_guard<std::mutex> lock(mutex_);
    heat_map_ = on;
    restart_locked();
}

void RenderWorker::set_aov(bool on) {
    session_->set_aov(on);
    std::lock_guard<std::mutex> lock(mutex_);
    restart_locked();
}

void RenderWorker::set_paused(bool paused) {
    std::lock_guard<std::mutex> lock(mutex_);
    paused_ = paused;
    stats_.paused = paused;
    ++updates_;
    if (paused) session_->cancel();
    wake_.notify_all();
}

WorkerStats RenderWorker::stats() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
}

bool RenderWorker::copy_preview(FilmImage& out) const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (preview_.version == 0 || preview_.version == out.version) return false;
    out = preview_;
    return true;
}

std::shared_ptr<const RenderSnapshot> RenderWorker::snapshot() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return snapshot_;
}

CameraDesc RenderWorker::camera() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return camera_;
}

Camera RenderWorker::full_camera_locked() const { return make_camera(camera_, width_, height_); }

void RenderWorker::run() {
    // The render threads (this one and the OpenMP pool it starts, which inherits it) yield to
    // the UI thread, so a frame never waits for a core behind a tile, and to the tree builder,
    // so a new tree is ready sooner while the old one keeps rendering on what is left.
    setpriority(PRIO_PROCESS, 0, kRenderNice);  // Linux: 0 is the calling thread
    // Nothing may escape the thread (std::terminate): an error is reported, the thread idles
    // as if done, and the next change starts it again from a restart.
    for (;;) {
        std::string error;
        try {
            render_loop();
            return;
        } catch (const std::exception& e) {
            error = e.what();
        } catch (...) {
            error = "unknown error on the render thread";
        }
        std::lock_guard<std::mutex> lock(mutex_);
        if (quit_) return;
        stats_.render_error = error;
        if (!restart_) stats_.done = true;  // a change meanwhile starts it again at once
        ++failures_;
        ++updates_;
    }
}

void RenderWorker::render_loop() {
    bool preview = false;  // the pass in the session is the low-resolution preview
    uint64_t restart = 0;  // the restart (WorkerStats::restarts) the passes belong to
    PathCounters totals;
    // The per_pass of the next full pass (first_samples_per_pass() after a restart, then
    // next_samples_per_pass(), as run_render() does).
    int per_pass = first_samples_per_pass(*session_);
    for (;;) {
        StopConditions stop;
        bool adaptive = false, restarted = false;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [&] { return quit_ || (!paused_ && (restart_ || !stats_.done)); });
            if (quit_) return;
            if (restart_) {
                restart_ = false;
                restart = stats_.restarts;
                const int pw = width_ / preview_divisor_, ph = height_ / preview_divisor_;
                preview = preview_wanted_ && preview_divisor_ > 1 && pw >= 8 && ph >= 8;
                restarted = true;
                totals = PathCounters{};
                per_pass = first_samples_per_pass(*session_);
            }
            stop = stop_;
            adaptive = film_.adaptive;
        }
        if (restarted) {
            // Scene changes go in before the camera (set_snapshot brings its own camera,
            // which set_camera replaces).
            apply_scene_changes();
            std::lock_guard<std::mutex> lock(mutex_);
            session_->set_camera(preview ? make_camera(camera_, width_ / preview_divisor_,
                                                       height_ / preview_divisor_)
                                         : full_camera_locked());
        }
        // Without adaptivity a sample count is exact per pixel; with it, stop.spp is a budget
        // of samples that no pass draws past (run_render's rules); the preview takes one.
        int cap = stop.max_spp;
        if (stop.spp > 0 && !adaptive) cap = std::min(cap, stop.spp);
        if (preview) cap = std::min(cap, 1);
        const int budget_spp = adaptive && !preview ? stop.spp : 0;
        const PassStats ps = session_->render_pass(cap, preview ? 1 : per_pass, budget_spp);
        if (ps.cancelled) continue;  // a change (or pause) is waiting
        if (preview) {
            preview = false;
            std::lock_guard<std::mutex> lock(mutex_);
            if (restart_) continue;
            const uint64_t serial = preview_.version + 1;
            preview_.version = 0;
            session_->copy_image(preview_, true);
            preview_.version = serial;
            ++updates_;
            preview_.generation = restart;
            session_->set_camera(full_camera_locked());
            continue;
        }
        totals += ps.counters;
        const Film& film = session_->film();
        const double pixels = double(film.pixel_count());
        const double error = film.mean_relative_error();
        std::lock_guard<std::mutex> lock(mutex_);
        if (restart_) continue;
        WorkerStats& s = stats_;
        ++s.full_passes;
        ++completed_passes_;  // under the lock: a reader who sees it sees these stats too
        ++updates_;
        s.seconds += ps.seconds;
        s.spp = double(session_->totals().samples) / pixels;
        s.mean_error = error;
        const double rays = double(std::max<uint64_t>(totals.rays(), 1));
        s.mrays_per_second = s.seconds > 0.0 ? double(totals.rays()) / s.seconds * 1e-6 : 0.0;
        s.nodes_per_ray = double(totals.nodes_visited) / rays;
        s.triangles_per_ray = double(totals.triangles_tested) / rays;
        if (error > 0.0) s.error_curve.emplace_back(s.seconds, error);  // 0: < 2 samples
        RenderProgress p;
        p.seconds = s.seconds;
        p.samples = session_->totals().samples;
        p.error_known = error > 0.0;  // 0 until every pixel has 2 samples
        p.mean_relative_error = error;
        per_pass = next_samples_per_pass(*session_, stop, per_pass, ps.seconds, p);
        bool done = ps.active_pixels == 0;
        if (stop.spp > 0 && adaptive && s.spp >= double(stop.spp)) done = true;
        if (stop.seconds > 0.0 && s.seconds >= stop.seconds) done = true;
        if (stop.error > 0.0f && !adaptive && error > 0.0 && error <= stop.error) done = true;
        s.done = done;
    }
}

}  // namespace kdt::ui
