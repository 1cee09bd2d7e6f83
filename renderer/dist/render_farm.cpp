#include "renderer/dist/render_farm.h"

#include <mpi.h>

#include <omp.h>

#include <algorithm>
#include <cstring>

#include "renderer/core/error.h"

namespace kdt::dist {

namespace {

FilmRect tile_rect(const Film& film, int tile) {
    constexpr int s = RenderSession::kTileSize;
    const int tiles_x = (film.width() + s - 1) / s;
    const int x0 = (tile % tiles_x) * s, y0 = (tile / tiles_x) * s;
    return {x0, y0, std::min(x0 + s, film.width()), std::min(y0 + s, film.height())};
}

PathCounters reduce_counters(const PathCounters& mine) {
    static_assert(sizeof(PathCounters) == 7 * sizeof(uint64_t));
    uint64_t in[7], out[7] = {};
    std::memcpy(in, &mine, sizeof in);
    MPI_Reduce(in, out, 7, MPI_UINT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
    PathCounters sum;
    std::memcpy(&sum, out, sizeof out);
    return sum;
}

// Whether a render stops on decisions over the whole film after each pass (adaptive
// sampling, an error target, a time limit) rather than on a fixed count per pixel.
bool decides_per_pass(const FilmParams& film, const StopConditions& stop) {
    return film.adaptive || stop.spp <= 0 || stop.error > 0.0f || stop.seconds > 0.0;
}

int tiles_x(const Camera& c) {
    return (c.width + RenderSession::kTileSize - 1) / RenderSession::kTileSize;
}

// Farmed images travel without their coverage (alpha): `what` are tiles or frames.
void check_opaque(const RenderOptions& o, const char* what) {
    if (o.film.transparent) {
        throw Error(std::string("a distributed render (--mpi) cannot be transparent yet: ") + what +
                    " travel without their coverage (film.transparent)");
    }
}

}  // namespace

void render_tiles_to_spp(RenderSession& session, const std::vector<int>& tiles, int spp,
                         const std::function<void()>& poll) {
    const int per_pass = std::max(session.trace_params().samples_per_pass, 1);
    for (int drawn = 0; drawn < spp; drawn += per_pass) {
        session.render_pass(tiles, spp);
        if (poll) poll();
    }
}

std::vector<int> fixed_pass_sizes(int samples_per_pass, int spp) {
    const int per_pass = samples_per_pass > 0 ? samples_per_pass : kMaxAutoSamplesPerPass;
    std::vector<int> sizes;
    for (int drawn = 0; drawn < spp; drawn += sizes.back())
        sizes.push_back(std::min(drawn == 0 ? 1 : per_pass, spp - drawn));
    return sizes;
}

int render_frame(RenderSession& session, const StopConditions& stop,
                 const std::function<void()>& poll, int tiles_per_part) {
    if (decides_per_pass(session.film_params(), stop)) {
        // Passes decide over the whole film (active pixels, budget, mean error): a pass is
        // the smallest part that leaves the render as run_render's.
        return run_render(session, stop, [&poll](const RenderProgress&) { poll(); }).passes;
    }
    // Every part in run_render's passes, so that the frame's pass count is the local
    // render's; the image does not depend on the pass sizes.
    const std::vector<int> sizes =
        fixed_pass_sizes(session.trace_params().samples_per_pass, stop.spp);
    std::vector<int> all(size_t(session.tile_count()));
    for (size_t i = 0; i < all.size(); ++i) all[i] = int(i);
    const size_t step = size_t(std::max(tiles_per_part, 1));
    for (size_t i = 0; i < all.size(); i += step) {
        const std::vector<int> part(all.begin() + long(i),
                                    all.begin() + long(std::min(i + step, all.size())));
        for (int n : sizes) session.render_pass(part, stop.spp, n);
        poll();
    }
    return int(sizes.size());
}

void check_tile_farm_options(const RenderOptions& o) {
    if (decides_per_pass(o.film, o.stop)) {
        throw Error(
            "a tiled render (--mpi without --frames) takes a fixed stop.spp without "
            "film.adaptive, stop.error or stop.seconds: adaptive sampling keeps a pixel going "
            "while the largest error in its 3x3 neighbourhood, across tile borders, is above "
            "the threshold and stops on totals over the whole image, and a time limit depends "
            "on each rank's speed, so a tile rendered apart would not equal the same pixels of "
            "the single-process render; adaptive frames can be farmed whole (--frames)");
    }
    check_opaque(o, "tiles");
}

void check_frame_farm_options(const RenderOptions& o) {
    if (o.stop.seconds > 0.0) {
        throw Error(
            "a frame farm (--mpi --frames) cannot stop on stop.seconds: each image would "
            "depend on the speed and load of the rank that draws it (and rank 0 serves the "
            "others while it renders); use stop.spp or stop.error");
    }
    check_opaque(o, "frames");
}

FarmResult render_tile_farm(const MpiContext& ctx, std::shared_ptr<const RenderSnapshot> snapshot,
                            const RenderOptions& options, FarmParams params, Film* film,
                            const FarmProgress& progress) {
    check_tile_farm_options(options);
    RenderSession session(snapshot, options.trace, options.film);
    const int spp = options.stop.spp;
    params.columns = tiles_x(snapshot->camera);
    if (ctx.rank() == 0) film->resize(snapshot->camera.width, snapshot->camera.height);

    // Rank 0 serves the workers after every pass of its own tiles: answering only between
    // its batches, it would answer a worker, that renders batches as long as its own, about
    // one batch late, just as the worker runs out of work, and both would idle.
    const RenderItems render = [&](const std::vector<int>& tiles,
                                   const std::function<void()>& poll) {
        render_tiles_to_spp(session, tiles, spp, poll);
        const Film& f = session.film();
        size_t pixels = 0;
        for (int t : tiles) pixels += tile_rect(f, t).pixel_count();
        std::vector<char> bytes(pixels * sizeof(FilmPixel));
        auto* out = reinterpret_cast<FilmPixel*>(bytes.data());
        for (int t : tiles) {
            const FilmRect r = tile_rect(f, t);
            f.export_tile(r, std::span<FilmPixel>(out, r.pixel_count()));
            out += r.pixel_count();
        }
        return bytes;
    };
    const ConsumeItems consume = [&](const std::vector<int>& tiles, const char* bytes,
                                     size_t size) {
        size_t off = 0;
        for (int t : tiles) {
            const FilmRect r = tile_rect(*film, t);
            const size_t n = r.pixel_count();
            if ((off + n) * sizeof(FilmPixel) > size) throw Error("tile farm: short result");
            std::vector<FilmPixel> px(n);
            std::memcpy(px.data(), bytes + off * sizeof(FilmPixel), n * sizeof(FilmPixel));
            film->import_tile(r, px);
            off += n;
        }
    };
    const ResultSize size = [&](const std::vector<int>& tiles) {
        size_t pixels = 0;
        for (int t : tiles) pixels += tile_rect(session.film(), t).pixel_count();
        return pixels * sizeof(FilmPixel);
    };
    FarmResult out;
    out.ranks = run_farm(ctx, session.tile_count(), params, render, size, consume, progress);
    out.counters = reduce_counters(session.totals());
    return out;
}

FarmResult render_frame_farm(const MpiContext& ctx, const std::vector<FrameJob>& frames,
                             FarmParams params, const FrameDone& done,
                             const FarmProgress& progress) {
    for (const FrameJob& f : frames) check_frame_farm_options(f.options);
    params.columns = 1;  // strips: rank r renders frames [r F / N, (r + 1) F / N)
    params.batch = 1;
    // Rank 0 answers between parts of two tiles per thread, a small share of a frame, so a
    // worker waits little for its next frame; one frame requested ahead would instead sit in
    // a worker's queue at the end while the other ranks have nothing left. Adaptive frames
    // answer only between passes, so they keep one frame ahead.
    bool fixed = true;
    for (const FrameJob& f : frames)
        fixed = fixed && !decides_per_pass(f.options.film, f.options.stop);
    params.batches_in_flight = fixed ? 1 : 2;
    PathCounters mine;
    const RenderItems render = [&](const std::vector<int>& items,
                                   const std::function<void()>& poll) {
        std::vector<char> bytes;
        for (int frame : items) {
            const FrameJob& job = frames[size_t(frame)];
            RenderSession session(job.snapshot, job.options.trace, job.options.film);
            session.set_publishing(false);
            // Rank 0 serves workers between parts of its own frame (poll is a no-op
            // elsewhere); two tiles per thread keep the parts short.
            const int threads =
                job.options.trace.threads > 0 ? job.options.trace.threads : omp_get_max_threads();
            const int32_t passes =
                render_frame(session, job.options.stop, poll, 2 * std::max(threads, 1));
            mine += session.totals();
            const Film& f = session.film();
            const std::vector<FilmPixel> px = f.export_tile(FilmRect{0, 0, f.width(), f.height()});
            const size_t at = bytes.size(), pixels = px.size() * sizeof(FilmPixel);
            bytes.resize(at + pixels + sizeof passes);
            std::memcpy(bytes.data() + at, px.data(), pixels);
            std::memcpy(bytes.data() + at + pixels, &passes, sizeof passes);
        }
        return bytes;
    };
    const ConsumeItems consume = [&](const std::vector<int>& items, const char* bytes,
                                     size_t size) {
        size_t off = 0;
        for (int frame : items) {
            const Camera& c = frames[size_t(frame)].snapshot->camera;
            Film film(c.width, c.height);
            const size_t pixels = film.pixel_count() * sizeof(FilmPixel);
            int32_t passes = 0;
            if (off + pixels + sizeof passes > size)
                throw Error("frame farm: result of the wrong size");
            std::vector<FilmPixel> px(film.pixel_count());
            std::memcpy(px.data(), bytes + off, pixels);
            std::memcpy(&passes, bytes + off + pixels, sizeof passes);
            if (passes < 1) {
                throw Error("frame farm: frame " + std::to_string(frame) + " came with " +
                            std::to_string(passes) + " passes");
            }
            film.import_tile(FilmRect{0, 0, film.width(), film.height()}, px);
            done(frame, film, passes);
            off += pixels + sizeof passes;
        }
        if (off != size) throw Error("frame farm: result of the wrong size");
    };
    const ResultSize size = [&](const std::vector<int>& items) {
        size_t pixels = 0;
        for (int frame : items) {
            const Camera& c = frames[size_t(frame)].snapshot->camera;
            pixels += size_t(c.width) * size_t(c.height);
        }
        return pixels * sizeof(FilmPixel) + items.size() * sizeof(int32_t);  // and the passes
    };
    FarmResult out;
    out.ranks = run_farm(ctx, int(frames.size()), params, render, size, consume, progress);
    out.counters = reduce_counters(mine);
    return out;
}

}  // namespace kdt::dist
