// `kdtrace bench converge`: error against time. Makes (or takes) a high-spp reference, then
// renders progressively with several sampling strategies, recording wall time, rays, RMSE
// and relative MSE at 1, 2, 4, ... N spp; writes CSV, a log-log plot, and checks that the
// error falls as time^(-1/2).
#include <omp.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "app/bench/bench_options.h"
#include "app/bench/bench_rays.h"
#include "app/bench/bench_table.h"
#include "app/bench/run_program.h"
#include "app/commands.h"
#include "app/options_cli.h"
#include "renderer/core/error.h"
#include "renderer/core/output_path.h"
#include "renderer/core/temp_file.h"
#include "renderer/core/timer.h"
#include "renderer/io/image_io.h"
#include "renderer/render/prepare.h"
#include "renderer/render/render_options.h"
#include "renderer/render/session.h"
#include "renderer/render/settings.h"

namespace kdt::app {

namespace {

struct ConvergeArgs {
    std::string scene, env, reference, out_dir = "converge", view, views;
    int width = 256, height = 192, reference_spp = 4096, max_spp = 256, threads = 0;
    uint64_t seed = 0;
    std::string configs = "uniform,bsdf,mis,mis+adaptive";
    float adaptive_threshold = 0.02f;
    bool adaptive_threshold_given = false;
    int path_depth = 16;
    bool no_plot = false;
    bool throughput = false;
    bool no_cache = false;
    int repeats = 3;
};

struct Config {
    std::string name;
    TraceParams trace;
    FilmParams film;
};

Config make_config(const std::string& name, const ConvergeArgs& a) {
    Config c;
    c.name = name;
    c.trace.seed = a.seed;
    c.trace.threads = a.threads;
    c.trace.max_depth = a.path_depth;
    if (name == "uniform") {
        // The naive baseline: uniform hemisphere sampling, no light sampling, no adaptivity.
        c.trace.light_sampling = LightSampling::bsdf;
        c.trace.diffuse_sampling = DiffuseSampling::uniform;
        c.trace.env_importance = false;
    } else if (name == "bsdf") {
        c.trace.light_sampling = LightSampling::bsdf;
    } else if (name == "nee") {
        c.trace.light_sampling = LightSampling::nee;
    } else if (name == "mis-uniform-env") {
        c.trace.env_importance = false;
    } else if (name == "mis") {
    } else if (name == "mis+adaptive") {
        c.film.adaptive = true;
        c.film.adaptive_threshold = a.adaptive_threshold;
        c.film.adaptive_min_spp = 4;
    } else {
        throw Error("--configs: unknown configuration '" + name +
                    "' (uniform, bsdf, nee, mis-uniform-env, mis, mis+adaptive)");
    }
    return c;
}

// The configurations of --configs, each made and checked before anything renders (the
// reference alone takes minutes at the defaults).
std::vector<Config> parse_configs(const ConvergeArgs& a) {
    // Out of range is an error even where no configuration reads it (then it only warns).
    FilmParams threshold;
    threshold.adaptive_threshold = a.adaptive_threshold;
    try {
        validate(threshold);
    } catch (const Error& e) {
        throw Error(with_flags(e.what()));
    }
    std::vector<Config> out;
    std::vector<std::string> names;
    const std::string list = a.configs + ",";
    for (size_t start = 0, comma; (comma = list.find(',', start)) != std::string::npos;
         start = comma + 1) {
        if (comma == start) continue;
        Config c = make_config(list.substr(start, comma - start), a);
        try {
            validate(c.trace);
            validate(c.film);
        } catch (const Error& e) {
            throw Error("--configs " + c.name + ": " + with_flags(e.what()));
        }
        names.push_back(c.name);
        out.push_back(std::move(c));
    }
    if (out.empty())
        throw Error(
            "--configs: no configuration given (uniform, bsdf, nee, mis-uniform-env, mis, "
            "mis+adaptive)");
    refuse_repeated_entries("--configs", names);
    return out;
}

struct Point {
    std::string config;
    double spp = 0.0, seconds = 0.0;
    uint64_t rays = 0;
    double rmse = 0.0, relmse = 0.0;
};

// RMSE over all channels, and relative MSE (squared error over reference^2 + 0.01,
// averaged; Rousselle et al. 2011).
void errors(const std::vector<float>& img, const std::vector<float>& ref, double& rmse,
            double& relmse) {
    double se = 0.0, rel = 0.0;
    for (size_t i = 0; i < img.size(); ++i) {
        const double d = double(img[i]) - double(ref[i]);
        se += d * d;
        rel += d * d / (double(ref[i]) * double(ref[i]) + 0.01);
    }
    rmse = std::sqrt(se / double(img.size()));
    relmse = rel / double(img.size());
}

// Least-squares slope of log(y) against log(x); NaN when it cannot be estimated (fewer than
// two points, or all at one x).
double loglog_slope(const std::vector<double>& x, const std::vector<double>& y) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    const double n = double(x.size());
    for (size_t i = 0; i < x.size(); ++i) {
        const double lx = std::log(x[i]), ly = std::log(y[i]);
        sx += lx;
        sy += ly;
        sxx += lx * lx;
        sxy += lx * ly;
    }
    return n >= 2.0 ? quotient(n * sxy - sx * sy, n * sxx - sx * sx) : std::nan("");
}

// RMSE at time t by log-log interpolation between the recorded points; NaN outside.
double rmse_at(const std::vector<Point>& pts, double t) {
    for (size_t i = 1; i < pts.size(); ++i) {
        if (pts[i - 1].seconds <= t && t <= pts[i].seconds) {
            const double f = (std::log(t) - std::log(pts[i - 1].seconds)) /
                             (std::log(pts[i].seconds) - std::log(pts[i - 1].seconds));
            return std::exp(std::log(pts[i - 1].rmse) +
                            f * (std::log(pts[i].rmse) - std::log(pts[i - 1].rmse)));
        }
    }
    return std::nan("");
}

// scripts/plot_converge.py of the source tree: searched upwards from the executable
// (build/<preset>/bin/kdtrace), then from the working directory.
std::filesystem::path find_plot_script() {
    namespace fs = std::filesystem;
    std::error_code ec;
    for (fs::path dir :
         {fs::read_symlink("/proc/self/exe", ec).parent_path(), fs::current_path(ec)}) {
        for (int up = 0; up < 5 && !dir.empty(); ++up, dir = dir.parent_path()) {
            const fs::path p = dir / "scripts" / "plot_converge.py";
            if (fs::exists(p, ec)) return p;
        }
    }
    return "scripts/plot_converge.py";
}

// Shading overhead: the path tracer's rays per second against raw kd-tree traversal of the
// very same rays (recorded from the same samples), same threads; medians of a.repeats runs.
void run_throughput(const ConvergeArgs& a, const RenderSnapshot& snap,
                    const std::shared_ptr<const RenderSnapshot>& snap_ptr) {
    TraceParams tp;
    tp.seed = a.seed;
    tp.threads = a.threads;
    tp.max_depth = a.path_depth;
    tp.samples_per_pass = 4;
    // One path at a time, as the replay traces one ray per query: the ratio is the shading's
    // overhead, not the wavefront's stream gain (docs/performance.md measures that).
    tp.wavefront = false;
    const int threads = a.threads > 0 ? a.threads : omp_get_max_threads();
    // The rays in the render pass's order (tile by tile, row by row, pixel by pixel, sample
    // by sample), so the replay has the same memory locality; the camera rays (each sample's
    // first closest-hit query) apart: the render pass traces them with the batch query in
    // groups of up to 16, and so does the replay; bounce and shadow rays go one query per
    // ray in both.
    RayRecord rec;
    std::vector<Ray> camera_rays;
    const int width = snap.camera.width, height = snap.camera.height;
    constexpr int kTile = RenderSession::kTileSize;
    for (int y0 = 0; y0 < height; y0 += kTile) {
        for (int x0 = 0; x0 < width; x0 += kTile) {
            for (int y = y0; y < std::min(y0 + kTile, height); ++y) {
                for (int x = x0; x < std::min(x0 + kTile, width); ++x) {
                    for (int s = 0; s < tp.samples_per_pass; ++s) {
                        const size_t first = rec.closest.size();
                        record_rays(*snap.scene, snap.camera, tp, x, y, uint32_t(s), rec);
                        camera_rays.push_back(rec.closest[first]);
                        rec.closest.erase(rec.closest.begin() + ptrdiff_t(first));
                    }
                }
            }
        }
    }
    constexpr int64_t kGroup = 16;
    const KdTree& tree = *snap.scene->tree;
    std::vector<double> pt_rates, pt_nc_rates, raw_rates;
    for (int r = 0; r < a.repeats; ++r) {
        // The path tracer as shipped (traversal counters on), then without the counters.
        RenderSession session(snap_ptr, tp, FilmParams{});
        const PassStats ps = session.render_pass();
        pt_rates.push_back(double(ps.counters.rays()) / ps.seconds * 1e-6);
        TraceParams tp_nc = tp;
        tp_nc.count_traversal = false;
        RenderSession session_nc(snap_ptr, tp_nc, FilmParams{});
        const PassStats ps_nc = session_nc.render_pass();
        pt_nc_rates.push_back(double(ps_nc.counters.rays()) / ps_nc.seconds * 1e-6);

        Timer timer;
        const auto nc = int64_t(rec.closest.size()), na = int64_t(rec.any.size());
        const auto ncam = int64_t(camera_rays.size());
        uint64_t hits = 0;
#pragma omp parallel num_threads(threads) reduction(+ : hits)
        {
#pragma omp for schedule(dynamic, 16) nowait
            for (int64_t g = 0; g < ncam; g += kGroup) {
                Hit h[kGroup];
                const int64_t m = std::min(kGroup, ncam - g);
                tree.intersect(camera_rays.data() + g, size_t(m), h);
                for (int64_t i = 0; i < m; ++i) hits += h[i].prim != Hit::kNoHit;
            }
#pragma omp for schedule(dynamic, 256) nowait
            for (int64_t i = 0; i < nc; ++i) {
                Hit h;
                hits += tree.intersect(rec.closest[size_t(i)], h);
            }
#pragma omp for schedule(dynamic, 256)
            for (int64_t i = 0; i < na; ++i) hits += tree.occluded(rec.any[size_t(i)]);
        }
        const double secs = timer.seconds();
        raw_rates.push_back(double(ncam + nc + na) / secs * 1e-6);
        std::printf(
            "  run %d: path tracer %.3f Mrays/s (%llu rays; %.3f without traversal counters), "
            "raw traversal %.3f Mrays/s (%lld camera + %lld closest + %lld any-hit, %llu "
            "hits)\n",
            r + 1, pt_rates.back(), (unsigned long long)ps.counters.rays(), pt_nc_rates.back(),
            raw_rates.back(), (long long)ncam, (long long)nc, (long long)na,
            (unsigned long long)hits);
        std::fflush(stdout);
    }
    const double pt = median(pt_rates), pt_nc = median(pt_nc_rates), raw = median(raw_rates);
    std::printf(
        "throughput: path tracer %.3f Mrays/s, raw traversal %.3f Mrays/s, ratio %.3f (without "
        "traversal counters %.3f Mrays/s, ratio %.3f; medians of %d, %d threads)\n",
        pt, raw, pt / raw, pt_nc, pt_nc / raw, a.repeats, threads);
    // The same in time per ray and thread: what shading, sampling and the film add to each
    // ray's traversal (negative if the path tracer's traversal ran faster than the replay).
    const double ns_pt = threads * 1e3 / pt, ns_raw = threads * 1e3 / raw;
    std::printf(
        "per ray and thread: path tracer %.1f ns, raw traversal %.1f ns, difference %.1f ns "
        "(without traversal counters %.1f ns)\n",
        ns_pt, ns_raw, ns_pt - ns_raw, threads * 1e3 / pt_nc - ns_raw);
}

void run(const ConvergeArgs& a) {
    namespace fs = std::filesystem;
    if (a.max_spp < 1 || a.reference_spp < 1)
        throw Error("--max-spp and --reference-spp must be >= 1");
    const std::vector<Config> configs = parse_configs(a);
    // Only mis+adaptive reads the threshold; said as render says its --adaptive-* flags have
    // no effect without adaptive sampling.
    if (a.adaptive_threshold_given) {
        if (a.throughput) {
            std::fprintf(stderr,
                         "kdtrace: warning: --adaptive-threshold has no effect with --throughput "
                         "(it renders none of --configs)\n");
        } else if (std::none_of(configs.begin(), configs.end(),
                                [](const Config& c) { return c.film.adaptive; })) {
            std::fprintf(stderr,
                         "kdtrace: warning: --adaptive-threshold has no effect without "
                         "mis+adaptive in --configs\n");
        }
    }
    // The reference and the outputs are checked before the reference render (minutes).
    const std::vector<std::string> inputs = {a.scene, a.env, a.views};
    ImageRGB given_ref;
    if (!a.reference.empty()) {
        std::string ext = fs::path(a.reference).extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(),
                       [](unsigned char c) { return char(std::tolower(c)); });
        if (ext != ".exr" && ext != ".pfm") {
            throw Error(
                "--reference " + a.reference +
                ": must be .exr or .pfm (a linear image; a PNG is tone-mapped and clipped)");
        }
        if (fs::exists(a.reference)) {
            given_ref = load_image(a.reference);
        } else {
            check_output(a.reference, inputs, "the reference");
        }
    }
    create_output_directory("-o", a.out_dir);
    std::vector<std::string> outputs = {"converge.csv"};
    if (a.reference.empty()) outputs.push_back("reference.exr");
    if (!a.no_plot) outputs.push_back("converge.png");
    for (const std::string& name : outputs)
        check_output((fs::path(a.out_dir) / name).string(), inputs, "a bench converge output");
    RenderOptions ro;
    ro.scene.scene_path = a.scene;
    ro.scene.env_file = a.env;
    ro.scene.width = a.width;
    ro.scene.height = a.height;
    ro.tree.threads = a.threads;
    ro.scene.use_cache = !a.no_cache;
    if (!a.view.empty()) ro.scene.camera = find_view(a.views, a.view);
    const Prepared prep = prepare_render(ro);
    std::printf("bench converge: %s%s%s, %dx%d, tree %.2f s\n",
                a.scene.empty() ? "default scene" : a.scene.c_str(), a.env.empty() ? "" : " under ",
                a.env.c_str(), a.width, a.height, prep.tree_seconds);
    if (!a.view.empty()) warn_view_model(a.views, "--view " + a.view, a.scene, prep.scene);
    if (a.throughput) {
        run_throughput(a, *prep.snapshot, prep.snapshot);
        return;
    }

    // Reference: given, or rendered with MIS at reference_spp under an independent seed.
    ImageRGB ref;
    if (given_ref.width > 0) {
        ref = std::move(given_ref);
        if (ref.width != a.width || ref.height != a.height) {
            throw Error(ErrorLocation{a.reference}, "reference is " + std::to_string(ref.width) +
                                                        "x" + std::to_string(ref.height) +
                                                        ", expected " + std::to_string(a.width) +
                                                        "x" + std::to_string(a.height));
        }
        std::printf("reference: %s\n", a.reference.c_str());
    } else {
        TraceParams& tp = ro.trace;
        tp.seed = a.seed ^ 0x5eed5eed5eedull;
        tp.threads = a.threads;
        tp.max_depth = a.path_depth;
        tp.samples_per_pass = 16;
        RenderSession rs(prep.snapshot, tp, FilmParams{});
        ro.stop.spp = a.reference_spp;
        const RenderProgress p = run_render(rs, ro.stop);
        ref = ImageRGB(a.width, a.height);
        ref.rgb = rs.film().linear_rgb();
        const std::string path =
            a.reference.empty() ? (fs::path(a.out_dir) / "reference.exr").string() : a.reference;
        write_image(path, ref, {},
                    {{"kdtrace:params", options_to_json(ro)},
                     {"kdtrace:spp", std::to_string(a.reference_spp)}});
        std::printf("reference: %d spp in %.1f s -> %s\n", a.reference_spp, p.seconds,
                    path.c_str());
    }

    std::vector<Point> points;
    std::vector<std::vector<Point>> curves;
    for (const Config& cfg : configs) {
        RenderSession s(prep.snapshot, cfg.trace, cfg.film);
        const double pixels = double(s.film().pixel_count());
        std::vector<Point> curve;
        double seconds = 0.0;
        uint64_t rays = 0;
        for (int target = 1; target <= a.max_spp; target *= 2) {
            // Passes until the film holds target x pixels samples (exactly target per pixel
            // without adaptivity); only rendering is timed.
            for (;;) {
                const double done = double(s.totals().samples);
                if (done >= double(target) * pixels) break;
                const PassStats ps = s.render_pass(cfg.film.adaptive ? 0 : target);
                seconds += ps.seconds;
                rays += ps.counters.rays();
                if (ps.active_pixels == 0) break;
            }
            Point pt;
            pt.config = cfg.name;
            pt.spp = double(s.film().total_samples()) / pixels;
            pt.seconds = seconds;
            pt.rays = rays;
            errors(s.film().linear_rgb(), ref.rgb, pt.rmse, pt.relmse);
            curve.push_back(pt);
            points.push_back(pt);
            std::printf("  %-16s %7.1f spp %9.3f s %12llu rays  RMSE %.5f  relMSE %.6f\n",
                        cfg.name.c_str(), pt.spp, pt.seconds, (unsigned long long)pt.rays, pt.rmse,
                        pt.relmse);
        }
        curves.push_back(curve);
    }

    const std::string csv = (fs::path(a.out_dir) / "converge.csv").string();
    {
        std::ostringstream out;
        out << "config,spp,seconds,rays,rmse,relmse\n";
        for (const Point& p : points) {
            out << p.config << ',' << p.spp << ',' << p.seconds << ',' << p.rays << ',' << p.rmse
                << ',' << p.relmse << '\n';
        }
        const std::string text = out.str();
        write_file_atomically(csv, text.data(), text.size());
    }
    std::printf("wrote %s\n", csv.c_str());

    // Slopes of log RMSE against log time, from 4 spp on (the first passes carry fixed costs).
    std::printf(
        "\n| config | slope of log RMSE vs log time | RMSE at %d spp | seconds "
        "|\n|---|---|---|---|\n",
        a.max_spp);
    double common_t = kInfinity;
    for (const auto& c : curves) {
        std::vector<double> t, e;
        for (const Point& p : c) {
            if (p.spp >= 4.0 && p.seconds > 0.0 && p.rmse > 0.0) {
                t.push_back(p.seconds);
                e.push_back(p.rmse);
            }
        }
        // Too few points (a run of fewer than 8 spp) leave the slope, and so its verdict, open.
        const double slope = loglog_slope(t, e);
        const char* verdict = !std::isfinite(slope) ? ""
                              : std::abs(slope + 0.5) <= 0.15
                                  ? " (close to -1/2)"
                                  : " (NOT close to -1/2: reference noise or bias?)";
        std::printf("| %s | %s%s | %.5f | %.3f |\n", c.front().config.c_str(),
                    fmt("%.3f", slope).c_str(), verdict, c.back().rmse, c.back().seconds);
        common_t = std::min(common_t, c.back().seconds);
    }
    // Equal-time comparison against the first configuration (the baseline).
    if (curves.size() >= 2) {
        std::printf("\nequal time %.3f s: RMSE ratio against %s:\n", common_t,
                    curves.front().front().config.c_str());
        const double base = rmse_at(curves.front(), common_t);
        for (size_t i = 1; i < curves.size(); ++i) {
            const double e = rmse_at(curves[i], common_t);
            std::printf("  %-16s %s\n", curves[i].front().config.c_str(),
                        fmt("%.3f", quotient(e, base)).c_str());
        }
    }
    if (!a.no_plot) {
        const std::string png = (fs::path(a.out_dir) / "converge.png").string();
        const fs::path script = find_plot_script();
        // Debian's interpreter has python3-matplotlib; a python3 earlier in PATH may not.
        const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
        // An argument vector, not a shell command: any character in the paths is plain.
        if (fs::exists(script) && run_program({python, script.string(), csv, png}) == 0) {
            std::printf("wrote %s\n", png.c_str());
        } else {
            std::printf("plot skipped: needs python3-matplotlib and %s\n", script.string().c_str());
        }
    }
}

// The upper bound of a field of the render's scene options (scene.width), so that the help
// states what the render accepts.
double scene_field_max(const char* name) {
    for (const Field<SceneOptions>& f : scene_fields())
        if (std::strcmp(f.name, name) == 0) return f.max;
    throw std::logic_error(std::string("no scene field ") + name);
}

}  // namespace

void add_bench_converge_command(CLI::App& parent) {
    static ConvergeArgs a;
    auto* cmd =
        parent.add_subcommand("converge", "Error against time for several sampling strategies");
    non_empty_file_name(
        cmd->add_option("SCENE", a.scene, "Scene or model; omitted = built-in default scene"),
        "SCENE", " (omit SCENE for the built-in scene)");
    non_empty_file_name(cmd->add_option("--env", a.env, "Environment map replacing the scene's"),
                        "--env");
    cmd->add_option("--view", a.view,
                    "Camera of this view of the views file (the kd-tree bench's views A-D)");
    non_empty_file_name(cmd->add_option("--views", a.views,
                                        "Views file for --view (default assets/views/dragon.json)"),
                        "--views", " (omit --views for assets/views/dragon.json)");
    non_empty_file_name(
        cmd->add_option("--reference", a.reference,
                        "Reference image (.exr/.pfm); rendered and written there when missing"),
        "--reference");
    cmd->add_option("--reference-spp", a.reference_spp, "Samples per pixel of a new reference")
        ->capture_default_str()
        ->check(in_range(1, 1 << 20));
    cmd->add_option("--max-spp", a.max_spp, "Largest N of the 1, 2, 4 ... N spp series")
        ->capture_default_str()
        ->check(in_range(1, 65536));
    cmd->add_option("--width", a.width, "Image width")
        ->capture_default_str()
        ->check(in_range(1, scene_field_max("width")));
    cmd->add_option("--height", a.height, "Image height")
        ->capture_default_str()
        ->check(in_range(1, scene_field_max("height")));
    cmd->add_option("--threads", a.threads, "OpenMP threads (0 = all)")
        ->capture_default_str()
        ->check(in_range(0, 1024));
    cmd->add_option("--seed", a.seed, "Seed of all randomness")->capture_default_str();
    cmd->add_option("--path-depth", a.path_depth, "Maximum bounces")
        ->capture_default_str()
        ->check(in_range(0, 1024));
    cmd->add_option(
           "--configs", a.configs,
           "Comma-separated: uniform, bsdf, nee, mis-uniform-env, mis, mis+adaptive; the first "
           "is the equal-time baseline")
        ->capture_default_str();
    cmd->add_option("--adaptive-threshold", a.adaptive_threshold,
                    "mis+adaptive: relative error to stop at")
        ->capture_default_str();
    non_empty_file_name(
        cmd->add_option("-o,--out-dir", a.out_dir, "Directory for reference, CSV and plot")
            ->capture_default_str(),
        "-o");
    cmd->add_flag("--no-plot", a.no_plot, "Do not run scripts/plot_converge.py");
    cmd->add_flag("--no-cache", a.no_cache, "Build the kd-tree without the tree cache");
    cmd->add_flag("--throughput", a.throughput,
                  "Instead: path tracer rays/s against raw traversal of the same rays");
    cmd->add_option("--repeats", a.repeats, "--throughput: runs (median)")
        ->capture_default_str()
        ->check(in_range(1, 1000));
    cmd->callback([cmd] {
        a.adaptive_threshold_given = cmd->count("--adaptive-threshold") > 0;
        run(a);
    });
}

}  // namespace kdt::app
