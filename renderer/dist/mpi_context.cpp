#include "renderer/dist/mpi_context.h"

#include <mpi.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <vector>

#include "renderer/core/error.h"

namespace kdt::dist {

MpiContext::MpiContext() {
    int provided = 0;
    // Only the main thread calls MPI (OpenMP threads render, the watchdog sets a flag).
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiContext::~MpiContext() {
    stop_watchdog();
    MPI_Finalize();
}

void MpiContext::start_watchdog(double seconds, double grace_seconds) {
    if (!(seconds > 0.0) || watchdog_.joinable()) return;
    timeout_ = seconds;
    watchdog_ = std::thread([this, seconds, grace_seconds] {
        std::unique_lock<std::mutex> lock(mutex_);
        if (cv_.wait_for(lock, std::chrono::duration<double>(seconds), [this] { return stop_; }))
            return;
        expired_.store(true);
        if (cv_.wait_for(lock, std::chrono::duration<double>(grace_seconds),
                         [this] { return stop_; }))
            return;
        std::fprintf(stderr,
                     "kdtrace: error: rank %d: --timeout %g s reached and the rank is stuck; "
                     "ending it\n",
                     rank_, seconds);
        std::fflush(stderr);
        std::_Exit(3);
    });
}

void MpiContext::stop_watchdog() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stop_ = true;
    }
    cv_.notify_all();
    if (watchdog_.joinable()) watchdog_.join();
}

std::string MpiContext::broadcast(const std::string& text) const {
    uint64_t n = text.size();
    MPI_Bcast(&n, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    std::string out = rank_ == 0 ? text : std::string(n, '\0');
    MPI_Bcast(out.data(), int(n), MPI_CHAR, 0, MPI_COMM_WORLD);
    return out;
}

void MpiContext::check_timeout() const {
    if (!expired()) return;
    char buf[96];
    std::snprintf(buf, sizeof buf, "--timeout %g s reached; every rank stopped", timeout_);
    throw FarmError(buf, rank_ == 0);
}

void MpiContext::poll_until(const std::function<bool()>& done) const {
    for (int spins = 0;; ++spins) {
        if (done()) return;
        check_timeout();
        // Spin briefly for low latency, then yield the core to the renderers.
        if (spins > 1000) std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
}

void MpiContext::wait(MPI_Request& request) const {
    poll_until([&] {
        int done = 0;
        MPI_Test(&request, &done, MPI_STATUS_IGNORE);
        return done != 0;
    });
}

uint64_t snapshot_hash(const RenderSnapshot& snap, const std::string& options_json) {
    // FNV-1a style mixing of 64-bit words.
    uint64_t h = 0xcbf29ce484222325ull;
    auto mix = [&h](uint64_t v) {
        h ^= v;
        h *= 0x100000001b3ull;
        h ^= h >> 29;
    };
    mix(snap.scene->mesh ? snap.scene->mesh->content_hash() : 0);
    mix(snap.scene->tree ? snap.scene->tree->nodes().size() : 0);
    mix(std::hash<std::string>{}(options_json));
    return h;
}

namespace {

// What every rank reports after loading, gathered on all ranks as bytes.
struct LoadStatus {
    int32_t ok = 0;
    uint64_t hash = 0;
    char message[480] = {};
};

}  // namespace

void check_every_rank(const MpiContext& ctx, const std::string& what,
                      const std::function<uint64_t()>& step, bool compare) {
    LoadStatus mine;
    try {
        mine.hash = step();
        mine.ok = 1;
    } catch (const std::exception& e) {
        std::snprintf(mine.message, sizeof mine.message, "%s", e.what());
    }
    std::vector<LoadStatus> all(size_t(ctx.size()));
    // Ranks that finish first wait without spinning, leaving the cores to those still loading.
    MPI_Request request;
    MPI_Iallgather(&mine, int(sizeof mine), MPI_BYTE, all.data(), int(sizeof mine), MPI_BYTE,
                   MPI_COMM_WORLD, &request);
    ctx.wait(request);
    const std::string of = " of " + std::to_string(ctx.size());
    int failed = 0, first = -1;
    for (int r = 0; r < ctx.size(); ++r) {
        if (all[size_t(r)].ok) continue;
        if (first < 0) first = r;
        ++failed;
    }
    bool same = failed == ctx.size() && ctx.size() > 1;
    for (int r = 1; same && r < ctx.size(); ++r)
        same = std::strcmp(all[size_t(r)].message, all[0].message) == 0;
    if (same) throw FarmError("every rank " + what + ": " + all[0].message, ctx.rank() == 0);
    if (failed > 0) {
        std::string m =
            "rank " + std::to_string(first) + of + " " + what + ": " + all[size_t(first)].message;
        if (failed > 1) m += " (and " + std::to_string(failed - 1) + " more ranks failed)";
        throw FarmError(m, ctx.rank() == 0);
    }
    if (!compare) return;
    for (int r = 1; r < ctx.size(); ++r) {
        if (all[size_t(r)].hash == all[0].hash) continue;
        char buf[64];
        std::snprintf(buf, sizeof buf, "%016llx against %016llx",
                      (unsigned long long)all[size_t(r)].hash, (unsigned long long)all[0].hash);
        throw FarmError("rank " + std::to_string(r) + of +
                            " renders a different scene or kd-tree than rank 0 (hash " + buf +
                            "): every rank must see the same files (shared filesystem)",
                        ctx.rank() == 0);
    }
}

Prepared prepare_everywhere(const MpiContext& ctx, const RenderOptions& options,
                            const PrepareLog& log, const InjectedFault& fault) {
    const std::string json = options_to_json(options);
    Prepared prep;
    check_every_rank(
        ctx, "could not load the scene",
        [&] {
            RenderOptions o = options;
            if (fault.rank == ctx.rank() && fault.what == "load") {
                o.scene.scene_path =
                    "/nonexistent/kdtrace-injected-fault/" +
                    (o.scene.scene_path.empty() ? "scene.json" : o.scene.scene_path);
            }
            prep = prepare_render(o, log);
            uint64_t hash = snapshot_hash(*prep.snapshot, json);
            if (fault.rank == ctx.rank() && fault.what == "hash") hash ^= 1;
            return hash;
        },
        true);
    return prep;
}

}  // namespace kdt::dist
