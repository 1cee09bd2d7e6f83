// Polygons in PLY (ascii, binary both byte orders, faces before vertices) and OBJ files:
// concave ones are split by triangulate_polygon, not fanned, so their triangles cover each
// polygon exactly; convex ones keep their fan. Cross-checked against Assimp's triangulation.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/geometry/polygon.h"
#include "renderer/io/mesh_io.h"
#include "renderer/io/obj_reader.h"
#include "tests/renderer/io/ply_test_util.h"
#include "tests/test_util.h"

#ifdef KDT_HAVE_ASSIMP
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#endif

namespace kdt {
namespace {

// Vertices in the plane z = 0; each polygon lists vertex numbers counter-clockwise seen
// from +z. The L, dart and star are concave with a corner the fan from corner 0 gets wrong;
// the square is convex.
struct Model {
    std::vector<Vec3f> positions;
    std::vector<std::vector<uint32_t>> faces;
};

Model make_model() {
    Model m;
    auto add = [&](std::vector<Vec3f> corners) {
        std::vector<uint32_t> f;
        for (const Vec3f& c : corners) {
            f.push_back(uint32_t(m.positions.size()));
            m.positions.push_back(c);
        }
        m.faces.push_back(f);
    };
    add({{2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0}, {0, 0, 0}, {2, 0, 0}});  // L
    add({{10, 0, 0}, {12, 1, 0}, {14, 0, 0}, {12, 3, 0}});                    // dart
    std::vector<Vec3f> star;
    for (int k = 0; k < 10; ++k) {
        const float r = k % 2 ? 0.4f : 1.0f, a = float(k) * 0.6283185f;
        star.emplace_back(20.0f + r * std::cos(a + 0.3f), r * std::sin(a + 0.3f), 0.0f);
    }
    add(star);
    add({{30, 0, 0}, {31, 0, 0}, {31, 1, 0}, {30, 1, 0}});  // square
    // A triangle sharing the square's corners: faces mixed with polygons.
    m.faces.push_back({m.faces.back()[0], m.faces.back()[1], m.faces.back()[2]});
    return m;
}

std::string ply_text(const Model& m, const std::string& format, const std::string& index_type,
                     bool faces_first) {
    const bool binary = format != "ascii";
    const bool big = format == "binary_big_endian";
    std::string vertices = "element vertex " + std::to_string(m.positions.size()) +
                           "\nproperty float x\nproperty float y\nproperty float z\n";
    std::string faces = "element face " + std::to_string(m.faces.size()) +
                        "\nproperty list uchar " + index_type + " vertex_indices\n";
    std::string head = "ply\nformat " + format + " 1.0\n" +
                       (faces_first ? faces + vertices : vertices + faces) + "end_header\n";
    test::Bytes vb, fb;
    vb.big = fb.big = big;
    std::string vt, ft;
    for (const Vec3f& p : m.positions) {
        vb.put(p.x).put(p.y).put(p.z);
        char line[96];
        std::snprintf(line, sizeof(line), "%.9g %.9g %.9g\n", p.x, p.y, p.z);
        vt += line;
    }
    for (const std::vector<uint32_t>& f : m.faces) {
        fb.put(uint8_t(f.size()));
        ft += std::to_string(f.size());
        for (uint32_t i : f) {
            if (index_type == "float")
                fb.put(float(i));
            else if (index_type == "double")
                fb.put(double(i));
            else
                fb.put(int32_t(i));
            ft += " " + std::to_string(i) + (index_type == "int" ? "" : ".0");
        }
        ft += "\n";
    }
    const std::string v = binary ? vb.s : vt, f = binary ? fb.s : ft;
    return head + (faces_first ? f + v : v + f);
}

std::string obj_text(const Model& m, bool normals) {
    std::string s;
    char line[96];
    for (const Vec3f& p : m.positions) {
        std::snprintf(line, sizeof(line), "v %.9g %.9g %.9g\n", p.x, p.y, p.z);
        s += line;
    }
    if (normals) s += "vn 0 0 1\n";
    for (const std::vector<uint32_t>& f : m.faces) {
        s += "f";
        for (uint32_t i : f) s += " " + std::to_string(i + 1) + (normals ? "//1" : "");
        s += "\n";
    }
    return s;
}

using test::Tri;
using test::triangles_of;

// The triangles each face should give, by corner positions, in face order.
std::vector<Tri> expected(const Model& m) {
    std::vector<Tri> out;
    PolygonScratch s;
    for (const std::vector<uint32_t>& f : m.faces) {
        std::vector<Vec3f> c;
        for (uint32_t i : f) c.push_back(m.positions[i]);
        std::vector<Vec3u> t(f.size() - 2);
        triangulate_polygon(c, t.data(), s);
        for (const Vec3u& k : t) out.push_back({c[k.x], c[k.y], c[k.z]});
    }
    return out;
}

double area_z(const Tri& t) {
    return 0.5 * (double(t[1].x - t[0].x) * double(t[2].y - t[0].y) -
                  double(t[1].y - t[0].y) * double(t[2].x - t[0].x));
}

bool inside(const std::vector<Vec3f>& p, double x, double y) {
    bool in = false;
    for (size_t i = 0, j = p.size() - 1; i < p.size(); j = i++)
        if ((p[i].y > y) != (p[j].y > y) &&
            x < double(p[j].x - p[i].x) * (y - p[i].y) / double(p[j].y - p[i].y) + p[i].x)
            in = !in;
    return in;
}

// Every triangle lies in one of the model's polygons, faces the way they do (+z), and the
// areas add up to the polygons' areas.
void expect_cover(const Model& m, const std::vector<Tri>& tris) {
    double polygons = 0.0, sum = 0.0;
    for (const std::vector<uint32_t>& f : m.faces) {
        std::vector<Vec3f> c;
        for (uint32_t i : f) c.push_back(m.positions[i]);
        for (size_t k = 1; k + 1 < c.size(); ++k) polygons += area_z({c[0], c[k], c[k + 1]});
    }
    for (const Tri& t : tris) {
        const double a = area_z(t);
        EXPECT_GT(a, 0.0) << "a triangle faces away from its polygon's side";
        sum += a;
        const double x = (t[0].x + t[1].x + t[2].x) / 3.0, y = (t[0].y + t[1].y + t[2].y) / 3.0;
        bool in = false;
        for (const std::vector<uint32_t>& f : m.faces) {
            std::vector<Vec3f> c;
            for (uint32_t i : f) c.push_back(m.positions[i]);
            in |= inside(c, x, y);
        }
        EXPECT_TRUE(in) << "triangle centred at (" << x << ", " << y << ") outside the polygons";
    }
    EXPECT_NEAR(sum, polygons, 1e-5 * polygons);
}

TEST(PolygonFaces, PlyConcavePolygonsAreCoveredExactly) {
    const Model m = make_model();
    const std::vector<Tri> want = expected(m);
    for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
        for (bool faces_first : {false, true}) {
            SCOPED_TRACE(std::string(format) + (faces_first ? ", faces first" : ""));
            MeshLoadInfo info;
            const TriangleMesh mesh =
                test::load(ply_text(m, format, "int", faces_first), {}, &info);
            EXPECT_EQ(triangles_of(mesh), want);
            expect_cover(m, triangles_of(mesh));
            EXPECT_EQ(info.source_faces, m.faces.size());
            EXPECT_EQ(info.degenerate_faces, 0u);
        }
    }
}

TEST(PolygonFaces, PlyConvexQuadKeepsItsFan) {
    const TriangleMesh mesh = test::load(test::kCubeAscii);
    EXPECT_EQ(mesh.triangles, (std::vector<Vec3u>{{0, 1, 2}, {0, 2, 3}, {0, 1, 4}}));
}

TEST(PolygonFaces, ObjConcavePolygonsAreCoveredExactly) {
    const Model m = make_model();
    const std::vector<Tri> want = expected(m);
    for (bool normals : {false, true}) {
        SCOPED_TRACE(normals ? "with normals" : "positions only");
        const std::string text = obj_text(m, normals);
        const TriangleMesh mesh = read_obj_memory(text.data(), text.size(), "t.obj", {});
        EXPECT_EQ(mesh.normals.empty(), !normals);
        EXPECT_EQ(triangles_of(mesh), want);
        expect_cover(m, triangles_of(mesh));
    }
}

TEST(PolygonFaces, DropInvalidDropsAConcavePolygonOfANonFiniteVertex) {
    Model m = make_model();
    m.positions[m.faces[1][2]].x = std::nanf("");  // the dart's
    MeshLoadOptions drop;
    drop.drop_invalid = true;
    for (bool faces_first : {false, true}) {
        std::string text = ply_text(m, "ascii", "int", faces_first);
        const TriangleMesh ply = test::load(text, drop);
        Model rest = make_model();
        rest.faces.erase(rest.faces.begin() + 1);
        expect_cover(rest, triangles_of(ply));
        EXPECT_EQ(ply.triangle_count(), 4u + 8u + 2u + 1u);
    }
    const std::string text = obj_text(m, false);
    const TriangleMesh obj = read_obj_memory(text.data(), text.size(), "t.obj", drop);
    EXPECT_EQ(obj.triangle_count(), 4u + 8u + 2u + 1u);
}

#ifdef KDT_HAVE_ASSIMP
// Assimp's triangulation (aiProcess_Triangulate) of the same concave PLY: its triangles may
// start elsewhere or come in another order, so both sets are checked to cover the polygons,
// with the same total area.
TEST(PolygonFaces, PlyConcavePolygonsCoverWhatAssimpCovers) {
    const Model m = make_model();
    const std::filesystem::path dir = test::temp_dir("polygon_faces");
    const std::string path =
        test::write_text(dir, "concave.ply", ply_text(m, "binary_little_endian", "int", false));
    const aiScene* scene = aiImportFile(path.c_str(), aiProcess_Triangulate);
    ASSERT_NE(scene, nullptr) << aiGetErrorString();
    std::vector<Tri> theirs;
    for (unsigned k = 0; k < scene->mNumMeshes; ++k) {
        const aiMesh* am = scene->mMeshes[k];
        auto v = [&](unsigned i) {
            return Vec3f(am->mVertices[i].x, am->mVertices[i].y, am->mVertices[i].z);
        };
        for (unsigned f = 0; f < am->mNumFaces; ++f) {
            const aiFace& face = am->mFaces[f];
            ASSERT_EQ(face.mNumIndices, 3u);
            theirs.push_back({v(face.mIndices[0]), v(face.mIndices[1]), v(face.mIndices[2])});
        }
    }
    aiReleaseImport(scene);
    const std::vector<Tri> ours = triangles_of(load_mesh(path));
    std::filesystem::remove_all(dir);
    {
        SCOPED_TRACE("Assimp");
        expect_cover(m, theirs);
    }
    expect_cover(m, ours);
    EXPECT_EQ(ours.size(), theirs.size());
    double a = 0.0, b = 0.0;
    for (const Tri& t : ours) a += area_z(t);
    for (const Tri& t : theirs) b += area_z(t);
    EXPECT_NEAR(a, b, 1e-6 * b);
}

// Float and double index lists, which Assimp reads too: the same polygons, the same area.
TEST(PolygonFaces, RealIndexListsLoadAsAssimpLoadsThem) {
    const Model m = make_model();
    const std::vector<Tri> want = expected(m);
    const std::filesystem::path dir = test::temp_dir("polygon_faces_real");
    for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
        for (const char* type : {"float", "double"}) {
            SCOPED_TRACE(std::string(format) + " " + type);
            const std::string path =
                test::write_text(dir, "real.ply", ply_text(m, format, type, false));
            const std::vector<Tri> ours = triangles_of(load_mesh(path));
            EXPECT_EQ(ours, want);
            const aiScene* scene = aiImportFile(path.c_str(), aiProcess_Triangulate);
            ASSERT_NE(scene, nullptr) << aiGetErrorString();
            double theirs = 0.0;
            for (unsigned k = 0; k < scene->mNumMeshes; ++k) {
                const aiMesh* am = scene->mMeshes[k];
                auto v = [&](unsigned i) {
                    return Vec3f(am->mVertices[i].x, am->mVertices[i].y, am->mVertices[i].z);
                };
                for (unsigned f = 0; f < am->mNumFaces; ++f) {
                    const unsigned* i = am->mFaces[f].mIndices;
                    if (am->mFaces[f].mNumIndices == 3)
                        theirs += area_z({v(i[0]), v(i[1]), v(i[2])});
                }
            }
            aiReleaseImport(scene);
            double a = 0.0;
            for (const Tri& t : ours) a += area_z(t);
            EXPECT_NEAR(a, theirs, 1e-6 * theirs);
        }
    }
    std::filesystem::remove_all(dir);
}
#endif

}  // namespace
}  // namespace kdt
