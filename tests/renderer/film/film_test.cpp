#include "renderer/film/film.h"

#include <cmath>

#include <gtest/gtest.h>

#include "renderer/core/sampler.h"

namespace kdt {
namespace {

TEST(Film, MeansAndRelativeError) {
    Film f(4, 3);
    EXPECT_EQ(f.pixel_count(), 12u);
    EXPECT_EQ(f.mean(1, 1), Vec3f(0.0f));
    EXPECT_EQ(f.relative_error(1, 1), kInfinity);
    // Samples 1 and 3 (grey): mean 2, sample variance 2, stderr 1, relative error 0.5.
    f.add_sample(1, 1, Vec3f(1.0f));
    f.add_sample(1, 1, Vec3f(3.0f));
    EXPECT_NEAR(f.mean(1, 1).x, 2.0f, 1e-6f);
    EXPECT_NEAR(f.relative_error(1, 1), 0.5f, 1e-5f);
    EXPECT_EQ(f.count(1, 1), 2u);
    EXPECT_EQ(f.next_sample_index(1, 1), 2u);
    f.skip_sample(1, 1);
    EXPECT_EQ(f.count(1, 1), 2u);
    EXPECT_EQ(f.next_sample_index(1, 1), 3u);
    EXPECT_EQ(f.total_samples(), 2u);
    f.clear();
    EXPECT_EQ(f.total_samples(), 0u);
}

TEST(Film, AdaptiveMaskStopsConvergedRegions) {
    Film f(12, 4);
    Pcg32 rng(1);
    // Left half constant (converged), right half noisy.
    for (int s = 0; s < 32; ++s) {
        for (int y = 0; y < 4; ++y) {
            for (int x = 0; x < 12; ++x) {
                const float v = x < 6 ? 0.5f : 2.0f * rng.next_float();
                f.add_sample(x, y, Vec3f(v));
            }
        }
    }
    FilmParams p;
    p.adaptive = true;
    p.adaptive_threshold = 0.01f;
    p.adaptive_min_spp = 8;
    const size_t active = f.update_active(p);
    // Columns 0..4 stop; column 5 sees noisy neighbours in its 3x3 window, so 7 columns stay
    // open, and the pass samples a quarter of them (kAdaptivePassShare).
    EXPECT_EQ(f.open_count(), 4u * 7u);
    EXPECT_EQ(active, 7u);
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 5; ++x) EXPECT_FALSE(f.active(x, y)) << x << "," << y;
    }
    p.adaptive_min_spp = 64;  // nobody has enough samples yet
    EXPECT_EQ(f.update_active(p), f.pixel_count());
    EXPECT_EQ(f.open_count(), f.pixel_count());
    p.adaptive = false;
    EXPECT_EQ(f.update_active(p), f.pixel_count());
}

TEST(Film, SrgbEncoding) {
    EXPECT_EQ(linear_to_srgb8(0.0f), 0);
    EXPECT_EQ(linear_to_srgb8(1.0f), 255);
    EXPECT_EQ(linear_to_srgb8(std::nanf("")), 0);
    EXPECT_EQ(linear_to_srgb8(0.5f), 188);  // 0.7354 * 255
    Film f(1, 1);
    f.add_sample(0, 0, Vec3f(0.25f));
    EXPECT_EQ(f.srgb8(1.0f)[0], 188);  // exposure +1 doubles
}

}  // namespace
}  // namespace kdt
