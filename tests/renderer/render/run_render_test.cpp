// run_render's progress is honest: 100 % only at the end, whatever the stop condition, and no
// error estimate before there is a variance to estimate it from. Automatic pass sizes change
// the passes, not the image.
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/render/session.h"
#include "tests/renderer/integrator/test_scenes.h"

namespace kdt {
namespace {

std::shared_ptr<const RenderSnapshot> scene_snapshot() {
    const TraceScene scene = test::make_scene(
        {{test::make_icosphere({0, 0.5f, 0}, 0.5f, 2), test::smooth(test::diffuse(0.7f))},
         {test::make_box({-1, -1, -1}, {1, 0, 1}), test::flat(test::diffuse(0.5f))}},
        std::make_shared<test::GradientEnv>());
    return compile_snapshot(scene, make_camera({2, 2, 3}, {0, 0, 0}, {0, 1, 0}, 40.0f, 24, 16));
}

std::vector<RenderProgress> run(const TraceParams& tp, const FilmParams& fp,
                                const StopConditions& stop) {
    RenderSession s(scene_snapshot(), tp, fp);
    std::vector<RenderProgress> seen;
    run_render(s, stop, [&](const RenderProgress& p) { seen.push_back(p); });
    return seen;
}

void expect_full_only_at_the_end(const std::vector<RenderProgress>& seen) {
    ASSERT_GE(seen.size(), 2u);
    for (size_t i = 0; i + 1 < seen.size(); ++i) {
        EXPECT_LT(seen[i].fraction, 1.0) << "pass " << i << " of " << seen.size();
        EXPECT_GE(seen[i].fraction, 0.0);
    }
    EXPECT_EQ(seen.back().fraction, 1.0);
}

TEST(RunRender, AdaptiveErrorTargetReachesFullOnlyWhenDone) {
    // The mean error falls below the target long before the last pixel does: the bar must
    // follow the pixels still sampling, not the mean.
    TraceParams tp;
    tp.samples_per_pass = 4;
    FilmParams fp;
    fp.adaptive = true;
    fp.adaptive_threshold = 0.03f;
    fp.adaptive_min_spp = 8;
    StopConditions stop;
    stop.error = 0.03f;
    const auto seen = run(tp, fp, stop);
    expect_full_only_at_the_end(seen);
    EXPECT_EQ(seen.back().active_pixels, 0u);
}

// The first adaptive pass samples every pixel: a pass size above the spp budget is cut to it,
// not drawn in full (--adaptive --spp 1 --spp-per-pass 65536 drew 65536 spp).
TEST(RunRender, AdaptiveFirstPassKeepsToTheSppBudget) {
    for (const auto& [spp, per_pass] : {std::pair{1, 4096}, std::pair{4, 8}, std::pair{3, 1024}}) {
        TraceParams tp;
        tp.samples_per_pass = per_pass;
        FilmParams fp;
        fp.adaptive = true;
        StopConditions stop;
        stop.spp = spp;
        const auto seen = run(tp, fp, stop);
        ASSERT_FALSE(seen.empty());
        EXPECT_EQ(seen.back().samples, uint64_t(spp) * 24u * 16u)
            << "--spp " << spp << " --spp-per-pass " << per_pass;
    }
}

// Later adaptive passes keep to the budget too: a pass that would draw past spp * pixels is
// cut to what is left (--adaptive --spp 16 --spp-per-pass 12 drew 24 spp: 12, then 12 more).
// Below adaptive_min_spp every pixel samples, so each one ends at exactly spp.
TEST(RunRender, AdaptivePassesKeepToTheSppBudget) {
    struct Case {
        int spp, per_pass;
    };
    for (const Case c : {Case{16, 12}, Case{8, 3}, Case{40, 16}, Case{64, 12}, Case{21, 5}}) {
        TraceParams tp;
        tp.samples_per_pass = c.per_pass;
        FilmParams fp;
        fp.adaptive = true;
        StopConditions stop;
        stop.spp = c.spp;
        RenderSession s(scene_snapshot(), tp, fp);
        const RenderProgress p = run_render(s, stop);
        const Film& f = s.film();
        const uint64_t budget = uint64_t(c.spp) * f.pixel_count();
        const std::string what =
            "--spp " + std::to_string(c.spp) + " --spp-per-pass " + std::to_string(c.per_pass);
        EXPECT_EQ(p.samples, budget) << what;
        EXPECT_EQ(f.total_drawn(), budget) << what;
        if (c.spp > fp.adaptive_min_spp) continue;
        for (int y = 0; y < f.height(); ++y) {
            for (int x = 0; x < f.width(); ++x)
                ASSERT_EQ(f.next_sample_index(x, y), uint32_t(c.spp))
                    << what << " " << x << "," << y;
        }
    }
}

// Adaptive sampling with pass sizes that are not powers of two (--spp-per-pass 3, 5, 12):
// doublings end on powers of two, so once warmed up most open pixels rest in a pass.
// Without the pass end the drawn counts (18 + 8k, 20 + 8k, 24 + 12k) miss every power of
// two, a pixel between two powers counts as doubling, and every open pixel samples every
// pass.
TEST(RunRender, AdaptivePassesOfAnySizeLetPixelsRest) {
    for (const int per_pass : {3, 5, 12}) {
        TraceParams tp;
        tp.samples_per_pass = per_pass;
        FilmParams fp;
        fp.adaptive = true;
        fp.adaptive_threshold = 1e-6f;  // the allocation decides, not the stopping rule
        RenderSession s(scene_snapshot(), tp, fp);
        size_t open = 0, active = 0;  // over the passes after the warm-up's
        for (int pass = 0; pass < 30; ++pass) {
            const PassStats ps = s.render_pass(0, per_pass);
            if (pass * per_pass < fp.adaptive_min_spp) continue;
            open += ps.open_pixels;
            active += ps.active_pixels;
        }
        // About a quarter of the open pixels doubling at a time.
        EXPECT_LT(double(active), 0.5 * double(open)) << "--spp-per-pass " << per_pass;
        const Film& f = s.film();
        size_t at_powers = 0;
        for (int y = 0; y < f.height(); ++y) {
            for (int x = 0; x < f.width(); ++x) {
                const uint32_t n = f.next_sample_index(x, y);
                at_powers += (n & (n - 1)) == 0;
            }
        }
        EXPECT_GT(at_powers, f.pixel_count() / 2) << "--spp-per-pass " << per_pass;
    }
}

// Less than one sample per active pixel left: one each for the first active pixels in tile
// order, none for the rest.
TEST(RunRender, SampleBudgetBelowOnePerPixelGoesToTheFirstPixels) {
    TraceParams tp;
    FilmParams fp;
    fp.adaptive = true;
    RenderSession s(scene_snapshot(), tp, fp);  // 24x16: tile 0 is x < 16, tile 1 the rest
    s.render_pass(0, 1);
    s.render_pass(std::vector<int>{1}, 0, 2);  // 1 + 2 samples for tile 1's 128 pixels
    // A budget of 2 spp leaves 768 - 640 = 128 samples for 384 active pixels.
    const PassStats ps = s.render_pass(0, 4, 2);
    EXPECT_EQ(ps.active_pixels, 128u);
    EXPECT_EQ(s.totals().samples, 2u * 24u * 16u);
    for (int y = 0; y < 16; ++y) {
        for (int x = 0; x < 24; ++x) {
            const uint32_t want = x >= 16 ? 3u : y < 8 ? 2u : 1u;
            ASSERT_EQ(s.film().next_sample_index(x, y), want) << x << "," << y;
        }
    }
}

// With an explicit pass size and no adaptive sampling the first pass takes 1 sample per pixel:
// an interrupt or a time limit after it leaves no pixel unsampled (--spp-per-pass 4096 left
// most tiles black). The image is that of any pass size.
TEST(RunRender, ExplicitPassSizeStartsWithOneSamplePerPixel) {
    StopConditions stop;
    stop.spp = 9;
    std::vector<float> images[2];
    for (int k = 0; k < 2; ++k) {
        TraceParams tp;
        tp.samples_per_pass = k == 0 ? 4096 : 1;
        RenderSession s(scene_snapshot(), tp, FilmParams{});
        EXPECT_EQ(first_samples_per_pass(s, stop), 1);
        std::vector<RenderProgress> seen;
        run_render(s, stop, [&](const RenderProgress& p) { seen.push_back(p); });
        ASSERT_FALSE(seen.empty());
        EXPECT_EQ(seen.front().samples, 24u * 16u) << "--spp-per-pass " << tp.samples_per_pass;
        EXPECT_EQ(seen.back().samples, 9u * 24u * 16u);
        EXPECT_EQ(seen.size(), k == 0 ? 2u : 9u);
        images[k] = s.film().linear_rgb();
    }
    ASSERT_EQ(images[0].size(), images[1].size());
    EXPECT_EQ(0, std::memcmp(images[0].data(), images[1].data(), images[0].size() * 4));
}

// A time limit cuts explicit passes to half the time left, as automatic ones: a pass of 1
// sample that took 0.1 s with 0.3 s left is followed by one of 1, not 4096 (--time 1
// --spp-per-pass 256 ran 8.7 s). Adaptive passes only under a time limit: their size
// changes the image.
TEST(RunRender, TimeLimitCutsExplicitPasses) {
    for (const bool adaptive : {false, true}) {
        TraceParams tp;
        tp.samples_per_pass = 4096;
        FilmParams fp;
        fp.adaptive = adaptive;
        RenderSession s(scene_snapshot(), tp, fp);
        StopConditions timed;
        timed.seconds = 1.0;
        RenderProgress p;
        p.seconds = 0.7;
        EXPECT_EQ(first_samples_per_pass(s, timed), 1);
        EXPECT_EQ(next_samples_per_pass(s, timed, 1, 0.1, p), 1);
        p.seconds = 0.2;
        EXPECT_EQ(next_samples_per_pass(s, timed, 1, 0.01, p), 40);
        EXPECT_EQ(next_samples_per_pass(s, timed, 1, 1e-6, p), 0);  // 4096 fits
        StopConditions spp;
        spp.spp = 8192;
        EXPECT_EQ(first_samples_per_pass(s, spp), adaptive ? 0 : 1);
        EXPECT_EQ(next_samples_per_pass(s, spp, 1, 100.0, p), 0);
    }
}

TEST(RunRender, ErrorTargetWithoutAdaptivityReachesFullOnlyWhenDone) {
    TraceParams tp;
    StopConditions stop;
    stop.error = 0.1f;
    expect_full_only_at_the_end(run(tp, FilmParams{}, stop));
}

TEST(RunRender, NoErrorEstimateBelowTwoSamples) {
    TraceParams tp;
    StopConditions stop;
    stop.spp = 1;
    auto seen = run(tp, FilmParams{}, stop);
    ASSERT_EQ(seen.size(), 1u);
    EXPECT_FALSE(seen.back().error_known);
    stop.spp = 2;
    seen = run(tp, FilmParams{}, stop);
    EXPECT_FALSE(seen.front().error_known);
    EXPECT_TRUE(seen.back().error_known);
    EXPECT_GT(seen.back().mean_relative_error, 0.0);
}

// One render with automatic passes (samples_per_pass 0) and one with 1 sample per pass: the
// progress after each pass, and the image.
struct AutoAndSingle {
    std::vector<RenderProgress> seen[2];
    std::vector<float> image[2];
};

AutoAndSingle render_auto_and_single(const FilmParams& fp, const StopConditions& stop) {
    AutoAndSingle r;
    for (int k = 0; k < 2; ++k) {
        TraceParams tp;
        tp.samples_per_pass = k == 0 ? 0 : 1;
        tp.seed = 9;
        RenderSession s(scene_snapshot(), tp, fp);
        run_render(s, stop, [&](const RenderProgress& p) { r.seen[k].push_back(p); });
        r.image[k] = s.film().linear_rgb();
    }
    return r;
}

void expect_same_image(const AutoAndSingle& r) {
    ASSERT_EQ(r.image[0].size(), r.image[1].size());
    EXPECT_EQ(0,
              std::memcmp(r.image[0].data(), r.image[1].data(), r.image[0].size() * sizeof(float)));
}

TEST(RunRender, AutomaticPassesGiveTheImageOfOneSamplePerPass) {
    StopConditions stop;
    stop.spp = 21;
    const AutoAndSingle r = render_auto_and_single(FilmParams{}, stop);
    for (const auto& seen : r.seen) {
        ASSERT_FALSE(seen.empty());
        EXPECT_EQ(seen.back().samples, 21u * 24u * 16u);
    }
    EXPECT_EQ(r.seen[1].size(), 21u);
    // 1 sample, then at most kMaxAutoSamplesPerPass (fewer if a pass would exceed a second).
    EXPECT_LT(r.seen[0].size(), 21u);
    EXPECT_GE(r.seen[0].size(),
              size_t(1 + (21 - 1 + kMaxAutoSamplesPerPass - 1) / kMaxAutoSamplesPerPass));
    expect_same_image(r);
}

TEST(RunRender, AdaptiveWarmUpInLargerPassesGivesTheSameImage) {
    // Every pixel samples until adaptive_min_spp: automatic passes take those samples in
    // fewer passes, ending exactly at the minimum, and the film then picks the same pixels.
    FilmParams fp;
    fp.adaptive = true;
    fp.adaptive_min_spp = 12;
    fp.adaptive_threshold = 0.05f;
    StopConditions stop;
    stop.spp = 20;
    const AutoAndSingle r = render_auto_and_single(fp, stop);
    ASSERT_FALSE(r.seen[0].empty());
    EXPECT_EQ(r.seen[0].front().samples, 24u * 16u);  // the first pass: one sample per pixel
    EXPECT_LT(r.seen[0].size(), r.seen[1].size());
    EXPECT_EQ(r.seen[0].back().samples, r.seen[1].back().samples);
    expect_same_image(r);
}

}  // namespace
}  // namespace kdt
