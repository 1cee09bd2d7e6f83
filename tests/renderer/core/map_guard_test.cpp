// MapGuard: a read of a mapped file that shrank meanwhile sees zeros and is reported as an
// Error naming the file, on any thread, instead of killing the process with SIGBUS.
#include "renderer/core/map_guard.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;

class MapGuardTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = test::temp_dir("kdt_map_guard");
        path_ = (dir_ / "data.bin").string();
        page_ = size_t(::sysconf(_SC_PAGESIZE));
        test::write_bytes(path_, std::vector<unsigned char>(4 * page_, 7));
        fd_ = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
        ASSERT_GE(fd_, 0);
        void* p = ::mmap(nullptr, 4 * page_, PROT_READ, MAP_PRIVATE, fd_, 0);
        ASSERT_NE(p, MAP_FAILED);
        data_ = static_cast<const volatile unsigned char*>(p);
    }
    void TearDown() override {
        if (data_) ::munmap(const_cast<unsigned char*>(data_), 4 * page_);
        if (fd_ >= 0) ::close(fd_);
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }

    fs::path dir_;
    std::string path_;
    size_t page_ = 4096;
    int fd_ = -1;
    const volatile unsigned char* data_ = nullptr;
};

TEST_F(MapGuardTest, UnchangedFileReadsAsItIs) {
    MapGuard guard(const_cast<const unsigned char*>(data_), 4 * page_, fd_, path_);
    EXPECT_EQ(data_[3 * page_ + 5], 7);
    EXPECT_FALSE(guard.faulted());
    EXPECT_NO_THROW(guard.check());
}

TEST_F(MapGuardTest, ReadPastATruncationSeesZerosAndIsReported) {
    MapGuard guard(const_cast<const unsigned char*>(data_), 4 * page_, fd_, path_);
    ASSERT_EQ(::truncate(path_.c_str(), off_t(page_)), 0);
    EXPECT_EQ(data_[0], 7);
    EXPECT_EQ(data_[2 * page_ + 1], 0);  // SIGBUS without the guard
    EXPECT_EQ(data_[3 * page_], 0);
    EXPECT_EQ(data_[page_ + 9], 0);  // an earlier page of the truncated part
    EXPECT_TRUE(guard.faulted());
    const std::string msg = test::error_of_call([&] { guard.check(); });
    EXPECT_EQ(msg, path_ + ": the file changed or was truncated while it was read");
}

TEST_F(MapGuardTest, FaultOnAnotherThreadIsCaught) {
    MapGuard guard(const_cast<const unsigned char*>(data_), 4 * page_, fd_, path_);
    ASSERT_EQ(::truncate(path_.c_str(), 0), 0);
    int seen = -1;
    std::thread([&] { seen = data_[page_]; }).join();
    EXPECT_EQ(seen, 0);
    EXPECT_TRUE(guard.faulted());
    EXPECT_NE(test::error_of_call([&] { guard.check(); }).find("truncated"), std::string::npos);
}

TEST_F(MapGuardTest, GrownFileIsReportedWithoutAFault) {
    MapGuard guard(const_cast<const unsigned char*>(data_), 4 * page_, fd_, path_);
    ASSERT_EQ(::truncate(path_.c_str(), off_t(5 * page_)), 0);
    EXPECT_EQ(data_[3 * page_], 7);
    EXPECT_FALSE(guard.faulted());
    EXPECT_NE(test::error_of_call([&] { guard.check(); }).find("changed"), std::string::npos);
}

void custom_handler(int) {}

TEST_F(MapGuardTest, PreviousHandlerIsRestored) {
    struct sigaction mine {
    }, old{}, now{};
    mine.sa_handler = custom_handler;
    ::sigemptyset(&mine.sa_mask);
    ASSERT_EQ(::sigaction(SIGBUS, &mine, &old), 0);
    {
        MapGuard a(const_cast<const unsigned char*>(data_), 2 * page_, fd_, path_);
        MapGuard b(const_cast<const unsigned char*>(data_) + 2 * page_, 2 * page_, fd_, path_);
        ::sigaction(SIGBUS, nullptr, &now);
        EXPECT_NE(now.sa_handler, custom_handler);
    }
    ::sigaction(SIGBUS, nullptr, &now);
    EXPECT_EQ(now.sa_handler, custom_handler);
    ::sigaction(SIGBUS, &old, nullptr);
}

}  // namespace
}  // namespace kdt
