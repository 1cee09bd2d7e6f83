// Every .ply of Debian's assimp-testmodels (/usr/share/assimp/models, valid and invalid/)
// either loads with the triangle count and vertex positions Assimp's importer produces, or
// is rejected with our error. Skipped when assimp-testmodels or Assimp are absent.
// Positions are compared within one float ulp (see near()), faces in file order.
//
// | file                 | outcome  | why |
// |----------------------|----------|----------------------------------------------------------------------|
// | PLY/Wuson.ply        | loads    | ascii, normals + s/t; bare "Created by Blender3D" header line
// ignored | | PLY/cube.ply         | loads    | ascii quads (float32/uint8/int32 aliases, trailing
// blanks): 12 tris  | | PLY/cube_binary.ply  | loads    | binary little endian triangles | |
// PLY/cube_uv.ply      | loads    | ascii quads with normals and texture coordinates (skipped) | |
// PLY/float-color.ply  | loads    | float red/green/blue/alpha colours kept as given | |
// PLY/issue623.ply     | rejected | header declares a vertex list property vertex_indices that the
// data  | |                      |          | lines lack: "line 13: vertex 0: missing value for
// property ..."      | | PLY/points.ply       | loads    | point cloud (no face element): 4
// vertices, 0 triangles               | | PLY/pond.0.ply       | rejected | binary point cloud
// whose data is 69 bytes shorter than its 70051     | |                      |          | vertices
// x 31 bytes: "element vertex: count 70051 needs at least     | |                      |          |
// 2171581 bytes, more than the 2171512 bytes of data in the file"      | | invalid/empty.ply    |
// rejected | zero bytes: "line 1: header: empty file (not a PLY file)"            |
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/mesh_io.h"

#ifdef KDT_HAVE_ASSIMP
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#endif

namespace kdt {
namespace {

const std::filesystem::path kModels = "/usr/share/assimp/models";

struct Expectation {
    const char* file;
    bool loads;
    const char* error;  // substring of our message when rejected
};

const Expectation kCorpus[] = {
    {"PLY/Wuson.ply", true, nullptr},
    {"PLY/cube.ply", true, nullptr},
    {"PLY/cube_binary.ply", true, nullptr},
    {"PLY/cube_uv.ply", true, nullptr},
    {"PLY/float-color.ply", true, nullptr},
    {"PLY/issue623.ply", false,
     "issue623.ply: line 13: vertex 0: missing value for property vertex_indices"},
    {"PLY/points.ply", true, nullptr},
    {"PLY/pond.0.ply", false,
     "pond.0.ply: line 3: header: element vertex: count 70051 needs at least 2171581 bytes, more "
     "than the "
     "2171512 bytes of data in the file"},
    {"invalid/empty.ply", false, "empty.ply: line 1: header: empty file (not a PLY file)"},
};

using Tri = std::array<Vec3f, 3>;

// Equal within one float ulp: Assimp's fast_atof is not correctly rounded (Wuson.ply's
// "1.515251" becomes 1.51525092 there, 1.51525104 = the nearest float here).
[[maybe_unused]] bool near(const Vec3f& a, const Vec3f& b) {
    for (int k = 0; k < 3; ++k) {
        float tol = 1.2e-7f * std::max(std::fabs(a[k]), std::fabs(b[k]));
        if (std::fabs(a[k] - b[k]) > tol) return false;
    }
    return true;
}

// Same triangle up to where each reader starts it (winding kept).
[[maybe_unused]] bool same_triangle(const Tri& a, const Tri& b) {
    for (int r = 0; r < 3; ++r)
        if (near(a[0], b[size_t(r)]) && near(a[1], b[size_t((r + 1) % 3)]) &&
            near(a[2], b[size_t((r + 2) % 3)]))
            return true;
    return false;
}

TEST(AssimpCorpus, EveryPlyLoadsLikeAssimpOrIsRejectedClearly) {
    if (!std::filesystem::is_directory(kModels))
        GTEST_SKIP() << kModels << " not found (apt-get install assimp-testmodels)";
    // Every .ply in the corpus must be listed in the table above.
    std::vector<std::string> found;
    for (const auto& e : std::filesystem::recursive_directory_iterator(kModels)) {
        std::string name = e.path().filename().string();
        if (e.is_regular_file() && name.size() > 4 && name.substr(name.size() - 4) == ".ply")
            found.push_back(std::filesystem::relative(e.path(), kModels).string());
    }
    for (const std::string& f : found) {
        bool listed = std::any_of(std::begin(kCorpus), std::end(kCorpus),
                                  [&](const Expectation& x) { return f == x.file; });
        EXPECT_TRUE(listed) << f << " is not in the corpus table";
    }

    for (const Expectation& x : kCorpus) {
        std::string path = (kModels / x.file).string();
        SCOPED_TRACE(path);
        if (!std::filesystem::exists(path)) continue;
        if (!x.loads) {
            try {
                load_mesh(path);
                ADD_FAILURE() << "loaded, but the table says it is rejected";
            } catch (const Error& e) {
                EXPECT_NE(std::string(e.what()).find(x.error), std::string::npos) << e.what();
            }
            continue;
        }
        TriangleMesh mesh = load_mesh(path);
#ifdef KDT_HAVE_ASSIMP
        // Flags 0: Assimp's PLY import as is (one vertex per face corner, polygons kept);
        // its polygons, all convex quads, are fanned here as ours are.
        const aiScene* scene = aiImportFile(path.c_str(), 0);
        ASSERT_NE(scene, nullptr) << aiGetErrorString();
        std::vector<Tri> theirs, ours;
        std::vector<Vec3f> their_points;
        for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
            const aiMesh* am = scene->mMeshes[m];
            auto v = [&](unsigned i) {
                return Vec3f(am->mVertices[i].x, am->mVertices[i].y, am->mVertices[i].z);
            };
            bool points = true;
            for (unsigned f = 0; f < am->mNumFaces; ++f) {
                const aiFace& face = am->mFaces[f];
                if (face.mNumIndices >= 3) points = false;
                for (unsigned k = 1; k + 1 < face.mNumIndices; ++k)
                    theirs.push_back(
                        {v(face.mIndices[0]), v(face.mIndices[k]), v(face.mIndices[k + 1])});
            }
            if (points || am->mNumFaces == 0)
                for (unsigned i = 0; i < am->mNumVertices; ++i) their_points.push_back(v(i));
        }
        aiReleaseImport(scene);
        for (size_t t = 0; t < mesh.triangle_count(); ++t) {
            const Vec3u& i = mesh.triangles[t];
            ours.push_back({mesh.positions[i.x], mesh.positions[i.y], mesh.positions[i.z]});
        }
        EXPECT_EQ(ours.size(), theirs.size()) << "triangle count differs from Assimp's";
        // Both readers keep the file's face order.
        size_t differ = 0;
        for (size_t t = 0; t < std::min(ours.size(), theirs.size()); ++t)
            differ += !same_triangle(ours[t], theirs[t]);
        EXPECT_EQ(differ, 0u) << "triangles whose corner positions differ from Assimp's";
        if (mesh.triangle_count() == 0) {
            ASSERT_EQ(mesh.positions.size(), their_points.size());
            for (size_t i = 0; i < their_points.size(); ++i)
                EXPECT_TRUE(near(mesh.positions[i], their_points[i])) << "point " << i;
        }
#else
        EXPECT_GT(mesh.vertex_count(), 0u);
#endif
    }
}

}  // namespace
}  // namespace kdt
