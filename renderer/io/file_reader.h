// Sequential large-block reading of files, gzip-compressed files (detected by their magic
// bytes) and memory buffers, without mapping whole files. Depends on core and zlib.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace kdt {

/// gzip input may inflate to at most kMaxInflationRatio times the compressed bytes consumed
/// so far once it has inflated kInflationFreeBytes: mesh data compresses 2-10:1, while runs of
/// one byte (the stuff of gzip bombs) reach deflate's 1032:1. Past that, read() throws an
/// error giving the ratio, so a small file never makes the reader inflate gigabytes.
inline constexpr uint64_t kMaxInflationRatio = 200;
inline constexpr uint64_t kInflationFreeBytes = uint64_t(64) << 20;

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
    /// Throws kdt::Error on read errors, corrupt gzip streams and gzip data inflating beyond
    /// kMaxInflationRatio.
    size_t read(char* dst, size_t n);

    const std::string& path() const { return path_; }
    bool gzip() const { return gzip_; }
    /// Bytes on disk (compressed size for gzip).
    uint64_t file_bytes() const { return file_bytes_; }
    /// An upper bound of the bytes read() can ever return: the file size, or for gzip what
    /// the inflation limit lets through (kInflationFreeBytes, or the compressed size times
    /// kMaxInflationRatio, plus one read step). Used to reject element counts that the file
    /// cannot hold before allocating for them.
    uint64_t size_bound() const { return size_bound_; }
    /// True when size_bound() is the exact size of the data (plain files and memory); false
    /// for gzip, whose size is known only once it is inflated.
    bool size_known() const { return !gzip_; }
    /// Bytes read() has returned so far (inflated bytes for gzip).
    uint64_t bytes_read() const { return bytes_read_; }
    /// For gzip: bytes read() returned per compressed byte consumed so far (the compressed
    /// count includes zlib's read-ahead, so this errs low); 1 for other input.
    double inflation_ratio() const;
    /// True once read() has refused gzip data for inflating beyond kMaxInflationRatio.
    bool over_inflation_limit() const { return over_limit_; }
    /// The descriptor of a plain (not gzip) file, so callers may map it instead of calling
    /// read(); -1 for gzip and memory input. Mapping callers read from offset 0 themselves.
    int plain_fd() const { return gz_ ? -1 : fd_; }

private:
    FileReader() = default;
    void close();
    size_t read_gzip(char* dst, size_t n);
    uint64_t compressed_read() const;
    double inflation_ratio_of(uint64_t inflated) const;
    std::string path_;
    int fd_ = -1;
    void* gz_ = nullptr;  // gzFile
    const char* mem_ = nullptr;
    size_t mem_size_ = 0, mem_pos_ = 0;
    bool gzip_ = false, over_limit_ = false;
    uint64_t file_bytes_ = 0, size_bound_ = 0, bytes_read_ = 0;
};

/// True when the file starts with the gzip magic bytes 1f 8b.
bool is_gzip_file(const std::string& path);

}  // namespace kdt
