// Binary PLY values: loads of every scalar type in either byte order, and the batch decoders
// of float positions and "3 a b c" triangle records. Internal to renderer/io/ply_*; depends
// on geometry (vector types).
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "renderer/geometry/mesh.h"
#include "renderer/io/ply_format.h"
#include "renderer/io/ply_simd.h"

namespace kdt::ply {

// Binary value loads; Swap selects big-endian input on our little-endian hosts.

template <typename T>
inline T load_raw(const char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}

template <bool Swap, typename U>
inline U load_uint(const char* p) {
    U v = load_raw<U>(p);
    if constexpr (Swap) {
        if constexpr (sizeof(U) == 2) v = __builtin_bswap16(v);
        if constexpr (sizeof(U) == 4) v = __builtin_bswap32(v);
        if constexpr (sizeof(U) == 8) v = __builtin_bswap64(v);
    }
    return v;
}

template <bool Swap>
inline double load_double(const char* p, PlyType t) {
    switch (t) {
        case PlyType::i8:
            return double(int8_t(*p));
        case PlyType::u8:
            return double(uint8_t(*p));
        case PlyType::i16:
            return double(int16_t(load_uint<Swap, uint16_t>(p)));
        case PlyType::u16:
            return double(load_uint<Swap, uint16_t>(p));
        case PlyType::i32:
            return double(int32_t(load_uint<Swap, uint32_t>(p)));
        case PlyType::u32:
            return double(load_uint<Swap, uint32_t>(p));
        case PlyType::f32:
            return double(std::bit_cast<float>(load_uint<Swap, uint32_t>(p)));
        case PlyType::f64:
            return std::bit_cast<double>(load_uint<Swap, uint64_t>(p));
        default:
            return 0.0;
    }
}

template <bool Swap>
inline float load_float(const char* p, PlyType t) {
    if (t == PlyType::f32) return std::bit_cast<float>(load_uint<Swap, uint32_t>(p));
    return float(load_double<Swap>(p, t));
}

// Integer types only (checked in the header).
template <bool Swap>
inline int64_t load_int(const char* p, PlyType t) {
    switch (t) {
        case PlyType::i8:
            return int8_t(*p);
        case PlyType::u8:
            return uint8_t(*p);
        case PlyType::i16:
            return int16_t(load_uint<Swap, uint16_t>(p));
        case PlyType::u16:
            return load_uint<Swap, uint16_t>(p);
        case PlyType::i32:
            return int32_t(load_uint<Swap, uint32_t>(p));
        case PlyType::u32:
            return load_uint<Swap, uint32_t>(p);
        default:
            return 0;
    }
}

// Face records "3 a b c" (uchar count, 4-byte indices) are 13 bytes each.
constexpr size_t kTriangleRecord = 1 + 3 * 4;

// How far ahead the binary decoders prefetch: the hardware prefetchers stop at 4 KiB page
// boundaries, and the file's pages lie anywhere in memory.
constexpr size_t kPrefetchBytes = 1024;

// Decodes the float x, y, z at r, r + rec, r + 2 rec, ... (up to n records) into out while
// they are finite; returns how many it took. With SSSE3 one 16-byte load per record,
// byte-swapped by a shuffle for big-endian input; it reads 4 bytes past the last z (inside
// the record or the Input padding) and writes 4 bytes past out[n - 1], so out must hold
// n + 1 positions.
template <bool Swap>
[[gnu::always_inline]] inline size_t decode_positions(const char* r, size_t n, size_t rec,
                                                      Vec3f* out) {
#if defined(__SSSE3__)
    const __m128i order = Swap
                              ? _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, -1, -1, -1, -1)
                              : _mm_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, -1, -1, -1, -1);
    const __m128i exponent = _mm_set1_epi32(0x7f800000);
    for (size_t k = 0; k < n; ++k, r += rec) {
        __builtin_prefetch(r + kPrefetchBytes);
        const __m128i xyz =
            _mm_shuffle_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(r)), order);
        // Infinities and NaNs have every exponent bit set.
        const __m128i inf_nan = _mm_cmpeq_epi32(_mm_and_si128(xyz, exponent), exponent);
        if (_mm_movemask_ps(_mm_castsi128_ps(inf_nan)) & 7) return k;
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + k), xyz);
    }
    return n;
#else
    for (size_t k = 0; k < n; ++k, r += rec) {
        __builtin_prefetch(r + kPrefetchBytes);
        const Vec3f p(std::bit_cast<float>(load_uint<Swap, uint32_t>(r)),
                      std::bit_cast<float>(load_uint<Swap, uint32_t>(r + 4)),
                      std::bit_cast<float>(load_uint<Swap, uint32_t>(r + 8)));
        if (!is_finite(p)) return k;
        out[k] = p;
    }
    return n;
#endif
}

// Decodes up to n face records at r into out while they are "3 a b c" with a, b, c below
// `limit` and all different; returns how many it took (the record after them is anything
// else). With SSSE3 one 16-byte load and one shuffle per record take the indices out and
// swap their bytes for big-endian input; it reads 3 bytes past the last record (the Input
// padding) and writes 4 bytes past out[n - 1], so out must hold n + 1 triangles.
template <bool Swap>
[[gnu::always_inline]] inline size_t decode_triangles(const char* r, size_t n, uint32_t limit,
                                                      Vec3u* out) {
#if defined(__SSSE3__)
    const __m128i take = Swap
                             ? _mm_setr_epi8(4, 3, 2, 1, 8, 7, 6, 5, 12, 11, 10, 9, -1, -1, -1, -1)
                             : _mm_setr_epi8(1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, -1, -1, -1, -1);
    // Unsigned a < limit as signed compares of values with the top bit flipped.
    const __m128i flip = _mm_set1_epi32(INT32_MIN);
    const __m128i lim = _mm_set1_epi32(int32_t(limit ^ 0x80000000u));
    for (size_t k = 0; k < n; ++k, r += kTriangleRecord) {
        __builtin_prefetch(r + kPrefetchBytes);
        const __m128i rec = _mm_loadu_si128(reinterpret_cast<const __m128i*>(r));
        const __m128i idx = _mm_shuffle_epi8(rec, take);  // a, b, c, 0
        // Lanes 0-2: index in range; index equal to the next one (a = b, b = c, c = a).
        const __m128i in_range = _mm_cmpgt_epi32(lim, _mm_xor_si128(idx, flip));
        const __m128i repeated =
            _mm_cmpeq_epi32(idx, _mm_shuffle_epi32(idx, _MM_SHUFFLE(3, 0, 2, 1)));
        const int bad = (~_mm_movemask_ps(_mm_castsi128_ps(in_range)) |
                         _mm_movemask_ps(_mm_castsi128_ps(repeated))) &
                        7;
        if (bad | (uint8_t(r[0]) ^ 3)) return k;
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + k), idx);
    }
    return n;
#else
    for (size_t k = 0; k < n; ++k, r += kTriangleRecord) {
        __builtin_prefetch(r + kPrefetchBytes);
        const uint32_t a = load_uint<Swap, uint32_t>(r + 1);
        const uint32_t b = load_uint<Swap, uint32_t>(r + 5);
        const uint32_t c = load_uint<Swap, uint32_t>(r + 9);
        if ((uint8_t(r[0]) != 3) | (a >= limit) | (b >= limit) | (c >= limit) | (a == b) |
            (b == c) | (a == c))
            return k;
        out[k] = Vec3u(a, b, c);
    }
    return n;
#endif
}

}  // namespace kdt::ply
