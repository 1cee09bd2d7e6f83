// Next-event estimation of a map under MIS follows the map minus its mean (MIS compensation,
// ImageEnvironment::sample_mis): a diffuse plane under a map keeps its analytic radiance with
// every light-sampling strategy, and a uniform map is left to BSDF sampling alone.
#include <cmath>

#include <gtest/gtest.h>

#include "renderer/integrator/path_tracer.h"
#include "renderer/light/image_environment.h"
#include "renderer/light/mapping.h"
#include "tests/renderer/integrator/test_scenes.h"

namespace kdt {
namespace {

using test::diffuse;
using test::flat;
using test::make_quad;
using test::make_scene;

constexpr float kAlbedo = 0.6f;

TraceScene plane_under(std::shared_ptr<const EnvironmentLight> env) {
    return make_scene(
        {{make_quad({-50, 0, -50}, {0, 0, 100}, {100, 0, 0}), flat(diffuse(kAlbedo))}},
        std::move(env));
}

Camera camera_above() { return make_camera({0, 2, 0}, {0.3f, 0, 0.2f}, {0, 0, 1}, 60.0f, 8, 8); }

TEST(MisCompensation, UniformMapIsLeftToBsdfSampling) {
    ImageRGB img(16, 8);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) img.set(x, y, Vec3f(0.5f));
    const TraceScene scene =
        plane_under(std::make_shared<ImageEnvironment>(img, EnvMapping::latlong, 0.0f, 1.0f));
    const Camera cam = camera_above();
    TraceParams tp;  // mis
    tp.max_depth = 1;
    PathCounters counters;
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
            for (uint32_t s = 0; s < 4; ++s) {
                const Vec3f v = render_sample(scene, cam, tp, x, y, s, counters);
                for (int c = 0; c < 3; ++c) ASSERT_NEAR(v[c], kAlbedo * 0.5f, 1e-6f);
            }
        }
    }
    EXPECT_EQ(counters.shadow_rays, 0u);
}

TEST(MisCompensation, PlaneUnderAMapKeepsItsRadianceWithEveryStrategy) {
    // A sky (1) with a brighter patch (8) above the plane: bright enough to be sampled, dim
    // enough that the full map's density in the sky matters (a MIS weight computed with it
    // instead of the compensated one's would lose a visible part of the sky).
    ImageRGB img(32, 16);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) img.set(x, y, Vec3f(1.0f));
    for (int y = 3; y < 7; ++y)
        for (int x = 8; x < 16; ++x) img.set(x, y, Vec3f(8.0f));
    const auto env = std::make_shared<ImageEnvironment>(img, EnvMapping::latlong, 0.0f, 1.0f);
    ASSERT_FALSE(env->mis_distribution().empty());
    // Reference: albedo / pi times the integral of L cos over the upper hemisphere (midpoint
    // rule over the image, 16 x 16 points per pixel).
    const int nu = img.width * 16, nv = img.height * 16;
    double irradiance = 0.0;
    for (int y = 0; y < nv; ++y) {
        for (int x = 0; x < nu; ++x) {
            const Vec3f d = *env->dir_from_uv({(x + 0.5f) / float(nu), (y + 0.5f) / float(nv)});
            if (d.y <= 0.0f) continue;
            irradiance += double(env->eval(d).x) * d.y * env_jacobian(EnvMapping::latlong, d) /
                          (double(nu) * nv);
        }
    }
    const double expected = kAlbedo / M_PI * irradiance;
    const TraceScene scene = plane_under(env);
    const Camera cam = camera_above();
    for (LightSampling ls : {LightSampling::bsdf, LightSampling::nee, LightSampling::mis}) {
        TraceParams tp;
        tp.light_sampling = ls;
        tp.max_depth = 1;
        PathCounters counters;
        double sum = 0.0, sum2 = 0.0;
        const int spp = ls == LightSampling::bsdf ? 512 : 64;
        for (int y = 0; y < 8; ++y) {
            for (int x = 0; x < 8; ++x) {
                for (uint32_t s = 0; s < uint32_t(spp); ++s) {
                    const double v = render_sample(scene, cam, tp, x, y, s, counters).x;
                    sum += v;
                    sum2 += v * v;
                }
            }
        }
        const double n = 64.0 * spp, mean = sum / n;
        const double se = std::sqrt(std::max(sum2 / n - mean * mean, 0.0) / n);
        EXPECT_NEAR(mean, expected, 4.0 * se + 1e-4 * expected)
            << kLightSamplingNames[size_t(ls)] << " (standard error " << se << ")";
        if (ls == LightSampling::mis) {
            EXPECT_GT(counters.shadow_rays, 0u);
        }
    }
}

}  // namespace
}  // namespace kdt
