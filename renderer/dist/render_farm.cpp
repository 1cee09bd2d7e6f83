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

int tiles_x(const Camera& c) {
    return (c.width + RenderSession::kTileSize - 1) / RenderSession::kTileSize;
}

}  // namespace

void render_tiles_to_spp(RenderSession& session, const std::vector<int>& tiles, int spp) {
    const int per_pass = std::max(session.trace_params().samples_per_pass, 1);
    for (int drawn = 0; drawn < spp; drawn += per_pass) session.render_pass(tiles, spp);
}

void check_farm_options(const RenderOptions& o) {
    if (o.film.adaptive || o.stop.error > 0.0f || o.stop.seconds > 0.0 || o.stop.spp <= 0) {
        throw Error(
            "a distributed render (--mpi) takes a fixed stop.spp without film.adaptive, "
            "stop.error or stop.seconds: adaptive sampling decides each pixel from its "
            "neighbours across tile borders, and a time limit depends on each rank's speed, so "
            "neither image would be the same for every split");
    }
    if (o.film.transparent)
        throw Error(
            "a distributed render (--mpi) cannot be transparent yet: tiles travel "
            "without their coverage (film.transparent)");
}

FarmResult render_tile_farm(const MpiContext& ctx, std::shared_ptr<const RenderSnapshot> snapshot,
                            const RenderOptions& options, FarmParams params, Film* film,
                            const FarmProgress& progress) {
    check_farm_options(options);
    RenderSession session(snapshot, options.trace, options.film);
    const int spp = options.stop.spp;
    params.columns = tiles_x(snapshot->camera);
    if (ctx.rank() == 0) film->resize(snapshot->camera.width, snapshot->camera.height);

    const RenderItems render = [&](const std::vector<int>& tiles, const std::function<void()>&) {
        render_tiles_to_spp(session, tiles, spp);
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
    FarmResult out;
    out.ranks = run_farm(ctx, session.tile_count(), params, render, consume, progress);
    out.counters = reduce_counters(session.totals());
    return out;
}

FarmResult render_frame_farm(const MpiContext& ctx, int frames, const FrameSnapshot& snapshot,
                             const RenderOptions& options, FarmParams params, const FrameDone& done,
                             const FarmProgress& progress) {
    check_farm_options(options);
    const int spp = options.stop.spp;
    params.columns = 1;  // strips: rank r renders frames [r F / N, (r + 1) F / N)
    params.batch = 1;
    PathCounters mine;
    const RenderItems render = [&](const std::vector<int>& items,
                                   const std::function<void()>& poll) {
        std::vector<char> bytes;
        for (int frame : items) {
            RenderSession session(snapshot(frame), options.trace, options.film);
            std::vector<int> all(size_t(session.tile_count()));
            for (size_t i = 0; i < all.size(); ++i) all[i] = int(i);
            if (ctx.rank() == 0) {
                // Rank 0 serves workers between batches of tiles of its own frame.
                const int threads =
                    options.trace.threads > 0 ? options.trace.threads : omp_get_max_threads();
                const size_t step = size_t(std::max(threads, 1)) * 2;
                for (size_t i = 0; i < all.size(); i += step) {
                    const std::vector<int> part(all.begin() + long(i),
                                                all.begin() + long(std::min(i + step, all.size())));
                    render_tiles_to_spp(session, part, spp);
                    poll();
                }
            } else {
                render_tiles_to_spp(session, all, spp);
            }
            mine += session.totals();
            const Film& f = session.film();
            const std::vector<FilmPixel> px = f.export_tile(FilmRect{0, 0, f.width(), f.height()});
            const size_t at = bytes.size();
            bytes.resize(at + px.size() * sizeof(FilmPixel));
            std::memcpy(bytes.data() + at, px.data(), px.size() * sizeof(FilmPixel));
        }
        return bytes;
    };
    Film film(options.scene.width, options.scene.height);
    const ConsumeItems consume = [&](const std::vector<int>& items, const char* bytes,
                                     size_t size) {
        const size_t each = film.pixel_count() * sizeof(FilmPixel);
        if (size != each * items.size()) throw Error("frame farm: result of the wrong size");
        for (size_t k = 0; k < items.size(); ++k) {
            std::vector<FilmPixel> px(film.pixel_count());
            std::memcpy(px.data(), bytes + k * each, each);
            film.import_tile(FilmRect{0, 0, film.width(), film.height()}, px);
            done(items[k], film);
        }
    };
    FarmResult out;
    out.ranks = run_farm(ctx, frames, params, render, consume, progress);
    out.counters = reduce_counters(mine);
    return out;
}

}  // namespace kdt::dist
