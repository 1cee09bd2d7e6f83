// Analytic renders: white furnace, convex objects and enclosures with closed-form radiance,
// a diffuse plane under a constant sky, mirrors, depth counting, hard scenes.
#include "renderer/integrator/path_tracer.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <tuple>

#include <gtest/gtest.h>

#include "renderer/render/session.h"
#include "tests/renderer/integrator/test_scenes.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::ConstantEnv;
using test::diffuse;
using test::flat;
using test::make_box;
using test::make_icosphere;
using test::make_quad;
using test::make_scene;

struct Image {
    int width = 0, height = 0;
    std::vector<float> rgb;
    PathCounters counters;
    Vec3f at(int x, int y) const {
        const size_t i = (size_t(y) * size_t(width) + size_t(x)) * 3;
        return {rgb[i], rgb[i + 1], rgb[i + 2]};
    }
};

Image render(const TraceScene& scene, const Camera& camera, TraceParams tp, int spp) {
    tp.samples_per_pass = spp;
    RenderSession session(compile_snapshot(scene, camera), tp, FilmParams{});
    Image img;
    img.counters = session.render_pass().counters;
    img.width = camera.width;
    img.height = camera.height;
    img.rgb = session.film().linear_rgb();
    return img;
}

// Mean and standard error of channel c over the pixels where mask() holds.
template <class Mask>
std::pair<double, double> mean_stderr(const Image& img, int c, Mask mask) {
    double s = 0.0, s2 = 0.0;
    int n = 0;
    for (int y = 0; y < img.height; ++y) {
        for (int x = 0; x < img.width; ++x) {
            if (!mask(x, y)) continue;
            const double v = img.at(x, y)[c];
            s += v;
            s2 += v * v;
            ++n;
        }
    }
    const double m = s / n;
    const double var = std::max(0.0, (s2 - s * m) / (n - 1));
    return {m, std::sqrt(var / n)};
}

auto all_pixels = [](int, int) { return true; };

std::string describe(const TraceParams& tp) {
    return std::string(kLightSamplingNames[size_t(tp.light_sampling)]) +
           (tp.env_importance ? " env-is" : " env-uniform") +
           (tp.russian_roulette ? " rr" : " no-rr") + " " +
           kDiffuseSamplingNames[size_t(tp.diffuse_sampling)];
}

std::vector<TraceParams> all_strategies() {
    std::vector<TraceParams> out;
    for (LightSampling ls : {LightSampling::bsdf, LightSampling::nee, LightSampling::mis}) {
        for (bool rr : {false, true}) {
            for (DiffuseSampling ds : {DiffuseSampling::cosine, DiffuseSampling::uniform}) {
                TraceParams tp;
                tp.light_sampling = ls;
                tp.russian_roulette = rr;
                tp.diffuse_sampling = ds;
                tp.env_importance = ds == DiffuseSampling::cosine;
                tp.max_depth = 64;
                tp.seed = 11;
                out.push_back(tp);
            }
        }
    }
    return out;
}

// A convex object of albedo rho seen from outside under a constant environment L: every
// scattered ray escapes, so the surface radiance is rho * L exactly (rho = 1: the white
// furnace, the object vanishes).
TEST(PathTracer, ConvexObjectInConstantEnvironmentReturnsAlbedoTimesRadiance) {
    const Camera cam = make_camera({0, 0, 4}, {0, 0, 0}, {0, 1, 0}, 30.0f, 16, 16);
    for (float rho : {1.0f, 0.5f}) {
        const TraceScene scene =
            make_scene({{make_icosphere({0, 0, 0}, 1.0f, 2), flat(diffuse(rho))}},
                       std::make_shared<ConstantEnv>(Vec3f(1.0f)));
        for (const TraceParams& tp : all_strategies()) {
            const Image img = render(scene, cam, tp, 32);
            // The sphere covers the central pixels (its silhouette is about 0.5 rad wide).
            auto centre = [](int x, int y) { return std::abs(x - 8) < 4 && std::abs(y - 8) < 4; };
            auto [m, se] = mean_stderr(img, 1, centre);
            EXPECT_NEAR(m, rho, 4.0 * se + 1e-4) << describe(tp) << " rho " << rho;
            EXPECT_EQ(img.at(0, 0), Vec3f(1.0f));  // background: the environment
            for (int y = 0; y < 16; ++y) {
                for (int x = 0; x < 16; ++x) ASSERT_TRUE(is_finite(img.at(x, y)));
            }
        }
    }
}

// White furnace with interreflection: two albedo-1 objects that see each other (a sphere
// resting on a box) still render 1 everywhere; with RR off up to the depth cut-off.
TEST(PathTracer, WhiteFurnaceWithInterreflections) {
    const TraceScene scene =
        make_scene({{make_icosphere({0, 0.5f, 0}, 0.5f, 2), flat(diffuse(1.0f))},
                    {make_box({-1, -1, -1}, {1, 0, 1}), flat(diffuse(1.0f))}},
                   std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    const Camera cam = make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 24, 24);
    for (LightSampling ls : {LightSampling::bsdf, LightSampling::mis}) {
        for (bool rr : {false, true}) {
            TraceParams tp;
            tp.light_sampling = ls;
            tp.russian_roulette = rr;
            tp.max_depth = 256;
            const Image img = render(scene, cam, tp, 32);
            auto [m, se] = mean_stderr(img, 0, all_pixels);
            EXPECT_NEAR(m, 1.0, 4.0 * se + 1e-3) << describe(tp);
            EXPECT_LT(se, 0.02);
        }
    }
}

// Inside a closed box whose walls emit E and reflect diffusely with albedo rho, a path that
// scatters k times before reaching an emitting wall carries rho^k E, so with depth limit D
// (at most D scattering events) the radiance is E (1 - rho^(D+1)) / (1 - rho) exactly, for
// any enclosure; the outside environment (bright)
// must not leak in through shadow rays.
TEST(PathTracer, EmissiveEnclosureGivesTheGeometricSeries) {
    const float rho = 0.5f;
    const TraceScene scene =
        make_scene({{make_box({-1, -1, -1}, {1, 1, 1}), flat(diffuse(rho, Vec3f(1.0f)))}},
                   std::make_shared<ConstantEnv>(Vec3f(10.0f)));
    const Camera cam = make_camera({0.1f, 0.2f, 0.3f}, {0.5f, -0.3f, -1}, {0, 1, 0}, 90.0f, 16, 16);
    for (int depth : {0, 1, 2, 3, 5}) {
        TraceParams tp;
        tp.max_depth = depth;
        tp.russian_roulette = false;
        tp.sample_emitters = false;  // BSDF rays alone: every sample is the series exactly
        // nee: the constant sky is sampled (mis leaves it to BSDF rays), so that shadow rays
        // toward the bright outside are cast and must all be blocked.
        tp.light_sampling = LightSampling::nee;
        const Image img = render(scene, cam, tp, 16);
        const double expected = (1.0 - std::pow(rho, depth + 1)) / (1.0 - rho);
        auto [m, se] = mean_stderr(img, 2, all_pixels);
        EXPECT_NEAR(m, expected, 1e-5) << "depth " << depth;  // exact: every sample is the same
        EXPECT_LT(se, 1e-5);
        if (depth == 0) {
            EXPECT_EQ(img.counters.shadow_rays, 0u);
        } else {
            EXPECT_GT(img.counters.shadow_rays, 0u);
        }
    }
    // Emitter sampling (walls are lights) under MIS and alone: the same series in mean.
    for (LightSampling ls : {LightSampling::mis, LightSampling::nee}) {
        TraceParams tp;
        tp.max_depth = 3;
        tp.russian_roulette = false;
        tp.light_sampling = ls;
        const Image img = render(scene, cam, tp, 64);
        auto [m, se] = mean_stderr(img, 1, all_pixels);
        EXPECT_NEAR(m, (1.0 - std::pow(rho, 4)) / (1.0 - rho), 4.0 * se + 1e-4)
            << kLightSamplingNames[size_t(ls)];
        EXPECT_GT(se, 0.0);  // a different estimator than the exact one above
    }
    // Russian roulette is unbiased: with a deep limit the series sums to 1 / (1 - rho).
    TraceParams tp;
    tp.max_depth = 200;
    tp.russian_roulette = true;
    tp.rr_min_depth = 1;
    const Image img = render(scene, cam, tp, 64);
    auto [m, se] = mean_stderr(img, 0, all_pixels);
    EXPECT_NEAR(m, 1.0 / (1.0 - rho), 4.0 * se + 1e-3);
    EXPECT_GT(se, 0.0);  // roulette adds noise: the check above is not vacuous
}

// Area lights: next-event estimation of emissive triangles (alone, and under MIS with BSDF
// sampling) agrees in mean with BSDF sampling alone, which needs no emitter table, and
// has far less noise. Two lamps of different size and power test the pick by power; the
// environment is black, so all light comes from the lamps.
TEST(PathTracer, EmitterSamplingAgreesWithBsdfSampling) {
    MaterialDesc lamp_a, lamp_b;
    lamp_a.type = lamp_b.type = MaterialType::emissive;
    lamp_a.emission = Vec3f(40.0f, 20.0f, 10.0f);
    lamp_b.emission = Vec3f(2.0f, 4.0f, 8.0f);
    const TraceScene scene =
        make_scene({{make_quad({-3, 0, -3}, {0, 0, 6}, {6, 0, 0}), flat(diffuse(0.5f))},
                    {make_box({0.5f, 0.2f, 0.5f}, {0.9f, 0.3f, 0.9f}), flat(diffuse(0.8f))},
                    {make_quad({-0.2f, 1.0f, -0.2f}, {0.3f, 0, 0}, {0, 0, 0.3f}),
                     flat(compile_material(lamp_a))},
                    {make_quad({0.6f, 1.5f, -1.0f}, {1.0f, 0, 0}, {0, 0.2f, 1.0f}),
                     flat(compile_material(lamp_b))}},
                   std::make_shared<ConstantEnv>(Vec3f(0.0f)));
    ASSERT_EQ(build_emitter_table(scene).triangles.size(), 4u);
    const Camera cam = make_camera({0, 3, 3}, {0, 0, 0}, {0, 1, 0}, 50.0f, 24, 16);
    // Per mode: the image mean, and the noise of one pixel estimated from two renders with
    // different seeds (the image itself varies, so the spread over pixels is not noise).
    double mean[3][3], noise[3][3];
    const LightSampling modes[3] = {LightSampling::bsdf, LightSampling::nee, LightSampling::mis};
    const int spp[3] = {1024, 64, 64};
    for (int k = 0; k < 3; ++k) {
        TraceParams tp;
        tp.light_sampling = modes[k];
        tp.max_depth = 2;
        tp.russian_roulette = false;
        const Image a = render(scene, cam, tp, spp[k]);
        tp.seed = 99;
        const Image b = render(scene, cam, tp, spp[k]);
        if (k > 0) {
            EXPECT_GT(a.counters.shadow_rays, 0u);
        }
        for (int c = 0; c < 3; ++c) {
            double sum = 0.0, d2 = 0.0;
            for (size_t i = size_t(c); i < a.rgb.size(); i += 3) {
                sum += 0.5 * (a.rgb[i] + b.rgb[i]);
                d2 += double(a.rgb[i] - b.rgb[i]) * double(a.rgb[i] - b.rgb[i]);
            }
            const double n = double(a.rgb.size() / 3);
            mean[k][c] = sum / n;
            noise[k][c] = std::sqrt(d2 / n / 2.0);  // of one render's pixel
        }
    }
    const double pixels = double(cam.width * cam.height);
    for (int k = 1; k < 3; ++k) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_GT(mean[0][c], 0.01);
            // Standard error of the two-render mean of each mode's image mean.
            const double se0 = noise[0][c] / std::sqrt(2.0 * pixels);
            const double sek = noise[k][c] / std::sqrt(2.0 * pixels);
            EXPECT_NEAR(mean[k][c], mean[0][c], 4.0 * std::hypot(se0, sek))
                << "mode " << k << " channel " << c;
            // Variance per sample: light sampling must cut it well below BSDF sampling's
            // (measured: about 7x lower here; antialiased lamp edges add noise to both).
            const double var0 = noise[0][c] * noise[0][c] * spp[0];
            const double vark = noise[k][c] * noise[k][c] * spp[k];
            EXPECT_LT(vark, var0 / 3.0) << "mode " << k << " channel " << c;
        }
    }
}

// A diffuse plane of albedo rho under a constant sky L returns rho * L, seen from either
// side (materials are two-sided).
TEST(PathTracer, DiffusePlaneUnderConstantSky) {
    const Vec3f sky(0.2f, 0.4f, 0.8f);
    const float rho = 0.6f;
    const TraceScene scene =
        make_scene({{make_quad({-50, 0, -50}, {0, 0, 100}, {100, 0, 0}), flat(diffuse(rho))}},
                   std::make_shared<ConstantEnv>(sky));
    for (float side : {1.0f, -1.0f}) {
        const Camera cam = make_camera({0, 2 * side, 0}, {0.3f, 0, 0.2f}, {0, 0, 1}, 60.0f, 16, 16);
        const Image img = render(scene, cam, TraceParams{}, 32);
        for (int c = 0; c < 3; ++c) {
            auto [m, se] = mean_stderr(img, c, all_pixels);
            EXPECT_NEAR(m, rho * sky[c], 4.0 * se + 1e-5) << "side " << side << " channel " << c;
        }
    }
}

// Under the default mis a constant sky is sampled by the BSDF alone: a plane under it, which
// every scattered ray leaves, returns rho * L in every sample (zero variance, no shadow ray);
// with an environment sample under MIS each sample's value varied with the weights.
TEST(PathTracer, ConstantSkyIsSampledByTheBsdfAlone) {
    const Vec3f sky(0.2f, 0.4f, 0.8f);
    const float rho = 0.6f;
    const TraceScene scene =
        make_scene({{make_quad({-50, 0, -50}, {0, 0, 100}, {100, 0, 0}), flat(diffuse(rho))}},
                   std::make_shared<ConstantEnv>(sky));
    const Camera cam = make_camera({0, 2, 0}, {0.3f, 0, 0.2f}, {0, 0, 1}, 60.0f, 8, 8);
    TraceParams tp;
    tp.max_depth = 4;
    tp.russian_roulette = false;
    PathCounters counters;
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
            for (uint32_t s = 0; s < 8; ++s) {
                const Vec3f v = render_sample(scene, cam, tp, x, y, s, counters);
                for (int c = 0; c < 3; ++c) ASSERT_NEAR(v[c], rho * sky[c], 1e-6f);
            }
        }
    }
    EXPECT_EQ(counters.shadow_rays, 0u);
    EXPECT_EQ(counters.bounce_rays, 8u * 8u * 8u);
    // A sky that is not constant is still sampled under MIS.
    const TraceScene grad =
        make_scene({{make_quad({-50, 0, -50}, {0, 0, 100}, {100, 0, 0}), flat(diffuse(rho))}},
                   std::make_shared<test::GradientEnv>());
    PathCounters gc;
    for (uint32_t s = 0; s < 8; ++s) render_sample(grad, cam, tp, 4, 4, s, gc);
    EXPECT_GT(gc.shadow_rays, 0u);
}

// Under a constant sky (BSDF sampling alone) and no roulette, bounce k of a path takes its
// direction from draw k of the sample (draw 0 is the film position): every bounce of a
// depth-4 path falls on a Sobol draw (PixelSampler::kSobolPairs), none is spent on an unused
// light or roulette number. Inside a closed box every path scatters 4 times; bounce k's
// cosine to its wall's normal must be that of the cosine-hemisphere sample of draw k.
TEST(PathTracer, BounceDirectionsUseTheSobolDrawsInOrder) {
    const TraceScene scene = make_scene({{make_box({-1, -1, -1}, {1, 1, 1}), flat(diffuse(0.5f))}},
                                        std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    const Camera cam = make_camera({0.1f, 0.2f, 0.3f}, {1, 0.5f, -1}, {0, 1, 0}, 60.0f, 4, 4);
    TraceParams tp;
    tp.max_depth = 4;
    tp.russian_roulette = false;
    ASSERT_EQ(tp.light_sampling, LightSampling::mis);
    static_assert(PixelSampler::kSobolPairs >= 5);
    for (uint32_t s = 0; s < 64; ++s) {
        RayRecord rec;
        record_rays(scene, cam, tp, 2, 1, s, rec);
        ASSERT_EQ(rec.closest.size(), 5u);  // camera ray + 4 bounces
        EXPECT_TRUE(rec.any.empty());
        PixelSampler draws(tp.seed, 2, 1, s);
        draws.next_2d();  // the film position
        for (size_t k = 1; k <= 4; ++k) {
            const Ray& r = rec.closest[k];
            // The wall the bounce leaves: the coordinate nearest +-1.
            int axis = 0;
            for (int a = 1; a < 3; ++a)
                if (std::abs(r.origin[a]) > std::abs(r.origin[axis])) axis = a;
            const float cos_theta = std::abs(r.dir[axis]) / glm::length(r.dir);
            EXPECT_NEAR(cos_theta, sample_cosine_hemisphere(draws.next_2d()).z, 1e-4f)
                << "sample " << s << " bounce " << k;
        }
    }
}

// A flat-shaded mirror sphere reflects the environment exactly: the radiance of a camera
// ray equals albedo * env(reflect(d, n)) with n the hit triangle's normal.
TEST(PathTracer, MirrorReflectsTheEnvironmentExactly) {
    auto env = std::make_shared<test::GradientEnv>();
    const Vec3f tint(0.9f, 0.8f, 0.7f);
    const TraceScene scene = make_scene(
        {{make_icosphere({0, 0, 0}, 1.0f, 3), flat(test::of_type(MaterialType::mirror, tint))}},
        env);
    Pcg32 rng(4);
    int hits = 0;
    for (int i = 0; i < 500; ++i) {
        Ray ray;
        ray.origin = Vec3f(0, 0, 5);
        ray.dir = glm::normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, -5.0f));
        Hit hit;
        if (!scene.tree->intersect(ray, hit)) continue;
        ++hits;
        const Vec3u t = scene.mesh->triangles[hit.prim];
        const auto& p = scene.mesh->positions;
        const Vec3f n = glm::normalize(glm::cross(p[t.y] - p[t.x], p[t.z] - p[t.x]));
        const Vec3f r = glm::normalize(ray.dir - 2.0f * glm::dot(ray.dir, n) * n);
        PixelSampler sampler(1, 0, 0, uint32_t(i));
        PathCounters counters;
        TraceParams tp;
        const Vec3f L = trace_path(scene, tp, ray, sampler, counters);
        const Vec3f expected = tint * env->eval(r);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(L[c], expected[c], 2e-5f * expected[c]) << i;
    }
    EXPECT_GT(hits, 100);
}

// The same with the Grace probe: a mirror sphere shows the probe, smooth-shaded, exactly
// (reflection about the interpolated normal), through the real environment light.
TEST(PathTracer, MirrorSphereReflectsTheProbe) {
    const auto grace = test::grace_probe();
    if (grace.empty()) GTEST_SKIP() << test::kNoGraceProbe;
    EnvironmentDesc desc;
    desc.file = grace.string();
    desc.rotation_degrees = 30.0f;
    auto env = make_environment_light(desc);
    const TraceScene scene = make_scene(
        {{make_icosphere({0, 0, 0}, 1.0f, 3), test::smooth(test::of_type(MaterialType::mirror))}},
        env);
    Pcg32 rng(6);
    int hits = 0;
    for (int i = 0; i < 500; ++i) {
        Ray ray;
        ray.origin = Vec3f(0, 0.5f, 5);
        ray.dir = glm::normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.6f, -5.0f));
        Hit hit;
        if (!scene.tree->intersect(ray, hit)) continue;
        const Vec3u t = scene.mesh->triangles[hit.prim];
        const float w = 1.0f - hit.u - hit.v;
        const Vec3f n = glm::normalize(w * scene.normals[t.x] + hit.u * scene.normals[t.y] +
                                       hit.v * scene.normals[t.z]);
        if (glm::dot(n, -ray.dir) <= 0.0f) continue;
        ++hits;
        const Vec3f r = glm::normalize(ray.dir - 2.0f * glm::dot(ray.dir, n) * n);
        PixelSampler sampler(1, 0, 0, uint32_t(i));
        PathCounters counters;
        const Vec3f L = trace_path(scene, TraceParams{}, ray, sampler, counters);
        const Vec3f expected = env->eval(r);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(L[c], expected[c], 1e-4f * (1.0f + expected[c])) << i;
    }
    EXPECT_GT(hits, 100);
}

// Unbiasedness under real probes: BSDF sampling, NEE and MIS (with and without the map's
// importance sampling) estimate the same image of a diffuse sphere on a box. Under Pisa all
// strategies converge quickly; under Grace (tiny, very bright windows) only the importance-
// sampled ones do within test time, so there NEE and MIS are compared with each other.
TEST(PathTracer, LightSamplingStrategiesAgreeUnderProbes) {
    const auto data = test::shared_data_dir();
    if (data.empty() || !std::filesystem::exists(data / "probes" / "grace.hdr")) {
        GTEST_SKIP() << "shared data (probes/*.hdr) not found; set KDT_SHARED_DATA";
    }
    const Camera cam = make_camera({0, 1, 3.5f}, {0, -0.3f, 0}, {0, 1, 0}, 35.0f, 12, 12);
    for (const char* probe : {"pisa.hdr", "grace.hdr"}) {
        EnvironmentDesc desc;
        desc.file = (data / "probes" / probe).string();
        const TraceScene scene =
            make_scene({{make_icosphere({0, 0, 0}, 1.0f, 2), test::smooth(diffuse(0.7f))},
                        {make_box({-3, -2, -3}, {3, -1, 3}), flat(diffuse(0.5f))}},
                       make_environment_light(desc));
        const bool hard = std::string(probe) == "grace.hdr";
        std::vector<double> means;
        for (int k = 0; k < 4; ++k) {
            if (hard && (k == 0 || k == 3)) {
                means.push_back(0.0);
                continue;
            }
            TraceParams tp;
            tp.light_sampling =
                k == 0 ? LightSampling::bsdf : (k == 1 ? LightSampling::nee : LightSampling::mis);
            tp.env_importance = k != 3;
            tp.seed = uint64_t(k);
            const Image img = render(scene, cam, tp, k == 0 ? 128 : 64);
            means.push_back(mean_stderr(img, 1, all_pixels).first);
        }
        const double mis = means[2];
        EXPECT_GT(mis, 0.05);
        for (int k : {0, 1, 3}) {
            if (hard && k != 1) continue;
            EXPECT_NEAR(means[size_t(k)], mis, (hard ? 0.015 : 0.03) * mis)
                << probe << ": strategy " << kLightSamplingNames[size_t(k < 3 ? k : 2)]
                << (k == 3 ? " (uniform env)" : "");
        }
    }
}

// Depth counting: max_depth 0 shows only the environment and emitters.
TEST(PathTracer, DepthZeroSeesOnlyTheEnvironment) {
    const TraceScene scene = make_scene({{make_icosphere({0, 0, 0}, 1.0f, 1), flat(diffuse(0.8f))}},
                                        std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    const Camera cam = make_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 20.0f, 8, 8);
    TraceParams tp;
    tp.max_depth = 0;
    const Image img = render(scene, cam, tp, 4);
    EXPECT_EQ(img.at(4, 4), Vec3f(0.0f));
    tp.max_depth = 1;
    const Image img1 = render(scene, cam, tp, 64);
    EXPECT_NEAR(img1.at(4, 4).x, 0.8f, 0.05f);
}

// Glass: a dielectric sphere in a constant environment conserves energy (no absorption),
// up to the 1/eta^2 radiance scaling that cancels on the way out.
TEST(PathTracer, DielectricSphereInFurnaceIsInvisible) {
    const TraceScene scene = make_scene({{make_icosphere({0, 0, 0}, 1.0f, 3),
                                          test::smooth(test::of_type(MaterialType::dielectric))}},
                                        std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    const Camera cam = make_camera({0, 0, 4}, {0, 0, 0}, {0, 1, 0}, 30.0f, 16, 16);
    TraceParams tp;
    tp.max_depth = 64;
    const Image img = render(scene, cam, tp, 16);
    auto [m, se] = mean_stderr(img, 0, all_pixels);
    EXPECT_NEAR(m, 1.0, 4.0 * se + 2e-3);
}

// Hard cases: degenerate triangles, grazing rays along a plane, a tiny very bright emitter,
// broken file normals. No pixel may be NaN or infinite.
TEST(PathTracer, HardScenesStayFinite) {
    TriangleMesh junk;
    junk.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}, {0, 1, 0}};
    junk.triangles = {{0, 1, 2}, {3, 4, 0}, {1, 1, 1}, {0, 1, 3}};
    junk.normals = {{0, 0, 0}, {std::nanf(""), 0, 0}, {0, 0, 1}, {0, 0, -1}, {1e-30f, 0, 0}};
    MaterialDesc lamp;
    lamp.type = MaterialType::emissive;
    lamp.emission = Vec3f(1e6f);
    const TraceScene scene =
        make_scene({{junk, test::smooth(diffuse(0.7f))},
                    {make_quad({-5, 0, -5}, {0, 0, 10}, {10, 0, 0}), test::smooth(diffuse(0.9f))},
                    {make_quad({0.3f, 0.5f, 0.3f}, {0.001f, 0, 0}, {0, 0, 0.001f}),
                     flat(compile_material(lamp))},
                    {make_icosphere({1, 0.3f, 0}, 0.3f, 1),
                     test::smooth(test::of_type(MaterialType::dielectric))},
                    {make_icosphere({-1, 0.3f, 0}, 0.3f, 1),
                     test::smooth(test::of_type(MaterialType::conductor))}},
                   std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    // Camera almost in the plane: grazing primary rays.
    const Camera cam = make_camera({0, 1e-4f, 4}, {0, 0, 0}, {0, 1, 0}, 60.0f, 24, 16);
    for (LightSampling ls : {LightSampling::bsdf, LightSampling::mis}) {
        TraceParams tp;
        tp.light_sampling = ls;
        const Image img = render(scene, cam, tp, 16);
        for (float v : img.rgb) ASSERT_TRUE(std::isfinite(v) && v >= 0.0f);
        EXPECT_EQ(img.counters.nonfinite_dropped, 0u);
    }
}

// Scaling a scene by a power of two is exact, and so is everything the path tracer does
// with it: the image must be bit for bit the same from 2^-60 to 2^60. Ray offsets with an
// absolute part near the origin (a ground plane at y = 0) and normals normalised in float
// (whose squared length overflows beyond edges of about 1e9) each broke this.
TEST(PathTracer, ImagesAreTheSameAtEveryPowerOfTwoScale) {
    MaterialDesc lamp;
    lamp.type = MaterialType::emissive;
    lamp.emission = Vec3f(6.0f, 5.0f, 4.0f);
    auto scene_at = [&](float s) {
        return make_scene(
            {{make_quad(s * Vec3f(-20, 0, -20), s * Vec3f(0, 0, 40), s * Vec3f(40, 0, 0)),
              flat(diffuse(0.5f))},
             {make_icosphere(s * Vec3f(0, 0.8f, 0), 0.8f * s, 2), test::smooth(diffuse(0.7f))},
             {make_box(s * Vec3f(0.9f, 0, -0.3f), s * Vec3f(1.5f, 0.6f, 0.3f)),
              flat(diffuse(0.6f))},
             {make_quad(s * Vec3f(-1, 2.5f, -1), s * Vec3f(0.6f, 0, 0), s * Vec3f(0, 0, 0.6f)),
              flat(compile_material(lamp))}},
            std::make_shared<ConstantEnv>(Vec3f(0.3f, 0.4f, 0.5f)));
    };
    TraceParams tp;
    tp.light_sampling = LightSampling::mis;
    auto image_at = [&](float s) {
        return render(scene_at(s),
                      make_camera(s * Vec3f(2.5f, 1.8f, 3.2f), s * Vec3f(0, 0.6f, 0), {0, 1, 0},
                                  45.0f, 24, 16),
                      tp, 16);
    };
    const Image ref = image_at(1.0f);
    ASSERT_GT(ref.counters.bounce_rays, 1000u);
    for (int e : {-60, -20, 20, 60}) {
        const Image img = image_at(std::ldexp(1.0f, e));
        EXPECT_EQ(img.counters.bounce_rays, ref.counters.bounce_rays) << "scale 2^" << e;
        EXPECT_EQ(img.counters.shadow_rays, ref.counters.shadow_rays) << "scale 2^" << e;
        EXPECT_EQ(img.counters.nonfinite_dropped, 0u) << "scale 2^" << e;
        EXPECT_TRUE(img.rgb == ref.rgb) << "scale 2^" << e;
    }
}

// Offsetting along the geometric normal avoids self-intersection without a scene-scale
// epsilon, also far from the origin.
TEST(PathTracer, OffsetOriginsDoNotSelfIntersect) {
    for (float scale : {1.0f, 1e3f, 1e5f}) {
        const Vec3f c(scale, -0.5f * scale, 0.25f * scale);
        const TraceScene scene =
            make_scene({{make_icosphere(c, 0.01f * scale, 2), flat(diffuse(0.5f))}},
                       std::make_shared<ConstantEnv>(Vec3f(1.0f)));
        Pcg32 rng(8);
        int tested = 0;
        for (int i = 0; i < 300; ++i) {
            Ray ray;
            ray.origin = c + Vec3f(0, 0, 0.05f * scale);
            ray.dir =
                glm::normalize(Vec3f(rng.next_float() - 0.5f, rng.next_float() - 0.5f, -1.0f) *
                               Vec3f(0.2f, 0.2f, 1.0f));
            Hit hit;
            if (!scene.tree->intersect(ray, hit)) continue;
            const Vec3u t = scene.mesh->triangles[hit.prim];
            const auto& p = scene.mesh->positions;
            const Vec3f ng = glm::normalize(glm::cross(p[t.y] - p[t.x], p[t.z] - p[t.x]));
            const Vec3f hp = (1 - hit.u - hit.v) * p[t.x] + hit.u * p[t.y] + hit.v * p[t.z];
            // Outgoing rays into the upper hemisphere of the convex sphere must escape.
            Vec3f tt, bb;
            make_basis(ng, tt, bb);
            const Vec3f local = sample_cosine_hemisphere({rng.next_float(), rng.next_float()});
            Ray out;
            out.origin = offset_ray_origin(hp, ng, offset_scale(hp, p[t.x], p[t.y], p[t.z]));
            out.dir = local.x * tt + local.y * bb + local.z * ng;
            Hit again;
            EXPECT_FALSE(scene.tree->intersect(out, again)) << "scale " << scale;
            EXPECT_FALSE(scene.tree->occluded(out)) << "scale " << scale;
            ++tested;
        }
        EXPECT_GT(tested, 50);
    }
}

}  // namespace
}  // namespace kdt

namespace kdt {
namespace {

// Shading looks a hit's instance up in runs of triangles; it must agree with the array.
TEST(PathTracer, InstanceRunsAgreeWithTheTriangleInstances) {
    TraceScene s;
    s.triangle_instance = {0, 0, 0, 2, 2, 1, 1, 1, 1, 0};
    s.runs = build_instance_runs(s);
    ASSERT_EQ(s.runs.first.size(), 4u);
    for (uint32_t i = 0; i < s.triangle_instance.size(); ++i)
        EXPECT_EQ(s.instance_of(i), s.triangle_instance[i]) << i;
    // More runs than kMaxRuns: none are built and the array answers.
    s.triangle_instance.clear();
    for (uint32_t i = 0; i < 40; ++i) s.triangle_instance.push_back(i % 3);
    s.runs = build_instance_runs(s);
    EXPECT_TRUE(s.runs.first.empty());
    for (uint32_t i = 0; i < s.triangle_instance.size(); ++i)
        EXPECT_EQ(s.instance_of(i), s.triangle_instance[i]) << i;
    // A snapshot builds them.
    const TraceScene scene =
        make_scene({{make_icosphere({0, 0.5f, 0}, 0.5f, 1), test::smooth(diffuse(0.8f))},
                    {make_box({-1, -1, -1}, {1, 0, 1}), flat(diffuse(0.5f))}},
                   std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    const auto snap =
        compile_snapshot(scene, make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40, 4, 4));
    EXPECT_EQ(snap->scene->runs.first, (std::vector<uint32_t>{0, 80}));
    EXPECT_EQ(snap->scene->runs.instance, (std::vector<uint32_t>{0, 1}));
}

// record_rays() sees exactly the rays render_sample() traces (for the throughput bench).
TEST(PathTracer, RecordedRaysMatchTheCounters) {
    const TraceScene scene =
        make_scene({{make_icosphere({0, 0.5f, 0}, 0.5f, 2), test::smooth(diffuse(0.8f))},
                    {make_box({-1, -1, -1}, {1, 0, 1}), flat(diffuse(0.5f))}},
                   std::make_shared<ConstantEnv>(Vec3f(1.0f)));
    const Camera cam = make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 8, 8);
    TraceParams tp;
    PathCounters counters;
    RayRecord rec;
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
            for (uint32_t s = 0; s < 4; ++s) {
                render_sample(scene, cam, tp, x, y, s, counters);
                record_rays(scene, cam, tp, x, y, s, rec);
            }
        }
    }
    EXPECT_EQ(rec.closest.size(), counters.camera_rays + counters.bounce_rays);
    EXPECT_EQ(rec.any.size(), counters.shadow_rays);
    EXPECT_GT(counters.bounce_rays, 0u);
}

}  // namespace
}  // namespace kdt
