// The normals and depth views (AOVs) of a render session: analytic values on a sphere and a
// plane, sky pixels, and a radiance image that does not change when they are on.
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "renderer/render/session.h"
#include "renderer/render/tile_renderer.h"
#include "tests/renderer/integrator/test_scenes.h"

namespace kdt {
namespace {

constexpr int kW = 33, kH = 33;  // odd: a centre pixel

// A smooth unit sphere at the origin (level-4 icosphere) seen from z = 5 with a 30 degree
// field: the centre pixel sees the sphere's pole facing the camera, the corners the sky.
std::shared_ptr<const RenderSnapshot> sphere_snapshot() {
    const TraceScene scene = test::make_scene(
        {{test::make_icosphere({0, 0, 0}, 1.0f, 4), test::smooth(test::diffuse(0.5f))}},
        std::make_shared<test::GradientEnv>());
    return compile_snapshot(scene, make_camera({0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 30.0f, kW, kH));
}

// A flat quad in the plane y = -1 (normal +y) seen from above at height 3, looking down.
std::shared_ptr<const RenderSnapshot> plane_snapshot() {
    const TraceScene scene =
        test::make_scene({{test::make_quad({-50, -1, 50}, {100, 0, 0}, {0, 0, -100}),
                           test::flat(test::diffuse(0.5f))}},
                         std::make_shared<test::GradientEnv>());
    return compile_snapshot(scene, make_camera({0, 2, 0}, {0, -1, 0}, {0, 0, 1}, 30.0f, kW, kH));
}

FilmImage render_with_aov(std::shared_ptr<const RenderSnapshot> snap, bool heat, int passes) {
    TraceParams tp;
    tp.threads = 2;
    tp.samples_per_pass = 2;
    RenderSession s(snap, tp, FilmParams{});
    s.set_aov(true);
    s.set_heat_map(heat);
    for (int i = 0; i < passes; ++i) s.render_pass();
    FilmImage img;
    s.copy_image(img, true);
    return img;
}

TEST(Aov, SphereCentreHasTheAnalyticNormalAndDepthAndCornersAreSky) {
    for (bool heat : {false, true}) {
        const FilmImage img = render_with_aov(sphere_snapshot(), heat, 2);
        ASSERT_EQ(img.aov_normals.size(), size_t(3 * kW * kH));
        ASSERT_EQ(img.aov_depth.size(), size_t(kW * kH));
        const size_t c = size_t(kH / 2) * kW + kW / 2;
        // The pole of the unit sphere is at distance 4 from the eye; the centre pixel's rays
        // deviate by at most half a pixel (0.5 degrees), and the level-4 icosphere's flat
        // facets lie within 0.2 % of the radius.
        EXPECT_NEAR(img.aov_depth[c], 4.0f, 0.01f) << "heat " << heat;
        EXPECT_NEAR(img.aov_normals[3 * c + 0], 0.0f, 0.02f);
        EXPECT_NEAR(img.aov_normals[3 * c + 1], 0.0f, 0.02f);
        EXPECT_NEAR(img.aov_normals[3 * c + 2], 1.0f, 0.001f);
        // A pixel left of the centre sees the sphere's left side: its normal points left
        // and its depth is larger than the pole's.
        const size_t l = size_t(kH / 2) * kW + kW / 2 - 8;
        EXPECT_LT(img.aov_normals[3 * l], -0.3f);
        EXPECT_GT(img.aov_depth[l], 4.0f);
        for (size_t corner : {size_t(0), size_t(kW - 1), size_t(kW * kH - 1)}) {
            EXPECT_TRUE(std::isinf(img.aov_depth[corner])) << corner;  // sky
            EXPECT_EQ(img.aov_normals[3 * corner], 0.0f);
        }
    }
}

TEST(Aov, PlaneDepthIsTheDistanceAlongTheCameraRay) {
    const std::shared_ptr<const RenderSnapshot> snap = plane_snapshot();
    const FilmImage img = render_with_aov(snap, false, 1);
    // Every sample of a pixel hits the plane 3 units below the eye at a distance of
    // 3 / |dir.y|; the pixel's mean lies between the extremes over its area.
    const Camera& cam = snap->camera;
    for (int y : {0, kH / 2, kH - 1}) {
        for (int x : {0, kW / 2, kW - 1}) {
            const size_t i = size_t(y) * kW + size_t(x);
            float lo = INFINITY, hi = 0.0f;
            for (float dy : {0.0f, 1.0f}) {
                for (float dx : {0.0f, 1.0f}) {
                    const Ray r = cam.generate_ray(Vec2f(float(x) + dx, float(y) + dy));
                    const float d = 3.0f / std::abs(r.dir.y);
                    lo = std::min(lo, d);
                    hi = std::max(hi, d);
                }
            }
            EXPECT_GE(img.aov_depth[i], lo * 0.9999f) << x << " " << y;
            EXPECT_LE(img.aov_depth[i], hi * 1.0001f) << x << " " << y;
            EXPECT_NEAR(img.aov_normals[3 * i + 1], 1.0f, 1e-6f);
        }
    }
}

TEST(Aov, RadianceIsBitwiseTheSameWithTheAovOn) {
    for (bool heat : {false, true}) {
        TraceParams tp;
        tp.threads = 2;
        tp.samples_per_pass = 2;
        FilmParams fp;
        fp.transparent = heat;  // the transparent path shares the camera ray's hit
        RenderSession plain(sphere_snapshot(), tp, fp), with(sphere_snapshot(), tp, fp);
        plain.set_heat_map(heat);
        with.set_heat_map(heat);
        with.set_aov(true);
        for (int i = 0; i < 3; ++i) {
            plain.render_pass();
            with.render_pass();
        }
        const std::vector<float> a = plain.film().linear_rgb(), b = with.film().linear_rgb();
        ASSERT_EQ(a.size(), b.size());
        EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << heat;
        EXPECT_TRUE(with.aov());
        EXPECT_FALSE(plain.aov());
        const std::optional<PixelInfo> p = with.inspect(kW / 2, kH / 2);
        ASSERT_TRUE(p);
        EXPECT_NEAR(p->depth, 4.0f, 0.01f);
    }
}

TEST(Aov, OffByDefaultAndNotCopiedWithoutLayers) {
    RenderSession s(sphere_snapshot(), TraceParams{}, FilmParams{});
    s.render_pass();
    FilmImage img;
    s.copy_image(img, true);
    EXPECT_TRUE(img.aov_depth.empty());
    s.set_aov(true);
    s.render_pass();
    FilmImage plain;
    s.copy_image(plain, false);
    EXPECT_TRUE(plain.aov_depth.empty());
    s.copy_image(img, true);
    EXPECT_EQ(img.aov_depth.size(), size_t(kW * kH));
}

}  // namespace
}  // namespace kdt
