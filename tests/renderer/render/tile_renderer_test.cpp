// render_tile() through the wavefront (TraceParams::wavefront) against one path at a time:
// the same film bit for bit, the same AOVs and counters, for any thread count, with
// adaptive sampling (inactive pixels), a sample cap, several samples per pass and a
// transparent background.
#include "renderer/render/tile_renderer.h"

#include <algorithm>
#include <cstring>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/render/session.h"
#include "tests/renderer/integrator/test_scenes.h"

namespace kdt {
namespace {

struct Result {
    FilmImage image;
    PathCounters totals;
};

Result render(const std::shared_ptr<const RenderSnapshot>& snap, TraceParams tp, FilmParams fp,
              bool wavefront, int passes, int max_spp) {
    tp.wavefront = wavefront;
    RenderSession session(snap, tp, fp);
    session.set_aov(true);
    for (int i = 0; i < passes; ++i) session.render_pass(max_spp);
    Result r;
    session.copy_image(r.image, true);
    r.totals = session.totals();
    return r;
}

template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

TEST(TileRenderer, WavefrontFilmEqualsOnePathAtATime) {
    const TraceScene scene = test::make_mixed_scene(std::make_shared<test::GradientEnv>());
    // 40 x 24: partial tiles on the right and bottom.
    const auto snap = compile_snapshot(
        scene, make_camera({0.3f, 1.2f, 3.2f}, {0, 0.3f, 0}, {0, 1, 0}, 45.0f, 40, 24));
    for (int threads : {1, 2}) {
        // {samples per pass, passes, sample cap}: 20 per pass on a full tile make 5120
        // samples, more than one chunk takes (kMaxChunk), so a pixel's samples span two.
        for (const auto& [per_pass, passes, cap] :
             {std::tuple{1, 4, 10}, std::tuple{3, 4, 10}, std::tuple{20, 2, 0}}) {
            for (bool transparent : {false, true}) {
                TraceParams tp;
                tp.threads = threads;
                tp.samples_per_pass = per_pass;
                tp.max_depth = 5;
                FilmParams fp;
                fp.transparent = transparent;
                // Adaptive sampling stops pixels (the sky's first) after 2 samples at this
                // threshold, so later passes skip them; a cap of 10 cuts the last pass of 3
                // short.
                fp.adaptive = true;
                fp.adaptive_min_spp = 2;
                fp.adaptive_threshold = 0.3f;
                const std::string what = "threads " + std::to_string(threads) + ", per pass " +
                                         std::to_string(per_pass) +
                                         (transparent ? ", transparent" : "");
                const Result one = render(snap, tp, fp, false, passes, cap);
                const Result wave = render(snap, tp, fp, true, passes, cap);
                EXPECT_TRUE(same_bits(one.image.rgb, wave.image.rgb)) << what;
                EXPECT_TRUE(same_bits(one.image.aov_normals, wave.image.aov_normals)) << what;
                EXPECT_TRUE(same_bits(one.image.aov_depth, wave.image.aov_depth)) << what;
                EXPECT_EQ(one.totals.samples, wave.totals.samples) << what;
                EXPECT_EQ(one.totals.camera_rays, wave.totals.camera_rays) << what;
                EXPECT_EQ(one.totals.bounce_rays, wave.totals.bounce_rays) << what;
                EXPECT_EQ(one.totals.shadow_rays, wave.totals.shadow_rays) << what;
                EXPECT_EQ(one.totals.nodes_visited, wave.totals.nodes_visited) << what;
                EXPECT_EQ(one.totals.triangles_tested, wave.totals.triangles_tested) << what;
                EXPECT_GT(one.totals.shadow_rays, 0u) << what;
                const int most = cap > 0 ? std::min(passes * per_pass, cap) : passes * per_pass;
                EXPECT_LT(one.totals.samples, uint64_t(40 * 24 * most)) << what << ": no stop";
                EXPECT_FALSE(one.image.aov_depth.empty()) << what;
            }
        }
    }
}

}  // namespace
}  // namespace kdt
