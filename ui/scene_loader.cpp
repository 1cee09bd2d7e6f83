#include "ui/scene_loader.h"

#include <sys/resource.h>

#include <algorithm>
#include <cctype>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"

namespace kdt::ui {

SceneLoader::SceneLoader() : thread_([this] { run(); }) {}

SceneLoader::~SceneLoader() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        quit_ = true;
        cancel_build_ = true;
    }
    wake_.notify_all();
    thread_.join();
}

uint64_t SceneLoader::request(LoadRequest request) {
    std::lock_guard<std::mutex> lock(mutex_);
    next_ = std::move(request);
    result_.reset();                     // an older result is superseded
    if (loading_) cancel_build_ = true;  // and so is a load in flight, even mid-build
    requested_at_ = std::chrono::steady_clock::now();
    wake_.notify_all();
    return ++requested_;
}

std::optional<LoadResult> SceneLoader::take() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<LoadResult> r = std::move(result_);
    result_.reset();
    return r;
}

LoadProgress SceneLoader::progress() const {
    std::lock_guard<std::mutex> lock(mutex_);
    LoadProgress p;
    p.path = next_.path;
    p.busy = loading_ || started_ != requested_;
    if (!p.busy) return p;
    p.started = loading_ && started_ == requested_ && stage_started_;
    p.stage = stage_;
    p.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - requested_at_).count();
    return p;
}

bool SceneLoader::busy() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return loading_ || started_ != requested_;
}

int SceneLoader::cancelled_count() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return cancelled_;
}

LoadResult SceneLoader::load(const LoadRequest& request, uint64_t id) {
    LoadResult r;
    r.request = id;
    r.what = request;
    Timer timer;
    PrepareHooks hooks;
    hooks.stage = [&](PrepareStage stage) {
        std::lock_guard<std::mutex> lock(mutex_);
        stage_ = stage;
        stage_started_ = true;
    };
    hooks.cancelled = [&] {
        std::lock_guard<std::mutex> lock(mutex_);
        return requested_ != id || quit_;
    };
    hooks.cancel_build = &cancel_build_;
    try {
        if (request.kind == LoadKind::scene) {
            r.prepared = prepare_render(
                request.options, [&](const std::string& line) { r.log.push_back(line); }, hooks);
        } else {
            hooks.stage(PrepareStage::environment);
            r.probe = make_environment_light(
                request.environment, [&](const std::string& line) { r.log.push_back(line); });
        }
    } catch (const Error& e) {
        r.error = e.what();
    } catch (const std::bad_alloc&) {
        r.error = (request.path.empty() ? std::string("the default scene") : request.path) +
                  ": out of memory while loading";
    } catch (const std::exception& e) {  // e.g. std::filesystem: never ends the viewer
        r.error = (request.path.empty() ? std::string("the default scene") : request.path) + ": " +
                  e.what();
    }
    r.seconds = timer.seconds();
    return r;
}

void SceneLoader::run() {
    setpriority(PRIO_PROCESS, 0, 5);  // as the render threads: the UI thread goes first
    for (;;) {
        LoadRequest request;
        uint64_t id = 0;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [&] { return quit_ || started_ != requested_; });
            if (quit_) return;
            request = next_;
            id = started_ = requested_;
            loading_ = true;
            cancel_build_ = false;
            stage_started_ = false;
            stage_ = PrepareStage::reading;
        }
        LoadResult r = load(request, id);
        std::lock_guard<std::mutex> lock(mutex_);
        loading_ = false;
        if (id == requested_) {
            result_ = std::move(r);
        } else if (!r.prepared && !r.probe) {
            ++cancelled_;  // stopped at a stage boundary (or failed) for a newer request
        }
    }
}

std::optional<LoadKind> load_kind_of(const std::string& path) {
    std::string p = path;
    for (char& c : p) c = char(std::tolower(static_cast<unsigned char>(c)));
    const auto ends = [&](const std::string& ext) {
        return p.size() > ext.size() && p.compare(p.size() - ext.size(), ext.size(), ext) == 0;
    };
    for (const char* ext : {".ply", ".ply.gz", ".obj", ".json"}) {
        if (ends(ext)) return LoadKind::scene;
    }
    for (const char* ext : {".hdr", ".exr", ".pfm"}) {
        if (ends(ext)) return LoadKind::probe;
    }
    return std::nullopt;
}

std::shared_ptr<const RenderSnapshot> with_materials(const RenderSnapshot& snapshot,
                                                     const std::vector<MaterialDesc>& materials) {
    if (materials.size() != snapshot.scene->instances.size()) {
        throw Error("material: " + std::to_string(materials.size()) + " materials for " +
                    std::to_string(snapshot.scene->instances.size()) + " instances");
    }
    auto scene = std::make_shared<TraceScene>(*snapshot.scene);
    for (size_t i = 0; i < materials.size(); ++i)
        scene->instances[i].material = compile_material(materials[i]);
    scene->emitters = build_emitter_table(*scene);  // emission may have changed
    auto snap = std::make_shared<RenderSnapshot>(snapshot);
    snap->scene = std::move(scene);
    return snap;
}

}  // namespace kdt::ui
