#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/interrupt.h"
#include "renderer/core/temp_file.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;

std::string read_text(const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

int mode_of(const fs::path& p) {
    struct stat st {};
    EXPECT_EQ(::stat(p.c_str(), &st), 0) << p;
    return int(st.st_mode & 07777);
}

size_t entries(const fs::path& dir) {
    return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

TEST(TempFile, ReplacingAFileKeepsItsMode) {
    const fs::path dir = test::temp_dir("temp_file_mode");
    for (int mode : {0600, 0640, 0644, 0755, 0400, 0700}) {
        const fs::path target = dir / ("out_" + std::to_string(mode) + ".txt");
        std::ofstream(target) << "old";
        ASSERT_EQ(::chmod(target.c_str(), mode_t(mode)), 0);
        const std::string text = "new contents " + std::to_string(mode);
        write_file_atomically(target.string(), text.data(), text.size());
        EXPECT_EQ(read_text(target), text);
        EXPECT_EQ(mode_of(target), mode) << target;
    }
    // A new file gets the usual mode (0666 less the umask), as any other writer would give it.
    const mode_t mask = ::umask(0);
    ::umask(mask);
    const fs::path fresh = dir / "fresh.txt";
    write_file_atomically(fresh.string(), "x", 1);
    EXPECT_EQ(mode_of(fresh), int(0666 & ~mask));
    EXPECT_EQ(entries(dir), 7u);  // no temporary file left
    EXPECT_EQ(interrupt::registered_temp_count(), 0);
}

TEST(TempFile, AnAbandonedFileIsRemovedAndUnregistered) {
    const fs::path dir = test::temp_dir("temp_file_abandon");
    const fs::path target = dir / "t.bin";
    std::ofstream(target) << "keep me";
    {
        TempFile tmp(target.string());
        tmp.write("partial", 7);
        EXPECT_TRUE(fs::exists(tmp.path()));
        EXPECT_EQ(fs::path(tmp.path()).parent_path(), dir);
        EXPECT_EQ(interrupt::registered_temp_count(), 1);
    }
    EXPECT_EQ(interrupt::registered_temp_count(), 0);
    EXPECT_EQ(entries(dir), 1u);
    EXPECT_EQ(read_text(target), "keep me");
    // An exception thrown between write and commit takes the same path.
    try {
        TempFile tmp(target.string());
        tmp.write("partial", 7);
        throw Error("interrupted");
    } catch (const Error&) {
    }
    EXPECT_EQ(entries(dir), 1u);
    EXPECT_EQ(read_text(target), "keep me");
}

TEST(TempFile, ASymlinkIsWrittenThroughAndStays) {
    const fs::path dir = test::temp_dir("temp_file_link");
    fs::create_directories(dir / "real");
    std::ofstream(dir / "real" / "a.png") << "old";
    ASSERT_EQ(::chmod((dir / "real" / "a.png").c_str(), 0640), 0);
    // A chain: an absolute link to a relative one, resolved against its own directory.
    fs::create_symlink("real/a.png", dir / "rel.png");
    fs::create_symlink(dir / "rel.png", dir / "abs.png");
    write_file_atomically((dir / "abs.png").string(), "new", 3);
    EXPECT_TRUE(fs::is_symlink(dir / "abs.png"));
    EXPECT_TRUE(fs::is_symlink(dir / "rel.png"));
    EXPECT_EQ(read_text(dir / "real" / "a.png"), "new");
    EXPECT_EQ(mode_of(dir / "real" / "a.png"), 0640);
    // A dangling link: its target is created, the link stays.
    fs::create_symlink("real/b.png", dir / "dangling.png");
    EXPECT_EQ(write_target((dir / "dangling.png").string()), (dir / "real/b.png").string());
    write_file_atomically((dir / "dangling.png").string(), "made", 4);
    EXPECT_TRUE(fs::is_symlink(dir / "dangling.png"));
    EXPECT_EQ(read_text(dir / "real" / "b.png"), "made");
    EXPECT_EQ(entries(dir), 4u);  // no temporary file left, in either directory
    EXPECT_EQ(entries(dir / "real"), 2u);
    // A loop is an error naming the path given.
    fs::create_symlink("loop2", dir / "loop1");
    fs::create_symlink("loop1", dir / "loop2");
    try {
        write_file_atomically((dir / "loop1").string(), "x", 1);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("loop1: too many levels of symbolic links"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_EQ(interrupt::registered_temp_count(), 0);
}

TEST(TempFile, FailuresNameTheTargetAndLeaveNothing) {
    const fs::path dir = test::temp_dir("temp_file_fail");
    fs::create_directories(dir / "d.png" / "inside");
    try {
        write_file_atomically((dir / "d.png").string(), "abc", 3);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("d.png: cannot replace the file"), std::string::npos)
            << e.what();
    }
    EXPECT_EQ(entries(dir), 1u);
    try {
        write_file_atomically((dir / "missing" / "x.png").string(), "abc", 3);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("x.png: cannot create temporary file"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_EQ(interrupt::registered_temp_count(), 0);
}

}  // namespace
}  // namespace kdt
