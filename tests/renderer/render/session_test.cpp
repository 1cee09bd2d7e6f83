// The render session: determinism for any thread count and tile split, reset, cancel,
// snapshot swaps, adaptive sampling and stop conditions; compiling a Scene.
#include "renderer/render/session.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include "renderer/core/error.h"
#include "renderer/render/prepare.h"
#include "tests/renderer/integrator/test_scenes.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::ConstantEnv;
using test::diffuse;
using test::flat;

std::shared_ptr<const RenderSnapshot> small_snapshot(int w = 40, int h = 24, float rho = 0.7f) {
    const TraceScene scene =
        test::make_scene({{test::make_icosphere({0, 0.5f, 0}, 0.5f, 2), test::smooth(diffuse(rho))},
                          {test::make_box({-1, -1, -1}, {1, 0, 1}), flat(diffuse(0.5f))},
                          {test::make_icosphere({0.7f, 0.3f, 0.4f}, 0.25f, 1),
                           test::smooth(test::of_type(MaterialType::dielectric))}},
                         std::make_shared<test::GradientEnv>());
    return compile_snapshot(scene, make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, w, h));
}

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

TEST(RenderSession, ImagesAreBitwiseIdenticalForAnyThreadCountAndTileSplit) {
    auto snap = small_snapshot();
    // Enough passes for the adaptive allocation to pick pixels and raise pass_samples().
    constexpr int kPasses = 10;
    std::vector<std::vector<float>> images;
    for (int threads : {1, 2, 3}) {
        for (bool adaptive : {false, true}) {
            TraceParams tp;
            tp.threads = threads;
            tp.samples_per_pass = 2;
            FilmParams fp;
            fp.adaptive = adaptive;
            fp.adaptive_min_spp = 4;
            fp.adaptive_threshold = 0.05f;
            RenderSession s(snap, tp, fp);
            for (int pass = 0; pass < kPasses; ++pass) s.render_pass();
            if (threads == 1) {
                images.push_back(s.film().linear_rgb());
            } else {
                EXPECT_TRUE(same_bits(images[adaptive ? 1 : 0], s.film().linear_rgb()))
                    << threads << " threads, adaptive " << adaptive;
            }
        }
    }
    // Rendering the tiles in two halves, in reverse order (an MPI-like split), matches too.
    TraceParams tp;
    tp.samples_per_pass = 2;
    RenderSession s(snap, tp, FilmParams{});
    std::vector<int> even, odd;
    for (int t = s.tile_count() - 1; t >= 0; --t) (t % 2 ? odd : even).push_back(t);
    for (int pass = 0; pass < kPasses; ++pass) {
        s.render_pass(odd);
        s.render_pass(even);
    }
    EXPECT_TRUE(same_bits(images[0], s.film().linear_rgb()));
    EXPECT_NE(images[0], images[1]);  // adaptive sampling changed the sample distribution
}

// The pass makes camera rays in batches; the film must hold exactly what render_sample()
// gives sample by sample, in order, with the per-pass count and the max_spp cap applied
// (tiles of 16 pixels, rows of 20 and 10: batches end inside pixels and rows).
TEST(RenderSession, BatchedPassesMatchSampleBySampleRendering) {
    auto snap = small_snapshot(20, 10);
    TraceParams tp;
    tp.samples_per_pass = 3;
    tp.seed = 5;
    RenderSession s(snap, tp, FilmParams{});
    const PassStats first = s.render_pass(4);
    const PassStats second = s.render_pass(4);  // one more sample each: the cap
    EXPECT_EQ(first.counters.samples, 200u * 3u);
    EXPECT_EQ(second.counters.samples, 200u);
    EXPECT_EQ(second.active_pixels, 200u);
    EXPECT_EQ(s.render_pass(4).active_pixels, 0u);
    for (int y = 0; y < 10; ++y) {
        for (int x = 0; x < 20; ++x) {
            Film f(1, 1);
            PathCounters c;
            for (uint32_t i = 0; i < 4; ++i) {
                f.add_sample(0, 0, render_sample(*snap->scene, snap->camera, tp, x, y, i, c));
            }
            ASSERT_EQ(s.film().count(x, y), 4u);
            ASSERT_EQ(s.film().mean(x, y), f.mean(0, 0)) << x << " " << y;
        }
    }
}

TEST(RenderSession, SeedChangesTheImage) {
    auto snap = small_snapshot(16, 16);
    TraceParams a, b;
    b.seed = 1;
    RenderSession sa(snap, a, FilmParams{}), sb(snap, b, FilmParams{});
    sa.render_pass();
    sb.render_pass();
    EXPECT_FALSE(same_bits(sa.film().linear_rgb(), sb.film().linear_rgb()));
}

TEST(RenderSession, ResetRestartsAndSnapshotSwapTakesEffect) {
    auto snap = small_snapshot(16, 16);
    RenderSession s(snap, TraceParams{}, FilmParams{});
    s.render_pass();
    const std::vector<float> first = s.film().linear_rgb();
    s.render_pass();
    EXPECT_EQ(s.film().count(3, 3), 2u);
    EXPECT_EQ(s.passes(), 2);
    s.reset();
    s.render_pass();
    EXPECT_EQ(s.film().count(3, 3), 1u);
    EXPECT_TRUE(same_bits(first, s.film().linear_rgb()));  // a clean restart replays

    // A new snapshot with a different size and albedo swaps in at the next pass.
    auto other = small_snapshot(8, 6, 0.1f);
    s.set_snapshot(other);
    EXPECT_EQ(s.film().width(), 16);  // not before the next pass
    s.render_pass();
    EXPECT_EQ(s.film().width(), 8);
    EXPECT_EQ(s.film().height(), 6);
    EXPECT_EQ(s.film().count(0, 0), 1u);
    EXPECT_EQ(&s.snapshot(), other.get());
    EXPECT_GT(s.totals().rays(), 0u);
    EXPECT_TRUE(s.heat_nodes().empty());  // heat maps are opt-in
    s.set_heat_map(true);
    s.render_pass();
    ASSERT_EQ(s.heat_nodes().size(), 48u);
    uint64_t nodes = 0, tris = 0;
    for (size_t i = 0; i < 48; ++i) {
        nodes += s.heat_nodes()[i];
        tris += s.heat_triangles()[i];
    }
    EXPECT_EQ(nodes, s.totals().nodes_visited);
    EXPECT_EQ(tris, s.totals().triangles_tested);
    EXPECT_GT(nodes, 0u);
}

TEST(RenderSession, HeatMapPassesMatchBatchedPasses) {
    // With a heat map, camera rays are traced one query each (for per-pixel counts);
    // without, by the kd-tree's batch query. Same films, same totals. 160x96 pixels of
    // 0.42 degrees and 8 samples per pixel and pass, so the batches form 8-ray packets.
    auto snap = small_snapshot(160, 96);
    TraceParams tp;
    tp.samples_per_pass = 8;
    RenderSession plain(snap, tp, FilmParams{}), heat(snap, tp, FilmParams{});
    heat.set_heat_map(true);
    for (int pass = 0; pass < 2; ++pass) {
        plain.render_pass();
        heat.render_pass();
    }
    EXPECT_TRUE(same_bits(plain.film().linear_rgb(), heat.film().linear_rgb()));
    EXPECT_EQ(plain.totals().rays(), heat.totals().rays());
    EXPECT_EQ(plain.totals().nodes_visited, heat.totals().nodes_visited);
    EXPECT_EQ(plain.totals().triangles_tested, heat.totals().triangles_tested);
    EXPECT_GT(plain.totals().nodes_visited, 0u);
}

TEST(RenderSession, CancelStopsAPassAndKeepsFinishedTiles) {
    auto snap = small_snapshot(64, 64);
    TraceParams tp;
    tp.samples_per_pass = 64;
    tp.threads = 1;
    RenderSession s(snap, tp, FilmParams{});
    std::thread canceller([&] {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        s.cancel();
    });
    const PassStats ps = s.render_pass();
    canceller.join();
    EXPECT_TRUE(ps.cancelled) << ps.seconds;
    if (ps.cancelled) {
        EXPECT_LT(s.film().total_samples(), uint64_t(64 * 64 * 64));
    }
    for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
            const uint32_t n = s.film().count(x, y);
            EXPECT_TRUE(n == 0 || n == 64);  // whole tiles only
        }
    }
    // The next pass runs normally (one sample per pixel to keep the test short).
    tp.samples_per_pass = 1;
    s.set_params(tp, FilmParams{});
    EXPECT_FALSE(s.render_pass().cancelled);
    EXPECT_EQ(s.film().count(63, 63), 1u);
}

// The adaptive settings of the tests below: a pixel stops after 8 samples once its 3x3
// neighbourhood's relative error is under 1 %.
FilmParams adaptive_film(bool adaptive) {
    FilmParams fp;
    fp.adaptive = adaptive;
    fp.adaptive_min_spp = 8;
    fp.adaptive_threshold = 0.01f;
    return fp;
}

TEST(RenderSession, AdaptiveSamplingSpendsSamplesWhereTheNoiseIs) {
    // A constant-environment furnace with one noisy object: background pixels converge at
    // once (zero variance) and stop; the object keeps sampling.
    const TraceScene scene =
        test::make_scene({{test::make_icosphere({0, 0, 0}, 0.5f, 2), flat(diffuse(0.8f))}},
                         std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    auto snap =
        compile_snapshot(scene, make_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 32, 32));
    TraceParams tp;
    tp.light_sampling = LightSampling::bsdf;
    tp.diffuse_sampling = DiffuseSampling::uniform;
    tp.samples_per_pass = 4;
    FilmParams fp = adaptive_film(true);
    RenderSession s(snap, tp, fp);
    StopConditions stop;
    stop.spp = 32;
    const RenderProgress p = run_render(s, stop);
    EXPECT_GE(p.samples, 32u * 32u * 32u);
    EXPECT_EQ(s.film().count(0, 0), 8u);     // background stopped at the minimum
    EXPECT_GT(s.film().count(16, 16), 32u);  // the object got the rest
    EXPECT_NEAR(s.film().mean(16, 16).x, 0.8f, 0.1f);

    // adaptive_max_spp holds exactly, although a late pass gives a pixel several samples;
    // with every open pixel at it the render ends before the budget.
    fp.adaptive_max_spp = 21;
    RenderSession capped(snap, tp, fp);
    const RenderProgress q = run_render(capped, stop);
    EXPECT_LT(q.samples, 32u * 32u * 32u);
    EXPECT_EQ(q.active_pixels, 0u);
    EXPECT_EQ(capped.film().count(0, 0), 8u);
    EXPECT_EQ(capped.film().count(16, 16), 21u);
    for (int y = 0; y < 32; ++y) {
        for (int x = 0; x < 32; ++x) ASSERT_LE(capped.film().count(x, y), 21u) << x << "," << y;
    }
}

// Adaptive sampling chooses how many samples a pixel gets from its samples, but each pixel
// stays a plain mean: the image mean must agree with uniform sampling's within the noise.
TEST(RenderSession, AdaptiveImagesAreUnbiased) {
    auto snap = small_snapshot(40, 24);
    struct Result {
        double mean = 0.0, variance = 0.0;  // image mean luminance; variance of that mean
        uint32_t min_count = ~0u, max_count = 0;
    };
    auto render = [&](bool adaptive, uint64_t seed) {
        TraceParams tp;
        tp.seed = seed;
        RenderSession s(snap, tp, adaptive_film(adaptive));
        StopConditions stop;
        stop.spp = 64;
        run_render(s, stop);
        const Film& f = s.film();
        Result r;
        const double n = double(f.pixel_count());
        for (int y = 0; y < f.height(); ++y) {
            for (int x = 0; x < f.width(); ++x) {
                const Vec3f m = f.mean(x, y);
                const double lum = 0.2126 * m.x + 0.7152 * m.y + 0.0722 * m.z;
                const double se = double(f.relative_error(x, y)) * std::max(lum, 1e-4);
                r.mean += lum / n;
                r.variance += se * se / (n * n);
                r.min_count = std::min(r.min_count, f.count(x, y));
                r.max_count = std::max(r.max_count, f.count(x, y));
            }
        }
        return r;
    };
    const Result uniform = render(false, 1), adaptive = render(true, 2);
    EXPECT_EQ(uniform.min_count, 64u);
    EXPECT_GT(adaptive.max_count, 2 * adaptive.min_count);  // it did reallocate
    const double z =
        (adaptive.mean - uniform.mean) / std::sqrt(uniform.variance + adaptive.variance);
    EXPECT_LT(std::abs(z), 4.0) << uniform.mean << " vs " << adaptive.mean;
}

TEST(RenderSession, RejectsBadParametersWithTheirNames) {
    auto snap = small_snapshot(8, 8);
    auto bad_trace = [&](auto change) {
        TraceParams tp;
        change(tp);
        return test::error_of_call([&] { RenderSession s(snap, tp, FilmParams{}); });
    };
    auto bad_film = [&](auto change) {
        FilmParams fp;
        change(fp);
        return test::error_of_call([&] { RenderSession s(snap, TraceParams{}, fp); });
    };
    auto has = [](const std::string& msg, const char* part) {
        return msg.find(part) != std::string::npos;
    };
    EXPECT_TRUE(has(bad_trace([](TraceParams& t) { t.threads = 100000; }), "threads"));
    EXPECT_TRUE(has(bad_trace([](TraceParams& t) { t.threads = -1; }), "threads"));
    EXPECT_TRUE(has(bad_trace([](TraceParams& t) { t.max_depth = -1; }), "max_depth"));
    EXPECT_TRUE(has(bad_trace([](TraceParams& t) { t.rr_min_depth = -2; }), "rr_min_depth"));
    EXPECT_TRUE(
        has(bad_trace([](TraceParams& t) { t.samples_per_pass = -1; }), "samples_per_pass"));
    EXPECT_TRUE(has(bad_trace([](TraceParams& t) { t.filter = PixelFilter(7); }), "filter"));
    EXPECT_TRUE(has(bad_film([](FilmParams& f) { f.adaptive_threshold = std::nanf(""); }),
                    "adaptive_threshold"));
    EXPECT_TRUE(
        has(bad_film([](FilmParams& f) { f.adaptive_threshold = 0.0f; }), "adaptive_threshold"));
    EXPECT_TRUE(has(bad_film([](FilmParams& f) { f.adaptive_min_spp = -4; }), "adaptive_min_spp"));
    EXPECT_TRUE(has(bad_film([](FilmParams& f) { f.exposure = INFINITY; }), "exposure"));
    EXPECT_EQ(bad_trace([](TraceParams&) {}), "");

    // set_params checks before it changes anything.
    RenderSession s(snap, TraceParams{}, FilmParams{});
    TraceParams tp;
    tp.threads = 5000;
    EXPECT_THROW(s.set_params(tp, FilmParams{}), Error);
    EXPECT_EQ(s.trace_params().threads, 0);

    // Stop conditions: negative or non-finite values are errors, never a silent default or
    // an endless render.
    auto stop_error = [&](auto change) {
        StopConditions stop;
        stop.spp = 1;
        change(stop);
        // validate() alone, as the CLI calls it before loading anything, says the same.
        const std::string checked = test::error_of_call([&] { validate(stop); });
        const std::string rendered = test::error_of_call([&] { run_render(s, stop); });
        EXPECT_EQ(checked, rendered);
        return rendered;
    };
    EXPECT_TRUE(has(stop_error([](StopConditions& c) { c.spp = -1; }), "stop.spp"));
    EXPECT_TRUE(
        has(stop_error([](StopConditions& c) { c.seconds = std::nan(""); }), "stop.seconds"));
    EXPECT_TRUE(has(stop_error([](StopConditions& c) { c.seconds = -1.0; }), "stop.seconds"));
    EXPECT_TRUE(has(stop_error([](StopConditions& c) { c.error = std::nanf(""); }), "stop.error"));
    EXPECT_TRUE(has(stop_error([](StopConditions& c) { c.error = INFINITY; }), "stop.error"));
    EXPECT_EQ(stop_error([](StopConditions&) {}), "");
}

TEST(RenderSession, StopConditions) {
    auto snap = small_snapshot(16, 16);
    TraceParams tp;
    tp.samples_per_pass = 3;
    RenderSession s(snap, tp, FilmParams{});
    StopConditions stop;
    EXPECT_THROW(run_render(s, stop), Error);
    stop.spp = 10;
    int calls = 0;
    const RenderProgress p = run_render(s, stop, [&](const RenderProgress&) { ++calls; });
    EXPECT_EQ(calls, 4);  // 3 + 3 + 3 + 1
    EXPECT_EQ(s.film().count(5, 5), 10u);
    EXPECT_EQ(p.fraction, 1.0);
    // Error target without adaptivity: stops once the mean relative error is reached.
    s.reset();
    stop = StopConditions{};
    stop.error = 0.2f;
    const RenderProgress pe = run_render(s, stop);
    EXPECT_LE(pe.mean_relative_error, 0.2);
    EXPECT_GT(pe.mean_relative_error, 0.0);
}

TEST(RenderSession, CameraChangeEqualsAFreshSessionAndCopiesNoScene) {
    auto snap = small_snapshot(40, 24);
    TraceParams tp;
    tp.samples_per_pass = 2;
    RenderSession s(snap, tp, FilmParams{});
    s.render_pass();
    s.render_pass();
    const Camera other = make_camera({-2, 1.5f, 3}, {0, 0.2f, 0}, {0, 1, 0}, 35.0f, 32, 20);
    s.set_camera(other);
    s.render_pass();
    s.render_pass();
    EXPECT_EQ(s.snapshot().scene.get(), snap->scene.get());  // the scene is shared, not copied
    EXPECT_EQ(s.film().width(), 32);
    RenderSession fresh(compile_snapshot(*snap->scene, other), tp, FilmParams{});
    fresh.render_pass();
    fresh.render_pass();
    EXPECT_TRUE(same_bits(s.film().linear_rgb(), fresh.film().linear_rgb()));

    // The published image is the film, whole tiles, after the passes.
    FilmImage img;
    ASSERT_TRUE(s.copy_image(img));
    EXPECT_EQ(img.width, 32);
    EXPECT_EQ(img.complete_passes, 2);
    EXPECT_TRUE(same_bits(img.rgb, s.film().linear_rgb()));
    EXPECT_FALSE(s.copy_image(img));  // nothing new
    const std::optional<PixelInfo> px = s.inspect(5, 7);
    ASSERT_TRUE(px);
    EXPECT_EQ(px->samples, 4u);
    EXPECT_EQ(px->rgb.x, s.film().mean(5, 7).x);
    EXPECT_EQ(px->relative_error, s.film().relative_error(5, 7));
    EXPECT_FALSE(s.inspect(32, 0));
}

TEST(RenderSession, CancelFromAnotherThreadStopsWithinOneTilePerThread) {
    auto snap = small_snapshot(256, 128);  // 128 tiles
    TraceParams tp;
    tp.threads = 2;
    tp.samples_per_pass = 64;
    RenderSession s(snap, tp, FilmParams{});
    const uint64_t start = [&] {
        FilmImage img;
        s.copy_image(img);
        return img.version;
    }();
    // Every finished tile bumps the published version by one.
    std::atomic<uint64_t> tiles_at_cancel{0};
    std::thread canceller([&] {
        FilmImage img;
        img.version = start;
        while (img.version < start + 4) {
            s.copy_image(img);
            std::this_thread::yield();
        }
        s.cancel();
        img.version = 0;
        s.copy_image(img);
        tiles_at_cancel = img.version - start;
    });
    const PassStats ps = s.render_pass();
    canceller.join();
    EXPECT_TRUE(ps.cancelled);
    size_t tiles_done = 0;
    for (int ty = 0; ty < 128; ty += RenderSession::kTileSize) {
        for (int tx = 0; tx < 256; tx += RenderSession::kTileSize) {
            tiles_done += s.film().count(tx, ty) > 0;
        }
    }
    EXPECT_GE(tiles_done, 4u);
    EXPECT_LE(tiles_done, tiles_at_cancel.load() + 2);  // in flight when cancelled: one per thread
    EXPECT_LT(tiles_done, size_t(s.tile_count()));
    // The next pass runs whole again.
    EXPECT_FALSE(s.render_pass().cancelled);
}

TEST(RenderSession, SettersFromAnotherThreadWhilePassesRun) {
    auto snap = small_snapshot(48, 32);
    auto other = small_snapshot(24, 16, 0.2f);
    TraceParams tp;
    tp.threads = 2;
    tp.count_traversal = true;
    RenderSession s(snap, tp, FilmParams{});
    std::atomic<bool> done{false};
    std::thread hammer([&] {
        FilmImage img;
        for (int i = 0; i < 100; ++i) {
            const float a = float(i) * 0.1f;
            s.set_camera(make_camera({3 * std::cos(a), 2, 3 * std::sin(a)}, {0, 0, 0}, {0, 1, 0},
                                     40.0f, 16 + i % 3 * 16, 16));
            TraceParams t = tp;
            t.samples_per_pass = 1 + i % 3;
            FilmParams f;
            f.adaptive = i % 2 == 0;
            s.set_params(t, f);
            s.set_heat_map(i % 4 == 0);
            if (i % 10 == 0) s.set_snapshot(i % 20 == 0 ? other : snap);
            if (i % 3 == 0) s.cancel();
            if (i % 7 == 0) s.reset();
            s.copy_image(img);
            (void)s.inspect(i % 16, i % 16);
        }
        s.set_camera(make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 48, 16));
        done = true;
    });
    int passes = 0;
    while (!done || passes < 3) {
        s.render_pass();
        ++passes;
    }
    hammer.join();
    // Settled: the last camera (48x16) is in force and the film agrees with what is published.
    s.render_pass();
    EXPECT_EQ(s.film().width(), 48);
    FilmImage img;
    ASSERT_TRUE(s.copy_image(img));
    EXPECT_EQ(img.width, 48);
    EXPECT_TRUE(same_bits(img.rgb, s.film().linear_rgb()));
}

TEST(RenderSnapshot, CompilesAScene) {
    Scene scene;
    scene.name = "test";
    MeshInstance a;
    a.mesh = std::make_shared<TriangleMesh>(test::make_box({0, 0, 0}, {1, 1, 1}));
    a.world_from_object[3] = Vec4f(2, 0, 0, 1);  // translation by +2 in x
    a.smooth = false;
    MeshInstance b;
    b.mesh = std::make_shared<TriangleMesh>(test::make_icosphere({0, 0, 0}, 1.0f, 1));
    b.material.type = MaterialType::mirror;
    scene.meshes = {a, b};
    scene.camera.eye = {0, 0, 6};
    SnapshotOptions opt;
    opt.width = 20;
    opt.height = 10;
    opt.env = std::make_shared<ConstantEnv>(Vec3f(0.5f));
    auto snap = compile_snapshot(scene, opt);
    const TraceScene& ts = *snap->scene;
    EXPECT_EQ(ts.mesh->triangle_count(), 12u + 80u);
    EXPECT_EQ(ts.normals.size(), ts.mesh->vertex_count());
    // Triangles are in spatial order (spatial_order), each still with its instance: the
    // box's 12 in world space [2, 3] x [0, 1]^2, the sphere's 80 on the unit sphere.
    ASSERT_EQ(ts.triangle_instance.size(), ts.mesh->triangle_count());
    size_t box = 0;
    for (size_t i = 0; i < ts.mesh->triangle_count(); ++i) {
        const Vec3u t = ts.mesh->triangles[i];
        for (int k = 0; k < 3; ++k) {
            const Vec3f p = ts.mesh->positions[t[k]];
            if (ts.triangle_instance[i] == 0) {
                EXPECT_TRUE(p.x >= 2.0f && p.x <= 3.0f && p.y >= 0.0f && p.y <= 1.0f &&
                            p.z >= 0.0f && p.z <= 1.0f)
                    << "box triangle " << i;
            } else {
                EXPECT_EQ(ts.triangle_instance[i], 1u);
                EXPECT_NEAR(glm::length(p), 1.0f, 1e-5f) << "sphere triangle " << i;
            }
        }
        box += ts.triangle_instance[i] == 0;
    }
    EXPECT_EQ(box, 12u);
    EXPECT_FALSE(ts.instances[0].smooth);
    EXPECT_EQ(ts.instances[1].material.type, MaterialType::mirror);
    EXPECT_EQ(snap->camera.width, 20);
    ASSERT_TRUE(ts.tree);

    scene.meshes[1].mesh.reset();
    EXPECT_THROW(compile_snapshot(scene, opt), Error);
    scene.meshes[1].mesh = b.mesh;
    scene.meshes[1].material.albedo = Vec3f(std::nanf(""));
    EXPECT_THROW(compile_snapshot(scene, opt), Error);
}

// A bad camera (image size, field of view) is reported before any tree is built: a build of
// minutes on a big model would otherwise come before the error. The tree cache directory
// shows whether a tree was built.
TEST(RenderSnapshot, BadCameraFailsBeforeTheTreeIsBuilt) {
    const std::filesystem::path dir = test::temp_dir("bad_camera_cache");
    RenderOptions o;
    o.scene.cache_dir = dir.string();
    o.scene.width = o.scene.height = 8;
    auto trees = [&] {
        return std::distance(std::filesystem::directory_iterator(dir),
                             std::filesystem::directory_iterator());
    };
    CameraDesc wide;
    wide.vfov_degrees = 180.0f;
    o.scene.camera = wide;
    EXPECT_NE(test::error_of_call([&] { prepare_render(o, [](const std::string&) {}); }), "");
    o.scene.width = 100000;
    o.scene.camera.reset();
    EXPECT_NE(test::error_of_call([&] {
                  prepare_render(o, [](const std::string&) {});
              }).find("scene.width"),
              std::string::npos);
    EXPECT_EQ(trees(), 0);
    o.scene.width = 8;
    EXPECT_TRUE(prepare_render(o, [](const std::string&) {}).snapshot);
    EXPECT_EQ(trees(), 1);
}

// The summary lines' word for where the tree came from (render's last line, the viewer's
// status): built, the cache, or a tree file given by --tree.
TEST(PrepareRender, TreeSourceNamesATreeFileGiven) {
    Prepared p;
    SceneOptions o;
    EXPECT_EQ(tree_source_text(p, o), "");
    p.tree_from_cache = true;
    EXPECT_EQ(tree_source_text(p, o), " (cached)");
    o.tree_file = "/t/dragon.kdt";
    EXPECT_EQ(tree_source_text(p, o), " (from /t/dragon.kdt)");
    o.tree_file = "/t/\x1b.kdt";
    EXPECT_EQ(tree_source_text(p, o).find('\x1b'), std::string::npos);
}

// A mirrored glass sphere is the same sphere: the sphere is symmetric under each axis flip,
// so scale (-1, 1, 1) and (-1, -1, -1) must render it as without the transform, flat and
// smooth. Without reversing the winding, the dielectric saw the inside as the outside
// (an air bubble in glass: a mean several times higher).
TEST(RenderSnapshot, MirroredDielectricRendersAsUnmirrored) {
    for (bool smooth : {false, true}) {
        auto render_mean = [&](Vec3f scale) {
            Scene scene;
            MeshInstance glass;
            glass.mesh = std::make_shared<TriangleMesh>(test::make_icosphere({0, 0, 0}, 1.0f, 3));
            glass.world_from_object = glm::scale(Mat4f(1.0f), scale);
            glass.material.type = MaterialType::dielectric;
            glass.smooth = smooth;
            scene.meshes = {glass};
            scene.camera.eye = {0, 0, 4};
            SnapshotOptions opt;
            opt.width = 24;
            opt.height = 16;
            opt.env = std::make_shared<test::GradientEnv>();
            TraceParams tp;
            tp.samples_per_pass = 16;
            RenderSession s(compile_snapshot(scene, opt), tp, FilmParams{});
            s.render_pass();
            double sum = 0.0;
            for (float v : s.film().linear_rgb()) sum += v;
            return sum / double(s.film().linear_rgb().size());
        };
        const double plain = render_mean(Vec3f(1, 1, 1));
        EXPECT_NEAR(render_mean(Vec3f(-1, 1, 1)), plain, 1e-4 * plain) << "smooth " << smooth;
        EXPECT_NEAR(render_mean(Vec3f(-1, -1, -1)), plain, 1e-4 * plain) << "smooth " << smooth;
    }
}

}  // namespace
}  // namespace kdt
