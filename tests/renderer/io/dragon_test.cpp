// The Stanford dragon loads with its exact counts in every resolution, gzip or not, and in
// binary copies made with our writer. Skipped when scripts/fetch_assets.sh has not run.
#include <filesystem>

#include <gtest/gtest.h>

#include "renderer/io/mesh_io.h"
#include "renderer/io/ply_writer.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

#define REQUIRE_DRAGON()                                  \
    const std::filesystem::path dir = test::dragon_dir(); \
    if (dir.empty()) GTEST_SKIP() << "Stanford dragon not fetched: run scripts/fetch_assets.sh"

TEST(Dragon, ExactCountsInEveryResolution) {
    REQUIRE_DRAGON();
    struct Res {
        const char* file;
        size_t vertices, triangles;
    };
    const Res res[] = {{"dragon_vrip.ply", 437645, 871414},
                       {"dragon_vrip_res2.ply", 100250, 202520},
                       {"dragon_vrip_res3.ply", 22998, 47794},
                       {"dragon_vrip_res4.ply", 5205, 11102}};
    for (const Res& r : res) {
        SCOPED_TRACE(r.file);
        MeshLoadInfo info;
        TriangleMesh m = load_mesh((dir / r.file).string(), {}, &info);
        EXPECT_EQ(m.vertex_count(), r.vertices);
        EXPECT_EQ(m.triangle_count(), r.triangles);
        EXPECT_EQ(info.source_faces, r.triangles);
        EXPECT_EQ(info.encoding, "ascii");
        EXPECT_TRUE(is_finite(m.bounds().lower));
    }
}

TEST(Dragon, GzipAndBinaryCopiesGiveTheSameMesh) {
    REQUIRE_DRAGON();
    const std::string plain = (dir / "dragon_vrip_res2.ply").string();
    TriangleMesh ref = load_mesh(plain);
    if (std::filesystem::exists(plain + ".gz")) {
        MeshLoadInfo info;
        TriangleMesh gz = load_mesh(plain + ".gz", {}, &info);
        EXPECT_TRUE(info.gzip);
        EXPECT_EQ(gz.content_hash(), ref.content_hash());
    }
    auto tmp = test::temp_dir("dragon");
    for (PlyEncoding enc : {PlyEncoding::binary_little_endian, PlyEncoding::binary_big_endian}) {
        std::string path = (tmp / (std::string(kPlyEncodingNames[size_t(enc)]) + ".ply")).string();
        write_ply(path, ref, enc);
        EXPECT_EQ(load_mesh(path).content_hash(), ref.content_hash()) << path;
    }
    std::filesystem::remove_all(tmp);
}

}  // namespace
}  // namespace kdt
