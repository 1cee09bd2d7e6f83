#include "renderer/render/prepare.h"

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
        out.scene.environment.mapping =
            o.env_mapping.empty()
                ? EnvMapping::latlong
                : EnvMapping(parse_name(kEnvMappingNames, o.env_mapping, "--env-mapping"));
    }
    if (o.env_intensity > 0.0f) out.scene.environment.intensity = o.env_intensity;
    out.scene.environment.rotation_degrees += o.env_rotation_degrees;
    out.load_seconds = timer.seconds();

    SnapshotOptions so;
    so.width = o.width;
    so.height = o.height;
    so.tree = o.tree;
    so.build_tree = [&](std::shared_ptr<const TriangleMesh> mesh, const KdTreeParams& params) {
        Timer t;
        auto tree = build_kdtree(std::move(mesh), params);
        out.tree_seconds = t.seconds();
        return tree;
    };
    out.snapshot = compile_snapshot(out.scene, so);
    return out;
}

}  // namespace kdt
