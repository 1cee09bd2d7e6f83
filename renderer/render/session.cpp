#include "renderer/render/session.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <omp.h>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/render/settings.h"
#include "renderer/render/tile_renderer.h"

namespace kdt {

namespace {

/// The cost of samples for adaptive sampling: kd-tree nodes visited plus triangles tested
/// (the traversal work, which dominates a sample's time and varies with where its rays
/// go), or the rays traced when traversal is not counted.
uint64_t sample_work(const PathCounters& c) {
    const uint64_t steps = c.nodes_visited + c.triangles_tested;
    return steps > 0 ? steps : c.rays();
}

/// The most samples a pixel may draw in a pass; 0 = no cap. max_spp is the pass's cap and,
/// while adaptive, adaptive_max_spp caps too, counted as drawn samples so that a pass of
/// several samples per pixel (Film::pass_samples) stops at it rather than past it.
uint32_t sample_cap(int max_spp, const FilmParams& film) {
    uint32_t cap = max_spp > 0 ? uint32_t(max_spp) : 0;
    if (film.adaptive && film.adaptive_max_spp > 0) {
        const auto a = uint32_t(film.adaptive_max_spp);
        cap = cap > 0 ? std::min(cap, a) : a;
    }
    return cap;
}

}  // namespace

RenderSession::RenderSession(std::shared_ptr<const RenderSnapshot> snapshot,
                             const TraceParams& trace, const FilmParams& film)
    : snapshot_(std::move(snapshot)), trace_(trace), film_params_(film) {
    if (!snapshot_) throw Error("render session: no snapshot");
    validate_render_params(trace, film);
    film_.keep_coverage(film.transparent);
    film_.resize(snapshot_->camera.width, snapshot_->camera.height);
    reset_published();
}

void RenderSession::set_snapshot(std::shared_ptr<const RenderSnapshot> snapshot) {
    if (!snapshot) return;
    std::lock_guard<std::mutex> lock(pending_mutex_);
    pending_.snapshot = std::move(snapshot);
    pending_.camera.reset();  // the new snapshot brings its own camera
    reset_requested_.store(true);
}

void RenderSession::set_camera(const Camera& camera) {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    pending_.camera = camera;
    reset_requested_.store(true);
}

void RenderSession::set_params(const TraceParams& trace, const FilmParams& film) {
    validate_render_params(trace, film);  // before anything changes
    std::lock_guard<std::mutex> lock(pending_mutex_);
    pending_.trace = trace;
    pending_.film = film;
    reset_requested_.store(true);
}

void RenderSession::set_heat_map(bool on) {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    pending_.heat_map = on;
    reset_requested_.store(true);
}

void RenderSession::set_aov(bool on) {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    pending_.aov = on;
    reset_requested_.store(true);
}

FilmRect RenderSession::tile_rect(int tile) const {
    const int tiles_x = (film_.width() + kTileSize - 1) / kTileSize;
    FilmRect r;
    r.x0 = (tile % tiles_x) * kTileSize;
    r.y0 = (tile / tiles_x) * kTileSize;
    r.x1 = std::min(r.x0 + kTileSize, film_.width());
    r.y1 = std::min(r.y0 + kTileSize, film_.height());
    return r;
}

int RenderSession::tile_count() const {
    const int tx = (film_.width() + kTileSize - 1) / kTileSize;
    const int ty = (film_.height() + kTileSize - 1) / kTileSize;
    return tx * ty;
}

void RenderSession::apply_pending() {
    {
        std::lock_guard<std::mutex> lock(pending_mutex_);
        if (pending_.snapshot) snapshot_ = std::move(pending_.snapshot);
        if (pending_.camera) snapshot_ = with_camera(*snapshot_, *pending_.camera);
        if (pending_.trace) trace_ = *pending_.trace;
        if (pending_.film) film_params_ = *pending_.film;
        if (pending_.heat_map) heat_map_ = *pending_.heat_map;
        if (pending_.aov) aov_ = *pending_.aov;
        pending_ = Pending{};
    }
    if (reset_requested_.exchange(false)) {
        if (film_.width() != snapshot_->camera.width ||
            film_.height() != snapshot_->camera.height) {
            film_.resize(snapshot_->camera.width, snapshot_->camera.height);
        } else {
            film_.clear();
        }
        if (film_.keeps_coverage() != film_params_.transparent)
            film_.keep_coverage(film_params_.transparent);
        heat_nodes_.assign(heat_map_ ? film_.pixel_count() : 0, 0);
        heat_tris_.assign(heat_map_ ? film_.pixel_count() : 0, 0);
        aov_normal_.assign(aov_ ? 3 * film_.pixel_count() : 0, 0.0f);
        aov_depth_.assign(aov_ ? film_.pixel_count() : 0, 0.0f);
        aov_hits_.assign(aov_ ? film_.pixel_count() : 0, 0);
        totals_ = PathCounters{};
        tile_work_.clear();
        tile_samples_.clear();
        passes_ = 0;
        reset_published();
    }
}

void RenderSession::reset_published() {
    const size_t n = film_.pixel_count();
    std::lock_guard<std::mutex> lock(published_mutex_);
    Published& p = published_;
    p.image.width = film_.width();
    p.image.height = film_.height();
    p.image.rgb.assign(n * 3, 0.0f);
    p.samples.assign(n, 0);
    p.error.assign(n, std::numeric_limits<float>::infinity());
    p.nodes.assign(n, 0.0f);
    p.triangles.assign(n, 0.0f);
    p.heat = !heat_nodes_.empty();
    p.normals.assign(aov_hits_.empty() ? 0 : 3 * n, 0.0f);
    p.depth.assign(aov_hits_.empty() ? 0 : n, 0.0f);
    ++p.image.version;
    ++p.image.generation;
    p.image.complete_passes = 0;
}

void RenderSession::publish_tile(int x0, int y0, int x1, int y1) {
    // The values are computed outside the lock from pixels only this thread writes in this
    // pass; the lock covers the copy of one tile.
    constexpr int kN = kTileSize * kTileSize;
    float rgb[kN * 3], error[kN], nodes[kN], tris[kN], normals[kN * 3], depth[kN];
    uint32_t samples[kN];
    const int w = x1 - x0;
    const bool heat = !heat_nodes_.empty();
    const bool aov = !aov_hits_.empty();
    for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
            const int i = (y - y0) * w + (x - x0);
            const Vec3f m = film_.mean(x, y);
            rgb[3 * i] = m.x;
            rgb[3 * i + 1] = m.y;
            rgb[3 * i + 2] = m.z;
            samples[i] = film_.count(x, y);
            error[i] = film_.relative_error(x, y);
            const size_t pi = size_t(y) * size_t(film_.width()) + size_t(x);
            if (heat) {
                const float inv = samples[i] > 0 ? 1.0f / float(samples[i]) : 0.0f;
                nodes[i] = float(heat_nodes_[pi]) * inv;
                tris[i] = float(heat_tris_[pi]) * inv;
            }
            if (aov) {
                const uint32_t hits = aov_hits_[pi];
                const float inv_hits = hits > 0 ? 1.0f / float(hits) : 0.0f;
                for (int k = 0; k < 3; ++k) normals[3 * i + k] = aov_normal_[3 * pi + k] * inv_hits;
                depth[i] = hits > 0         ? aov_depth_[pi] * inv_hits
                           : samples[i] > 0 ? std::numeric_limits<float>::infinity()
                                            : 0.0f;
            }
        }
    }
    std::lock_guard<std::mutex> lock(published_mutex_);
    Published& p = published_;
    for (int y = y0; y < y1; ++y) {
        const size_t row = size_t(y) * size_t(film_.width()) + size_t(x0);
        const int i = (y - y0) * w;
        std::copy_n(rgb + 3 * i, 3 * w, p.image.rgb.begin() + ptrdiff_t(3 * row));
        std::copy_n(samples + i, w, p.samples.begin() + ptrdiff_t(row));
        std::copy_n(error + i, w, p.error.begin() + ptrdiff_t(row));
        if (heat) {  // without a heat map the published counts stay reset_published()'s 0
            std::copy_n(nodes + i, w, p.nodes.begin() + ptrdiff_t(row));
            std::copy_n(tris + i, w, p.triangles.begin() + ptrdiff_t(row));
        }
        if (aov && !p.depth.empty()) {
            std::copy_n(normals + 3 * i, 3 * w, p.normals.begin() + ptrdiff_t(3 * row));
            std::copy_n(depth + i, w, p.depth.begin() + ptrdiff_t(row));
        }
    }
    ++p.image.version;
}

bool RenderSession::copy_image(FilmImage& out, bool layers) const {
    std::lock_guard<std::mutex> lock(published_mutex_);
    const Published& p = published_;
    if (out.version == p.image.version) return false;
    out.width = p.image.width;
    out.height = p.image.height;
    out.rgb = p.image.rgb;
    out.version = p.image.version;
    out.generation = p.image.generation;
    out.complete_passes = p.image.complete_passes;
    out.heat_nodes.clear();
    out.heat_triangles.clear();
    out.aov_normals.clear();
    out.aov_depth.clear();
    if (layers && p.heat) {
        out.heat_nodes = p.nodes;
        out.heat_triangles = p.triangles;
    }
    if (layers) {
        out.aov_normals = p.normals;
        out.aov_depth = p.depth;
    }
    return true;
}

std::optional<PixelInfo> RenderSession::inspect(int x, int y) const {
    std::lock_guard<std::mutex> lock(published_mutex_);
    const Published& p = published_;
    if (x < 0 || y < 0 || x >= p.image.width || y >= p.image.height) return std::nullopt;
    const size_t i = size_t(y) * size_t(p.image.width) + size_t(x);
    PixelInfo info;
    info.rgb = Vec3f(p.image.rgb[3 * i], p.image.rgb[3 * i + 1], p.image.rgb[3 * i + 2]);
    info.samples = p.samples[i];
    info.relative_error = p.error[i];
    info.nodes_per_sample = p.nodes[i];
    info.triangles_per_sample = p.triangles[i];
    if (!p.depth.empty()) {
        info.normal = Vec3f(p.normals[3 * i], p.normals[3 * i + 1], p.normals[3 * i + 2]);
        info.depth = p.depth[i];
    }
    return info;
}

PassStats RenderSession::render_pass(int max_spp, int per_pass, int budget_spp) {
    // Cleared before the changes are taken: a cancel() that follows a change never goes
    // missing, it can at worst stop the first pass that already has the change.
    cancel_requested_.store(false);
    apply_pending();
    std::vector<int> tiles(static_cast<size_t>(tile_count()));
    for (size_t i = 0; i < tiles.size(); ++i) tiles[i] = int(i);
    return run_tiles(tiles, max_spp, per_pass, budget_spp);
}

PassStats RenderSession::render_pass(const std::vector<int>& tiles, int max_spp, int per_pass,
                                     int budget_spp) {
    cancel_requested_.store(false);
    apply_pending();
    return run_tiles(tiles, max_spp, per_pass, budget_spp);
}

int RenderSession::fit_budget(const std::vector<int>& tiles, int per_pass, size_t active,
                              int budget_spp) {
    const uint64_t budget = uint64_t(budget_spp) * film_.pixel_count();
    const uint64_t left = budget > totals_.samples ? budget - totals_.samples : 0;
    // `active` counts the whole film: when even that fits, the tiles' pixels do.
    if (uint64_t(active) * uint64_t(per_pass) <= left) return per_pass;
    const auto for_each_active = [&](const auto& f) {
        for (const int tile : tiles) {
            const FilmRect r = tile_rect(tile);
            for (int y = r.y0; y < r.y1; ++y) {
                for (int x = r.x0; x < r.x1; ++x) {
                    if (film_.active(x, y)) f(x, y);
                }
            }
        }
    };
    uint64_t in_tiles = 0;
    for_each_active([&](int, int) { ++in_tiles; });
    if (in_tiles * uint64_t(per_pass) <= left) return per_pass;
    // Sample indices are per pixel: cutting a pass drops samples, it changes none.
    if (left >= in_tiles) return int(left / in_tiles);
    uint64_t kept = 0;
    for_each_active([&](int x, int y) {
        if (kept < left) {
            ++kept;
        } else {
            film_.set_active(x, y, false);
        }
    });
    return 1;
}

size_t RenderSession::update_active(int max_spp, int per_pass) {
    // The first pass samples everything; later passes ask the film which pixels remain.
    if (passes_ == 0 || !film_params_.adaptive)
        return film_.update_active(FilmParams{}, {.samples_per_pass = per_pass});
    // A pixel's cost per sample is its tile's mean since the reset: counted per tile, so the
    // same for any thread count. A tile without samples yet costs the film's mean.
    const int width = film_.width(), height = film_.height();
    const int tiles_x = (width + kTileSize - 1) / kTileSize;
    uint64_t work = 0, samples = 0;
    for (size_t t = 0; t < tile_work_.size(); ++t) {
        work += tile_work_[t];
        samples += tile_samples_[t];
    }
    const auto per_sample = [](uint64_t w, uint64_t n) { return float(double(w) / double(n)); };
    const float mean_cost = samples > 0 && work > 0 ? per_sample(work, samples) : 1.0f;
    pixel_cost_.resize(film_.pixel_count());
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            const size_t t = size_t((y / kTileSize) * tiles_x + x / kTileSize);
            const bool known =
                t < tile_samples_.size() && tile_samples_[t] > 0 && tile_work_[t] > 0;
            pixel_cost_[size_t(y) * size_t(width) + size_t(x)] =
                known ? per_sample(tile_work_[t], tile_samples_[t]) : mean_cost;
        }
    }
    AdaptiveInputs in;
    in.cost_per_sample = pixel_cost_;
    in.sample_cap = sample_cap(max_spp, film_params_);
    in.samples_per_pass = per_pass;
    return film_.update_active(film_params_, in);
}

PassStats RenderSession::run_tiles(const std::vector<int>& tiles, int max_spp, int per_pass,
                                   int budget_spp) {
    Timer timer;
    PassStats stats;
    stats.active_pixels = update_active(max_spp, per_pass > 0 ? per_pass : trace_.samples_per_pass);
    stats.open_pixels = film_.open_count();
    int pass_samples = film_.pass_samples();
    if (budget_spp > 0)
        pass_samples = fit_budget(tiles, pass_samples, stats.active_pixels, budget_spp);

    const int threads = trace_.threads > 0 ? trace_.threads : omp_get_max_threads();
    TileTarget target;
    target.scene = snapshot_->scene.get();
    target.camera = &snapshot_->camera;
    // The pass's samples per pixel: per_pass or samples_per_pass, or more for an adaptive
    // pass (Film::pass_samples), or fewer to keep to the sample budget.
    TraceParams pass_trace = trace_;
    pass_trace.samples_per_pass = pass_samples;
    target.trace = &pass_trace;
    target.film = &film_;
    if (heat_map_ && !heat_nodes_.empty()) {
        target.heat_nodes = heat_nodes_.data();
        target.heat_triangles = heat_tris_.data();
    }
    if (aov_ && !aov_hits_.empty()) {
        target.aov_normal = aov_normal_.data();
        target.aov_depth = aov_depth_.data();
        target.aov_hits = aov_hits_.data();
    }
    if (const uint32_t cap = sample_cap(max_spp, film_params_); cap > 0) target.max_spp = cap;
    target.transparent = film_params_.transparent;

    // One cache line per thread for its counters.
    struct alignas(64) ThreadCounters {
        PathCounters c;
    };
    std::vector<ThreadCounters> per_thread(static_cast<size_t>(threads));
    size_t pixels_done = 0;
    const auto ntiles = int64_t(tiles.size());
    const bool cost_model = film_params_.adaptive;
    if (cost_model && tile_work_.size() != size_t(tile_count())) {
        tile_work_.assign(size_t(tile_count()), 0);
        tile_samples_.assign(size_t(tile_count()), 0);
    }

#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) reduction(+ : pixels_done)
    for (int64_t k = 0; k < ntiles; ++k) {
        if (cancel_requested_.load(std::memory_order_relaxed)) continue;
        const int tile = tiles[size_t(k)];
        const FilmRect r = tile_rect(tile);
        PathCounters counters;
        pixels_done += render_tile(target, r, counters);
        per_thread[size_t(omp_get_thread_num())].c += counters;
        if (cost_model) {  // each tile index once per pass: no other thread writes its entry
            tile_work_[size_t(tile)] += sample_work(counters);
            tile_samples_[size_t(tile)] += counters.samples;
        }
        if (publishing_) publish_tile(r.x0, r.y0, r.x1, r.y1);
    }
    for (const ThreadCounters& t : per_thread) stats.counters += t.c;
    stats.active_pixels = pixels_done;
    stats.cancelled = cancel_requested_.exchange(false);
    totals_ += stats.counters;
    ++passes_;
    if (!stats.cancelled) {
        std::lock_guard<std::mutex> lock(published_mutex_);
        ++published_.image.complete_passes;
        ++published_.image.version;
    }
    stats.seconds = timer.seconds();
    return stats;
}

namespace {

// The automatic pass size without adaptive sampling (next_samples_per_pass()).
int auto_samples_per_pass(const StopConditions& stop, int last, double seconds, double pixels,
                          const RenderProgress& p) {
    double k = kMaxAutoSamplesPerPass;
    const double per_sample = seconds / double(std::max(last, 1));
    if (per_sample > 0.0) {
        double budget = 1.0;
        if (stop.seconds > 0.0) budget = std::min(budget, 0.5 * (stop.seconds - p.seconds));
        k = std::min(k, std::floor(budget / per_sample));
    }
    const double done_spp = double(p.samples) / pixels;
    if (stop.spp > 0) k = std::min(k, double(stop.spp) - done_spp);
    if (stop.error > 0.0f) {
        if (!p.error_known || !(p.mean_relative_error > 0.0)) return 1;
        const double ratio = p.mean_relative_error / double(stop.error);
        k = std::min(k, 0.25 * done_spp * (ratio * ratio - 1.0));
    }
    return std::max(1, int(std::min(k, double(kMaxAutoSamplesPerPass))));
}

}  // namespace

int next_samples_per_pass(const RenderSession& session, const StopConditions& stop, int last,
                          double seconds, const RenderProgress& p) {
    const int explicit_per_pass = session.trace_params().samples_per_pass;
    if (explicit_per_pass != 0) {
        // A pass ends only at its last tile: one larger than the time left would overrun the
        // limit many times over. The cut pass, like the first one (first_samples_per_pass()),
        // changes an adaptive image, which a time limit leaves to the run anyway.
        const double per_sample = seconds / double(last > 0 ? last : explicit_per_pass);
        if (stop.seconds <= 0.0 || !(per_sample > 0.0)) return 0;
        const double fits = std::floor(0.5 * (stop.seconds - p.seconds) / per_sample);
        if (fits >= double(explicit_per_pass)) return 0;
        return std::max(1, int(fits));
    }
    const double pixels = double(session.film().pixel_count());
    last = std::max(last, 1);
    if (!session.film_params().adaptive)
        return auto_samples_per_pass(stop, last, seconds, pixels, p);
    // Adaptive: every pixel samples until adaptive_min_spp (Film::update_active), so that
    // warm-up takes passes as large as the spp and time conditions allow, ending exactly at
    // the minimum: the same samples as one per pass. Then the film sizes the passes (0).
    const double left = double(session.film_params().adaptive_min_spp) - double(p.samples) / pixels;
    if (left < 1.0) return 0;
    StopConditions warm = stop;
    warm.error = 0.0f;  // the error target is the stopping rule's, not a sample count
    return std::min(auto_samples_per_pass(warm, last, seconds, pixels, p), int(left));
}

size_t unsampled_pixels(const Film& film) {
    size_t n = 0;
    for (int y = 0; y < film.height(); ++y) {
        for (int x = 0; x < film.width(); ++x) n += film.next_sample_index(x, y) == 0 ? 1 : 0;
    }
    return n;
}

RenderProgress run_render(RenderSession& session, const StopConditions& stop,
                          const std::function<void(const RenderProgress&)>& progress) {
    validate(stop);
    if (stop.spp == 0 && stop.seconds == 0.0 && stop.error == 0.0f)
        throw Error("stop: no stop condition (spp, seconds or error; resolve() sets a default)");
    const bool adaptive = session.film_params().adaptive;
    const double pixels = double(session.film().pixel_count());
    const uint64_t budget = stop.spp > 0 ? uint64_t(stop.spp) * uint64_t(pixels) : 0;
    // Without adaptivity, --spp is exact per pixel; with it, a total budget that no pass
    // draws past, and a cap.
    int cap = stop.max_spp;
    if (stop.spp > 0 && !adaptive) cap = std::min(cap, stop.spp);
    const int budget_spp = adaptive ? stop.spp : 0;
    Timer timer;
    RenderProgress p;
    int per_pass = first_samples_per_pass(session, stop);
    for (;;) {
        const PassStats ps = session.render_pass(cap, per_pass, budget_spp);
        const Film& film = session.film();
        p.passes = session.passes();
        p.seconds = timer.seconds();
        p.samples = session.totals().samples;  // drawn, kept or dropped
        p.active_pixels = ps.open_pixels;
        // A full pass over the film: only when someone looks at it.
        if (progress || stop.error > 0.0f) p.mean_relative_error = film.mean_relative_error();
        double frac = 0.0;
        if (budget > 0) frac = std::max(frac, double(p.samples) / double(budget));
        if (stop.seconds > 0.0) frac = std::max(frac, p.seconds / stop.seconds);
        // Kept samples from the counters, not a pass over the film.
        const PathCounters& totals = session.totals();
        p.error_known = totals.samples - totals.nonfinite_dropped >= 2 * uint64_t(pixels);
        if (stop.error > 0.0f && adaptive) {
            // Adaptive: done when every pixel is below the target, so the share of pixels
            // that stopped, not the mean error (below the target long before the last pixel).
            frac = std::max(frac, 1.0 - double(ps.open_pixels) / pixels);
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
        if (progress) progress(p);
        if (done) break;
        per_pass = next_samples_per_pass(session, stop, per_pass, ps.seconds, p);
    }
    return p;
}

}  // namespace kdt
