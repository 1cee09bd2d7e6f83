// Heat-map colours: a log scale from the smallest to the largest positive value, black for
// pixels without samples, and the mean for the legend.
#include "ui/heat_map.h"

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

}  // namespace
}  // namespace kdt::ui
