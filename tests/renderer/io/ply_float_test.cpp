// Exactness tests of the ascii PLY number parsers (renderer/io/ply_reader): random decimal
// strings of every shape must give the bits std::from_chars gives, whichever of the reader's
// paths (whole line, token by token, from_chars itself) takes them, on one thread or two;
// random face lines must give their indices.
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_reader.h"

namespace kdt {
namespace {

// A random decimal: sign (none, '-', or rarely '+'), 1-20 mantissa digits with leading zeros
// at times, a dot anywhere (or none), an exponent at times.
std::string random_decimal(std::mt19937& rng) {
    auto pick = [&](int n) { return int(rng() % uint32_t(n)); };
    std::string s;
    int sign = pick(10);
    if (sign < 4) s += '-';
    if (sign == 4) s += '+';
    const int digits = 1 + pick(20);
    std::string m;
    int zeros = pick(4) == 0 ? pick(6) : 0;
    for (int k = 0; k < digits; ++k) m += char('0' + (k < zeros ? 0 : pick(10)));
    int dot = pick(digits + 2) - 1;  // -1: no dot; digits: trailing dot
    if (dot >= 0) m.insert(size_t(dot), ".");
    s += m;
    if (pick(4) == 0) {
        s += pick(2) ? 'e' : 'E';
        int r = pick(3);
        if (r == 0) s += '-';
        if (r == 1) s += '+';
        s += std::to_string(pick(3) == 0 ? pick(60) : pick(10));
    }
    return s;
}

// Hand-picked edge cases: subnormals, the float range's ends, overflow, halfway cases.
const char* const kEdgeCases[] = {
    "1e-45",
    "-1e-45",
    "1.4e-45",
    "7e-46",
    "8e-46",
    "1e-46",
    "1e-50",
    "-1e-50",
    "1.17549435e-38",
    "1.1754942e-38",
    "3e-39",
    "3.4028235e38",
    "3.40282347e38",
    "3.4028236e38",
    "-3.4028236e38",
    "3.40282357e38",
    "1e39",
    "-1e39",
    "16777216",
    "16777217",
    "16777218",
    "16777219",
    "33554433",
    "0.1",
    "0.2",
    "0.30000001",
    "1.00000006",
    "1.00000005960464477539062",
    "0",
    "-0",
    "-0.0",
    "0.000",
    ".5",
    "5.",
    "-.5",
    "+7",
    "+.25",
    "0000000000001",
    "9007199254740993",
    "123456789.12345678",
    "12345678.12345678",
    "99999999.99999999",
    "1e22",
    "1e23",
    "4.7019774e-38",
    "2.5e-8",
    "0.0503644",
    "-0.0503644",
};

// What the reader defines for a float or double property written as `s`: from_chars's
// value; when from_chars reports the value out of range, strtod's, narrowed (an infinity for
// overflow, a zero for underflow). A leading '+' is accepted.
template <typename T>
float expected_value(const std::string& s, bool* out_of_range) {
    const char* b = s.c_str();
    if (*b == '+') ++b;
    T v = 0;
    auto r = std::from_chars(b, s.c_str() + s.size(), v);
    EXPECT_EQ(r.ptr, s.c_str() + s.size()) << s;
    *out_of_range = r.ec == std::errc::result_out_of_range;
    if (*out_of_range) return float(T(std::strtod(b, nullptr)));
    EXPECT_EQ(r.ec, std::errc()) << s;
    return float(v);
}

TEST(PlyFloat, RandomDecimalsMatchFromChars) {
    std::mt19937 rng(20261122);
    std::vector<std::string> tokens;
    for (const char* s : kEdgeCases) tokens.emplace_back(s);
    while (tokens.size() < 60000) tokens.push_back(random_decimal(rng));
    // Three values a line in nx (float), ny (float) and nz (double), so non-finite results
    // are kept as read; x y z stay zero. Short lines go through the whole-line parser, long
    // ones (and exponents) token by token.
    const size_t n = tokens.size() / 3;
    std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
                       "\nproperty float x\nproperty float y\nproperty float z\n"
                       "property float nx\nproperty float ny\nproperty double nz\nend_header\n";
    std::vector<float> expect(3 * n);
    int out_of_range = 0;
    for (size_t i = 0; i < n; ++i) {
        text += i % 2 ? "0 0 0 " : "0\t0 0  ";
        for (size_t k = 0; k < 3; ++k) {
            const std::string& s = tokens[3 * i + k];
            bool oor = false;
            expect[3 * i + k] =
                k < 2 ? expected_value<float>(s, &oor) : expected_value<double>(s, &oor);
            if (oor && k < 2) {
                EXPECT_TRUE(std::isinf(expect[3 * i + k]) || expect[3 * i + k] == 0.0f) << s;
                ++out_of_range;
            }
            text += s + (k < 2 ? " " : (i % 3 ? "\n" : " \r\n"));
        }
    }
    EXPECT_GT(out_of_range, 10);  // the edge cases and large exponents reach both ends
    for (int threads : {1, 2}) {
        MeshLoadOptions options;
        options.threads = threads;
        TriangleMesh m = read_ply_memory(text.data(), text.size(), "floats.ply", options);
        ASSERT_EQ(m.normals.size(), n);
        int wrong = 0;
        for (size_t i = 0; i < n; ++i) {
            for (int k = 0; k < 3; ++k) {
                const uint32_t got = std::bit_cast<uint32_t>(m.normals[i][k]);
                const uint32_t want = std::bit_cast<uint32_t>(expect[3 * i + size_t(k)]);
                if (got != want && ++wrong <= 10)
                    ADD_FAILURE() << "'" << tokens[3 * i + size_t(k)] << "' read as "
                                  << m.normals[i][k] << ", from_chars gives "
                                  << expect[3 * i + size_t(k)] << " (threads " << threads << ")";
            }
        }
        EXPECT_EQ(wrong, 0);
    }
    // The same tokens as x y z only (the reader's vertex fast path), finite ones only since
    // a non-finite position is an error.
    std::vector<float> want;
    std::string xyz;
    size_t in_line = 0;
    for (size_t i = 0; i < tokens.size(); ++i) {
        if (!std::isfinite(expect[i])) continue;
        want.push_back(expect[i]);
        xyz += tokens[i] + (++in_line % 3 ? " " : "\n");
    }
    want.resize(want.size() / 3 * 3);
    xyz.resize(xyz.rfind('\n') + 1);
    const size_t nv = want.size() / 3;
    xyz = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(nv) +
          "\nproperty float x\nproperty float y\nproperty float z\nend_header\n" + xyz;
    for (int threads : {1, 2}) {
        MeshLoadOptions options;
        options.threads = threads;
        TriangleMesh m = read_ply_memory(xyz.data(), xyz.size(), "xyz.ply", options);
        ASSERT_EQ(m.positions.size(), nv);
        int wrong = 0;
        for (size_t i = 0; i < nv; ++i)
            for (int k = 0; k < 3; ++k)
                wrong += std::bit_cast<uint32_t>(m.positions[i][k]) !=
                         std::bit_cast<uint32_t>(want[3 * i + size_t(k)]);
        EXPECT_EQ(wrong, 0) << "threads " << threads;
    }
}

// Short plain decimals only (the whole-line path's domain), every digit split of up to 8 + 8
// digits, against from_chars.
TEST(PlyFloat, PlainDecimalsEverySplit) {
    std::mt19937 rng(7);
    std::string text;
    std::vector<std::string> tokens;
    for (int a = 0; a <= 9; ++a) {
        for (int b = 0; b <= 9; ++b) {
            if (a + b == 0) continue;
            for (int rep = 0; rep < 60; ++rep) {
                std::string s = rng() % 2 ? "-" : "";
                for (int k = 0; k < a; ++k) s += char('0' + rng() % 10);
                if (b > 0 || rng() % 2) s += '.';
                for (int k = 0; k < b; ++k) s += char('0' + rng() % 10);
                tokens.push_back(s);
            }
        }
    }
    const size_t n = tokens.size();
    text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
           "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    for (const std::string& s : tokens) text += "1 " + s + " -2.5\n";
    TriangleMesh m = read_ply_memory(text.data(), text.size(), "plain.ply");
    ASSERT_EQ(m.positions.size(), n);
    int wrong = 0;
    for (size_t i = 0; i < n; ++i) {
        bool oor = false;
        float want = expected_value<float>(tokens[i], &oor);
        EXPECT_FALSE(oor);
        if (std::bit_cast<uint32_t>(m.positions[i].y) != std::bit_cast<uint32_t>(want) &&
            ++wrong <= 10)
            ADD_FAILURE() << "'" << tokens[i] << "' read as " << m.positions[i].y
                          << ", from_chars gives " << want;
        EXPECT_EQ(m.positions[i].x, 1.0f);
        EXPECT_EQ(m.positions[i].z, -2.5f);
    }
    EXPECT_EQ(wrong, 0);
}

// Decimals on and next to the midpoint between two floats, where rounding the decimal to a
// double first and then to float could go wrong: exact midpoints of floats in [2^16, 2^26)
// (at most 8 + 8 digits, the whole-line path) and their neighbours 1e-8 apart, 16-digit
// roundings of midpoints of floats in [1e-6, 1e6) (the token path) and 14-decimal roundings
// of midpoints in [0.25, 8), a few double ulps away from them (the whole-line path).
TEST(PlyFloat, NearFloatMidpoints) {
    std::mt19937 rng(2024);
    std::vector<std::string> tokens;
    char buf[64];
    for (int i = 0; i < 6000; ++i) {
        const int e = 16 + int(rng() % 10);
        const float f = std::ldexp(1.0f + float(rng() % (1u << 23)) * 0x1p-23f, e);
        const double mid = 0.5 * (double(f) + double(std::nextafter(f, INFINITY)));
        const auto scaled = uint64_t(mid * 1e8);  // exact: mid has at most 8 fraction digits
        for (int64_t d : {0, -1, 1, -2, 2}) {
            const uint64_t v = scaled + uint64_t(d);
            std::snprintf(buf, sizeof buf, "%llu.%08llu", (unsigned long long)(v / 100000000),
                          (unsigned long long)(v % 100000000));
            tokens.emplace_back(buf);
        }
        const float g =
            std::ldexp(1.0f + float(rng() % (1u << 23)) * 0x1p-23f, int(rng() % 40) - 20);
        const double gmid = 0.5 * (double(g) + double(std::nextafter(g, INFINITY)));
        std::snprintf(buf, sizeof buf, "%.15e", gmid);
        tokens.emplace_back(buf);
        // 14-decimal roundings of midpoints in [0.25, 8): 16 bytes, a few double ulps off.
        const float h = std::ldexp(1.0f + float(rng() % (1u << 23)) * 0x1p-23f, int(rng() % 5) - 2);
        const double hmid = 0.5 * (double(h) + double(std::nextafter(h, INFINITY)));
        std::snprintf(buf, sizeof buf, "%s%.14f", rng() % 2 ? "-" : "", hmid);
        tokens.emplace_back(buf);
    }
    const size_t n = tokens.size();
    std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
                       "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    for (const std::string& s : tokens) text += "0 " + s + " 0\n";
    TriangleMesh m = read_ply_memory(text.data(), text.size(), "midpoints.ply");
    ASSERT_EQ(m.positions.size(), n);
    int wrong = 0;
    for (size_t i = 0; i < n; ++i) {
        bool oor = false;
        const float want = expected_value<float>(tokens[i], &oor);
        if (std::bit_cast<uint32_t>(m.positions[i].y) != std::bit_cast<uint32_t>(want) &&
            ++wrong <= 10)
            ADD_FAILURE() << "'" << tokens[i] << "' read as " << m.positions[i].y
                          << ", from_chars gives " << want;
    }
    EXPECT_EQ(wrong, 0);
}

// Face lines in many spellings (blanks, tabs, CR, leading zeros, long indices, trailing
// blanks) must give their indices on one thread and two.
TEST(PlyFloat, FaceLinesInEverySpelling) {
    std::mt19937 rng(99);
    const uint32_t nv = 1100000;  // up to 7-digit indices
    const size_t nf = 40000;
    auto blank = [&] {
        const char* kBlanks[] = {" ", " ", " ", "  ", "\t", " \t "};
        return std::string(kBlanks[rng() % 6]);
    };
    std::string faces;
    std::vector<Vec3u> expect;
    for (size_t f = 0; f < nf; ++f) {
        uint32_t i[3];
        do {
            for (uint32_t& x : i) x = rng() % 3 == 0 ? rng() % 100 : rng() % nv;
        } while (i[0] == i[1] || i[1] == i[2] || i[0] == i[2]);
        expect.emplace_back(i[0], i[1], i[2]);
        std::string line = rng() % 8 == 0 ? blank() : "";
        line += "3";
        for (uint32_t x : i) {
            line += blank();
            if (rng() % 8 == 0) line += std::string(rng() % 6, '0');
            line += std::to_string(x);
        }
        if (rng() % 3 == 0) line += blank();
        if (rng() % 10 == 0) line += "\r";
        faces += line + "\n";
    }
    // Vertices are cheap single zeros; the index range is what matters.
    std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(nv) +
                       "\nproperty float x\nproperty float y\nproperty float z\n"
                       "element face " +
                       std::to_string(nf) +
                       "\nproperty list uchar int vertex_indices\nend_header\n";
    text.reserve(text.size() + size_t(nv) * 6 + faces.size());
    for (uint32_t v = 0; v < nv; ++v) text += "0 0 0\n";
    text += faces;
    for (int threads : {1, 2}) {
        MeshLoadOptions options;
        options.threads = threads;
        MeshLoadInfo info;
        TriangleMesh m = read_ply_memory(text.data(), text.size(), "faces.ply", options, &info);
        ASSERT_EQ(m.positions.size(), size_t(nv));
        EXPECT_EQ(m.triangles, expect) << "threads " << threads;
        EXPECT_EQ(info.source_faces, nf);
    }
}

}  // namespace
}  // namespace kdt
