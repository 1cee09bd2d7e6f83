#include "renderer/core/sampler.h"

#include <array>
#include <set>
#include <vector>

#include <gtest/gtest.h>

namespace kdt {
namespace {

TEST(Sampler, PcgReplaysAndIsUniform) {
    Pcg32 a(42, 7), b(42, 7), c(43, 7);
    bool differs = false;
    double sum = 0.0;
    for (int i = 0; i < 10000; ++i) {
        const uint32_t x = a.next_u32();
        EXPECT_EQ(x, b.next_u32());
        differs |= x != c.next_u32();
        sum += bits_to_unit_float(x);
    }
    EXPECT_TRUE(differs);
    EXPECT_NEAR(sum / 10000.0, 0.5, 0.01);
    Pcg32 d(1);
    for (int i = 0; i < 1000; ++i) EXPECT_LT(d.next_bounded(7), 7u);
}

TEST(Sampler, SobolFirstPointsAreA02Net) {
    // Any aligned block of 2^k points of the (scrambled, shuffled) 2D Sobol sequence puts
    // exactly one point in every elementary interval of area 2^-k.
    for (uint64_t seed : {0ull, 1ull, 12345ull}) {
        for (int k : {4, 6, 8}) {
            const int n = 1 << k;
            for (int xbits = 0; xbits <= k; ++xbits) {
                const int nx = 1 << xbits, ny = 1 << (k - xbits);
                std::vector<int> cells(size_t(n), 0);
                for (int i = 0; i < n; ++i) {
                    const Vec2f p = sobol_2d(uint32_t(i), seed);
                    ASSERT_GE(p.x, 0.0f);
                    ASSERT_LT(p.x, 1.0f);
                    ASSERT_GE(p.y, 0.0f);
                    ASSERT_LT(p.y, 1.0f);
                    const int cx = int(p.x * float(nx)), cy = int(p.y * float(ny));
                    ++cells[size_t(cy * nx + cx)];
                }
                for (int c : cells)
                    ASSERT_EQ(c, 1) << "seed " << seed << " k " << k << " xbits " << xbits;
            }
        }
    }
}

// The definition sobol_2d() implements, written out bit by bit: shuffle the index by a
// nested uniform scramble, take Sobol dimensions 0 and 1 of it (generator matrices from
// the direction numbers), Owen-scramble each coordinate with its own seed.
uint32_t reverse_reference(uint32_t x) {
    uint32_t r = 0;
    for (int i = 0; i < 32; ++i) r |= ((x >> i) & 1u) << (31 - i);
    return r;
}

uint32_t laine_karras_reference(uint32_t x, uint32_t seed) {
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

uint32_t scramble_reference(uint32_t x, uint32_t seed) {
    return reverse_reference(laine_karras_reference(reverse_reference(x), seed));
}

uint32_t sobol1_reference(uint32_t index) {
    uint32_t r = 0, m = 1;
    for (int k = 1; k <= 32; ++k) {
        if (k > 1) m = (m << 1) ^ m;
        if (index & (1u << (k - 1))) r ^= m << (32 - k);
    }
    return r;
}

TEST(Sampler, Sobol2dMatchesItsBitByBitDefinition) {
    Pcg32 rng(5);
    for (int i = 0; i < 20000; ++i) {
        const uint32_t index = i < 10000 ? uint32_t(i) : rng.next_u32();
        const uint64_t seed = (uint64_t(rng.next_u32()) << 32) | rng.next_u32();
        const auto s0 = uint32_t(seed), s1 = uint32_t(seed >> 32);
        const uint32_t shuffled = scramble_reference(index, s0 ^ 0x5bd1e995u);
        const uint32_t x = scramble_reference(reverse_reference(shuffled), s0);
        const uint32_t y = scramble_reference(sobol1_reference(shuffled), s1);
        const Vec2f p = sobol_2d(index, seed);
        ASSERT_EQ(p.x, bits_to_unit_float(x)) << "index " << index << " seed " << seed;
        ASSERT_EQ(p.y, bits_to_unit_float(y)) << "index " << index << " seed " << seed;
        ASSERT_EQ(sobol_u32(index, 0), reverse_reference(index));
        ASSERT_EQ(sobol_u32(index, 1), sobol1_reference(index));
        ASSERT_EQ(owen_scramble(index, s1), scramble_reference(index, s1));
    }
}

// Sobol dimensions 2 and 3 from Joe & Kuo's direction numbers (new-joe-kuo-6.21201: s 2,
// a 1, m 1 3 and s 3, a 1, m 1 3 1), by the recurrence written out for each.
uint32_t sobol23_reference(uint32_t index, int dim) {
    uint32_t m[33] = {0, 1, 3, dim == 2 ? 0u : 1u};
    const int s = dim == 2 ? 2 : 3;
    for (int k = s + 1; k <= 32; ++k) {
        // x^2 + x + 1: m_k = 2 m_{k-1} ^ 4 m_{k-2} ^ m_{k-2}; x^3 + x + 1: m_k = 4 m_{k-2} ^
        // 8 m_{k-3} ^ m_{k-3}.
        m[k] = dim == 2 ? (m[k - 1] << 1) ^ (m[k - 2] << 2) ^ m[k - 2]
                        : (m[k - 2] << 2) ^ (m[k - 3] << 3) ^ m[k - 3];
    }
    uint32_t r = 0;
    for (int k = 1; k <= 32; ++k)
        if (index & (1u << (k - 1))) r ^= m[k] << (32 - k);
    return r;
}

TEST(Sampler, Sobol4dUpperMatchesItsBitByBitDefinition) {
    // The first direction numbers, as published.
    const uint32_t m2[6] = {1, 3, 3, 9, 29, 23}, m3[6] = {1, 3, 1, 5, 31, 29};
    for (int k = 0; k < 6; ++k) {
        EXPECT_EQ(sobol_u32(1u << k, 2), m2[k] << (31 - k));
        EXPECT_EQ(sobol_u32(1u << k, 3), m3[k] << (31 - k));
    }
    Pcg32 rng(6);
    for (int i = 0; i < 20000; ++i) {
        const uint32_t index = i < 10000 ? uint32_t(i) : rng.next_u32();
        const uint64_t seed = (uint64_t(rng.next_u32()) << 32) | rng.next_u32();
        const uint64_t upper = (uint64_t(rng.next_u32()) << 32) | rng.next_u32();
        // The same shuffled index as sobol_2d(index, seed).
        const uint32_t shuffled = scramble_reference(index, uint32_t(seed) ^ 0x5bd1e995u);
        const uint32_t z = scramble_reference(sobol23_reference(shuffled, 2), uint32_t(upper));
        const uint32_t w =
            scramble_reference(sobol23_reference(shuffled, 3), uint32_t(upper >> 32));
        const Vec2f p = sobol_4d_upper(index, seed, upper);
        ASSERT_EQ(p.x, bits_to_unit_float(z)) << "index " << index;
        ASSERT_EQ(p.y, bits_to_unit_float(w)) << "index " << index;
        ASSERT_EQ(sobol_u32(index, 2), sobol23_reference(index, 2));
        ASSERT_EQ(sobol_u32(index, 3), sobol23_reference(index, 3));
    }
}

// Points of [0,1)^4 whose 4 coordinates are the first two draws of a pixel's samples.
std::vector<std::array<float, 4>> first_two_draws(uint64_t seed, int n, int first_draw) {
    std::vector<std::array<float, 4>> pts;
    for (int i = 0; i < n; ++i) {
        PixelSampler s(seed, 5, 7, uint32_t(i));
        for (int d = 0; d < first_draw; ++d) s.next_2d();
        const Vec2f a = s.next_2d(), b = s.next_2d();
        pts.push_back({a.x, a.y, b.x, b.y});
    }
    return pts;
}

// Whether every elementary interval of volume 2^(t - m) (2^d_j cells along coordinate j,
// sum d_j = m - t) holds exactly 2^t of the 2^m points: a (t, m, 4)-net in base 2.
bool is_net(const std::vector<std::array<float, 4>>& pts, int m, int t) {
    const int sum = m - t;
    for (int d0 = 0; d0 <= sum; ++d0) {
        for (int d1 = 0; d0 + d1 <= sum; ++d1) {
            for (int d2 = 0; d0 + d1 + d2 <= sum; ++d2) {
                const int d[4] = {d0, d1, d2, sum - d0 - d1 - d2};
                std::vector<int> cells(size_t(1) << sum, 0);
                for (const auto& p : pts) {
                    size_t cell = 0;
                    for (int j = 0; j < 4; ++j)
                        cell = (cell << d[j]) | size_t(p[size_t(j)] * float(1 << d[j]));
                    ++cells[cell];
                }
                for (int c : cells)
                    if (c != 1 << t) return false;
            }
        }
    }
    return true;
}

TEST(Sampler, FilmPositionAndFirstBounceAreOne4dSobolPoint) {
    // Draws 0 and 1 (film position, first bounce direction) are stratified jointly: the
    // first 2^m samples form a (t, m, 4)-net with Sobol's t for dimensions 0-3 (2 at m 4 and
    // 6, 3 at m 8). Independently padded pairs (draws 2 and 3) are not.
    for (uint64_t seed : {0ull, 1ull, 77ull}) {
        EXPECT_TRUE(is_net(first_two_draws(seed, 16, 0), 4, 2)) << seed;
        EXPECT_TRUE(is_net(first_two_draws(seed, 64, 0), 6, 2)) << seed;
        EXPECT_TRUE(is_net(first_two_draws(seed, 256, 0), 8, 3)) << seed;
        EXPECT_FALSE(is_net(first_two_draws(seed, 256, 2), 8, 3)) << seed;
    }
}

TEST(Sampler, HoistedPixelKeyGivesTheSameDraws) {
    PixelSampler a(9, 3, 4, 17), b(PixelSampler::pixel_key(9, 3, 4), 17);
    for (int i = 0; i < 12; ++i) EXPECT_EQ(a.next_2d(), b.next_2d());
}

TEST(Sampler, ScramblingDependsOnSeed) {
    EXPECT_NE(sobol_2d(3, 1).x, sobol_2d(3, 2).x);
    EXPECT_EQ(sobol_2d(3, 1).x, sobol_2d(3, 1).x);
    // Owen scrambling is a bijection on 32-bit values: check on a small range that the top
    // 8 bits of 256 consecutive values stay distinct.
    std::set<uint32_t> tops;
    for (uint32_t i = 0; i < 256; ++i) tops.insert(owen_scramble(i << 24, 99u) >> 24);
    EXPECT_EQ(tops.size(), 256u);
}

TEST(Sampler, PixelSamplerIsAPureFunctionOfItsKey) {
    PixelSampler a(7, 10, 20, 5), b(7, 10, 20, 5), c(7, 10, 20, 6), d(7, 11, 20, 5);
    for (int i = 0; i < 40; ++i) {
        const Vec2f va = a.next_2d();
        EXPECT_EQ(va, b.next_2d());
        EXPECT_NE(va, c.next_2d());
        EXPECT_NE(va, d.next_2d());
    }
    EXPECT_EQ(a.dimension(), 40u);
}

TEST(Sampler, PaddedDimensionsAreUncorrelated) {
    // Padded dimension pairs (draws 1 and 2) of the same pixel must not be the same sequence.
    double cov = 0.0;
    const int n = 4096;
    for (int i = 0; i < n; ++i) {
        PixelSampler s(3, 1, 1, uint32_t(i));
        s.next_2d();
        const float a = s.next_2d().x, b = s.next_2d().x;
        cov += (a - 0.5) * (b - 0.5);
    }
    EXPECT_LT(std::abs(cov / n), 0.01);
}

}  // namespace
}  // namespace kdt
