// Whole-line ASCII scanning by byte classes: masks of a line's digits, blanks, dots, minus
// signs and newlines give every token's span by bit arithmetic, so a line's values convert
// independently. SSE2 at least; AVX-512 VBMI gathers a line's digits in one permute.
// Internal to renderer/io/ply_*; depends on geometry (vector types).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "renderer/core/error.h"
#include "renderer/geometry/mesh.h"
#include "renderer/io/ply_numbers.h"
#include "renderer/io/ply_simd.h"

namespace kdt::ply {

// Whole-line parsing by byte classes. One pass over the 64 bytes at a line start gives bit
// masks of its digits, blanks, dots, minus signs and newlines; every token's start and end
// then follow by bit arithmetic, so the tokens of a line are converted independently
// instead of each one waiting for the end of the one before. Lines longer than 64 bytes,
// exponents, '+' signs and anything else unusual go to the per-token parsers.

struct LineClasses {
    uint64_t digit = 0, blank = 0, dot = 0, minus = 0, newline = 0;
};

#if defined(__SSE2__)
constexpr bool kHaveLineClasses = true;

// Bit i of each mask describes p[i]; reads 64 bytes at p (the Input padding keeps them
// inside the buffer).
[[gnu::always_inline]] inline LineClasses classify_line(const char* p) {
    LineClasses c;
#if defined(__AVX512BW__)
    const __m512i x = _mm512_loadu_si512(p);
    c.digit =
        _mm512_cmplt_epu8_mask(_mm512_sub_epi8(x, _mm512_set1_epi8('0')), _mm512_set1_epi8(10));
    c.blank = _mm512_cmpeq_epi8_mask(x, _mm512_set1_epi8(' ')) |
              _mm512_cmpeq_epi8_mask(x, _mm512_set1_epi8('\t')) |
              _mm512_cmpeq_epi8_mask(x, _mm512_set1_epi8('\r'));
    c.dot = _mm512_cmpeq_epi8_mask(x, _mm512_set1_epi8('.'));
    c.minus = _mm512_cmpeq_epi8_mask(x, _mm512_set1_epi8('-'));
    c.newline = _mm512_cmpeq_epi8_mask(x, _mm512_set1_epi8('\n'));
#else
    for (int k = 0; k < 4; ++k) {
        const __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 16 * k));
        const __m128i t = _mm_sub_epi8(x, _mm_set1_epi8('0'));
        auto bits = [k](__m128i m) { return uint64_t(uint32_t(_mm_movemask_epi8(m))) << (16 * k); };
        c.digit |= bits(_mm_cmpeq_epi8(_mm_min_epu8(t, _mm_set1_epi8(9)), t));
        c.blank |= bits(_mm_or_si128(_mm_or_si128(_mm_cmpeq_epi8(x, _mm_set1_epi8(' ')),
                                                  _mm_cmpeq_epi8(x, _mm_set1_epi8('\t'))),
                                     _mm_cmpeq_epi8(x, _mm_set1_epi8('\r'))));
        c.dot |= bits(_mm_cmpeq_epi8(x, _mm_set1_epi8('.')));
        c.minus |= bits(_mm_cmpeq_epi8(x, _mm_set1_epi8('-')));
        c.newline |= bits(_mm_cmpeq_epi8(x, _mm_set1_epi8('\n')));
    }
#endif
    return c;
}
#else
constexpr bool kHaveLineClasses = false;
inline LineClasses classify_line(const char*) { return {}; }
#endif

// Length of the line at p (bytes before its '\n'), when the '\n' lies within the 64 classified
// bytes and before e; else -1.
[[gnu::always_inline]] inline int line_length(const LineClasses& c, const char* p, const char* e) {
    uint64_t nl = c.newline;
    if (e - p < 64) nl &= (uint64_t(1) << (e - p)) - 1;
    return nl ? __builtin_ctzll(nl) : -1;
}

// Value of the first n bytes of x (0 < n <= 8, all digits, first digit in the low byte), by
// multiply-shift as in digits8.
[[gnu::always_inline]] inline uint64_t digits_word_value(uint64_t x, int n) {
    uint64_t d = (x & 0x0f0f0f0f0f0f0f0full) << (8 * (8 - n));
    d = (d * 10 + (d >> 8)) & 0x00ff00ff00ff00ffull;
    d = (d * 100 + (d >> 16)) & 0x0000ffff0000ffffull;
    d = (d * 10000 + (d >> 32)) & 0xffffffffull;
    return d;
}

// Value of the n decimal digits at q (0 <= n <= 8). Loads 8 bytes at q when n > 0.
[[gnu::always_inline]] inline uint64_t digits_value(const char* q, int n) {
    if (n == 0) return 0;
    uint64_t x;
    std::memcpy(&x, q, 8);
    return digits_word_value(x, n);
}

#if defined(__SSSE3__) && defined(__SSE4_1__)
// Value of the `digits` decimal digits (1 to 16) in the 16 bytes at q, skipping the byte at
// `dot` (127 when there is none): one shuffle right-aligns the digits without the dot, then
// multiply-adds combine pairs, quads and octets (Lemire's SIMD digit parsing). No branch, so
// no misprediction however the digit counts vary from token to token.
[[gnu::always_inline]] inline uint64_t digits16_value(const char* q, int digits, int dot) {
    const __m128i x =
        _mm_sub_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(q)), _mm_set1_epi8('0'));
    const __m128i iota = _mm_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    // Output byte i takes digit i - (16 - digits), one byte further on from the dot.
    __m128i src = _mm_sub_epi8(iota, _mm_set1_epi8(char(16 - digits)));
    src = _mm_sub_epi8(src, _mm_cmpgt_epi8(src, _mm_set1_epi8(char(dot - 1))));
    src = _mm_or_si128(src, _mm_cmpgt_epi8(_mm_setzero_si128(), src));  // leading zeros
    __m128i d = _mm_shuffle_epi8(x, src);
    d = _mm_maddubs_epi16(d, _mm_setr_epi8(10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1));
    d = _mm_madd_epi16(d, _mm_setr_epi16(100, 1, 100, 1, 100, 1, 100, 1));
    d = _mm_packus_epi32(d, d);
    d = _mm_madd_epi16(d, _mm_setr_epi16(10000, 1, 10000, 1, 10000, 1, 10000, 1));
    return uint64_t(uint32_t(_mm_cvtsi128_si32(d))) * 100000000u +
           uint32_t(_mm_extract_epi32(d, 1));
}

// The token of n bytes at t, made of digits, dots and minus signs only (`dots` and `minus`
// mark them, bit i for t[i]): a plain decimal "-ddd.ddd" of at most 16 bytes after the sign is
// m / 10^k with m <= 2^53 (checked) and k <= 15, which Clinger's fast path converts exactly
// (decimal_to_real). False for anything else, which the caller hands to parse_real.
template <typename T>
[[gnu::always_inline]] inline bool parse_plain_decimal(const char* t, int n, uint64_t dots,
                                                       uint64_t minus, T& out) {
    if (minus > 1 || (dots & (dots - 1))) return false;
    const int a = int(minus);  // the sign as a number, not a branch: signs are random
    const int body = n - a;
    const int dot = dots ? __builtin_ctzll(dots) - a : 127;
    const int digits = body - (dots != 0);
    if (digits == 0 || body > 16) return false;
    const uint64_t m = digits16_value(t + a, digits, dot);
    if (m > (uint64_t(1) << 53)) return false;
    return decimal_to_real(double(m), dots ? dot + 1 - body : 0, a != 0, out);
}
#else
// The token of n bytes at t, made of digits, dots and minus signs only (`dots` and `minus`
// mark them, bit i for t[i]): a plain decimal "-ddd.ddd" with up to 8 digits on either side
// of the dot is m / 10^k with m < 10^16 < 2^53 and k <= 8, which Clinger's fast path converts
// exactly (decimal_to_real). False for anything else, which the caller hands to parse_real.
template <typename T>
[[gnu::always_inline]] inline bool parse_plain_decimal(const char* t, int n, uint64_t dots,
                                                       uint64_t minus, T& out) {
    if (minus > 1) return false;
    const int a = int(minus);
    int int_digits = n - a, frac_digits = 0;
    if (dots) {
        if (dots & (dots - 1)) return false;
        const int dot = __builtin_ctzll(dots);
        int_digits = dot - a;
        frac_digits = n - dot - 1;
    }
    if (int_digits + frac_digits == 0 || int_digits > 8 || frac_digits > 8) return false;
    const uint64_t m = digits_value(t + a, int_digits) * kPow10Int[frac_digits] +
                       digits_value(t + a + int_digits + 1, frac_digits);
    return decimal_to_real(double(m), -frac_digits, a != 0, out);
}
#endif

inline uint64_t low_bits(int n) { return n >= 64 ? ~uint64_t(0) : (uint64_t(1) << n) - 1; }

// Counts '\n' in [b, e).
inline uint64_t count_newlines(const char* b, const char* e) {
    uint64_t n = 0;
    if constexpr (kHaveLineClasses) {
        // classify_line reads 64 bytes: stop one block early and count the rest bytewise.
        for (; e - b >= 64; b += 64) n += uint64_t(__builtin_popcountll(classify_line(b).newline));
    }
    return n + uint64_t(std::count(b, e, '\n'));
}

// The line of len bytes at p (len > 0, its newline at p[len]), whose byte classes c holds
// with bit 0 for p[0]: "x y z" as plain floats into pos. False for anything else (the caller
// then parses the line token by token).
[[gnu::always_inline]] inline bool xyz_from_classes(const LineClasses& c, const char* p, int len,
                                                    Vec3f& pos) {
    const uint64_t tok = low_bits(len) & ~c.blank;
    if (tok & ~(c.digit | c.dot | c.minus)) return false;
    uint64_t starts = tok & ~(tok << 1);
    uint64_t ends = tok & ~(tok >> 1);  // last byte of each token
    if (__builtin_popcountll(starts) != 3) return false;
    const char* le = p + len;
    int s[3], n[3];
    for (int k = 0; k < 3; ++k) {
        s[k] = __builtin_ctzll(starts);
        n[k] = __builtin_ctzll(ends) - s[k] + 1;
        starts &= starts - 1;
        ends &= ends - 1;
    }
    // f[] stays in registers: only the rare from_chars path writes through memory (a float
    // array in memory read back as a vector would stall store forwarding every line).
    float f[3];
    for (int k = 0; k < 3; ++k) {
        const uint64_t m = low_bits(n[k]);
        const char* t = p + s[k];
        if (!parse_plain_decimal(t, n[k], (c.dot >> s[k]) & m, (c.minus >> s[k]) & m, f[k])) {
            float slow;
            if (!parse_real(t, le, slow)) return false;
            f[k] = slow;
        }
    }
    pos = Vec3f(f[0], f[1], f[2]);
    return true;
}

// The token spans of a face line "3 a b c" of len bytes at p (byte classes c, bit 0 for
// p[0]): each index's first byte s[k] and length n[k], all digits and at most 8 of them.
// False for any other line.
[[gnu::always_inline]] inline bool triangle_tokens(const LineClasses& c, const char* p, int len,
                                                   int* s, int* n) {
    const uint64_t tok = low_bits(len) & ~c.blank;
    if (tok & ~c.digit) return false;
    uint64_t starts = tok & ~(tok << 1);
    uint64_t ends = tok & ~(tok >> 1);  // last byte of each token
    if (__builtin_popcountll(starts) != 4 || (starts & -starts) != (ends & -ends) ||
        p[__builtin_ctzll(starts)] != '3')
        return false;
    starts &= starts - 1;
    ends &= ends - 1;
    for (int k = 0; k < 3; ++k) {
        s[k] = __builtin_ctzll(starts);
        n[k] = __builtin_ctzll(ends) - s[k] + 1;
        starts &= starts - 1;
        ends &= ends - 1;
    }
    return n[0] <= 8 && n[1] <= 8 && n[2] <= 8;
}

// Same as xyz_from_classes for a face line "3 a b c" with indices of up to 8 digits.
[[gnu::always_inline]] inline bool triangle_from_classes(const LineClasses& c, const char* p,
                                                         int len, int64_t* idx) {
    int s[3], n[3];
    if (!triangle_tokens(c, p, len, s, n)) return false;
    for (int k = 0; k < 3; ++k) idx[k] = int64_t(digits_value(p + s[k], n[k]));
    return true;
}

#if defined(__AVX512VBMI__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
#define KDT_PLY_VBMI 1

// The 64 bytes at p less '0': digit values for the vbmi paths below.
[[gnu::always_inline]] inline __m512i window_digits(const char* p) {
    return _mm512_sub_epi8(_mm512_loadu_si512(p), _mm512_set1_epi8('0'));
}

// Byte v in every byte of a 64-bit lane.
inline long long bytes8(int v) { return (long long)(uint64_t(uint8_t(v)) * 0x0101010101010101ull); }

// Bytes 0..7 in every 64-bit lane, and 0..15 in every 128-bit lane.
inline __m512i iota8() { return _mm512_set1_epi64(0x0706050403020100ll); }
inline __m512i iota16() {
    return _mm512_set4_epi64(0x0f0e0d0c0b0a0908ll, 0x0706050403020100ll, 0x0f0e0d0c0b0a0908ll,
                             0x0706050403020100ll);
}

// Pairs, quads and octets of digit bytes combined by multiply-adds: each 64-bit lane of the
// result holds the value of its 8 digit bytes (first byte most significant).
[[gnu::always_inline]] inline __m512i octets_value(__m512i d) {
    d = _mm512_maddubs_epi16(d, _mm512_set1_epi16(0x010a));   // bytes (10, 1)
    d = _mm512_madd_epi16(d, _mm512_set1_epi32(0x00010064));  // words (100, 1)
    return _mm512_add_epi64(_mm512_mul_epu32(d, _mm512_set1_epi64(10000)),
                            _mm512_srli_epi64(d, 32));
}

// The face line "3 a b c" of len bytes at `off` in the window whose digit values are wd and
// whose classes (shifted to the line) are c: the three indices (up to 8 digits) gathered by
// one byte permute and converted together.
[[gnu::always_inline]] inline bool triangle_vbmi(const LineClasses& c, __m512i wd, int off,
                                                 const char* p, int len, int64_t* idx) {
    int s[3], n[3];
    if (!triangle_tokens(c, p, len, s, n)) return false;
    // Lane k takes the 8 bytes ending at index k's last digit, the bytes before it zeroed.
    const __m512i base =
        _mm512_set_epi64(0, 0, 0, 0, 0, bytes8(off + s[2] + n[2] - 8),
                         bytes8(off + s[1] + n[1] - 8), bytes8(off + s[0] + n[0] - 8));
    const __m512i lead =
        _mm512_set_epi64(-1, -1, -1, -1, -1, bytes8(8 - n[2]), bytes8(8 - n[1]), bytes8(8 - n[0]));
    const __mmask64 keep = _mm512_cmpge_epu8_mask(iota8(), lead);
    const __m512i d = _mm512_maskz_permutexvar_epi8(keep, _mm512_add_epi8(base, iota8()), wd);
    alignas(64) uint64_t v[8];
    _mm512_store_si512(v, octets_value(d));
    idx[0] = int64_t(v[0]);
    idx[1] = int64_t(v[1]);
    idx[2] = int64_t(v[2]);
    return true;
}

constexpr double kInvPow10Lo[8] = {1e0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7};
constexpr double kInvPow10Hi[8] = {1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15};

// The vertex line "x y z" of len bytes at `off` in the window (see triangle_vbmi): plain
// decimals of at most 16 bytes after the sign, their digits gathered without the dot into
// one 128-bit lane each, converted together, then scaled and rounded to float as
// decimal_to_real does. Lines where a value lies near a float midpoint (or anything
// unusual) return false and take the scalar path, which decides those exactly.
[[gnu::always_inline]] inline bool xyz_vbmi(const LineClasses& c, __m512i wd, int off, int len,
                                            Vec3f& pos) {
    const uint64_t tok = low_bits(len) & ~c.blank;
    if (tok & ~(c.digit | c.dot | c.minus)) return false;
    uint64_t starts = tok & ~(tok << 1);
    uint64_t ends = tok & ~(tok >> 1);
    if (__builtin_popcountll(starts) != 3) return false;
    long long base[3], lead[3], after[3], scale[3];
    int sign[3];
    for (int k = 0; k < 3; ++k) {
        const int s = __builtin_ctzll(starts);
        const int n = __builtin_ctzll(ends) - s + 1;
        starts &= starts - 1;
        ends &= ends - 1;
        const uint64_t in = low_bits(n);
        const uint64_t minus = (c.minus >> s) & in, dots = (c.dot >> s) & in;
        if (minus > 1 || (dots & (dots - 1))) return false;
        const int a = int(minus);
        const int body = n - a;
        const int digits = body - (dots != 0);
        if (digits == 0 || body > 16) return false;
        const int dot = dots ? __builtin_ctzll(dots) - a : 64;
        // Output byte j (of 16) takes byte j - (16 - digits) of the body, one further on from
        // the dot; bytes j < 16 - digits are zero.
        base[k] = bytes8(off + s + a - (16 - digits));
        lead[k] = bytes8(16 - digits);
        after[k] = bytes8(std::min(dot + 16 - digits, 255));
        scale[k] = dots ? body - dot - 1 : 0;
        sign[k] = a;
    }
    const __m512i vbase =
        _mm512_set_epi64(0, 0, base[2], base[2], base[1], base[1], base[0], base[0]);
    const __m512i vlead =
        _mm512_set_epi64(-1, -1, lead[2], lead[2], lead[1], lead[1], lead[0], lead[0]);
    const __m512i vafter =
        _mm512_set_epi64(-1, -1, after[2], after[2], after[1], after[1], after[0], after[0]);
    const __mmask64 keep = _mm512_cmpge_epu8_mask(iota16(), vlead);
    const __mmask64 past_dot = _mm512_cmpge_epu8_mask(iota16(), vafter);
    __m512i ctrl = _mm512_add_epi8(vbase, iota16());
    ctrl = _mm512_mask_add_epi8(ctrl, past_dot, ctrl, _mm512_set1_epi8(1));
    const __m512i oct = octets_value(_mm512_maskz_permutexvar_epi8(keep, ctrl, wd));
    // Even 64-bit lanes: high octet * 10^8 + low octet = the token's digits as an integer.
    const __m512i m = _mm512_add_epi64(_mm512_mul_epu32(oct, _mm512_set1_epi64(100000000)),
                                       _mm512_bsrli_epi128(oct, 8));
    constexpr __mmask8 kLanes = 0x15;  // lanes 0, 2, 4
    if (_mm512_mask_cmpgt_epu64_mask(kLanes, m, _mm512_set1_epi64(int64_t(1) << 53))) return false;
    const __m512i which = _mm512_set_epi64(0, 0, 0, scale[2], 0, scale[1], 0, scale[0]);
    const __m512d inv =
        _mm512_permutex2var_pd(_mm512_loadu_pd(kInvPow10Lo), which, _mm512_loadu_pd(kInvPow10Hi));
    const __m512d d = _mm512_mul_pd(_mm512_cvtepu64_pd(m), inv);
    // Within 4 double ulps of a float midpoint: let the scalar path decide (as in
    // decimal_to_real, which then divides exactly or asks from_chars).
    const __m512i low = _mm512_and_si512(_mm512_castpd_si512(d), _mm512_set1_epi64(0x1fffffff));
    const __m512i dist = _mm512_add_epi64(_mm512_sub_epi64(low, _mm512_set1_epi64(0x10000000)),
                                          _mm512_set1_epi64(4));
    if (_mm512_mask_cmple_epu64_mask(kLanes, dist, _mm512_set1_epi64(8))) return false;
    __m256i f = _mm256_castps_si256(_mm512_cvtpd_ps(d));
    f = _mm256_or_si256(
        f, _mm256_set_epi32(0, 0, 0, sign[2] << 31, 0, sign[1] << 31, 0, sign[0] << 31));
    alignas(32) float out[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(out), f);
    pos = Vec3f(out[0], out[2], out[4]);
    return true;
}
#endif

// The token at p for a message: at most 40 bytes, through printable().
inline std::string token_text(const char* p, const char* e) {
    const char* t = skip_token(p, e);
    std::string_view s(p, size_t(t - p));
    return s.size() > 40 ? printable(s.substr(0, 40)) + "..." : printable(s);
}

}  // namespace kdt::ply
