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

// Generator matrices of Sobol dimensions 0 (van der Corput) to 3, one 32-bit column per index
// bit, from the direction numbers of Joe & Kuo 2008 (new-joe-kuo-6.21201): dimension 1 has
// the primitive polynomial x + 1 (s 1, a 0, m 1), dimension 2 x^2 + x + 1 (s 2, a 1, m 1 3),
// dimension 3 x^3 + x + 1 (s 3, a 1, m 1 3 1).
constexpr std::array<uint32_t, 32> make_sobol_matrix(int s, uint32_t a,
                                                     std::array<uint32_t, 3> m0) {
    // m_k = m_{k-s} xor 2^s m_{k-s} xor (xor over j < s with bit s-1-j of a: 2^j m_{k-j});
    // column k (0-based) is m_k << (31 - k).
    std::array<uint32_t, 32> m{};
    for (int k = 0; k < 32; ++k) {
        if (k < s) {
            m[size_t(k)] = m0[size_t(k)];
            continue;
        }
        uint32_t v = m[size_t(k - s)] ^ (m[size_t(k - s)] << s);
        for (int j = 1; j < s; ++j)
            if ((a >> (s - 1 - j)) & 1u) v ^= m[size_t(k - j)] << j;
        m[size_t(k)] = v;
    }
    std::array<uint32_t, 32> col{};
    for (int k = 0; k < 32; ++k) col[size_t(k)] = m[size_t(k)] << (31 - k);
    return col;
}

constexpr std::array<std::array<uint32_t, 32>, 4> make_sobol_matrices() {
    std::array<std::array<uint32_t, 32>, 4> v{};
    for (int i = 0; i < 32; ++i) v[0][size_t(i)] = 1u << (31 - i);
    v[1] = make_sobol_matrix(1, 0, {1, 0, 0});
    v[2] = make_sobol_matrix(2, 1, {1, 3, 0});
    v[3] = make_sobol_matrix(3, 1, {1, 3, 1});
    return v;
}

constexpr auto kSobol = make_sobol_matrices();

// Dimensions 1 to 3 in the bit-reversed domain, by bytes: kSobolReversed[d - 1][k][byte k
// of p] XORed over k is reverse(sobol_d(reverse(p))). Bit j of p is bit 31 - j of
// reverse(p), whose generator column is kSobol[d][31 - j]. Working on reversed values saves
// two of the six bit reversals of sobol_2d (the points are unchanged).
constexpr uint32_t reverse_bits_constexpr(uint32_t x) {
    uint32_t r = 0;
    for (int i = 0; i < 32; ++i) r |= ((x >> i) & 1u) << (31 - i);
    return r;
}

using ReversedTable = std::array<std::array<uint32_t, 256>, 4>;

constexpr ReversedTable make_sobol_reversed_table(int dim) {
    ReversedTable t{};
    for (int byte = 0; byte < 4; ++byte) {
        for (uint32_t v = 0; v < 256; ++v) {
            uint32_t r = 0;
            for (int bit = 0; bit < 8; ++bit) {
                if (v & (1u << bit))
                    r ^= reverse_bits_constexpr(kSobol[size_t(dim)][size_t(31 - (byte * 8 + bit))]);
            }
            t[size_t(byte)][v] = r;
        }
    }
    return t;
}

constexpr std::array<ReversedTable, 3> kSobolReversed = {
    make_sobol_reversed_table(1), make_sobol_reversed_table(2), make_sobol_reversed_table(3)};

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

// reverse(sobol_dim(reverse(p))), dim 1 to 3.
inline uint32_t sobol_reversed(uint32_t p, int dim) {
    const ReversedTable& t = kSobolReversed[size_t(dim - 1)];
    return t[0][p & 0xffu] ^ t[1][(p >> 8) & 0xffu] ^ t[2][(p >> 16) & 0xffu] ^ t[3][p >> 24];
}

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

// The shuffled sample index of sobol_2d(index, seed), bit-reversed: nested_scramble(index,
// ...) without its last reversal.
inline uint32_t shuffled_index_reversed(uint32_t index, uint64_t seed) {
    return laine_karras_permutation(reverse_bits(index), uint32_t(seed) ^ 0x5bd1e995u);
}

}  // namespace

uint32_t sobol_u32(uint32_t index, int dim) {
    return dim == 0 ? reverse_bits(index) : reverse_bits(sobol_reversed(reverse_bits(index), dim));
}

uint32_t owen_scramble(uint32_t x, uint32_t seed) { return nested_scramble(x, seed); }

Vec2f sobol_2d(uint32_t index, uint64_t seed) {
    // Shuffle the sample order (so that padded dimensions decorrelate), then scramble each
    // coordinate with its own seed (Burley 2020, section 4).
    const auto s0 = uint32_t(seed), s1 = uint32_t(seed >> 32);
    const uint32_t shuffled_reversed = shuffled_index_reversed(index, seed);
    // Dimension 0 is the bit reversal, so its Owen scramble needs no reversal at all.
    const uint32_t x = reverse_bits(laine_karras_permutation(reverse_bits(shuffled_reversed), s0));
    // Dimension 1 scrambled: reverse(LK(reverse(sobol1(shuffled)))), the inner part tabled.
    const uint32_t y =
        reverse_bits(laine_karras_permutation(sobol_reversed(shuffled_reversed, 1), s1));
    return {bits_to_unit_float(x), bits_to_unit_float(y)};
}

Vec2f sobol_4d_upper(uint32_t index, uint64_t seed, uint64_t seed_upper) {
    const uint32_t shuffled_reversed = shuffled_index_reversed(index, seed);
    const auto s2 = uint32_t(seed_upper), s3 = uint32_t(seed_upper >> 32);
    const uint32_t x =
        reverse_bits(laine_karras_permutation(sobol_reversed(shuffled_reversed, 2), s2));
    const uint32_t y =
        reverse_bits(laine_karras_permutation(sobol_reversed(shuffled_reversed, 3), s3));
    return {bits_to_unit_float(x), bits_to_unit_float(y)};
}

}  // namespace kdt
