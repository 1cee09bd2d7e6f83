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
/// (passes of the session's samples_per_pass, capped at spp). Non-adaptive films only.
void render_tiles_to_spp(RenderSession& session, const std::vector<int>& tiles, int spp);

/// Throws kdt::Error unless `options` (resolved) is a render a farm reproduces exactly: a
/// fixed stop.spp without adaptive sampling, time limit or error target. (Adaptive sampling
/// decides per pixel from its 3x3 neighbourhood, across tile borders, and a time limit
/// depends on speed: neither is a function of the pixel alone.)
void check_farm_options(const RenderOptions& options);

struct FarmResult {
    std::vector<RankStats> ranks;  ///< rank 0: one per rank
    PathCounters counters;         ///< rank 0: summed over all ranks
};

/// Collective: the tiles of `snapshot`'s film (RenderSession::kTileSize squares, row-major),
/// `batch` tiles at a time; rank 0's `film` (sized like the camera) receives every tile.
FarmResult render_tile_farm(const MpiContext& ctx, std::shared_ptr<const RenderSnapshot> snapshot,
                            const RenderOptions& options, FarmParams params, Film* film,
                            const FarmProgress& progress = {});

/// The snapshot of frame i of a sequence (called on the rank that renders it).
using FrameSnapshot = std::function<std::shared_ptr<const RenderSnapshot>(int frame)>;
/// Rank 0: a finished frame, as RenderSession::film() leaves it.
using FrameDone = std::function<void(int frame, const Film& film)>;

/// Collective: whole frames [0, frames), one at a time per rank, handed out by `params`'
/// distribution (strips: consecutive frames per rank); results are films sent to rank 0 and passed
/// to `done`. Rank 0 renders its own frames in tile batches and serves workers in between.
FarmResult render_frame_farm(const MpiContext& ctx, int frames, const FrameSnapshot& snapshot,
                             const RenderOptions& options, FarmParams params, const FrameDone& done,
                             const FarmProgress& progress = {});

}  // namespace kdt::dist
