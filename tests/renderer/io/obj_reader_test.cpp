// Tests of renderer/io/obj_reader and of load_mesh's format dispatch: the statements and
// corner forms read, what is skipped, one hostile file per error the reader reports (each
// asserting that the message names the file and the line), and a cross-check against
// tinyobjloader and Assimp on the OBJ files of Debian's assimp-testmodels.
#include "renderer/io/obj_reader.h"

#include <sys/stat.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tiny_obj_loader.h>

#include "renderer/core/error.h"
#include "renderer/geometry/polygon.h"
#include "renderer/io/mesh_io.h"
#include "tests/test_util.h"

#ifdef KDT_HAVE_ASSIMP
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#endif

namespace kdt {
namespace {

TriangleMesh load(const std::string& text, MeshLoadOptions options = {},
                  MeshLoadInfo* info = nullptr) {
    return read_obj_memory(text.data(), text.size(), "t.obj", options, info);
}

std::string error_of(const std::string& text, MeshLoadOptions options = {}) {
    try {
        load(text, options);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

const char* const kTriangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

class ObjReader : public ::testing::Test {
protected:
    void SetUp() override { dir_ = test::temp_dir("obj_reader"); }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    std::string write(const std::string& name, const std::string& text) {
        std::string path = (dir_ / name).string();
        std::ofstream(path, std::ios::binary) << text;
        return path;
    }
    std::string file_error_of(const std::string& path, MeshLoadOptions o = {}) {
        try {
            load_mesh(path, o);
        } catch (const Error& e) {
            return e.what();
        }
        return "";
    }
    std::filesystem::path dir_;
};

TEST_F(ObjReader, QuadsTriangulatedAndPositionsKept) {
    std::string p =
        write("quad.obj",
              "# a square and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\n"
              "f 1 2 3 4\nf -5 -4 -1\n");
    MeshLoadInfo info;
    TriangleMesh m = load_mesh(p, {}, &info);
    EXPECT_EQ(info.format, "obj");
    EXPECT_EQ(info.encoding, "text");
    EXPECT_EQ(info.source_faces, 2u);
    EXPECT_EQ(info.file_bytes, std::filesystem::file_size(p));
    ASSERT_EQ(m.vertex_count(), 5u);
    ASSERT_EQ(m.triangle_count(), 3u);
    // Fans (v0, vi, vi+1), as for PLY.
    EXPECT_EQ(m.triangles[0], Vec3u(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3u(0, 2, 3));
    EXPECT_EQ(m.triangles[2], Vec3u(0, 1, 4));
    EXPECT_EQ(m.positions[4], Vec3f(0.5f, 0.5f, 1.0f));
    EXPECT_TRUE(m.normals.empty());
}

TEST_F(ObjReader, NormalsSplitVerticesPerPositionNormalPair) {
    std::string p = write("n.obj",
                          "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nvn 0 1 0\n"
                          "f 1//1 2//1 3//1\nf 1//2 2//2 4//2\n");
    TriangleMesh m = load_mesh(p);
    ASSERT_EQ(m.triangle_count(), 2u);
    EXPECT_EQ(m.vertex_count(), 6u);
    ASSERT_EQ(m.normals.size(), 6u);
    const Vec3u& t = m.triangles[1];
    EXPECT_EQ(m.normals[t.x], Vec3f(0, 1, 0));
    EXPECT_EQ(m.positions[t.z], Vec3f(0, 0, 1));
    // Shared (position, normal) pairs stay shared.
    TriangleMesh s = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n");
    EXPECT_EQ(s.vertex_count(), 4u);
    EXPECT_EQ(s.triangle_count(), 2u);
    // Without keep_normals, or when a corner has none, the file's positions are used.
    MeshLoadOptions no_normals;
    no_normals.keep_normals = false;
    EXPECT_EQ(load_mesh(p, no_normals).vertex_count(), 4u);
    EXPECT_TRUE(load_mesh(p, no_normals).normals.empty());
    TriangleMesh mixed = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3\n");
    EXPECT_EQ(mixed.vertex_count(), 3u);
    EXPECT_TRUE(mixed.normals.empty());
}

TEST_F(ObjReader, CornerFormsAndRelativeIndices) {
    TriangleMesh m = load(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1\nf -4/-3/-1 -3//-1 -1/-1/1\n");
    ASSERT_EQ(m.triangle_count(), 2u);
    ASSERT_EQ(m.normals.size(), m.vertex_count());
    EXPECT_EQ(m.positions[m.triangles[1].z], Vec3f(0, 0, 1));
    TriangleMesh t = load(std::string(kTriangle) + "vt 0 0\nf 1/1 2/1 3/1\nf 1/ 2/ 3//\n");
    EXPECT_EQ(t.triangle_count(), 2u);
    // Relative indices count back from the vertices defined so far, not from the end.
    TriangleMesh r = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -3 -1\n");
    ASSERT_EQ(r.triangle_count(), 2u);
    EXPECT_EQ(r.triangles[0], Vec3u(0, 1, 2));
    EXPECT_EQ(r.triangles[1], Vec3u(0, 1, 3));
    // Positive indices may point at vertices defined later.
    TriangleMesh ahead = load("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
    EXPECT_EQ(ahead.triangle_count(), 1u);
}

TEST_F(ObjReader, BigPolygonsAreFans) {
    // 300 corners on a circle: 298 triangles, all sharing corner 0, covering the polygon.
    std::string text;
    const int n = 300;
    for (int k = 0; k < n; ++k)
        text += "v " + std::to_string(std::cos(6.283185307 * k / n)) + " " +
                std::to_string(std::sin(6.283185307 * k / n)) + " 0\n";
    text += "f";
    for (int k = 1; k <= n; ++k) text += " " + std::to_string(k);
    MeshLoadInfo info;
    TriangleMesh m = load(text, {}, &info);
    ASSERT_EQ(m.triangle_count(), size_t(n - 2));
    EXPECT_EQ(info.degenerate_faces, 0u);
    double area = 0;
    for (size_t t = 0; t < m.triangle_count(); ++t) {
        const Vec3u& i = m.triangles[t];
        EXPECT_EQ(i, Vec3u(0, uint32_t(t + 1), uint32_t(t + 2)));
        area += 0.5 * glm::length(glm::cross(m.positions[i.y] - m.positions[i.x],
                                             m.positions[i.z] - m.positions[i.x]));
    }
    EXPECT_NEAR(area, 0.5 * n * std::sin(6.283185307 / n), 1e-4);
    // A polygon repeating a corner is kept and counted as degenerate (sorted test beyond 32).
    text += " 7\n";
    load(text, {}, &info);
    EXPECT_EQ(info.degenerate_faces, 1u);
}

TEST_F(ObjReader, TextConventions) {
    // CRLF, '\' continuation (also of a corner list and with CRLF), tabs, comments after a
    // statement, a UTF-8 byte order mark, '+' signs, a last line without newline.
    TriangleMesh m = load(
        "\xef\xbb\xbfv 0 0 0\r\nv\t1 0 0 # x axis\r\nv 0 \\\r\n 1 0\r\nv +1 +1e0 -0.0\n"
        "f 1 2 \\\n3 4");
    ASSERT_EQ(m.vertex_count(), 4u);
    EXPECT_EQ(m.positions[2], Vec3f(0, 1, 0));
    EXPECT_EQ(m.positions[3], Vec3f(1, 1, 0));
    EXPECT_EQ(m.triangle_count(), 2u);
    // A comment ending in '\' does not swallow the next line.
    EXPECT_EQ(load(std::string("# C:\\models\\\n") + kTriangle + "f 1 2 3\n").triangle_count(), 1u);
    // Line numbers count physical lines, continued ones included.
    EXPECT_NE(
        error_of("v 0 \\\n0 0\n\nv x 0 0\n").find("t.obj: line 4: vertex 2: invalid number 'x'"),
        std::string::npos)
        << error_of("v 0 \\\n0 0\n\nv x 0 0\n");
    // Everything not needed for rendering is skipped.
    TriangleMesh s = load(
        "mtllib a.mtl b.mtl\no thing\ng a b\ns 1\nusemtl red\nvt 0 0\nvp 0.5\nv 0 0 0 1\n"
        "v 1 0 0 1 0 0\nv 0 1 0 0.5 0.5 0.5 1\nl 1 2\np 3\ncstype bezier\ns off\nfo 1 2 3\n");
    EXPECT_EQ(s.vertex_count(), 3u);
    EXPECT_EQ(s.triangle_count(), 1u);
    // A point cloud (no faces) keeps its vertices.
    EXPECT_EQ(load("v 0 0 0\nvn 0 0 1\nv 1 1 1\n").vertex_count(), 2u);
    // Out of float's range: overflow is infinite (an error), underflow is zero.
    EXPECT_NE(error_of("v 1e39 0 0\n").find("t.obj: line 1: vertex 1: non-finite coordinate"),
              std::string::npos);
    EXPECT_EQ(load("v 1e-50 -1e-999 0.000000000000000000000000000000000000000000000000001\n")
                  .positions[0],
              Vec3f(0.0f));
}

TEST_F(ObjReader, LfCrlfAndCrLineEndingsReadAlike) {
    // A cube with LF, CRLF and CR-only (old Mac) line endings, and all three mixed.
    const std::vector<std::string> lines = {"v 0 0 0",   "v 1 0 0",   "v 1 1 0",   "v 0 1 0",
                                            "v 0 0 1",   "v 1 0 1",   "v 1 1 1",   "v 0 1 1",
                                            "# faces",   "f 1 2 3 4", "f 5 6 7 8", "f 1 2 6 5",
                                            "f 2 3 7 6", "f 3 4 8 7", "f 4 1 5 8"};
    auto join = [&](const std::vector<std::string>& ends) {
        std::string text;
        for (size_t i = 0; i < lines.size(); ++i) text += lines[i] + ends[i % ends.size()];
        return text;
    };
    const TriangleMesh lf = load(join({"\n"}));
    ASSERT_EQ(lf.vertex_count(), 8u);
    ASSERT_EQ(lf.triangle_count(), 12u);
    for (const auto& ends : std::vector<std::vector<std::string>>{
             {"\r\n"}, {"\r"}, {"\r", "\n", "\r\n"}, {"\r\n", "\r", "\r", "\n"}}) {
        const TriangleMesh m = load(join(ends));
        EXPECT_EQ(m.positions, lf.positions) << printable(join(ends));
        EXPECT_EQ(m.triangles, lf.triangles) << printable(join(ends));
    }
    // CR counts lines as LF does, CRLF counts one; '\' continues a line before any of them;
    // a comment ends at a CR; a last CR is a line end.
    EXPECT_EQ(error_of("v 0 0 0\rv 1 \\\r0 0\r\nv 0 1 0\n\r# c \\\rf 1 2 x\r"),
              "t.obj: line 7: face 1: invalid vertex index 'x'");
    EXPECT_EQ(load("v 0 0 0\rv 1 \\\r0 0\r\nv 0 1 0 # c\rf 1 2 3\r").triangle_count(), 1u);
    // A CR before the end of the data is not "inside a line" any more: old files that were
    // refused for it load.
    EXPECT_EQ(load("v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r").triangle_count(), 1u);
}

// A '\' ending the file continues the statement onto nothing: each text reads as it does
// with a line end after the '\' (the same mesh or the same message).
TEST_F(ObjReader, ContinuationAtTheEndOfTheFile) {
    const std::string tri = kTriangle;
    EXPECT_EQ(load(tri + "f 1 2 3\\").triangle_count(), 1u);
    EXPECT_EQ(load(tri + "f 1 2 \\\n3\\").triangle_count(), 1u);
    const std::vector<std::string> texts = {
        tri + "f 1 2 3\\", tri + "f 1 2 \\\r\n3 \\",   tri + "f 1 2 3\\\\",
        tri + "v\\",       tri + "f 1 2 3\n\\",        tri + "f 1 2 3 # c\\",
        tri + "vn 0 0\\",  tri + "# c \\\nf 1 2 3 \\", "\xef\xbb\xbf\\",
    };
    for (const std::string& text : texts) {
        for (const char* eol : {"\n", "\r\n", "\r"}) {
            SCOPED_TRACE(printable(text) + " " + printable(eol));
            EXPECT_EQ(error_of(text), error_of(text + eol));
            if (error_of(text).empty()) {
                EXPECT_EQ(load(text).triangles, load(text + eol).triangles);
            }
        }
    }
    EXPECT_EQ(error_of(tri + "v\\"), "t.obj: line 4: vertex 4: has 0 coordinates (x y z needed)");
}

TEST_F(ObjReader, LongLines) {
    // Lines longer than the 1 MiB read block: a comment, then a polygon of 400000 corners.
    std::string text = "#" + std::string(3u << 20, 'c') + "\n" + kTriangle + "f";
    for (int k = 0; k < 400000; ++k) text += k % 2 ? " 1 2" : " 3 2";
    text += "\nv x\n";
    EXPECT_NE(error_of(text).find("t.obj: line 6: vertex 4: invalid number 'x'"), std::string::npos)
        << error_of(text);
    text.resize(text.size() - 4);
    MeshLoadInfo info;
    EXPECT_EQ(load(text, {}, &info).triangle_count(), 799998u);
    EXPECT_EQ(info.degenerate_faces, 1u);
}

TEST_F(ObjReader, FileAndMemoryAgree) {
    const std::string text =
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n";
    TriangleMesh a = load_mesh(write("a.obj", text));
    TriangleMesh b = load(text);
    EXPECT_EQ(a.positions, b.positions);
    EXPECT_EQ(a.normals, b.normals);
    EXPECT_EQ(a.triangles, b.triangles);
}

TEST_F(ObjReader, Errors) {
    EXPECT_NE(file_error_of((dir_ / "missing.obj").string()).find("missing.obj: cannot open file"),
              std::string::npos);
    std::string oor = write("oor.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n");
    EXPECT_NE(file_error_of(oor).find("oor.obj: line 5: face 2: vertex index 9 out of range (3 "
                                      "vertices)"),
              std::string::npos)
        << file_error_of(oor);
    std::string rel = write("rel.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9\n");
    EXPECT_NE(file_error_of(rel).find("rel.obj: line 4: face 1: relative vertex index -9 points "
                                      "before the first vertex (3 vertices so far)"),
              std::string::npos)
        << file_error_of(rel);
    std::string inf =
        write("inf.obj", "v 0 0 0\nv 1e999 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 3 4\n");
    EXPECT_NE(file_error_of(inf).find("inf.obj: line 2: vertex 2: non-finite coordinate (inf, "
                                      "0.000000, 0.000000); --drop-invalid drops"),
              std::string::npos)
        << file_error_of(inf);
    MeshLoadOptions o;
    o.drop_invalid = true;
    MeshLoadInfo info;
    TriangleMesh m = load_mesh(inf, o, &info);
    EXPECT_EQ(info.dropped_faces, 1u);
    EXPECT_EQ(m.vertex_count(), 3u);
    ASSERT_EQ(m.triangle_count(), 1u);
    EXPECT_EQ(m.positions[m.triangles[0].z], Vec3f(1, 1, 0));
    std::string gz_path = (dir_ / "z.obj").string();
    gzFile gz = gzopen(gz_path.c_str(), "wb");
    gzputs(gz, kTriangle);
    gzclose(gz);
    EXPECT_NE(file_error_of(gz_path).find("z.obj: gzip-compressed OBJ files are not supported"),
              std::string::npos)
        << file_error_of(gz_path);
    // A directory, read_obj called directly.
    std::filesystem::create_directory(dir_ / "d.obj");
    try {
        read_obj((dir_ / "d.obj").string());
        ADD_FAILURE() << "a directory loaded";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("d.obj: is a directory"), std::string::npos)
            << e.what();
    }
}

TEST_F(ObjReader, NonFiniteVerticesMirrorPly) {
    // NaN and inf in any coordinate; with drop_invalid the faces using them and the vertices
    // themselves go (indices remapped), with or without normals.
    const std::string text =
        "v 0 0 0\nv nan 0 0\nv 1 0 0\nv 0 -inf 0\nv 0 1 0\nvn 0 0 1\n"
        "f 1//1 3//1 5//1\nf 1//1 2//1 3//1\nf 3//1 4//1 5//1\n";
    EXPECT_NE(error_of(text).find("t.obj: line 2: vertex 2: non-finite coordinate (nan"),
              std::string::npos)
        << error_of(text);
    MeshLoadOptions o;
    o.drop_invalid = true;
    for (bool normals : {true, false}) {
        o.keep_normals = normals;
        MeshLoadInfo info;
        TriangleMesh m = load(text, o, &info);
        EXPECT_EQ(info.source_faces, 3u);
        EXPECT_EQ(info.dropped_faces, 2u);
        ASSERT_EQ(m.triangle_count(), 1u);
        EXPECT_EQ(m.vertex_count(), 3u);
        for (const Vec3f& p : m.positions) EXPECT_TRUE(is_finite(p));
        EXPECT_EQ(m.positions[m.triangles[0].y], Vec3f(1, 0, 0));
        EXPECT_EQ(m.normals.size(), normals ? 3u : 0u);
    }
}

TEST_F(ObjReader, FacesOfFewerThanThreeCornersDroppedLikePly) {
    const std::string tri = kTriangle;
    EXPECT_NE(error_of(tri + "f 1 2\n")
                  .find("t.obj: line 4: face 1: 2 indices, a face needs at least 3; --drop-invalid "
                        "drops such faces"),
              std::string::npos)
        << error_of(tri + "f 1 2\n");
    MeshLoadOptions o;
    o.drop_invalid = true;
    // Dropped faces lack normals and name a vertex out of range: neither counts, as a PLY
    // face dropped for its size is not checked either.
    const std::string text =
        tri + "vn 0 0 1\nf 1//1 2//1 3//1\nf 1 2\nf 1\nf\nf 1 9\nf 3//1 2//1 1//1\n";
    for (bool normals : {true, false}) {
        o.keep_normals = normals;
        MeshLoadInfo info;
        TriangleMesh m = load(text, o, &info);
        EXPECT_EQ(info.source_faces, 6u);
        EXPECT_EQ(info.dropped_faces, 4u);
        ASSERT_EQ(m.triangle_count(), 2u);
        EXPECT_EQ(m.triangles[1], Vec3u(m.triangles[0].z, m.triangles[0].y, m.triangles[0].x));
        EXPECT_EQ(m.normals.size(), normals ? 3u : 0u);
    }
    o.keep_normals = true;
    // Faces after a dropped one keep their numbers in the file.
    EXPECT_NE(error_of(tri + "f 1 2\nf 1 2 7\n", o)
                  .find("t.obj: line 5: face 2: vertex index 7 out of range (3 vertices)"),
              std::string::npos)
        << error_of(tri + "f 1 2\nf 1 2 7\n", o);
    // Malformed corners stay errors.
    EXPECT_NE(error_of(tri + "f 0 1\n", o).find("face 1: vertex index 0"), std::string::npos);
    // Every face dropped: the vertices stay, as in a file without faces.
    MeshLoadInfo info;
    TriangleMesh m = load(tri + "vn 0 0 1\nf 1//1 2//1\n", o, &info);
    EXPECT_EQ(info.dropped_faces, 1u);
    EXPECT_EQ(m.triangle_count(), 0u);
    EXPECT_EQ(m.vertex_count(), 3u);
}

// One hostile input per error: each message names the file, and the line where there is one.
TEST_F(ObjReader, HostileInputsGiveClearErrors) {
    const std::string tri = kTriangle;
    struct Case {
        std::string text;
        const char* error;
    };
    const Case cases[] = {
        {"", "t.obj: no vertices (an empty file, or not an OBJ file)"},
        {"# only a comment\n\n", "t.obj: no vertices"},
        {"g nothing\nusemtl x\n", "t.obj: no vertices"},
        {tri + "f 0 1 2\n", "t.obj: line 4: face 1: vertex index 0 (OBJ indices start at 1)"},
        {tri + "f 1 2 3\nf 1 2 99999999999\n",
         "t.obj: line 5: face 2: vertex index 99999999999 out of range (a mesh holds at most "
         "2^32-1 vertices)"},
        // tinyobjloader read this with atoi, which wrapped it to 3: a valid face.
        {tri + "f 1 2 4294967299\n", "t.obj: line 4: face 1: vertex index 4294967299 out of range"},
        {tri + "f 1 2 4294967295\n",
         "t.obj: line 4: face 1: vertex index 4294967295 out of range (3 vertices)"},
        {tri + "f 1 2 " + std::string(60, '9') + "\n", "t.obj: line 4: face 1: vertex index 999"},
        {tri + "f 1 2 -99999999999\n",
         "t.obj: line 4: face 1: relative vertex index -99999999999 points before the first "
         "vertex (3 vertices so far)"},
        // tinyobjloader dropped a quad with an index out of range without a word.
        {tri + "v 1 1 0\nf 1 2 3 99\n",
         "t.obj: line 5: face 1: vertex index 99 out of range (4 vertices)"},
        {tri + "f 1 2 3 4 5 6 7 8 9 10\n", "t.obj: line 4: face 1: vertex index 10 out of range"},
        {tri + "f\n", "t.obj: line 4: face 1: 0 indices, a face needs at least 3"},
        {tri + "f 1\n", "t.obj: line 4: face 1: 1 index, a face needs at least 3"},
        {tri + "f 1 2 3\nf 1 2\n", "t.obj: line 5: face 2: 2 indices, a face needs at least 3"},
        {tri + "vn 0 0 1\nf 1//1 2//1 3//2\n",
         "t.obj: line 5: face 1: normal index 2 out of range (1 normals)"},
        {tri + "f 1//-1 2//1 3//1\n",
         "t.obj: line 4: face 1: relative normal index -1 points before the first normal (0 "
         "normals so far)"},
        {tri + "f 1/0 2 3\n", "t.obj: line 4: face 1: texture coordinate index 0"},
        {tri + "f 1/1/1/1 2 3\n", "t.obj: line 4: face 1: invalid corner '1/1/1/1'"},
        {tri + "f 1 2 3x\n", "t.obj: line 4: face 1: invalid vertex index '3x'"},
        {tri + "f 1 2 /3\n", "t.obj: line 4: face 1: corner '/3' has no vertex index"},
        {tri + "f 1 2 -\n", "t.obj: line 4: face 1: invalid vertex index '-'"},
        {tri + "f 1 2 3/-\n", "t.obj: line 4: face 1: invalid texture coordinate index '-'"},
        {tri + "f 1 2 \\ 3\n", "t.obj: line 4: face 1: invalid vertex index '\\'"},
        {"v 1 2\n", "t.obj: line 1: vertex 1: has 2 coordinates (x y z needed)"},
        {"v 1 2 3 4 5 6 7 8\n", "t.obj: line 1: vertex 1: more than 7 values"},
        {"v 1,5 2 3\n", "t.obj: line 1: vertex 1: invalid number '1,5'"},
        {"v 1 2 0x10\n", "t.obj: line 1: vertex 1: invalid number '0x10'"},
        {"v 1 2 3.1+e2\n", "t.obj: line 1: vertex 1: invalid number '3.1+e2'"},
        {"v 1 2 1e\n", "t.obj: line 1: vertex 1: invalid number '1e'"},
        {"v 1 2 ++1\n", "t.obj: line 1: vertex 1: invalid number '++1'"},
        {tri + "vn 0 0\n", "t.obj: line 4: normal 1: has 2 values (x y z needed)"},
        {tri + "vn 0 0 1 0\n", "t.obj: line 4: normal 1: more than 3 values (x y z)"},
        // tinyobjloader overflowed an int on this exponent (undefined behaviour).
        {"v 1e2147483648 0 0\n", "t.obj: line 1: vertex 1: non-finite coordinate (inf"},
        {std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16),
         "t.obj: line 1: not an OBJ statement: '\\x89PNG' (binary data or UTF-16 text?)"},
        {std::string("\xfe\xff\0v\0 \0\x31", 8), "t.obj: line 1: not an OBJ statement: '\\xfe"},
        {tri + "1 2 3\n", "t.obj: line 4: not an OBJ statement: '1'"},
        {tri + std::string("f 1 2 3\0\n", 9),
         "t.obj: line 4: NUL byte in a statement (binary data or UTF-16 text?)"},
        {tri + std::string("vt\0\x01\r\x80 x\n", 9), "t.obj: line 4: NUL byte in a statement"},
    };
    for (const Case& c : cases) {
        const std::string e = error_of(c.text);
        EXPECT_NE(e.find(c.error), std::string::npos) << "input: " << c.text << "\ngot: " << e;
    }
    // A tinyobjloader extension it read with undefined behaviour (a float joint id cast to
    // int): skipped here like any other statement.
    EXPECT_EQ(load(tri + "vw 0 4294967296 1\nf 1 2 3\n").triangle_count(), 1u);
}

TEST_F(ObjReader, MaterialLibrariesAreNeverOpened) {
    // tinyobjloader's file parser opened every mtllib relative to the OBJ: a FIFO there
    // blocked forever, ../../dev/zero was read until memory ran out. Materials are not
    // used, so no other file is opened at all, whatever mtllib names.
    ASSERT_EQ(::mkfifo((dir_ / "fifo.mtl").c_str(), 0600), 0);
    std::string dots;
    for (const char* c = dir_.c_str(); *c; ++c) dots += *c == '/' ? "../" : "";
    std::string p = write(
        "m.obj", "mtllib fifo.mtl\nmtllib " + dots + "dev/zero\nmtllib /dev/zero\n" +
                     "mtllib missing.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\n" + "f 1 2 3\n");
    EXPECT_EQ(load_mesh(p).triangle_count(), 1u);
}

TEST_F(ObjReader, LoadMeshDispatchesOnContentThenExtension) {
    // PLY content wins over a misleading name; unknown content and extension is an error.
    std::string ply = write(
        "mesh.dat",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(detect_mesh_format(ply), MeshFormat::ply);
    EXPECT_EQ(load_mesh(ply).triangle_count(), 1u);
    std::string unknown = write("mesh.stl", "solid x\nendsolid x\n");
    EXPECT_NE(file_error_of(unknown).find("mesh.stl: unknown mesh format"), std::string::npos)
        << file_error_of(unknown);
    std::string bad_ply = write("bad.ply", "not a ply\n");
    EXPECT_NE(file_error_of(bad_ply).find("bad.ply: line 1: header: not a PLY file"),
              std::string::npos)
        << file_error_of(bad_ply);
    EXPECT_NE(file_error_of(dir_.string()).find("is a directory"), std::string::npos)
        << file_error_of(dir_.string());
}

// ---- the OBJ files of assimp-testmodels ---------------------------------------------------

const std::filesystem::path kModels = "/usr/share/assimp/models";

struct Expectation {
    const char* file;
    const char* error;  // substring of our message when rejected, nullptr when it loads
};

// | file                          | outcome  | why |
// | OBJ/box_UTF16BE.obj           | rejected | UTF-16 text (convert it to UTF-8)
// | OBJ/number_formats.obj        | rejected | "3.1+e2" is no number (others read 3.1)
// | invalid/empty.obj             | rejected | zero bytes
// | invalid/malformed.obj         | rejected | index 0 (and index 12 of 8 vertices earlier)
// | invalid/malformed2.obj        | rejected | a face without vertices
// | OBJ/testline.obj, testpoints  | loads    | lines and points only: vertices, no triangles
// | OBJ/box_longline.obj          | loads    | a polygon of 900+ corners (tinyobjloader counts
// |                               |          | corners in a byte: compared with Assimp only)
// | all the others                | loads    | as tinyobjloader and Assimp read them
const Expectation kCorpus[] = {
    {"OBJ/WusonOBJ.obj", nullptr},
    {"OBJ/box.obj", nullptr},
    {"OBJ/box_UTF16BE.obj", "box_UTF16BE.obj: line 1: not an OBJ statement: '\\xfe\\xff"},
    {"OBJ/box_longline.obj", nullptr},
    {"OBJ/box_mat_with_spaces.obj", nullptr},
    {"OBJ/box_without_lineending.obj", nullptr},
    {"OBJ/concave_polygon.obj", nullptr},
    {"OBJ/cube_mtllib_after_g.obj", nullptr},
    {"OBJ/cube_usemtl.obj", nullptr},
    {"OBJ/cube_with_vertexcolors.obj", nullptr},
    {"OBJ/cube_with_vertexcolors_uni.obj", nullptr},
    {"OBJ/empty_mat.obj", nullptr},
    {"OBJ/multiple_spaces.obj", nullptr},
    {"OBJ/number_formats.obj", "number_formats.obj: line 11: vertex 8: invalid number '3.1+e2'"},
    {"OBJ/point_cloud.obj", nullptr},
    {"OBJ/regr01.obj", nullptr},
    {"OBJ/regr_3429812.obj", nullptr},
    {"OBJ/space_in_material_name.obj", nullptr},
    {"OBJ/spider.obj", nullptr},
    {"OBJ/testline.obj", nullptr},
    {"OBJ/testmixed.obj", nullptr},
    {"OBJ/testpoints.obj", nullptr},
    {"invalid/empty.obj", "empty.obj: no vertices (an empty file, or not an OBJ file)"},
    {"invalid/malformed.obj",
     "malformed.obj: line 28: face 6: vertex index 0 (OBJ indices start at 1)"},
    {"invalid/malformed2.obj",
     "malformed2.obj: line 23: face 1: 0 indices, a face needs at least 3"},
};

using test::Tri;
using test::triangles_of;

// Equal within one float ulp: Assimp's fast_atof and tinyobjloader's parser are not
// correctly rounded.
bool near(const Vec3f& a, const Vec3f& b) {
    for (int k = 0; k < 3; ++k) {
        float tol = 1.2e-7f * std::max(std::fabs(a[k]), std::fabs(b[k]));
        if (std::fabs(a[k] - b[k]) > tol) return false;
    }
    return true;
}

bool same_triangle(const Tri& a, const Tri& b) {
    for (int k = 0; k < 3; ++k)
        if (!near(a[size_t(k)], b[size_t(k)])) return false;
    return true;
}

// A peer's polygon split as our reader splits it (triangulate_polygon), so that a wrong
// corner or corner order shows as different triangles.
void split_like_ours(const std::vector<Vec3f>& corners, std::vector<Tri>& out) {
    std::vector<Vec3u> t(corners.size() - 2);
    PolygonScratch scratch;
    triangulate_polygon(corners, t.data(), scratch);
    for (const Vec3u& k : t) out.push_back({corners[k.x], corners[k.y], corners[k.z]});
}

// Total area of the triangles (used by the Assimp comparison only).
[[maybe_unused]] double area_of(const std::vector<Tri>& tris) {
    double a = 0.0;
    for (const Tri& t : tris)
        a += 0.5 * glm::length(glm::cross(Vec3d(t[1]) - Vec3d(t[0]), Vec3d(t[2]) - Vec3d(t[0])));
    return a;
}

// tinyobjloader without its triangulation (it splits quads along the shorter diagonal and
// ear-clips bigger polygons), its polygons split here the way ours are, in file order.
// Empty when it cannot hold a face: it counts corners in an unsigned char.
std::optional<std::vector<Tri>> tinyobj_triangles(const std::string& path) {
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    std::ifstream in(path, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_TRUE(reader.ParseFromString(text, std::string(), config)) << reader.Error();
    const std::vector<float>& v = reader.GetAttrib().vertices;
    auto at = [&](int i) {
        return Vec3f(v[3 * size_t(i)], v[3 * size_t(i) + 1], v[3 * size_t(i) + 2]);
    };
    std::vector<Tri> out;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        size_t corners = 0;
        for (const unsigned char n : shape.mesh.num_face_vertices) corners += n;
        if (corners != shape.mesh.indices.size()) return std::nullopt;
        size_t c = 0;
        for (const unsigned char n : shape.mesh.num_face_vertices) {
            const tinyobj::index_t* idx = &shape.mesh.indices[c];
            std::vector<Vec3f> polygon;
            for (size_t k = 0; k < n; ++k) polygon.push_back(at(idx[k].vertex_index));
            if (n >= 3) split_like_ours(polygon, out);
            c += n;
        }
    }
    return out;
}

TEST(ObjCorpus, EveryObjLoadsLikeTinyobjloaderAndAssimpOrIsRejectedClearly) {
    if (!std::filesystem::is_directory(kModels))
        GTEST_SKIP() << kModels << " not found (apt-get install assimp-testmodels)";
    std::vector<std::string> found;
    for (const auto& e : std::filesystem::recursive_directory_iterator(kModels)) {
        std::string name = e.path().filename().string();
        if (e.is_regular_file() && name.size() > 4 && name.substr(name.size() - 4) == ".obj")
            found.push_back(std::filesystem::relative(e.path(), kModels).string());
    }
    for (const std::string& f : found) {
        bool listed = std::any_of(std::begin(kCorpus), std::end(kCorpus),
                                  [&](const Expectation& x) { return f == x.file; });
        EXPECT_TRUE(listed) << f << " is not in the corpus table";
    }

    for (const Expectation& x : kCorpus) {
        const std::string path = (kModels / x.file).string();
        SCOPED_TRACE(path);
        if (!std::filesystem::exists(path)) continue;
        if (x.error) {
            try {
                load_mesh(path);
                ADD_FAILURE() << "loaded, but the table says it is rejected";
            } catch (const Error& e) {
                EXPECT_NE(std::string(e.what()).find(x.error), std::string::npos) << e.what();
            }
            continue;
        }
        MeshLoadOptions positions_only;
        positions_only.keep_normals = false;
        const TriangleMesh mesh = load_mesh(path, positions_only);
        const std::vector<Tri> ours = triangles_of(mesh);
        // With normals the same triangles, split per (position, normal) pair.
        EXPECT_EQ(load_mesh(path).triangle_count(), mesh.triangle_count());

        // tinyobjloader: the same triangles in the same order.
        const std::optional<std::vector<Tri>> tiny = tinyobj_triangles(path);
        EXPECT_EQ(!tiny, std::string(x.file) == "OBJ/box_longline.obj");
        if (tiny) {
            ASSERT_EQ(ours.size(), tiny->size()) << "triangle count differs from tinyobjloader's";
            size_t differ = 0;
            for (size_t t = 0; t < ours.size(); ++t) differ += !same_triangle(ours[t], (*tiny)[t]);
            EXPECT_EQ(differ, 0u) << "triangles whose corners differ from tinyobjloader's";
        }

#ifdef KDT_HAVE_ASSIMP
        // Assimp (flags 0: polygons kept, split here): one mesh per object and material,
        // each in file order. So each of its meshes must be a subsequence of our triangles,
        // and the counts must agree.
        const aiScene* scene = aiImportFile(path.c_str(), 0);
        ASSERT_NE(scene, nullptr) << aiGetErrorString();
        size_t their_count = 0;
        for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
            const aiMesh* am = scene->mMeshes[m];
            auto v = [&](unsigned i) {
                return Vec3f(am->mVertices[i].x, am->mVertices[i].y, am->mVertices[i].z);
            };
            size_t next = 0, missing = 0;
            for (unsigned f = 0; f < am->mNumFaces; ++f) {
                const aiFace& face = am->mFaces[f];
                if (face.mNumIndices < 3) continue;
                std::vector<Vec3f> corners;
                for (unsigned k = 0; k < face.mNumIndices; ++k)
                    corners.push_back(v(face.mIndices[k]));
                std::vector<Tri> split;
                split_like_ours(corners, split);
                for (const Tri& t : split) {
                    ++their_count;
                    while (next < ours.size() && !same_triangle(ours[next], t)) ++next;
                    if (next == ours.size())
                        ++missing;
                    else
                        ++next;
                }
            }
            EXPECT_EQ(missing, 0u) << "Assimp mesh " << m << ": triangles not found in ours";
        }
        aiReleaseImport(scene);
        EXPECT_EQ(ours.size(), their_count) << "triangle count differs from Assimp's";

        // Assimp's own split (aiProcess_Triangulate) covers the same area: a fan of a
        // concave polygon (concave_polygon.obj's keyhole 66-gon) covers more.
        const aiScene* split = aiImportFile(path.c_str(), aiProcess_Triangulate);
        ASSERT_NE(split, nullptr) << aiGetErrorString();
        std::vector<Tri> theirs;
        for (unsigned m = 0; m < split->mNumMeshes; ++m) {
            const aiMesh* am = split->mMeshes[m];
            auto v = [&](unsigned i) {
                return Vec3f(am->mVertices[i].x, am->mVertices[i].y, am->mVertices[i].z);
            };
            for (unsigned f = 0; f < am->mNumFaces; ++f)
                if (am->mFaces[f].mNumIndices == 3)
                    theirs.push_back({v(am->mFaces[f].mIndices[0]), v(am->mFaces[f].mIndices[1]),
                                      v(am->mFaces[f].mIndices[2])});
        }
        aiReleaseImport(split);
        EXPECT_NEAR(area_of(ours), area_of(theirs), 1e-5 * area_of(theirs))
            << "area differs from Assimp's triangulation";
#endif
    }
}

}  // namespace
}  // namespace kdt
