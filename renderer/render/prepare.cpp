#include "renderer/render/prepare.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "renderer/accel/kdtree_cache.h"
#include "renderer/camera/camera.h"
#include "renderer/core/error.h"
#include "renderer/core/timer.h"
#include "renderer/render/settings.h"

namespace kdt {

CameraDesc with_camera_overrides(CameraDesc c, const SceneOptions& o) {
    if (o.camera) c = *o.camera;
    if (o.eye) c.eye = *o.eye;
    if (o.target) c.target = *o.target;
    if (o.up) c.up = *o.up;
    if (o.vfov_degrees) c.vfov_degrees = *o.vfov_degrees;
    return c;
}

namespace {
constexpr const char* kCameraPartNames[] = {"eye", "target", "up"};
}  // namespace

CameraPartSource camera_part_source(const SceneOptions& o, size_t part) {
    using Kind = CameraPartSource::Kind;
    static constexpr std::optional<Vec3f> SceneOptions::*kSet[] = {
        &SceneOptions::eye, &SceneOptions::target, &SceneOptions::up};
    static constexpr std::optional<Vec3f> SessionCamera::*kRead[] = {
        &SessionCamera::eye, &SessionCamera::target, &SessionCamera::up};
    const SessionCamera& s = o.session_camera;
    const std::string name = kCameraPartNames[part];
    // As with_camera_overrides() takes the part: its own override, else the camera that
    // replaces the scene's, else the scene.
    if (const std::optional<Vec3f>& set = o.*kSet[part]) {
        const std::optional<Vec3f>& read = s.*kRead[part];
        if (!s.file.empty() && read && *read == *set) return {Kind::session, "/scene/" + name, ""};
        return {Kind::flag, "", "--" + name};
    }
    if (o.camera) {
        const std::optional<CameraDesc>& read = s.camera;
        if (!s.file.empty() && read && read->eye == o.camera->eye &&
            read->target == o.camera->target && read->up == o.camera->up) {
            // A key the object left out is its default: the object is to blame.
            return {Kind::session, s.camera_keys[part] ? "/scene/camera/" + name : "/scene/camera",
                    ""};
        }
        return {Kind::view, "", "the view"};
    }
    return {
        Kind::scene, "",
        o.scene_path.empty() ? "the built-in scene" : "the scene file " + printable(o.scene_path)};
}

void check_session_camera(const CameraDesc& scene_camera, const SceneOptions& o) {
    const SessionCamera& s = o.session_camera;
    if (s.file.empty()) return;
    const CameraDesc c = with_camera_overrides(scene_camera, o);
    const CameraFrameProblem problem = camera_frame_problem(c.eye, c.target, c.up);
    if (problem.why.empty()) return;
    const bool blamed[] = {problem.eye, problem.target, problem.up};
    std::vector<std::string> keys;
    std::vector<std::pair<std::string, std::string>> others;  // (parts, where from)
    for (size_t i = 0; i < 3; ++i) {
        if (!blamed[i]) continue;
        const auto [kind, key, other] = camera_part_source(o, i);
        if (!key.empty() && std::find(keys.begin(), keys.end(), key) == keys.end())
            keys.push_back(key);
        if (other.empty()) continue;
        if (!others.empty() && others.back().second == other) {
            others.back().first += std::string(" and ") + kCameraPartNames[i];
        } else {
            others.emplace_back(kCameraPartNames[i], other);
        }
    }
    if (keys.empty()) return;
    std::string pointers, from;
    for (const std::string& k : keys) pointers += (pointers.empty() ? "" : ", ") + k;
    for (const auto& [names, where] : others)
        from += (from.empty() ? " (" : ", ") + names + " from " + where;
    throw Error(ErrorLocation{s.file, pointers}, problem.why + (from.empty() ? "" : from + ")"));
}

Scene load_scene_with_overrides(const SceneOptions& o, const PrepareLog& log) {
    validate(o);
    SceneLoadOptions lo;
    lo.drop_invalid = o.drop_invalid;
    lo.warn = log;
    Scene scene =
        o.scene_path.empty() ? make_default_scene() : load_scene_or_model(o.scene_path, lo);
    if (o.subdivide > 0) {
        Timer timer;
        subdivide_scene(scene, o.subdivide, o.scene_path);
        char line[160];
        std::snprintf(line, sizeof(line), "subdivided %d times: %llu triangles (%.2f s)",
                      o.subdivide, static_cast<unsigned long long>(instanced_triangle_count(scene)),
                      timer.seconds());
        if (log) log(line);
    }
    EnvironmentDesc& env = scene.environment;
    if (!o.env_file.empty()) {
        env.file = o.env_file;
        env.mapping = EnvMapping::latlong;
    }
    if (!o.env_mapping.empty()) {
        if (env.file.empty()) {
            const std::string what = "the scene has no environment map to map";
            if (!o.env_mapping_from.path.empty()) throw Error(o.env_mapping_from, what);
            throw Error("scene.env_mapping: " + what);
        }
        env.mapping = EnvMapping(parse_name(kEnvMappingNames, o.env_mapping, "scene.env_mapping"));
    }
    if (o.env_intensity) env.intensity = *o.env_intensity;
    // The scene's whole turns come off first (fmod is exact): a rotation of 1e20 would
    // otherwise swallow the flag's 90 in the float sum.
    env.rotation_degrees = std::fmod(env.rotation_degrees, 360.0f) + o.env_rotation_degrees;
    check_session_camera(scene.camera, o);
    scene.camera = with_camera_overrides(scene.camera, o);
    if (!o.materials.empty()) {
        if (o.materials.size() != scene.meshes.size()) {
            const std::string what = std::to_string(o.materials.size()) +
                                     " materials for a scene of " +
                                     std::to_string(scene.meshes.size()) + " mesh instances";
            if (!o.materials_from.path.empty()) throw Error(o.materials_from, what);
            throw Error("scene.materials: " + what);
        }
        for (size_t i = 0; i < o.materials.size(); ++i) scene.meshes[i].material = o.materials[i];
    }
    return scene;
}

Prepared prepare_render(const RenderOptions& o, const PrepareLog& log, const PrepareHooks& hooks) {
    const auto enter = [&](PrepareStage stage) {
        if (hooks.cancelled && hooks.cancelled())
            throw Error(o.scene.scene_path + ": loading cancelled");
        if (hooks.stage) hooks.stage(stage);
    };
    validate(o);
    Prepared out;
    Timer timer;
    const PrepareLog say =
        log ? log : [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
    enter(PrepareStage::reading);
    out.scene = load_scene_with_overrides(o.scene, say);
    out.load_seconds = timer.seconds();

    // The camera and the environment before the tree: a bad image size or probe fails first.
    const Camera camera = make_camera(out.scene.camera, o.scene.width, o.scene.height);
    TraceScene ts = merge_instances(out.scene);
    enter(PrepareStage::environment);
    try {
        ts.env = make_environment_light(out.scene.environment, say);
    } catch (const Error& e) {
        // A map's errors name the map; a constant colour's radiance (colour times intensity)
        // names the option that gave the intensity, or else the scene file.
        if (!out.scene.environment.file.empty()) throw;
        if (o.scene.env_intensity) throw Error(std::string("scene.env_intensity: ") + e.what());
        if (o.scene.scene_path.empty()) throw;
        throw Error(ErrorLocation{o.scene.scene_path, "environment"}, e.what());
    }

    enter(PrepareStage::tree);
    Timer tree_timer;
    if (!o.scene.tree_file.empty()) {
        KdTreeParams params = kdtree_file_params(o.scene.tree_file);
        params.threads = o.tree.threads;
        // A file of the user's choice, verified once per version of it while the cache is
        // in use; --no-cache keeps the cache directory untouched.
        ts.tree = load_kdtree(o.scene.tree_file, ts.mesh, params, nullptr, o.scene.use_cache);
        out.tree_from_cache = true;
    } else if (o.scene.use_cache) {
        KdCacheReport report;
        // The merged world-space mesh of a scene file differs from the file's mesh; the cache
        // checks the content hash, so naming the file after the scene is safe.
        ts.tree = get_or_build_kdtree(subdivided_model_key(o.scene.scene_path, o.scene.subdivide),
                                      ts.mesh, o.tree, o.scene.cache_dir, say, &report,
                                      hooks.cancel_build);
        out.tree_from_cache = report.loaded;
    } else {
        ts.tree = build_kdtree(ts.mesh, o.tree, hooks.cancel_build);
        if (const std::string w = kdtree_leaf_warning(*ts.tree); !w.empty()) say("warning: " + w);
    }
    out.tree_seconds = tree_timer.seconds();

    auto snap = std::const_pointer_cast<RenderSnapshot>(compile_snapshot(std::move(ts), camera));
    snap->camera_desc = out.scene.camera;
    snap->environment = out.scene.environment;
    snap->scene_name = out.scene.name;
    snap->build_seconds = timer.seconds();
    out.snapshot = std::move(snap);
    return out;
}

std::string tree_source_text(const Prepared& prepared, const SceneOptions& options) {
    if (!prepared.tree_from_cache) return "";
    if (options.tree_file.empty()) return " (cached)";
    return " (from " + printable(options.tree_file) + ")";
}

}  // namespace kdt
