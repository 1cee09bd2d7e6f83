#include "app/options_cli.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <new>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/light/environment.h"
#include "renderer/render/prepare.h"
#include "renderer/scene/scene.h"
#include "renderer/scene/views.h"

namespace kdt::app {

namespace {

// "X,Y,Z" with three finite numbers, else an error naming the flag.
Vec3f parse_vec3(const std::string& flag, const std::string& text) {
    Vec3f v(0.0f);
    size_t start = 0;
    for (int i = 0; i < 3; ++i) {
        const size_t comma = text.find(',', start);
        const bool last = i == 2;
        if ((comma == std::string::npos) != last) {
            throw Error(flag + " must be three numbers X,Y,Z (got '" + excerpt(text) + "')");
        }
        const std::string part = text.substr(start, last ? std::string::npos : comma - start);
        double d = 0.0;
        if (!detail::parse_number(part, d) || !std::isfinite(float(d))) {
            throw Error(flag + " must be three finite numbers X,Y,Z (got '" + excerpt(text) + "')");
        }
        v[i] = float(d);
        start = comma + 1;
    }
    return v;
}

bool skipped(const char* flag, SkipFlags skip) {
    for (const char* s : skip) {
        if (std::strcmp(s, flag) == 0) return true;
    }
    return false;
}

template <class S>
void add_fields(CLI::App& app, S& s, std::span<const Field<S>> fields, SkipFlags skip) {
    for (const Field<S>& field : fields) {
        if (!field.flag || skipped(field.flag, skip)) continue;
        const Field<S>* f = &field;
        const FieldRef ref = f->at(s);
        if (auto* b = std::get_if<bool*>(&ref)) {
            bool* target = *b;
            const bool value = std::strncmp(f->flag, "--no-", 5) != 0;
            app.add_flag_callback(
                f->flag, [target, value] { *target = value; }, f->help);
            continue;
        }
        const std::string flag = f->flag;
        auto* opt = app.add_option_function<std::string>(
            flag,
            [&s, f, flag](const std::string& text) {
                if (std::string why = parse_field(*f, s, text); !why.empty())
                    throw Error(flag + " " + why);
            },
            std::holds_alternative<ChoiceRef>(ref)
                ? std::string(f->help)
                : std::string(f->help) + " " + field_range_text(*f));
        // A repeated option takes its last value (TakeLast), and only that one reaches the
        // callback: every value is still checked, so that a bad one is never silently passed over.
        opt->each([&s, f, flag](const std::string& text) {
            S scratch = s;
            if (std::string why = parse_field(*f, scratch, text); !why.empty())
                throw Error(flag + " " + why);
        });
        // A stop condition's 0 is "off", which its range refuses: "unset", not "=0".
        const bool off = f->zero_is_off && field_number(ref) == 0.0;
        opt->default_str(off ? "unset" : field_text(*f, s));
        if (std::holds_alternative<ChoiceRef>(ref)) {
            opt->type_name("NAME");
        } else if (field_is_integral(ref)) {
            opt->type_name("INT");
        } else {
            opt->type_name("FLOAT");
        }
    }
}

}  // namespace

CLI::Option* non_empty_file_name(CLI::Option* opt, const std::string& name,
                                 const std::string& hint) {
    // A kdt::Error, not a CLI11 validation message: one line in kdtrace's own format.
    return opt->each([name, hint](const std::string& text) {
        if (text.empty()) throw Error(name + ": empty file name" + hint);
    });
}

CLI::Option* file_extension(CLI::Option* opt, const std::string& name, const std::string& ext,
                            const std::string& holds, std::initializer_list<const char*> allowed) {
    std::vector<std::string> pass(allowed.begin(), allowed.end());
    return opt->each([name, ext, holds, pass](const std::string& text) {
        if (std::find(pass.begin(), pass.end(), text) != pass.end()) return;
        std::string given = std::filesystem::path(text).extension().string();
        for (char& c : given) c = char(std::tolower(static_cast<unsigned char>(c)));
        if (given != ext)
            throw Error(name + " " + excerpt(text) + ": " + holds + "; give a " + ext +
                        " file name");
    });
}

void check_image_output_flag(const std::string& output, bool with_alpha) {
    try {
        check_image_output(output, with_alpha);
    } catch (const Error& e) {
        throw Error(std::string("-o ") + e.what());
    }
}

double parse_flag_number(const std::string& flag, const std::string& text, double min, double max,
                         bool integral) {
    double v = 0.0;
    if (!detail::parse_number(text, v))
        throw Error(flag + " " +
                    detail::number_error(text, detail::range_text(min, max, false, integral)));
    if (std::string why = detail::check_number(v, min, max, false, integral); !why.empty())
        throw Error(flag + " " + why);
    return v;
}

std::string flag_range_help(double min, double max, bool integral) {
    return " " + detail::range_text(min, max, false, integral);
}

CLI::Validator in_range(double min, double max, bool integral) {
    return CLI::Validator(
        [min, max, integral](std::string& text) -> std::string {
            double v = 0.0;
            if (!detail::parse_number(text, v))
                return detail::number_error(text, detail::range_text(min, max, false, integral));
            return detail::check_number(v, min, max, false, integral);
        },
        detail::range_text(min, max, false, integral));
}

void add_tree_options(CLI::App& app, KdTreeParams& tree, SkipFlags skip) {
    add_fields(app, tree, kd_tree_fields(), skip);
}
void add_trace_options(CLI::App& app, TraceParams& trace, SkipFlags skip) {
    add_fields(app, trace, trace_fields(), skip);
}
void add_film_options(CLI::App& app, FilmParams& film, SkipFlags skip) {
    add_fields(app, film, film_fields(), skip);
}
void add_stop_options(CLI::App& app, StopConditions& stop, SkipFlags skip) {
    add_fields(app, stop, stop_fields(), skip);
}

void warn_unused_tree_flags(const CLI::App& app, const KdTreeParams& tree, bool tree_file) {
    for (const Field<KdTreeParams>& f : kd_tree_fields()) {
        if (!f.flag || std::strcmp(f.flag, "--threads") == 0 || app.count(f.flag) == 0) continue;
        if (tree_file) {
            std::fprintf(stderr,
                         "kdtrace: warning: %s has no effect with --tree (the file's tree "
                         "is used as it was built)\n",
                         f.flag);
        } else if (!kd_tree_field_applies(tree, f.name)) {
            std::fprintf(stderr, "kdtrace: warning: %s has no effect with the %s builder\n", f.flag,
                         kKdBuilderNames[size_t(tree.builder)]);
        }
    }
}

void check_views_file(const CLI::App& app) {
    const CLI::Option* views = app.get_option_no_throw("--views");
    if (views && views->count() > 0) load_views(views->as<std::string>());
}

void warn_unused_render_flags(const CLI::App& app, const RenderOptions& given) {
    const RenderOptions o = resolve(given);
    for (const Field<FilmParams>& f : film_fields()) {
        if (!f.flag || std::strncmp(f.flag, "--adaptive-", 11) != 0 || app.count(f.flag) == 0)
            continue;
        if (!o.film.adaptive) {
            std::fprintf(stderr,
                         "kdtrace: warning: %s has no effect without --adaptive or --error\n",
                         f.flag);
        } else if (o.stop.error > 0.0f && std::strcmp(f.flag, "--adaptive-threshold") == 0) {
            std::fprintf(stderr,
                         "kdtrace: warning: --adaptive-threshold has no effect with --error (the "
                         "error target is the threshold)\n");
        }
    }
    if (given.stop.spp > o.stop.max_spp) {
        std::fprintf(stderr,
                     "kdtrace: warning: --spp %d is above --max-spp %d: the render stops at %d "
                     "samples per pixel\n",
                     o.stop.spp, o.stop.max_spp, o.stop.max_spp);
    }
}

void warn_unused_output_flags(const CLI::App& app, const std::string& output) {
    std::string ext = std::filesystem::path(output).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".exr" && ext != ".pfm" && ext != ".hdr") return;
    for (const char* flag : {"--exposure", "--tonemap"}) {
        if (app.count(flag) == 0) continue;
        std::fprintf(stderr,
                     "kdtrace: warning: %s has no effect on %s output, which stays linear (it "
                     "applies to .png)\n",
                     flag, ext.c_str());
    }
}

void warn_view_model(const std::string& views, const std::string& label,
                     const std::string& scene_path, const Scene& scene) {
    const std::string path = views_file_path(views);
    const std::string w = view_model_warning(
        path, load_views(path), label,
        scene_path.empty() ? "the built-in default scene" : scene_path, scene_input_files(scene));
    if (!w.empty()) std::fprintf(stderr, "kdtrace: warning: %s\n", w.c_str());
}

void check_image_memory(int width, int height) {
    const uint64_t pixels = uint64_t(std::max(width, 0)) * uint64_t(std::max(height, 0));
    const uint64_t need = pixels * kRenderBytesPerPixel;
    const uint64_t memory = allocatable_memory_bytes();
    if (memory == 0 || need <= memory) return;
    throw Error("--width " + std::to_string(width) + " --height " + std::to_string(height) +
                ": an image of " + std::to_string(pixels) + " pixels needs about " +
                std::to_string(need >> 20) + " MiB (" + std::to_string(kRenderBytesPerPixel) +
                " bytes per pixel), more than the " + std::to_string(memory >> 20) +
                " MiB of memory available; render a smaller image");
}

void add_scene_options(CLI::App& app, SceneOptions& scene) {
    non_empty_file_name(
        app.add_option("SCENE", scene.scene_path,
                       "Scene (.json) or model (.ply, .ply.gz, .obj); omitted = built-in scene"),
        "SCENE", " (omit SCENE for the built-in scene)");
    non_empty_file_name(
        app.add_option("--env", scene.env_file,
                       "Environment map (.hdr, .exr, .pfm; .png as sRGB) replacing the scene's"),
        "--env");
    // Empty is "not given" in SceneOptions; on the command line it is a mistake. The flag
    // replaces a session's mapping, so an error about it names the flag, not the session.
    app.add_option_function<std::string>(
           "--env-mapping",
           [&scene](const std::string& text) {
               scene.env_mapping = text;
               scene.env_mapping_from = {};
           },
           "Mapping of --env: latlong or angular")
        ->type_name("TEXT")
        ->each([](const std::string& text) {
            if (text.empty())
                throw Error("--env-mapping must be " + detail::choices_text(kEnvMappingNames) +
                            " " + detail::got(text));
        });
    app.add_option_function<std::string>(
           "--env-intensity",
           [&scene](const std::string& text) {
               scene.env_intensity =
                   float(parse_flag_number("--env-intensity", text, 0.0, 3.0e38, false));
           },
           "Scale of the environment radiance, replacing the scene's" +
               flag_range_help(0.0, 3.0e38, false))
        ->type_name("FLOAT");
    non_empty_file_name(
        app.add_option("--cache-dir", scene.cache_dir,
                       "Directory of kd-tree cache files (default: the user's cache directory; "
                       "a relative one is taken from the working directory)"),
        "--cache-dir");
    non_empty_file_name(app.add_option("--tree", scene.tree_file,
                                       "kd-tree file written by `kdtrace build -o`, used instead "
                                       "of the cache (checked against the model; its "
                                       "parameters are the file's)"),
                        "--tree")
        ->type_name("FILE");
    add_fields(app, scene, scene_fields(), {});
    // Camera parts, each overriding the scene's (and --view's).
    for (auto [flag, target, help] :
         {std::tuple{"--eye", &scene.eye, "Camera position X,Y,Z (world space)"},
          std::tuple{"--target", &scene.target, "Point the camera looks at, X,Y,Z"},
          std::tuple{"--up", &scene.up, "Camera up direction X,Y,Z"}}) {
        const std::string name = flag;
        std::optional<Vec3f>* out = target;
        app.add_option_function<std::string>(
               name, [name, out](const std::string& text) { *out = parse_vec3(name, text); }, help)
            ->type_name("X,Y,Z");
    }
    app.add_option_function<std::string>(
           "--fov",
           [&scene](const std::string& text) {
               // Checked as the float it is stored as: 179.999999999 is 180 there.
               double v = 0.0;
               const bool number = detail::parse_number(text, v);
               const float f = number && std::fabs(v) < 1e38 ? float(v) : 0.0f;
               if (!(f > 0.0f && f < 180.0f))
                   throw Error("--fov must be a vertical field of view in (0, 180) degrees (got '" +
                               excerpt(text) + "')");
               scene.vfov_degrees = f;
           },
           "Vertical field of view in degrees, (0, 180)")
        ->type_name("DEG");
    // --view NAME picks a camera of a views file (--views, default: the dragon's views).
    auto views = std::make_shared<std::string>();
    // Read when given, with --view or not (check_views_file()): a missing or broken file is
    // an error, not ignored.
    non_empty_file_name(
        app.add_option("--views", *views,
                       "Views file for --view and --frames views: (default: the dragon's views)"),
        "--views")
        ->type_name("FILE");
    app.add_option_function<std::string>(
           "--view",
           [&scene, views](const std::string& name) { scene.camera = find_view(*views, name); },
           "Camera of this view of the views file (A-D for the dragon)")
        ->trigger_on_parse(false);
}

void add_render_options(CLI::App& app, RenderOptions& o) {
    // First, so that the flags given with it (their callbacks run after its) override it.
    non_empty_file_name(
        app.add_option_function<std::string>(
            "--session", [&o](const std::string& path) { options_from_session_file(path, o); },
            "Session file (the viewer's, any options JSON, or a PNG/EXR kdtrace wrote): all its "
            "options, then the flags"),
        "--session")
        ->type_name("FILE");
    add_scene_options(app, o.scene);
    add_stop_options(app, o.stop);
    add_trace_options(app, o.trace);
    add_film_options(app, o.film);
    add_tree_options(app, o.tree, {"--threads"});
}

void command_line_stop(const CLI::App& app, StopConditions& stop) {
    const bool given =
        app.count("--spp") > 0 || app.count("--time") > 0 || app.count("--error") > 0;
    if (!given) return;
    StopConditions replaced;
    for (const Field<StopConditions>& f : stop_fields()) {
        if (f.flag && app.count(f.flag) > 0)
            set_field_number(f.at(replaced), field_number(f.at(stop)));
    }
    stop = replaced;
}

namespace {

template <class S>
void name_flags(std::string& m, std::span<const Field<S>> fields, const std::string& group) {
    for (const Field<S>& f : fields) {
        if (!f.flag) continue;
        const std::string name = group + "." + f.name;
        for (size_t at = m.find(name); at != std::string::npos; at = m.find(name, at + 1)) {
            const size_t end = at + name.size();
            const bool word = end == m.size() || !(std::isalnum(uint8_t(m[end])) || m[end] == '_');
            if (!word) continue;
            const std::string flag = std::string(" (") + f.flag + ")";
            m.insert(end, flag);
            at = end + flag.size() - 1;
        }
    }
}

}  // namespace

std::string with_flags(const std::string& message) {
    std::string m = message;
    name_flags(m, scene_fields(), "scene");
    name_flags(m, kd_tree_fields(), "tree");
    name_flags(m, trace_fields(), "trace");
    name_flags(m, film_fields(), "film");
    name_flags(m, stop_fields(), "stop");
    // The scene's string and optional fields, which have no table entry.
    const std::pair<const char*, const char*> extras[] = {
        {"scene.env_mapping", "--env-mapping"},
        {"scene.env_intensity", "--env-intensity"},
        {"scene.env_file", "--env"}};
    for (const auto& [name, flag] : extras) {
        const std::string insert = std::string(" (") + flag + ")";
        for (size_t at = m.find(name); at != std::string::npos; at = m.find(name, at + 1)) {
            m.insert(at + std::strlen(name), insert);
        }
    }
    return m;
}

namespace {

// check_session_camera()'s message with the flags it names spelled as given: "eye from
// --eye" becomes "eye from --eye 1,2,3", "up from the view" "up from --view A".
std::string with_camera_flag_values(const CLI::App& app, const std::string& message) {
    std::string m = message;
    const CLI::Option* view = app.get_option_no_throw("--view");
    for (const char* part : {"eye", "target", "up"}) {
        const std::string flag = std::string("--") + part;
        const CLI::Option* opt = app.get_option_no_throw(flag);
        std::vector<std::pair<std::string, std::string>> spelled;
        if (opt && opt->count() > 0)
            spelled.emplace_back(flag, flag + " " + excerpt(opt->results().back()));
        if (view && view->count() > 0)
            spelled.emplace_back("the view", "--view " + excerpt(view->results().back()));
        for (const auto& [said, given] : spelled) {
            const std::string from = std::string(part) + " from " + said;
            for (size_t at = m.find(from); at != std::string::npos; at = m.find(from, at + 1)) {
                const size_t end = at + from.size();
                if (end < m.size() && m[end] != ',' && m[end] != ')') continue;
                m.replace(at, from.size(), std::string(part) + " from " + given);
            }
        }
    }
    return m;
}

}  // namespace

std::string with_camera_flags(const CLI::App& app, const std::string& message,
                              const SceneOptions& scene, const std::string& view) {
    if (message.rfind("camera: ", 0) != 0) return with_camera_flag_values(app, message);
    if (message.find("eye") == std::string::npos && message.find("target") == std::string::npos &&
        message.find("up vector") == std::string::npos && message.find("up (") == std::string::npos)
        return message;  // the image size or the field of view: named by their own checks
    std::string given;
    std::vector<std::pair<std::string, std::string>> others;  // (where from, parts)
    const CLI::Option* view_flag = app.get_option_no_throw("--view");
    for (size_t i = 0; i < 3; ++i) {
        const std::string part = std::array{"eye", "target", "up"}[i];
        const std::string flag = "--" + part;
        const CLI::Option* opt = app.get_option_no_throw(flag);
        if (opt && opt->count() > 0) {
            given += (given.empty() ? "" : ", ") + flag + " " + excerpt(opt->results().back());
            continue;
        }
        // Where the part came from, in the words of a flag's error: a session file's, a
        // view's, else the scene's.
        const CameraPartSource source = camera_part_source(scene, i);
        std::string from = "the scene's";
        if (source.kind == CameraPartSource::Kind::session) {
            from = printable(scene.session_camera.file) + "'s";
        } else if (source.kind == CameraPartSource::Kind::view) {
            from = "the view's";
            if (!view.empty()) {
                from = view + "'s";
            } else if (view_flag && view_flag->count() > 0) {
                from = "--view " + excerpt(view_flag->results().back()) + "'s";
            }
        }
        if (!others.empty() && others.back().first == from) {
            others.back().second += " and " + part;
        } else {
            others.emplace_back(from, part);
        }
    }
    if (given.empty()) return message;
    std::string with;
    for (const auto& [from, parts] : others)
        with += (with.empty() ? " with " : " and ") + from + " " + parts;
    return message + " (" + given + with + ")";
}

bool is_warning(const std::string& line) {
    return line.rfind("warning: ", 0) == 0 || line.find(": warning: ") != std::string::npos;
}

}  // namespace kdt::app
