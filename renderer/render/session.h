// A render session: the film, the current snapshot and the parameters, with progressive
// passes, reset and cancel -- the one API the CLI, the viewer and the MPI farm call.
// Passes run OpenMP over 16x16 tiles with dynamic scheduling; any subset of tiles can be
// rendered (MPI split), and the image does not depend on thread count or split because
// every sample is keyed on (seed, pixel, sample index).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
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
    PathCounters counters;
    bool cancelled = false;  ///< cancel() stopped the pass early (finished tiles are kept)
};

class RenderSession {
public:
    static constexpr int kTileSize = 16;

    RenderSession(std::shared_ptr<const RenderSnapshot> snapshot, const TraceParams& trace,
                  const FilmParams& film);

    /// Swaps in a new snapshot; thread-safe. Takes effect, with a reset, at the next pass.
    void set_snapshot(std::shared_ptr<const RenderSnapshot> snapshot);
    /// Changes parameters; the film restarts at the next pass.
    void set_params(const TraceParams& trace, const FilmParams& film);
    /// Clears the film at the start of the next pass; thread-safe.
    void reset() { reset_requested_.store(true); }
    /// Stops the running pass after its tiles in flight; thread-safe. Cleared at the next pass.
    void cancel() { cancel_requested_.store(true); }

    /// One pass: samples_per_pass samples for every active pixel (all pixels without
    /// adaptive sampling). max_spp > 0 caps samples drawn per pixel.
    PassStats render_pass(int max_spp = 0);
    /// The same restricted to the given tile indices (row-major, tile_count() of them).
    PassStats render_pass(const std::vector<int>& tiles, int max_spp = 0);

    int tile_count() const;
    const Film& film() const { return film_; }
    const RenderSnapshot& snapshot() const { return *snapshot_; }
    std::shared_ptr<const RenderSnapshot> snapshot_ptr() const { return snapshot_; }
    const TraceParams& trace_params() const { return trace_; }
    const FilmParams& film_params() const { return film_params_; }
    /// Totals since the last reset.
    const PathCounters& totals() const { return totals_; }
    int passes() const { return passes_; }
    /// Turns per-pixel heat-map accumulation on or off (off by default; needs
    /// TraceParams::count_traversal). Takes effect with the next reset.
    void set_heat_map(bool on) {
        heat_map_ = on;
        reset();
    }
    bool heat_map() const { return heat_map_; }
    /// Per-pixel sums of kd-tree nodes visited and triangles tested (heat maps; empty when
    /// off); divide by
    /// Film::count for per-sample values.
    const std::vector<uint64_t>& heat_nodes() const { return heat_nodes_; }
    const std::vector<uint64_t>& heat_triangles() const { return heat_tris_; }

private:
    void apply_pending();

    std::shared_ptr<const RenderSnapshot> snapshot_;
    std::shared_ptr<const RenderSnapshot> pending_;
    std::mutex pending_mutex_;
    TraceParams trace_;
    FilmParams film_params_;
    Film film_;
    PathCounters totals_;
    int passes_ = 0;
    bool heat_map_ = false;
    std::vector<uint64_t> heat_nodes_, heat_tris_;
    std::atomic<bool> reset_requested_{false};
    std::atomic<bool> cancel_requested_{false};
};

struct RenderProgress {
    int passes = 0;
    double seconds = 0.0;
    double fraction = 0.0;  ///< 0..1 estimate of completion
    uint64_t samples = 0;
    size_t active_pixels = 0;
    double mean_relative_error = 0.0;
    /// False until every pixel has 2 samples: with fewer, no variance is known, and
    /// mean_relative_error is not an estimate (0 at 1 spp).
    bool error_known = false;
};

/// Runs passes until a stop condition holds (or cancel). Calls progress after each pass.
/// Throws kdt::Error when the conditions do not pass validate().
RenderProgress run_render(RenderSession& session, const StopConditions& stop,
                          const std::function<void(const RenderProgress&)>& progress = {});

}  // namespace kdt
