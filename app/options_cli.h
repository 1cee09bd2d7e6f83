// Command-line flags bound straight to the fields of the option structs (render_options.h):
// every flag's name, help, default and range come from the structs' range tables, and a bad
// value is an error naming the flag. Used by render, build and the benches.
#pragma once

#include <initializer_list>
#include <string>

#include <CLI/CLI.hpp>

#include "renderer/geometry/mesh.h"
#include "renderer/render/render_options.h"
#include "renderer/scene/scene.h"

namespace kdt::app {

/// Flags of fields not to register (a command that sets them itself, or shares one flag
/// between two groups, such as --threads).
using SkipFlags = std::initializer_list<const char*>;

/// Makes `opt`, a file or directory name called `name` in messages, refuse an empty value
/// ("--env: empty file name"): on the command line "" is a mistake (`render "$MODEL"` with
/// MODEL unset), never a way to say "not given". Returns `opt`.
CLI::Option* non_empty_file_name(CLI::Option* opt, const std::string& name,
                                 const std::string& hint = "");

/// Makes `opt`, a file name called `name` in messages, refuse a value whose extension (any
/// case) is not `ext`, saying why (`holds`): "-o out.png: the scene is written as JSON; give
/// a .json file name". A value in `allowed` (such as "-" for standard output) passes.
/// Returns `opt`.
CLI::Option* file_extension(CLI::Option* opt, const std::string& name, const std::string& ext,
                            const std::string& holds,
                            std::initializer_list<const char*> allowed = {});

/// check_image_output() of the -o of a render, its errors naming the flag: "-o /tmp: is a
/// directory, not an image file name".
void check_image_output_flag(const std::string& output, bool with_alpha);

/// `text` as a number in [min, max] (a whole one when `integral`) for flags outside the
/// option structs' tables, refused in the tables' words: "--timeout must be a number (got
/// 'x')", "--timeout must be in [0, 1000000000] (got -1)".
double parse_flag_number(const std::string& flag, const std::string& text, double min, double max,
                         bool integral);
/// " [min, max]", for the help of such a flag.
std::string flag_range_help(double min, double max, bool integral);
/// A CLI11 check of a number option against [min, max] (a whole number when `integral`),
/// refusing in the tables' words; main() prints CLI11's "--repeat: must be in [1, 1000] (got
/// 0)" as "--repeat must be in ...". The help shows the range.
CLI::Validator in_range(double min, double max, bool integral = true);

void add_tree_options(CLI::App& app, KdTreeParams& tree, SkipFlags skip = {});
void add_trace_options(CLI::App& app, TraceParams& trace, SkipFlags skip = {});
void add_film_options(CLI::App& app, FilmParams& film, SkipFlags skip = {});
void add_stop_options(CLI::App& app, StopConditions& stop, SkipFlags skip = {});
/// The SCENE positional, the environment overrides, the image size, the tree cache and the
/// camera (--view, --views).
void add_scene_options(CLI::App& app, SceneOptions& scene);
/// All of the above for a render; --threads sets the trace's threads (resolve() gives the
/// tree the same).
void add_render_options(CLI::App& app, RenderOptions& options);

/// The stop conditions of a session (--session, --frames sessions:) with `app`'s command
/// line: when it gives a stop flag (--spp, --time, --error), that replaces the session's whole
/// stop block, so that `--session IMAGE --spp 200` is not still cut by the image's --time;
/// the stop fields it does not give take their defaults. Else `stop` is left as it is.
void command_line_stop(const CLI::App& app, StopConditions& stop);

/// Warns on stderr about kd-tree flags given on `app`'s command line that cannot change the
/// tree: those of the builder not chosen (kd_tree_field_applies()), and with `tree_file` (a
/// --tree, whose parameters are the file's) all of them but --threads.
void warn_unused_tree_flags(const CLI::App& app, const KdTreeParams& tree, bool tree_file);

/// Reads the --views file given on `app`'s command line, if any, so that a missing or broken
/// one is an error even when no --view reads it (throws kdt::Error naming the file).
void check_views_file(const CLI::App& app);

/// Warns on stderr about render flags given on `app`'s command line that `options` (as
/// given, before resolve()) cannot honour: the adaptive sampling flags without adaptive
/// sampling (--adaptive or --error), --adaptive-threshold with --error (the target is the
/// threshold), and an --spp above --max-spp (the render stops at the cap; the default spp
/// of a render without a stop condition is not the user's, and not warned about).
void warn_unused_render_flags(const CLI::App& app, const RenderOptions& options);

/// Warns on stderr about --exposure and --tonemap given on `app`'s command line when `output`
/// (an image name or a --frames pattern) is linear (.exr, .pfm, .hdr): only PNG output is
/// tone-mapped.
void warn_unused_output_flags(const CLI::App& app, const std::string& output);

/// Peak bytes per pixel of a render: the film's sums, counts and scratch, and the linear and
/// output images made from it at the end. Measured with /usr/bin/time at 4096x4096: 113,
/// 119 with --adaptive, 122 with --transparent; rounded up.
inline constexpr uint64_t kRenderBytesPerPixel = 128;

/// Refuses a `width` x `height` render whose film and output would not fit in the memory
/// available (allocatable_memory_bytes()), naming --width and --height, before any work:
/// 16384x8192 takes about 15 GB, which a smaller machine runs out of only after loading the
/// scene and building its tree, with main()'s bare "out of memory".
void check_image_memory(int width, int height);

/// Prints view_model_warning() ("kdtrace: warning: ..." on stderr) for a camera that `label`
/// ("--view A") took from the views file `views` ("" = the shipped one) and the scene
/// `scene`, loaded from `scene_path` ("" = the built-in scene), if there is one.
void warn_view_model(const std::string& views, const std::string& label,
                     const std::string& scene_path, const Scene& scene);

/// A camera error ("camera: up vector is zero") followed by the camera flags given on `app`'s
/// command line, and where the other parts of `scene` (the options that made the camera)
/// came from (camera_part_source()): "camera: up vector is parallel to the viewing direction
/// (--eye 0,0,0 with the scene's target and up)", "(--up 0,0,0 with the scene's eye and
/// s.json's target)", "(--up 0,0,0 with --view A's eye and target)"; `view` names a view that
/// is no --view flag ("view A" of --frames views:A). A session file's camera error
/// (check_session_camera()) gets the values of the flags it names: "target from --target
/// 1,2,3", "up from --view A". Other messages unchanged.
std::string with_camera_flags(const CLI::App& app, const std::string& message,
                              const SceneOptions& scene, const std::string& view = "");

/// Whether a line of prepare_render()'s log (or a worker's, "ranks 1, 2 of 3: ...") is a
/// warning: shown under --quiet, which silences progress and cache messages, not problems.
bool is_warning(const std::string& line);

/// A renderer message with every field name it mentions ("trace.max_depth") followed by the
/// flag that sets it ("trace.max_depth (--path-depth)"), so a CLI user knows what to change.
std::string with_flags(const std::string& message);

}  // namespace kdt::app
