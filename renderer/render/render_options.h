// Everything a render needs, in one struct set with valid defaults: the scene to prepare, the
// kd-tree, path tracing, film and stop conditions. Every numeric, bool and enum field is also
// described as data (renderer/core/fields.h): validate(), the CLI's flags, the viewer's widgets
// and the JSON of image metadata and session files all read these tables.
// Depends on accel, integrator, film, scene.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "renderer/accel/kdtree.h"
#include "renderer/core/error.h"
#include "renderer/core/fields.h"
#include "renderer/film/film.h"
#include "renderer/integrator/path_tracer.h"
#include "renderer/scene/scene.h"

namespace kdt {

/// When a render stops; any non-zero condition that is met stops it (0 = that condition off).
struct StopConditions {
    int spp = 0;           ///< samples per pixel (adaptive: a budget of spp * pixels in total)
    double seconds = 0.0;  ///< wall time
    float error = 0.0f;    ///< target relative error; implies adaptive sampling (resolve())
    int max_spp = 65536;   ///< safety cap per pixel
};

/// Samples per pixel of a render given no stop condition.
inline constexpr int kDefaultSpp = 16;

/// The camera parts a session file gave, as read: its /scene/camera, /scene/eye, /scene/target
/// and /scene/up, which SceneOptions also holds as `camera`, `eye`, `target` and `up`. Kept so
/// that parts making no camera with the scene's are an error naming the file and its keys
/// (check_session_camera()). A part counts as the session's while SceneOptions still holds
/// the value read: one a flag or a view replaced is not the session's to answer for.
struct SessionCamera {
    std::string file;  ///< the session file; empty when none gave a camera part
    std::optional<CameraDesc> camera;
    std::array<bool, 3> camera_keys{};  ///< whether /scene/camera gave eye, target and up
    std::optional<Vec3f> eye, target, up;
};

/// What to load and how to compile it into a snapshot (the tree's parameters are
/// RenderOptions::tree).
struct SceneOptions {
    std::string scene_path;   ///< .json scene or model file; empty = make_default_scene()
    std::string env_file;     ///< replaces the scene's environment map when non-empty
    std::string env_mapping;  ///< "latlong" or "angular" (with env_file); empty = latlong
    std::optional<float> env_intensity;  ///< replaces the scene's intensity (finite, >= 0)
    float env_rotation_degrees = 0.0f;   ///< added to the scene's rotation about +y
    std::optional<CameraDesc> camera;    ///< replaces the scene's camera when set
    /// Each replaces one part of the camera (after `camera`): the command line's --eye,
    /// --target, --up and --fov.
    std::optional<Vec3f> eye, target, up;
    std::optional<float> vfov_degrees;
    int width = 640, height = 480;  ///< image size in pixels
    bool use_cache = true;          ///< kd-tree cache (get_or_build_kdtree)
    std::string cache_dir;          ///< empty = the user's cache directory
    /// A tree file written by `kdtrace build -o` to render with instead of the cache: checked
    /// against the scene's mesh like a cache file; its parameters are the file's.
    std::string tree_file;
    bool drop_invalid = false;  ///< drop faces with non-finite vertices
    int subdivide = 0;          ///< split every triangle into 4^subdivide (subdivide_scene())
    /// One per mesh instance of the scene, replacing the scene's materials when non-empty
    /// (the viewer's edits, saved with its session); another count is an error.
    std::vector<MaterialDesc> materials;
    /// Where `materials` were read (a session file and "/scene/materials"), named by the
    /// error that their count does not match the scene's, found once the scene is loaded;
    /// an empty path when they were set otherwise (the viewer).
    ErrorLocation materials_from;
    /// Where `env_mapping` was read (a session file and "/scene/env_mapping"), named by the
    /// error that the scene has no environment map to map, found once the scene is loaded;
    /// an empty path when it was set otherwise (--env-mapping, the viewer).
    ErrorLocation env_mapping_from;
    /// The camera parts of the last session file read that gave any.
    SessionCamera session_camera;
};

struct RenderOptions {
    SceneOptions scene;
    KdTreeParams tree;
    TraceParams trace;
    FilmParams film;
    StopConditions stop;
};

/// The range tables (defaults: the structs' initialisers). Messages name fields as
/// "<group>.<name>" with the groups scene, tree, trace, film and stop.
std::span<const Field<SceneOptions>> scene_fields();
std::span<const Field<TraceParams>> trace_fields();
std::span<const Field<FilmParams>> film_fields();
/// A stop field of value 0 is off and valid; a set one must be within its range.
std::span<const Field<StopConditions>> stop_fields();

/// The options a render actually runs with; every rule that ties fields together is here and
/// nowhere else: no stop condition means kDefaultSpp samples per pixel; an error target
/// turns adaptive sampling on with that target as the per-pixel threshold; a tree built for a
/// render uses the render's threads.
RenderOptions resolve(RenderOptions options);

/// Throws kdt::Error naming the first invalid field ("trace.max_depth must be in [0, 1024]
/// (got -1)"). Checks values only: files are checked when they are opened.
void validate(const SceneOptions& scene);
void validate(const TraceParams& trace);
void validate(const FilmParams& film);
void validate(const StopConditions& stop);
void validate(const RenderOptions& options);

/// The scene's file names (scene_path, env_file, tree_file, cache_dir) made absolute
/// (absolute_file_name()): what sessions and image metadata hold, since they are read from
/// any directory.
void make_file_names_absolute(SceneOptions& scene);

/// Every tabled field of every group as one JSON object {"tree": {...}, "trace": {...},
/// "film": {...}, "stop": {...}, "scene": {...}} (one line; strings of the scene too). A file
/// name (scene_path, env_file, cache_dir, tree_file) that is not valid UTF-8 is written
/// losslessly as NAME_bytes: the name with "%" and every byte outside a well-formed UTF-8
/// sequence as %XX (upper-case hex), e.g. "scene_path_bytes": "/m/%9Bq.ply".
std::string options_to_json(const RenderOptions& options);
/// Reads options_to_json() output (any subset of groups and keys) into `options`; unknown
/// or repeated groups or keys and invalid values throw kdt::Error naming `where` and the key.
/// With `relative_to` (a folder), a relative file name resolves against it, and one of an
/// input (scene_path, env_file, tree_file) that does not exist there is an error; empty keeps
/// names as given.
void options_from_json(const std::string& json, RenderOptions& options,
                       const std::string& where = "options", const std::string& relative_to = "");
/// options_from_json() of a session file: a regular file of at most 1 MiB (a FIFO or a
/// device is refused, not read), errors naming `path`. A PNG or OpenEXR file saved by kdtrace
/// (render or view) is a session too: its `kdtrace:params` metadata is read. Relative file
/// names resolve against the session's folder, as a scene file's do (kdtrace writes absolute
/// ones). The camera parts it gives are kept in options.scene.session_camera too.
void options_from_session_file(const std::string& path, RenderOptions& options);

}  // namespace kdt
