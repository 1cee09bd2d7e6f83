// The viewer's threads under stress: while the render thread runs passes and the rebuild thread
// builds trees, the UI side changes camera, parameters, heat map, pause and trees 100 times and
// reads images, previews and stats. Run under the tsan preset by scripts/run_tsan.sh: no race,
// no deadlock, no crash; and the worker settles on the last change.
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "renderer/io/image_io.h"
#include "renderer/render/snapshot.h"
#include "tests/renderer/integrator/test_scenes.h"
#include "tests/test_util.h"
#include "ui/camera_control.h"
#include "ui/render_worker.h"
#include "ui/tree_rebuild.h"

namespace kdt::ui {
namespace {

std::shared_ptr<const RenderSnapshot> stress_snapshot() {
    const TraceScene scene = test::make_scene(
        {{test::make_icosphere({0, 0.5f, 0}, 0.5f, 2), test::smooth(test::diffuse(0.7f))},
         {test::make_box({-1, -1, -1}, {1, 0, 1}), test::flat(test::diffuse(0.5f))}},
        std::make_shared<test::GradientEnv>());
    return compile_snapshot(scene, make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 48, 32));
}

template <class F>
bool wait_for(F&& done, double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (!done()) {
        if (std::chrono::steady_clock::now() > end) return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return true;
}

TEST(ViewerThreads, HundredChangesWhileRenderingAndRebuilding) {
    auto snap = stress_snapshot();
    TraceParams tp;
    tp.threads = 2;
    tp.count_traversal = true;
    StopConditions stop;  // none: render on
    RenderWorker worker(snap, tp, FilmParams{}, stop, 4);
    TreeRebuilder rebuilder;
    CameraDesc camera = snap->camera_desc;
    FilmImage image, preview;
    size_t swapped = 0;
    for (int i = 0; i < 100; ++i) {
        camera = orbit(camera, 7.0f, (i % 5) - 2.0f);
        worker.set_camera(camera);
        TraceParams t = tp;
        t.samples_per_pass = 1 + i % 3;
        FilmParams f;
        f.adaptive = i % 4 == 0;
        worker.set_params(t, f, stop);
        if (i % 9 == 0) worker.set_heat_map(i % 18 == 0);
        if (i % 11 == 0) {
            EnvironmentDesc env;
            env.color = Vec3f(0.5f, 0.6f, 0.7f);
            env.intensity = 1.0f + 0.01f * float(i);
            worker.set_environment(env);
        }
        if (i % 13 == 0) worker.set_paused(true);
        if (i % 13 == 1) worker.set_paused(false);
        if (i % 10 == 0) {
            KdTreeParams kp;
            kp.builder = i % 20 == 0 ? KdBuilder::thesis : KdBuilder::sah;
            kp.q = 0.8f + 0.002f * float(i);
            kp.threads = 1;
            rebuilder.request(worker.snapshot(), kp);
        }
        if (std::optional<RebuildResult> r = rebuilder.take()) {
            ASSERT_TRUE(r->snapshot) << r->error;
            worker.set_snapshot(r->snapshot);
            ++swapped;
        }
        worker.session().copy_image(image, i % 2 == 0);
        worker.copy_preview(preview);
        (void)worker.session().inspect(i % 48, i % 32);
        (void)worker.stats();
        std::this_thread::sleep_for(std::chrono::microseconds(200 * (i % 7)));
    }
    worker.set_paused(false);
    // The last rebuild lands and the worker renders the last camera at full resolution.
    ASSERT_TRUE(wait_for([&] { return !rebuilder.busy(); }, 120.0));
    if (std::optional<RebuildResult> r = rebuilder.take()) {
        ASSERT_TRUE(r->snapshot) << r->error;
        worker.set_snapshot(r->snapshot);
        ++swapped;
    }
    EXPECT_GE(swapped, 1u);
    ASSERT_TRUE(wait_for([&] { return worker.stats().full_passes >= 2; }, 120.0));
    ASSERT_TRUE(wait_for(
        [&] {
            worker.session().copy_image(image);
            return image.complete_passes >= 1;
        },
        120.0));
    EXPECT_EQ(image.width, 48);
    EXPECT_EQ(image.height, 32);
    // The last environment (i = 99) is in force, also over the trees rebuilt before it.
    EXPECT_EQ(worker.snapshot()->environment.intensity, 1.0f + 0.01f * 99.0f);
    EXPECT_EQ(worker.stats().error, "");
    const CameraDesc now = worker.camera();
    EXPECT_EQ(now.eye, camera.eye);
    EXPECT_GT(worker.stats().mrays_per_second, 0.0);
}

// A scene swapped in while the render thread loads a probe file (outside its lock) is the one
// it renders with that probe; it once put the snapshot it had read before the load back.
TEST(ViewerThreads, ASceneSwappedInWhileAProbeLoadsIsKept) {
    const auto dir = test::temp_dir("ui_probe_swap");
    // Probes large enough that building their light takes a while.
    std::vector<std::string> probes;
    for (int k = 0; k < 2; ++k) {
        ImageRGB map(2048, 1024);
        for (size_t i = 0; i < map.rgb.size(); ++i) map.rgb[i] = float((i * 7 + size_t(k)) % 13);
        probes.push_back((dir / ("probe" + std::to_string(k) + ".pfm")).string());
        write_image(probes.back(), map);
    }
    const auto first = stress_snapshot();
    const auto second = compile_snapshot(
        test::make_scene(
            {{test::make_box({-1, -1, -1}, {1, 0, 1}), test::flat(test::diffuse(0.5f))}},
            std::make_shared<test::GradientEnv>()),
        make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 48, 32));
    TraceParams tp;
    tp.threads = 2;
    RenderWorker worker(first, tp, FilmParams{}, StopConditions{}, 4);
    for (int round = 0; round < 12; ++round) {
        EnvironmentDesc env;
        env.file = probes[size_t(round % 2)];
        worker.set_environment(env);
        std::this_thread::sleep_for(std::chrono::milliseconds(round * 3));
        const auto& scene = round % 2 == 0 ? second : first;
        worker.set_snapshot(scene);
        const auto taken = [&] {
            const auto s = worker.snapshot();
            return s->environment.file == env.file && s->scene->mesh == scene->scene->mesh &&
                   worker.stats().full_passes >= 1;
        };
        ASSERT_TRUE(wait_for(taken, 60.0))
            << "round " << round << ": the render thread lost the scene or the probe";
    }
    EXPECT_EQ(worker.stats().error, "");
}

TEST(ViewerThreads, ATreeSwapAloneSkipsThePreviewACameraMoveDoesNot) {
    auto snap = stress_snapshot();
    TraceParams tp;
    tp.threads = 2;
    RenderWorker worker(snap, tp, FilmParams{}, StopConditions{}, 4);
    FilmImage preview;
    auto settled = [&](uint64_t restarts) {
        return wait_for(
            [&] {
                const WorkerStats s = worker.stats();
                return s.restarts == restarts && s.full_passes >= 1;
            },
            120.0);
    };
    ASSERT_TRUE(settled(worker.stats().restarts));
    ASSERT_TRUE(worker.copy_preview(preview));  // the first image starts with a preview
    EXPECT_EQ(preview.width, 48 / 4);
    KdTreeParams kp;
    kp.builder = KdBuilder::thesis;
    const auto rebuilt = with_tree(*snap, build_kdtree(snap->scene->mesh, kp));
    worker.set_snapshot(rebuilt);
    ASSERT_TRUE(settled(worker.stats().restarts));
    EXPECT_FALSE(worker.copy_preview(preview)) << "a tree swap made a preview";
    EXPECT_EQ(worker.snapshot()->scene->tree, rebuilt->scene->tree);
    worker.set_camera(orbit(snap->camera_desc, 10.0f, 0.0f));
    ASSERT_TRUE(settled(worker.stats().restarts));
    EXPECT_TRUE(worker.copy_preview(preview)) << "a camera move made no preview";
    // With the heat map on, a new tree changes the picture: it gets a preview.
    worker.set_heat_map(true);
    ASSERT_TRUE(settled(worker.stats().restarts));
    worker.copy_preview(preview);
    worker.set_snapshot(snap);
    ASSERT_TRUE(settled(worker.stats().restarts));
    EXPECT_TRUE(worker.copy_preview(preview)) << "a tree swap under the heat map made no preview";
}

TEST(ViewerThreads, AnErrorOnTheRenderThreadIsReportedAndTheNextChangeRendersAgain) {
    auto snap = stress_snapshot();
    TraceParams tp;
    tp.threads = 2;
    RenderWorker worker(snap, tp, FilmParams{}, StopConditions{}, 4);
    CameraDesc collapsed = snap->camera_desc;
    collapsed.eye = collapsed.target;  // make_camera() throws on the render thread
    worker.set_camera(collapsed);
    ASSERT_TRUE(wait_for([&] { return worker.failures() == 1; }, 120.0));
    const WorkerStats failed = worker.stats();
    EXPECT_NE(failed.render_error.find("eye and target coincide"), std::string::npos)
        << failed.render_error;
    EXPECT_TRUE(failed.done);
    worker.set_camera(snap->camera_desc);
    const uint64_t restarts = worker.stats().restarts;
    ASSERT_TRUE(wait_for(
        [&] {
            const WorkerStats s = worker.stats();
            return s.restarts == restarts && s.full_passes >= 2;
        },
        120.0));
    EXPECT_EQ(worker.stats().render_error, "");
    EXPECT_EQ(worker.failures(), 1u);
}

TEST(ViewerThreads, ANewerRebuildRequestSupersedesAnOlderOne) {
    auto snap = stress_snapshot();
    TreeRebuilder rebuilder;
    KdTreeParams a, b;
    a.q = 0.9f;
    b.q = 0.85f;
    b.builder = KdBuilder::thesis;
    rebuilder.request(snap, a);
    const uint64_t last = rebuilder.request(snap, b);
    ASSERT_TRUE(wait_for([&] { return !rebuilder.busy(); }, 120.0));
    std::optional<RebuildResult> r = rebuilder.take();
    ASSERT_TRUE(r);
    EXPECT_EQ(r->request, last);
    ASSERT_TRUE(r->snapshot);
    EXPECT_EQ(r->snapshot->tree_params.builder, KdBuilder::thesis);
    EXPECT_EQ(r->snapshot->scene->mesh, snap->scene->mesh);  // the mesh is shared
    EXPECT_FALSE(rebuilder.take());                          // taken once
    // A bad parameter is an error in the result, not a crash.
    KdTreeParams bad;
    bad.q = 2.0f;
    rebuilder.request(snap, bad);
    ASSERT_TRUE(wait_for([&] { return !rebuilder.busy(); }, 120.0));
    r = rebuilder.take();
    ASSERT_TRUE(r);
    EXPECT_FALSE(r->snapshot);
    EXPECT_NE(r->error.find("tree.q"), std::string::npos) << r->error;
}

}  // namespace
}  // namespace kdt::ui
