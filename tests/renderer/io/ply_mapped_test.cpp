// The mapped path of the PLY reader on small files: set_map_params() lowers the 1 MiB mapping
// threshold and the window (as the PLY fuzzer does), and a mapped read through any window
// gives what a read from memory gives, mesh for mesh and message for message.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/map_guard.h"
#include "renderer/io/ply_input.h"
#include "renderer/io/ply_reader.h"
#include "tests/renderer/io/ply_test_util.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;

int g_mapped = 0;  // MapGuards made (files mapped) since the test reset it
void count_mapping(const std::string&) { ++g_mapped; }

// What one read gave: the mesh, or the error's message.
struct Result {
    TriangleMesh mesh;
    std::string error;
};

template <typename F>
Result result_of(F&& read) {
    Result r;
    try {
        r.mesh = read();
    } catch (const Error& e) {
        r.error = e.what();
    }
    return r;
}

class PlyMappedTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = test::temp_dir("kdt_ply_mapped");
        g_mapped = 0;
        set_map_guard_test_hook(count_mapping);
    }
    void TearDown() override {
        set_map_guard_test_hook(nullptr);
        ply::set_map_params({});
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }
    fs::path dir_;
};

// Small PLY files: the fuzz seeds (ascii, binary of both byte orders, odd layouts) and one of
// a few thousand records in each encoding, so that windows end inside lines and records.
std::vector<std::string> inputs() {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(test::source_dir() / "tests/fuzz/corpus/ply")) {
        if (e.path().extension() != ".ply") continue;
        const std::vector<unsigned char> b = test::read_bytes(e.path());
        out.emplace_back(b.begin(), b.end());
    }
    std::string ascii =
        "ply\nformat ascii 1.0\nelement vertex 3000\nproperty float x\n"
        "property float y\nproperty float z\nelement face 2998\n"
        "property list uchar int vertex_indices\nend_header\n";
    test::Bytes bin;
    bin.s =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3000\nproperty float x\n"
        "property float y\nproperty float z\nelement face 2998\n"
        "property list uchar int vertex_indices\nend_header\n";
    for (int i = 0; i < 3000; ++i) {
        const float v[3] = {float(i) * 0.25f, float(i % 17) - 3.5f, 1.0f / float(i + 1)};
        ascii +=
            std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + "\n";
        bin.put(v[0]).put(v[1]).put(v[2]);
    }
    for (int i = 0; i < 2998; ++i) {
        ascii += "3 " + std::to_string(i) + " " + std::to_string(i + 1) + " " +
                 std::to_string(i + 2) + "\n";
        bin.put(uint8_t(3)).put(int32_t(i)).put(int32_t(i + 1)).put(int32_t(i + 2));
    }
    out.push_back(ascii);
    out.push_back(bin.s);
    out.push_back(ascii.substr(0, ascii.size() - 1000));  // truncated: an error
    out.push_back(bin.s.substr(0, bin.s.size() - 7));
    return out;
}

TEST_F(PlyMappedTest, SmallFilesAreMappedOnlyWhenTheThresholdIsLowered) {
    const std::string path = test::write_text(dir_, "cube.ply", test::kCubeAscii);
    const TriangleMesh buffered = read_ply(path);
    EXPECT_EQ(g_mapped, 0);  // under 1 MiB: read through a buffer
    const ply::MapParams old = ply::set_map_params({1, 64});
    EXPECT_EQ(old.min_file_bytes, uint64_t(1) << 20);
    EXPECT_EQ(old.window_bytes, ply::kBlockBytes);
    test::expect_same_mesh(read_ply(path), buffered);
    EXPECT_EQ(g_mapped, 1);
}

TEST_F(PlyMappedTest, MappedReadsThroughAnyWindowMatchMemoryReads) {
    const std::vector<std::string> files = inputs();
    ASSERT_GE(files.size(), 10u);
    for (size_t f = 0; f < files.size(); ++f) {
        const std::string path = test::write_text(dir_, "in.ply", files[f]);
        for (const bool drop : {false, true}) {
            MeshLoadOptions o;
            o.drop_invalid = drop;
            const Result memory = result_of(
                [&] { return read_ply_memory(files[f].data(), files[f].size(), path, o); });
            for (const size_t window : {size_t(1), size_t(7), size_t(64), size_t(4096)}) {
                ply::set_map_params({1, window});
                g_mapped = 0;
                const Result mapped = result_of([&] { return read_ply(path, o); });
                EXPECT_EQ(g_mapped, 1) << "file " << f;
                EXPECT_EQ(mapped.error, memory.error) << "file " << f << ", window " << window;
                EXPECT_EQ(mapped.mesh.positions, memory.mesh.positions) << "file " << f;
                EXPECT_EQ(mapped.mesh.triangles, memory.mesh.triangles) << "file " << f;
                EXPECT_EQ(mapped.mesh.normals, memory.mesh.normals) << "file " << f;
                EXPECT_EQ(mapped.mesh.colors, memory.mesh.colors) << "file " << f;
            }
        }
    }
}

}  // namespace
}  // namespace kdt
