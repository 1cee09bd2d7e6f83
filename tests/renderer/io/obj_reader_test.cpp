// Tests of renderer/io/obj_reader (tinyobjloader) and of load_mesh's format dispatch.
#include "renderer/io/obj_reader.h"

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/mesh_io.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

class ObjReader : public ::testing::Test {
protected:
    void SetUp() override { dir_ = test::temp_dir("obj_reader"); }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    std::string write(const std::string& name, const std::string& text) {
        std::string path = (dir_ / name).string();
        std::ofstream(path, std::ios::binary) << text;
        return path;
    }
    std::string error_of(const std::string& path, MeshLoadOptions o = {}) {
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
    ASSERT_EQ(m.vertex_count(), 5u);
    ASSERT_EQ(m.triangle_count(), 3u);
    EXPECT_EQ(m.triangles[2], Vec3u(0, 1, 4));
    EXPECT_EQ(m.positions[4], Vec3f(0.5f, 0.5f, 1.0f));
    EXPECT_TRUE(m.normals.empty());
    // The quad's two triangles cover the square: areas add up to 1.
    float area = 0;
    for (int t = 0; t < 2; ++t) {
        const Vec3u& i = m.triangles[size_t(t)];
        area += 0.5f * glm::length(glm::cross(m.positions[i.y] - m.positions[i.x],
                                              m.positions[i.z] - m.positions[i.x]));
    }
    EXPECT_FLOAT_EQ(area, 1.0f);
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
}

TEST_F(ObjReader, Errors) {
    EXPECT_NE(error_of((dir_ / "missing.obj").string()).find("missing.obj: cannot open file"),
              std::string::npos);
    std::string oor = write("oor.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n");
    EXPECT_NE(error_of(oor).find("oor.obj: face 1: vertex index 9 (1-based, relative indices "
                                 "resolved) out of range (3 vertices)"),
              std::string::npos)
        << error_of(oor);
    std::string rel = write("rel.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9\n");
    EXPECT_NE(error_of(rel).find("rel.obj: face 0: vertex index"), std::string::npos)
        << error_of(rel);
    std::string inf =
        write("inf.obj", "v 0 0 0\nv 1e999 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 3 4\n");
    EXPECT_NE(error_of(inf).find("inf.obj: vertex 1: non-finite coordinate"), std::string::npos)
        << error_of(inf);
    MeshLoadOptions o;
    o.drop_invalid = true;
    MeshLoadInfo info;
    TriangleMesh m = load_mesh(inf, o, &info);
    EXPECT_EQ(info.dropped_faces, 1u);
    EXPECT_EQ(m.vertex_count(), 3u);
    ASSERT_EQ(m.triangle_count(), 1u);
    EXPECT_EQ(m.positions[m.triangles[0].z], Vec3f(1, 1, 0));
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
    EXPECT_NE(error_of(unknown).find("mesh.stl: unknown mesh format"), std::string::npos)
        << error_of(unknown);
    std::string bad_ply = write("bad.ply", "not a ply\n");
    EXPECT_NE(error_of(bad_ply).find("bad.ply: line 1: header: not a PLY file"), std::string::npos)
        << error_of(bad_ply);
    EXPECT_NE(error_of(dir_.string()).find("is a directory"), std::string::npos)
        << error_of(dir_.string());
}

}  // namespace
}  // namespace kdt
