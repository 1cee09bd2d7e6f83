// Round trips through renderer/io/ply_writer: all three encodings (and gzip) give back the
// identical mesh, bit for bit, with and without normals and colours.
#include "renderer/io/ply_writer.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/ply_reader.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

// A seeded random mesh including awkward floats: -0, subnormals, huge and tiny values.
TriangleMesh random_mesh(uint32_t seed, size_t vertices, size_t triangles, bool normals,
                         bool colors) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<uint32_t> bits;
    auto any_float = [&] {
        float f;
        do {
            f = std::bit_cast<float>(bits(rng));
        } while (!std::isfinite(f));
        return f;
    };
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    TriangleMesh m;
    for (size_t i = 0; i < vertices; ++i) {
        Vec3f p = i % 2 ? Vec3f(any_float(), any_float(), any_float())
                        : Vec3f(unit(rng), -unit(rng), unit(rng) * 1e3f);
        m.positions.push_back(p);
        if (normals)
            m.normals.push_back(glm::normalize(Vec3f(unit(rng) - 0.5f, unit(rng) - 0.5f, 1.0f)));
        if (colors) m.colors.push_back(Vec3f(unit(rng), unit(rng), unit(rng)));
    }
    m.positions[0] =
        Vec3f(-0.0f, std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::max());
    m.positions[1] =
        Vec3f(std::numeric_limits<float>::lowest(), std::numeric_limits<float>::min(), 1e-30f);
    std::uniform_int_distribution<uint32_t> vi(0, uint32_t(vertices - 1));
    for (size_t t = 0; t < triangles; ++t) m.triangles.emplace_back(vi(rng), vi(rng), vi(rng));
    return m;
}

template <typename T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
    if (a.size() != b.size()) return false;
    return a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

TEST(PlyWriter, RoundTripInEveryEncodingIsBitExact) {
    auto dir = test::temp_dir("ply_writer");
    for (int variant = 0; variant < 4; ++variant) {
        bool normals = variant & 1, colors = variant & 2;
        TriangleMesh mesh = random_mesh(7 + uint32_t(variant), 3000, 5000, normals, colors);
        for (PlyEncoding enc : {PlyEncoding::ascii, PlyEncoding::binary_little_endian,
                                PlyEncoding::binary_big_endian}) {
            for (const char* ext : {".ply", ".ply.gz"}) {
                std::string path = (dir / (std::string("m") + std::to_string(variant) + "_" +
                                           kPlyEncodingNames[size_t(enc)] + ext))
                                       .string();
                SCOPED_TRACE(path);
                write_ply(path, mesh, enc);
                MeshLoadInfo info;
                TriangleMesh back = read_ply(path, {}, &info);
                EXPECT_EQ(info.encoding, kPlyEncodingNames[size_t(enc)]);
                EXPECT_EQ(info.gzip, std::string(ext) == ".ply.gz");
                EXPECT_TRUE(same_bits(back.positions, mesh.positions));
                EXPECT_TRUE(same_bits(back.normals, mesh.normals));
                EXPECT_TRUE(same_bits(back.colors, mesh.colors));
                EXPECT_TRUE(same_bits(back.triangles, mesh.triangles));
                EXPECT_EQ(back.content_hash(), mesh.content_hash());
            }
        }
    }
    std::filesystem::remove_all(dir);
}

TEST(PlyWriter, EmptyMeshAndPointCloud) {
    auto dir = test::temp_dir("ply_writer_empty");
    TriangleMesh empty;
    write_ply((dir / "e.ply").string(), empty, PlyEncoding::binary_big_endian);
    TriangleMesh back = read_ply((dir / "e.ply").string());
    EXPECT_EQ(back.vertex_count(), 0u);
    TriangleMesh pts;
    pts.positions = {Vec3f(1, 2, 3), Vec3f(4, 5, 6)};
    write_ply((dir / "p.ply").string(), pts, PlyEncoding::ascii);
    back = read_ply((dir / "p.ply").string());
    EXPECT_EQ(back.positions, pts.positions);
    EXPECT_EQ(back.triangle_count(), 0u);
    EXPECT_THROW(write_ply((dir / "no" / "such" / "dir.ply").string(), pts, PlyEncoding::ascii),
                 Error);
    std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace kdt
