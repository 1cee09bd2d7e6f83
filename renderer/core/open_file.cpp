#include "renderer/core/open_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "renderer/core/error.h"

namespace kdt {

std::string file_name_problem(const std::string& name) {
    for (size_t i = 0; i < name.size(); ++i) {
        const unsigned char c = static_cast<unsigned char>(name[i]);
        if (c < 0x20 || c == 0x7f) {
            char buf[96];
            std::snprintf(buf, sizeof(buf),
                          "file name contains a control character (byte 0x%02x at offset %zu)",
                          unsigned(c), i);
            return buf;
        }
    }
    return {};
}
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& message) {
    throw Error(ErrorLocation{path}, message);
}

}  // namespace

const char* special_file_kind(uint32_t st_mode) {
    const mode_t mode = mode_t(st_mode);
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISFIFO(mode)) return "a FIFO (pipe)";
    if (S_ISSOCK(mode)) return "a socket";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (!S_ISREG(mode)) return "not a regular file";
    return nullptr;
}

int open_regular_file(const std::string& path, const char* what, uint64_t* size) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) fail(path, std::string("cannot open file: ") + std::strerror(errno));
    // Closes fd before throwing.
    auto fail_closed = [&](const std::string& message) {
        ::close(fd);
        fail(path, message);
    };
    struct stat st {};
    if (::fstat(fd, &st) != 0)
        fail_closed(std::string("cannot stat file: ") + std::strerror(errno));
    if (!S_ISREG(st.st_mode))
        fail_closed(std::string("is ") + special_file_kind(st.st_mode) + ", not " + what);
    const int flags = ::fcntl(fd, F_GETFL);
    if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0)
        fail_closed(std::string("cannot configure file: ") + std::strerror(errno));
    if (size) *size = uint64_t(st.st_size);
    return fd;
}

std::vector<uint8_t> read_regular_file(const std::string& path, uint64_t max_bytes,
                                       const char* what) {
    uint64_t size = 0;
    const int fd = open_regular_file(path, what, &size);
    auto fail_closed = [&](const std::string& message) {
        ::close(fd);
        fail(path, message);
    };
    if (size > max_bytes) {
        fail_closed("file is larger than " + std::to_string(max_bytes >> 20) +
                    " MiB, too large for " + what);
    }
    std::vector<uint8_t> data(size_t(size), 0);
    size_t total = 0;
    while (total < data.size()) {
        const ssize_t got = ::read(fd, data.data() + total, data.size() - total);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) fail_closed(std::string("read error: ") + std::strerror(errno));
        if (got == 0) fail_closed("file shrank while being read");
        total += size_t(got);
    }
    ::close(fd);
    return data;
}

std::string absolute_file_name(const std::string& name) {
    if (name.empty()) return name;
    std::error_code ec;
    const std::filesystem::path p = std::filesystem::absolute(name, ec);
    return ec ? name : p.lexically_normal().string();
}

bool same_file(const std::string& a, const std::string& b) {
    if (a == b) return true;
    struct stat sa {
    }, sb{};
    if (::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0)
        return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    std::error_code ea, eb;
    const std::filesystem::path pa = std::filesystem::weakly_canonical(a, ea);
    const std::filesystem::path pb = std::filesystem::weakly_canonical(b, eb);
    return !ea && !eb && pa == pb;
}

}  // namespace kdt
