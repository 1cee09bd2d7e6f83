#include "renderer/core/sampler.h"

#include <array>

namespace kdt {

Pcg32::Pcg32(uint64_t seed, uint64_t stream) {
    inc_ = (stream << 1u) | 1u;
    state_ = 0;
    next_u32();
    state_ += seed;
    next_u32();
}

uint32_t Pcg32::next_u32() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ull + inc_;
    const auto xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
    const auto rot = uint32_t(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
}

uint32_t Pcg32::next_bounded(uint32_t bound) {
    // Multiply-shift with rejection of the biased low range (Lemire 2019).
    uint64_t m = uint64_t(next_u32()) * bound;
    auto low = uint32_t(m);
    if (low < bound) {
        const uint32_t threshold = (0u - bound) % bound;
        while (low < threshold) {
            m = uint64_t(next_u32()) * bound;
            low = uint32_t(m);
        }
    }
    return uint32_t(m >> 32);
}

namespace {

// Generator matrices of Sobol dimensions 0 (van der Corput) and 1 (primitive polynomial
// x + 1, initial direction number m1 = 1; Joe & Kuo 2008), one 32-bit column per index bit.
constexpr std::array<std::array<uint32_t, 32>, 2> make_sobol_matrices() {
    std::array<std::array<uint32_t, 32>, 2> v{};
    for (int i = 0; i < 32; ++i) v[0][i] = 1u << (31 - i);
    // m_k = 2 m_{k-1} xor m_{k-1}; v_k = m_k << (32 - k) with k 1-based.
    uint32_t m = 1;
    for (int k = 1; k <= 32; ++k) {
        if (k > 1) m = (m << 1) ^ m;
        v[1][k - 1] = m << (32 - k);
    }
    return v;
}

constexpr auto kSobol = make_sobol_matrices();

// Dimension 1 in the bit-reversed domain, by bytes: kSobol1Reversed[k][byte k of p] XORed
// over k is reverse(sobol1(reverse(p))). Bit j of p is bit 31 - j of reverse(p), whose
// generator column is kSobol[1][31 - j]. Working on reversed values saves two of the six
// bit reversals of sobol_2d (the points are unchanged).
constexpr uint32_t reverse_bits_constexpr(uint32_t x) {
    uint32_t r = 0;
    for (int i = 0; i < 32; ++i) r |= ((x >> i) & 1u) << (31 - i);
    return r;
}

constexpr std::array<std::array<uint32_t, 256>, 4> make_sobol1_reversed_tables() {
    std::array<std::array<uint32_t, 256>, 4> t{};
    for (int byte = 0; byte < 4; ++byte) {
        for (uint32_t v = 0; v < 256; ++v) {
            uint32_t r = 0;
            for (int bit = 0; bit < 8; ++bit) {
                if (v & (1u << bit))
                    r ^= reverse_bits_constexpr(kSobol[1][size_t(31 - (byte * 8 + bit))]);
            }
            t[size_t(byte)][v] = r;
        }
    }
    return t;
}

constexpr auto kSobol1Reversed = make_sobol1_reversed_tables();

// Bit reversal by bytes.
constexpr std::array<uint8_t, 256> make_reverse8_table() {
    std::array<uint8_t, 256> t{};
    for (uint32_t v = 0; v < 256; ++v) t[v] = uint8_t(reverse_bits_constexpr(v) >> 24);
    return t;
}

constexpr auto kReverse8 = make_reverse8_table();

inline uint32_t reverse_bits(uint32_t x) {
    return (uint32_t(kReverse8[x & 0xffu]) << 24) | (uint32_t(kReverse8[(x >> 8) & 0xffu]) << 16) |
           (uint32_t(kReverse8[(x >> 16) & 0xffu]) << 8) | kReverse8[x >> 24];
}

// reverse(sobol1(reverse(p))).
inline uint32_t sobol1_reversed(uint32_t p) {
    return kSobol1Reversed[0][p & 0xffu] ^ kSobol1Reversed[1][(p >> 8) & 0xffu] ^
           kSobol1Reversed[2][(p >> 16) & 0xffu] ^ kSobol1Reversed[3][p >> 24];
}

inline uint32_t sobol1(uint32_t i) { return reverse_bits(sobol1_reversed(reverse_bits(i))); }

// A hash that only propagates bits upwards: applied to bit-reversed values it flips each
// bit depending only on the more significant bits, which is an Owen scramble
// (Laine & Karras 2011; constants from Burley 2020).
inline uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

inline uint32_t nested_scramble(uint32_t x, uint32_t seed) {
    return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

}  // namespace

uint32_t sobol_u32(uint32_t index, int dim) {
    return dim == 0 ? reverse_bits(index) : sobol1(index);
}

uint32_t owen_scramble(uint32_t x, uint32_t seed) { return nested_scramble(x, seed); }

Vec2f sobol_2d(uint32_t index, uint64_t seed) {
    // Shuffle the sample order (so that padded dimensions decorrelate), then scramble each
    // coordinate with its own seed (Burley 2020, section 4).
    const auto s0 = uint32_t(seed), s1 = uint32_t(seed >> 32);
    // The shuffled index, bit-reversed: nested_scramble(index, ...) without its last reversal.
    const uint32_t shuffled_reversed =
        laine_karras_permutation(reverse_bits(index), s0 ^ 0x5bd1e995u);
    // Dimension 0 is the bit reversal, so its Owen scramble needs no reversal at all.
    const uint32_t x = reverse_bits(laine_karras_permutation(reverse_bits(shuffled_reversed), s0));
    // Dimension 1 scrambled: reverse(LK(reverse(sobol1(shuffled)))), the inner part tabled.
    const uint32_t y =
        reverse_bits(laine_karras_permutation(sobol1_reversed(shuffled_reversed), s1));
    return {bits_to_unit_float(x), bits_to_unit_float(y)};
}

}  // namespace kdt
