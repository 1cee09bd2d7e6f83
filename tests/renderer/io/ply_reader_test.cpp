// Tests of renderer/io/ply_reader: every encoding, scalar type and alias, layouts,
// skipping, triangulation, attributes, gzip, float parsing exactness, and one hand-made
// broken file per error the reader reports, each asserting its message.
#include "renderer/io/ply_reader.h"

#include <zlib.h>
#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_writer.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

TriangleMesh load(const std::string& text, MeshLoadOptions options = {},
                  MeshLoadInfo* info = nullptr) {
    return read_ply_memory(text.data(), text.size(), "test.ply", options, info);
}

// Loads `text`, expects a kdt::Error and returns its message ("" when none was thrown).
std::string error_of(const std::string& text, MeshLoadOptions options = {}) {
    try {
        load(text, options);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

#define EXPECT_ERROR(text, substring)                                                            \
    do {                                                                                         \
        std::string msg_ = error_of(text);                                                       \
        EXPECT_NE(msg_.find(substring), std::string::npos)                                       \
            << "expected an error containing \"" << (substring) << "\", got \"" << msg_ << "\""; \
    } while (0)

// Writes `data` to dir/name and returns the path.
std::string write_text(const std::filesystem::path& dir, const std::string& name,
                       const std::string& data) {
    std::ofstream(dir / name, std::ios::binary) << data;
    return (dir / name).string();
}

// Reads the file, expects a kdt::Error and returns its message ("" when none was thrown).
std::string error_of_file(const std::string& path) {
    try {
        read_ply(path);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

void expect_same_mesh(const TriangleMesh& a, const TriangleMesh& b) {
    EXPECT_EQ(a.positions, b.positions);
    EXPECT_EQ(a.triangles, b.triangles);
}

// Binary record builder.
struct Bytes {
    std::string s;
    bool big = false;
    template <typename T>
    Bytes& put(T v) {
        char b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (big) std::reverse(b, b + sizeof(T));
        s.append(b, sizeof(T));
        return *this;
    }
};

const char* kCubeAscii =
    "ply\n"
    "format ascii 1.0\n"
    "comment a unit square and a triangle\n"
    "obj_info made by hand\n"
    "element vertex 5\n"
    "property float x\n"
    "property float y\n"
    "property float z\n"
    "element face 2\n"
    "property list uchar int vertex_indices\n"
    "end_header\n"
    "0 0 0\n"
    "1 0 0\n"
    "1 1 0\n"
    "0 1 0\n"
    "0.5 0.5 1\n"
    "4 0 1 2 3\n"
    "3 0 1 4\n";

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
    // In an unsigned list, 2^32 - 1 (the bit pattern of -1) restarts a strip too.
    std::string unsigned_list = strips_file(PlyEncoding::ascii);
    unsigned_list.replace(unsigned_list.find("property list int int vertex_indices"), 36,
                          "property list int uint vertex_indices");
    unsigned_list.replace(unsigned_list.find(" -1 "), 4, " 4294967295 ");
    const TriangleMesh u = load(unsigned_list);
    ASSERT_EQ(u.triangles.size(), expected.size());
    for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(u.triangles[k], expected[k]) << k;
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

// Binary faces of 4-byte indices are decoded in runs; a polygon, a degenerate face or a bad
// index anywhere (at a run's start, end or middle) leaves the run to the record-by-record
// path: same triangles, counts and errors in both byte orders, signed and unsigned, as with
// 2-byte indices (no runs).
TEST(PlyReader, BinaryFaceRunsMatchRecordByRecord) {
    const int nv = 5000, nf = 9000;
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> vi(0, nv - 1);
    std::vector<std::vector<int>> faces;
    std::vector<Vec3u> expected;
    for (int f = 0; f < nf; ++f) {
        std::vector<int> c;
        if (f == 0 || f == 1023 || f == 1024 || f == 5000) {
            c = {vi(rng) % 1000, 1000 + vi(rng) % 1000, 2000 + vi(rng) % 1000,
                 3000 + vi(rng) % 1000};
        } else if (f == 2047 || f == 2048 || f == 6000) {
            // a = b, b = c and c = a in turn.
            const int a = vi(rng), b = (a + 1) % nv;
            c = f % 3 == 0 ? std::vector<int>{a, a, b}
                           : (f % 3 == 1 ? std::vector<int>{b, a, a} : std::vector<int>{a, b, a});
        } else {
            c = {vi(rng) % 1500, 1500 + vi(rng) % 1500, 3000 + vi(rng) % 2000};
        }
        for (size_t k = 1; k + 1 < c.size(); ++k)
            expected.emplace_back(uint32_t(c[0]), uint32_t(c[k]), uint32_t(c[k + 1]));
        faces.push_back(c);
    }
    for (bool big : {false, true}) {
        for (const char* type : {"int", "uint", "ushort"}) {
            auto file = [&](int bad_face, int bad_index) {
                Bytes b;
                b.big = big;
                for (int i = 0; i < nv; ++i) b.put(float(i)).put(0.5f).put(-1.0f);
                for (int f = 0; f < nf; ++f) {
                    b.put(uint8_t(faces[size_t(f)].size()));
                    for (size_t k = 0; k < faces[size_t(f)].size(); ++k) {
                        const int v = f == bad_face && k == 1 ? bad_index : faces[size_t(f)][k];
                        if (std::string(type) == "ushort")
                            b.put(uint16_t(v));
                        else
                            b.put(int32_t(v));
                    }
                }
                return std::string("ply\nformat ") +
                       (big ? "binary_big_endian" : "binary_little_endian") +
                       " 1.0\nelement vertex " + std::to_string(nv) +
                       "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                       std::to_string(nf) + "\nproperty list uchar " + type +
                       " vertex_indices\nend_header\n" + b.s;
            };
            SCOPED_TRACE(std::string(big ? "big endian, " : "little endian, ") + type);
            MeshLoadInfo info;
            TriangleMesh m = load(file(-1, 0), {}, &info);
            EXPECT_EQ(m.triangles, expected);
            EXPECT_EQ(info.source_faces, uint64_t(nf));
            EXPECT_EQ(info.degenerate_faces, 3u);
            // A bad index in the middle of a run: the error names its face and first byte.
            const std::string text = file(3000, nv + 7);
            const size_t isz = std::string(type) == "ushort" ? 2 : 4;
            size_t at = text.find("end_header\n") + 11 + size_t(nv) * 12;
            for (int f = 0; f < 3000; ++f) at += 1 + faces[size_t(f)].size() * isz;
            EXPECT_ERROR(text, "test.ply: byte " + std::to_string(at) +
                                   ": face 3000: vertex index " + std::to_string(nv + 7) +
                                   " out of range (5000 vertices)");
            if (std::string(type) == "int")
                EXPECT_ERROR(file(4095, -3), "face 4095: vertex index -3 out of range");
        }
    }
}

// Binary vertices of float x, y, z are decoded in runs; a non-finite one anywhere (at a run's
// start, end or middle) goes to the record-by-record path: the same error, or with
// drop_invalid the same dropped vertices and faces, in both byte orders, with the
// coordinates alone in the record or after another property.
TEST(PlyReader, BinaryVertexRunsMatchRecordByRecord) {
    const int nv = 5000;
    const std::vector<int> bad = {1023, 1024, 3002};  // NaN in x, y, z (i % 3)
    auto is_bad = [&](int i) { return std::find(bad.begin(), bad.end(), i) != bad.end(); };
    for (bool big : {false, true}) {
        for (bool leading : {false, true}) {
            SCOPED_TRACE(std::string(big ? "big endian" : "little endian") +
                         (leading ? ", after another property" : ""));
            // NaN in the vertices `nan_at` (x, y or z by i % 3).
            auto file = [&](const std::vector<int>& nan_at) {
                Bytes b;
                b.big = big;
                for (int i = 0; i < nv; ++i) {
                    if (leading) b.put(float(-i));
                    const bool bad_i = std::find(nan_at.begin(), nan_at.end(), i) != nan_at.end();
                    const int nan_in = bad_i ? int(i % 3) : -1;
                    b.put(nan_in == 0 ? NAN : float(i))
                        .put(nan_in == 1 ? NAN : 0.25f * float(i))
                        .put(nan_in == 2 ? NAN : -1.0f);
                }
                for (int f = 0; f + 2 < nv; ++f)
                    b.put(uint8_t(3)).put(uint32_t(f)).put(uint32_t(f + 1)).put(uint32_t(f + 2));
                return std::string("ply\nformat ") +
                       (big ? "binary_big_endian" : "binary_little_endian") +
                       " 1.0\nelement vertex " + std::to_string(nv) +
                       (leading ? "\nproperty float confidence" : "") +
                       "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                       std::to_string(nv - 2) +
                       "\nproperty list uchar uint vertex_indices\nend_header\n" + b.s;
            };
            TriangleMesh all = load(file({}));
            ASSERT_EQ(all.vertex_count(), size_t(nv));
            for (int i = 0; i < nv; ++i)
                ASSERT_EQ(all.positions[size_t(i)], Vec3f(float(i), 0.25f * float(i), -1.0f));
            // Each bad vertex alone is an error naming it and its first byte.
            const size_t rec = leading ? 16 : 12;
            for (int i : bad) {
                const std::string text = file({i});
                const size_t at = text.find("end_header\n") + 11 + size_t(i) * rec;
                EXPECT_ERROR(text, "test.ply: byte " + std::to_string(at) + ": vertex " +
                                       std::to_string(i) + ": non-finite coordinate (");
            }
            const std::string text = file(bad);
            MeshLoadOptions o;
            o.drop_invalid = true;
            MeshLoadInfo info;
            TriangleMesh m = load(text, o, &info);
            std::vector<Vec3f> positions;
            for (int i = 0; i < nv; ++i)
                if (!is_bad(i)) positions.emplace_back(float(i), 0.25f * float(i), -1.0f);
            EXPECT_EQ(m.positions, positions);
            // Faces (f, f + 1, f + 2) touching 1023, 1024 or 3002: f = 1021 to 1024, 3000 to 3002.
            EXPECT_EQ(info.dropped_faces, 7u);
            EXPECT_EQ(m.triangle_count(), size_t(nv - 2 - 7));
        }
    }
}

TEST(PlyReader, BinaryTrailingBytesIgnored) {
    Bytes b;
    b.put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(0.0f);
    b.put(uint8_t(3)).put(0).put(1).put(2);
    std::string t =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float "
        "y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n" +
        b.s + "\n\n";
    EXPECT_EQ(load(t).triangle_count(), 1u);
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
    }
    std::filesystem::remove_all(dir);
}

// The ascii fast path (Clinger with a reciprocal multiply) must give the correctly rounded
// float for every input: compare against from_chars on random floats in several notations.
TEST(PlyReader, AsciiFloatsParseExactly) {
    std::mt19937 rng(12345);
    std::uniform_int_distribution<uint32_t> bits;
    std::string data;
    std::vector<float> expect;
    const int n = 20000;
    char buf[64];
    for (int i = 0; i < n; ++i) {
        float f;
        do {
            f = std::bit_cast<float>(bits(rng));
        } while (!std::isfinite(f));
        if (i % 3 == 1)
            f = float(std::ldexp(double(bits(rng) % 2000000) - 1e6, -int(bits(rng) % 20)));
        int style = i % 4;
        if (style == 0) {
            auto r = std::to_chars(buf, buf + 64, f);
            *r.ptr = 0;
        } else if (style == 1) {
            std::snprintf(buf, sizeof buf, "%.9g", double(f));
        } else if (style == 2) {
            std::snprintf(buf, sizeof buf, "%.6f", double(f));
        } else {
            std::snprintf(buf, sizeof buf, "%.7e", double(f));
        }
        float ref = 0;
        std::from_chars(buf, buf + std::strlen(buf), ref);
        expect.push_back(ref);
        data += std::string(buf) + " 0 0\n";
    }
    std::string h = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(n) +
                    "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    TriangleMesh m = load(h + data);
    ASSERT_EQ(m.vertex_count(), size_t(n));
    int wrong = 0;
    for (int i = 0; i < n; ++i)
        wrong += std::bit_cast<uint32_t>(m.positions[size_t(i)].x) !=
                 std::bit_cast<uint32_t>(expect[size_t(i)]);
    EXPECT_EQ(wrong, 0);
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

// ---- one hand-made broken file per error --------------------------------------------------

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
    EXPECT_ERROR(with("format ascii 1.0", "format ascii 2.0"),
                 "line 2: header: unknown format line 'format ascii 2.0'");
    EXPECT_ERROR(with("format ascii 1.0\n", ""), "missing format line");
    EXPECT_ERROR(with("end_header\n", ""), "missing end_header");
    EXPECT_ERROR(with("ply\n", "plx\n"), "line 1: header: not a PLY file");
    EXPECT_ERROR(with("property float y", "property float16 y"),
                 "line 7: header: unknown property type 'float16'");
    EXPECT_ERROR(with("list uchar int", "list float int"),
                 "list count type 'float' is not an integer type");
    EXPECT_ERROR(with("list uchar int", "list uchar float"),
                 "face list vertex_indices has non-integer item type");
    EXPECT_ERROR(with("property float y", "property float x"), "second property named 'x'");
    EXPECT_ERROR(with("property float y", "property float w"), "element vertex has no property y");
    EXPECT_ERROR(with("element vertex 5", "element vertex five"), "count 'five' is not an integer");
    EXPECT_ERROR(with("comment", "property float q\ncomment"), "property before any element");
    EXPECT_ERROR(with("vertex_indices", "corners"),
                 "element face has no list property vertex_indices");
    EXPECT_ERROR("", "test.ply: line 1: header: empty file");
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

namespace kdt {
namespace {

// A large ascii file (several parallel chunks) with the irregular lines the two-thread
// path must hand to the serial one: blank lines, a polygon, a degenerate face, and with
// drop_invalid a non-finite vertex. One and two threads must agree exactly, and report
// errors on the same line.
std::string big_ascii(bool with_nan, bool irregular = true) {
    const int nv = 60000, nf = 120000;
    std::string s = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(nv) +
                    "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                    std::to_string(nf) + "\nproperty list uchar int vertex_indices\nend_header\n";
    std::mt19937 rng(99);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    char buf[96];
    for (int i = 0; i < nv; ++i) {
        if (with_nan && i == 40000) {
            s += "nan 0 0\n";
            continue;
        }
        std::snprintf(buf, sizeof buf, "%.7g %.7g %.7g\n", double(u(rng)), double(u(rng)),
                      double(u(rng)));
        s += buf;
        if (i == 20000 && irregular) s += "\n   \n";
    }
    std::uniform_int_distribution<int> vi(0, nv - 1);
    for (int f = 0; f < nf; ++f) {
        if (f == 70000 && irregular) {
            s += "4 1 2 3 4\n";
        } else if (f == 90000 && irregular) {
            s += "3 5 5 6\n";
        } else {
            s += "3 " + std::to_string(vi(rng)) + " " + std::to_string(vi(rng)) + " " +
                 std::to_string(vi(rng)) + "\n";
        }
    }
    return s;
}

TEST(PlyReader, TwoThreadAsciiMatchesOneThread) {
    for (bool with_nan : {false, true}) {
        std::string text = big_ascii(with_nan);
        MeshLoadOptions one, two;
        one.threads = 1;
        two.threads = 2;
        one.drop_invalid = two.drop_invalid = with_nan;
        MeshLoadInfo i1, i2;
        TriangleMesh a = load(text, one, &i1), b = load(text, two, &i2);
        EXPECT_EQ(a.positions, b.positions);
        EXPECT_EQ(a.triangles, b.triangles);
        EXPECT_EQ(a.triangle_count(), with_nan ? 120001u - i1.dropped_faces : 120001u);
        EXPECT_EQ(i1.dropped_faces > 0, with_nan);
        EXPECT_EQ(i1.degenerate_faces, i2.degenerate_faces);
        EXPECT_EQ(i1.dropped_faces, i2.dropped_faces);
        EXPECT_EQ(i1.source_faces, 120000u);
        EXPECT_EQ(i2.source_faces, 120000u);
        EXPECT_GE(i2.degenerate_faces, 1u);
    }
    // Regular lines only: every chunk is taken whole by the tight loop.
    {
        std::string text = big_ascii(false, false);
        MeshLoadOptions one, two;
        one.threads = 1;
        two.threads = 2;
        TriangleMesh a = load(text, one), b = load(text, two), c = load(text);
        EXPECT_EQ(a.triangle_count(), 120000u);
        EXPECT_EQ(a.positions, b.positions);
        EXPECT_EQ(a.triangles, b.triangles);
        EXPECT_EQ(a.triangles, c.triangles);
    }
    // An error deep in the file: same message (same line) either way.
    std::string text = big_ascii(false);
    size_t pos = text.find("\n3 ", text.size() - 200000);
    text.replace(pos + 1, 1, "2");
    std::string e1, e2;
    MeshLoadOptions one, two;
    one.threads = 1;
    two.threads = 2;
    try {
        load(text, one);
    } catch (const Error& e) {
        e1 = e.what();
    }
    try {
        load(text, two);
    } catch (const Error& e) {
        e2 = e.what();
    }
    EXPECT_NE(e1.find("indices, a face needs at least 3"), std::string::npos) << e1;
    EXPECT_EQ(e1, e2);
}

// Files of 1 MiB and more are mapped and read through a sliding window instead of a buffer:
// same meshes and same errors as from memory, in every encoding, for a file ending exactly
// on a page without a final newline, and for one cut short.
TEST(PlyReader, MappedFilesMatchMemory) {
    const std::filesystem::path dir = test::temp_dir("ply_mapped");
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const int nv = 100000, nf = 200000;
    std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(nv) +
                       "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                       std::to_string(nf) +
                       "\nproperty list uchar int vertex_indices\nend_header\n";
    char buf[96];
    for (int i = 0; i < nv; ++i) {
        std::snprintf(buf, sizeof buf, "%.7g %.7g %.7g\n", double(u(rng)), double(u(rng)),
                      double(u(rng)));
        text += buf;
    }
    std::uniform_int_distribution<int> vi(0, nv - 1);
    for (int f = 0; f < nf; ++f) {
        int a = vi(rng), b = (a + 1 + vi(rng) % 1000) % nv, c = (b + 1 + vi(rng) % 1000) % nv;
        if (c == a) c = (c + 1) % nv;
        text += (f == 150000 ? "4 " : "3 ") + std::to_string(a) + " " + std::to_string(b) + " " +
                std::to_string(c) + (f == 150000 ? " 7" : "") + "\n";
    }
    ASSERT_GT(text.size(), size_t(6) << 20);  // more than one window
    auto write = [&](const std::string& name, const std::string& data) {
        return write_text(dir, name, data);
    };
    const auto same = expect_same_mesh;
    const TriangleMesh ref = load(text);
    ASSERT_EQ(ref.triangle_count(), size_t(nf + 1));
    for (int threads : {1, 2}) {
        MeshLoadOptions options;
        options.threads = threads;
        MeshLoadInfo info;
        same(read_ply(write("a.ply", text), options, &info), ref);
        EXPECT_EQ(info.file_bytes, text.size());
        // Ends on a page boundary, last line without its newline: the parser reads the
        // padding past the mapped file.
        std::string cut = text.substr(0, text.size() - 1);
        const size_t pad = (4096 - cut.size() % 4096) % 4096;
        cut.insert(cut.find("end_header"),
                   "comment " + std::string(pad > 9 ? pad - 9 : 0, 'x') + "\n");
        cut.insert(cut.find("end_header"), std::string((4096 - cut.size() % 4096) % 4096, ' '));
        ASSERT_EQ(cut.size() % 4096, 0u);
        same(read_ply(write("b.ply", cut), options), ref);
    }
    // Truncated mid-file: the same message as from memory.
    const std::string trunc = text.substr(0, text.size() * 3 / 4);
    const std::string from_file = error_of_file(write("c.ply", trunc));
    const std::string from_memory = error_of(trunc);
    EXPECT_NE(from_memory.find("unexpected end of data"), std::string::npos) << from_memory;
    EXPECT_EQ(from_file.substr(from_file.find(':')), from_memory.substr(from_memory.find(':')));
    // Binary copies, little- and big-endian, through the same window.
    for (PlyEncoding enc : {PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
        const std::string path = (dir / "bin.ply").string();
        write_ply(path, ref, enc);
        ASSERT_GT(std::filesystem::file_size(path), uint64_t(1) << 20);
        same(read_ply(path), ref);
    }
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace kdt
