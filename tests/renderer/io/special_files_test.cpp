// Every reader of user-named files refuses FIFOs and devices at once, naming the file,
// instead of blocking on a FIFO without a writer or reading /dev/zero forever.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/io/image_io.h"
#include "renderer/io/mesh_io.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

class SpecialFiles : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = test::temp_dir("special_files");
        for (const char* name : {"mesh.ply", "mesh.obj", "mesh.ply.gz", "probe.hdr", "probe.exr"}) {
            const std::string p = (dir_ / name).string();
            ASSERT_EQ(::mkfifo(p.c_str(), 0600), 0) << p;
        }
    }
    std::string path(const char* name) const { return (dir_ / name).string(); }
    std::filesystem::path dir_;
};

TEST_F(SpecialFiles, MeshReadersRefuseFifos) {
    for (const char* name : {"mesh.ply", "mesh.obj", "mesh.ply.gz"}) {
        const std::string p = path(name);
        const std::string msg = test::error_of_call([&] { load_mesh(p); });
        EXPECT_NE(msg.find(p + ": is a FIFO (pipe)"), std::string::npos) << msg;
    }
}

TEST_F(SpecialFiles, ImageReadersRefuseFifos) {
    for (const char* name : {"probe.hdr", "probe.exr"}) {
        const std::string p = path(name);
        const std::string msg = test::error_of_call([&] { load_image(p); });
        EXPECT_NE(msg.find(p + ": is a FIFO (pipe)"), std::string::npos) << msg;
    }
}

TEST_F(SpecialFiles, ReadersRefuseCharacterDevices) {
    std::string msg = test::error_of_call([] { load_mesh("/dev/zero"); });
    EXPECT_NE(msg.find("/dev/zero: is a character device"), std::string::npos) << msg;
    msg = test::error_of_call([] { load_image("/dev/zero"); });
    EXPECT_NE(msg.find("/dev/zero: is a character device"), std::string::npos) << msg;
}

}  // namespace
}  // namespace kdt
