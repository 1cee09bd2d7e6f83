// Tests of the errors of renderer/io/ply_reader: one hand-made broken file per error the
// reader reports (truncated data, impossible counts, bad indices, header and value errors,
// very long lines, a missing file), each asserting its message.

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_reader.h"
#include "tests/renderer/io/ply_test_util.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::Bytes;
using test::error_of_file;
using test::expect_same_mesh;
using test::kCubeAscii;
using test::load;
using test::write_text;

const char* kHeaderXYZ =
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

std::string xyz_body() {
    Bytes b;
    b.put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f);
    return b.s;
}

TEST(PlyReaderErrors, TruncatedBinaryData) {
    std::string full =
        std::string(kHeaderXYZ) + xyz_body() + Bytes().put(uint8_t(3)).put(0).put(1).put(2).s;
    EXPECT_EQ(load(full).triangle_count(), 1u);
    // The size check passes (a face needs at least 13 bytes) but the list says 200 indices.
    std::string t =
        std::string(kHeaderXYZ) + xyz_body() + Bytes().put(uint8_t(200)).put(0).put(1).put(2).s;
    EXPECT_ERROR(t, "test.ply: byte ");
    EXPECT_ERROR(t, "face 0: unexpected end of data (file truncated?)");
    std::string short_vertices =
        std::string(kHeaderXYZ).substr(0, std::strlen(kHeaderXYZ)) + xyz_body();
    short_vertices.replace(short_vertices.find("element face 1"), 14, "element face 0");
    EXPECT_EQ(load(short_vertices).triangle_count(), 0u);
    std::string missing = short_vertices.substr(0, short_vertices.size() - 5);
    EXPECT_ERROR(missing, "element vertex: count 3 needs at least 36 bytes");
}

TEST(PlyReaderErrors, TruncatedAsciiData) {
    // Long vertex lines so the header's size check passes; the last face line is missing.
    std::string t = kCubeAscii;
    t.replace(t.find("0.5 0.5 1"), 9, "0.500000000 0.500000000 1.000000000");
    t = t.substr(0, t.find("3 0 1 4"));
    EXPECT_ERROR(t,
                 "test.ply: line 18: face 1: unexpected end of data (file truncated? the header "
                 "declares 2 face elements)");
    std::string short_line = kCubeAscii;
    short_line.replace(short_line.find("1 1 0\n"), 6, "1 1\n");
    EXPECT_ERROR(short_line, "line 14: vertex 2: missing value for property z");
    std::string short_list = kCubeAscii;
    short_list.replace(short_list.find("3 0 1 4"), 7, "3 0 1");
    EXPECT_ERROR(short_list, "line 18: face 1: face lists 2 of 3 vertex indices");
}

// Three vertices (18 bytes at least in ascii) and two faces of three indices (8 bytes at
// least each) in 32 bytes of data: each element fits on its own, both do not.
std::string header_body_of_two_faces() {
    return "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
           "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
           "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2\n";
}

TEST(PlyReaderErrors, CountsTheFileCannotHold) {
    std::string t = kCubeAscii;
    t.replace(t.find("element vertex 5"), 16, "element vertex 999999999999");
    EXPECT_ERROR(t,
                 "test.ply: line 5: header: element vertex: 999999999999 vertices exceed the "
                 "32-bit index limit");
    t = kCubeAscii;
    t.replace(t.find("element vertex 5"), 16, "element vertex 999999999");
    EXPECT_ERROR(t,
                 "test.ply: line 5: header: element vertex: count 999999999 needs at least "
                 "5999999994 bytes, "
                 "more than the 52 bytes of data in the file");
    std::string other = kCubeAscii;
    other.replace(other.find("element face 2"), 14,
                  "element normals 999999999999\nproperty float q\nelement face 2");
    EXPECT_ERROR(other, "element normals: count 999999999999 needs at least");
    std::string b = std::string(kHeaderXYZ) + xyz_body();
    b.replace(b.find("element face 1"), 14, "element face 4000000000");
    // Lists may be empty in this check, so a face takes at least its count byte.
    EXPECT_ERROR(b, "element face: count 4000000000 needs at least 4000000000 bytes (");
    // When the element alone would fit, the message gives the total with those before it.
    std::string twenty = header_body_of_two_faces();
    twenty.replace(twenty.find("element face 2"), 14, "element face 20");
    EXPECT_ERROR(twenty,
                 "element face: count 20 needs at least 40 bytes (58 with the elements before it), "
                 "more than the 32 bytes of data in the file");
    // Two faces fit that check; the short second face is reported as read.
    EXPECT_ERROR(header_body_of_two_faces(), "line 14: face 1: face lists 2 of 3 vertex indices");
    std::string huge = kCubeAscii;
    huge.replace(huge.find("element vertex 5"), 16, "element vertex 99999999999999999999999");
    EXPECT_ERROR(huge, "element vertex: count 99999999999999999999999 is too large");
}

TEST(PlyReaderErrors, NegativeCounts) {
    std::string t = kCubeAscii;
    t.replace(t.find("element face 2"), 14, "element face -2");
    EXPECT_ERROR(t, "line 9: header: element face: negative count -2");
    std::string list = kCubeAscii;
    list.replace(list.find("3 0 1 4"), 7, "-3 0 1 4");
    list.replace(list.find("list uchar int"), 14, "list char int");
    EXPECT_ERROR(list, "line 18: face 1: negative list count -3 in vertex_indices");
    std::string bin =
        std::string(kHeaderXYZ) + xyz_body() + Bytes().put(int8_t(-1)).put(0).put(1).put(2).s;
    bin.replace(bin.find("list uchar int"), 14, "list char int");
    EXPECT_ERROR(bin, "test.ply: byte 204: face 0: negative list count -1 in vertex_indices");
}

TEST(PlyReaderErrors, IndicesOutOfRange) {
    std::string t = kCubeAscii;
    t.replace(t.find("3 0 1 4"), 7, "3 0 1 912345");
    EXPECT_ERROR(t, "test.ply: line 18: face 1: vertex index 912345 out of range (5 vertices)");
    std::string neg = kCubeAscii;
    neg.replace(neg.find("3 0 1 4"), 7, "3 0 -1 4");
    EXPECT_ERROR(neg, "face 1: vertex index -1 out of range (5 vertices)");
    std::string bin =
        std::string(kHeaderXYZ) + xyz_body() + Bytes().put(uint8_t(3)).put(0).put(1).put(3).s;
    EXPECT_ERROR(bin, "test.ply: byte 205: face 0: vertex index 3 out of range (3 vertices)");
    std::string bin_be = bin;
    bin_be.replace(bin_be.find("binary_little_endian"), 20, "binary_big_endian");
    EXPECT_ERROR(bin_be, "out of range (3 vertices)");
}

// Float and double face indices that are not integers, or out of range, in every encoding;
// --drop-invalid drops none of them, as it drops no out-of-range integer index.
TEST(PlyReaderErrors, FloatFaceIndicesThatAreNoIndices) {
    auto file = [](const std::string& format, const std::string& type, const std::string& value,
                   double x) {
        std::string head = kCubeAscii;
        head.erase(head.find("end_header\n") + 11);
        head.replace(head.find("ascii"), 5, format);
        head.replace(head.find("uchar int"), 9, "uchar " + type);
        if (format == "ascii")
            return head + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n4 0 1 2 3\n3 0 " + value + " 4\n";
        Bytes b;
        b.big = format == "binary_big_endian";
        for (int k = 0; k < 15; ++k) b.put(0.0f);
        const double idx[] = {0, 1, 2, 3, 0, x, 4};
        for (int k = 0; k < 7; ++k) {
            if (k == 0 || k == 4) b.put(uint8_t(k == 0 ? 4 : 3));
            if (type == "float")
                b.put(float(idx[k]));
            else
                b.put(idx[k]);
        }
        return head + b.s;
    };
    struct Case {
        const char* text;  // as written in ascii, and as named for binary
        double value;
        const char* problem;
    };
    const double inf = std::numeric_limits<double>::infinity();
    const Case cases[] = {
        {"1.5", 1.5, "is not an integer"},          {"-0.5", -0.5, "is not an integer"},
        {"nan", std::nan(""), "is not an integer"}, {"inf", inf, "is not an integer"},
        {"-inf", -inf, "is not an integer"},        {"-2", -2.0, "out of range (5 vertices)"},
        {"5", 5.0, "out of range (5 vertices)"},    {"1e+30", 1e30, "out of range (5 vertices)"},
    };
    MeshLoadOptions drop;
    drop.drop_invalid = true;
    for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
        for (const char* type : {"float", "double"}) {
            for (const Case& c : cases) {
                SCOPED_TRACE(std::string(format) + " " + type + " " + c.text);
                const std::string f = file(format, type, c.text, c.value);
                // Face 1 starts after the header, 5 vertices and face 0's count and 4 indices.
                const size_t isz = std::string(type) == "float" ? 4 : 8;
                const std::string where =
                    std::string(format) == "ascii"
                        ? "test.ply: line 18: face 1: "
                        : "test.ply: byte " +
                              std::to_string(f.find("end_header\n") + 11 + 60 + 1 + 4 * isz) +
                              ": face 1: ";
                const std::string want = where + "vertex index " + c.text + " " + c.problem;
                EXPECT_EQ(test::error_of(f), want);
                EXPECT_EQ(test::error_of(f, drop), want);
            }
        }
    }
}

TEST(PlyReaderErrors, FacesWithFewerThanThreeVertices) {
    std::string t = kCubeAscii;
    t.replace(t.find("3 0 1 4"), 7, "2 0 1");
    EXPECT_ERROR(t, "line 18: face 1: 2 indices, a face needs at least 3");
    std::string bin =
        std::string(kHeaderXYZ) + xyz_body() + Bytes().put(uint8_t(0)).put(0).put(1).put(2).s;
    EXPECT_ERROR(bin, "test.ply: byte 205: face 0: 0 indices, a face needs at least 3");
}

TEST(PlyReaderErrors, HeaderErrors) {
    auto with = [](const std::string& from, const std::string& to) {
        std::string t = kCubeAscii;
        t.replace(t.find(from), from.size(), to);
        return t;
    };
    EXPECT_ERROR(with("format ascii 1.0", "format ebcdic 1.0"),
                 "line 2: header: unknown format 'ebcdic'");
    for (const char* version : {"2.0", "2", "0.9", "1.x", "1.", "1.1a", "10.0", "v1.0"}) {
        EXPECT_ERROR(with("format ascii 1.0", std::string("format ascii ") + version),
                     std::string("test.ply: line 2: header: PLY version '") + version +
                         "' is not supported (versions 1.x are read, as 1.0)");
        EXPECT_ERROR(with("format ascii 1.0", std::string("format binary_big_endian ") + version),
                     std::string("PLY version '") + version + "' is not supported");
    }
    EXPECT_ERROR(with("format ascii 1.0", "format ascii 1.0 extra"),
                 "line 2: header: unknown format line 'format ascii 1.0 extra'");
    EXPECT_ERROR(with("format ascii 1.0\n", ""), "missing format line");
    EXPECT_ERROR(with("end_header\n", ""), "missing end_header");
    EXPECT_ERROR(with("ply\n", "plx\n"), "line 1: header: not a PLY file");
    EXPECT_ERROR(with("property float y", "property float16 y"),
                 "line 7: header: unknown property type 'float16'");
    EXPECT_ERROR(with("list uchar int", "list float int"),
                 "list count type 'float' is not an integer type");
    EXPECT_ERROR(with("property float y", "property float x"), "second property named 'x'");
    EXPECT_ERROR(with("property float y", "property float w"), "element vertex has no property y");
    EXPECT_ERROR(with("element vertex 5", "element vertex five"), "count 'five' is not an integer");
    EXPECT_ERROR(with("comment", "property float q\ncomment"), "property before any element");
    EXPECT_ERROR(with("vertex_indices", "corners"),
                 "element face has no list property vertex_indices");
    EXPECT_ERROR("", "test.ply: line 1: header: empty file");
    // CR-only line ends (old Mac) are named: the lines are read at LF.
    std::string cr = kCubeAscii;
    for (char& c : cr) c = c == '\n' ? '\r' : c;
    EXPECT_ERROR(cr, "test.ply: line 1: header: line ends are CR only (old Mac)");
    std::string crlf;
    for (char c : std::string(kCubeAscii))
        crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
    EXPECT_EQ(load(crlf).triangle_count(), load(kCubeAscii).triangle_count());
    // A header without end_header that goes on forever stops at 4 MiB.
    std::string endless = "ply\nformat ascii 1.0\n" + std::string(5 << 20, 'c');
    for (size_t i = 100; i < endless.size(); i += 100) endless[i] = '\n';
    EXPECT_ERROR(endless, "missing end_header");
}

// Lines longer than the read window: a header line stops at 4 MiB, and a data line of many
// MiB is read whole (the window grows geometrically, so such a line costs linear time), from
// memory and from a mapped file alike.
TEST(PlyReaderErrors, VeryLongLines) {
    const std::filesystem::path dir = test::temp_dir("ply_long_lines");
    const std::string header_line = "ply\nformat ascii 1.0\ncomment " + std::string(24 << 20, 'c');
    const char* const expected = "line 3: header: no end_header in the first 4 MiB";
    EXPECT_ERROR(header_line, expected);
    const std::string from_file = error_of_file(write_text(dir, "long_header.ply", header_line));
    EXPECT_NE(from_file.find(expected), std::string::npos) << from_file;
    std::string data = kCubeAscii;
    data.insert(data.find("0.5 0.5 1") + 9, std::string(24 << 20, ' '));
    const TriangleMesh ref = load(kCubeAscii);
    expect_same_mesh(load(data), ref);
    expect_same_mesh(read_ply(write_text(dir, "long_data.ply", data)), ref);
}

TEST(PlyReaderErrors, AsciiValueErrors) {
    auto with = [](const std::string& from, const std::string& to) {
        std::string t = kCubeAscii;
        t.replace(t.find(from), from.size(), to);
        return t;
    };
    EXPECT_ERROR(with("1 1 0\n", "1 x1 0\n"),
                 "line 14: vertex 2: invalid number 'x1' for property y");
    EXPECT_ERROR(with("1 1 0\n", "1 1 0 7\n"),
                 "line 14: vertex 2: more values on the line than the header declares");
    EXPECT_ERROR(with("3 0 1 4", "3 0 1.5 4"), "line 18: face 1: invalid vertex index '1.5'");
    EXPECT_ERROR(with("3 0 1 4", "300 0 1 4"), "invalid list count '300' for vertex_indices");
    EXPECT_ERROR(std::string(kCubeAscii) + "3 0 1 2\n", "line 19: data after the last element");
}

TEST(PlyReaderErrors, MissingFile) {
    try {
        read_ply("/nonexistent/dir/mesh.ply");
        FAIL();
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/mesh.ply: cannot open file"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace kdt
