// ASCII PLY numbers: integer and decimal tokens parsed in place, bounded by the line end,
// with Clinger's fast path for plain decimals and from_chars for the rest. Internal to
// renderer/io/ply_*; depends on the standard library only.
#pragma once

#include <bit>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <system_error>

#include "renderer/io/ply_format.h"

namespace kdt::ply {

// ASCII token parsing, bounded by the line end.

inline const char* skip_blanks(const char* p, const char* e) {
    while (p < e && is_blank(*p)) ++p;
    return p;
}

inline const char* skip_token(const char* p, const char* e) {
    while (p < e && !is_sep(*p)) ++p;
    return p;
}

enum class IntResult { ok, invalid, overflow };

constexpr uint64_t kPow10Int[] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000};

// Reads the run of up to 8 decimal digits at q with one 8-byte load (SWAR): returns how
// many there are before e and stores their value. May load up to 8 bytes past e, which
// the Input padding keeps inside the buffer; those bytes never count.
[[gnu::always_inline]] inline int digits8(const char* q, const char* e, uint64_t& value) {
    uint64_t x;
    std::memcpy(&x, q, 8);
    // Bytes outside '0'..'9' get a non-zero high nibble in t or t + 6 (borrows only move
    // towards later bytes, past the first non-digit, so they do not matter).
    uint64_t t = x - 0x3030303030303030ull;
    uint64_t bad = (t | (t + 0x0606060606060606ull)) & 0xf0f0f0f0f0f0f0f0ull;
    int n = bad ? __builtin_ctzll(bad) >> 3 : 8;
    if (n > e - q) n = int(e - q);
    if (n == 0) {
        value = 0;
        return 0;
    }
    // Keep the first n digits as the low-order end of an 8-digit number, then combine
    // pairs, quads and octets by multiply-shift.
    uint64_t d = (x & 0x0f0f0f0f0f0f0f0full) << (8 * (8 - n));
    d = (d * 10 + (d >> 8)) & 0x00ff00ff00ff00ffull;
    d = (d * 100 + (d >> 16)) & 0x0000ffff0000ffffull;
    d = (d * 10000 + (d >> 32)) & 0xffffffffull;
    value = d;
    return n;
}

// Parses an integer token starting at p; on success p is moved past it. Overflow is
// detected by the digit count (18 significant digits always fit).
[[gnu::always_inline]] inline IntResult parse_int(const char*& p, const char* e, int64_t& out) {
    const char* q = p;
    bool neg = false;
    if (q < e && (*q == '-' || *q == '+')) neg = *q++ == '-';
    const char* d0 = q;
    uint64_t v = 0, chunk;
    for (;;) {
        int n = digits8(q, e, chunk);
        v = v * kPow10Int[n] + chunk;
        q += n;
        if (n < 8) break;
    }
    if (q == d0 || (q < e && !is_sep(*q))) return IntResult::invalid;
    if (q - d0 > 18) {
        while (d0 < q - 1 && *d0 == '0') ++d0;
        if (q - d0 > 18) return IntResult::overflow;
    }
    out = neg ? -int64_t(v) : int64_t(v);
    p = q;
    return IntResult::ok;
}

constexpr double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                             1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

// Clinger's fast path: a decimal with a mantissa below 2^53 and a power of ten up to 22 is
// m * 10^e or m / 10^e in one correctly rounded double operation (Clinger 1990). Splits
// the token into m (exact as a double) and e; returns false for anything else (the
// caller then uses from_chars).
[[gnu::always_inline]] inline bool fast_decimal(const char*& p, const char* e, double& mant,
                                                int& exp10_out, bool& negative) {
    const char* q = p;
    bool neg = false;
    if (q < e && (*q == '-' || *q == '+')) neg = *q++ == '-';
    uint64_t m = 0, chunk;
    int digits = 0, exp10 = 0;
    if (e - q > 1 && is_digit(q[0]) && q[1] == '.') {
        // One integer digit, as in most normalised coordinates: skip the SWAR step.
        m = uint64_t(q[0] - '0');
        digits = 1;
        ++q;
    } else {
        for (;;) {
            int n = digits8(q, e, chunk);
            m = m * kPow10Int[n] + chunk;
            q += n;
            digits += n;
            if (n < 8 || digits > 19) break;
        }
    }
    if (q < e && *q == '.') {
        ++q;
        for (;;) {
            int n = digits8(q, e, chunk);
            m = m * kPow10Int[n] + chunk;
            q += n;
            digits += n;
            exp10 -= n;
            if (n < 8 || digits > 19) break;
        }
    }
    if (digits == 0 || digits > 19) return false;
    if (q < e && (*q == 'e' || *q == 'E')) {
        ++q;
        bool eneg = false;
        if (q < e && (*q == '-' || *q == '+')) eneg = *q++ == '-';
        if (q == e || !is_digit(*q)) return false;
        int x = 0;
        while (q < e && is_digit(*q)) {
            if (x < 10000) x = x * 10 + (*q - '0');
            ++q;
        }
        exp10 += eneg ? -x : x;
    }
    if (q < e && !is_sep(*q)) return false;
    if (m > (uint64_t(1) << 53) || exp10 < -22 || exp10 > 22) return false;
    mant = double(m);
    exp10_out = exp10;
    negative = neg;
    p = q;
    return true;
}

constexpr double kInvPow10[] = {1e0,   1e-1,  1e-2,  1e-3,  1e-4,  1e-5,  1e-6,  1e-7,
                                1e-8,  1e-9,  1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15,
                                1e-16, 1e-17, 1e-18, 1e-19, 1e-20, 1e-21, 1e-22};

// Rounds m * 10^exp10 (m < 2^53 exact, |exp10| <= 22) to T; false when the float result could
// round twice (the caller then asks from_chars).
template <typename T>
[[gnu::always_inline]] inline bool decimal_to_real(double m, int exp10, bool neg, T& out) {
    if constexpr (sizeof(T) == 8) {
        double d = exp10 < 0 ? m / kPow10[-exp10] : m * kPow10[exp10];
        // The sign as a bit, not a branch: signs of coordinates are random.
        out = std::bit_cast<double>(std::bit_cast<uint64_t>(d) | (uint64_t(neg) << 63));
        return true;
    } else {
        // For a float result, multiplying by a rounded 10^-k (no division latency) is
        // within 2 double ulps of m / 10^k. Rounding that to float gives the correctly
        // rounded float unless a float midpoint lies within those ulps; such rare
        // values take the exact division, and a result exactly on a midpoint (where
        // rounding twice could differ) goes to from_chars.
        double d;
        if (exp10 >= 0) {
            d = m * kPow10[exp10];
        } else {
            d = m * kInvPow10[-exp10];
            uint64_t low = std::bit_cast<uint64_t>(d) & 0x1fffffffu;
            if (low - 0x10000000u + 4u <= 8u) d = m / kPow10[-exp10];
        }
        if ((std::bit_cast<uint64_t>(d) & 0x1fffffffu) == 0x10000000u) return false;
        out = std::bit_cast<float>(std::bit_cast<uint32_t>(float(d)) | (uint32_t(neg) << 31));
        return true;
    }
}

template <typename T>
inline bool parse_real(const char*& p, const char* e, T& out) {
    double m;
    int exp10;
    bool neg;
    const char* fp = p;
    if (fast_decimal(fp, e, m, exp10, neg) && decimal_to_real(m, exp10, neg, out)) {
        p = fp;
        return true;
    }
    const char* q = p;
    if (q < e && *q == '+') ++q;
    auto r = std::from_chars(q, e, out);
    if (r.ec == std::errc::invalid_argument) return false;
    if (r.ptr < e && !is_sep(*r.ptr)) return false;
    if (r.ec == std::errc::result_out_of_range) {
        char tmp[128];
        size_t n = size_t(r.ptr - q);
        if (n >= sizeof(tmp)) return false;
        std::memcpy(tmp, q, n);
        tmp[n] = 0;
        out = T(std::strtod(tmp, nullptr));
    }
    p = r.ptr;
    return true;
}

}  // namespace kdt::ply
