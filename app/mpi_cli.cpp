#include "app/mpi_cli.h"

#include "app/options_cli.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <regex>

#include <nlohmann/json.hpp>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/io/image_io.h"
#include "renderer/render/prepare.h"
#include "renderer/render/session.h"
#include "renderer/render/settings.h"
#ifdef KDT_HAVE_MPI
#include <mpi.h>

#include "renderer/dist/render_farm.h"
#endif

namespace kdt::app {

void add_dist_options(CLI::App& app, DistArgs& a) {
    app.add_flag("--mpi", a.mpi,
                 "Split the render over the ranks of mpirun (every rank loads the scene and the "
                 "tree cache itself: a shared filesystem is assumed)");
    app.add_option("--distribution", a.distribution,
                   "How --mpi hands out work: dynamic (a queue served on request), interleaved "
                   "(every n-th tile to rank n) or strips (one band of tile rows per rank)")
        ->check(CLI::IsMember({"dynamic", "interleaved", "strips"}))
        ->capture_default_str();
    app.add_option("--tile-batch", a.batch, "Tiles per --mpi work message (0 = threads per rank)")
        ->check(CLI::Range(0, 1 << 16));
    app.add_option("--timeout", a.timeout_seconds,
                   "With --mpi: abort every rank after this many seconds (0 = never)")
        ->check(CLI::Range(0.0, 1e9));
    app.add_option("--frames", a.frames,
                   "Render a sequence of this many frames (with --turntable); -o is then a "
                   "pattern such as frame_%03d.png")
        ->check(CLI::Range(1, 1 << 20));
    app.add_flag("--turntable", a.turntable,
                 "The --frames orbit the camera about its up axis through its target");
    app.add_option("--mpi-stats", a.stats_file, "With --mpi: rank 0 writes per-rank stats (JSON)");
    app.add_option("--throttle", a.throttle,
                   "Test only: RANK:FACTOR makes that rank sleep (FACTOR - 1) x its render time");
    app.add_option("--mpi-inject", a.inject,
                   "Test only: RANK:load (the rank cannot open the scene) or RANK:hash (the "
                   "rank reports a different tree)");
}

CameraDesc turntable_camera(const CameraDesc& c, int frame, int frames) {
    const double angle = 2.0 * 3.14159265358979323846 * double(frame) / double(frames);
    const glm::dvec3 k = glm::normalize(glm::dvec3(c.up));
    const glm::dvec3 v = glm::dvec3(c.eye) - glm::dvec3(c.target);
    // Rodrigues' rotation of the eye's offset about the unit axis k.
    const glm::dvec3 r = v * std::cos(angle) + glm::cross(k, v) * std::sin(angle) +
                         k * glm::dot(k, v) * (1.0 - std::cos(angle));
    CameraDesc out = c;
    out.eye = Vec3f(glm::dvec3(c.target) + r);
    return out;
}

std::string frame_path(const std::string& pattern, int frame) {
    static const std::regex conversion("%0?[0-9]{0,2}d");
    const auto count = std::distance(
        std::sregex_iterator(pattern.begin(), pattern.end(), conversion), std::sregex_iterator());
    const auto percents = std::count(pattern.begin(), pattern.end(), '%');
    if (count != 1 || percents != 1) {
        throw Error(pattern +
                    ": a --frames output needs exactly one frame number conversion such as %03d "
                    "(and no other %)");
    }
    char buf[4096];
    std::snprintf(buf, sizeof buf, pattern.c_str(), frame);
    return buf;
}

namespace {

void write_film(const std::string& path, const Film& film, const RenderOptions& o,
                const Camera& camera, const std::string& how) {
    ImageRGB image(film.width(), film.height());
    image.rgb = film.linear_rgb();
    ImageMetadata meta;
    meta.emplace_back("Software", "kdtrace 0.1.0");
    const std::string& scene = o.scene.scene_path;
    meta.emplace_back("kdtrace:scene", scene.empty() ? std::string("builtin:default") : scene);
    meta.emplace_back("kdtrace:camera", camera_to_json(camera));
    meta.emplace_back("kdtrace:params", options_to_json(o));
    meta.emplace_back("kdtrace:seed", std::to_string(o.trace.seed));
    meta.emplace_back("kdtrace:spp", std::to_string(o.stop.spp));
    meta.emplace_back("kdtrace:distribution", how);
    ToneParams tone;
    tone.exposure = o.film.exposure;
    write_image(path, image, tone, meta);
}

std::shared_ptr<const RenderSnapshot> frame_snapshot(const RenderSnapshot& base,
                                                     const RenderOptions& o, int frame,
                                                     int frames) {
    // A copy shares the mesh, tree and environment; only the camera changes.
    auto s = std::make_shared<RenderSnapshot>(base);
    s->camera_desc = turntable_camera(base.camera_desc, frame, frames);
    s->camera = make_camera(s->camera_desc, o.scene.width, o.scene.height);
    return s;
}

// The sequence flags and the output (its pattern, and, when check_output, its directory).
void check_frames(const std::string& output, const DistArgs& a, bool check_output = true) {
    if (a.frames > 0 && !a.turntable)
        throw Error("--frames needs --turntable (the one kind of sequence so far)");
    if (a.turntable && a.frames == 0) throw Error("--turntable needs --frames N");
    const std::string first = a.frames > 0 ? frame_path(output, 0) : output;
    if (check_output) check_image_output(first);
}

// --frames without --mpi: every frame in this process, with any stop condition.
void run_local_frames(const RenderOptions& o, const std::string& output, bool quiet,
                      const DistArgs& a) {
    const Prepared prep = prepare_render(o, [&](const std::string& line) {
        if (!quiet) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
    });
    Timer timer;
    for (int f = 0; f < a.frames; ++f) {
        const auto snap = frame_snapshot(*prep.snapshot, o, f, a.frames);
        RenderSession session(snap, o.trace, o.film);
        run_render(session, o.stop);
        const std::string path = frame_path(output, f);
        write_film(path, session.film(), o, snap->camera, "local");
        if (!quiet)
            std::fprintf(stderr, "kdtrace: frame %d/%d -> %s\n", f + 1, a.frames, path.c_str());
    }
    std::printf("render: %d frames %dx%d, %.2f s, %d spp -> %s\n", a.frames, o.scene.width,
                o.scene.height, timer.seconds(), o.stop.spp, output.c_str());
}

}  // namespace

#ifdef KDT_HAVE_MPI
namespace {

std::pair<int, std::string> rank_and(const std::string& spec, const char* flag) {
    const auto colon = spec.find(':');
    try {
        if (colon != std::string::npos)
            return {std::stoi(spec.substr(0, colon)), spec.substr(colon + 1)};
    } catch (const std::exception&) {
    }
    throw Error(std::string(flag) + " takes RANK:VALUE (got '" + spec + "')");
}

dist::FarmParams farm_params(const DistArgs& a, const RenderOptions& o) {
    dist::FarmParams p;
    p.distribution =
        dist::Distribution(parse_name(dist::kDistributionNames, a.distribution, "--distribution"));
    const int threads = o.trace.threads > 0 ? o.trace.threads : 1;
    p.batch = a.batch > 0 ? a.batch : threads;
    if (!a.throttle.empty()) {
        const auto [rank, factor] = rank_and(a.throttle, "--throttle");
        p.throttle_rank = rank;
        p.throttle_factor = std::stod(factor);
        if (!(p.throttle_factor >= 1.0)) throw Error("--throttle: FACTOR must be >= 1");
    }
    return p;
}

void report(const std::vector<dist::RankStats>& ranks, const DistArgs& a, const char* unit,
            int items, double seconds) {
    double busy = 0.0;
    for (const dist::RankStats& r : ranks) {
        std::printf("mpi: rank %d: %d %s, busy %.3f s, idle %.3f s, %llu messages, %llu bytes\n",
                    r.rank, r.items, unit, r.busy_seconds, std::max(0.0, seconds - r.busy_seconds),
                    (unsigned long long)r.messages, (unsigned long long)r.bytes);
        busy += r.busy_seconds;
    }
    const double eff = seconds > 0.0 ? busy / (double(ranks.size()) * seconds) : 0.0;
    std::printf("mpi: %zu ranks, %s, %d %s, %.3f s, efficiency %.3f (busy / (ranks x wall))\n",
                ranks.size(), a.distribution.c_str(), items, unit, seconds, eff);
    if (a.stats_file.empty()) return;
    nlohmann::json j;
    j["ranks"] = ranks.size();
    j["distribution"] = a.distribution;
    j["items"] = items;
    j["seconds"] = seconds;
    for (const dist::RankStats& r : ranks) {
        j["per_rank"].push_back({{"rank", r.rank},
                                 {"items", r.items},
                                 {"busy_seconds", r.busy_seconds},
                                 {"wall_seconds", r.wall_seconds},
                                 {"cpu_seconds", r.cpu_seconds},
                                 {"messages", r.messages},
                                 {"bytes", r.bytes}});
    }
    std::ofstream(a.stats_file) << j.dump(1) << "\n";
}

void draw_farm_progress(int done, int total, double seconds, const char* unit) {
    constexpr int kWidth = 30;
    const double f = total > 0 ? double(done) / double(total) : 1.0;
    std::string bar(size_t(f * kWidth + 0.5), '#');
    bar.resize(kWidth, '.');
    const double eta = f > 0.0 ? seconds * (1.0 - f) / f : 0.0;
    std::fprintf(stderr, "\r[%s] %3d%% %.1fs ETA %.1fs  %d/%d %s   ", bar.c_str(), int(f * 100.0),
                 seconds, eta, done, total, unit);
    std::fflush(stderr);
}

void run_mpi(dist::MpiContext& ctx, RenderOptions o, const std::string& output, bool quiet,
             const DistArgs& a) {
    ctx.start_watchdog(a.timeout_seconds);
    const bool root = ctx.rank() == 0;
    // Rank 0's options are everyone's; the checks are collective, so that a bad flag stops
    // every rank with one message instead of leaving some waiting.
    const std::string json = ctx.broadcast(options_to_json(o));
    dist::FarmParams params;
    dist::InjectedFault fault;
    dist::check_every_rank(ctx, "could not start", [&]() -> uint64_t {
        options_from_json(json, o, "rank 0's options");
        dist::check_farm_options(o);
        check_frames(output, a, root);  // only rank 0 writes
        params = farm_params(a, o);
        if (!a.inject.empty())
            std::tie(fault.rank, fault.what) = rank_and(a.inject, "--mpi-inject");
        return 0;
    });
    const Prepared prep = dist::prepare_everywhere(
        ctx, o,
        [&](const std::string& line) {
            if (root && !quiet) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
        },
        fault);
    const bool tty = root && !quiet && isatty(fileno(stderr));
    Timer timer;
    const char* unit = a.frames > 0 ? "frames" : "tiles";
    dist::FarmProgress progress;
    if (tty)
        progress = [&](int done, int total) {
            draw_farm_progress(done, total, timer.seconds(), unit);
        };
    const std::string how = a.distribution + " over " + std::to_string(ctx.size()) + " ranks";
    dist::FarmResult result;
    int items = 0;
    if (a.frames > 0) {
        items = a.frames;
        result = dist::render_frame_farm(
            ctx, a.frames, [&](int f) { return frame_snapshot(*prep.snapshot, o, f, a.frames); }, o,
            params,
            [&](int f, const Film& film) {
                const auto cam =
                    make_camera(turntable_camera(prep.snapshot->camera_desc, f, a.frames),
                                o.scene.width, o.scene.height);
                write_film(frame_path(output, f), film, o, cam, how);
            },
            progress);
    } else {
        Film film;
        result = dist::render_tile_farm(ctx, prep.snapshot, o, params, &film, progress);
        if (root) write_film(output, film, o, prep.snapshot->camera, how);
        items = (film.width() + RenderSession::kTileSize - 1) / RenderSession::kTileSize *
                ((film.height() + RenderSession::kTileSize - 1) / RenderSession::kTileSize);
    }
    const double seconds = timer.seconds();
    if (tty) std::fprintf(stderr, "\n");
    if (!root) return;
    const PathCounters& c = result.counters;
    report(result.ranks, a, unit, items, seconds);
    std::printf(
        "render: %s: %dx%d, %.2f s, %d spp, %.2f Mrays/s over %d ranks (%llu rays, %llu "
        "non-finite dropped) -> %s\n",
        o.scene.scene_path.empty() ? "default scene" : o.scene.scene_path.c_str(), o.scene.width,
        o.scene.height, seconds, o.stop.spp,
        seconds > 0.0 ? double(c.rays()) / seconds * 1e-6 : 0.0, ctx.size(),
        (unsigned long long)c.rays(), (unsigned long long)c.nonfinite_dropped, output.c_str());
}

}  // namespace
#endif

void run_dist_render(const RenderOptions& options, const std::string& output, bool quiet,
                     const DistArgs& a) {
    if (!a.mpi) {
        check_frames(output, a);
        run_local_frames(options, output, quiet, a);
        return;
    }
#ifdef KDT_HAVE_MPI
    bool failed = false;
    {
        dist::MpiContext ctx;
        try {
            run_mpi(ctx, options, output, quiet, a);
        } catch (const dist::FarmError& e) {
            // Printed before MPI_Finalize: mpirun ends the job once any rank has exited
            // non-zero, which could otherwise cut rank 0 off before its message.
            if (e.report())
                std::fprintf(stderr, "kdtrace: error: %s\n", with_flags(e.what()).c_str());
            std::fflush(stderr);
            failed = true;
        } catch (const std::exception& e) {
            // A failure of this rank alone after the collective checks: the others may be
            // waiting for it, so the whole job ends here.
            std::fprintf(stderr, "kdtrace: error: rank %d: %s\n", ctx.rank(), e.what());
            std::fflush(stderr);
            MPI_Abort(MPI_COMM_WORLD, 1);
        }
    }
    if (failed) std::exit(1);
#else
    throw Error("--mpi: this kdtrace was built without MPI (KDT_WITH_MPI off or MPI not found)");
#endif
}

}  // namespace kdt::app
