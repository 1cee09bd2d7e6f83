#include "app/mpi_cli.h"

#include "app/options_cli.h"
#include "app/rescue.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <string_view>

#include <omp.h>
#include <nlohmann/json.hpp>

#include "renderer/core/error.h"
#include "renderer/core/fields.h"
#include "renderer/core/interrupt.h"
#include "renderer/core/open_file.h"
#include "renderer/core/output_path.h"
#include "renderer/core/shell_word.h"
#include "renderer/core/temp_file.h"
#include "renderer/core/timer.h"
#include "renderer/io/image_io.h"
#include "renderer/render/prepare.h"
#include "renderer/render/session.h"
#include "renderer/render/settings.h"
#include "renderer/scene/scene.h"
#include "renderer/scene/views.h"
#ifdef KDT_HAVE_MPI
#include <mpi.h>

#include "renderer/dist/render_farm.h"
#endif

namespace kdt::app {

namespace {

// The names of --distribution, also without MPI (the flag is then only warned about).
constexpr std::array<const char*, 3> kDistributions = {"dynamic", "interleaved", "strips"};
#ifdef KDT_HAVE_MPI
static_assert(std::string_view(kDistributions[0]) == dist::kDistributionNames[0] &&
              std::string_view(kDistributions[1]) == dist::kDistributionNames[1] &&
              std::string_view(kDistributions[2]) == dist::kDistributionNames[2]);
#endif

// Why --frames SPEC names no frames.
std::string frames_spec_error(const std::string& spec) {
    return "--frames takes N (with --turntable), views:A,B,..., views:all or "
           "sessions:a.json,b.json,... (got '" +
           printable(spec) + "')";
}

}  // namespace

void check_distribution_name(const std::string& option, const std::string& text) {
    if (std::find_if(kDistributions.begin(), kDistributions.end(),
                     [&](const char* n) { return text == n; }) == kDistributions.end())
        throw Error(option + " must be " + detail::choices_text(kDistributions) + " " +
                    detail::got(text));
}

void add_dist_options(CLI::App& app, DistArgs& a, RenderOptions& options) {
    a.command = &app;
    a.command_options = &options;
    app.add_flag("--mpi", a.mpi,
                 "Split the render over the ranks of mpirun (every rank loads the scene and the "
                 "tree cache itself: a shared filesystem is assumed)");
    app.add_option_function<std::string>(
           "--distribution",
           [&a](const std::string& text) {
               check_distribution_name("--distribution", text);
               a.distribution = text;
           },
           "How --mpi hands out work: dynamic (a queue served on request), interleaved "
           "(every n-th tile to rank n) or strips (one band of tile rows per rank)")
        ->type_name("NAME")
        ->default_str(a.distribution);
    app.add_option_function<std::string>(
           "--tile-batch",
           [&a](const std::string& text) {
               a.batch = int(parse_flag_number("--tile-batch", text, 0, 1 << 16, true));
           },
           "Tiles per --mpi work message (0 = threads per rank)" +
               flag_range_help(0, 1 << 16, true))
        ->type_name("INT");
    app.add_option_function<std::string>(
           "--timeout",
           [&a](const std::string& text) {
               a.timeout_seconds = parse_flag_number("--timeout", text, 0.0, 1e9, false);
           },
           "With --mpi: abort every rank after this many seconds (0 = never)" +
               flag_range_help(0.0, 1e9, false))
        ->type_name("SECONDS");
    app.add_option("--frames", a.frames,
                   "Render a sequence: N (with --turntable), views:A,B,... or views:all (cameras "
                   "of the --views file), sessions:a.json,b.json,... (each as --session FILE "
                   "with the other flags). -o is a pattern such as frame_%03d.png (position "
                   "from 0), or for views and sessions a name that gets _VIEW or _STEM")
        ->type_name("SPEC")
        ->each([](const std::string& spec) {
            if (spec.empty()) throw Error(frames_spec_error(spec));  // "" is not "not given"
        });
    app.add_flag("--turntable", a.turntable,
                 "The --frames N orbit the camera about its up axis through its target");
    non_empty_file_name(app.add_option("--mpi-stats", a.stats_file,
                                       "With --mpi: rank 0 writes per-rank stats (JSON)"),
                        "--mpi-stats");
    app.add_option("--throttle", a.throttle,
                   "Test only: RANK:FACTOR makes that rank sleep (FACTOR - 1) x its render time");
    app.add_option("--mpi-inject", a.inject,
                   "Test only: RANK:load (the rank cannot open the scene), RANK:hash (the "
                   "rank reports a different tree), RANK:stall (its load never ends), RANK:stop "
                   "(a worker hangs, asleep for good, before its first item), RANK:interrupt (a "
                   "worker raises SIGTERM just after sending its first result), 0:write (rank "
                   "0 cannot write the images), RANK:result-item|result-header|result-ids|"
                   "result-short (the worker's first result is malformed), "
                   "RANK:work-item|work-repeat|work-count|work-bytes (rank 0's first reply to "
                   "the worker is), RANK:orphan (rank 0 sends the worker a malformed first "
                   "work message, as work-item, and then stops answering), "
                   "RANK:options-header|options-short|options-long|"
                   "options-huge (rank 0's options message to the worker is) or "
                   "RANK:log-header|log-short|log-long|log-huge (the worker's load log to rank "
                   "0 is)");
}

int launcher_rank() {
    for (const char* name : {"OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK", "SLURM_PROCID"}) {
        const char* value = std::getenv(name);
        double rank = 0.0;
        if (value && detail::parse_number(value, rank) && rank >= 0 && rank < 1e9 &&
            rank == std::floor(rank))
            return int(rank);
    }
    return -1;
}

namespace {

#ifdef KDT_HAVE_MPI
// The ranks the launcher started on this node (Open MPI, MPICH's Hydra); 1 when unknown.
int local_ranks() {
    for (const char* name : {"OMPI_COMM_WORLD_LOCAL_SIZE", "MPI_LOCALNRANKS"}) {
        const char* value = std::getenv(name);
        double n = 0.0;
        if (value && detail::parse_number(value, n) && n >= 1 && n < 1e6 && n == std::floor(n))
            return int(n);
    }
    return 1;
}

// KDT_MPI_FAILURE_GRACE, for tests: how long a worker that failed alone waits for rank 0 to
// end the job before it prints its line and ends itself (MpiContext::end_after_failure()),
// default MpiContext::kFailureGraceSeconds.
double failure_grace_seconds() {
    const char* value = std::getenv("KDT_MPI_FAILURE_GRACE");
    if (!value) return dist::MpiContext::kFailureGraceSeconds;
    double seconds = 0.0;
    if (!detail::parse_number(value, seconds) || !(seconds >= 0.0 && seconds <= 3600.0)) {
        throw Error("KDT_MPI_FAILURE_GRACE must be seconds in [0, 3600] (got '" + excerpt(value) +
                    "')");
    }
    return seconds;
}

// Under --mpi without --threads (or OMP_NUM_THREADS), each rank's OpenMP threads default to
// its share of the node's cores: every rank taking all of them puts ranks x cores threads on
// the cores, and libgomp's spin-waiting at each pass's end then starves the threads still
// working (mpirun --oversubscribe -np 4 on 2 cores: 11.6 s for a 0.2 s render). Ranks bound
// to some of the cores (mpirun's binding) already see only theirs. Returns the threads.
int share_cores_among_ranks(bool quiet, bool root) {
    const int procs = omp_get_num_procs();
    const long online = sysconf(_SC_NPROCESSORS_ONLN);
    const int ranks = local_ranks();
    if (std::getenv("OMP_NUM_THREADS") || ranks <= 1 || procs < online)
        return omp_get_max_threads();
    const int threads = std::max(1, procs / ranks);
    omp_set_num_threads(threads);
    if (root && !quiet) {
        std::fprintf(stderr,
                     "kdtrace: --mpi: %d ranks on this node's %d cores: %d %s each (--threads "
                     "to choose)\n",
                     ranks, procs, threads, threads == 1 ? "thread" : "threads");
    }
    return threads;
}
#endif

}  // namespace

bool mpi_worker_before_init(int argc, const char* const* argv) {
    bool mpi = false;
    for (int i = 1; i < argc; ++i) mpi = mpi || std::strcmp(argv[i], "--mpi") == 0;
    return mpi && launcher_rank() > 0;
}

void check_dist_flags(const CLI::App& app, const DistArgs& a) {
    if (a.mpi) return;
    for (const char* flag : {"--mpi-stats", "--throttle", "--mpi-inject"}) {
        if (app.count(flag) > 0) throw Error(std::string(flag) + " needs --mpi");
    }
    for (const char* flag : {"--distribution", "--tile-batch", "--timeout"}) {
        if (app.count(flag) > 0)
            std::fprintf(stderr, "kdtrace: warning: %s has no effect without --mpi\n", flag);
    }
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
    // One '%', followed by an optional '0', at most two width digits and 'd'.
    const size_t at = pattern.find('%');
    size_t i = at + 1;
    if (at != std::string::npos && i < pattern.size() && pattern[i] == '0') ++i;
    for (int digits = 0; digits < 2 && i < pattern.size() && std::isdigit(uint8_t(pattern[i]));
         ++digits)
        ++i;
    if (at == std::string::npos || pattern.find('%', at + 1) != std::string::npos ||
        i >= pattern.size() || pattern[i] != 'd') {
        throw Error(pattern +
                    ": a --frames output needs exactly one frame number conversion such as %03d "
                    "(and no other %)");
    }
    char buf[4096];
    std::snprintf(buf, sizeof buf, pattern.c_str(), frame);
    return buf;
}

std::string frame_output(const std::string& output, int frame, const std::string& name) {
    if (output.find('%') != std::string::npos || name.empty()) return frame_path(output, frame);
    const bool plain = std::all_of(name.begin(), name.end(), [](char c) {
        return std::isalnum(uint8_t(c)) || c == '.' || c == '_' || c == '+' || c == '-';
    });
    if (!plain || name == "." || name == "..") {
        throw Error("frame '" + printable(name) + "' cannot name a file (" + output +
                    " + _NAME); give -o a pattern such as frame_%03d.png");
    }
    const std::filesystem::path p(output);
    std::filesystem::path out = p;
    out.replace_filename(p.stem().string() + "_" + name + p.extension().string());
    return out.string();
}

namespace {

// One frame of a sequence before anything is loaded.
struct FramePlan {
    RenderOptions options;  // resolved and validated
    std::string name;       // view name or session file stem; empty for a turntable
    std::string output;
    std::string session;      // the session file it came from, if any
    int turn = 0, turns = 0;  // a turntable's frame `turn` of `turns`; turns = 0: none
};

// The files a sequence writes, for its summary line: "a.png", "a.png, b.png" or
// "a.png ... z.png" (each frame's own line names the others); for one image, output itself.
std::string files_written(const std::vector<FramePlan>& frames, const std::string& output) {
    if (frames.empty() || frames.front().output.empty()) return printable(output);
    const std::string first = printable(frames.front().output);
    if (frames.size() == 1) return first;
    return first + (frames.size() == 2 ? ", " : " ... ") + printable(frames.back().output);
}

std::vector<std::string> split_list(const std::string& list, const std::string& spec) {
    std::vector<std::string> out;
    size_t start = 0;
    for (;;) {
        const size_t comma = list.find(',', start);
        out.push_back(list.substr(start, comma == std::string::npos ? comma : comma - start));
        if (out.back().empty())
            throw Error("--frames " + printable(spec) + ": an empty name in the list");
        if (comma == std::string::npos) return out;
        start = comma + 1;
    }
}

bool given(const DistArgs& a, const char* flag) {
    const CLI::Option* o = a.command ? a.command->get_option_no_throw(flag) : nullptr;
    return o && o->count() > 0;
}

std::string views_file(const DistArgs& a) {
    return given(a, "--views") ? a.command->get_option("--views")->as<std::string>() : "";
}

// The options of `render --session PATH` with this command's other flags: the session over
// the defaults, then the command line's flags again in the order they were applied (CLI11
// runs the callbacks in the order the flags were added; --session is first).
RenderOptions session_frame_options(const DistArgs& a, const std::string& path) {
    if (!a.command || !a.command_options)
        throw Error("--frames sessions: needs the render command's flags");
    RenderOptions& target = *a.command_options;
    struct Restore {
        RenderOptions& target;
        RenderOptions saved;
        ~Restore() { target = saved; }
    } restore{target, target};
    target = RenderOptions{};
    options_from_session_file(path, target);
    for (CLI::Option* opt : a.command->get_options()) {
        if (opt->count() > 0) opt->run_callback();
    }
    command_line_stop(*a.command, target.stop);
    RenderOptions o = resolve(target);
    try {
        validate(o);
    } catch (const Error& e) {
        throw Error(path + " with the command line's flags: " + e.what());
    }
    return o;
}

std::vector<FramePlan> list_frames(const RenderOptions& base, const DistArgs& a) {
    const std::string& spec = a.frames;
    std::vector<FramePlan> out;
    if (spec.empty()) {
        if (a.turntable) throw Error("--turntable needs --frames N");
        out.push_back({base, "", "", "", 0, 0});
        return out;
    }
    if (spec.rfind("views:", 0) == 0) {
        if (a.turntable) throw Error("--turntable goes with --frames N, not with a list");
        if (given(a, "--view"))
            throw Error("--frames views: takes the cameras of the views file; drop --view");
        const std::string file = views_file(a);
        std::vector<std::pair<std::string, CameraDesc>> views;
        if (spec == "views:all") {
            const std::string path = file.empty() ? find_asset("views/dragon.json") : file;
            for (const View& v : load_views(path).views) views.emplace_back(v.name, v.camera);
        } else {
            for (const std::string& name : split_list(spec.substr(6), spec))
                views.emplace_back(name, find_view(file, name));
        }
        for (const auto& [name, camera] : views) {
            FramePlan f{base, name, "", "", 0, 0};
            f.options.scene.camera = camera;
            out.push_back(std::move(f));
        }
        return out;
    }
    if (spec.rfind("sessions:", 0) == 0) {
        if (a.turntable) throw Error("--turntable goes with --frames N, not with a list");
        if (given(a, "--session"))
            throw Error("--frames sessions: gives each frame its session file; drop --session");
        for (const std::string& path : split_list(spec.substr(9), spec)) {
            out.push_back({session_frame_options(a, path),
                           std::filesystem::path(path).stem().string(), "", path, 0, 0});
        }
        return out;
    }
    double n = 0.0;
    if (!detail::parse_number(spec, n) || n != std::floor(n)) throw Error(frames_spec_error(spec));
    if (n < 1 || n > double(1 << 20)) {
        throw Error("--frames N must be in [1, " + std::to_string(1 << 20) + "] " +
                    detail::got(spec));
    }
    if (!a.turntable)
        throw Error("--frames N needs --turntable (or list views: or sessions: instead)");
    for (int f = 0; f < int(n); ++f) out.push_back({base, "", "", "", f, int(n)});
    return out;
}

// --mpi-stats is written after the render: it must be no input and no image of the run, and
// writable, before anything is loaded.
void check_stats_output(const std::vector<FramePlan>& frames, const DistArgs& a,
                        const std::string& views, const std::string& session) {
    std::vector<std::string> inputs = {views, session};
    for (const FramePlan& f : frames) {
        if (same_file(a.stats_file, f.output)) {
            throw Error("--mpi-stats " + a.stats_file +
                        ": is also the image output; give the stats another file");
        }
        const SceneOptions& sc = f.options.scene;
        inputs.insert(inputs.end(),
                      {sc.scene_path, sc.env_file, sc.tree_file, f.session, f.output});
    }
    check_output(a.stats_file, inputs, "the --mpi-stats file");
}

// The frames of the sequence the flags ask for (one frame without --frames), with their
// outputs; with check_outputs the outputs are checked too (only the rank that writes).
std::vector<FramePlan> plan_frames(const RenderOptions& base, const std::string& output,
                                   const DistArgs& a, bool check_outputs) {
    std::vector<FramePlan> frames = list_frames(base, a);
    std::map<std::string, size_t> seen;
    const std::string views = views_file(a);
    if (!views.empty()) load_views(views);  // read even when no frame takes a view from it
    const std::string session =
        given(a, "--session") ? a.command->get_option("--session")->as<std::string>() : "";
    for (size_t i = 0; i < frames.size(); ++i) {
        FramePlan& f = frames[i];
        f.output = a.frames.empty() ? output : frame_output(output, int(i), f.name);
        if (auto [it, fresh] = seen.emplace(f.output, i); !fresh) {
            throw Error("frames " + std::to_string(it->second) + " and " + std::to_string(i) +
                        " would both be written to " + f.output +
                        "; give -o a pattern such as frame_%03d.png");
        }
        if (!check_outputs) continue;
        check_image_output_flag(f.output, f.options.film.transparent);
        const SceneOptions& sc = f.options.scene;
        check_output(f.output,
                     {sc.scene_path, sc.env_file, sc.tree_file, f.session, views, session},
                     "the image");
    }
    if (check_outputs && !a.stats_file.empty()) check_stats_output(frames, a, views, session);
    return frames;
}

// The options a frame's scene is loaded and its tree built with: its own, without the
// camera, the image size and what only rendering reads. Frames with equal ones share one
// load.
RenderOptions scene_options_of(const RenderOptions& o) {
    RenderOptions k;
    k.scene = o.scene;
    k.scene.camera.reset();
    k.scene.eye.reset();
    k.scene.target.reset();
    k.scene.up.reset();
    k.scene.vfov_degrees.reset();
    k.scene.width = SceneOptions{}.width;
    k.scene.height = SceneOptions{}.height;
    k.tree = o.tree;
    return k;
}

// The loaded scenes of a plan, one per distinct scene_options_of(), in order of first use,
// and the scene of each frame.
struct SceneGroups {
    std::vector<Prepared> prepared;
    std::vector<size_t> of_frame;  // index into prepared, per frame of the plan
};

// Calls load(options) once per distinct scene of `frames`, in order.
SceneGroups load_scenes(const std::vector<FramePlan>& frames,
                        const std::function<Prepared(const RenderOptions&)>& load) {
    SceneGroups g;
    std::map<std::string, size_t> group;  // options_to_json(scene_options_of(frame))
    for (const FramePlan& f : frames) {
        const RenderOptions k = scene_options_of(f.options);
        const auto [it, fresh] = group.emplace(options_to_json(k), g.prepared.size());
        if (fresh) g.prepared.push_back(load(k));
        g.of_frame.push_back(it->second);
    }
    return g;
}

// The warning `render --view` gives when the views file places its cameras for another
// model, for a sequence whose cameras are views (--frames views:..., or --view), once per
// scene.
void warn_view_models(const std::vector<FramePlan>& frames, const SceneGroups& scenes,
                      const DistArgs& a) {
    const bool listed = a.frames.rfind("views:", 0) == 0;
    if (!listed && !given(a, "--view")) return;
    const std::string label = listed
                                  ? "--frames " + a.frames
                                  : "--view " + a.command->get_option("--view")->as<std::string>();
    // Every frame's camera is a view (--view replaces a listed session's camera too).
    std::set<size_t> said;
    for (size_t i = 0; i < frames.size(); ++i) {
        if (!said.insert(scenes.of_frame[i]).second) continue;
        warn_view_model(views_file(a), label, frames[i].options.scene.scene_path,
                        scenes.prepared[scenes.of_frame[i]].scene);
    }
}

// "view A" for a frame of --frames views:..., else "" (with_camera_flags()'s `view`).
std::string frame_view(const DistArgs& a, const FramePlan& f) {
    return a.frames.rfind("views:", 0) == 0 ? "view " + f.name : "";
}

// The snapshot of a frame: its scene's, seen through the frame's camera (the scene's with
// the frame's overrides, as prepare_render() applies them, then the turntable's turn). A
// camera error is a single render's, naming the flags as given (with_camera_flags()) and
// where the frame's other camera parts came from.
std::shared_ptr<const RenderSnapshot> frame_snapshot(const SceneGroups& g,
                                                     const std::vector<FramePlan>& frames, size_t i,
                                                     const DistArgs& a) {
    const FramePlan& f = frames[i];
    const RenderSnapshot& base = *g.prepared[g.of_frame[i]].snapshot;
    const SceneOptions& o = f.options.scene;
    try {
        check_session_camera(base.camera_desc, o);
        CameraDesc c = with_camera_overrides(base.camera_desc, o);
        // The camera's own problem, not the non-finite turn that a camera without a frame
        // would give.
        if (f.turns > 0) {
            make_camera(c, o.width, o.height);
            c = turntable_camera(c, f.turn, f.turns);
        }
        // A copy shares the mesh, tree and environment; only the camera changes.
        auto s = std::make_shared<RenderSnapshot>(base);
        s->camera_desc = c;
        s->camera = make_camera(c, o.width, o.height);
        return s;
    } catch (const Error& e) {
        if (!a.command) throw;
        throw Error(with_camera_flags(*a.command, e.what(), o, frame_view(a, f)));
    }
}

// What `render --session IMAGE` reads back from a frame image to render it again: the
// frame's options with the tree used (a --tree file's parameters, not the flags'), the
// frame's own camera in full (a turntable's turn, a view's or a session's camera with the
// command line's --eye, --fov, ...) and absolute file names.
RenderOptions frame_session(const FramePlan& f, const RenderSnapshot& snap) {
    RenderOptions o = f.options;
    o.tree = snap.tree_params;
    SceneOptions& sc = o.scene;
    sc.camera = snap.camera_desc;
    sc.eye.reset();
    sc.target.reset();
    sc.up.reset();
    sc.vfov_degrees.reset();
    make_file_names_absolute(sc);
    return o;
}

// The scene a frame renders, for its kdtrace:scene_json: its group's, with the frame's camera.
Scene frame_scene(const SceneGroups& g, size_t i, const RenderSnapshot& snap) {
    Scene scene = g.prepared[g.of_frame[i]].scene;  // the meshes are shared, not copied
    scene.camera = snap.camera_desc;
    return scene;
}

// The keys of a single render's image (app/cmd_render.cpp), and the frame's name and the
// distribution. `passes` < 0: not known (a tiled --mpi render's tiles each have their own
// passes), not stored.
// `partial`: the render was interrupted (a local sequence's frame in flight).
void write_film(const FramePlan& f, const Film& film, const RenderSnapshot& snap,
                const Scene& scene, const std::string& how, int passes = -1, bool partial = false) {
    RenderOptions o = frame_session(f, snap);
    const double spp = double(film.total_drawn()) / double(film.pixel_count());
    if (partial || o.stop.seconds > 0.0) {
        // Where a time limit or a signal stopped it depends on the run: the image's session
        // asks for the samples it reached instead.
        o.stop.seconds = 0.0;
        o.stop.error = 0.0f;
        o.stop.spp = std::max(1, int(std::lround(spp)));
    }
    ImageRGB image(film.width(), film.height());
    image.rgb = film.linear_rgb();
    image.alpha = film.coverage();
    ImageMetadata meta;
    meta.emplace_back("Software", "kdtrace 0.1.0");
    const std::string& scene_path = o.scene.scene_path;
    meta.emplace_back("kdtrace:scene",
                      scene_path.empty() ? std::string("builtin:default") : scene_path);
    meta.emplace_back("kdtrace:scene_json", scene_to_json(scene));
    meta.emplace_back("kdtrace:camera", camera_to_json(snap.camera));
    meta.emplace_back("kdtrace:params", options_to_json(o));
    meta.emplace_back("kdtrace:seed", std::to_string(o.trace.seed));
    // Measured: a farmed frame may be adaptive or stop on an error target.
    meta.emplace_back("kdtrace:spp", std::to_string(spp));
    if (passes >= 0) meta.emplace_back("kdtrace:passes", std::to_string(passes));
    if (partial) {
        // A signal in the first pass leaves the tiles it did not reach black.
        const size_t unsampled = unsampled_pixels(film);
        meta.emplace_back(
            "kdtrace:interrupted",
            std::string(interrupt::signal_name()) + " at " + std::to_string(spp) + " spp" +
                (unsampled > 0
                     ? "; " + std::to_string(unsampled) + " of " +
                           std::to_string(film.pixel_count()) + " pixels have no samples (black)"
                     : ""));
    }
    if (!f.name.empty()) meta.emplace_back("kdtrace:frame", f.name);
    meta.emplace_back("kdtrace:distribution", how);
    // The image is its own session; the spp of its stop conditions (none when it stops on an
    // error target alone).
    std::string command = "kdtrace render --session " + shell_word(absolute_file_name(f.output));
    if (o.stop.spp > 0) command += " --spp " + std::to_string(o.stop.spp);
    meta.emplace_back("kdtrace:command", command);
    ToneParams tone;
    tone.exposure = o.film.exposure;
    tone.curve = o.film.tonemap;
    write_or_rescue(f.output, image, tone, meta);
}

// --frames without --mpi: every frame in this process, with any stop condition.
void run_local_frames(const RenderOptions& base, const std::string& output, bool quiet,
                      const DistArgs& a) {
    const std::vector<FramePlan> frames = plan_frames(base, output, a, true);
    const PrepareLog log = [&](const std::string& line) {
        if (!quiet || is_warning(line)) std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
    };
    const SceneGroups scenes =
        load_scenes(frames, [&](const RenderOptions& o) { return prepare_render(o, log); });
    warn_view_models(frames, scenes, a);
    std::vector<std::shared_ptr<const RenderSnapshot>> snaps;
    for (size_t i = 0; i < frames.size(); ++i)
        snaps.push_back(frame_snapshot(scenes, frames, i, a));
    Timer timer;
    // The first SIGINT/SIGTERM ends the frame in flight after its tiles in flight; that frame
    // is written, marked interrupted, and the sequence stops (render then exits 130 or 143).
    interrupt::install(interrupt::Mode::finish_work);
    for (size_t i = 0; i < frames.size(); ++i) {
        if (interrupt::requested()) {
            std::fprintf(stderr, "kdtrace: interrupted (%s); kept the %zu of %zu frames written\n",
                         interrupt::signal_name(), i, frames.size());
            return;
        }
        const FramePlan& f = frames[i];
        RenderSession session(snaps[i], f.options.trace, f.options.film);
        session.set_publishing(false);
        {
            interrupt::Watcher watcher([&session] { session.cancel(); });
            run_render(session, f.options.stop);
        }
        const bool partial = interrupt::requested();
        write_film(f, session.film(), *snaps[i], frame_scene(scenes, i, *snaps[i]), "local",
                   session.passes(), partial);
        if (partial) {
            std::fprintf(stderr,
                         "kdtrace: interrupted (%s); kept the %zu of %zu frames written, the last "
                         "(%s) with the samples it had\n",
                         interrupt::signal_name(), i + 1, frames.size(),
                         printable(f.output).c_str());
            return;
        }
        if (!quiet)
            std::fprintf(stderr, "kdtrace: frame %zu/%zu -> %s\n", i + 1, frames.size(),
                         printable(f.output).c_str());
    }
    std::printf("render: %zu %s, %.2f s -> %s\n", frames.size(),
                frames.size() == 1 ? "frame" : "frames", timer.seconds(),
                files_written(frames, output).c_str());
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

// The malformed message an --mpi-inject fault names ("result-item"); none for other faults.
dist::BadMessage bad_message(const std::string& what) {
    for (size_t i = 1; i < dist::kBadMessageNames.size(); ++i)
        if (what == dist::kBadMessageNames[i]) return dist::BadMessage(i);
    return dist::BadMessage::none;
}

// The malformed options message an --mpi-inject fault names ("options-short"); none for other
// faults.
dist::BadBroadcast bad_broadcast(const std::string& what) {
    for (size_t i = 1; i < dist::kBadBroadcastNames.size(); ++i)
        if (what == dist::kBadBroadcastNames[i]) return dist::BadBroadcast(i);
    return dist::BadBroadcast::none;
}

// --mpi-inject RANK:WHAT names a rank of the job and a fault the farm knows; a typo must not
// make a fault test pass.
void check_fault(const dist::InjectedFault& fault, const std::string& spec, int ranks) {
    if (fault.rank < 0 || fault.rank >= ranks) {
        throw Error("--mpi-inject " + spec + ": no rank " + std::to_string(fault.rank) + " among " +
                    std::to_string(ranks));
    }
    const bool message = bad_message(fault.what) != dist::BadMessage::none ||
                         bad_broadcast(fault.what) != dist::BadBroadcast::none ||
                         std::find(dist::kBadLogNames.begin() + 1, dist::kBadLogNames.end(),
                                   fault.what) != dist::kBadLogNames.end();
    if (fault.what != "load" && fault.what != "hash" && fault.what != "write" &&
        fault.what != "stall" && fault.what != "stop" && fault.what != "interrupt" && !message &&
        fault.what != "orphan") {
        throw Error("--mpi-inject " + spec + ": unknown fault '" + printable(fault.what) +
                    "' (faults: load, hash, stall, stop, interrupt, write, result-item, "
                    "result-header, result-ids, result-short, work-item, work-repeat, "
                    "work-count, work-bytes, orphan, options-header, options-short, options-long, "
                    "options-huge, log-header, log-short, log-long, log-huge)");
    }
    if (fault.what == "write" && fault.rank != 0)
        throw Error("--mpi-inject " + spec + ": only rank 0 writes images (use 0:write)");
    if (message && fault.rank == 0) {
        throw Error("--mpi-inject " + spec +
                    ": only a worker sends results and load logs and receives work and "
                    "options (rank 1 or above)");
    }
    if (fault.what == "orphan" && fault.rank == 0) {
        throw Error("--mpi-inject " + spec +
                    ": a stuck rank 0 orphans a worker: name the worker (rank 1 or above)");
    }
    if ((fault.what == "stop" || fault.what == "interrupt") && fault.rank == 0) {
        throw Error("--mpi-inject " + spec + ": only a worker can " + fault.what +
                    " (rank 1 or above)");
    }
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
    if (!ranks.empty())
        std::printf("mpi: rank 0 served results for %.3f s (receive, import, reply)\n",
                    ranks[0].serve_seconds);
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
                                 {"serve_seconds", r.serve_seconds},
                                 {"messages", r.messages},
                                 {"bytes", r.bytes}});
    }
    const std::string text = j.dump(1) + "\n";
    write_file_atomically(a.stats_file, text.data(), text.size());
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

const char* frames_unit(const DistArgs& a) { return a.frames.empty() ? "tiles" : "frames"; }

uint64_t plan_hash(const std::vector<FramePlan>& frames) {
    std::string all;
    for (const FramePlan& f : frames) all += options_to_json(f.options) + f.name + "\n";
    return std::hash<std::string>{}(all);
}

// Rank 0: the images written so far, for the message of an interrupted run (read from the
// signal watcher's thread too).
struct Kept {
    bool sequence = false;
    std::atomic<int> written{0};
    std::atomic<int> frames{0};  // of a sequence, once planned
};

std::string kept_text(const Kept& k) {
    const int written = k.written.load(), frames = k.frames.load();
    if (!k.sequence) {
        return written > 0 ? "the image was written"
                           : "nothing was kept: a tiled --mpi render writes its image only once "
                             "every tile is back";
    }
    if (written == 0) return "nothing was kept: no frame was finished";
    if (written == frames) return "all " + std::to_string(frames) + " frames were written";
    return "kept the " + std::to_string(written) + " of " + std::to_string(frames) +
           " frames already written";
}

void run_mpi(dist::MpiContext& ctx, RenderOptions o, const std::string& output, bool quiet,
             const DistArgs& a, Kept& kept) {
    ctx.start_watchdog(a.timeout_seconds);
    const bool root = ctx.rank() == 0;
    const bool sequence = !a.frames.empty();
    // Rank 0's options are everyone's; the checks are collective, so that a bad flag or a bad
    // listed file stops every rank with one message instead of leaving some waiting. Every
    // rank reads the listed files itself, and all must agree on the frames.
    // A malformed options message fails the receiving worker in the check below, so that
    // every rank stops with one message naming it. The test fault is checked there too.
    int bad_rank = -1;
    dist::BadBroadcast bad = dist::BadBroadcast::none;
    if (!a.inject.empty()) {
        try {
            const auto [rank, what] = rank_and(a.inject, "--mpi-inject");
            bad_rank = rank;
            bad = bad_broadcast(what);
        } catch (const Error&) {
        }
    }
    std::string json, received;
    try {
        json = ctx.broadcast(options_to_json(o), bad_rank, bad);
    } catch (const Error& e) {
        received = e.what();
    }
    dist::FarmParams params;
    dist::InjectedFault fault;
    std::vector<FramePlan> frames;
    dist::check_every_rank(ctx, "start", [&]() -> dist::Fingerprint {
        if (!received.empty()) throw Error(received);
        // The options' JSON refuses a zero up vector (a session's "up"): the flag's is named
        // as --frames without --mpi names it for the first frame. Every rank has the same flags.
        if (o.scene.up && *o.scene.up == Vec3f(0.0f) && a.command) {
            const FramePlan first = list_frames(o, a).front();
            throw Error(with_camera_flags(*a.command, "camera: up vector is zero",
                                          first.options.scene, frame_view(a, first)));
        }
        options_from_json(json, o, "rank 0's options");
        frames = plan_frames(o, output, a, root);  // only rank 0 writes
        for (const FramePlan& f : frames) {
            if (sequence) {
                dist::check_frame_farm_options(f.options);
            } else {
                dist::check_tile_farm_options(f.options);
            }
        }
        params = farm_params(a, o);
        if (!a.throttle.empty() &&
            (params.throttle_rank < 0 || params.throttle_rank >= ctx.size())) {
            throw Error("--throttle " + a.throttle + ": no rank " +
                        std::to_string(params.throttle_rank) + " among " +
                        std::to_string(ctx.size()));
        }
        if (!a.inject.empty()) {
            std::tie(fault.rank, fault.what) = rank_and(a.inject, "--mpi-inject");
            check_fault(fault, a.inject, ctx.size());
            if (fault.what == "stop") params.stop_rank = fault.rank;
            if (fault.what == "interrupt") params.interrupt_rank = fault.rank;
            params.bad_message = bad_message(fault.what);
            if (fault.what == "orphan") {
                params.bad_message = dist::BadMessage::work_item;
                params.stall_after_bad_work = true;
            }
            if (params.bad_message != dist::BadMessage::none) params.bad_message_rank = fault.rank;
        }
        return dist::Fingerprint{
            {"list of frames and their options (views and session files)", plan_hash(frames)}};
    });
    kept.frames = int(frames.size());
    const PrepareLog log = [&](const std::string& line) {
        if (root && (!quiet || is_warning(line)))
            std::fprintf(stderr, "kdtrace: %s\n", line.c_str());
    };
    // Every scene of the sequence is loaded on every rank before any frame renders.
    const SceneGroups scenes = load_scenes(frames, [&](const RenderOptions& k) {
        return dist::prepare_everywhere(ctx, k, log, fault);
    });
    if (root) warn_view_models(frames, scenes, a);
    std::vector<dist::FrameJob> jobs;
    dist::check_every_rank(ctx, "set up the frames", [&]() -> dist::Fingerprint {
        for (size_t i = 0; i < frames.size(); ++i) {
            jobs.push_back({frame_snapshot(scenes, frames, i, a), frames[i].options});
            if (!root) continue;
            // The files a scene file names are known once it is loaded.
            const std::vector<std::string> inputs =
                scene_input_files(scenes.prepared[scenes.of_frame[i]].scene);
            check_output(frames[i].output, inputs, "the image");
            if (!a.stats_file.empty()) check_output(a.stats_file, inputs, "the --mpi-stats file");
        }
        return {};
    });
    if (fault.what == "write" && root) {
        // The outputs were checked above: the writes themselves fail.
        for (FramePlan& f : frames)
            f.output = "/nonexistent/kdtrace-injected-fault/" +
                       std::filesystem::path(f.output).filename().string();
    }
    const bool tty = root && !quiet && isatty(fileno(stderr));
    Timer timer;
    const char* unit = frames_unit(a);
    dist::FarmProgress progress;
    if (tty)
        progress = [&](int done, int total) {
            draw_farm_progress(done, total, timer.seconds(), unit);
        };
    const std::string how = a.distribution + " over " + std::to_string(ctx.size()) + " ranks";
    dist::FarmResult result;
    int items = 0;
    if (sequence) {
        items = int(jobs.size());
        result = dist::render_frame_farm(
            ctx, jobs, params,
            [&](int f, const Film& film, int passes) {
                const FramePlan& plan = frames[size_t(f)];
                const RenderSnapshot& snap = *jobs[size_t(f)].snapshot;
                write_film(plan, film, snap, frame_scene(scenes, size_t(f), snap), how, passes);
                ++kept.written;
                // As the local sequence names them (in the order they are written here).
                if (!quiet) {
                    if (tty) std::fprintf(stderr, "\r\33[K");  // over the progress bar
                    std::fprintf(stderr, "kdtrace: frame %d/%zu -> %s\n", f + 1, frames.size(),
                                 printable(plan.output).c_str());
                }
            },
            progress);
    } else {
        Film film;
        result = dist::render_tile_farm(ctx, jobs[0].snapshot, o, params, &film, progress);
        items = (film.width() + RenderSession::kTileSize - 1) / RenderSession::kTileSize *
                ((film.height() + RenderSession::kTileSize - 1) / RenderSession::kTileSize);
        // Every rank is done with the farm: a failed write ends rank 0 alone, as an error,
        // after write_or_rescue() has saved the image elsewhere.
        if (root) {
            try {
                write_film(frames[0], film, *jobs[0].snapshot,
                           frame_scene(scenes, 0, *jobs[0].snapshot), how);
                ++kept.written;
            } catch (const Error& e) {
                throw dist::FarmError(e.what(), true);
            }
        }
    }
    const double seconds = timer.seconds();
    if (tty) std::fprintf(stderr, "\n");
    if (!root) return;
    const PathCounters& c = result.counters;
    try {
        report(result.ranks, a, unit, items, seconds);
    } catch (const Error& e) {
        throw dist::FarmError(e.what(), true);
    }
    // A sequence's frames were named as they were written; each has its own size and stop.
    char what[64];
    if (sequence) {
        std::snprintf(what, sizeof what, "%zu %s", frames.size(),
                      frames.size() == 1 ? "frame" : "frames");
    } else {
        std::snprintf(what, sizeof what, "%dx%d, %d spp", o.scene.width, o.scene.height,
                      o.stop.spp);
    }
    std::printf(
        "render: %s: %s, %.2f s, %.2f Mrays/s over %d ranks (%llu rays, %llu "
        "non-finite dropped) -> %s\n",
        o.scene.scene_path.empty() ? "default scene" : printable(o.scene.scene_path).c_str(), what,
        seconds, seconds > 0.0 ? double(c.rays()) / seconds * 1e-6 : 0.0, ctx.size(),
        (unsigned long long)c.rays(), (unsigned long long)c.nonfinite_dropped,
        (sequence ? files_written(frames, output) : printable(output)).c_str());
}

}  // namespace
#endif

void run_dist_render(const RenderOptions& options, const std::string& output, bool quiet,
                     const DistArgs& a) {
    if (!a.mpi) return run_local_frames(options, output, quiet, a);
#ifdef KDT_HAVE_MPI
    // Without a launcher MPI_Init would start Open MPI's singleton mode, whose daemon needs
    // ssh or rsh on PATH even for one process, and fails in 40 lines of its own otherwise.
    if (launcher_rank() < 0) {
        throw Error(
            "--mpi: not started by mpirun (run it as `mpirun -np N kdtrace render ... --mpi`; "
            "without --mpi one process renders the same image)");
    }
    const double failure_grace = failure_grace_seconds();
    if (options.trace.threads == 0) share_cores_among_ranks(quiet, launcher_rank() == 0);
    bool failed = false;
    Kept kept;  // outlives ctx, whose signal watcher reads it
    kept.sequence = !a.frames.empty();
    {
        dist::MpiContext ctx;
        ctx.set_failure_grace_seconds(failure_grace);
        // mpirun passes a Ctrl-C on as SIGTERM and SIGKILLs the ranks 1 s later: no time to
        // finish the tiles in flight, nor always to write an image. Rank 0 says what was
        // written (a sequence's frames are written as they come) and every rank ends.
        ctx.watch_interrupts([&kept] { return kept_text(kept); });
        try {
            run_mpi(ctx, options, output, quiet, a, kept);
            if (interrupt::requested()) ctx.end_after_interrupt();
        } catch (const dist::FarmInterrupted&) {
            ctx.end_after_interrupt();  // never finalizes: see FarmInterrupted
        } catch (const dist::FarmRankFailed& e) {
            ctx.end_after_failure(e.what());  // rank 0: a worker's failure, its one line
        } catch (const dist::FarmTimeout& e) {
            // Never finalizes: see FarmTimeout.
            ctx.end_after_timeout(with_flags(e.what()));
        } catch (const dist::FarmError& e) {
            // A signal may have ended the others mid-step: it, not their absence, is the news.
            if (interrupt::requested()) ctx.end_after_interrupt();
            ctx.note_failure();  // a signal from now on is the job's end, not the news
            // Printed before MPI_Finalize: mpirun ends the job once any rank has exited
            // non-zero, which could otherwise cut rank 0 off before its message.
            if (e.report())
                std::fprintf(stderr, "kdtrace: error: %s\n",
                             printable(with_flags(e.what())).c_str());
            std::fflush(stderr);
            failed = true;
        } catch (const std::exception& e) {
            // A failure of this rank alone after the collective checks: the others may be
            // waiting for it, so the whole job ends (end_after_failure: through rank 0, which
            // prints this rank's line).
            if (interrupt::requested()) ctx.end_after_interrupt();
            ctx.end_after_failure("rank " + std::to_string(ctx.rank()) + ": " + e.what());
        }
    }
    if (failed) std::exit(1);
#else
    throw Error("--mpi: this kdtrace was built without MPI (KDT_WITH_MPI off or MPI not found)");
#endif
}

}  // namespace kdt::app
