#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/open_file.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

std::string error_reading(const std::string& path, uint64_t max_bytes = uint64_t(1) << 30) {
    try {
        read_regular_file(path, max_bytes, "a test file");
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

TEST(OpenFile, ReadsARegularFileWhole) {
    const auto dir = test::temp_dir("open_file_regular");
    const std::string path = (dir / "a.txt").string();
    std::ofstream(path) << "hello";
    const std::vector<uint8_t> bytes = read_regular_file(path, 5);
    EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "hello");
    EXPECT_EQ(read_regular_file((dir / "a.txt").string(), 100).size(), 5u);
    std::ofstream((dir / "empty").string()).close();
    EXPECT_TRUE(read_regular_file((dir / "empty").string(), 0).empty());
}

TEST(OpenFile, RefusesMissingFilesAndOversizedOnes) {
    const auto dir = test::temp_dir("open_file_missing");
    const std::string missing = (dir / "nope.bin").string();
    std::string msg = error_reading(missing);
    EXPECT_NE(msg.find(missing + ": cannot open file"), std::string::npos) << msg;
    const std::string big = (dir / "big.bin").string();
    std::ofstream(big) << std::string(3u << 20, 'x');
    msg = error_reading(big, 2u << 20);
    EXPECT_NE(msg.find(big + ": file is larger than 2 MiB, too large for a test file"),
              std::string::npos)
        << msg;
}

// A FIFO without a writer would block open() and read() forever; a device such as /dev/zero
// never ends. Both are refused at once, naming the file and what it is.
TEST(OpenFile, RefusesFifosDevicesAndDirectoriesWithoutBlocking) {
    const auto dir = test::temp_dir("open_file_special");
    const std::string fifo = (dir / "pipe").string();
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::string msg = error_reading(fifo);
    EXPECT_NE(msg.find(fifo + ": is a FIFO (pipe), not a test file"), std::string::npos) << msg;
    msg = error_reading("/dev/zero");
    EXPECT_NE(msg.find("/dev/zero: is a character device, not a test file"), std::string::npos)
        << msg;
    msg = error_reading(dir.string());
    EXPECT_NE(msg.find(dir.string() + ": is a directory, not a test file"), std::string::npos)
        << msg;
    try {
        open_regular_file(fifo, "a mesh file");
        ADD_FAILURE() << "a FIFO was opened";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("not a mesh file"), std::string::npos) << e.what();
    }
}

// same_file(): every spelling and link of one file, and a file yet to be written.
TEST(SameFile, NamesOfOneFileAndOnlyThose) {
    const auto dir = test::temp_dir("same_file");
    const std::string a = (dir / "a.txt").string(), b = (dir / "b.txt").string();
    std::ofstream(a) << "a";
    std::ofstream(b) << "b";
    std::filesystem::create_hard_link(a, dir / "hard.txt");
    std::filesystem::create_symlink(a, dir / "soft.txt");
    EXPECT_TRUE(same_file(a, a));
    EXPECT_TRUE(same_file(a, (dir / "hard.txt").string()));
    EXPECT_TRUE(same_file((dir / "soft.txt").string(), a));
    EXPECT_TRUE(same_file(a, (dir / ".." / dir.filename() / "a.txt").string()));
    EXPECT_FALSE(same_file(a, b));
    const std::string later = (dir / "later.png").string();
    EXPECT_TRUE(same_file(later, (dir / "." / "later.png").string()));
    EXPECT_FALSE(same_file(later, (dir / "other.png").string()));
}

}  // namespace
}  // namespace kdt
