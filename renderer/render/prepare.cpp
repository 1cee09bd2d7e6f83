#include "renderer/render/prepare.h"

#include <cmath>
#include <cstdio>

#include "renderer/accel/kdtree_cache.h"
#include "renderer/core/timer.h"
#include "renderer/render/settings.h"

namespace kdt {

Prepared prepare_render(const PrepareOptions& o) {
    Prepared out;
    Timer timer;
    SceneLoadOptions lo;
    lo.drop_invalid = o.drop_invalid;
    out.scene = o.scene_path.empty() ? make_default_scene() : load_scene_or_model(o.scene_path, lo);
    if (!o.env_file.empty()) {
        out.scene.environment.file = o.env_file;
        out.scene.environment.mapping = EnvMapping::latlong;
    }
    if (!o.env_mapping.empty()) {
        const auto mapping =
            EnvMapping(parse_name(kEnvMappingNames, o.env_mapping, "--env-mapping"));
        if (out.scene.environment.file.empty())
            throw Error(
                "--env-mapping: the scene has no environment map to map (give one with --env)");
        out.scene.environment.mapping = mapping;
    }
    if (!std::isfinite(o.env_rotation_degrees))
        throw Error("--env-rotation must be a finite number of degrees (got " +
                    std::to_string(o.env_rotation_degrees) + ")");
    if (o.env_intensity) {
        if (!(*o.env_intensity >= 0.0f && std::isfinite(*o.env_intensity)))
            throw Error("--env-intensity must be a finite number >= 0 (got " +
                        std::to_string(*o.env_intensity) + ")");
        out.scene.environment.intensity = *o.env_intensity;
    }
    out.scene.environment.rotation_degrees += o.env_rotation_degrees;
    if (o.camera) out.scene.camera = *o.camera;
    out.load_seconds = timer.seconds();

    auto log =
        o.log ? o.log : [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
    SnapshotOptions so;
    so.width = o.width;
    so.height = o.height;
    so.tree = o.tree;
    const std::string model = o.scene_path;
    if (o.use_cache) {
        so.build_tree = [&](std::shared_ptr<const TriangleMesh> mesh, const KdTreeParams& params) {
            Timer t;
            KdCacheReport report;
            // The merged world-space mesh of a scene file differs from the file's mesh; the
            // cache validates the content hash, so naming it after the scene is safe.
            auto tree =
                get_or_build_kdtree(model, std::move(mesh), params, o.cache_dir, log, &report);
            out.tree_seconds = t.seconds();
            out.tree_from_cache = report.loaded;
            return tree;
        };
    } else {
        so.build_tree = [&](std::shared_ptr<const TriangleMesh> mesh, const KdTreeParams& params) {
            Timer t;
            auto tree = build_kdtree(std::move(mesh), params);
            out.tree_seconds = t.seconds();
            return tree;
        };
    }
    out.snapshot = compile_snapshot(out.scene, so);
    return out;
}

}  // namespace kdt
