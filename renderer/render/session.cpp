#include "renderer/render/session.h"

#include <algorithm>
#include <cmath>

#include <omp.h>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/render/settings.h"

namespace kdt {

RenderSession::RenderSession(std::shared_ptr<const RenderSnapshot> snapshot,
                             const TraceParams& trace, const FilmParams& film)
    : snapshot_(std::move(snapshot)), trace_(trace), film_params_(film) {
    if (!snapshot_) throw Error("render session: no snapshot");
    validate_render_params(trace, film);
    film_.resize(snapshot_->camera.width, snapshot_->camera.height);
}

void RenderSession::set_snapshot(std::shared_ptr<const RenderSnapshot> snapshot) {
    if (!snapshot) return;
    std::lock_guard<std::mutex> lock(pending_mutex_);
    pending_ = std::move(snapshot);
    reset_requested_.store(true);
}

void RenderSession::set_params(const TraceParams& trace, const FilmParams& film) {
    validate_render_params(trace, film);  // before anything changes
    trace_ = trace;
    film_params_ = film;
    reset_requested_.store(true);
}

int RenderSession::tile_count() const {
    const int tx = (film_.width() + kTileSize - 1) / kTileSize;
    const int ty = (film_.height() + kTileSize - 1) / kTileSize;
    return tx * ty;
}

void RenderSession::apply_pending() {
    {
        std::lock_guard<std::mutex> lock(pending_mutex_);
        if (pending_) snapshot_ = std::move(pending_);
        pending_.reset();
    }
    if (reset_requested_.exchange(false)) {
        if (film_.width() != snapshot_->camera.width ||
            film_.height() != snapshot_->camera.height) {
            film_.resize(snapshot_->camera.width, snapshot_->camera.height);
        } else {
            film_.clear();
        }
        heat_nodes_.assign(heat_map_ ? film_.pixel_count() : 0, 0);
        heat_tris_.assign(heat_map_ ? film_.pixel_count() : 0, 0);
        totals_ = PathCounters{};
        passes_ = 0;
    }
}

PassStats RenderSession::render_pass(int max_spp) {
    apply_pending();
    std::vector<int> tiles(static_cast<size_t>(tile_count()));
    for (size_t i = 0; i < tiles.size(); ++i) tiles[i] = int(i);
    return render_pass(tiles, max_spp);
}

PassStats RenderSession::render_pass(const std::vector<int>& tiles, int max_spp) {
    apply_pending();
    cancel_requested_.store(false);
    Timer timer;
    PassStats stats;
    // The first pass samples everything; later passes ask the film which pixels remain.
    stats.active_pixels = passes_ == 0 ? film_.pixel_count() : film_.update_active(film_params_);
    if (passes_ == 0) film_.update_active(FilmParams{});

    const RenderSnapshot& snap = *snapshot_;
    const int width = film_.width(), height = film_.height();
    const int tiles_x = (width + kTileSize - 1) / kTileSize;
    const int spp = std::max(trace_.samples_per_pass, 1);
    const uint32_t cap = max_spp > 0 ? uint32_t(max_spp) : 0xffffffffu;
    const int threads = trace_.threads > 0 ? trace_.threads : omp_get_max_threads();
    const bool heat = heat_map_ && !heat_nodes_.empty();

    // One cache line per thread for its counters.
    struct alignas(64) ThreadCounters {
        PathCounters c;
    };
    std::vector<ThreadCounters> per_thread(static_cast<size_t>(threads));
    size_t pixels_done = 0;
    const auto ntiles = int64_t(tiles.size());

#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) reduction(+ : pixels_done)
    for (int64_t k = 0; k < ntiles; ++k) {
        if (cancel_requested_.load(std::memory_order_relaxed)) continue;
        PathCounters& counters = per_thread[size_t(omp_get_thread_num())].c;
        const int tile = tiles[size_t(k)];
        const int x0 = (tile % tiles_x) * kTileSize, y0 = (tile / tiles_x) * kTileSize;
        const int x1 = std::min(x0 + kTileSize, width), y1 = std::min(y0 + kTileSize, height);
        // Camera rays are made for up to kBatch samples of a tile row (in pixel and sample
        // order) before they are traced, in separate loops for the sampler's first draw and
        // for the rays: the draws (and the rays) of different samples are short independent
        // chains the CPU overlaps, instead of one long latency-bound chain in front of every
        // traversal. Each sample stays a pure function of its key, and the film sees the
        // samples in the same order as one at a time.
        constexpr int kBatch = 16;
        struct CameraSample {
            PixelSampler sampler;
            Vec2f u_film{0.0f};
            int x = 0;
        };
        CameraSample batch[kBatch];
        Ray rays[kBatch];
        Hit hits[kBatch];
        for (int y = y0; y < y1; ++y) {
            int x = x0, s = 0;  // the next sample to make: sample s of this pass at pixel x
            uint32_t first_index = 0;
            uint64_t key = 0;
            while (x < x1) {
                int n = 0;
                while (n < kBatch && x < x1) {
                    if (s == 0) {
                        if (!film_.active(x, y)) {
                            ++x;
                            continue;
                        }
                        first_index = film_.next_sample_index(x, y);
                        key = PixelSampler::pixel_key(trace_.seed, uint32_t(x), uint32_t(y));
                    }
                    // Every sample made is traced and advances the pixel's index by one.
                    const uint32_t index = first_index + uint32_t(s);
                    if (s == spp || index >= cap) {
                        pixels_done += s > 0;
                        ++x;
                        s = 0;
                        continue;
                    }
                    CameraSample& c = batch[n++];
                    c.x = x;
                    c.sampler = PixelSampler(key, index);
                    ++s;
                }
                for (int i = 0; i < n; ++i) batch[i].u_film = batch[i].sampler.next_2d();
                for (int i = 0; i < n; ++i) {
                    // Field by field: a whole-Ray copy from a temporary makes GCC reload
                    // just-stored floats as 16-byte vectors (a store-forwarding stall).
                    const Ray r = camera_ray(snap.camera, trace_, batch[i].x, y, batch[i].u_film);
                    rays[i].origin = r.origin;
                    rays[i].tmin = r.tmin;
                    rays[i].dir = r.dir;
                    rays[i].tmax = r.tmax;
                }
                // Without a heat map (which needs each ray's own counts), the camera rays go
                // to the kd-tree's batch query: neighbouring samples' rays are coherent and
                // traced as 8-ray packets, with exactly the hits of one query per ray.
                if (!heat) {
                    TraversalCounters tc;
                    snap.scene.tree->intersect(rays, size_t(n), hits,
                                               trace_.count_traversal ? &tc : nullptr);
                    counters.nodes_visited += tc.nodes_visited;
                    counters.triangles_tested += tc.triangles_tested;
                }
                for (int i = 0; i < n; ++i) {
                    CameraSample& c = batch[i];
                    const uint64_t nodes0 = counters.nodes_visited,
                                   tris0 = counters.triangles_tested;
                    const Vec3f L =
                        heat ? trace_camera_ray(snap.scene, trace_, rays[i], c.sampler, counters)
                             : trace_camera_hit(snap.scene, trace_, rays[i], hits[i], c.sampler,
                                                counters);
                    if (heat) {
                        const size_t pi = size_t(y) * size_t(width) + size_t(c.x);
                        heat_nodes_[pi] += counters.nodes_visited - nodes0;
                        heat_tris_[pi] += counters.triangles_tested - tris0;
                    }
                    if (is_finite(L) && L.x >= 0.0f && L.y >= 0.0f && L.z >= 0.0f) {
                        film_.add_sample(c.x, y, L);
                    } else {
                        film_.skip_sample(c.x, y);
                        ++counters.nonfinite_dropped;
                    }
                }
            }
        }
    }
    for (const ThreadCounters& t : per_thread) stats.counters += t.c;
    stats.active_pixels = pixels_done;
    stats.cancelled = cancel_requested_.exchange(false);
    totals_ += stats.counters;
    ++passes_;
    stats.seconds = timer.seconds();
    return stats;
}

RenderProgress run_render(RenderSession& session, const StopConditions& stop,
                          const std::function<void(const RenderProgress&)>& progress) {
    validate(stop);
    if (stop.spp == 0 && stop.seconds == 0.0 && stop.error == 0.0f)
        throw Error("stop: no stop condition (spp, seconds or error; resolve() sets a default)");
    const bool adaptive = session.film_params().adaptive;
    const double pixels = double(session.film().pixel_count());
    const uint64_t budget = stop.spp > 0 ? uint64_t(stop.spp) * uint64_t(pixels) : 0;
    // Without adaptivity, --spp is exact per pixel; with it, a total budget and a cap.
    int cap = stop.max_spp;
    if (stop.spp > 0 && !adaptive) cap = std::min(cap, stop.spp);
    Timer timer;
    RenderProgress p;
    for (;;) {
        const PassStats ps = session.render_pass(cap);
        const Film& film = session.film();
        p.passes = session.passes();
        p.seconds = timer.seconds();
        p.samples = session.totals().samples;  // drawn, kept or dropped
        p.active_pixels = ps.active_pixels;
        // A full pass over the film: only when someone looks at it.
        if (progress || stop.error > 0.0f) p.mean_relative_error = film.mean_relative_error();
        double frac = 0.0;
        if (budget > 0) frac = std::max(frac, double(p.samples) / double(budget));
        if (stop.seconds > 0.0) frac = std::max(frac, p.seconds / stop.seconds);
        p.error_known = film.total_samples() >= 2 * uint64_t(pixels);
        if (stop.error > 0.0f && adaptive) {
            // Adaptive: done when every pixel is below the target, so the share of pixels
            // that stopped, not the mean error (below the target long before the last pixel).
            frac = std::max(frac, 1.0 - double(ps.active_pixels) / pixels);
        } else if (stop.error > 0.0f && p.error_known && p.mean_relative_error > 0.0) {
            // Error falls as 1/sqrt(samples): (target / error)^2 is the share of samples done.
            frac = std::max(frac, std::pow(double(stop.error) / p.mean_relative_error, 2.0));
        }
        p.fraction = std::min(frac, 0.99);  // 100 % only when done
        bool done = ps.cancelled || ps.active_pixels == 0;
        if (budget > 0 && p.samples >= budget) done = true;
        if (stop.seconds > 0.0 && p.seconds >= stop.seconds) done = true;
        if (stop.error > 0.0f && !adaptive && p.error_known && p.mean_relative_error > 0.0 &&
            p.mean_relative_error <= stop.error) {
            done = true;
        }
        if (done) p.fraction = 1.0;
        if (done && !(progress || stop.error > 0.0f))
            p.mean_relative_error = film.mean_relative_error();
        if (done) p.error_known = film.total_samples() >= 2 * uint64_t(pixels);
        if (progress) progress(p);
        if (done) break;
    }
    return p;
}

}  // namespace kdt
