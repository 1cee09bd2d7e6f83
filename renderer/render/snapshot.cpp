#include "renderer/render/snapshot.h"

#include <string>

#include "renderer/core/error.h"
#include "renderer/core/timer.h"

namespace kdt {

Camera make_camera(const CameraDesc& c, int width, int height) {
    return make_camera(c.eye, c.target, c.up, c.vfov_degrees, width, height);
}

TraceScene merge_instances(const Scene& scene) {
    TraceScene ts;
    auto merged = std::make_shared<TriangleMesh>();
    bool any_smooth = false;
    for (size_t i = 0; i < scene.meshes.size(); ++i) {
        const MeshInstance& inst = scene.meshes[i];
        if (!inst.mesh) {
            throw Error(ErrorLocation{inst.file, "mesh", int64_t(i)},
                        "mesh instance has no loaded mesh");
        }
        ShadingInstance si;
        si.material = compile_material(inst.material);
        si.smooth = inst.smooth;
        any_smooth |= inst.smooth;
        ts.instances.push_back(si);
    }
    for (size_t i = 0; i < scene.meshes.size(); ++i) {
        const MeshInstance& inst = scene.meshes[i];
        TriangleMesh m = *inst.mesh;
        m.colors.clear();
        const size_t nv = m.positions.size();
        if (m.normals.size() != nv) m.normals.clear();
        transform_mesh(m, inst.world_from_object);
        for (size_t v = 0; v < nv; ++v) {
            if (!is_finite(m.positions[v])) {
                throw Error(ErrorLocation{inst.file, "vertex", int64_t(v)},
                            "not finite after the instance's transform (it overflows float)");
            }
        }
        // Triangles close in space close in memory, instance by instance (each instance's
        // triangles stay one run): a kd-tree leaf's triangles and vertices then share cache
        // lines and pages, which speeds up queries, above all incoherent ones.
        apply_order(m, spatial_order(m));
        const auto base = uint32_t(merged->positions.size());
        merged->positions.insert(merged->positions.end(), m.positions.begin(), m.positions.end());
        if (any_smooth) {
            if (inst.smooth && m.normals.empty()) m.normals = compute_vertex_normals(m);
            if (!inst.smooth) m.normals.assign(nv, Vec3f(0.0f, 0.0f, 1.0f));
            ts.normals.insert(ts.normals.end(), m.normals.begin(), m.normals.end());
        }
        merged->triangles.reserve(merged->triangles.size() + m.triangles.size());
        for (const Vec3u& t : m.triangles) {
            if (t.x >= nv || t.y >= nv || t.z >= nv) {
                throw Error(ErrorLocation{inst.file, "face", int64_t(&t - m.triangles.data())},
                            "vertex index out of range (" + std::to_string(nv) + " vertices)");
            }
            merged->triangles.push_back(t + Vec3u(base));
        }
        ts.triangle_instance.insert(ts.triangle_instance.end(), m.triangles.size(), uint32_t(i));
    }
    ts.mesh = merged;
    return ts;
}

namespace {

// The CameraDesc a Camera was made from (its target one unit ahead).
CameraDesc camera_desc_of(const Camera& camera) {
    CameraDesc d;
    d.eye = camera.eye;
    d.target = camera.eye + camera.forward;
    d.up = camera.up;
    d.vfov_degrees = camera.vfov_degrees;
    return d;
}

}  // namespace

std::shared_ptr<const RenderSnapshot> compile_snapshot(const Scene& scene,
                                                       const SnapshotOptions& options) {
    Timer timer;
    // The camera first: a bad image size or field of view fails before any tree is built.
    const Camera camera = make_camera(scene.camera, options.width, options.height);
    TraceScene ts = merge_instances(scene);
    ts.env = options.env ? options.env : make_environment_light(scene.environment);
    auto snap =
        std::const_pointer_cast<RenderSnapshot>(compile_snapshot(std::move(ts), camera, options));
    snap->camera_desc = scene.camera;
    snap->environment = scene.environment;
    snap->scene_name = scene.name;
    snap->build_seconds = timer.seconds();
    return snap;
}

std::shared_ptr<const RenderSnapshot> compile_snapshot(TraceScene scene, const Camera& camera,
                                                       const SnapshotOptions& options) {
    Timer timer;
    if (!scene.mesh) throw Error("snapshot: scene has no mesh");
    if (scene.triangle_instance.size() != scene.mesh->triangle_count()) {
        throw Error("snapshot: triangle_instance must have one entry per triangle");
    }
    if (!scene.env) scene.env = options.env ? options.env : make_environment_light({});
    if (!scene.tree) scene.tree = build_kdtree(scene.mesh, options.tree);
    scene.emitters = build_emitter_table(scene);
    scene.runs = build_instance_runs(scene);
    auto snap = std::make_shared<RenderSnapshot>();
    snap->scene = std::make_shared<const TraceScene>(std::move(scene));
    snap->camera = camera;
    snap->camera_desc = camera_desc_of(camera);
    snap->tree_params = snap->scene->tree->params();
    snap->build_seconds = timer.seconds();
    return snap;
}

std::shared_ptr<const RenderSnapshot> with_camera(const RenderSnapshot& snapshot,
                                                  const Camera& camera) {
    auto snap = std::make_shared<RenderSnapshot>(snapshot);
    snap->camera = camera;
    snap->camera_desc = camera_desc_of(camera);
    return snap;
}

std::shared_ptr<const RenderSnapshot> with_tree(const RenderSnapshot& snapshot,
                                                std::shared_ptr<const KdTree> tree) {
    if (!tree) throw Error("snapshot: no kd-tree");
    if (&tree->mesh() != snapshot.scene->mesh.get())
        throw Error("snapshot: the kd-tree was built over another mesh");
    auto scene = std::make_shared<TraceScene>(*snapshot.scene);
    scene->tree = std::move(tree);
    auto snap = std::make_shared<RenderSnapshot>(snapshot);
    snap->tree_params = scene->tree->params();
    snap->scene = std::move(scene);
    return snap;
}

std::shared_ptr<const RenderSnapshot> with_environment(const RenderSnapshot& snapshot,
                                                       std::shared_ptr<const EnvironmentLight> env,
                                                       const EnvironmentDesc& desc) {
    if (!env) throw Error("snapshot: no environment light");
    auto scene = std::make_shared<TraceScene>(*snapshot.scene);
    scene->env = std::move(env);
    auto snap = std::make_shared<RenderSnapshot>(snapshot);
    snap->scene = std::move(scene);
    snap->environment = desc;
    return snap;
}

}  // namespace kdt
