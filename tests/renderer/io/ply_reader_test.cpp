// Tests of renderer/io/ply_reader on well-formed files: every encoding, scalar type and alias,
// layouts, skipping, triangle strips, triangulation, attributes, gzip and dropped vertices.
// The fast paths are checked in ply_fast_paths_test, the error messages in ply_errors_test.
#include "renderer/io/ply_reader.h"

#include <zlib.h>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_input.h"
#include "tests/renderer/io/ply_test_util.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

using test::Bytes;
using test::kCubeAscii;
using test::load;

TEST(PlyReader, AsciiQuadTriangulatedAsFan) {
    MeshLoadInfo info;
    TriangleMesh m = load(kCubeAscii, {}, &info);
    ASSERT_EQ(m.vertex_count(), 5u);
    ASSERT_EQ(m.triangle_count(), 3u);
    EXPECT_EQ(m.triangles[0], Vec3u(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3u(0, 2, 3));
    EXPECT_EQ(m.triangles[2], Vec3u(0, 1, 4));
    EXPECT_EQ(m.positions[4], Vec3f(0.5f, 0.5f, 1.0f));
    EXPECT_EQ(info.format, "ply");
    EXPECT_EQ(info.encoding, "ascii");
    EXPECT_EQ(info.source_faces, 2u);
    EXPECT_EQ(info.degenerate_faces, 0u);
    EXPECT_FALSE(info.gzip);
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.colors.empty());
}

TEST(PlyReader, AnyVersionOneIsReadWithAWarning) {
    const TriangleMesh want = load(kCubeAscii);
    auto with_version = [](const std::string& text, const std::string& version) {
        std::string t = text;
        const size_t at = t.find(" 1.0\n");
        return t.replace(at + 1, 3, version);
    };
    // The cube in each encoding, through our writer's layout: vertices, then faces.
    Bytes le, be;
    be.big = true;
    for (Bytes* b : {&le, &be}) {
        for (const Vec3f& p : want.positions) b->put(p.x).put(p.y).put(p.z);
        b->put(uint8_t(4)).put(0).put(1).put(2).put(3).put(uint8_t(3)).put(0).put(1).put(4);
    }
    std::string head = kCubeAscii;
    head.erase(head.find("end_header\n") + 11);
    const std::string files[] = {
        kCubeAscii,
        std::string(head).replace(head.find("ascii"), 5, "binary_little_endian") + le.s,
        std::string(head).replace(head.find("ascii"), 5, "binary_big_endian") + be.s,
    };
    for (const std::string& text : files) {
        for (const char* version : {"1.1", "1.2", "1.10"}) {
            SCOPED_TRACE(version);
            MeshLoadInfo info;
            test::expect_same_mesh(load(with_version(text, version), {}, &info), want);
            ASSERT_EQ(info.warnings.size(), 1u);
            EXPECT_EQ(info.warnings[0], std::string("test.ply: line 2: header: format version ") +
                                            version + ": only PLY 1.0 is specified; read as 1.0");
        }
        for (const char* version : {"1.0", "1", "1.00"}) {
            SCOPED_TRACE(version);
            MeshLoadInfo info;
            test::expect_same_mesh(load(with_version(text, version), {}, &info), want);
            EXPECT_TRUE(info.warnings.empty());
        }
    }
}

// The cube with its face indices stored as `type` (float or double) in the given format.
std::string cube_with_real_indices(const std::string& format, const std::string& type,
                                   const std::string& ascii_faces = "4 0 1 2 3\n3 0 1 4\n") {
    std::string head = kCubeAscii;
    head.erase(head.find("end_header\n") + 11);
    head.replace(head.find("ascii"), 5, format);
    head.replace(head.find("uchar int"), 9, "uchar " + type);
    if (format == "ascii") return head + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n" + ascii_faces;
    Bytes b;
    b.big = format == "binary_big_endian";
    const float xyz[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5f, 0.5f, 1};
    for (float v : xyz) b.put(v);
    const int indices[] = {0, 1, 2, 3, 0, 1, 4};
    for (int k = 0; k < 7; ++k) {
        if (k == 0 || k == 4) b.put(uint8_t(k == 0 ? 4 : 3));
        if (type == "float" || type == "float32")
            b.put(float(indices[k]));
        else
            b.put(double(indices[k]));
    }
    return head + b.s;
}

TEST(PlyReader, FloatAndDoubleFaceIndicesInEveryEncoding) {
    const TriangleMesh want = load(kCubeAscii);
    for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
        for (const char* type : {"float", "double", "float32", "float64"}) {
            SCOPED_TRACE(std::string(format) + " " + type);
            test::expect_same_mesh(load(cube_with_real_indices(format, type)), want);
        }
    }
    // Integers in any form a float list may hold them.
    test::expect_same_mesh(
        load(cube_with_real_indices("ascii", "float", "4 0.0 1.000 2e0 3\n3 -0 +1 0.4e1\n")), want);
    // Past float's 2^24 an integer written out in full is that integer (read as a double).
    const std::string big = cube_with_real_indices("ascii", "float", "4 0 1 2 3\n3 0 1 16777217\n");
    EXPECT_NE(test::error_of(big).find("face 1: vertex index 16777217 out of range (5 vertices)"),
              std::string::npos)
        << test::error_of(big);
}

TEST(PlyReader, CrlfHeaderAndDataAndBlankLines) {
    std::string t = kCubeAscii;
    std::string crlf;
    for (char c : t) {
        if (c == '\n')
            crlf += "\r\n";
        else
            crlf += c;
    }
    crlf.insert(crlf.find("0.5 0.5 1"), "\r\n  \r\n");
    TriangleMesh m = load(crlf);
    EXPECT_EQ(m.vertex_count(), 5u);
    EXPECT_EQ(m.triangle_count(), 3u);
}

TEST(PlyReader, UnknownHeaderLinesAreIgnored) {
    std::string t = kCubeAscii;
    t.insert(t.find("element vertex"), "Created by some exporter\n");
    EXPECT_EQ(load(t).triangle_count(), 3u);
}

// One file per scalar type name, x/y/z stored with that type, in all three encodings.
TEST(PlyReader, EveryScalarTypeAndAliasInEveryEncoding) {
    struct T {
        const char* name;
        int kind;  // 0 i8, 1 u8, 2 i16, 3 u16, 4 i32, 5 u32, 6 f32, 7 f64
    };
    const T types[] = {{"char", 0},  {"int8", 0},    {"uchar", 1},  {"uint8", 1},
                       {"short", 2}, {"int16", 2},   {"ushort", 3}, {"uint16", 3},
                       {"int", 4},   {"int32", 4},   {"uint", 5},   {"uint32", 5},
                       {"float", 6}, {"float32", 6}, {"double", 7}, {"float64", 7}};
    const double values[3][3] = {{1, 2, 3}, {4, 5, 6}, {7, 8, 100}};
    for (const T& t : types) {
        for (int enc = 0; enc < 3; ++enc) {
            std::string h = std::string("ply\nformat ") + kPlyEncodingNames[size_t(enc)] +
                            " 1.0\nelement vertex 3\nproperty " + t.name + " x\nproperty " +
                            t.name + " y\nproperty " + t.name +
                            " z\nelement face 1\nproperty list " +
                            (t.kind == 6 || t.kind == 7 ? std::string("uchar") : t.name) + " " +
                            (t.kind == 6 || t.kind == 7 ? std::string("int") : t.name) +
                            " vertex_indices\nend_header\n";
            Bytes b;
            b.big = enc == 2;
            auto put = [&](double v, int kind) {
                switch (kind) {
                    case 0:
                        b.put(int8_t(v));
                        break;
                    case 1:
                        b.put(uint8_t(v));
                        break;
                    case 2:
                        b.put(int16_t(v));
                        break;
                    case 3:
                        b.put(uint16_t(v));
                        break;
                    case 4:
                        b.put(int32_t(v));
                        break;
                    case 5:
                        b.put(uint32_t(v));
                        break;
                    case 6:
                        b.put(float(v));
                        break;
                    default:
                        b.put(double(v));
                        break;
                }
            };
            std::string data;
            if (enc == 0) {
                for (auto& v : values)
                    data += std::to_string(int(v[0])) + " " + std::to_string(int(v[1])) + " " +
                            std::to_string(int(v[2])) + "\n";
                data += "3 0 1 2\n";
            } else {
                for (auto& v : values)
                    for (double c : v) put(c, t.kind);
                int ik = t.kind >= 6 ? 4 : t.kind;
                put(3, t.kind >= 6 ? 1 : t.kind);
                for (int k = 0; k < 3; ++k) put(k, ik);
                data = b.s;
            }
            SCOPED_TRACE(std::string(t.name) + " " + kPlyEncodingNames[size_t(enc)]);
            TriangleMesh m = load(h + data);
            ASSERT_EQ(m.vertex_count(), 3u);
            ASSERT_EQ(m.triangle_count(), 1u);
            EXPECT_EQ(m.positions[2], Vec3f(7, 8, 100));
            EXPECT_EQ(m.positions[1], Vec3f(4, 5, 6));
            EXPECT_EQ(m.triangles[0], Vec3u(0, 1, 2));
        }
    }
}

// Properties in any order, unknown scalar and list properties, unknown elements with
// lists before and after the known ones, normals and colours.
std::string mixed_layout(PlyEncoding enc) {
    std::string h = std::string("ply\nformat ") + kPlyEncodingNames[size_t(enc)] +
                    " 1.0\n"
                    "element material 2\n"
                    "property list ushort short ids\n"
                    "property double shininess\n"
                    "element vertex 4\n"
                    "property uchar blue\n"
                    "property float nz\n"
                    "property list int uint junk\n"
                    "property double z\n"
                    "property uchar red\n"
                    "property float nx\n"
                    "property short quality\n"
                    "property float y\n"
                    "property float ny\n"
                    "property float x\n"
                    "property uchar green\n"
                    "element face 2\n"
                    "property uchar flags\n"
                    "property list uint ushort vertex_index\n"
                    "property list uchar float texcoord\n"
                    "element edge 1\n"
                    "property int vertex1\n"
                    "property int vertex2\n"
                    "end_header\n";
    // vertex i: position (i, 2i, 3i), normal (0, 0, 1), colour (255, 0, 51)
    if (enc == PlyEncoding::ascii) {
        std::string d = "2 7 8 0.5\n0 1.5\n";
        for (int i = 0; i < 4; ++i)
            d += "51 1 2 9 9 " + std::to_string(3 * i) + " 255 0 -7 " + std::to_string(2 * i) +
                 " 0 " + std::to_string(i) + " 0\n";
        d += "9 4 0 1 2 3 2 0.25 0.75\n1 3 1 2 3 0\n";
        d += "0 1\n";
        return h + d;
    }
    Bytes b;
    b.big = enc == PlyEncoding::binary_big_endian;
    b.put(uint16_t(2)).put(int16_t(7)).put(int16_t(8)).put(0.5);
    b.put(uint16_t(0)).put(1.5);
    for (int i = 0; i < 4; ++i) {
        b.put(uint8_t(51))
            .put(1.0f)
            .put(int32_t(2))
            .put(uint32_t(9))
            .put(uint32_t(9))
            .put(double(3 * i));
        b.put(uint8_t(255))
            .put(0.0f)
            .put(int16_t(-7))
            .put(float(2 * i))
            .put(0.0f)
            .put(float(i))
            .put(uint8_t(0));
    }
    b.put(uint8_t(9))
        .put(uint32_t(4))
        .put(uint16_t(0))
        .put(uint16_t(1))
        .put(uint16_t(2))
        .put(uint16_t(3));
    b.put(uint8_t(2)).put(0.25f).put(0.75f);
    b.put(uint8_t(1))
        .put(uint32_t(3))
        .put(uint16_t(1))
        .put(uint16_t(2))
        .put(uint16_t(3))
        .put(uint8_t(0));
    b.put(int32_t(0)).put(int32_t(1));
    return h + b.s;
}

TEST(PlyReader, AnyPropertyOrderUnknownElementsAndListsSkipped) {
    for (PlyEncoding enc :
         {PlyEncoding::ascii, PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
        SCOPED_TRACE(kPlyEncodingNames[size_t(enc)]);
        TriangleMesh m = load(mixed_layout(enc));
        ASSERT_EQ(m.vertex_count(), 4u);
        ASSERT_EQ(m.triangle_count(), 3u);
        for (int i = 0; i < 4; ++i)
            EXPECT_EQ(m.positions[size_t(i)], Vec3f(float(i), float(2 * i), float(3 * i)));
        ASSERT_EQ(m.normals.size(), 4u);
        EXPECT_EQ(m.normals[3], Vec3f(0, 0, 1));
        ASSERT_EQ(m.colors.size(), 4u);
        EXPECT_FLOAT_EQ(m.colors[2].x, 1.0f);
        EXPECT_FLOAT_EQ(m.colors[2].y, 0.0f);
        EXPECT_FLOAT_EQ(m.colors[2].z, 0.2f);
        EXPECT_EQ(m.triangles[0], Vec3u(0, 1, 2));
        EXPECT_EQ(m.triangles[1], Vec3u(0, 2, 3));
        EXPECT_EQ(m.triangles[2], Vec3u(1, 2, 3));
    }
}

// "tristrips" elements (as Cyberware-era scans store them): each strip is a run of
// triangles with alternating winding, -1 restarts a run, and stitching triangles with a
// repeated vertex are dropped. Same result in every encoding, alongside ordinary faces.
std::string strips_file(PlyEncoding enc) {
    const std::string h = std::string("ply\nformat ") + kPlyEncodingNames[size_t(enc)] +
                          " 1.0\n"
                          "element vertex 6\n"
                          "property float x\nproperty float y\nproperty float z\n"
                          "element tristrips 2\n"
                          "property list int int vertex_indices\n"
                          "element face 1\n"
                          "property list uchar int vertex_indices\n"
                          "end_header\n";
    // Strip 0: 0 1 2 3 -1 4 5 0 (triangles 012, 213; then 450). Strip 1: 1 2 2 3 4, whose
    // first two triangles repeat vertex 2 (dropped), leaving 234 (third, even: unswapped).
    const std::vector<std::vector<int>> strips = {{0, 1, 2, 3, -1, 4, 5, 0}, {1, 2, 2, 3, 4}, {}};
    if (enc == PlyEncoding::ascii) {
        std::string d;
        for (int i = 0; i < 6; ++i) d += std::to_string(i) + " " + std::to_string(i * i) + " 1\n";
        for (int k = 0; k < 2; ++k) {
            d += std::to_string(strips[size_t(k)].size());
            for (int v : strips[size_t(k)]) d += " " + std::to_string(v);
            d += "\n";
        }
        return h + d + "3 5 4 3\n";
    }
    Bytes b;
    b.big = enc == PlyEncoding::binary_big_endian;
    for (int i = 0; i < 6; ++i) b.put(float(i)).put(float(i * i)).put(1.0f);
    for (int k = 0; k < 2; ++k) {
        b.put(int32_t(strips[size_t(k)].size()));
        for (int v : strips[size_t(k)]) b.put(int32_t(v));
    }
    b.put(uint8_t(3)).put(int32_t(5)).put(int32_t(4)).put(int32_t(3));
    return h + b.s;
}

TEST(PlyReader, TriangleStripsInEveryEncoding) {
    const std::vector<Vec3u> expected = {{0, 1, 2}, {2, 1, 3}, {4, 5, 0}, {2, 3, 4}, {5, 4, 3}};
    for (PlyEncoding enc :
         {PlyEncoding::ascii, PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
        SCOPED_TRACE(kPlyEncodingNames[size_t(enc)]);
        MeshLoadInfo info;
        const TriangleMesh m = load(strips_file(enc), {}, &info);
        ASSERT_EQ(m.triangles.size(), expected.size());
        for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(m.triangles[k], expected[k]) << k;
        EXPECT_EQ(m.positions[5], Vec3f(5, 25, 1));
        EXPECT_EQ(info.source_faces, 3u);  // two strips and one face
    }
    // A strip index out of range names the strip; an empty strip is fine.
    std::string bad = strips_file(PlyEncoding::ascii);
    bad.replace(bad.find("5 1 2 2 3 4"), 11, "5 1 2 2 3 9");
    EXPECT_ERROR(bad, "tristrips 1: vertex index 9 out of range (6 vertices; -1 ends a strip)");
    std::string empty = strips_file(PlyEncoding::ascii);
    empty.replace(empty.find("5 1 2 2 3 4"), 11, "0");
    EXPECT_EQ(load(empty).triangles.size(), 4u);
    // In an unsigned list, 2^32 - 1 (the bit pattern of -1) restarts a strip too; in a float
    // list, -1.0.
    const struct {
        const char* type;
        const char* restart;
    } lists[] = {{"uint", " 4294967295 "}, {"float", " -1.0 "}};
    for (const auto& list : lists) {
        SCOPED_TRACE(list.type);
        std::string text = strips_file(PlyEncoding::ascii);
        text.replace(text.find("property list int int vertex_indices"), 36,
                     std::string("property list int ") + list.type + " vertex_indices");
        text.replace(text.find(" -1 "), 4, list.restart);
        const TriangleMesh m = load(text);
        ASSERT_EQ(m.triangles.size(), expected.size());
        for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(m.triangles[k], expected[k]) << k;
    }
    std::string no_list = strips_file(PlyEncoding::ascii);
    no_list.replace(no_list.find("property list int int vertex_indices"), 36,
                    "property list int int vertex_ids");
    EXPECT_ERROR(no_list, "element tristrips has no list property vertex_indices");
}

TEST(PlyReader, KeepOptionsDropAttributes) {
    MeshLoadOptions o;
    o.keep_normals = false;
    o.keep_colors = false;
    TriangleMesh m = load(mixed_layout(PlyEncoding::binary_little_endian), o);
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.colors.empty());
    EXPECT_EQ(m.positions[3], Vec3f(3, 6, 9));
}

TEST(PlyReader, FloatColoursKeptAsGiven) {
    std::string t =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty "
        "float z\n"
        "property float red\nproperty float green\nproperty float blue\nproperty float alpha\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0 0.25 0.5 1 1\n1 0 0 0 0 1 1\n0 1 0 0 0 1 1\n3 0 1 2\n";
    TriangleMesh m = load(t);
    ASSERT_EQ(m.colors.size(), 3u);
    EXPECT_EQ(m.colors[0], Vec3f(0.25f, 0.5f, 1.0f));
}

TEST(PlyReader, PointCloudAndEmptyMeshes) {
    std::string pc =
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty "
        "float z\n"
        "end_header\n1 2 3\n4 5 6\n";
    TriangleMesh m = load(pc);
    EXPECT_EQ(m.vertex_count(), 2u);
    EXPECT_EQ(m.triangle_count(), 0u);
    std::string empty =
        "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float "
        "y\n"
        "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
    TriangleMesh e = load(empty);
    EXPECT_EQ(e.vertex_count(), 0u);
    EXPECT_EQ(e.triangle_count(), 0u);
    EXPECT_TRUE(e.bounds().empty());
}

TEST(PlyReader, FacesBeforeVerticesAndDegenerateFacesCounted) {
    std::string t =
        "ply\nformat ascii 1.0\nelement face 3\nproperty list uchar int vertex_indices\n"
        "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
        "3 0 1 2\n3 0 0 1\n4 0 1 2 1\n0 0 0\n1 0 0\n0 1 0\n";
    MeshLoadInfo info;
    TriangleMesh m = load(t, {}, &info);
    EXPECT_EQ(m.triangle_count(), 4u);
    EXPECT_EQ(info.degenerate_faces, 2u);
    EXPECT_EQ(m.positions[1], Vec3f(1, 0, 0));
}

TEST(PlyReader, BigPolygonFannedAndDegenerateTestedFast) {
    // One face with 200000 corners: fanned into n-2 triangles; a repeated corner far apart
    // makes it degenerate (found by sorting, not by comparing all pairs).
    const int n = 200000;
    Bytes b;
    for (int i = 0; i < n; ++i) b.put(float(i)).put(0.0f).put(0.0f);
    b.put(uint32_t(n));
    for (int i = 0; i < n; ++i) b.put(i == n - 1 ? 0 : i);
    std::string t = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) +
                    "\nproperty float x\nproperty float y\nproperty float z\nelement face 1\n"
                    "property list uint int vertex_indices\nend_header\n" +
                    b.s;
    MeshLoadInfo info;
    TriangleMesh m = load(t, {}, &info);
    EXPECT_EQ(m.triangle_count(), size_t(n - 2));
    EXPECT_EQ(info.degenerate_faces, 1u);
    EXPECT_EQ(m.triangles[5], Vec3u(0, 6, 7));
}

TEST(PlyReader, BinaryTrailingBytesLoadWithAWarning) {
    Bytes b;
    b.put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f);
    b.put(uint8_t(3)).put(0).put(1).put(2);
    const std::string data =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float "
        "y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n" +
        b.s;
    const std::string at = "byte " + std::to_string(data.size()) + ": ";
    const std::string why =
        " after the last element, ignored (padding, or data the header's "
        "element counts leave out)";
    struct Case {
        std::string trailing, warning;  // warning "" when none
    };
    const Case cases[] = {
        {"", ""},
        {"\n", ""},  // one line end or one blank: a writer's final newline
        {"\r\n", ""},
        {" ", ""},
        {"\n\n", at + "2 bytes" + why},
        {"x", at + "1 byte" + why},
        {b.s.substr(b.s.size() - 13), at + "13 bytes" + why},  // a face the count leaves out
    };
    const std::filesystem::path dir = test::temp_dir("ply_trailing");
    for (const Case& c : cases) {
        SCOPED_TRACE("trailing '" + c.trailing + "'");
        const std::string path = test::write_text(dir, "t.ply", data + c.trailing);
        // From memory, a buffered file, a mapped file and gzip (its size unknown up front).
        std::string gz = (dir / "t.ply.gz").string();
        gzFile f = gzopen(gz.c_str(), "wb");
        ASSERT_NE(f, nullptr);
        gzwrite(f, (data + c.trailing).data(), unsigned(data.size() + c.trailing.size()));
        gzclose(f);
        for (int how = 0; how < 4; ++how) {
            SCOPED_TRACE(how);
            MeshLoadInfo info;
            TriangleMesh m;
            if (how == 0) m = load(data + c.trailing, {}, &info);
            if (how == 1) m = read_ply(path, {}, &info);  // under 1 MiB: buffered
            if (how == 2) {
                const ply::MapParams old = ply::set_map_params({1, 7});
                m = read_ply(path, {}, &info);
                ply::set_map_params(old);
            }
            if (how == 3) m = read_ply(gz, {}, &info);
            EXPECT_EQ(m.triangle_count(), 1u);
            const std::string name = how == 0 ? "test.ply" : how == 3 ? gz : path;
            if (c.warning.empty()) {
                EXPECT_TRUE(info.warnings.empty()) << info.warnings[0];
            } else {
                ASSERT_EQ(info.warnings.size(), 1u);
                EXPECT_EQ(info.warnings[0], name + ": " + c.warning);
            }
        }
    }
    std::filesystem::remove_all(dir);
}

TEST(PlyReader, GzipFileReadTransparently) {
    auto dir = test::temp_dir("ply_gz");
    std::string path = (dir / "cube.ply.gz").string();
    gzFile gz = gzopen(path.c_str(), "wb");
    ASSERT_NE(gz, nullptr);
    gzwrite(gz, kCubeAscii, unsigned(std::strlen(kCubeAscii)));
    gzclose(gz);
    MeshLoadInfo info;
    TriangleMesh m = read_ply(path, {}, &info);
    EXPECT_TRUE(info.gzip);
    EXPECT_EQ(m.triangle_count(), 3u);

    // A gzip stream cut in half is reported, not crashed on.
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::string cut = (dir / "cut.ply.gz").string();
    std::ofstream(cut, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size() / 2));
    try {
        read_ply(cut);
        FAIL() << "no error for a truncated gzip file";
    } catch (const Error& e) {
        std::string msg = e.what();
        EXPECT_NE(msg.find("cut.ply.gz"), std::string::npos) << msg;
        EXPECT_EQ(msg.find("<fd:"), std::string::npos) << msg;
    }
    // A bad CRC names the file, not zlib's name for the descriptor ("<fd:5>").
    std::string crc = (dir / "crc.ply.gz").string();
    std::string bad = bytes;
    bad[bad.size() - 8] ^= 0x55;
    std::ofstream(crc, std::ios::binary).write(bad.data(), std::streamsize(bad.size()));
    EXPECT_EQ(test::error_of_call([&] { read_ply(crc); }),
              crc + ": corrupt gzip data: incorrect data check");
    std::filesystem::remove_all(dir);
}

TEST(PlyReader, DropInvalidDropsFacesOfNonFiniteVertices) {
    std::string t =
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty "
        "float z\n"
        "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\nnan 1 0\n0 1 0\n3 0 1 2\n3 0 1 3\n";
    EXPECT_ERROR(t, "test.ply: line 12: vertex 2: non-finite coordinate");
    MeshLoadOptions o;
    o.drop_invalid = true;
    MeshLoadInfo info;
    TriangleMesh m = load(t, o, &info);
    EXPECT_EQ(info.dropped_faces, 1u);
    EXPECT_EQ(m.vertex_count(), 3u);
    ASSERT_EQ(m.triangle_count(), 1u);
    EXPECT_EQ(m.triangles[0], Vec3u(0, 1, 2));
    EXPECT_EQ(m.positions[2], Vec3f(0, 1, 0));
    EXPECT_FALSE(m.bounds().empty());

    // Binary infinity, and an overflowing ascii literal, are non-finite too.
    Bytes b;
    b.put(0.0f).put(0.0f).put(0.0f).put(INFINITY).put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f);
    std::string bin =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float "
        "y\n"
        "property float z\nend_header\n" +
        b.s;
    EXPECT_ERROR(bin,
                 "test.ply: byte 127: vertex 1: non-finite coordinate (inf, 0.000000, 0.000000)");
    std::string big = t;
    big.replace(big.find("nan"), 3, "1e999");
    EXPECT_ERROR(big, "vertex 2: non-finite coordinate");
}

TEST(PlyReader, TightAsciiWithoutFinalNewline) {
    // One byte per value and one separator, none after the file's last value: the size
    // check before allocating must accept exactly this much data.
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\n";
    const TriangleMesh a = load(header +
                                "element face 1\nproperty list uchar int vertex_indices\n"
                                "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2");
    EXPECT_EQ(a.triangles.size(), 1u);
    EXPECT_EQ(a.positions[1], Vec3f(1, 0, 0));
    const TriangleMesh b = load(header + "end_header\n0 0 0\n1 0 0\n0 1 0");
    EXPECT_EQ(b.positions.size(), 3u);
    EXPECT_EQ(b.positions[2], Vec3f(0, 1, 0));
    // One value less is still rejected before allocating.
    EXPECT_ERROR(header + "end_header\n0 0 0\n1 0 0\n0 1",
                 "element vertex: count 3 needs at least 18 bytes, more than the 15 bytes");
}

}  // namespace
}  // namespace kdt
