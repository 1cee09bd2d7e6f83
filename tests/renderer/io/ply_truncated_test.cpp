// A PLY file mapped for reading and truncated by another process before its data is read
// gives an Error naming the file, not SIGBUS. The test hook of MapGuard truncates the file
// right after the reader mapped it, so the reads deterministically meet missing pages.
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/map_guard.h"
#include "renderer/io/mesh_io.h"
#include "tests/renderer/io/ply_test_util.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;

std::string g_victim;  // the file the hook truncates
off_t g_keep = 0;      // to this many bytes

void truncate_victim(const std::string& path) {
    if (path == g_victim) {
        ASSERT_EQ(::truncate(path.c_str(), g_keep), 0);
    }
}

class PlyTruncatedTest : public ::testing::Test {
protected:
    void SetUp() override { dir_ = test::temp_dir("kdt_ply_truncated"); }
    void TearDown() override {
        set_map_guard_test_hook(nullptr);
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }
    // Loads `path` with the file cut to `keep` bytes once it is mapped; the error message.
    std::string error_when_cut(const std::string& path, off_t keep, int threads) {
        g_victim = path;
        g_keep = keep;
        set_map_guard_test_hook(truncate_victim);
        MeshLoadOptions options;
        options.threads = threads;
        return test::error_of_call([&] { load_mesh(path, options); });
    }
    fs::path dir_;
};

constexpr int kVertices = 200000;  // files of 2 MiB or more: mapped

TEST_F(PlyTruncatedTest, BinaryFileCutWhileReadIsAnError) {
    std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex " +
                      std::to_string(kVertices) +
                      "\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const float v[3] = {0.5f, 0.25f, 0.125f};
    for (int i = 0; i < kVertices; ++i) ply.append(reinterpret_cast<const char*>(v), sizeof(v));
    const unsigned char count = 3;
    const int32_t idx[3] = {0, 1, 2};
    ply.append(reinterpret_cast<const char*>(&count), 1);
    ply.append(reinterpret_cast<const char*>(idx), sizeof(idx));
    const std::string path = test::write_text(dir_, "big.ply", ply);
    ASSERT_NO_THROW(load_mesh(path));
    EXPECT_EQ(error_when_cut(path, 100000, 1),
              path + ": the file changed or was truncated while it was read");
}

TEST_F(PlyTruncatedTest, AsciiFileCutWhileReadOnTwoThreadsIsAnError) {
    std::string ply = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(kVertices) +
                      "\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    for (int i = 0; i < kVertices; ++i) ply += "0.5 0.25 0.125\n";
    ply += "3 0 1 2\n";
    const std::string path = test::write_text(dir_, "big_ascii.ply", ply);
    ASSERT_NO_THROW(load_mesh(path));
    EXPECT_EQ(error_when_cut(path, 300000, 2),
              path + ": the file changed or was truncated while it was read");
}

}  // namespace
}  // namespace kdt
