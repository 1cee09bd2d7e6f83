#include "renderer/io/ply_reader.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <charconv>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string_view>
#include <system_error>
#include <thread>
#include <vector>

#include <sys/mman.h>
#include <unistd.h>

#if defined(__SSE2__)
// GCC 12 warns about the deliberately undefined vectors inside its own AVX-512 intrinsics
// (GCC PR 105593); the pragma covers the header's lines only.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <immintrin.h>
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

#include "renderer/core/error.h"
#include "renderer/core/huge_pages.h"
#include "renderer/core/timer.h"

namespace kdt {
namespace {

// ---------------------------------------------------------------------------------------
// Types and header structures

enum class PlyType : uint8_t { none, i8, u8, i16, u16, i32, u32, f32, f64 };

struct TypeName {
    std::string_view name;
    PlyType type;
};
constexpr TypeName kTypeNames[] = {
    {"char", PlyType::i8},     {"int8", PlyType::i8},     {"uchar", PlyType::u8},
    {"uint8", PlyType::u8},    {"short", PlyType::i16},   {"int16", PlyType::i16},
    {"ushort", PlyType::u16},  {"uint16", PlyType::u16},  {"int", PlyType::i32},
    {"int32", PlyType::i32},   {"uint", PlyType::u32},    {"uint32", PlyType::u32},
    {"float", PlyType::f32},   {"float32", PlyType::f32}, {"double", PlyType::f64},
    {"float64", PlyType::f64},
};

PlyType parse_type(std::string_view s) {
    for (const TypeName& t : kTypeNames)
        if (t.name == s) return t.type;
    return PlyType::none;
}

constexpr size_t type_size(PlyType t) {
    switch (t) {
        case PlyType::i8:
        case PlyType::u8:
            return 1;
        case PlyType::i16:
        case PlyType::u16:
            return 2;
        case PlyType::i32:
        case PlyType::u32:
        case PlyType::f32:
            return 4;
        case PlyType::f64:
            return 8;
        default:
            return 0;
    }
}

constexpr bool is_integer(PlyType t) {
    return t != PlyType::none && t != PlyType::f32 && t != PlyType::f64;
}

constexpr int64_t type_min(PlyType t) {
    switch (t) {
        case PlyType::i8:
            return INT8_MIN;
        case PlyType::i16:
            return INT16_MIN;
        case PlyType::i32:
            return INT32_MIN;
        default:
            return 0;
    }
}

constexpr int64_t type_max(PlyType t) {
    switch (t) {
        case PlyType::i8:
            return INT8_MAX;
        case PlyType::u8:
            return UINT8_MAX;
        case PlyType::i16:
            return INT16_MAX;
        case PlyType::u16:
            return UINT16_MAX;
        case PlyType::i32:
            return INT32_MAX;
        case PlyType::u32:
            return UINT32_MAX;
        default:
            return 0;
    }
}

// Destination of a vertex value: position, normal, colour component, or the face's index list.
enum Slot : int8_t {
    kSkip = -1,
    kPosX = 0,
    kPosY,
    kPosZ,
    kNormX,
    kNormY,
    kNormZ,
    kColR,
    kColG,
    kColB,
    kIndices,
};

struct Property {
    std::string name;
    PlyType type = PlyType::none;        // scalar type, or the list's item type
    PlyType count_type = PlyType::none;  // list count type; none for scalars
    int slot = kSkip;
    float scale = 1.0f;  // colour normalisation for integer types
    bool is_list() const { return count_type != PlyType::none; }
};

struct Element {
    std::string name;
    uint64_t count = 0;
    int64_t line = 0;  // header line declaring it
    std::vector<Property> props;
    bool has_lists = false;
    size_t scalar_bytes = 0;  // bytes of the scalar properties of one record (binary)
};

constexpr size_t kBlockBytes = size_t(4) << 20;      // read() block; reused buffer
constexpr size_t kMaxHeaderBytes = size_t(4) << 20;  // "missing end_header" beyond this
constexpr size_t kMaxLineBytes = size_t(256) << 20;  // one ascii element per line

inline bool is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}
// Ends a token: a blank, or the newline when parsing straight from the buffer.
inline bool is_sep(char c) { return is_blank(c) || c == '\n'; }
inline bool is_digit(char c) { return unsigned(c - '0') < 10u; }

// ---------------------------------------------------------------------------------------
// Block input: a reused buffer refilled from the reader; never reads past its data.

class Input {
public:
    // kPad bytes after the usable capacity let the parsers load 64 bytes of a line (and 8
    // more for a digit run inside it) near the end of the data without leaving the
    // allocation; bytes at or past end() never count.
    static constexpr size_t kPad = 80;

    // Plain files of at least kMapBytes are mapped: no copy, no buffer to fault in.
    // Small files and gzip/memory input get a buffer, small inputs one of their own size.
    explicit Input(FileReader& reader) : reader_(reader) {
        if (map_file()) return;
        buf_.resize(
            size_t(std::min<uint64_t>(kBlockBytes, std::max<uint64_t>(reader.size_bound(), 4096))) +
            kPad);
        pos_ = end_ = buf_.data();
    }
    Input(const Input&) = delete;
    Input& operator=(const Input&) = delete;
    ~Input() {
        if (map_) ::munmap(map_, map_bytes_);
    }

    const char* pos() const { return pos_; }
    const char* end() const { return end_; }
    bool eof() const { return eof_; }
    size_t avail() const { return size_t(end_ - pos_); }
    /// Bytes the buffer holds without growing.
    size_t capacity() const { return map_ ? kBlockBytes : buf_.size() - kPad; }
    void advance(size_t n) { pos_ += n; }
    /// Stream offset of pos().
    uint64_t offset() const {
        return map_ ? uint64_t(pos_ - map_) : base_ + uint64_t(pos_ - buf_.data());
    }

    /// Makes at least n bytes available at pos(); false when the data ends first.
    bool fill(size_t n) {
        if (avail() >= n) return true;
        if (map_) return slide(n);
        size_t have = avail();
        if (pos_ != buf_.data()) {
            base_ += uint64_t(pos_ - buf_.data());
            std::memmove(buf_.data(), pos_, have);
            pos_ = buf_.data();
            end_ = pos_ + have;
        }
        if (n > buf_.size() - kPad) {
            std::vector<char> bigger(std::max(n, 2 * (buf_.size() - kPad)) + kPad);
            std::memcpy(bigger.data(), buf_.data(), have);
            buf_.swap(bigger);
            pos_ = buf_.data();
            end_ = pos_ + have;
        }
        while (avail() < n && !eof_) {
            size_t room = buf_.size() - kPad - size_t(end_ - buf_.data());
            size_t got = reader_.read(const_cast<char*>(end_), room);
            if (got == 0) eof_ = true;
            end_ += got;
        }
        return avail() >= n;
    }

    /// Skips n bytes; false when the data ends first.
    bool skip(uint64_t n) {
        while (n > 0) {
            if (pos_ == end_ && !fill(1)) return false;
            size_t k = size_t(std::min<uint64_t>(n, avail()));
            pos_ += k;
            n -= k;
        }
        return true;
    }

    /// The next line [b, e) without its '\n'; false at the end of the data. Throws through
    /// `too_long` when a line exceeds max_bytes. The window grows geometrically while a
    /// line is scanned, so a line of n bytes costs O(n) however long it is.
    template <typename TooLong>
    bool next_line(const char*& b, const char*& e, TooLong&& too_long,
                   size_t max_bytes = kMaxLineBytes) {
        size_t scanned = 0;
        for (;;) {
            const void* nl = std::memchr(pos_ + scanned, '\n', avail() - scanned);
            if (nl) {
                b = pos_;
                e = static_cast<const char*>(nl);
                pos_ = e + 1;
                return true;
            }
            scanned = avail();
            if (eof_) {
                if (scanned == 0) return false;
                b = pos_;
                e = end_;
                pos_ = end_;
                return true;
            }
            if (scanned >= max_bytes) too_long();
            fill(std::min(max_bytes + 1, scanned + std::max(scanned, capacity())));
        }
    }

private:
    // Maps the whole file read-only over a reservation one padding page longer, so loads
    // past the end read zeros; the parser then sees the file through a window of
    // kBlockBytes that slide() moves on. (A file truncated by another process while it is
    // read would fault, as with any mapped file.)
    bool map_file() {
        const int fd = reader_.plain_fd();
        const uint64_t size = reader_.file_bytes();
        if (fd < 0 || size < kMapBytes || size > uint64_t(SIZE_MAX) / 2) return false;
        const size_t page = size_t(::sysconf(_SC_PAGESIZE));
        const size_t bytes = (size_t(size) + kPad + 2 * page - 1) / page * page;
        void* base = ::mmap(nullptr, bytes, PROT_READ, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (base == MAP_FAILED) return false;
        if (::mmap(base, size_t(size), PROT_READ, MAP_PRIVATE | MAP_FIXED, fd, 0) == MAP_FAILED) {
            ::munmap(base, bytes);
            return false;
        }
        ::madvise(base, size_t(size), MADV_SEQUENTIAL);
        map_ = static_cast<char*>(base);
        map_bytes_ = bytes;
        map_end_ = map_ + size;
        page_ = page;
        released_ = map_;
        pos_ = end_ = map_;
        return true;
    }

    // Moves the window of a mapped file to [pos, pos + max(n, kBlockBytes)) and unmaps the
    // pages before it, so resident memory stays about one window whatever the file size.
    bool slide(size_t n) {
        char* done = map_ + size_t(pos_ - map_) / page_ * page_;
        if (size_t(done - released_) >= kReleaseBytes) {
            ::madvise(released_, size_t(done - released_), MADV_DONTNEED);
            released_ = done;
        }
        const char* old_end = end_;
        end_ = pos_ + std::min(size_t(map_end_ - pos_), std::max(n, kBlockBytes));
        eof_ = end_ == map_end_;
        // Map the window's pages in one call rather than one fault per 16 pages.
        char* from = map_ + size_t(std::max(old_end, pos_) - map_) / page_ * page_;
        if (end_ > from) ::madvise(from, size_t(end_ - from), kPopulateRead);
        return avail() >= n;
    }

    static constexpr uint64_t kMapBytes = uint64_t(1) << 20;
    // MADV_POPULATE_READ (Linux 5.14); older kernels reject it and fault pages in as read.
#ifdef MADV_POPULATE_READ
    static constexpr int kPopulateRead = MADV_POPULATE_READ;
#else
    static constexpr int kPopulateRead = 22;
#endif
    static constexpr size_t kReleaseBytes = size_t(1) << 20;

    FileReader& reader_;
    std::vector<char> buf_;
    const char* pos_ = nullptr;
    const char* end_ = nullptr;
    uint64_t base_ = 0;
    bool eof_ = false;
    char* map_ = nullptr;  // mapped file, or null for buffered input
    const char* map_end_ = nullptr;
    char* released_ = nullptr;  // pages before it are unmapped again
    size_t map_bytes_ = 0, page_ = 4096;
};

// ---------------------------------------------------------------------------------------
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

// ---------------------------------------------------------------------------------------
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

// ---------------------------------------------------------------------------------------
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

// Same for a face line "3 a b c" with indices of up to 8 digits.
[[gnu::always_inline]] inline bool triangle_from_classes(const LineClasses& c, const char* p,
                                                         int len, int64_t* idx) {
    const uint64_t tok = low_bits(len) & ~c.blank;
    if (tok & ~c.digit) return false;
    uint64_t starts = tok & ~(tok << 1);
    uint64_t ends = tok & ~(tok >> 1);  // last byte of each token
    if (__builtin_popcountll(starts) != 4 || (starts & -starts) != (ends & -ends) ||
        p[__builtin_ctzll(starts)] != '3')
        return false;
    starts &= starts - 1;
    ends &= ends - 1;
    int s[3], n[3];
    for (int k = 0; k < 3; ++k) {
        s[k] = __builtin_ctzll(starts);
        n[k] = __builtin_ctzll(ends) - s[k] + 1;
        starts &= starts - 1;
        ends &= ends - 1;
    }
    if (n[0] > 8 || n[1] > 8 || n[2] > 8) return false;
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
    const uint64_t tok = low_bits(len) & ~c.blank;
    if (tok & ~c.digit) return false;
    uint64_t starts = tok & ~(tok << 1);
    uint64_t ends = tok & ~(tok >> 1);  // last byte of each token
    if (__builtin_popcountll(starts) != 4 || (starts & -starts) != (ends & -ends) ||
        p[__builtin_ctzll(starts)] != '3')
        return false;
    starts &= starts - 1;
    ends &= ends - 1;
    int s[3], n[3];
    for (int k = 0; k < 3; ++k) {
        s[k] = __builtin_ctzll(starts);
        n[k] = __builtin_ctzll(ends) - s[k] + 1;
        starts &= starts - 1;
        ends &= ends - 1;
    }
    if (n[0] > 8 || n[1] > 8 || n[2] > 8) return false;
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

std::string token_text(const char* p, const char* e) {
    const char* t = skip_token(p, e);
    std::string s(p, size_t(t - p));
    if (s.size() > 40) s = s.substr(0, 40) + "...";
    return s;
}

// ---------------------------------------------------------------------------------------
// A second parsing thread that takes work when it gets a core: parallel_for(n, fn) runs
// fn(0), ..., fn(n - 1) on the calling thread and the helper, each taking the next index,
// and returns once all are done. A helper that wakes late (the machine is shared) finds
// little or nothing left and holds no one up, unlike a fixed split in halves.

class Helper {
public:
    Helper() : thread_([this] { loop(); }) {}
    Helper(const Helper&) = delete;
    Helper& operator=(const Helper&) = delete;
    ~Helper() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            quit_ = true;
        }
        wake_.notify_one();
        thread_.join();
    }

    /// fn must not throw.
    template <typename F>
    void parallel_for(size_t n, F&& fn) {
        Job job;
        job.n = n;
        job.fn = [&fn](size_t k) { fn(k); };
        {
            std::lock_guard<std::mutex> lock(mutex_);
            job_ = &job;
            ++generation_;
        }
        wake_.notify_one();
        work(job);
        std::unique_lock<std::mutex> lock(mutex_);
        job_ = nullptr;  // the helper can no longer join this job...
        done_.wait(lock, [&] { return job.active == 0; });  // ...and has left it
    }

private:
    struct Job {
        size_t n = 0;
        std::function<void(size_t)> fn;
        std::atomic<size_t> next{0};
        int active = 0;  // helpers inside work(); guarded by mutex_
    };

    static void work(Job& job) {
        for (size_t k; (k = job.next.fetch_add(1, std::memory_order_relaxed)) < job.n;) job.fn(k);
    }

    void loop() {
        std::unique_lock<std::mutex> lock(mutex_);
        uint64_t seen = 0;
        for (;;) {
            wake_.wait(lock, [&] { return quit_ || (job_ && generation_ != seen); });
            if (quit_) return;
            seen = generation_;
            Job* job = job_;
            ++job->active;
            lock.unlock();
            work(*job);
            lock.lock();
            if (--job->active == 0) done_.notify_all();
        }
    }

    std::mutex mutex_;
    std::condition_variable wake_, done_;
    Job* job_ = nullptr;
    uint64_t generation_ = 0;
    bool quit_ = false;
    std::thread thread_;  // last: starts once the members above exist
};

// ---------------------------------------------------------------------------------------
// The parser

class PlyParser {
public:
    PlyParser(FileReader& reader, const MeshLoadOptions& options)
        : reader_(reader), in_(reader), options_(options) {
        threads_ = options.threads > 0 ? options.threads
                                       : (std::thread::hardware_concurrency() >= 2 ? 2 : 1);
    }

    TriangleMesh parse(MeshLoadInfo* info);

private:
    // Errors
    [[noreturn]] void fail_header(const std::string& message) const {
        ErrorLocation w;
        w.path = reader_.path();
        w.element = "header";
        w.line = line_;
        throw Error(w, message);
    }
    [[noreturn]] void fail_data(const Element& el, uint64_t index, int64_t line, int64_t offset,
                                const std::string& message) const {
        ErrorLocation w;
        w.path = reader_.path();
        w.element = el.name;
        w.index = int64_t(index);
        w.line = line;
        w.offset = offset;
        throw Error(w, message);
    }
    // Location of the record being read: its line for ascii, its first byte for binary.
    [[noreturn]] void fail_at(const Element& el, uint64_t index, const std::string& message) const {
        if (ascii_) fail_data(el, index, line_, -1, message);
        fail_data(el, index, -1, int64_t(record_offset_), message);
    }

    void parse_header();
    void plan_elements();
    void check_counts();

    // Binary
    template <bool Swap>
    void read_binary_element(Element& el);
    template <bool Swap>
    void read_binary_vertices_fixed(Element& el);
    template <bool Swap>
    void read_binary_record(Element& el, uint64_t i);
    template <bool Swap>
    void read_binary_faces_fast(Element& el);
    void need(const Element& el, uint64_t i, size_t n) {
        if (!in_.fill(n))
            fail_data(el, i, -1, int64_t(in_.offset()), "unexpected end of data (file truncated?)");
    }

    // ASCII
    void read_ascii_element(Element& el);
    bool fast_ascii_scalars(const Element& el, const char*& p, const char* e, float* v) const;
    bool fast_ascii_triangle(const char*& p, const char* e, int64_t* idx) const;
    bool line_ascii_scalars(const Element& el, const char*& p, const char* e, float* v) const;
    bool line_ascii_triangle(const char*& p, const char* e, int64_t* idx) const;
    struct LinesResult {
        uint64_t lines = 0;
        const char* end = nullptr;
    };
    LinesResult parse_lines(const Element& el, bool faces, bool is_vertex, const char* p,
                            const char* e, uint64_t first, uint64_t max_lines, bool append);
    uint64_t parallel_chunk(const Element& el, uint64_t i, bool faces, bool is_vertex, bool& poor);
    bool next_data_line(const char*& b, const char*& e);

    // Shared
    void store_vertex(const Element& el, uint64_t i, const float* v);
    [[gnu::noinline]] void non_finite_vertex(const Element& el, uint64_t i, const Vec3f& p);
    void emit_face(const Element& el, uint64_t i, const int64_t* idx, size_t n);
    void emit_strip(const Element& el, uint64_t i, const int64_t* idx, size_t n);
    bool is_strip(const Element& el) const {
        return strip_el_ >= 0 && &el == &elements_[size_t(strip_el_)];
    }
    void finish(TriangleMesh& mesh);

    FileReader& reader_;
    Input in_;
    MeshLoadOptions options_;
    bool ascii_ = false, swap_ = false;
    PlyEncoding encoding_ = PlyEncoding::ascii;
    int64_t line_ = 0;
    int64_t header_lines_ = 0;
    uint64_t record_offset_ = 0;
    uint64_t data_offset_ = 0;
    std::vector<Element> elements_;
    int vertex_el_ = -1, face_el_ = -1;
    int strip_el_ = -1;  // element "tristrips" (Cyberware-era scans): strips, -1 restarts
    bool has_normals_ = false, has_colors_ = false;
    bool xyz_only_ = false;  // vertex properties: float x, y, z and nothing else
    bool vertices_read_ = false;
    uint64_t vertex_count_ = 0;

    TriangleMesh mesh_;
    std::vector<uint8_t> bad_vertex_;  // only allocated once a non-finite vertex is seen
    uint64_t bad_vertices_ = 0;
    uint64_t dropped_faces_ = 0, degenerate_faces_ = 0, source_faces_ = 0;
    std::vector<int64_t> poly_;    // indices of the face being read
    std::vector<int64_t> sorted_;  // scratch for the degenerate test of big polygons
    int threads_ = 1;
    std::unique_ptr<Helper> helper_;  // created by the first two-thread chunk
};

void PlyParser::parse_header() {
    // One bound for the whole header: a line may run only to the header's 4 MiB.
    auto too_long = [&] {
        ++line_;  // the line being read
        fail_header("no end_header in the first 4 MiB (missing end_header?)");
    };
    const char* b;
    const char* e;
    auto split = [](const char* p, const char* end, std::vector<std::string_view>& out) {
        out.clear();
        for (;;) {
            p = skip_blanks(p, end);
            if (p == end) break;
            const char* t = skip_token(p, end);
            out.emplace_back(p, size_t(t - p));
            p = t;
        }
    };
    std::vector<std::string_view> tok;

    if (!in_.next_line(b, e, too_long, kMaxHeaderBytes)) {
        line_ = 1;
        fail_header("empty file (not a PLY file)");
    }
    ++line_;
    split(b, e, tok);
    if (tok.size() != 1 || tok[0] != "ply")
        fail_header("not a PLY file (the first line must be 'ply')");

    bool have_format = false, have_end = false;
    while (!have_end) {
        if (in_.offset() >= kMaxHeaderBytes) too_long();
        if (!in_.next_line(b, e, too_long, kMaxHeaderBytes - size_t(in_.offset()))) {
            fail_header("missing end_header (the file ends inside the header)");
        }
        ++line_;
        split(b, e, tok);
        if (tok.empty()) continue;
        std::string_view kw = tok[0];
        if (kw == "format") {
            if (have_format) fail_header("second format line");
            if (tok.size() != 3 || (tok[2] != "1.0" && tok[2] != "1"))
                fail_header(
                    "unknown format line '" + std::string(b, size_t(e - b)) +
                    "' (expected 'format ascii|binary_little_endian|binary_big_endian 1.0')");
            if (tok[1] == "ascii")
                encoding_ = PlyEncoding::ascii;
            else if (tok[1] == "binary_little_endian")
                encoding_ = PlyEncoding::binary_little_endian;
            else if (tok[1] == "binary_big_endian")
                encoding_ = PlyEncoding::binary_big_endian;
            else
                fail_header("unknown format '" + std::string(tok[1]) + "'");
            have_format = true;
        } else if (kw == "element") {
            if (tok.size() != 3)
                fail_header("malformed element line (expected 'element NAME COUNT')");
            Element el;
            el.name = std::string(tok[1]);
            el.line = line_;
            const char* p = tok[2].data();
            int64_t count = 0;
            IntResult r = parse_int(p, tok[2].data() + tok[2].size(), count);
            if (r == IntResult::invalid)
                fail_header("element " + el.name + ": count '" + std::string(tok[2]) +
                            "' is not an integer");
            if (r == IntResult::overflow || count > int64_t(1) << 48)
                fail_header("element " + el.name + ": count " + std::string(tok[2]) +
                            " is too large");
            if (count < 0)
                fail_header("element " + el.name + ": negative count " + std::to_string(count));
            el.count = uint64_t(count);
            for (const Element& other : elements_)
                if (other.name == el.name) fail_header("second element named '" + el.name + "'");
            elements_.push_back(std::move(el));
        } else if (kw == "property") {
            if (elements_.empty()) fail_header("property before any element");
            Element& el = elements_.back();
            Property prop;
            if (tok.size() >= 2 && tok[1] == "list") {
                if (tok.size() != 5)
                    fail_header(
                        "malformed list property (expected 'property list COUNT_TYPE ITEM_TYPE "
                        "NAME')");
                prop.count_type = parse_type(tok[2]);
                prop.type = parse_type(tok[3]);
                if (prop.count_type == PlyType::none)
                    fail_header("unknown property type '" + std::string(tok[2]) + "'");
                if (prop.type == PlyType::none)
                    fail_header("unknown property type '" + std::string(tok[3]) + "'");
                if (!is_integer(prop.count_type))
                    fail_header("list count type '" + std::string(tok[2]) +
                                "' is not an integer type");
                prop.name = std::string(tok[4]);
                el.has_lists = true;
            } else {
                if (tok.size() != 3)
                    fail_header("malformed property line (expected 'property TYPE NAME')");
                prop.type = parse_type(tok[1]);
                if (prop.type == PlyType::none)
                    fail_header("unknown property type '" + std::string(tok[1]) + "'");
                prop.name = std::string(tok[2]);
                el.scalar_bytes += type_size(prop.type);
            }
            for (const Property& other : el.props)
                if (other.name == prop.name)
                    fail_header("element " + el.name + ": second property named '" + prop.name +
                                "'");
            el.props.push_back(std::move(prop));
        } else if (kw == "end_header") {
            have_end = true;
        }
        // comment, obj_info and unknown keywords: ignored (see ply_reader.h).
    }
    if (!have_format) fail_header("missing format line");
    ascii_ = encoding_ == PlyEncoding::ascii;
    swap_ = encoding_ == PlyEncoding::binary_big_endian;
    data_offset_ = in_.offset();
    header_lines_ = line_;
}

void PlyParser::plan_elements() {
    for (size_t k = 0; k < elements_.size(); ++k) {
        if (elements_[k].name == "vertex") vertex_el_ = int(k);
        if (elements_[k].name == "face") face_el_ = int(k);
        if (elements_[k].name == "tristrips") strip_el_ = int(k);
    }
    if (vertex_el_ < 0) {
        line_ = -1;
        fail_header("no 'element vertex' in the header");
    }
    Element& v = elements_[size_t(vertex_el_)];
    line_ = v.line;
    struct Name {
        std::string_view name;
        int slot;
    };
    static constexpr Name kNames[] = {
        {"x", kPosX},
        {"y", kPosY},
        {"z", kPosZ},
        {"nx", kNormX},
        {"ny", kNormY},
        {"nz", kNormZ},
        {"normal_x", kNormX},
        {"normal_y", kNormY},
        {"normal_z", kNormZ},
        {"red", kColR},
        {"green", kColG},
        {"blue", kColB},
        {"r", kColR},
        {"g", kColG},
        {"b", kColB},
        {"diffuse_red", kColR},
        {"diffuse_green", kColG},
        {"diffuse_blue", kColB},
    };
    int found[9] = {};
    for (Property& p : v.props) {
        if (p.is_list()) continue;
        for (const Name& n : kNames) {
            if (n.name == p.name && found[n.slot] == 0) {
                p.slot = n.slot;
                found[n.slot] = 1;
                break;
            }
        }
    }
    for (int s = kPosX; s <= kPosZ; ++s)
        if (!found[s]) fail_header(std::string("element vertex has no property ") + "xyz"[s]);
    for (const Property& p : v.props)
        if (p.is_list() && (p.name == "x" || p.name == "y" || p.name == "z"))
            fail_header("vertex property " + p.name + " is a list");
    has_normals_ = options_.keep_normals && found[kNormX] && found[kNormY] && found[kNormZ];
    has_colors_ = options_.keep_colors && found[kColR] && found[kColG] && found[kColB];
    for (Property& p : v.props) {
        if ((p.slot >= kNormX && p.slot <= kNormZ && !has_normals_) ||
            (p.slot >= kColR && p.slot <= kColB && !has_colors_))
            p.slot = kSkip;
        if (p.slot >= kColR && p.slot <= kColB && is_integer(p.type))
            p.scale = float(1.0 / double(type_max(p.type)));
    }
    xyz_only_ = v.props.size() == 3;
    for (size_t k = 0; k < v.props.size() && xyz_only_; ++k)
        xyz_only_ = v.props[k].slot == int(k) && v.props[k].type == PlyType::f32;
    if (v.count > uint64_t(UINT32_MAX))
        fail_header("element vertex: " + std::to_string(v.count) +
                    " vertices exceed the 32-bit index limit");
    vertex_count_ = v.count;

    for (int k : {face_el_, strip_el_}) {
        if (k < 0) continue;
        Element& f = elements_[size_t(k)];
        line_ = f.line;
        for (Property& p : f.props) {
            if (p.is_list() && (p.name == "vertex_indices" || p.name == "vertex_index")) {
                if (!is_integer(p.type))
                    fail_header(f.name + " list " + p.name + " has non-integer item type");
                p.slot = kIndices;
                break;
            }
        }
        bool have = false;
        for (const Property& p : f.props) have |= p.slot == kIndices;
        if (!have) fail_header("element " + f.name + " has no list property vertex_indices");
    }
}

// Rejects counts the file cannot hold before anything is allocated for them: binary
// records need at least their scalar bytes plus list counts (a face at least three
// indices); ascii needs at least two bytes (digit and separator) per value, except the
// file's last value, which needs no separator.
void PlyParser::check_counts() {
    const uint64_t bound = reader_.size_bound();
    const uint64_t remaining = (bound > data_offset_ ? bound - data_offset_ : 0) + (ascii_ ? 1 : 0);
    unsigned __int128 total = 0;
    for (const Element& el : elements_) {
        uint64_t min_bytes = 0;
        for (const Property& p : el.props) {
            // A face lists at least three indices; a strip may be empty.
            const bool indices = p.slot == kIndices && !is_strip(el);
            if (ascii_) {
                min_bytes += indices ? 8 : 2;
            } else if (p.is_list()) {
                min_bytes += type_size(p.count_type) + (indices ? 3 * type_size(p.type) : 0);
            } else {
                min_bytes += type_size(p.type);
            }
        }
        unsigned __int128 need = (unsigned __int128)el.count * min_bytes;
        total += need;
        if (total > remaining) {
            line_ = el.line;
            auto bytes = [](unsigned __int128 b) {
                return b > UINT64_MAX ? std::string("2^64") : std::to_string(uint64_t(b));
            };
            // Name the running total when earlier elements took part of the file.
            const std::string with_before =
                total == need ? "" : " (" + bytes(total) + " with the elements before it)";
            fail_header("element " + el.name + ": count " + std::to_string(el.count) +
                        " needs at least " + bytes(need) + " bytes" + with_before +
                        ", more than the " + std::to_string(remaining - (ascii_ ? 1 : 0)) +
                        (reader_.gzip() ? " bytes the compressed file can hold"
                                        : " bytes of data in the file"));
        }
    }
}

inline void PlyParser::store_vertex(const Element& el, uint64_t i, const float* v) {
    Vec3f p(v[kPosX], v[kPosY], v[kPosZ]);
    mesh_.positions[i] = p;
    if (has_normals_) mesh_.normals[i] = Vec3f(v[kNormX], v[kNormY], v[kNormZ]);
    if (has_colors_) mesh_.colors[i] = Vec3f(v[kColR], v[kColG], v[kColB]);
    if (!is_finite(p)) [[unlikely]]
        non_finite_vertex(el, i, p);
}

void PlyParser::non_finite_vertex(const Element& el, uint64_t i, const Vec3f& p) {
    if (!options_.drop_invalid)
        fail_at(el, i,
                "non-finite coordinate (" + std::to_string(p.x) + ", " + std::to_string(p.y) +
                    ", " + std::to_string(p.z) + "); --drop-invalid drops the faces using it");
    if (bad_vertex_.empty()) bad_vertex_.assign(vertex_count_, 0);
    bad_vertex_[i] = 1;
    ++bad_vertices_;
}

void PlyParser::emit_face(const Element& el, uint64_t i, const int64_t* idx, size_t n) {
    ++source_faces_;
    bool bad = false;
    for (size_t k = 0; k < n; ++k) {
        if (idx[k] < 0 || uint64_t(idx[k]) >= vertex_count_) [[unlikely]]
            fail_at(el, i,
                    "vertex index " + std::to_string(idx[k]) + " out of range (" +
                        std::to_string(vertex_count_) + " vertices)");
        if (!bad_vertex_.empty() && vertices_read_) bad |= bad_vertex_[size_t(idx[k])] != 0;
    }
    if (bad) {
        ++dropped_faces_;
        return;
    }
    bool degenerate = false;
    if (n == 3) {
        degenerate = idx[0] == idx[1] || idx[1] == idx[2] || idx[0] == idx[2];
    } else if (n <= 32) {
        for (size_t a = 0; a < n && !degenerate; ++a)
            for (size_t c = a + 1; c < n; ++c)
                if (idx[a] == idx[c]) {
                    degenerate = true;
                    break;
                }
    } else {
        // Big polygons: sort a copy instead of comparing all pairs (a hostile file could
        // hold a face with millions of corners).
        sorted_.assign(idx, idx + n);
        std::sort(sorted_.begin(), sorted_.end());
        degenerate = std::adjacent_find(sorted_.begin(), sorted_.end()) != sorted_.end();
    }
    degenerate_faces_ += degenerate;
    for (size_t k = 1; k + 1 < n; ++k)
        mesh_.triangles.emplace_back(uint32_t(idx[0]), uint32_t(idx[k]), uint32_t(idx[k + 1]));
}

// One triangle strip: triangle k of a run is (v_k, v_k+1, v_k+2), with the first two swapped
// for odd k so that all keep one winding; -1 ends a run. Triangles with a repeated vertex
// are how strips are stitched, so they are dropped (they have no area), not kept as faces.
void PlyParser::emit_strip(const Element& el, uint64_t i, const int64_t* idx, size_t n) {
    ++source_faces_;
    int64_t a = -1, b = -1;
    bool odd = false;
    for (size_t k = 0; k < n; ++k) {
        const int64_t c = idx[k];
        // -1 ends a run; so does 2^32 - 1, its bit pattern in an unsigned 32-bit list
        // (never a valid index: at most 2^32 - 1 vertices).
        if (c == -1 || c == int64_t(UINT32_MAX)) {
            a = b = -1;
            odd = false;
            continue;
        }
        if (c < 0 || uint64_t(c) >= vertex_count_) [[unlikely]]
            fail_at(el, i,
                    "vertex index " + std::to_string(c) + " out of range (" +
                        std::to_string(vertex_count_) + " vertices; -1 ends a strip)");
        if (a < 0) {
            a = c;
            continue;
        }
        if (b < 0) {
            b = c;
            continue;
        }
        const int64_t p = odd ? b : a, q = odd ? a : b;
        odd = !odd;
        a = b;
        b = c;
        if (p == q || q == c || p == c) continue;
        if (!bad_vertex_.empty() && vertices_read_ &&
            (bad_vertex_[size_t(p)] || bad_vertex_[size_t(q)] || bad_vertex_[size_t(c)])) {
            ++dropped_faces_;
            continue;
        }
        mesh_.triangles.emplace_back(uint32_t(p), uint32_t(q), uint32_t(c));
    }
}

// ---- binary -------------------------------------------------------------------------------

// Vertex element of scalars only: fixed-size records, decoded in whole-buffer batches and
// appended to the positions (reserved, not sized: no zero fill before the real values).
template <bool Swap>
void PlyParser::read_binary_vertices_fixed(Element& el) {
    struct Plan {
        size_t offset;
        PlyType type;
        int slot;
        float scale;
    };
    std::vector<Plan> plan;
    size_t off = 0;
    for (const Property& p : el.props) {
        if (p.slot != kSkip) plan.push_back({off, p.type, p.slot, p.scale});
        off += type_size(p.type);
    }
    const size_t rec = el.scalar_bytes;
    // Common case: x, y, z as consecutive floats first in the record and nothing else kept.
    const bool xyz_only = plan.size() == 3 && plan[0].slot == kPosX && plan[1].slot == kPosY &&
                          plan[2].slot == kPosZ && plan[0].offset + 4 == plan[1].offset &&
                          plan[1].offset + 4 == plan[2].offset && plan[0].type == PlyType::f32 &&
                          plan[1].type == PlyType::f32 && plan[2].type == PlyType::f32;
    constexpr size_t kRun = 1024;  // 12 KiB of positions, in L1
    Vec3f run[kRun + 1];           // + 1: decode_positions writes past the last
    uint64_t i = 0;
    float v[9] = {};
    while (i < el.count) {
        record_offset_ = in_.offset();
        need(el, i, rec);
        uint64_t n = std::min<uint64_t>(el.count - i, in_.avail() / rec);
        const char* base = in_.pos();
        if (xyz_only && bad_vertex_.empty()) {
            // Runs of finite positions through a small array and one insert each; a
            // non-finite one goes to store_vertex (an error, or flagged with drop_invalid).
            n = std::min<uint64_t>(n, kRun);
            const char* r = base + plan[0].offset;
            uint64_t k = decode_positions<Swap>(r, size_t(n), rec, run);
            mesh_.positions.insert(mesh_.positions.end(), run, run + k);
            if (k < n) {
                r += k * rec;
                record_offset_ = in_.offset() + k * rec;
                v[0] = std::bit_cast<float>(load_uint<Swap, uint32_t>(r));
                v[1] = std::bit_cast<float>(load_uint<Swap, uint32_t>(r + 4));
                v[2] = std::bit_cast<float>(load_uint<Swap, uint32_t>(r + 8));
                mesh_.positions.emplace_back();
                store_vertex(el, i + k, v);
                ++k;
            }
            n = k;
        } else {
            mesh_.positions.resize(size_t(i + n));
            for (uint64_t k = 0; k < n; ++k) {
                const char* r = base + k * rec;
                for (const Plan& pl : plan)
                    v[pl.slot] = load_float<Swap>(r + pl.offset, pl.type) * pl.scale;
                record_offset_ = in_.offset() + k * rec;
                store_vertex(el, i + k, v);
            }
        }
        in_.advance(size_t(n * rec));
        i += n;
    }
}

// One record of any element, property by property (lists included).
template <bool Swap>
void PlyParser::read_binary_record(Element& el, uint64_t i) {
    const bool is_vertex = &el == &elements_[size_t(vertex_el_)];
    float v[9] = {};
    record_offset_ = in_.offset();
    bool have_face = false;
    for (const Property& p : el.props) {
        if (!p.is_list()) {
            size_t sz = type_size(p.type);
            need(el, i, sz);
            if (p.slot >= 0) v[p.slot] = load_float<Swap>(in_.pos(), p.type) * p.scale;
            in_.advance(sz);
            continue;
        }
        size_t csz = type_size(p.count_type), isz = type_size(p.type);
        need(el, i, csz);
        int64_t count = load_int<Swap>(in_.pos(), p.count_type);
        in_.advance(csz);
        if (count < 0)
            fail_at(el, i, "negative list count " + std::to_string(count) + " in " + p.name);
        if (p.slot != kIndices) {
            if (!in_.skip(uint64_t(count) * isz))
                fail_data(el, i, -1, int64_t(in_.offset()),
                          "unexpected end of data (file truncated?)");
            continue;
        }
        if (count < 3 && !is_strip(el))
            fail_at(el, i, "face has " + std::to_string(count) + " vertices (at least 3 needed)");
        poly_.clear();
        if (uint64_t(count) * isz <= kBlockBytes) {
            need(el, i, size_t(count) * isz);
            const char* q = in_.pos();
            for (int64_t k = 0; k < count; ++k)
                poly_.push_back(load_int<Swap>(q + k * isz, p.type));
            in_.advance(size_t(count) * isz);
        } else {
            // A huge polygon: stream it; poly_ grows only as real data arrives.
            for (int64_t k = 0; k < count; ++k) {
                need(el, i, isz);
                poly_.push_back(load_int<Swap>(in_.pos(), p.type));
                in_.advance(isz);
            }
        }
        have_face = true;
    }
    if (is_vertex) store_vertex(el, i, v);
    if (have_face && is_strip(el))
        emit_strip(el, i, poly_.data(), poly_.size());
    else if (have_face)
        emit_face(el, i, poly_.data(), poly_.size());
}

// Face element holding only the index list with uchar count: the layout of nearly every
// scanned mesh. Decoded straight from the buffer: runs of valid triangles with 4-byte indices
// are collected in a small array (in L1) and appended by one insert each, so the loop keeps
// its state in registers and checks no capacity per triangle; any other record (a polygon,
// an invalid or degenerate face, one cut by the window end, other index types) takes the
// record-by-record path.
template <bool Swap>
void PlyParser::read_binary_faces_fast(Element& el) {
    const Property& p = el.props[0];
    const size_t isz = type_size(p.type);
    constexpr size_t kRun = 1024;  // 12 KiB of triangles
    Vec3u run[kRun + 1];           // + 1: decode_triangles writes past the last
    // Signed indices are valid below 2^31 however many vertices the header declares.
    const uint32_t limit =
        uint32_t(p.type == PlyType::i32 ? std::min<uint64_t>(vertex_count_, uint64_t(INT32_MAX) + 1)
                                        : vertex_count_);
    const bool runs = isz == 4;
    int64_t idx[3];
    for (uint64_t i = 0; i < el.count;) {
        if (runs && bad_vertex_.empty()) {
            const size_t n = size_t(std::min<uint64_t>(
                {el.count - i, uint64_t(in_.avail() / kTriangleRecord), uint64_t(kRun)}));
            const size_t k = decode_triangles<Swap>(in_.pos(), n, limit, run);
            mesh_.triangles.insert(mesh_.triangles.end(), run, run + k);
            source_faces_ += k;
            in_.advance(k * kTriangleRecord);
            i += k;
            if (k == kRun) continue;
            if (i == el.count) break;
        }
        record_offset_ = in_.offset();
        if (in_.avail() < 1 + 3 * isz) need(el, i, 1 + 3 * isz);
        const char* r = in_.pos();
        if (uint8_t(*r) != 3) {
            read_binary_record<Swap>(el, i++);
            continue;
        }
        for (int k = 0; k < 3; ++k) idx[k] = load_int<Swap>(r + 1 + isz * k, p.type);
        in_.advance(1 + 3 * isz);
        emit_face(el, i++, idx, 3);
    }
}

template <bool Swap>
void PlyParser::read_binary_element(Element& el) {
    const bool is_vertex = &el == &elements_[size_t(vertex_el_)];
    const bool is_face = face_el_ >= 0 && &el == &elements_[size_t(face_el_)];
    if (is_vertex && !el.has_lists) {
        read_binary_vertices_fixed<Swap>(el);
    } else if (is_face && el.props.size() == 1 && el.props[0].count_type == PlyType::u8) {
        read_binary_faces_fast<Swap>(el);
    } else if (!is_vertex && !is_face && !el.has_lists) {
        record_offset_ = in_.offset();
        if (!in_.skip(el.count * el.scalar_bytes))
            fail_data(el, (in_.offset() - record_offset_) / std::max<size_t>(el.scalar_bytes, 1),
                      -1, int64_t(in_.offset()), "unexpected end of data (file truncated?)");
    } else {
        for (uint64_t i = 0; i < el.count; ++i) read_binary_record<Swap>(el, i);
    }
}

// ---- ascii --------------------------------------------------------------------------------

// The next non-blank line; false at the end of the data.
bool PlyParser::next_data_line(const char*& b, const char*& e) {
    auto too_long = [&] {
        ErrorLocation w;
        w.path = reader_.path();
        w.line = line_ + 1;
        throw Error(w, "line longer than 256 MiB");
    };
    while (in_.next_line(b, e, too_long)) {
        ++line_;
        if (skip_blanks(b, e) != e) return true;
    }
    return false;
}

// Fast paths: parse one element straight from the buffer, without finding the line end
// first; a newline ends the last token. They return false, consuming nothing, on anything
// unusual (blank line, line cut by the buffer end, bad value, extra values), and the
// caller then takes the line-based general path, which also reports the errors.
// Line-at-once versions of the fast paths (see classify_line): the same results, false on
// anything they do not take (the fast paths then try token by token).
[[gnu::always_inline]] inline bool PlyParser::line_ascii_scalars(const Element& el, const char*& p,
                                                                 const char* e, float* v) const {
    if constexpr (!kHaveLineClasses) return false;
    const LineClasses c = classify_line(p);
    const int len = line_length(c, p, e);
    if (len <= 0) return false;
    const uint64_t line = low_bits(len);
    const uint64_t tok = line & ~c.blank;
    if (tok & ~(c.digit | c.dot | c.minus)) return false;
    uint64_t starts = tok & ~(tok << 1);
    uint64_t ends = tok & ~(tok >> 1);  // last byte of each token
    if (size_t(__builtin_popcountll(starts)) != el.props.size()) return false;
    const char* le = p + len;
    for (const Property& prop : el.props) {
        const int s = __builtin_ctzll(starts);
        const int n = __builtin_ctzll(ends) - s + 1;
        starts &= starts - 1;
        ends &= ends - 1;
        if (prop.slot < 0) continue;
        const char* t = p + s;
        if (prop.type == PlyType::f32) {
            const uint64_t m = low_bits(n);
            if (!parse_plain_decimal(t, n, (c.dot >> s) & m, (c.minus >> s) & m, v[prop.slot]) &&
                !parse_real(t, le, v[prop.slot]))
                return false;
        } else if (prop.type == PlyType::f64) {
            const uint64_t m = low_bits(n);
            double d;
            if (!parse_plain_decimal(t, n, (c.dot >> s) & m, (c.minus >> s) & m, d) &&
                !parse_real(t, le, d))
                return false;
            v[prop.slot] = float(d);
        } else {
            int64_t x;
            if (parse_int(t, le, x) != IntResult::ok || x < type_min(prop.type) ||
                x > type_max(prop.type))
                return false;
            v[prop.slot] = float(x) * prop.scale;
        }
    }
    p = le + 1;
    return true;
}

// "3 a b c" with indices of up to 8 digits.
[[gnu::always_inline]] inline bool PlyParser::line_ascii_triangle(const char*& p, const char* e,
                                                                  int64_t* idx) const {
    if constexpr (!kHaveLineClasses) return false;
    const LineClasses c = classify_line(p);
    const int len = line_length(c, p, e);
    if (len <= 0 || !triangle_from_classes(c, p, len, idx)) return false;
    p += len + 1;
    return true;
}

bool PlyParser::fast_ascii_scalars(const Element& el, const char*& p, const char* e,
                                   float* v) const {
    if (line_ascii_scalars(el, p, e, v)) return true;
    for (const Property& prop : el.props) {
        p = skip_blanks(p, e);
        if (p == e || *p == '\n') return false;
        if (prop.slot < 0) {
            p = skip_token(p, e);
        } else if (prop.type == PlyType::f32) {
            if (!parse_real(p, e, v[prop.slot])) return false;
        } else if (prop.type == PlyType::f64) {
            double d;
            if (!parse_real(p, e, d)) return false;
            v[prop.slot] = float(d);
        } else {
            int64_t x;
            if (parse_int(p, e, x) != IntResult::ok || x < type_min(prop.type) ||
                x > type_max(prop.type))
                return false;
            v[prop.slot] = float(x) * prop.scale;
        }
    }
    p = skip_blanks(p, e);
    if (p < e && *p == '\n') {
        ++p;
        return true;
    }
    return p == e && in_.eof();
}

bool PlyParser::fast_ascii_triangle(const char*& p, const char* e, int64_t* idx) const {
    if (line_ascii_triangle(p, e, idx)) return true;
    p = skip_blanks(p, e);
    if (e - p < 2 || p[0] != '3' || !is_blank(p[1])) return false;
    ++p;
    for (int k = 0; k < 3; ++k) {
        p = skip_blanks(p, e);
        if (p == e || parse_int(p, e, idx[k]) != IntResult::ok) return false;
    }
    p = skip_blanks(p, e);
    if (p < e && *p == '\n') {
        ++p;
        return true;
    }
    return p == e && in_.eof();
}

// Lines from p (up to e) of an all-scalar element, or "3 a b c" faces, stored as elements
// first, first + 1, ..., at most max_lines of them; stops at the first line the fast path
// cannot take (including a line cut by e, non-finite vertices and invalid or degenerate
// faces) and never throws. Faces are written to their entries of a sized array, or appended
// when `append` (one thread). Threads call it on disjoint line ranges, so they write disjoint
// array entries.
PlyParser::LinesResult PlyParser::parse_lines(const Element& el, bool faces, bool is_vertex,
                                              const char* p, const char* e, uint64_t first,
                                              uint64_t max_lines, bool append) {
    LinesResult r;
    r.end = p;
    float v[9] = {};
    int64_t idx[3];
    const bool xyz = is_vertex && xyz_only_;
    // Byte classes of the window [p, p + have): one classification serves every line that
    // ends inside it, so finding the next line is a shift, not a dependent 64-byte load.
    LineClasses c;
    int have = 0;
#ifdef KDT_PLY_VBMI
    __m512i wd = _mm512_setzero_si512();  // digit values of the window
    int off = 0;                          // p's offset in the window
#endif
    while (p < e && r.lines < max_lines) {
        const char* q = p;
        const size_t k = size_t(first + r.lines);
        int len = -1;
        if (kHaveLineClasses && (faces || xyz)) {
            if (have == 0 || (c.newline == 0 && have < 64)) {
                c = classify_line(p);
                have = int(std::min<ptrdiff_t>(64, e - p));
                c.newline &= low_bits(have);
#ifdef KDT_PLY_VBMI
                wd = window_digits(p);
                off = 0;
#endif
            }
            if (c.newline) len = __builtin_ctzll(c.newline);
        }
        if (faces) {
            int64_t ix[3];  // registers; idx[] is the token path's, in memory
#ifdef KDT_PLY_VBMI
            const bool line_ok = len > 0 && triangle_vbmi(c, wd, off, p, len, ix);
#else
            const bool line_ok = len > 0 && triangle_from_classes(c, p, len, ix);
#endif
            if (line_ok) {
                q = p + len + 1;
            } else {
                if (!fast_ascii_triangle(q, e, idx)) break;
                ix[0] = idx[0], ix[1] = idx[1], ix[2] = idx[2];
                have = 0;
            }
            if (uint64_t(ix[0]) >= vertex_count_ || uint64_t(ix[1]) >= vertex_count_ ||
                uint64_t(ix[2]) >= vertex_count_ || ix[0] == ix[1] || ix[1] == ix[2] ||
                ix[0] == ix[2])
                break;
            const Vec3u t{uint32_t(ix[0]), uint32_t(ix[1]), uint32_t(ix[2])};
            if (append)
                mesh_.triangles.push_back(t);
            else
                mesh_.triangles[k] = t;
        } else if (xyz) {
            Vec3f pos;
#ifdef KDT_PLY_VBMI
            const bool line_ok =
                len > 0 && (xyz_vbmi(c, wd, off, len, pos) || xyz_from_classes(c, p, len, pos));
#else
            const bool line_ok = len > 0 && xyz_from_classes(c, p, len, pos);
#endif
            if (line_ok) {
                q = p + len + 1;
            } else {
                if (!fast_ascii_scalars(el, q, e, v)) break;
                pos = Vec3f(v[kPosX], v[kPosY], v[kPosZ]);
                have = 0;
            }
            if (!is_finite(pos)) break;
            mesh_.positions[k] = pos;
        } else {
            if (!line_ascii_scalars(el, q, e, v) && !fast_ascii_scalars(el, q, e, v)) break;
            if (is_vertex) {
                // Exponent bits per coordinate, read back one float at a time: a wider load of
                // v[] would wait for the three separate stores (no store forwarding).
                const uint32_t bx = std::bit_cast<uint32_t>(v[kPosX]);
                const uint32_t by = std::bit_cast<uint32_t>(v[kPosY]);
                const uint32_t bz = std::bit_cast<uint32_t>(v[kPosZ]);
                constexpr uint32_t kExp = 0x7f800000u;
                if ((bx & kExp) == kExp || (by & kExp) == kExp || (bz & kExp) == kExp) break;
                Vec3f& pos = mesh_.positions[k];
                pos.x = std::bit_cast<float>(bx);
                pos.y = std::bit_cast<float>(by);
                pos.z = std::bit_cast<float>(bz);
                if (has_normals_) mesh_.normals[k] = Vec3f(v[kNormX], v[kNormY], v[kNormZ]);
                if (has_colors_) mesh_.colors[k] = Vec3f(v[kColR], v[kColG], v[kColB]);
            }
        }
        if (have > 0) {
            // Move the window's classes on to the next line (or drop them at its end).
            const int shift = int(q - p);
            if (shift >= have) {
                have = 0;
            } else {
                c.digit >>= shift;
                c.blank >>= shift;
                c.dot >>= shift;
                c.minus >>= shift;
                c.newline >>= shift;
                have -= shift;
#ifdef KDT_PLY_VBMI
                off += shift;
#endif
            }
        }
        p = q;
        ++r.lines;
        r.end = p;
    }
    return r;
}

// Parses the complete lines in the buffer (up to the element's end) in one tight loop. One
// thread runs it straight over the buffer. Two threads take half of the bytes each, split at
// a newline; the second half's first element index comes from counting newlines in the
// first. Returns how many elements were committed; 0 means "take the serial path for the
// next line" (small input, partial state, or a line the fast path cannot take, which the
// serial path then parses or reports). `poor` tells the caller to stay serial for the rest of
// the element (two threads: nothing or under half the chunk committed).
uint64_t PlyParser::parallel_chunk(const Element& el, uint64_t i, bool faces, bool is_vertex,
                                   bool& poor) {
    constexpr size_t kMinChunk = size_t(256) << 10;
    const uint64_t remaining = el.count - i;
    if (in_.avail() < kMinChunk && !in_.eof()) in_.fill(in_.capacity());
    if (threads_ == 1) {
        // No newline count: the loop stops at the element's end, the first line it cannot
        // take, or the line cut by the buffer end, and costs nothing when it stops at once.
        poor = false;
        if (faces && (mesh_.triangles.size() != i || !bad_vertex_.empty())) {
            poor = true;
            return 0;
        }
        LinesResult r =
            parse_lines(el, faces, is_vertex, in_.pos(), in_.end(), i, remaining, faces);
        if (faces) source_faces_ += r.lines;
        in_.advance(size_t(r.end - in_.pos()));
        line_ += int64_t(r.lines);
        return r.lines;
    }
    // Every early exit turns the parallel path off for the rest of the element, so no
    // buffer is ever scanned once per line.
    poor = true;
    if (faces && (mesh_.triangles.size() != i || !bad_vertex_.empty())) return 0;
    const char* b = in_.pos();
    const char* e = in_.end();
    if (size_t(e - b) < kMinChunk) return 0;
    const void* last = memrchr(b, '\n', size_t(e - b));
    if (!last) return 0;
    e = static_cast<const char*>(last) + 1;
    if (!helper_) {
        try {
            helper_ = std::make_unique<Helper>();
        } catch (const std::system_error&) {
            threads_ = 1;  // no second thread to be had: one thread from now on
            poor = false;
            return 0;
        }
    }
    // Pieces of about kPieceBytes, cut after a newline; the threads count each piece's
    // lines, the prefix sums give each piece its first element index, and the threads
    // parse the pieces.
    constexpr size_t kPieceBytes = size_t(64) << 10;
    std::vector<const char*> cut{b};
    while (size_t(e - cut.back()) > kPieceBytes) {
        const char* q = cut.back() + kPieceBytes;
        cut.push_back(static_cast<const char*>(std::memchr(q, '\n', size_t(e - q))) + 1);
    }
    if (cut.back() != e) cut.push_back(e);
    const size_t pieces = cut.size() - 1;
    std::vector<uint64_t> lines(pieces), first(pieces);
    helper_->parallel_for(pieces, [&](size_t k) { lines[k] = count_newlines(cut[k], cut[k + 1]); });
    uint64_t total = 0;
    size_t used = 0;
    for (; used < pieces && total < remaining; ++used) {
        first[used] = total;
        // The element ends inside this piece: parse only its own lines.
        lines[used] = std::min(lines[used], remaining - total);
        total += lines[used];
    }
    if (faces) mesh_.triangles.resize(size_t(i + total));
    std::vector<LinesResult> result(used);
    helper_->parallel_for(used, [&](size_t k) {
        result[k] =
            parse_lines(el, faces, is_vertex, cut[k], cut[k + 1], i + first[k], lines[k], false);
    });
    // Commit the pieces up to and including the first one the fast path stopped in.
    uint64_t done = 0;
    const char* end = b;
    for (size_t k = 0; k < used; ++k) {
        done += result[k].lines;
        end = result[k].end;
        if (result[k].lines != lines[k]) break;
    }
    if (faces) {
        mesh_.triangles.resize(size_t(i + done));
        source_faces_ += done;
    }
    poor = done < total / 2;
    in_.advance(size_t(end - in_.pos()));
    line_ += int64_t(done);
    return done;
}

void PlyParser::read_ascii_element(Element& el) {
    const bool is_vertex = &el == &elements_[size_t(vertex_el_)];
    const bool is_face = face_el_ >= 0 && &el == &elements_[size_t(face_el_)];
    const bool face_fast = is_face && el.props.size() == 1;
    const char* b;
    const char* e;
    float v[9] = {};
    const bool scalars_fast = !el.has_lists;
    // The tight loop over whole buffers, on one thread or two.
    bool parallel = scalars_fast || face_fast;
    uint64_t misses = 0, hits = 0;
    for (uint64_t i = 0; i < el.count; ++i) {
        if (parallel) {
            uint64_t before = i;
            bool poor = false;
            uint64_t done = parallel_chunk(el, i, face_fast, is_vertex, poor);
            hits += done;
            // Inputs the fast path keeps rejecting (say, blank lines or quads everywhere) go
            // serial, so no line is tried twice for long.
            if (done == 0 && ++misses > 64 && misses * 16 > hits) poor = true;
            if (poor) parallel = false;
            if (done > 0) {
                i = before + done - 1;
                continue;
            }
        }
        if (scalars_fast || face_fast) {
            // A partial line at the buffer end fails the fast path; refill early instead.
            if (in_.avail() < 256 && !in_.eof()) in_.fill(256);
            const char* p = in_.pos();
            int64_t idx[3];
            if (scalars_fast ? fast_ascii_scalars(el, p, in_.end(), v)
                             : fast_ascii_triangle(p, in_.end(), idx)) {
                in_.advance(size_t(p - in_.pos()));
                ++line_;
                if (is_vertex) {
                    store_vertex(el, i, v);
                } else if (face_fast) {
                    if (uint64_t(idx[0]) < vertex_count_ && uint64_t(idx[1]) < vertex_count_ &&
                        uint64_t(idx[2]) < vertex_count_ && bad_vertex_.empty() &&
                        idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2]) {
                        ++source_faces_;
                        mesh_.triangles.emplace_back(uint32_t(idx[0]), uint32_t(idx[1]),
                                                     uint32_t(idx[2]));
                    } else {
                        emit_face(el, i, idx, 3);
                    }
                }
                continue;
            }
        }
        if (!next_data_line(b, e))
            fail_data(el, i, line_ + 1, -1,
                      "unexpected end of data (file truncated? the header declares " +
                          std::to_string(el.count) + " " + el.name + " elements)");
        const char* p = b;
        bool have_face = false;
        for (const Property& prop : el.props) {
            p = skip_blanks(p, e);
            if (p == e)
                fail_at(el, i, "missing value for property " + prop.name + " (line too short)");
            if (!prop.is_list()) {
                if (prop.slot < 0) {
                    p = skip_token(p, e);
                    continue;
                }
                bool ok = true;
                if (prop.type == PlyType::f32) {
                    ok = parse_real(p, e, v[prop.slot]);
                } else if (prop.type == PlyType::f64) {
                    double d = 0;
                    ok = parse_real(p, e, d);
                    v[prop.slot] = float(d);
                } else {
                    int64_t x = 0;
                    const char* start = p;
                    IntResult r = parse_int(p, e, x);
                    ok = r == IntResult::ok;
                    if (ok && (x < type_min(prop.type) || x > type_max(prop.type)))
                        fail_at(el, i,
                                "value " + token_text(start, e) + " of property " + prop.name +
                                    " out of range for its type");
                    v[prop.slot] = float(x) * prop.scale;
                }
                if (!ok)
                    fail_at(el, i,
                            "invalid number '" + token_text(p, e) + "' for property " + prop.name);
                continue;
            }
            int64_t count = 0;
            const char* start = p;
            IntResult r = parse_int(p, e, count);
            if (r != IntResult::ok || count > type_max(prop.count_type) ||
                count < type_min(prop.count_type))
                fail_at(el, i,
                        "invalid list count '" + token_text(start, e) + "' for " + prop.name);
            if (count < 0)
                fail_at(el, i, "negative list count " + std::to_string(count) + " in " + prop.name);
            if (prop.slot != kIndices) {
                for (int64_t k = 0; k < count; ++k) {
                    p = skip_blanks(p, e);
                    if (p == e)
                        fail_at(el, i,
                                "list " + prop.name + " has " + std::to_string(k) + " of " +
                                    std::to_string(count) + " values");
                    p = skip_token(p, e);
                }
                continue;
            }
            if (count < 3 && !is_strip(el))
                fail_at(el, i,
                        "face has " + std::to_string(count) + " vertices (at least 3 needed)");
            poly_.clear();
            for (int64_t k = 0; k < count; ++k) {
                p = skip_blanks(p, e);
                if (p == e)
                    fail_at(el, i,
                            "face lists " + std::to_string(k) + " of " + std::to_string(count) +
                                " vertex indices");
                int64_t x = 0;
                const char* s = p;
                if (parse_int(p, e, x) != IntResult::ok)
                    fail_at(el, i, "invalid vertex index '" + token_text(s, e) + "'");
                poly_.push_back(x);
            }
            have_face = true;
        }
        if (skip_blanks(p, e) != e)
            fail_at(el, i,
                    "more values on the line than the header declares ('" +
                        token_text(skip_blanks(p, e), e) + "' after the last property)");
        if (is_vertex) store_vertex(el, i, v);
        if (have_face && is_strip(el))
            emit_strip(el, i, poly_.data(), poly_.size());
        else if (have_face)
            emit_face(el, i, poly_.data(), poly_.size());
    }
}

// ---- driver ---------------------------------------------------------------------------------

void PlyParser::finish(TriangleMesh& mesh) {
    if (bad_vertices_ == 0) return;
    // Faces read before the vertices could not see the flags: drop their triangles now.
    std::vector<Vec3u> kept;
    kept.reserve(mesh.triangles.size());
    for (const Vec3u& t : mesh.triangles) {
        if (bad_vertex_[t.x] || bad_vertex_[t.y] || bad_vertex_[t.z]) {
            ++dropped_faces_;
            continue;
        }
        kept.push_back(t);
    }
    mesh.triangles.swap(kept);
    // Remove the non-finite vertices so bounds and builders never see them.
    std::vector<uint32_t> remap(mesh.positions.size());
    uint32_t n = 0;
    for (size_t k = 0; k < mesh.positions.size(); ++k) {
        remap[k] = n;
        if (bad_vertex_[k]) continue;
        mesh.positions[n] = mesh.positions[k];
        if (!mesh.normals.empty()) mesh.normals[n] = mesh.normals[k];
        if (!mesh.colors.empty()) mesh.colors[n] = mesh.colors[k];
        ++n;
    }
    mesh.positions.resize(n);
    if (!mesh.normals.empty()) mesh.normals.resize(n);
    if (!mesh.colors.empty()) mesh.colors.resize(n);
    for (Vec3u& t : mesh.triangles) t = Vec3u(remap[t.x], remap[t.y], remap[t.z]);
}

TriangleMesh PlyParser::parse(MeshLoadInfo* info) {
    Timer timer;
    parse_header();
    plan_elements();
    check_counts();

    // Huge pages for the output arrays before anything touches them: first-touch faults of
    // 4 KiB pages would cost more than parsing a binary file.
    reserve_huge(mesh_.positions, vertex_count_);
    // read_binary_vertices_fixed appends the positions; other layouts write them by index.
    if (ascii_ || elements_[size_t(vertex_el_)].has_lists) mesh_.positions.resize(vertex_count_);
    if (has_normals_) {
        reserve_huge(mesh_.normals, vertex_count_);
        mesh_.normals.resize(vertex_count_);
    }
    if (has_colors_) {
        reserve_huge(mesh_.colors, vertex_count_);
        mesh_.colors.resize(vertex_count_);
    }
    if (face_el_ >= 0) reserve_huge(mesh_.triangles, elements_[size_t(face_el_)].count);

    line_ = header_lines_;
    for (Element& el : elements_) {
        if (ascii_)
            read_ascii_element(el);
        else if (swap_)
            read_binary_element<true>(el);
        else
            read_binary_element<false>(el);
        if (&el == &elements_[size_t(vertex_el_)]) vertices_read_ = true;
    }
    if (ascii_) {
        const char* b;
        const char* e;
        if (next_data_line(b, e)) {
            ErrorLocation w;
            w.path = reader_.path();
            w.line = line_;
            throw Error(w, "data after the last element ('" + token_text(skip_blanks(b, e), e) +
                               "'): the header's element counts do not match the data");
        }
    }
    finish(mesh_);
    if (info) {
        info->format = "ply";
        info->encoding = kPlyEncodingNames[size_t(encoding_)];
        info->gzip = reader_.gzip();
        info->file_bytes = in_.offset();
        info->source_faces = source_faces_;
        info->dropped_faces = dropped_faces_;
        info->degenerate_faces = degenerate_faces_;
        info->seconds = timer.seconds();
    }
    return std::move(mesh_);
}

}  // namespace

TriangleMesh read_ply(FileReader& reader, const MeshLoadOptions& options, MeshLoadInfo* info) {
    PlyParser parser(reader, options);
    return parser.parse(info);
}

TriangleMesh read_ply(const std::string& path, const MeshLoadOptions& options, MeshLoadInfo* info) {
    FileReader reader = FileReader::open(path);
    return read_ply(reader, options, info);
}

TriangleMesh read_ply_memory(const void* data, size_t size, const std::string& name,
                             const MeshLoadOptions& options, MeshLoadInfo* info) {
    FileReader reader = FileReader::from_memory(data, size, name);
    return read_ply(reader, options, info);
}

}  // namespace kdt
