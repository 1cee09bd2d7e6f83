#include "renderer/io/ply_writer.h"

#include <zlib.h>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <vector>

#include "renderer/core/error.h"

namespace kdt {
namespace {

// Buffered output to a plain or gzip file; flushes in 1 MiB blocks.
class Output {
public:
    Output(const std::string& path) : path_(path) {
        gzip_ = path.size() >= 3 && path.compare(path.size() - 3, 3, ".gz") == 0;
        if (gzip_) {
            gz_ = ::gzopen(path.c_str(), "wb6");
            if (!gz_) fail("cannot open for writing");
        } else {
            file_ = std::fopen(path.c_str(), "wb");
            if (!file_) fail(std::string("cannot open for writing: ") + std::strerror(errno));
        }
        buf_.reserve(kBlock + 256);
    }
    ~Output() {
        if (gz_) ::gzclose(gz_);
        if (file_) std::fclose(file_);
    }

    void put(const void* data, size_t n) {
        const char* p = static_cast<const char*>(data);
        buf_.insert(buf_.end(), p, p + n);
        if (buf_.size() >= kBlock) flush();
    }
    void put(const std::string& s) { put(s.data(), s.size()); }
    void put_char(char c) {
        buf_.push_back(c);
        if (buf_.size() >= kBlock) flush();
    }
    // Room for one short token written in place.
    char* reserve_tail(size_t n) {
        size_t old = buf_.size();
        buf_.resize(old + n);
        return buf_.data() + old;
    }
    void commit_tail(char* end) {
        buf_.resize(size_t(end - buf_.data()));
        if (buf_.size() >= kBlock) flush();
    }

    void close() {
        flush();
        bool ok = true;
        if (gz_) {
            ok = ::gzclose(gz_) == Z_OK;
            gz_ = nullptr;
        }
        if (file_) {
            ok = std::fclose(file_) == 0;
            file_ = nullptr;
        }
        if (!ok) fail("error closing the file");
    }

private:
    static constexpr size_t kBlock = size_t(1) << 20;
    void flush() {
        if (buf_.empty()) return;
        bool ok = gz_ ? ::gzwrite(gz_, buf_.data(), unsigned(buf_.size())) == int(buf_.size())
                      : std::fwrite(buf_.data(), 1, buf_.size(), file_) == buf_.size();
        if (!ok) fail("write error (disk full?)");
        buf_.clear();
    }
    [[noreturn]] void fail(const std::string& message) {
        ErrorLocation w;
        w.path = path_;
        throw Error(w, message);
    }
    std::string path_;
    bool gzip_ = false;
    gzFile gz_ = nullptr;
    FILE* file_ = nullptr;
    std::vector<char> buf_;
};

template <typename T>
void put_binary(Output& out, T v, bool swap) {
    if (swap) {
        if constexpr (sizeof(T) == 4) {
            v = std::bit_cast<T>(__builtin_bswap32(std::bit_cast<uint32_t>(v)));
        }
    }
    out.put(&v, sizeof(T));
}

void put_ascii(Output& out, float v) {
    char* p = out.reserve_tail(32);
    auto r = std::to_chars(p, p + 32, v);
    out.commit_tail(r.ptr);
}

void put_ascii(Output& out, uint32_t v) {
    char* p = out.reserve_tail(16);
    auto r = std::to_chars(p, p + 16, v);
    out.commit_tail(r.ptr);
}

}  // namespace

void write_ply(const std::string& path, const TriangleMesh& mesh, PlyEncoding encoding) {
    Output out(path);
    const bool has_n = !mesh.normals.empty() && mesh.normals.size() == mesh.positions.size();
    const bool has_c = !mesh.colors.empty() && mesh.colors.size() == mesh.positions.size();
    std::string header = "ply\nformat " + std::string(kPlyEncodingNames[size_t(encoding)]) +
                         " 1.0\ncomment written by kdtrace\nelement vertex " +
                         std::to_string(mesh.positions.size()) +
                         "\nproperty float x\nproperty float y\nproperty float z\n";
    if (has_n) header += "property float nx\nproperty float ny\nproperty float nz\n";
    if (has_c) header += "property float red\nproperty float green\nproperty float blue\n";
    header += "element face " + std::to_string(mesh.triangles.size()) +
              "\nproperty list uchar uint vertex_indices\nend_header\n";
    out.put(header);

    if (encoding == PlyEncoding::ascii) {
        for (size_t i = 0; i < mesh.positions.size(); ++i) {
            auto put3 = [&](const Vec3f& v) {
                for (int k = 0; k < 3; ++k) {
                    if (k) out.put_char(' ');
                    put_ascii(out, v[k]);
                }
            };
            put3(mesh.positions[i]);
            if (has_n) {
                out.put_char(' ');
                put3(mesh.normals[i]);
            }
            if (has_c) {
                out.put_char(' ');
                put3(mesh.colors[i]);
            }
            out.put_char('\n');
        }
        for (const Vec3u& t : mesh.triangles) {
            out.put("3", 1);
            for (int k = 0; k < 3; ++k) {
                out.put_char(' ');
                put_ascii(out, t[k]);
            }
            out.put_char('\n');
        }
    } else {
        const bool swap = encoding == PlyEncoding::binary_big_endian;
        for (size_t i = 0; i < mesh.positions.size(); ++i) {
            for (int k = 0; k < 3; ++k) put_binary(out, mesh.positions[i][k], swap);
            if (has_n)
                for (int k = 0; k < 3; ++k) put_binary(out, mesh.normals[i][k], swap);
            if (has_c)
                for (int k = 0; k < 3; ++k) put_binary(out, mesh.colors[i][k], swap);
        }
        for (const Vec3u& t : mesh.triangles) {
            out.put_char(3);
            for (int k = 0; k < 3; ++k) put_binary(out, uint32_t(t[k]), swap);
        }
    }
    out.close();
}

}  // namespace kdt
