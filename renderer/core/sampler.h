// Deterministic randomness: integer hashing, a PCG32 stream, and a padded, Owen-scrambled
// 2D Sobol sequence keyed on (seed, pixel, sample index) -- never one stream per thread --
// so images are identical for any thread count, tile order or MPI split.
// Depends on the standard library and core/math only.
#pragma once

#include <cstdint>

#include "renderer/core/math.h"

namespace kdt {

/// 64-bit finaliser (murmur3 fmix64); a bijection with good avalanche.
inline uint64_t mix64(uint64_t x) {
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdull;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ull;
    x ^= x >> 33;
    return x;
}

/// Hashes a sequence of 64-bit words into one.
inline uint64_t hash64(uint64_t a) { return mix64(a + 0x9e3779b97f4a7c15ull); }
inline uint64_t hash64(uint64_t a, uint64_t b) {
    return mix64(hash64(a) ^ (b + 0x632be59bd9b4e019ull));
}
inline uint64_t hash64(uint64_t a, uint64_t b, uint64_t c) { return hash64(hash64(a, b), c); }

/// 32 random bits -> float in [0, 1) (24-bit mantissa, never 1).
inline float bits_to_unit_float(uint32_t bits) { return float(bits >> 8) * 0x1p-24f; }

/// O'Neill's PCG32 (XSH RR): a small seeded stream for tests and tools.
class Pcg32 {
public:
    explicit Pcg32(uint64_t seed = 0x853c49e6748fea9bull, uint64_t stream = 0xda3e39cb94b95bdbull);
    uint32_t next_u32();
    /// Uniform in [0, 1).
    float next_float() { return bits_to_unit_float(next_u32()); }
    /// Uniform in [0, bound), bound > 0 (Lemire's rejection-free-ish bounded draw).
    uint32_t next_bounded(uint32_t bound);

private:
    uint64_t state_ = 0;
    uint64_t inc_ = 1;
};

/// The 32-bit generator matrix columns of Sobol dimension `dim` (0 to 3) applied to index.
uint32_t sobol_u32(uint32_t index, int dim);

/// Owen scrambling of the bits of x keyed by seed (Burley 2020, "Practical Hash-based
/// Owen Scrambling", nested uniform scramble via a Laine-Karras style permutation).
uint32_t owen_scramble(uint32_t x, uint32_t seed);

/// Point `index` of a shuffled, Owen-scrambled 2D Sobol sequence keyed by `seed`.
Vec2f sobol_2d(uint32_t index, uint64_t seed);

/// Coordinates 2 and 3 of the 4D Owen-scrambled Sobol point whose coordinates 0 and 1 are
/// sobol_2d(index, seed): the same shuffled index, Sobol dimensions 2 and 3, each scrambled
/// by its own half of seed_upper.
Vec2f sobol_4d_upper(uint32_t index, uint64_t seed, uint64_t seed_upper);

/// The per-sample sampler: every call draws the next dimension of sample `sample_index`
/// of pixel (x, y) for `seed`. Draws 0 and 1 are one 4D Owen-scrambled Sobol point (the
/// integrator's film position and first bounce direction: stratified jointly, not just each
/// pair by itself); draws 2 to kSobolPairs - 1 come from independent padded 2D Sobol
/// sequences; later draws are hashed uniform numbers.
/// Pure function of (seed, pixel, sample index, draw order): no state shared across samples.
class PixelSampler {
public:
    /// Camera + 4 bounces of a BSDF and an environment draw each (path_tracer.cpp).
    static constexpr uint32_t kSobolPairs = 9;

    /// A placeholder (pixel key 0, sample 0), for arrays filled later.
    PixelSampler() = default;
    PixelSampler(uint64_t seed, uint32_t x, uint32_t y, uint32_t sample_index)
        : PixelSampler(pixel_key(seed, x, y), sample_index) {}
    /// The same from key = pixel_key(seed, x, y), which callers may hoist out of a pixel's
    /// sample loop.
    PixelSampler(uint64_t key, uint32_t sample_index) : pixel_key_(key), index_(sample_index) {}

    /// What every sampler of pixel (x, y) for `seed` derives its draws from.
    static uint64_t pixel_key(uint64_t seed, uint32_t x, uint32_t y) {
        return hash64(seed, (uint64_t(y) << 32) | x);
    }

    /// Next 2D sample in [0,1)^2.
    Vec2f next_2d() {
        const uint32_t d = dim_++;
        // pixel_key_ is already well mixed: one finaliser round per draw suffices.
        const uint64_t dim_key = pixel_key_ ^ (uint64_t(d + 1) * 0x9e3779b97f4a7c15ull);
        if (d == 1)  // shares draw 0's shuffled index: coordinates 2 and 3 of its 4D point
            return sobol_4d_upper(index_, mix64(pixel_key_ ^ 0x9e3779b97f4a7c15ull),
                                  mix64(dim_key));
        if (d < kSobolPairs) return sobol_2d(index_, mix64(dim_key));
        const uint64_t h = mix64(dim_key ^ (uint64_t(index_) * 0xd1b54a32d192ed03ull));
        return {bits_to_unit_float(uint32_t(h)), bits_to_unit_float(uint32_t(h >> 32))};
    }
    /// Next 1D sample in [0,1) (consumes one 2D dimension pair).
    float next_1d() { return next_2d().x; }
    /// Number of 2D draws made so far.
    uint32_t dimension() const { return dim_; }

private:
    uint64_t pixel_key_ = 0;
    uint32_t index_ = 0;
    uint32_t dim_ = 0;
};

}  // namespace kdt
