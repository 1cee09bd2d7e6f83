// Film::update_active's allocation on synthetic films with known per-pixel noise and cost:
// samples go where sigma / sqrt(cost) is high, the summed variance comes close to the
// optimum for the cost spent, ties and caps are handled, and converged pixels still stop.
#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/sampler.h"
#include "renderer/film/film.h"

namespace kdt {
namespace {

// A 40x10 film of four 10x10 blocks, all with mean luminance 10 (so a relative-error rule
// would give each block samples in proportion to sigma^2): (sigma, cost) = (1, 1), (4, 1),
// (4, 16), (16, 16). The optimal allocation n ~ sigma / sqrt(cost) is 1 : 4 : 1 : 4.
constexpr int kW = 40, kH = 10;
constexpr float kSigma[4] = {1.0f, 4.0f, 4.0f, 16.0f};
constexpr float kCost[4] = {1.0f, 1.0f, 16.0f, 16.0f};
int block(int x) { return x / 10; }

FilmParams adaptive_params(float threshold, int min_spp) {
    FilmParams p;
    p.adaptive = true;
    p.adaptive_threshold = threshold;
    p.adaptive_min_spp = min_spp;
    return p;
}

struct Allocation {
    Film film{kW, kH};
    std::vector<float> cost = std::vector<float>(size_t(kW) * kH);
    double spent = 0.0;
};

// Samples uniform in mean +- sigma * sqrt(3) (standard deviation sigma).
void add_samples(Allocation& r, int x, int y, int n, Pcg32& rng) {
    for (int s = 0; s < n; ++s) {
        const float u = 2.0f * rng.next_float() - 1.0f;
        r.film.add_sample(x, y, Vec3f(10.0f + u * kSigma[block(x)] * std::sqrt(3.0f)));
        r.spent += kCost[block(x)];
    }
}

// Passes of update_active() until `budget` cost is spent; every pixel starts with one.
Allocation allocate(double budget, uint64_t seed) {
    Allocation r;
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) r.cost[size_t(y) * kW + size_t(x)] = kCost[block(x)];
    }
    const FilmParams p = adaptive_params(1e-6f, 8);  // nobody stops: the budget decides
    AdaptiveInputs in;
    in.cost_per_sample = r.cost;
    Pcg32 rng(seed);
    while (r.spent < budget) {
        if (r.film.update_active(p, in) == 0) {
            ADD_FAILURE() << "no pixel active with " << r.spent << " of " << budget << " spent";
            break;
        }
        for (int y = 0; y < kH; ++y) {
            for (int x = 0; x < kW; ++x) {
                if (r.film.active(x, y)) add_samples(r, x, y, r.film.pass_samples(), rng);
            }
        }
    }
    return r;
}

// Mean samples of a block's pixels away from its edges (the 3x3 variance mean blurs them).
double block_samples(const Film& f, int b) {
    double sum = 0.0;
    int n = 0;
    for (int y = 1; y < kH - 1; ++y) {
        for (int x = b * 10 + 1; x < b * 10 + 9; ++x, ++n) sum += f.count(x, y);
    }
    return sum / n;
}

TEST(FilmAdaptive, SamplesFollowSigmaOverSqrtCost) {
    const double mean_cost = (1.0 + 1.0 + 16.0 + 16.0) / 4.0;
    const Allocation r = allocate(200.0 * mean_cost * kW * kH, 7);  // 200 spp's worth
    const double n0 = block_samples(r.film, 0);
    EXPECT_GT(n0, 8.0);
    // 1 : 4 : 1 : 4, not the relative rule's 1 : 16 : 16 : 256 nor uniform 1 : 1 : 1 : 1,
    // each within a factor sqrt(2): counts grow in doublings, some under way at the end.
    const double expected[4] = {1.0, 4.0, 1.0, 4.0};
    for (int b = 1; b < 4; ++b) {
        EXPECT_LE(std::abs(std::log2(block_samples(r.film, b) / n0 / expected[b])), 0.5)
            << "block " << b << ": " << block_samples(r.film, b) / n0;
    }
    // The summed variance of the pixel means, sum sigma^2 / n, is close to the optimum for
    // the cost spent, (sum sigma sqrt(c))^2 / cost, and well below uniform sampling's.
    // Counts that are powers of two cost up to 6 % against the optimum (n off by sqrt(2)
    // costs (sqrt(2) + 1 / sqrt(2)) / 2), doublings under way at the end a little more.
    double mse = 0.0, root = 0.0, sigma2 = 0.0, costs = 0.0;
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            const double s = kSigma[block(x)], c = kCost[block(x)];
            mse += s * s / r.film.count(x, y);
            root += s * std::sqrt(c);
            sigma2 += s * s;
            costs += c;
        }
    }
    const double optimum = root * root / r.spent;
    const double uniform = sigma2 * costs / r.spent;
    EXPECT_LT(mse, 1.12 * optimum) << "optimum " << optimum << ", uniform " << uniform;
    EXPECT_LT(mse, 0.85 * uniform);
}

TEST(FilmAdaptive, SameResultForTheSameFilm) {
    const Allocation a = allocate(100000.0, 3), b = allocate(100000.0, 3);
    uint32_t fewest = ~0u, most = 0;
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            ASSERT_EQ(a.film.count(x, y), b.film.count(x, y));
            fewest = std::min(fewest, a.film.count(x, y));
            most = std::max(most, a.film.count(x, y));
        }
    }
    EXPECT_GT(most, fewest);  // an allocation, not a uniform count that any rule repeats
}

TEST(FilmAdaptive, EqualPrioritiesGoToTheLowerIndex) {
    Film f(8, 8);
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
            for (int s = 0; s < 16; ++s) f.add_sample(x, y, Vec3f(s % 2 ? 1.0f : 3.0f));
        }
    }
    const FilmParams p = adaptive_params(1e-3f, 4);
    AdaptiveInputs in;
    in.samples_per_pass = 2;
    // Every pixel open with the same priority: the pass starts doublings for the first
    // quarter, row-major.
    ASSERT_EQ(f.update_active(p, in), 16u);
    EXPECT_EQ(f.open_count(), 64u);
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) EXPECT_EQ(f.active(x, y), y < 2) << x << "," << y;
    }
    EXPECT_EQ(f.pass_samples(), kAdaptivePassSamples);
}

TEST(FilmAdaptive, PassSamplesOnceWarm) {
    Film f(4, 4);
    FilmParams p = adaptive_params(1e-3f, 8);
    AdaptiveInputs in;
    in.samples_per_pass = 2;
    for (int s = 0; s < 8; ++s) {
        for (int i = 0; i < 15; ++i) f.add_sample(i % 4, i / 4, Vec3f(float(s % 3)));
    }
    f.add_sample(3, 3, Vec3f(1.0f));
    // Pixel (3, 3) is below the minimum; 4 of the others start doublings (a quarter of 16).
    EXPECT_EQ(f.update_active(p, in), 5u);
    EXPECT_TRUE(f.active(3, 3));
    EXPECT_EQ(f.pass_samples(), 2);
    for (int s = 1; s < 8; ++s) f.add_sample(3, 3, Vec3f(float(s % 3)));
    f.update_active(p, in);
    EXPECT_EQ(f.pass_samples(), kAdaptivePassSamples);
    in.samples_per_pass = 32;  // never below the session's samples per pass
    f.update_active(p, in);
    EXPECT_EQ(f.pass_samples(), 32);
    p.adaptive = false;
    in.samples_per_pass = 3;
    EXPECT_EQ(f.update_active(p, in), 16u);
    EXPECT_EQ(f.pass_samples(), 3);
}

TEST(FilmAdaptive, DoublingsRunToTheirEnd) {
    // Pixels 0..3 are quiet (low priority) but mid-doubling (24 samples drawn): they stay
    // active; of the noisy pixels at 16 samples, the pass starts doublings for the best
    // ones while fewer than a quarter of the open pixels are doubling.
    Film f(16, 1);
    for (int x = 0; x < 16; ++x) {
        const int n = x < 4 ? 24 : 16;
        const float spread = x < 4 ? 0.01f : 1.0f + 0.1f * float(x);
        for (int s = 0; s < n; ++s) f.add_sample(x, 0, Vec3f(1.0f + (s % 2 ? spread : -spread)));
    }
    const FilmParams p = adaptive_params(1e-4f, 8);
    EXPECT_EQ(f.update_active(p), 4u);  // 4 doubling = ceil(16 / 4): nothing new starts
    for (int x = 0; x < 16; ++x) EXPECT_EQ(f.active(x, 0), x < 4) << x;
    for (int x = 0; x < 4; ++x) {
        for (int s = 0; s < 8; ++s) f.add_sample(x, 0, Vec3f(1.0f));  // now at 32
    }
    EXPECT_EQ(f.update_active(p), 4u);  // 4 new doublings, the noisiest (highest x)
    for (int x = 0; x < 16; ++x) EXPECT_EQ(f.active(x, 0), x >= 12) << x;
}

// A film fed in passes that are not a power of two (3 samples while warming up, then the
// film's pass size, each pixel only up to its pass_end() as the tile renderer does): the
// doublings still end on powers of two, and pixels that are not doubling rest.
TEST(FilmAdaptive, DoublingsEndOnPowersOfTwoWhateverThePassSize) {
    constexpr int kW = 16;
    Film f(kW, 1);
    const FilmParams p = adaptive_params(1e-6f, 16);  // nobody stops
    AdaptiveInputs in;
    in.samples_per_pass = 3;
    Pcg32 rng(5);
    size_t resting_passes = 0;
    for (int pass = 0; pass < 60; ++pass) {
        const size_t active = f.update_active(p, in);
        ASSERT_GT(active, 0u);
        ASSERT_EQ(f.open_count(), size_t(kW));
        if (active < f.open_count()) ++resting_passes;
        for (int x = 0; x < kW; ++x) {
            if (!f.active(x, 0)) {
                // At rest only at a power of two.
                const uint32_t n = f.next_sample_index(x, 0);
                EXPECT_EQ(n & (n - 1), 0u) << "pixel " << x << " rests at " << n;
                continue;
            }
            const uint32_t end = f.pass_end(x, 0);
            ASSERT_GT(end, f.next_sample_index(x, 0)) << "pixel " << x;
            for (int s = 0; s < f.pass_samples() && f.next_sample_index(x, 0) < end; ++s)
                f.add_sample(x, 0, Vec3f(1.0f + float(x + 1) * rng.next_float()));
        }
    }
    // Warm-up takes 6 passes (18 samples), then a quarter of the pixels doubling at a time.
    EXPECT_GT(resting_passes, 40u);
    uint32_t most = 0;
    for (int x = 0; x < kW; ++x) most = std::max(most, f.next_sample_index(x, 0));
    EXPECT_GE(most, 64u);
}

TEST(FilmAdaptive, PassEndsWithoutAdaptivityAreOpen) {
    Film f(4, 1);
    for (int s = 0; s < 5; ++s) f.add_sample(0, 0, Vec3f(float(s % 2)));
    f.update_active(FilmParams{});
    EXPECT_EQ(f.pass_end(0, 0), 0xffffffffu);
    FilmParams p = adaptive_params(1e-6f, 2);
    f.update_active(p);
    EXPECT_TRUE(f.active(0, 0));  // 5 samples drawn: a doubling under way, to 8
    EXPECT_EQ(f.pass_end(0, 0), 8u);
    EXPECT_EQ(f.pass_end(1, 0), 0xffffffffu);  // warming up
    p.adaptive = false;
    f.update_active(p);
    EXPECT_EQ(f.pass_end(0, 0), 0xffffffffu);
}

TEST(FilmAdaptive, CappedPixelsAreNeverPicked) {
    Film f(4, 1);
    // Pixel 0 is the noisiest but drew the cap: open without it, never picked with it.
    for (int s = 0; s < 32; ++s) f.add_sample(0, 0, Vec3f(s % 2 ? 0.0f : 10.0f));
    for (int x = 1; x < 4; ++x) {
        for (int s = 0; s < 16; ++s) f.add_sample(x, 0, Vec3f(s % 2 ? 1.0f : 1.5f));
    }
    const FilmParams p = adaptive_params(1e-3f, 4);
    // Pixel 1 shares pixel 0's noise through the 3x3 variance mean; a high cost keeps it
    // from ranking first, so that without the cap pixel 0 is the one picked.
    const float cost[4] = {1.0f, 100.0f, 1.0f, 1.0f};
    AdaptiveInputs in;
    in.cost_per_sample = cost;
    EXPECT_EQ(f.update_active(p, in), 1u);  // a quarter of 4
    EXPECT_TRUE(f.active(0, 0));
    EXPECT_EQ(f.open_count(), 4u);
    in.sample_cap = 32;
    EXPECT_EQ(f.update_active(p, in), 1u);
    EXPECT_FALSE(f.active(0, 0));
    EXPECT_EQ(f.open_count(), 3u);
    in.sample_cap = 16;  // everybody drew it: nothing open, nothing active
    EXPECT_EQ(f.update_active(p, in), 0u);
    EXPECT_EQ(f.open_count(), 0u);
}

TEST(FilmAdaptive, RejectsCostsOfTheWrongSize) {
    Film f(4, 4);
    FilmParams p;
    p.adaptive = true;
    const std::vector<float> cost(15, 1.0f);
    AdaptiveInputs in;
    in.cost_per_sample = cost;
    EXPECT_THROW(f.update_active(p, in), Error);
}

}  // namespace
}  // namespace kdt
