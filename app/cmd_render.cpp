// `kdtrace render`: renders a scene, a model or the built-in default scene progressively and
// writes PNG (tone-mapped), EXR or PFM (linear) with the render settings as metadata.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>

#include "app/bench_rays.h"
#include "app/commands.h"
#include "renderer/core/error.h"
#include "renderer/core/interrupt.h"
#include "renderer/core/output_path.h"
#include "renderer/io/image_io.h"
#include "renderer/render/prepare.h"
#include "renderer/render/session.h"
#include "renderer/render/settings.h"

namespace kdt::app {

namespace {

struct RenderArgs {
    std::string scene, output = "out.png", env, env_mapping, view, views;
    float env_intensity = 1.0f, env_rotation = 0.0f;
    bool env_intensity_given = false;
    int spp = 0;
    double seconds = 0.0;
    float error = 0.0f;
    int width = 640, height = 480, threads = 0;
    uint64_t seed = 0;
    // kd-tree
    std::string builder = "sah";
    float q = 0.98f;
    int n0 = 5, tree_depth = 0;
    bool no_cache = false;
    std::string cache_dir;
    // path tracing
    int path_depth = 16, rr_depth = 3, spp_per_pass = 1;
    bool no_rr = false, no_env_importance = false, adaptive = false, quiet = false;
    std::string light_sampling = "mis", diffuse_sampling = "cosine", filter = "box";
    float adaptive_threshold = 0.02f;
    int adaptive_min_spp = 16;
    float exposure = 0.0f;
    bool drop_invalid = false;
};

std::string human_seconds(double s) {
    char buf[32];
    if (s < 60.0) {
        std::snprintf(buf, sizeof buf, "%.1fs", s);
    } else {
        std::snprintf(buf, sizeof buf, "%dm%02ds", int(s / 60.0), int(std::fmod(s, 60.0)));
    }
    return buf;
}

void draw_progress(const RenderProgress& p, double pixels) {
    constexpr int kWidth = 30;
    const int filled = int(p.fraction * kWidth + 0.5);
    std::string bar(size_t(filled), '#');
    bar.resize(kWidth, '.');
    const double eta = p.fraction > 0.0 ? p.seconds * (1.0 - p.fraction) / p.fraction : 0.0;
    std::fprintf(stderr, "\r[%s] %3d%% %s ETA %s  %.1f spp  err %.4f  active %zu   ", bar.c_str(),
                 int(p.fraction * 100.0), human_seconds(p.seconds).c_str(),
                 human_seconds(eta).c_str(), double(p.samples) / pixels, p.mean_relative_error,
                 p.active_pixels);
    std::fflush(stderr);
}

// A command line that renders the same image again: every setting spelled out, and the
// sample count that was reached (exact for non-adaptive renders, whatever stopped them).
std::string rerender_command(const RenderArgs& a, const TraceParams& tp, const FilmParams& fp,
                             double spp) {
    std::string c = "kdtrace render";
    if (!a.scene.empty()) c += " '" + a.scene + "'";
    if (!a.env.empty()) c += " --env '" + a.env + "'";
    if (!a.env_mapping.empty()) c += " --env-mapping " + a.env_mapping;
    if (a.env_intensity_given) c += " --env-intensity " + std::to_string(a.env_intensity);
    if (a.env_rotation != 0.0f) c += " --env-rotation " + std::to_string(a.env_rotation);
    c += " --width " + std::to_string(a.width) + " --height " + std::to_string(a.height);
    c += " --seed " + std::to_string(tp.seed);
    c += " --path-depth " + std::to_string(tp.max_depth) + " --rr-depth " +
         std::to_string(tp.rr_min_depth);
    if (!tp.russian_roulette) c += " --no-rr";
    c += std::string(" --light-sampling ") + kLightSamplingNames[size_t(tp.light_sampling)];
    if (!tp.env_importance) c += " --no-env-importance";
    c += std::string(" --diffuse-sampling ") + kDiffuseSamplingNames[size_t(tp.diffuse_sampling)];
    c += std::string(" --filter ") + kPixelFilterNames[size_t(tp.filter)];
    c += " --spp-per-pass " + std::to_string(tp.samples_per_pass);
    c += " --exposure " + std::to_string(fp.exposure);
    if (fp.adaptive) {
        c += " --adaptive --adaptive-threshold " + std::to_string(fp.adaptive_threshold) +
             " --adaptive-min-spp " + std::to_string(fp.adaptive_min_spp);
        if (a.error > 0.0f) c += " --error " + std::to_string(a.error);
    }
    if (!fp.adaptive || a.error <= 0.0f) c += " --spp " + std::to_string(int(std::lround(spp)));
    return c;
}

void run(const RenderArgs& a) {
    TraceParams tp;
    tp.max_depth = a.path_depth;
    tp.rr_min_depth = a.rr_depth;
    tp.russian_roulette = !a.no_rr;
    tp.light_sampling =
        LightSampling(parse_name(kLightSamplingNames, a.light_sampling, "--light-sampling"));
    tp.diffuse_sampling = DiffuseSampling(
        parse_name(kDiffuseSamplingNames, a.diffuse_sampling, "--diffuse-sampling"));
    tp.filter = PixelFilter(parse_name(kPixelFilterNames, a.filter, "--filter"));
    tp.env_importance = !a.no_env_importance;
    tp.samples_per_pass = a.spp_per_pass;
    tp.seed = a.seed;
    tp.threads = a.threads;
    FilmParams fp;
    fp.adaptive = a.adaptive || a.error > 0.0f;
    fp.adaptive_threshold = a.error > 0.0f ? a.error : a.adaptive_threshold;
    fp.adaptive_min_spp = a.adaptive_min_spp;
    fp.exposure = a.exposure;
    if (tp.max_depth < 0) throw Error("--path-depth must be >= 0");
    if (tp.samples_per_pass < 1) throw Error("--spp-per-pass must be >= 1");
    StopConditions stop;
    stop.spp = a.spp;
    stop.seconds = a.seconds;
    stop.error = a.error;
    if (stop.spp == 0 && stop.seconds == 0.0 && stop.error == 0.0f) stop.spp = 16;  // none given
    // Fail before loading and rendering, not after.
    validate(stop);
    check_image_output(a.output);
    check_output(a.output, {a.scene, a.env, a.views}, "the image");

    PrepareOptions po;
    po.scene_path = a.scene;
    po.env_file = a.env;
    po.env_mapping = a.env_mapping;
    if (a.env_intensity_given) po.env_intensity = a.env_intensity;
    po.env_rotation_degrees = a.env_rotation;
    po.width = a.width;
    po.height = a.height;
    po.tree.builder = KdBuilder(parse_name(kKdBuilderNames, a.builder, "--builder"));
    po.tree.q = a.q;
    po.tree.n0 = a.n0;
    po.tree.max_depth = a.tree_depth;
    po.tree.threads = a.threads;
    po.use_cache = !a.no_cache;
    po.cache_dir = a.cache_dir;
    po.drop_invalid = a.drop_invalid;
    if (!a.view.empty()) po.camera = find_view(a.views, a.view);
    po.log = [&](const std::string& line) {
        if (!a.quiet) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
    };
    const Prepared prep = prepare_render(po);
    const RenderSnapshot& snap = *prep.snapshot;
    check_output(a.output, scene_input_files(prep.scene), "the image");

    RenderSession session(prep.snapshot, tp, fp);
    const bool tty = !a.quiet && isatty(fileno(stderr));
    const double pixels = double(session.film().pixel_count());
    std::function<void(const RenderProgress&)> progress;
    if (tty) progress = [&](const RenderProgress& pr) { draw_progress(pr, pixels); };
    // The first SIGINT/SIGTERM ends the render after the tiles in flight; the image is saved.
    interrupt::install(interrupt::Mode::finish_work);
    interrupt::Watcher watcher([&session] { session.cancel(); });
    const RenderProgress p = run_render(session, stop, progress);
    if (tty) std::fprintf(stderr, "\n");

    const Film& film = session.film();
    ImageRGB image(film.width(), film.height());
    image.rgb = film.linear_rgb();
    const PathCounters& c = session.totals();
    const double spp = double(film.total_samples() + c.nonfinite_dropped) / pixels;
    ImageMetadata meta;
    meta.emplace_back("Software", "kdtrace 0.1.0");
    meta.emplace_back("kdtrace:scene", a.scene.empty() ? std::string("builtin:default") : a.scene);
    meta.emplace_back("kdtrace:scene_json", scene_to_json(prep.scene));
    meta.emplace_back("kdtrace:camera", camera_to_json(snap.camera));
    meta.emplace_back("kdtrace:params", params_to_json(tp, fp, po.tree));
    meta.emplace_back("kdtrace:seed", std::to_string(tp.seed));
    meta.emplace_back("kdtrace:spp", std::to_string(spp));
    meta.emplace_back("kdtrace:passes", std::to_string(p.passes));
    meta.emplace_back("kdtrace:command", rerender_command(a, tp, fp, spp));
    if (interrupt::requested())
        meta.emplace_back("kdtrace:interrupted", std::string(interrupt::signal_name()) + " at " +
                                                     std::to_string(spp) + " spp");
    ToneParams tone;
    tone.exposure = fp.exposure;
    write_image(a.output, image, tone, meta);

    const double mrays = p.seconds > 0.0 ? double(c.rays()) / p.seconds * 1e-6 : 0.0;
    std::printf(
        "render: %s: %dx%d, %.2f s, %.1f spp, %.2f Mrays/s (%llu rays: %llu camera, %llu bounce, "
        "%llu shadow; %.1f nodes, %.1f triangles per ray), est. rel. error %.4f, %llu non-finite "
        "dropped, tree %.2f s%s -> %s\n",
        a.scene.empty() ? "default scene" : a.scene.c_str(), film.width(), film.height(), p.seconds,
        spp, mrays, (unsigned long long)c.rays(), (unsigned long long)c.camera_rays,
        (unsigned long long)c.bounce_rays, (unsigned long long)c.shadow_rays,
        double(c.nodes_visited) / double(std::max<uint64_t>(c.rays(), 1)),
        double(c.triangles_tested) / double(std::max<uint64_t>(c.rays(), 1)), p.mean_relative_error,
        (unsigned long long)c.nonfinite_dropped, prep.tree_seconds,
        prep.tree_from_cache ? " (cached)" : "", a.output.c_str());
}

}  // namespace

void add_render_command(CLI::App& parent) {
    static RenderArgs a;
    auto* cmd =
        parent.add_subcommand("render", "Render a scene, a model or the built-in default scene");
    cmd->add_option("SCENE", a.scene,
                    "Scene (.json) or model (.ply, .ply.gz, .obj); omitted = built-in scene");
    cmd->add_option("-o,--output", a.output,
                    "Output image: .png (tone-mapped sRGB), .exr or .pfm (linear)")
        ->capture_default_str();
    auto* spp = cmd->add_option(
        "--spp", a.spp, "Stop at N samples per pixel (adaptive: N x pixels in total); default 16");
    auto* seconds = cmd->add_option("--time", a.seconds, "Stop after S seconds of rendering");
    auto* error = cmd->add_option("--error", a.error,
                                  "Stop when every pixel's relative error is below E (adaptive)");
    cmd->add_option("--env", a.env, "Environment map (.hdr, .exr, .pfm) replacing the scene's");
    cmd->add_option("--view", a.view, "Camera of this view of the views file (A-D for the dragon)");
    cmd->add_option("--views", a.views, "Views file for --view (default assets/views/dragon.json)");
    cmd->add_option("--env-mapping", a.env_mapping, "latlong or angular")->capture_default_str();
    auto* intensity =
        cmd->add_option("--env-intensity", a.env_intensity, "Scale of the environment radiance");
    cmd->add_option("--env-rotation", a.env_rotation,
                    "Extra rotation of the environment about +y, degrees");
    cmd->add_option("--width", a.width, "Image width")->capture_default_str();
    cmd->add_option("--height", a.height, "Image height")->capture_default_str();
    cmd->add_option("--threads", a.threads, "OpenMP threads (0 = all)")->capture_default_str();
    cmd->add_option("--seed", a.seed, "Seed of all randomness")->capture_default_str();
    cmd->add_option("--builder", a.builder, "kd-tree builder: thesis or sah")
        ->capture_default_str();
    cmd->add_option("--q", a.q, "Thesis cost correction q in (0,1]")->capture_default_str();
    cmd->add_option("--n0", a.n0, "Thesis cost correction n0")->capture_default_str();
    cmd->add_option("--depth", a.tree_depth, "kd-tree maximum depth (0 = automatic)")
        ->capture_default_str();
    cmd->add_flag("--no-cache", a.no_cache, "Build the kd-tree without the tree cache");
    cmd->add_option("--cache-dir", a.cache_dir, "Directory of kd-tree cache files");
    cmd->add_option("--path-depth", a.path_depth, "Maximum bounces per path (0 = direct view only)")
        ->capture_default_str();
    cmd->add_option("--rr-depth", a.rr_depth, "Bounces before Russian roulette starts")
        ->capture_default_str();
    cmd->add_flag("--no-rr", a.no_rr, "Switch Russian roulette off");
    cmd->add_option("--light-sampling", a.light_sampling, "bsdf, nee or mis")
        ->capture_default_str();
    cmd->add_flag("--no-env-importance", a.no_env_importance, "Sample the environment uniformly");
    cmd->add_option("--diffuse-sampling", a.diffuse_sampling, "cosine or uniform")
        ->capture_default_str();
    cmd->add_option("--filter", a.filter, "Pixel filter: box or tent")->capture_default_str();
    cmd->add_option("--spp-per-pass", a.spp_per_pass, "Samples per active pixel and pass")
        ->capture_default_str();
    cmd->add_flag("--adaptive", a.adaptive, "Adaptive sampling: stop converged pixels");
    cmd->add_option("--adaptive-threshold", a.adaptive_threshold,
                    "Relative error at which a pixel stops")
        ->capture_default_str();
    cmd->add_option("--adaptive-min-spp", a.adaptive_min_spp, "Samples before a pixel may stop")
        ->capture_default_str();
    cmd->add_option("--exposure", a.exposure, "PNG exposure in stops")->capture_default_str();
    cmd->add_flag("--drop-invalid", a.drop_invalid, "Drop faces with non-finite vertices");
    cmd->add_flag("--quiet", a.quiet, "No progress bar or cache messages");
    cmd->callback([intensity, spp, seconds, error] {
        a.env_intensity_given = intensity->count() > 0;
        // 0 means "not given" inside; given explicitly, it is as wrong as a negative value.
        if (spp->count() > 0 && a.spp == 0) throw Error("render: --spp must be positive (got 0)");
        if (seconds->count() > 0 && a.seconds == 0.0)
            throw Error("render: --time must be a positive number of seconds (got 0)");
        if (error->count() > 0 && a.error == 0.0f)
            throw Error("render: --error must be a positive relative error (got 0)");
        interrupt::install();
        run(a);
        if (interrupt::requested()) interrupt::exit_interrupted();  // 130 or 143
    });
}

}  // namespace kdt::app
