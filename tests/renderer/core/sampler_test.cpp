#include "renderer/core/sampler.h"

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
    // Dimension pairs 0 and 1 of the same pixel must not be the same sequence.
    double cov = 0.0;
    const int n = 4096;
    for (int i = 0; i < n; ++i) {
        PixelSampler s(3, 1, 1, uint32_t(i));
        const float a = s.next_2d().x, b = s.next_2d().x;
        cov += (a - 0.5) * (b - 0.5);
    }
    EXPECT_LT(std::abs(cov / n), 0.01);
}

}  // namespace
}  // namespace kdt
