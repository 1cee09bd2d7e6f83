// `kdtrace render`: renders a scene, a model or the built-in default scene progressively and
// writes PNG (tone-mapped), EXR, PFM or Radiance HDR (linear), PNG and EXR with the render
// settings as metadata.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include "app/commands.h"
#include "app/mpi_cli.h"
#include "app/options_cli.h"
#include "app/rescue.h"
#include "renderer/core/error.h"
#include "renderer/core/interrupt.h"
#include "renderer/core/output_path.h"
#include "renderer/core/shell_word.h"
#include "renderer/io/image_io.h"
#include "renderer/render/prepare.h"
#include "renderer/render/session.h"
#include "renderer/render/settings.h"
#include "renderer/scene/views.h"

namespace kdt::app {

namespace {

// What `render` takes besides the render options.
struct RenderCommand {
    RenderOptions options;
    std::string output = "out.png";
    bool quiet = false;
    DistArgs dist;  // --mpi, --frames (app/mpi_cli.h)
    /// Files the options were read from (--session, --views): inputs the output must not be.
    std::vector<std::string> option_files;
    bool env_rotation_given = false;  // --env-rotation on the command line
    std::string view, views;          // --view and --views as given (empty: not given)
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
    const std::string eta =
        p.fraction > 0.0 ? human_seconds(p.seconds * (1.0 - p.fraction) / p.fraction) : "?";
    char err[32] = "err ?";
    if (p.error_known) std::snprintf(err, sizeof err, "err %.4f", p.mean_relative_error);
    std::fprintf(stderr, "\r[%s] %3d%% %s ETA %s  %.1f spp  %s  active %zu   ", bar.c_str(),
                 int(p.fraction * 100.0), human_seconds(p.seconds).c_str(), eta.c_str(),
                 double(p.samples) / pixels, err, p.active_pixels);
    std::fflush(stderr);
}

// Appends to a command line every option of `s` that differs from its default, spelled out
// by its own flag. `skip` names flags not to write (a flag shared by two groups is written
// once, from the first).
template <class S>
void append_flags(std::string& c, const S& s, std::span<const Field<S>> fields,
                  std::initializer_list<const char*> skip = {}) {
    const S defaults{};
    for (const Field<S>& f : fields) {
        if (!f.flag) continue;
        if (std::any_of(skip.begin(), skip.end(),
                        [&](const char* k) { return std::strcmp(k, f.flag) == 0; }))
            continue;
        const std::string value = field_text(f, s);
        if (value == field_text(f, defaults)) continue;
        const FieldRef r = f.at(s);
        if (std::holds_alternative<bool*>(r)) {
            c += std::string(" ") + f.flag;  // differs from the default: the flag flips it
        } else {
            c += std::string(" ") + f.flag + " " + value;
        }
    }
}

std::string vec3_text(const Vec3f& v) {
    return detail::number_text(v.x) + "," + detail::number_text(v.y) + "," +
           detail::number_text(v.z);
}

// The options that render the same image again, as `o` rendered it with `spp` samples per
// pixel reached: the stop conditions that decided it (exact for non-adaptive renders, whatever
// stopped them), so that the image's command and its session (kdtrace:params) agree.
RenderOptions reproducing_options(const RenderOptions& o, double spp) {
    RenderOptions r = o;
    StopConditions& stop = r.stop;
    stop = StopConditions{};
    stop.max_spp = o.stop.max_spp;  // the per-pixel cap shapes adaptive and --error renders
    if (o.film.adaptive && o.stop.error > 0.0f) {
        stop.error = o.stop.error;  // the error target sets the threshold (resolve())
        stop.spp = o.stop.spp;      // a budget given with it, which may stop the render first
        // resolve() turns these on again from the target; without it (a session given other
        // stop flags) the render is not adaptive, as one from the same flags.
        r.film.adaptive_threshold = FilmParams{}.adaptive_threshold;
        r.film.adaptive = false;
    } else if (o.film.adaptive && o.stop.spp > 0 && o.stop.seconds <= 0.0 &&
               !interrupt::requested()) {
        stop.spp = o.stop.spp;  // the budget decides an adaptive render, not the mean reached
    } else {
        // A time limit or a signal stopped it where the run happened to be.
        stop.spp = std::max(1, int(std::lround(spp)));
    }
    return r;
}

// `camera` is the camera the image was rendered with: spelled out whenever the options
// replace any part of the scene's (--view, --eye, ..., a session's camera), since a views
// file may change and --view is resolved when the options are parsed. `o` is
// reproducing_options()'s.
std::string rerender_command(const RenderOptions& o, const CameraDesc& camera) {
    std::string c = "kdtrace render";
    const SceneOptions& sc = o.scene;
    if (!sc.scene_path.empty()) c += " " + shell_word(sc.scene_path);
    if (!sc.env_file.empty()) c += " --env " + shell_word(sc.env_file);
    if (!sc.env_mapping.empty()) c += " --env-mapping " + sc.env_mapping;
    if (sc.env_intensity) c += " --env-intensity " + detail::number_text(*sc.env_intensity);
    if (sc.camera || sc.eye || sc.target || sc.up || sc.vfov_degrees) {
        c += " --eye " + vec3_text(camera.eye) + " --target " + vec3_text(camera.target) +
             " --up " + vec3_text(camera.up) + " --fov " + detail::number_text(camera.vfov_degrees);
    }
    append_flags(c, sc, scene_fields());
    // --threads sets both the trace's and the tree's threads (resolve()): written once, from
    // the trace. A --tree file's parameters are the file's: the tree flags would be ignored.
    if (!sc.tree_file.empty()) {
        c += " --tree " + shell_word(sc.tree_file);
    } else {
        append_flags(c, o.tree, kd_tree_fields(), {"--threads"});
    }
    append_flags(c, o.trace, trace_fields());
    append_flags(c, o.film, film_fields());
    append_flags(c, o.stop, stop_fields());
    return c;
}

// An adaptive render whose spp budget is at or below --adaptive-min-spp never adapts: every
// pixel samples up to the minimum before any may stop.
void warn_adaptive_budget(const RenderOptions& given) {
    const RenderOptions o = resolve(given);
    if (!o.film.adaptive || o.stop.spp <= 0 || o.stop.spp > o.film.adaptive_min_spp) return;
    std::fprintf(stderr,
                 "kdtrace: warning: adaptive sampling has no effect: the budget of %d spp is not "
                 "above --adaptive-min-spp %d, which every pixel takes first\n",
                 o.stop.spp, o.film.adaptive_min_spp);
}

// Pixels that stopped at the per-pixel cap with their error above an --error target.
size_t capped_above_target(const Film& film, const StopConditions& stop) {
    size_t n = 0;
    for (int y = 0; y < film.height(); ++y) {
        for (int x = 0; x < film.width(); ++x) {
            if (film.next_sample_index(x, y) >= uint32_t(stop.max_spp) &&
                film.relative_error(x, y) > stop.error)
                ++n;
        }
    }
    return n;
}

void run(const RenderCommand& cmd) {
    const RenderOptions o = resolve(cmd.options);
    // Fail before loading and rendering, not after.
    validate(o);
    check_image_memory(o.scene.width, o.scene.height);
    if (dist_requested(cmd.dist)) return run_dist_render(o, cmd.output, cmd.quiet, cmd.dist);
    check_image_output_flag(cmd.output, o.film.transparent);
    std::vector<std::string> inputs = {o.scene.scene_path, o.scene.env_file, o.scene.tree_file};
    inputs.insert(inputs.end(), cmd.option_files.begin(), cmd.option_files.end());
    check_output(cmd.output, inputs, "the image");

    const Prepared prep = prepare_render(o, [&](const std::string& line) {
        if (!cmd.quiet || is_warning(line)) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
    });
    const RenderSnapshot& snap = *prep.snapshot;
    if (cmd.env_rotation_given && prep.scene.environment.file.empty()) {
        std::fprintf(stderr,
                     "kdtrace: warning: --env-rotation has no effect: the environment is "
                     "a constant colour, not a map\n");
    }
    check_output(cmd.output, scene_input_files(prep.scene), "the image");
    if (!cmd.view.empty())
        warn_view_model(cmd.views, "--view " + cmd.view, o.scene.scene_path, prep.scene);

    // check_image_memory() counted what was available before the scene was loaded.
    std::unique_ptr<RenderSession> owned_session;
    try {
        owned_session = std::make_unique<RenderSession>(prep.snapshot, o.trace, o.film);
    } catch (const std::bad_alloc&) {
        throw Error("--width " + std::to_string(o.scene.width) + " --height " +
                    std::to_string(o.scene.height) + ": out of memory allocating the film");
    }
    RenderSession& session = *owned_session;
    session.set_publishing(false);  // nothing reads the image before the render ends
    const bool tty = !cmd.quiet && isatty(fileno(stderr));
    const double pixels = double(session.film().pixel_count());
    std::function<void(const RenderProgress&)> progress;
    if (tty) progress = [&](const RenderProgress& pr) { draw_progress(pr, pixels); };
    // The first SIGINT/SIGTERM ends the render after the tiles in flight; the image is saved.
    interrupt::install(interrupt::Mode::finish_work);
    interrupt::Watcher watcher([&session] { session.cancel(); });
    const RenderProgress p = run_render(session, o.stop, progress);
    if (tty) std::fprintf(stderr, "\n");

    const Film& film = session.film();
    const PathCounters& totals = session.totals();
    // A few dropped samples are noise; many mean radiance the scene cannot hold in float, and
    // an image missing them would be silently wrong (black where the light is).
    if (totals.nonfinite_dropped > 0 && totals.nonfinite_dropped * 1000 > totals.samples) {
        throw Error("render: " + std::to_string(totals.nonfinite_dropped) + " of " +
                    std::to_string(totals.samples) +
                    " samples were not finite (or negative) and were dropped, more than 0.1 %: "
                    "the scene's radiance overflows float (emission, environment colour or "
                    "intensity); no image written");
    }
    ImageRGB image(film.width(), film.height());
    image.rgb = film.linear_rgb();
    image.alpha = film.coverage();
    const PathCounters& c = session.totals();
    const double spp = double(film.total_drawn()) / pixels;
    // The tree's parameters are those of the tree used: a --tree file's, not the flags'.
    // With absolute file names, the image is a session (`--session IMAGE`) from anywhere.
    // Its stop conditions are the command's: a --time render's session asks for the spp
    // reached, so that `--session IMAGE` renders this image as the command does.
    const RenderOptions again = reproducing_options(o, spp);
    RenderOptions used = again;
    used.tree = snap.tree_params;
    make_file_names_absolute(used.scene);
    // kdtrace:scene is absolute too, as in frame sequences (the command keeps the names typed).
    const std::string& scene = used.scene.scene_path;
    ImageMetadata meta;
    meta.emplace_back("Software", "kdtrace 0.1.0");
    meta.emplace_back("kdtrace:scene", scene.empty() ? std::string("builtin:default") : scene);
    meta.emplace_back("kdtrace:scene_json", scene_to_json(prep.scene));
    meta.emplace_back("kdtrace:camera", camera_to_json(snap.camera));
    meta.emplace_back("kdtrace:params", options_to_json(used));
    meta.emplace_back("kdtrace:seed", std::to_string(o.trace.seed));
    meta.emplace_back("kdtrace:spp", std::to_string(spp));
    meta.emplace_back("kdtrace:passes", std::to_string(p.passes));
    meta.emplace_back("kdtrace:command", rerender_command(again, snap.camera_desc));
    // A signal in the first pass leaves the tiles it did not reach without samples: black.
    const size_t unsampled = interrupt::requested() ? unsampled_pixels(film) : 0;
    const std::string unsampled_text = unsampled > 0 ? std::to_string(unsampled) + " of " +
                                                           std::to_string(film.pixel_count()) +
                                                           " pixels have no samples (black)"
                                                     : "";
    if (interrupt::requested()) {
        meta.emplace_back("kdtrace:interrupted", std::string(interrupt::signal_name()) + " at " +
                                                     std::to_string(spp) + " spp" +
                                                     (unsampled > 0 ? "; " + unsampled_text : ""));
    }
    ToneParams tone;
    tone.exposure = o.film.exposure;
    tone.curve = o.film.tonemap;
    write_or_rescue(cmd.output, image, tone, meta);

    std::string capped_text;
    if (o.stop.error > 0.0f && !interrupt::requested()) {
        if (const size_t n = capped_above_target(film, o.stop); n > 0) {
            char buf[96];
            std::snprintf(buf, sizeof buf,
                          ", stopped at --max-spp %d with %zu pixels above --error %g",
                          o.stop.max_spp, n, double(o.stop.error));
            capped_text = buf;
        }
    }
    const double mrays = p.seconds > 0.0 ? double(c.rays()) / p.seconds * 1e-6 : 0.0;
    char error_buf[32];
    std::snprintf(error_buf, sizeof error_buf, "%.4f", p.mean_relative_error);
    const std::string error_text = p.error_known ? error_buf : "unknown (below 2 spp)";
    // A --tree file is the user's own, not the cache's.
    const std::string tree_source = tree_source_text(prep, o.scene);
    std::printf(
        "render: %s: %dx%d, %.2f s, %.1f spp, %.2f Mrays/s (%llu rays: %llu camera, %llu bounce, "
        "%llu shadow; %.1f nodes, %.1f triangles per ray), est. rel. error %s, %llu non-finite "
        "dropped, tree %.2f s%s%s%s -> %s\n",
        scene.empty() ? "default scene" : printable(scene).c_str(), film.width(), film.height(),
        p.seconds, spp, mrays, (unsigned long long)c.rays(), (unsigned long long)c.camera_rays,
        (unsigned long long)c.bounce_rays, (unsigned long long)c.shadow_rays,
        double(c.nodes_visited) / double(std::max<uint64_t>(c.rays(), 1)),
        double(c.triangles_tested) / double(std::max<uint64_t>(c.rays(), 1)), error_text.c_str(),
        (unsigned long long)c.nonfinite_dropped, prep.tree_seconds, tree_source.c_str(),
        unsampled > 0 ? (", interrupted: " + unsampled_text).c_str() : "", capped_text.c_str(),
        printable(cmd.output).c_str());
}

}  // namespace

void add_render_command(CLI::App& parent) {
    static RenderCommand cmd;
    auto* sub =
        parent.add_subcommand("render", "Render a scene, a model or the built-in default scene");
    add_render_options(*sub, cmd.options);
    non_empty_file_name(sub->add_option("-o,--output", cmd.output,
                                        "Output image: .png (tone-mapped sRGB), .exr, .pfm or "
                                        ".hdr (linear); the render settings are stored in .png "
                                        "and .exr")
                            ->capture_default_str(),
                        "-o");
    sub->add_flag("--quiet", cmd.quiet,
                  "No progress bar or cache messages (warnings are still printed)");
    add_dist_options(*sub, cmd.dist, cmd.options);
    sub->callback([sub] {
        interrupt::install();
        // Until the render starts (which saves what it has); MPI ranks report through rank 0.
        if (!cmd.dist.mpi) interrupt::set_exit_notice("interrupted while loading; nothing written");
        if (sub->count("--session") > 0) command_line_stop(*sub, cmd.options.stop);
        // Every rank of an --mpi render parses the same flags: rank 0 warns for all.
        if (!(cmd.dist.mpi && launcher_rank() > 0)) {
            warn_unused_tree_flags(*sub, cmd.options.tree, !cmd.options.scene.tree_file.empty());
            warn_unused_render_flags(*sub, cmd.options);
            warn_adaptive_budget(cmd.options);
            warn_unused_output_flags(*sub, cmd.output);
        }
        check_dist_flags(*sub, cmd.dist);
        // With --mpi or --frames, plan_frames() reads it (with --mpi, in step on every rank).
        if (!dist_requested(cmd.dist)) check_views_file(*sub);
        cmd.env_rotation_given = sub->count("--env-rotation") > 0;
        cmd.view = sub->count("--view") > 0 ? sub->get_option("--view")->as<std::string>() : "";
        cmd.views = sub->count("--views") > 0 ? sub->get_option("--views")->as<std::string>() : "";
        cmd.option_files.clear();
        for (const char* flag : {"--session", "--views"}) {
            for (const std::string& file : sub->get_option(flag)->results())
                cmd.option_files.push_back(file);
        }
        try {
            run(cmd);
        } catch (const Error& e) {
            // A sequence's camera errors name their frame's sources already (frame_snapshot()).
            if (dist_requested(cmd.dist)) throw Error(with_flags(e.what()));
            throw Error(with_camera_flags(*sub, with_flags(e.what()), cmd.options.scene));
        }
        if (interrupt::requested()) interrupt::exit_interrupted();  // 130 or 143
    });
}

}  // namespace kdt::app
