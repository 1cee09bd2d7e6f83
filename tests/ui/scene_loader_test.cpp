// The viewer's background loader: scenes, models and probes load off the calling thread, a
// newer request supersedes an older one, prepare_render's stage hooks and cancel point, and
// every failure comes back as a message naming the file (never an exception or a crash).
#include "ui/scene_loader.h"

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/render/settings.h"
#include "tests/test_util.h"

namespace kdt::ui {
namespace {

// An ASCII PLY of a unit quad (two triangles) in the z = 0 plane.
std::string write_quad_ply(const std::filesystem::path& dir) {
    const std::string path = (dir / "quad.ply").string();
    std::ofstream f(path);
    f << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
         "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
         "-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2\n3 0 2 3\n";
    return path;
}

LoadRequest scene_request(const std::string& path) {
    LoadRequest r;
    r.kind = LoadKind::scene;
    r.path = path;
    r.options.scene.scene_path = path;
    r.options.scene.width = 32;
    r.options.scene.height = 24;
    r.options.scene.use_cache = false;
    r.options = resolve(r.options);
    return r;
}

// The next result; fails the test after a minute (a hang, not a timing check).
LoadResult wait_result(SceneLoader& loader) {
    for (int i = 0; i < 60000; ++i) {
        if (std::optional<LoadResult> r = loader.take()) return *r;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ADD_FAILURE() << "the loader produced no result";
    return {};
}

TEST(SceneLoader, LoadsAModelInTheBackground) {
    const auto dir = test::temp_dir("loader_model");
    SceneLoader loader;
    const std::string ply = write_quad_ply(dir);
    EXPECT_EQ(loader.request(scene_request(ply)), 1u);
    const LoadResult r = wait_result(loader);
    EXPECT_EQ(r.request, 1u);
    EXPECT_EQ(r.error, "");
    ASSERT_TRUE(r.prepared);
    EXPECT_EQ(r.prepared->snapshot->scene->mesh->triangle_count(), 2u);
    EXPECT_EQ(r.prepared->snapshot->camera.width, 32);
    EXPECT_EQ(r.what.path, ply);
    EXPECT_FALSE(loader.busy());
    EXPECT_FALSE(loader.take());  // taken once
}

TEST(SceneLoader, FailuresNameTheFile) {
    const auto dir = test::temp_dir("loader_errors");
    SceneLoader loader;
    const std::string missing = (dir / "missing.ply").string();
    loader.request(scene_request(missing));
    LoadResult r = wait_result(loader);
    EXPECT_FALSE(r.prepared);
    EXPECT_NE(r.error.find(missing), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("cannot open"), std::string::npos) << r.error;

    // A header promising more vertices than the file has.
    const std::string bad = (dir / "bad.ply").string();
    std::ofstream(bad) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                          "property float y\nproperty float z\nelement face 1\n"
                          "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n";
    loader.request(scene_request(bad));
    r = wait_result(loader);
    EXPECT_FALSE(r.prepared);
    EXPECT_NE(r.error.find(bad), std::string::npos) << r.error;

    // A probe that is not an image.
    const std::string probe = (dir / "probe.hdr").string();
    std::ofstream(probe) << "#?RADIANCE\nthis is not a picture\n";
    LoadRequest p;
    p.kind = LoadKind::probe;
    p.path = probe;
    p.environment.file = probe;
    loader.request(p);
    r = wait_result(loader);
    EXPECT_FALSE(r.probe);
    EXPECT_NE(r.error.find(probe), std::string::npos) << r.error;
}

TEST(SceneLoader, LoadsAProbe) {
    const auto dir = test::temp_dir("loader_probe");
    ImageRGB img(8, 4);
    for (size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = i % 3 == 0 ? 2.0f : 0.5f;
    const std::string probe = (dir / "probe.pfm").string();
    write_image(probe, img);
    SceneLoader loader;
    LoadRequest p;
    p.kind = LoadKind::probe;
    p.path = probe;
    p.environment.file = probe;
    p.environment.mapping = EnvMapping::latlong;
    loader.request(p);
    const LoadResult r = wait_result(loader);
    EXPECT_EQ(r.error, "");
    ASSERT_TRUE(r.probe);
}

TEST(SceneLoader, NewerRequestSupersedesOlder) {
    const auto dir = test::temp_dir("loader_supersede");
    const std::string ply = write_quad_ply(dir);
    SceneLoader loader;
    // The default scene (a few hundred thousand triangles) takes a while; the quad, asked
    // for at once, is the only result, and the older one is never handed out.
    loader.request(scene_request(""));
    EXPECT_TRUE(loader.busy());
    EXPECT_TRUE(loader.progress().busy);
    // Once it is loading, so that the sanitizers see a load cancelled in flight (at its next
    // stage boundary; how far it got depends on the scheduler, so that is not asserted).
    for (int i = 0; i < 60000 && !loader.progress().started; ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_EQ(loader.progress().path, "");
    loader.request(scene_request(ply));
    const LoadResult r = wait_result(loader);
    EXPECT_EQ(r.request, 2u);
    EXPECT_EQ(r.what.path, ply);
    ASSERT_TRUE(r.prepared);
    EXPECT_EQ(r.prepared->snapshot->scene->mesh->triangle_count(), 2u);
    EXPECT_FALSE(loader.busy());
    EXPECT_FALSE(loader.take());
    EXPECT_FALSE(loader.progress().busy);
    EXPECT_EQ(loader.progress().path, ply);
    EXPECT_LE(loader.cancelled_count(), 1);
}

TEST(SceneLoader, DestroyedWhileLoadingJoinsCleanly) {
    SceneLoader loader;
    loader.request(scene_request(""));  // the destructor cancels it at a stage boundary
}

TEST(PrepareHooks, StagesInOrderAndCancelBetweenThem) {
    const auto dir = test::temp_dir("prepare_hooks");
    const LoadRequest req = scene_request(write_quad_ply(dir));
    std::vector<PrepareStage> stages;
    PrepareHooks hooks;
    hooks.stage = [&](PrepareStage s) { stages.push_back(s); };
    const Prepared p = prepare_render(
        req.options, [](const std::string&) {}, hooks);
    EXPECT_EQ(p.snapshot->scene->mesh->triangle_count(), 2u);
    ASSERT_EQ(stages.size(), 3u);
    EXPECT_EQ(stages[0], PrepareStage::reading);
    EXPECT_EQ(stages[1], PrepareStage::environment);
    EXPECT_EQ(stages[2], PrepareStage::tree);

    // Cancelled once the file is read: no environment and no tree.
    stages.clear();
    hooks.cancelled = [&] { return !stages.empty(); };
    const std::string e = test::error_of_call([&] {
        prepare_render(
            req.options, [](const std::string&) {}, hooks);
    });
    EXPECT_NE(e.find("cancelled"), std::string::npos) << e;
    EXPECT_EQ(stages.size(), 1u);
}

TEST(SceneLoader, FileKinds) {
    EXPECT_EQ(load_kind_of("a/dragon.PLY"), LoadKind::scene);
    EXPECT_EQ(load_kind_of("d.ply.gz"), LoadKind::scene);
    EXPECT_EQ(load_kind_of("m.obj"), LoadKind::scene);
    EXPECT_EQ(load_kind_of("s.json"), LoadKind::scene);
    EXPECT_EQ(load_kind_of("grace.hdr"), LoadKind::probe);
    EXPECT_EQ(load_kind_of("p.EXR"), LoadKind::probe);
    EXPECT_EQ(load_kind_of("p.pfm"), LoadKind::probe);
    EXPECT_FALSE(load_kind_of("notes.txt"));
    EXPECT_FALSE(load_kind_of(".ply"));
    EXPECT_FALSE(load_kind_of(""));
}

TEST(WithMaterials, ReplacesMaterialsAndSharesGeometry) {
    const auto dir = test::temp_dir("with_materials");
    const Prepared p =
        prepare_render(scene_request(write_quad_ply(dir)).options, [](const std::string&) {});
    const RenderSnapshot& base = *p.snapshot;
    ASSERT_EQ(base.scene->instances.size(), 1u);
    MaterialDesc red;
    red.albedo = Vec3f(0.9f, 0.1f, 0.1f);
    const auto snap = with_materials(base, {red});
    EXPECT_EQ(snap->scene->instances[0].material.albedo, red.albedo);
    EXPECT_TRUE(snap->scene->emitters.empty());
    MaterialDesc lamp;
    lamp.type = MaterialType::emissive;
    lamp.emission = Vec3f(1.0f);
    EXPECT_FALSE(with_materials(base, {lamp})->scene->emitters.empty());  // seen by the lights
    EXPECT_EQ(snap->scene->mesh, base.scene->mesh);
    EXPECT_EQ(snap->scene->tree, base.scene->tree);
    EXPECT_NE(base.scene->instances[0].material.albedo, red.albedo);  // the base is untouched
    EXPECT_NE(test::error_of_call([&] { with_materials(base, {}); }), "");
    MaterialDesc bad;
    bad.albedo = Vec3f(-1.0f);
    EXPECT_NE(test::error_of_call([&] { with_materials(base, {bad}); }), "");
}

}  // namespace
}  // namespace kdt::ui
