// Distributed renders over MPI: the tiles of one frame, or whole frames of a sequence, farmed
// out by run_farm(). Every rank renders with its own RenderSession over its own snapshot
// (prepare_everywhere); a pixel's samples are keyed on (seed, pixel, sample index) and all of
// a pixel's samples are drawn by one rank, so the image is bitwise the single-process
// render's for any number of ranks and any distribution.
// Compiled only with MPI. Depends on dist/work_farm, render.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "renderer/dist/work_farm.h"
#include "renderer/render/session.h"

namespace kdt::dist {

/// Draws samples for `tiles` of the session's film until each of their pixels has `spp`
/// (passes of the session's samples_per_pass, capped at spp), calling `poll` (if set) after
/// every pass. Non-adaptive films only.
void render_tiles_to_spp(RenderSession& session, const std::vector<int>& tiles, int spp,
                         const std::function<void()>& poll = {});

/// Renders the session's whole frame as run_render(session, stop) does, bitwise, calling
/// `poll` between parts: between batches of `tiles_per_part` tiles for a fixed stop.spp
/// without adaptive sampling, after every pass otherwise. Returns the passes each pixel got:
/// for a fixed stop.spp without adaptive sampling those of fixed_pass_sizes() (every batch
/// gets all of them), else run_render's count.
int render_frame(RenderSession& session, const StopConditions& stop,
                 const std::function<void()>& poll, int tiles_per_part);

/// The samples per pixel of each pass of a render to a fixed `spp` without adaptive sampling,
/// as run_render() sizes them when no automatic pass meets its time bound (about a second,
/// next_samples_per_pass()): 1 first, then `samples_per_pass` (kMaxAutoSamplesPerPass when
/// 0, automatic), the last one cut to reach `spp`. Empty for spp <= 0.
std::vector<int> fixed_pass_sizes(int samples_per_pass, int spp);

/// Throws kdt::Error unless `options` (resolved) is a tiled render (one frame split over
/// the ranks) that the farm reproduces exactly: a fixed stop.spp without adaptive sampling,
/// error target or time limit. Adaptive sampling is not local to a tile: after every pass a
/// pixel stays active while the largest error in its 3x3 neighbourhood (across tile borders)
/// is above the threshold, and the render stops on totals over the whole image (the sample
/// budget, the mean error); a time limit depends on each rank's speed.
void check_tile_farm_options(const RenderOptions& options);

/// Throws kdt::Error unless `options` (resolved) is a frame a frame farm reproduces exactly.
/// A whole frame is rendered by one rank with run_render(), so adaptive sampling and error
/// targets are allowed; a time limit (stop.seconds) is not, since the image would depend on
/// the speed and load of the rank that draws it.
void check_frame_farm_options(const RenderOptions& options);

struct FarmResult {
    std::vector<RankStats> ranks;  ///< rank 0: one per rank
    PathCounters counters;         ///< rank 0: summed over all ranks
};

/// Collective: the tiles of `snapshot`'s film (RenderSession::kTileSize squares, row-major),
/// `batch` tiles at a time; rank 0's `film` (sized like the camera) receives every tile.
FarmResult render_tile_farm(const MpiContext& ctx, std::shared_ptr<const RenderSnapshot> snapshot,
                            const RenderOptions& options, FarmParams params, Film* film,
                            const FarmProgress& progress = {});

/// One frame of a sequence: what to render (scene and camera) and how (trace, film, stop).
struct FrameJob {
    std::shared_ptr<const RenderSnapshot> snapshot;
    RenderOptions options;  ///< resolved; check_frame_farm_options() holds
};
/// Rank 0: a finished frame, as RenderSession::film() leaves it, and the passes it took
/// (render_frame()'s count, on whichever rank drew it).
using FrameDone = std::function<void(int frame, const Film& film, int passes)>;

/// Collective: whole frames (every rank holds the same list), one at a time per rank, handed
/// out by `params`' distribution (strips: consecutive frames per rank); results are films
/// and their passes, sent to rank 0 and passed to `done`. Each frame is rendered by
/// render_frame(); rank 0 serves workers between its parts.
FarmResult render_frame_farm(const MpiContext& ctx, const std::vector<FrameJob>& frames,
                             FarmParams params, const FrameDone& done,
                             const FarmProgress& progress = {});

}  // namespace kdt::dist
