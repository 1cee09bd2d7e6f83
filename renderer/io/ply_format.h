// The PLY reader's internal vocabulary: scalar types, properties and elements as the header
// declares them, and the byte classes every part of the reader shares. Internal to
// renderer/io/ply_*; depends on the standard library only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace kdt::ply {

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

inline PlyType parse_type(std::string_view s) {
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
// Input of unknown size (gzip): records the arrays hold before the data shows there are more.
constexpr uint64_t kFirstRecords = uint64_t(1) << 12;
// Blank bytes after the last ascii element looked at before the rest is taken as blank.
constexpr uint64_t kTrailingLookBytes = uint64_t(64) << 10;
// An error from gzip input that inflated at least kAbsurdInflationRatio:1 over at least
// kInflationNoteBytes says so (mesh data compresses about 2-10:1).
constexpr uint64_t kAbsurdInflationRatio = 50;
constexpr uint64_t kInflationNoteBytes = uint64_t(1) << 20;

inline bool is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}
// Ends a token: a blank, or the newline when parsing straight from the buffer.
inline bool is_sep(char c) { return is_blank(c) || c == '\n'; }
inline bool is_digit(char c) { return unsigned(c - '0') < 10u; }

}  // namespace kdt::ply
