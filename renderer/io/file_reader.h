// Sequential large-block reading of files, gzip-compressed files (detected by their magic
// bytes) and memory buffers, without mapping whole files. Depends on core and zlib.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace kdt {

/// Reads one file front to back in caller-sized blocks. gzip input (magic 1f 8b) is
/// inflated transparently. Not copyable; movable.
class FileReader {
public:
    /// Opens `path`; throws kdt::Error when it cannot be opened or is a directory.
    static FileReader open(const std::string& path);
    /// Reads from `size` bytes at `data`, which must outlive the reader. `name` is used in
    /// error messages. Memory input is never treated as gzip.
    static FileReader from_memory(const void* data, size_t size, const std::string& name);

    FileReader(FileReader&&) noexcept;
    FileReader& operator=(FileReader&&) noexcept;
    ~FileReader();

    /// Copies up to `n` bytes into `dst`; returns 0 only at the end of the data.
    /// Throws kdt::Error on read errors and corrupt gzip streams.
    size_t read(char* dst, size_t n);

    const std::string& path() const { return path_; }
    bool gzip() const { return gzip_; }
    /// Bytes on disk (compressed size for gzip).
    uint64_t file_bytes() const { return file_bytes_; }
    /// An upper bound of the bytes read() can ever return: the file size, or for gzip the
    /// compressed size times deflate's maximal ratio (1032:1). Used to reject element
    /// counts that the file cannot hold before allocating for them.
    uint64_t size_bound() const { return size_bound_; }
    /// The descriptor of a plain (not gzip) file, so callers may map it instead of calling
    /// read(); -1 for gzip and memory input. Mapping callers read from offset 0 themselves.
    int plain_fd() const { return gz_ ? -1 : fd_; }

private:
    FileReader() = default;
    void close();
    std::string path_;
    int fd_ = -1;
    void* gz_ = nullptr;  // gzFile
    const char* mem_ = nullptr;
    size_t mem_size_ = 0, mem_pos_ = 0;
    bool gzip_ = false;
    uint64_t file_bytes_ = 0, size_bound_ = 0;
};

/// True when the file starts with the gzip magic bytes 1f 8b.
bool is_gzip_file(const std::string& path);

}  // namespace kdt
