#include "renderer/io/file_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string_view>

#include "renderer/core/error.h"
#include "renderer/core/open_file.h"

namespace kdt {
namespace {

// gzread is called for at most this many bytes at a time, so the inflation limit is
// checked at least this often.
constexpr size_t kGzipStep = size_t(1) << 20;

std::string mib(uint64_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.1f MiB", double(bytes) / double(1 << 20));
    return buf;
}

[[noreturn]] void fail(const std::string& path, const std::string& message) {
    ErrorLocation where;
    where.path = path;
    throw Error(where, message);
}

// zlib's message without the name it gives a stream opened by descriptor ("<fd:5>: "): the
// error already names the file.
std::string gzip_message(const char* msg) {
    std::string_view m = msg ? msg : "unknown error";
    if (m.substr(0, 4) == "<fd:") {
        const size_t end = m.find(">: ");
        if (end != std::string_view::npos) m.remove_prefix(end + 3);
    }
    return "corrupt gzip data: " + std::string(m);
}

}  // namespace

FileReader FileReader::open(const std::string& path) {
    FileReader r;
    r.path_ = path;
    r.fd_ = open_regular_file(path, "a file", &r.file_bytes_);
    r.size_bound_ = r.file_bytes_;
    ::posix_fadvise(r.fd_, 0, 0, POSIX_FADV_SEQUENTIAL);
    unsigned char magic[2] = {0, 0};
    ssize_t got = ::pread(r.fd_, magic, 2, 0);
    if (got == 2 && magic[0] == 0x1f && magic[1] == 0x8b) {
        int fd2 = ::dup(r.fd_);
        if (fd2 < 0) fail(path, std::string("cannot dup file: ") + std::strerror(errno));
        gzFile gz = ::gzdopen(fd2, "rb");
        if (!gz) {
            ::close(fd2);
            fail(path, "cannot open gzip stream");
        }
        // zlib's input buffer (its output buffer is twice as big): 1 MiB for big files,
        // less for small ones, which would not fill it.
        ::gzbuffer(gz, unsigned(std::clamp<uint64_t>(r.file_bytes_, 64u << 10, 1u << 20)));
        r.gz_ = gz;
        r.gzip_ = true;
        r.size_bound_ =
            std::max(kInflationFreeBytes, r.file_bytes_ * kMaxInflationRatio) + kGzipStep;
    }
    return r;
}

FileReader FileReader::from_memory(const void* data, size_t size, const std::string& name) {
    FileReader r;
    r.path_ = name;
    r.mem_ = static_cast<const char*>(data);
    r.mem_size_ = size;
    r.file_bytes_ = size;
    r.size_bound_ = size;
    return r;
}

FileReader::FileReader(FileReader&& o) noexcept { *this = std::move(o); }

FileReader& FileReader::operator=(FileReader&& o) noexcept {
    if (this != &o) {
        close();
        path_ = std::move(o.path_);
        fd_ = o.fd_;
        gz_ = o.gz_;
        mem_ = o.mem_;
        mem_size_ = o.mem_size_;
        mem_pos_ = o.mem_pos_;
        gzip_ = o.gzip_;
        over_limit_ = o.over_limit_;
        file_bytes_ = o.file_bytes_;
        size_bound_ = o.size_bound_;
        bytes_read_ = o.bytes_read_;
        o.fd_ = -1;
        o.gz_ = nullptr;
        o.mem_ = nullptr;
    }
    return *this;
}

FileReader::~FileReader() { close(); }

void FileReader::close() {
    if (gz_) ::gzclose(static_cast<gzFile>(gz_));
    if (fd_ >= 0) ::close(fd_);
    gz_ = nullptr;
    fd_ = -1;
}

size_t FileReader::read(char* dst, size_t n) {
    size_t total = 0;
    if (mem_) {
        total = std::min(n, mem_size_ - mem_pos_);
        std::memcpy(dst, mem_ + mem_pos_, total);
        mem_pos_ += total;
    } else if (gz_) {
        total = read_gzip(dst, n);
    } else if (fd_ >= 0) {
        while (total < n) {
            ssize_t got = ::read(fd_, dst + total, n - total);
            if (got < 0) {
                if (errno == EINTR) continue;
                fail(path_, std::string("read error: ") + std::strerror(errno));
            }
            if (got == 0) break;
            total += static_cast<size_t>(got);
        }
    }
    bytes_read_ += total;
    return total;
}

size_t FileReader::read_gzip(char* dst, size_t n) {
    auto gz = static_cast<gzFile>(gz_);
    size_t total = 0;
    while (total < n) {
        unsigned chunk = static_cast<unsigned>(std::min(n - total, kGzipStep));
        int got = ::gzread(gz, dst + total, chunk);
        if (got < 0) {
            int code = 0;
            const char* msg = ::gzerror(gz, &code);
            fail(path_, gzip_message(msg));
        }
        if (got == 0) {
            // gzread reports a stream cut short only through gzerror.
            int code = 0;
            const char* msg = ::gzerror(gz, &code);
            if (code != Z_OK && code != Z_STREAM_END) fail(path_, gzip_message(msg));
            break;
        }
        total += static_cast<size_t>(got);
        const uint64_t inflated = bytes_read_ + total;
        if (inflated > kInflationFreeBytes && inflation_ratio_of(inflated) > kMaxInflationRatio) {
            over_limit_ = true;
            bytes_read_ = inflated;
            char ratio[32];
            std::snprintf(ratio, sizeof(ratio), "%.0f:1", inflation_ratio_of(inflated));
            fail(path_, "the gzip data inflate " + std::string(ratio) + " (" + mib(inflated) +
                            " from " + mib(compressed_read()) + "), beyond the " +
                            std::to_string(kMaxInflationRatio) +
                            ":1 that mesh data ever needs; stopped reading (a gzip bomb?)");
        }
    }
    return total;
}

uint64_t FileReader::compressed_read() const {
    if (!gz_) return bytes_read_;
    const z_off_t off = ::gzoffset(static_cast<gzFile>(gz_));
    return off > 0 ? uint64_t(off) : 0;
}

double FileReader::inflation_ratio_of(uint64_t inflated) const {
    return double(inflated) / double(std::max<uint64_t>(compressed_read(), 1));
}

double FileReader::inflation_ratio() const { return gz_ ? inflation_ratio_of(bytes_read_) : 1.0; }

bool is_gzip_file(const std::string& path) {
    int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return false;
    unsigned char magic[2] = {0, 0};
    ssize_t got = ::read(fd, magic, 2);
    ::close(fd);
    return got == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
}

}  // namespace kdt
