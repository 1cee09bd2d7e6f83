#include "renderer/core/temp_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "renderer/core/error.h"
#include "renderer/core/interrupt.h"

namespace kdt {

std::string write_target(const std::string& path) {
    namespace fs = std::filesystem;
    // The kernel's own limit on links followed in one path (Linux MAXSYMLINKS).
    constexpr int kMaxLinks = 40;
    fs::path p = path;
    for (int links = 0;; ++links) {
        struct stat st {};
        if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p.string();
        if (links == kMaxLinks) {
            throw Error(ErrorLocation{path}, "too many levels of symbolic links (a loop?)");
        }
        std::error_code ec;
        const fs::path link = fs::read_symlink(p, ec);
        if (ec) throw Error(ErrorLocation{path}, "cannot read the symlink " + p.string());
        p = link.is_absolute() ? link : p.parent_path() / link;
    }
}

TempFile::TempFile(const std::string& target) : target_(target), real_(write_target(target)) {
    interrupt::install_handlers();
    static std::atomic<uint64_t> counter{0};
    path_ = real_ + ".kdtrace-" + std::to_string(::getpid()) + "-" +
            std::to_string(counter.fetch_add(1)) + ".tmp";
    // Registered before it exists, so that no signal can come between creating and
    // registering it (removing a file that does not exist yet is harmless).
    slot_ = interrupt::register_temp(path_.c_str());
    fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd_ < 0) {
        const int err = errno;
        interrupt::unregister_temp(slot_);
        slot_ = -1;
        throw Error(ErrorLocation{target_},
                    "cannot create temporary file " + path_ + ": " + std::strerror(err));
    }
    // A handler that was already removing the registered files may have passed this slot.
    if (interrupt::dying()) {
        discard();
        interrupt::wait_if_dying();
    }
}

TempFile::~TempFile() { discard(); }

void TempFile::discard() {
    if (fd_ >= 0) {
        ::close(fd_);
        fd_ = -1;
        ::unlink(path_.c_str());
    }
    interrupt::unregister_temp(slot_);
    slot_ = -1;
}

void TempFile::fail(const std::string& message) {
    const int err = errno;
    discard();
    throw Error(ErrorLocation{target_}, message + ": " + std::strerror(err));
}

void TempFile::write(const void* data, size_t size) {
    if (fd_ < 0) throw Error(ErrorLocation{target_}, "write after commit");
    const auto* p = static_cast<const unsigned char*>(data);
    while (size > 0) {
        const ssize_t n = ::write(fd_, p, size);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) fail("write error in " + path_);
        p += n;
        size -= size_t(n);
    }
}

void TempFile::commit() {
    if (fd_ < 0) throw Error(ErrorLocation{target_}, "commit after commit");
    struct stat st {};
    if (::stat(real_.c_str(), &st) == 0 && S_ISREG(st.st_mode) &&
        ::fchmod(fd_, st.st_mode & 07777) != 0) {
        fail("cannot copy the file mode of the existing file");
    }
    if (::fsync(fd_) != 0) fail("cannot flush " + path_);
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) {
        const int err = errno;
        ::unlink(path_.c_str());
        errno = err;
        fail("cannot close " + path_);
    }
    // A signal handler on another thread may be removing this file on its way to ending the
    // process: then neither commit nor report an error (the signal is the outcome).
    if (!interrupt::commit_rename(slot_, path_.c_str(), real_.c_str())) {
        const int err = errno;
        ::unlink(path_.c_str());
        interrupt::unregister_temp(slot_);
        slot_ = -1;
        throw Error(ErrorLocation{target_},
                    std::string("cannot replace the file: ") + std::strerror(err));
    }
    interrupt::unregister_temp(slot_);
    slot_ = -1;
}

void write_file_atomically(const std::string& path, const void* data, size_t size) {
    TempFile tmp(path);
    tmp.write(data, size);
    tmp.commit();
}

}  // namespace kdt
