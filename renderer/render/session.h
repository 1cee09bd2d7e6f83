// A render session: the film, the current snapshot and the parameters, with progressive
// passes, reset and cancel -- the one API the CLI, the viewer and the MPI farm call.
// Passes run OpenMP over 16x16 tiles (render_tile) with dynamic scheduling; finished tiles are
// published for other threads to read (copy_image, inspect); any subset of tiles can be
// rendered (MPI split), and the image does not depend on thread count or split because
// every sample is keyed on (seed, pixel, sample index).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "renderer/film/film.h"
#include "renderer/integrator/path_tracer.h"
#include "renderer/render/render_options.h"
#include "renderer/render/snapshot.h"

namespace kdt {

/// What one pass did.
struct PassStats {
    double seconds = 0.0;
    size_t active_pixels = 0;  ///< pixels that took samples in this pass
    /// Pixels not yet stopped at the start of the pass (Film::open_count); with adaptive
    /// sampling a pass samples only some of them.
    size_t open_pixels = 0;
    PathCounters counters;
    bool cancelled = false;  ///< cancel() stopped the pass early (finished tiles are kept)
};

/// The image as published tile by tile while passes run (RenderSession::copy_image): every
/// tile in it is whole, from the end of some pass since the last reset.
struct FilmImage {
    int width = 0, height = 0;
    std::vector<float> rgb;  ///< linear mean radiance, 3 floats per pixel, top row first
    /// Per-sample kd-tree nodes visited and triangles tested (heat maps); filled only when
    /// asked for and the heat map is on, else empty.
    std::vector<float> heat_nodes, heat_triangles;
    /// The normals and depth views (AOVs); filled only when asked for and on, else empty.
    /// aov_normals: the mean aov_shading_normal() of the samples whose camera ray hits (3
    /// floats a pixel; not renormalised), 0 where none did. aov_depth: their mean distance
    /// along the camera ray (scene units); +infinity where every sample escaped (sky), 0
    /// where the pixel has no samples yet.
    std::vector<float> aov_normals, aov_depth;
    uint64_t version = 0;     ///< grows with every published tile and every reset
    uint64_t generation = 0;  ///< grows with every reset (camera, parameters, snapshot)
    int complete_passes = 0;  ///< passes of this generation that finished uncancelled
};

/// One pixel as published (RenderSession::inspect).
struct PixelInfo {
    Vec3f rgb{0.0f};           ///< linear mean radiance
    uint32_t samples = 0;      ///< finite samples accumulated
    float relative_error = 0;  ///< Film::relative_error (infinite below 2 samples)
    float nodes_per_sample = 0, triangles_per_sample = 0;  ///< heat counters (0 when off)
    Vec3f normal{0.0f};  ///< FilmImage::aov_normals of the pixel (0 when off)
    float depth = 0.0f;  ///< FilmImage::aov_depth of the pixel (0 when off)
};

/// Thread safety: the setters, reset(), cancel(), copy_image() and inspect() may be called
/// from any thread while another runs passes; a change is applied, with a reset, at the start
/// of the next pass. Everything else (render_pass, film(), totals(), ...) belongs to the one
/// thread that runs the passes.
class RenderSession {
public:
    static constexpr int kTileSize = 16;

    RenderSession(std::shared_ptr<const RenderSnapshot> snapshot, const TraceParams& trace,
                  const FilmParams& film);

    /// Swaps in a new snapshot (with its camera) at the next pass, with a reset.
    void set_snapshot(std::shared_ptr<const RenderSnapshot> snapshot);
    /// Views the current (or pending) snapshot's scene through `camera` from the next pass,
    /// with a reset; the film takes the camera's size. Copies no scene data.
    void set_camera(const Camera& camera);
    /// Changes parameters at the next pass, with a reset. Throws kdt::Error (and changes
    /// nothing) for invalid parameters.
    void set_params(const TraceParams& trace, const FilmParams& film);
    /// Turns per-pixel heat-map accumulation on or off at the next pass, with a reset (off by
    /// default; needs TraceParams::count_traversal).
    void set_heat_map(bool on);
    /// Turns accumulation of the normals and depth views (FilmImage::aov_*) on or off at the
    /// next pass, with a reset (off by default). They read the camera rays' hits and change
    /// no radiance.
    void set_aov(bool on);
    /// Clears the film at the start of the next pass.
    void reset() { reset_requested_.store(true); }
    /// Stops the running pass after its tiles in flight (at most one per thread). Cleared at
    /// the start of the next pass.
    void cancel() { cancel_requested_.store(true); }

    /// One pass: samples_per_pass samples for every active pixel (all pixels without
    /// adaptive sampling; per_pass > 0 replaces trace_params().samples_per_pass for this
    /// pass, and 0 there means 1). max_spp > 0 caps samples drawn per pixel. budget_spp > 0
    /// caps totals().samples (drawn since the last reset) at budget_spp times the film's
    /// pixels, both as they are after pending changes: a pass that could draw past it gives
    /// each active pixel its share of what is left, and when that is less than one sample
    /// each, one sample to the first active pixels in tile order and none to the rest. The
    /// image of a render that stays within the budget does not change.
    PassStats render_pass(int max_spp = 0, int per_pass = 0, int budget_spp = 0);
    /// The same restricted to the given tile indices (row-major, tile_count() of them); the
    /// budget is shared by those tiles' pixels.
    PassStats render_pass(const std::vector<int>& tiles, int max_spp = 0, int per_pass = 0,
                          int budget_spp = 0);

    /// Copies the published image (and with `layers`, the heat maps and AOVs that are on)
    /// into `out` when its version differs from out.version; returns whether it copied. Holds
    /// a lock for one copy only.
    bool copy_image(FilmImage& out, bool layers = false) const;
    /// The published pixel (x, y); nullopt outside the image.
    std::optional<PixelInfo> inspect(int x, int y) const;
    /// Whether finished tiles are published for copy_image() and inspect() (on by default).
    /// A caller that reads only film() after the passes, such as `kdtrace render`, turns it
    /// off and saves the copy per tile. Call between passes.
    void set_publishing(bool on) { publishing_ = on; }

    int tile_count() const;
    const Film& film() const { return film_; }
    const RenderSnapshot& snapshot() const { return *snapshot_; }
    std::shared_ptr<const RenderSnapshot> snapshot_ptr() const { return snapshot_; }
    const TraceParams& trace_params() const { return trace_; }
    const FilmParams& film_params() const { return film_params_; }
    /// Totals since the last reset.
    const PathCounters& totals() const { return totals_; }
    int passes() const { return passes_; }
    bool heat_map() const { return heat_map_; }
    bool aov() const { return aov_; }
    /// Per-pixel sums of kd-tree nodes visited and triangles tested (heat maps; empty when
    /// off); divide by Film::count for per-sample values.
    const std::vector<uint64_t>& heat_nodes() const { return heat_nodes_; }
    const std::vector<uint64_t>& heat_triangles() const { return heat_tris_; }

private:
    struct Pending {
        std::shared_ptr<const RenderSnapshot> snapshot;
        std::optional<Camera> camera;
        std::optional<TraceParams> trace;
        std::optional<FilmParams> film;
        std::optional<bool> heat_map;
        std::optional<bool> aov;
    };
    struct Published {
        FilmImage image;
        std::vector<uint32_t> samples;
        std::vector<float> error, nodes, triangles;
        bool heat = false;                  ///< nodes and triangles are counted
        std::vector<float> normals, depth;  ///< FilmImage::aov_*; empty when off
    };

    void apply_pending();
    /// The pixels of tile `tile` (row-major, kTileSize square, cut at the film's edges).
    FilmRect tile_rect(int tile) const;
    PassStats run_tiles(const std::vector<int>& tiles, int max_spp, int per_pass, int budget_spp);
    /// The samples per active pixel of a pass of `per_pass` over `tiles` cut to what is left
    /// of the budget (render_pass's budget_spp times the film's pixels), deactivating pixels
    /// when that is below one each.
    int fit_budget(const std::vector<int>& tiles, int per_pass, size_t active, int budget_spp);
    void reset_published();
    void publish_tile(int x0, int y0, int x1, int y1);
    /// Film::update_active for the next pass, whose active pixels take at least per_pass
    /// samples (0 counts as 1).
    size_t update_active(int max_spp, int per_pass);

    std::shared_ptr<const RenderSnapshot> snapshot_;
    TraceParams trace_;
    FilmParams film_params_;
    Film film_;
    PathCounters totals_;
    int passes_ = 0;
    bool heat_map_ = false;
    bool publishing_ = true;
    std::vector<uint64_t> heat_nodes_, heat_tris_;
    /// Adaptive sampling's cost model: work (sample_work() in session.cpp) and samples per
    /// tile since the last reset, and from them each pixel's cost per sample (its tile's).
    std::vector<uint64_t> tile_work_, tile_samples_;
    std::vector<float> pixel_cost_;
    bool aov_ = false;
    std::vector<float> aov_normal_, aov_depth_;  ///< per-pixel sums (TileTarget::aov_*)
    std::vector<uint32_t> aov_hits_;
    std::atomic<bool> reset_requested_{false};
    std::atomic<bool> cancel_requested_{false};

    std::mutex pending_mutex_;
    Pending pending_;  // guarded by pending_mutex_

    mutable std::mutex published_mutex_;
    Published published_;  // guarded by published_mutex_
};

struct RenderProgress {
    int passes = 0;
    double seconds = 0.0;
    double fraction = 0.0;  ///< 0..1 estimate of completion
    uint64_t samples = 0;
    size_t active_pixels = 0;  ///< pixels not yet stopped (PassStats::open_pixels)
    double mean_relative_error = 0.0;
    /// False until every pixel has 2 samples: with fewer, no variance is known, and
    /// mean_relative_error is not an estimate (0 at 1 spp).
    bool error_known = false;
};

/// Largest pass run_render() picks for samples_per_pass 0 (automatic).
inline constexpr int kMaxAutoSamplesPerPass = 16;

/// The samples per pixel of a render's first pass, as RenderSession::render_pass()'s
/// per_pass: 1 when samples_per_pass is 0 (automatic), without adaptive sampling (the image
/// does not depend on the pass sizes) and for a time limit; else 0 (the session's own),
/// except that a samples_per_pass above stop.spp is cut to stop.spp: the first adaptive
/// pass samples every pixel, so a larger one would spend the spp budget many times over
/// before any pixel could stop (--spp 1 --spp-per-pass 65536 drawing 65536 spp). A first
/// pass of 1 spp gives every pixel a sample soon, so that a time limit or an interrupt does
/// not leave whole tiles unsampled behind a large --spp-per-pass.
inline int first_samples_per_pass(const RenderSession& session, const StopConditions& stop = {}) {
    const int per_pass = session.trace_params().samples_per_pass;
    if (per_pass == 0 || !session.film_params().adaptive || stop.seconds > 0.0) return 1;
    if (stop.spp > 0 && per_pass > stop.spp) return stop.spp;
    return 0;
}

/// The per_pass of the next pass after one of `last` samples per pixel that took `seconds`,
/// with `p` the render's progress after it (samples, seconds, error). With samples_per_pass
/// 0 (automatic), without adaptive sampling, at most kMaxAutoSamplesPerPass, the samples
/// left to an spp target, about a second of work, half of the time left to a time target,
/// and for an error target a quarter of the samples the error's 1/sqrt(n) decay predicts (1
/// while no error is known); the image does not depend on the pass sizes. With adaptive
/// sampling, the warm-up to adaptive_min_spp in such passes, ending exactly at the minimum,
/// then 0 (the film sizes the passes). With an explicit samples_per_pass, 0 (the session's
/// own), or for a time target at most half of the time left, as automatic passes.
int next_samples_per_pass(const RenderSession& session, const StopConditions& stop, int last,
                          double seconds, const RenderProgress& p);

/// Pixels of `film` that drew no sample (kept or dropped): after a cancelled first pass, the
/// tiles it did not reach, written black.
size_t unsampled_pixels(const Film& film);

/// Runs passes until a stop condition holds (or cancel). Calls progress after each pass.
/// With samples_per_pass 0 and no adaptive sampling, the first pass takes 1 sample per
/// pixel and later ones up to kMaxAutoSamplesPerPass, fewer as the stop conditions near
/// and so that a pass takes about a second at most: the image is the same for any pass
/// size (each sample is a function of its pixel and index, added in index order), and
/// several samples of one pixel in a row trace as coherent camera packets.
/// Throws kdt::Error when the conditions do not pass validate().
RenderProgress run_render(RenderSession& session, const StopConditions& stop,
                          const std::function<void(const RenderProgress&)>& progress = {});

}  // namespace kdt
