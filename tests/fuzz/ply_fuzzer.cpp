// libFuzzer target for the PLY reader: any input must load or throw kdt::Error, never
// crash, leak, hang or trip a sanitizer. Built by tests/fuzz/tests.cmake (KDT_FUZZ=ON,
// clang); run by scripts/run_fuzz.sh. Inputs reach the reader three ways: gzip inputs (the
// .ply.gz seeds, magic 1f 8b) as a file, so FileReader inflates them with its limits; one
// plain input in two (by size) gzip-compressed here and read as a file, so the parser runs
// on input of unknown size, whose arrays grow as data arrives; the rest both from memory and
// as a mapped file (the mapping threshold lowered from 1 MiB to 1 byte, the window from 4 MiB
// to 1 byte .. 4 KiB or left, by size), which must give the same mesh or the same error.
#include <sys/mman.h>
#include <unistd.h>
#include <zlib.h>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/io/ply_input.h"
#include "renderer/io/ply_reader.h"
#include "tests/fuzz/fuzz_mesh.h"

namespace {

// `data` as one gzip member (fast compression: the fuzzer's time goes to the reader).
std::vector<uint8_t> gzip(const uint8_t* data, size_t size) {
    z_stream zs{};
    if (deflateInit2(&zs, 1, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) __builtin_trap();
    std::vector<uint8_t> out(deflateBound(&zs, uLong(size)) + 64);
    zs.next_in = const_cast<Bytef*>(data);
    zs.avail_in = uInt(size);
    zs.next_out = out.data();
    zs.avail_out = uInt(out.size());
    if (deflate(&zs, Z_FINISH) != Z_STREAM_END) __builtin_trap();
    out.resize(zs.total_out);
    deflateEnd(&zs);
    return out;
}

// An anonymous memory file holding `bytes`, closed with it.
struct MemFile {
    int fd;
    MemFile(const char* name, const uint8_t* bytes, size_t size)
        : fd(::memfd_create(name, MFD_CLOEXEC)) {
        if (fd < 0) __builtin_trap();
        for (size_t done = 0; done < size;) {
            const ssize_t n = ::write(fd, bytes + done, size - done);
            if (n <= 0) __builtin_trap();
            done += size_t(n);
        }
    }
    MemFile(const MemFile&) = delete;
    MemFile& operator=(const MemFile&) = delete;
    ~MemFile() { ::close(fd); }
    std::string path() const { return "/proc/self/fd/" + std::to_string(fd); }
};

// Reads `bytes` through a file, as read_ply(path) does.
kdt::TriangleMesh read_as_file(const uint8_t* bytes, size_t size, const kdt::MeshLoadOptions& o,
                               kdt::MeshLoadInfo* info) {
    const MemFile file("fuzz.ply.gz", bytes, size);
    return kdt::read_ply(file.path(), o, info);
}

// `data` read from memory and as a mapped file seen through a window of `window` bytes: the
// two must agree, bit for bit or message for message (both name the file by its path).
void read_both_ways(const uint8_t* data, size_t size, const kdt::MeshLoadOptions& o,
                    size_t window) {
    const MemFile file("fuzz.ply", data, size);
    const std::string path = file.path();
    using kdt::fuzz::result_of;
    const auto memory =
        result_of([&](kdt::MeshLoadInfo*) { return kdt::read_ply_memory(data, size, path, o); });
    const kdt::ply::MapParams old = kdt::ply::set_map_params({1, window});
    const auto mapped = result_of([&](kdt::MeshLoadInfo*) { return kdt::read_ply(path, o); });
    kdt::ply::set_map_params(old);
    if (memory.error != mapped.error) __builtin_trap();
    if (!kdt::fuzz::same_mesh(memory.mesh, mapped.mesh)) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    kdt::MeshLoadOptions options;
    // Exercise both the default (non-finite is an error) and the --drop-invalid path.
    options.drop_invalid = size % 2 == 1;
    try {
        kdt::MeshLoadInfo info;
        kdt::TriangleMesh mesh;
        if (size >= 2 && data[0] == 0x1f && data[1] == 0x8b) {
            mesh = read_as_file(data, size, options, &info);
        } else if (size % 4 >= 2) {
            const std::vector<uint8_t> gz = gzip(data, size);
            mesh = read_as_file(gz.data(), gz.size(), options, &info);
        } else {
            if (size > 0) {
                static constexpr size_t kWindows[] = {1, 7, 64, 1000, 4096, kdt::ply::kBlockBytes};
                read_both_ways(data, size, options, kWindows[size / 4 % std::size(kWindows)]);
            }
            mesh = kdt::read_ply_memory(data, size, "fuzz.ply", options, &info);
        }
        // Every index must be in range: read them all so ASan sees any stray one.
        for (const kdt::Vec3u& t : mesh.triangles) {
            if (t.x >= mesh.positions.size() || t.y >= mesh.positions.size() ||
                t.z >= mesh.positions.size())
                __builtin_trap();
        }
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) __builtin_trap();
        if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size()) __builtin_trap();
        // Memory follows the data: the arrays never hold more than twice what was read
        // (uncompressed), plus the first records a gzip load starts with.
        if (info.array_bytes > 2 * info.input_bytes_read * 12 + (uint64_t(4) << 20))
            __builtin_trap();
    } catch (const kdt::Error& e) {
        // Messages are safe to print.
        for (const char* p = e.what(); *p; ++p)
            if (static_cast<unsigned char>(*p) < 0x20 || *p == 0x7f) __builtin_trap();
    }
    return 0;
}
