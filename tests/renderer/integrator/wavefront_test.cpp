// The wavefront route (renderer/integrator/wavefront.h) against one path at a time: the
// same radiance bit for bit, the same counters and the same sampler states, on scenes with
// shadow rays to a non-constant environment, emissive triangles, dielectrics and roulette.
#include "renderer/integrator/wavefront.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/renderer/integrator/test_scenes.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

bool same_bits(const Vec3f& a, const Vec3f& b) { return std::memcmp(&a, &b, sizeof(Vec3f)) == 0; }

void expect_same_counters(const PathCounters& a, const PathCounters& b, const std::string& what) {
    EXPECT_EQ(a.samples, b.samples) << what;
    EXPECT_EQ(a.camera_rays, b.camera_rays) << what;
    EXPECT_EQ(a.bounce_rays, b.bounce_rays) << what;
    EXPECT_EQ(a.shadow_rays, b.shadow_rays) << what;
    EXPECT_EQ(a.nodes_visited, b.nodes_visited) << what;
    EXPECT_EQ(a.triangles_tested, b.triangles_tested) << what;
}

// Every sample of a width x height image, spp each, through trace_camera_hit() one at a time
// and through trace_camera_hits() in batches of `batch`; returns the one-path counters.
// camera_hits, when set, gets the number of camera rays that hit.
PathCounters expect_wavefront_equals_one_path(const TraceScene& scene, const TraceParams& tp,
                                              const std::string& what, size_t batch, int spp = 3,
                                              size_t* camera_hits = nullptr) {
    const int width = 12, height = 10;
    const Camera cam =
        make_camera({0.3f, 1.2f, 3.2f}, {0, 0.3f, 0}, {0, 1, 0}, 45.0f, width, height);
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    std::vector<PixelSampler> samplers;
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            for (int s = 0; s < spp; ++s) {
                PixelSampler sampler(tp.seed, uint32_t(x), uint32_t(y), uint32_t(s));
                rays.push_back(camera_ray(cam, tp, x, y, sampler.next_2d()));
                samplers.push_back(sampler);
                Hit hit;
                scene.tree->intersect(rays.back(), hit);
                hits.push_back(hit);
            }
        }
    }
    const size_t n = rays.size();
    if (camera_hits)
        *camera_hits =
            size_t(std::count_if(hits.begin(), hits.end(), [](const Hit& h) { return h.valid(); }));
    std::vector<PixelSampler> one_samplers = samplers;
    std::vector<Vec3f> one(n), wave(n);
    PathCounters one_counters, wave_counters;
    for (size_t i = 0; i < n; ++i)
        one[i] = trace_camera_hit(scene, tp, rays[i], hits[i], one_samplers[i], one_counters);
    WavefrontScratch scratch;
    for (size_t i = 0; i < n; i += batch) {
        const size_t m = std::min(batch, n - i);
        trace_camera_hits(scene, tp, rays.data() + i, hits.data() + i, samplers.data() + i, m,
                          wave.data() + i, wave_counters, scratch);
    }
    for (size_t i = 0; i < n; ++i) {
        EXPECT_TRUE(same_bits(one[i], wave[i]))
            << what << ": sample " << i << ": one path " << one[i].x << " " << one[i].y << " "
            << one[i].z << ", wavefront " << wave[i].x << " " << wave[i].y << " " << wave[i].z;
        // The samplers have made the same draws.
        EXPECT_TRUE(
            same_bits(Vec3f(one_samplers[i].next_2d(), 0.0f), Vec3f(samplers[i].next_2d(), 0.0f)))
            << what << ": sample " << i;
        if (::testing::Test::HasFailure()) break;
    }
    expect_same_counters(one_counters, wave_counters, what);
    return one_counters;
}

std::vector<TraceParams> strategies() {
    std::vector<TraceParams> all;
    for (LightSampling ls : {LightSampling::bsdf, LightSampling::nee, LightSampling::mis}) {
        for (bool rr : {false, true}) {
            TraceParams tp;
            tp.light_sampling = ls;
            tp.russian_roulette = rr;
            tp.rr_min_depth = 1;
            tp.max_depth = 6;
            tp.seed = 11;
            all.push_back(tp);
        }
    }
    return all;
}

std::string describe(const TraceParams& tp) {
    return std::string(kLightSamplingNames[size_t(tp.light_sampling)]) +
           (tp.russian_roulette ? " rr" : " no-rr");
}

TEST(Wavefront, MatchesOnePathUnderAConstantSky) {
    const TraceScene scene =
        test::make_mixed_scene(std::make_shared<test::ConstantEnv>(Vec3f(1.0f)));
    for (const TraceParams& tp : strategies()) {
        const PathCounters c = expect_wavefront_equals_one_path(scene, tp, describe(tp), 1000);
        EXPECT_GT(c.bounce_rays, 100u) << describe(tp);
    }
}

// Environment shadow rays (a non-constant sky under nee and mis), emitter shadow rays, the
// glass sphere's lobes; batches of 1, 7 and all samples.
TEST(Wavefront, MatchesOnePathWithShadowRaysEmittersAndGlass) {
    const TraceScene scene = test::make_mixed_scene(std::make_shared<test::GradientEnv>());
    for (const TraceParams& tp : strategies()) {
        for (size_t batch : {size_t(1), size_t(7), size_t(1000)}) {
            const std::string what = describe(tp) + ", batch " + std::to_string(batch);
            const PathCounters c = expect_wavefront_equals_one_path(scene, tp, what, batch);
            if (tp.light_sampling != LightSampling::bsdf) {
                EXPECT_GT(c.shadow_rays, 100u) << what;
            }
        }
    }
    // Without traversal counting the radiance is the same and nothing is counted.
    TraceParams tp;
    tp.count_traversal = false;
    const PathCounters c = expect_wavefront_equals_one_path(scene, tp, "uncounted", 64);
    EXPECT_EQ(c.nodes_visited, 0u);
}

// The wavefront with the partition traversal (TraceParams::partition) for the first bounce:
// batches below kWavefrontPartitionMinBatch (streams throughout) and batches whose camera
// hits reach it (the first bounce and its shadow rays by partition, later ones by streams).
TEST(Wavefront, PartitionTraversalMatchesOnePath) {
    const TraceScene scene = test::make_mixed_scene(std::make_shared<test::GradientEnv>());
    for (TraceParams tp : strategies()) {
        tp.partition = true;
        for (size_t batch : {size_t(1), size_t(7), size_t(1000)}) {
            const std::string what = describe(tp) + ", partition, batch " + std::to_string(batch);
            expect_wavefront_equals_one_path(scene, tp, what, batch);
        }
        // 12 x 10 pixels x 40 samples in one batch: enough camera hits for the partition,
        // and the same batch with streams only.
        for (bool partition : {true, false}) {
            tp.partition = partition;
            size_t camera_hits = 0;
            const std::string what =
                describe(tp) + (partition ? ", partition" : ", streams") + ", one batch of 4800";
            expect_wavefront_equals_one_path(scene, tp, what, 4800, 40, &camera_hits);
            EXPECT_GE(camera_hits, 2 * kWavefrontPartitionMinBatch) << what;
        }
    }
}

TEST(Wavefront, MatchesOnePathUnderTheGraceProbe) {
    const auto grace = test::grace_probe();
    if (grace.empty()) GTEST_SKIP() << test::kNoGraceProbe;
    EnvironmentDesc desc;
    desc.file = grace.string();
    const TraceScene scene = test::make_mixed_scene(make_environment_light(desc));
    for (const TraceParams& tp : strategies())
        expect_wavefront_equals_one_path(scene, tp, describe(tp) + ", grace", 1000);
}

}  // namespace
}  // namespace kdt
