// Debug-view colours: heat maps on a log scale from the smallest to the largest positive
// value, black for pixels without samples, and the mean for the legend; normals as
// n * 0.5 + 0.5; depth on the frame's log scale; sky marked in both.
#include "ui/heat_map.h"

#include <cmath>

#include <gtest/gtest.h>

namespace kdt::ui {
namespace {

TEST(HeatMap, LogScaleAndLegend) {
    const std::vector<float> v = {0.0f, 1.0f, 10.0f, 100.0f};
    std::vector<float> rgb;
    const HeatScale s = heat_colors(v, rgb);
    EXPECT_EQ(s.lo, 1.0f);
    EXPECT_EQ(s.hi, 100.0f);
    EXPECT_NEAR(s.mean, 37.0, 1e-9);
    ASSERT_EQ(rgb.size(), 12u);
    EXPECT_EQ(rgb[0] + rgb[1] + rgb[2], 0.0f);  // no samples: black
    EXPECT_NEAR(heat_position(10.0f, s), 0.5f, 1e-6f);
    EXPECT_EQ(heat_position(1000.0f, s), 1.0f);
    // Brighter with cost: the sum of channels grows along the scale.
    auto sum = [&](size_t i) { return rgb[3 * i] + rgb[3 * i + 1] + rgb[3 * i + 2]; };
    EXPECT_GT(sum(1), 0.0f);
    EXPECT_LT(sum(1), sum(2));
    EXPECT_LT(sum(2), sum(3));
    for (float c : rgb) {
        EXPECT_GE(c, 0.0f);
        EXPECT_LE(c, 1.0f);
    }
}

TEST(DebugColors, NormalsAsHalfPlusHalfAndSkyMarked) {
    // Four pixels in a row: +x, -y (unnormalised mean), sky, no samples.
    const std::vector<float> n = {1, 0, 0, 0, -0.5f, 0, 0, 0, 0, 0, 0, 0};
    const std::vector<float> d = {2.0f, 3.0f, INFINITY, 0.0f};
    std::vector<float> rgb;
    const HeatScale s = normal_colors(n, d, 4, rgb);
    ASSERT_EQ(rgb.size(), 12u);
    EXPECT_EQ(rgb[0], 1.0f);
    EXPECT_EQ(rgb[1], 0.5f);
    EXPECT_EQ(rgb[2], 0.5f);
    EXPECT_EQ(rgb[3], 0.5f);
    EXPECT_EQ(rgb[4], 0.0f);  // renormalised: -y
    EXPECT_EQ(rgb[5], 0.5f);
    const Vec3f sky = sky_color(2, 0);
    EXPECT_EQ(rgb[6], sky.x);
    EXPECT_EQ(rgb[8], sky.z);
    EXPECT_EQ(rgb[9] + rgb[10] + rgb[11], 0.0f);
    EXPECT_EQ(s.sky_fraction, 0.25);
    // The sky checks alternate every 4 pixels.
    EXPECT_NE(sky_color(0, 0).x, sky_color(4, 0).x);
    EXPECT_EQ(sky_color(0, 0).x, sky_color(4, 4).x);
}

TEST(DebugColors, DepthOnTheFramesLogScaleNearBrighterThanFar) {
    const std::vector<float> d = {1.0f, 10.0f, 100.0f, INFINITY, 0.0f, 10.0f};
    std::vector<float> rgb;
    const HeatScale s = depth_colors(d, 3, rgb);
    EXPECT_EQ(s.lo, 1.0f);
    EXPECT_EQ(s.hi, 100.0f);
    EXPECT_NEAR(s.mean, 30.25, 1e-9);
    EXPECT_NEAR(s.sky_fraction, 1.0 / 6.0, 1e-12);
    auto sum = [&](size_t i) { return rgb[3 * i] + rgb[3 * i + 1] + rgb[3 * i + 2]; };
    EXPECT_GT(sum(0), sum(1));
    EXPECT_GT(sum(1), sum(2));
    const Vec3f mid = depth_ramp(0.5f);  // 10 is halfway on the log scale from 1 to 100
    EXPECT_NEAR(rgb[3], mid.x, 1e-6f);
    EXPECT_NEAR(rgb[5], mid.z, 1e-6f);
    EXPECT_EQ(rgb[9], sky_color(0, 1).x);  // pixel 3 is (0, 1) in rows of 3
    EXPECT_EQ(sum(4), 0.0f);
    // debug_colors picks the layer, and refuses an image without it.
    FilmImage img;
    img.width = 3;
    img.height = 2;
    std::vector<float> out;
    HeatScale scale;
    EXPECT_FALSE(debug_colors(DebugLayer::depth, img, out, scale));
    EXPECT_FALSE(debug_colors(DebugLayer::nodes, img, out, scale));
    img.aov_depth = d;
    img.aov_normals.assign(18, 0.0f);
    ASSERT_TRUE(debug_colors(DebugLayer::depth, img, out, scale));
    EXPECT_EQ(out, rgb);
    EXPECT_EQ(scale.hi, 100.0f);
    // A split view's other side widens the colour scale, not the image's own scale: 10 is
    // then at a third of the log scale from 1 to 1000.
    const HeatScale other{2.0f, 1000.0f, 50.0, 0.0};
    ASSERT_TRUE(debug_colors(DebugLayer::depth, img, out, scale, &other));
    EXPECT_EQ(scale.hi, 100.0f);
    const Vec3f third = depth_ramp(1.0f / 3.0f);
    EXPECT_NEAR(out[3], third.x, 1e-5f);
    EXPECT_NEAR(out[4], third.y, 1e-5f);
    const HeatScale w = widen(scale, other), none = widen(scale, HeatScale{});
    EXPECT_EQ(w.lo, 1.0f);
    EXPECT_EQ(w.hi, 1000.0f);
    EXPECT_EQ(w.mean, scale.mean);
    EXPECT_EQ(none.hi, 100.0f);
    // A scale without a range (normals, or no samples) widens nothing, and a NaN position on
    // the ramp is its start.
    EXPECT_EQ(widen(scale, HeatScale{-1.0f, 1.0f, 0.0, 0.0}).lo, 1.0f);
    EXPECT_EQ(depth_ramp(NAN).x, depth_ramp(0.0f).x);
    EXPECT_EQ(heat_ramp(NAN).x, heat_ramp(0.0f).x);
}

}  // namespace
}  // namespace kdt::ui
