#include "renderer/accel/kdtree_cache.h"

#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <type_traits>
#include <vector>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "renderer/core/error.h"
#include "renderer/core/map_guard.h"
#include "renderer/core/open_file.h"
#include "renderer/core/temp_file.h"
#include "renderer/core/timer.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;

// "\x89KDT\r\n\x1a\n": non-ASCII first byte and CR/LF/^Z catch text-mode and 7-bit mangling
// (the PNG signature's idea).
constexpr unsigned char kMagic[8] = {0x89, 'K', 'D', 'T', '\r', '\n', 0x1a, '\n'};
constexpr uint32_t kByteOrderMark = 0x01020304u;
constexpr int kMaxDepthHistogram = 72;
// Traversal keeps a fixed stack; a file may not describe a deeper tree than any builder makes.
constexpr uint32_t kMaxTreeDepth = 64;

enum : uint8_t { kFlagMedian = 1, kFlagCenter = 2, kFlagCutoff = 4, kFlagAllAxes = 8 };

// Fixed-size header, native (little-endian) layout without implicit padding; the payload
// (nodes, then indices) follows at header_bytes.
struct FileHeader {
    unsigned char magic[8];
    uint32_t byte_order;
    uint32_t version;
    uint32_t header_bytes;
    uint32_t node_bytes;
    uint8_t builder;
    uint8_t split_flags;
    uint8_t reserved0[2];
    float q;
    int32_t n0;
    int32_t max_depth;
    float traversal_cost;
    float intersect_cost;
    float empty_bonus;
    uint32_t reserved1;
    uint64_t params_hash;
    uint64_t mesh_hash;
    uint64_t vertex_count;
    uint64_t triangle_count;
    uint64_t node_count;
    uint64_t index_count;
    float bounds[6];
    // Statistics as the build reported them (split counts and timings cannot be recomputed).
    uint64_t leaves, empty_leaves, references;
    uint32_t max_leaf_size, max_depth_reached;
    uint64_t median_splits, center_splits, cutoff_splits, sah_splits;
    uint64_t stats_bytes, peak_build_bytes;
    double build_seconds, mean_leaf_size, refs_per_triangle, bytes_per_triangle;
    uint32_t depth_histogram_count;
    uint32_t reserved2;
    uint64_t depth_histogram[kMaxDepthHistogram];
    uint64_t payload_checksum;
    uint64_t header_checksum;  ///< over every byte before this field
};
static_assert(std::is_trivially_copyable_v<FileHeader>);
static_assert(sizeof(FileHeader) % 8 == 0, "payload starts 8-byte aligned");
static_assert(sizeof(FileHeader) == 840, "no implicit padding in the header");

inline uint64_t rotl64(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }

// A 64-bit checksum over bytes: four independent multiply-rotate lanes (so it runs at memory
// speed on tens of megabytes) folded together with a final avalanche. Detects flipped bits
// and truncation; not cryptographic.
uint64_t checksum64(const void* data, size_t bytes) {
    constexpr uint64_t kP1 = 0x9E3779B185EBCA87ull, kP2 = 0xC2B2AE3D27D4EB4Full;
    const auto* p = static_cast<const unsigned char*>(data);
    uint64_t lane[4] = {kP1, kP2, ~kP1, ~kP2};
    size_t i = 0;
    for (; i + 32 <= bytes; i += 32) {
        for (int k = 0; k < 4; ++k) {
            uint64_t w;
            std::memcpy(&w, p + i + 8 * k, 8);
            lane[k] = rotl64(lane[k] + w * kP2, 31) * kP1;
        }
    }
    uint64_t h = uint64_t(bytes) * kP1;
    for (int k = 0; k < 4; ++k) h = (h ^ rotl64(lane[k], 7 + 12 * k)) * kP2;
    for (; i < bytes; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    h ^= h >> 33;
    h *= kP2;
    h ^= h >> 29;
    h *= kP1;
    h ^= h >> 32;
    return h;
}

uint8_t split_flags(const KdTreeParams& p) {
    return uint8_t((p.use_median_split ? kFlagMedian : 0) | (p.use_center_split ? kFlagCenter : 0) |
                   (p.use_cutoff_split ? kFlagCutoff : 0) | (p.thesis_all_axes ? kFlagAllAxes : 0));
}

uint32_t float_bits(float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
}

const char* builder_name(uint8_t b) {
    return b < kKdBuilderNames.size() ? kKdBuilderNames[b] : "unknown";
}

std::string describe_params(uint8_t builder, float q, int n0, int depth, uint8_t flags) {
    char buf[160];
    std::snprintf(buf, sizeof(buf),
                  "builder=%s q=%.4g n0=%d depth=%d median=%d center=%d cutoff=%d",
                  builder_name(builder), double(q), n0, depth, (flags & kFlagMedian) ? 1 : 0,
                  (flags & kFlagCenter) ? 1 : 0, (flags & kFlagCutoff) ? 1 : 0);
    return buf;
}

std::string hex64(uint64_t v) {
    char buf[20];
    std::snprintf(buf, sizeof(buf), "%016" PRIx64, v);
    return buf;
}

// Bounds of the triangles a ray can hit (both builders' boxes hold at least these).
Bounds3f hittable_triangle_bounds(const TriangleMesh& mesh) {
    Bounds3f b;
    for (size_t i = 0; i < mesh.triangles.size(); ++i)
        if (mesh.triangle_hittable(i)) b.extend(mesh.triangle_bounds(i));
    return b;
}

bool contains(const Bounds3f& outer, const Bounds3f& inner) {
    return outer.lower.x <= inner.lower.x && outer.lower.y <= inner.lower.y &&
           outer.lower.z <= inner.lower.z && outer.upper.x >= inner.upper.x &&
           outer.upper.y >= inner.upper.y && outer.upper.z >= inner.upper.z;
}

// A read-only mapping of a whole file, unmapped on destruction. Its reads are guarded: a
// file truncated meanwhile reads as zeros, and check_unchanged() throws an Error for it.
class MappedFile {
public:
    explicit MappedFile(const std::string& path) : path_(path) {
        uint64_t size = 0;
        fd_ = open_regular_file(path, "a cache file", &size);
        size_ = size_t(size);
        if (::fstat(fd_, &stat_) != 0) fail(std::string("cannot stat: ") + std::strerror(errno));
        if (size_ == 0) return;
        void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
        if (p == MAP_FAILED) fail(std::string("cannot map: ") + std::strerror(errno));
        data_ = static_cast<const unsigned char*>(p);
        try {
            guard_ = std::make_unique<MapGuard>(data_, size_, fd_, path_);
        } catch (...) {
            ::munmap(p, size_);
            data_ = nullptr;
            ::close(fd_);
            throw;
        }
    }
    ~MappedFile() {
        guard_.reset();
        if (data_) ::munmap(const_cast<unsigned char*>(data_), size_);
        if (fd_ >= 0) ::close(fd_);
    }
    MappedFile(const MappedFile&) = delete;
    MappedFile& operator=(const MappedFile&) = delete;

    const unsigned char* data() const { return data_; }
    size_t size() const { return size_; }
    const struct stat& stat() const { return stat_; }
    /// Throws an Error naming the file when it changed or shrank while it was read.
    void check_unchanged() const {
        if (guard_) guard_->check();
    }

private:
    [[noreturn]] void fail(const std::string& message) {
        if (fd_ >= 0) ::close(fd_);
        fd_ = -1;
        throw Error(ErrorLocation{path_}, message);
    }

    std::string path_;
    int fd_ = -1;
    const unsigned char* data_ = nullptr;
    size_t size_ = 0;
    struct stat stat_ {};
    std::unique_ptr<MapGuard> guard_;
};

// Verified-stamps. check_kdtree_complete() costs a sizeable fraction of a build, so a file
// is verified once and a stamp records it in the user's private cache directory (mode
// 0700): the file's device, inode, size and status-change time (ctime, which no write,
// rename or utime() call can preserve, nor an unprivileged user set), its header checksum
// (which covers the payload's) and the mesh hash. Any change to the file, or another file
// in its place, no longer matches its stamp and is verified again.
std::string stamp_key(const struct stat& st, uint64_t header_checksum, uint64_t mesh_hash) {
    char buf[256];
    std::snprintf(buf, sizeof(buf),
                  "kdtrace verified v%u %" PRIu64 " %" PRIu64 " %" PRIu64 " %" PRId64
                  ".%09ld %016" PRIx64 " %016" PRIx64 "\n",
                  kKdCacheVersion, uint64_t(st.st_dev), uint64_t(st.st_ino), uint64_t(st.st_size),
                  int64_t(st.st_ctim.tv_sec), long(st.st_ctim.tv_nsec), header_checksum, mesh_hash);
    return buf;
}

// Where the stamp of the file with this identity lives; empty without a cache directory.
fs::path stamp_path(const struct stat& st) {
    const std::string dir = default_kdtree_cache_dir();
    if (dir.empty()) return {};
    const uint64_t id[2] = {uint64_t(st.st_dev), uint64_t(st.st_ino)};
    return fs::path(dir) / "verified" / (hex64(checksum64(id, sizeof(id))) + ".stamp");
}

bool stamped(const struct stat& st, const std::string& key) {
    const fs::path p = stamp_path(st);
    if (p.empty()) return false;
    std::FILE* f = std::fopen(p.c_str(), "rb");
    if (!f) return false;
    char buf[256] = {};
    const size_t n = std::fread(buf, 1, sizeof(buf) - 1, f);
    std::fclose(f);
    return std::string(buf, n) == key;
}

void create_private_directories(const fs::path& dir);

// Best effort: a stamp that cannot be written only means verifying again next time.
void write_stamp(const struct stat& st, const std::string& key) {
    const fs::path p = stamp_path(st);
    if (p.empty()) return;
    try {
        create_private_directories(p.parent_path());
        write_file_atomically(p.string(), key.data(), key.size());
    } catch (const Error&) {
    }
}

// mkdir -p with mode 0700 for every directory it creates (existing ones are left alone):
// cache and stamp directories are the user's own.
void create_private_directories(const fs::path& dir) {
    fs::path partial;
    for (const fs::path& part : dir) {
        partial /= part;
        if (::mkdir(partial.c_str(), 0700) != 0 && errno != EEXIST) return;
    }
}

[[noreturn]] void fail_at(const std::string& path, const char* element, int64_t index,
                          int64_t offset, const std::string& message) {
    ErrorLocation where{path, element, index, -1, offset};
    throw Error(where, message);
}

void check_structure(const std::string& path, const KdNode* nodes, size_t node_count,
                     const uint32_t* indices, size_t index_count, size_t triangle_count,
                     size_t header_bytes) {
    const size_t nodes_offset = header_bytes;
    const size_t indices_offset = header_bytes + node_count * sizeof(KdNode);
    // A node's depth is the longest path reaching it; children always follow their parent,
    // so one forward pass sees every parent before its children.
    std::vector<uint8_t> depth(node_count, 0);
    std::vector<uint8_t> referenced(node_count, 0);
    for (size_t i = 0; i < node_count; ++i) {
        const KdNode& n = nodes[i];
        const int64_t off = int64_t(nodes_offset + i * sizeof(KdNode));
        if (n.is_leaf()) {
            const uint64_t first = n.first, count = n.count();
            if (first > index_count || count > index_count - first) {
                fail_at(path, "node", int64_t(i), off,
                        "leaf range [" + std::to_string(first) + ", " +
                            std::to_string(first + count) + ") outside the " +
                            std::to_string(index_count) + " indices");
            }
            continue;
        }
        const uint64_t c = n.child();
        if (c <= i || c + 1 >= node_count) {
            fail_at(path, "node", int64_t(i), off,
                    "child index " + std::to_string(c) + " out of range (" +
                        std::to_string(node_count) + " nodes, children must follow their parent)");
        }
        if (!std::isfinite(n.split))
            fail_at(path, "node", int64_t(i), off, "split plane not finite");
        for (uint64_t k = c; k <= c + 1; ++k) {
            if (referenced[k]) {
                fail_at(path, "node", int64_t(i), off,
                        "node " + std::to_string(k) + " is the child of two parents");
            }
            referenced[k] = 1;
            depth[k] = uint8_t(std::max<uint32_t>(depth[k], depth[i] + 1u));
        }
        if (depth[i] + 1u > kMaxTreeDepth) {
            fail_at(path, "node", int64_t(i), off,
                    "tree deeper than " + std::to_string(kMaxTreeDepth) + " levels");
        }
    }
    for (size_t i = 1; i < node_count; ++i) {
        if (!referenced[i]) {
            fail_at(path, "node", int64_t(i), int64_t(nodes_offset + i * sizeof(KdNode)),
                    "node is not reachable from the root");
        }
    }
    for (size_t i = 0; i < index_count; ++i) {
        if (indices[i] >= triangle_count) {
            fail_at(path, "index", int64_t(i), int64_t(indices_offset + i * 4),
                    "triangle index " + std::to_string(indices[i]) + " out of range (" +
                        std::to_string(triangle_count) + " triangles)");
        }
    }
}

bool directory_writable(const fs::path& dir) {
    std::error_code ec;
    return fs::is_directory(dir, ec) && ::access(dir.c_str(), W_OK) == 0;
}

void default_log(const std::string& line) { std::fprintf(stderr, "kdtrace: %s\n", line.c_str()); }

}  // namespace

uint64_t kdtree_params_hash(const KdTreeParams& p) {
    uint32_t words[10] = {uint32_t(p.builder),
                          float_bits(p.q),
                          uint32_t(p.n0),
                          uint32_t(p.max_depth),
                          split_flags(p),
                          float_bits(p.traversal_cost),
                          float_bits(p.intersect_cost),
                          float_bits(p.empty_bonus),
                          kKdCacheVersion,
                          0};
    return checksum64(words, sizeof(words));
}

std::string kdtree_cache_file_name(const std::string& model_path, const KdTreeParams& params) {
    const uint8_t b = uint8_t(params.builder);
    return fs::path(model_path).filename().string() + "." + builder_name(b) + "-" +
           hex64(kdtree_params_hash(params)) + ".kdt";
}

namespace {

// save_kdtree(), and when `stamp` (a tree this process built), a verified-stamp for the file.
void save_kdtree_file(const std::string& path, const KdTree& tree, bool stamp) {
    const TriangleMesh& mesh = tree.mesh();
    const KdTreeParams& p = tree.params();
    const KdTreeStats& s = tree.stats();
    const auto& nodes = tree.nodes();
    const auto& indices = tree.indices();

    FileHeader h;
    std::memset(&h, 0, sizeof(h));
    std::memcpy(h.magic, kMagic, 8);
    h.byte_order = kByteOrderMark;
    h.version = kKdCacheVersion;
    h.header_bytes = sizeof(FileHeader);
    h.node_bytes = sizeof(KdNode);
    h.builder = uint8_t(p.builder);
    h.split_flags = split_flags(p);
    h.q = p.q;
    h.n0 = p.n0;
    h.max_depth = p.max_depth;
    h.traversal_cost = p.traversal_cost;
    h.intersect_cost = p.intersect_cost;
    h.empty_bonus = p.empty_bonus;
    h.params_hash = kdtree_params_hash(p);
    h.mesh_hash = mesh.content_hash();
    h.vertex_count = mesh.vertex_count();
    h.triangle_count = mesh.triangle_count();
    h.node_count = nodes.size();
    h.index_count = indices.size();
    const Bounds3f& b = tree.bounds();
    const float bounds[6] = {b.lower.x, b.lower.y, b.lower.z, b.upper.x, b.upper.y, b.upper.z};
    std::memcpy(h.bounds, bounds, sizeof(bounds));
    h.leaves = s.leaves;
    h.empty_leaves = s.empty_leaves;
    h.references = s.references;
    h.max_leaf_size = s.max_leaf_size;
    h.max_depth_reached = s.max_depth_reached;
    h.median_splits = s.median_splits;
    h.center_splits = s.center_splits;
    h.cutoff_splits = s.cutoff_splits;
    h.sah_splits = s.sah_splits;
    h.stats_bytes = s.bytes;
    h.peak_build_bytes = s.peak_build_bytes;
    h.build_seconds = s.build_seconds;
    h.mean_leaf_size = s.mean_leaf_size;
    h.refs_per_triangle = s.refs_per_triangle;
    h.bytes_per_triangle = s.bytes_per_triangle;
    h.depth_histogram_count =
        uint32_t(std::min<size_t>(s.depth_histogram.size(), kMaxDepthHistogram));
    for (uint32_t i = 0; i < h.depth_histogram_count; ++i)
        h.depth_histogram[i] = s.depth_histogram[i];
    // The payload checksum covers nodes then indices as laid out in the file.
    std::vector<unsigned char> payload(nodes.size() * sizeof(KdNode) + indices.size() * 4);
    if (!nodes.empty()) std::memcpy(payload.data(), nodes.data(), nodes.size() * sizeof(KdNode));
    if (!indices.empty()) {
        std::memcpy(payload.data() + nodes.size() * sizeof(KdNode), indices.data(),
                    indices.size() * 4);
    }
    h.payload_checksum = checksum64(payload.data(), payload.size());
    h.header_checksum = checksum64(&h, offsetof(FileHeader, header_checksum));

    // The temporary file is removed on every exit path, signals included.
    try {
        TempFile tmp(path);
        tmp.write(&h, sizeof(h));
        tmp.write(payload.data(), payload.size());
        tmp.commit();
    } catch (const Error& e) {
        throw Error(ErrorLocation{path}, "cannot write tree cache: " + e.message());
    }
    // A tree the builder just made needs no verification when it is loaded back (a tree
    // given to save_kdtree() may come from anywhere: its file is verified on first use).
    struct stat st {};
    if (stamp && ::stat(path.c_str(), &st) == 0)
        write_stamp(st, stamp_key(st, h.header_checksum, h.mesh_hash));
}

}  // namespace

void save_kdtree(const std::string& path, const KdTree& tree) {
    save_kdtree_file(path, tree, false);
}

namespace {
// load_kdtree_memory() with check_kdtree_complete() optional (a stamped file).
std::shared_ptr<const KdTree> load_kdtree_image(const unsigned char* data, size_t size,
                                                const std::string& path,
                                                std::shared_ptr<const TriangleMesh> mesh,
                                                const KdTreeParams& params, bool verify,
                                                double* verify_seconds);

// The header of a cache file image after the checks that need nothing but the file: magic,
// size, byte order, version, record sizes and the header checksum.
FileHeader checked_header(const unsigned char* data, size_t size, const std::string& path) {
    if (size == 0) fail_at(path, "", -1, -1, "empty file");
    if (size < sizeof(kMagic) || std::memcmp(data, kMagic, sizeof(kMagic)) != 0) {
        fail_at(path, "header", -1, 0, "not a kdtrace tree cache (wrong magic)");
    }
    if (size < sizeof(FileHeader)) {
        fail_at(path, "header", -1, int64_t(size),
                "truncated: " + std::to_string(size) + " bytes, the header alone needs " +
                    std::to_string(sizeof(FileHeader)));
    }
    FileHeader h;
    std::memcpy(&h, data, sizeof(h));
    if (h.byte_order != kByteOrderMark) {
        fail_at(path, "header", -1, offsetof(FileHeader, byte_order),
                "written with a different byte order");
    }
    if (h.version != kKdCacheVersion) {
        fail_at(path, "header", -1, offsetof(FileHeader, version),
                "cache format version " + std::to_string(h.version) + ", this kdtrace reads " +
                    std::to_string(kKdCacheVersion));
    }
    if (h.header_bytes != sizeof(FileHeader) || h.node_bytes != sizeof(KdNode)) {
        fail_at(path, "header", -1, offsetof(FileHeader, header_bytes),
                "unexpected header or node size");
    }
    if (checksum64(&h, offsetof(FileHeader, header_checksum)) != h.header_checksum) {
        fail_at(path, "header", -1, offsetof(FileHeader, header_checksum),
                "header checksum mismatch (corrupt header)");
    }
    return h;
}

}  // namespace

std::shared_ptr<const KdTree> load_kdtree(const std::string& path,
                                          std::shared_ptr<const TriangleMesh> mesh,
                                          const KdTreeParams& params, double* verify_seconds,
                                          bool use_stamps) {
    MappedFile file(path);
    // The header checksum sits at a fixed offset; the full checks below validate it.
    uint64_t header_checksum = 0;
    if (file.size() >= sizeof(FileHeader)) {
        std::memcpy(&header_checksum, file.data() + offsetof(FileHeader, header_checksum), 8);
    }
    const std::string key = use_stamps && mesh
                                ? stamp_key(file.stat(), header_checksum, mesh->content_hash())
                                : std::string();
    const bool verified = !key.empty() && stamped(file.stat(), key);
    double seconds = 0.0;
    std::shared_ptr<const KdTree> tree;
    try {
        tree = load_kdtree_image(file.data(), file.size(), path, std::move(mesh), params, !verified,
                                 &seconds);
        file.check_unchanged();
    } catch (const Error&) {
        file.check_unchanged();  // a file that shrank meanwhile is the problem to report
        throw;
    }
    if (!verified && !key.empty()) write_stamp(file.stat(), key);
    if (verify_seconds) *verify_seconds = seconds;
    return tree;
}

KdTreeParams kdtree_file_params(const std::string& path) {
    MappedFile file(path);
    FileHeader h;
    try {
        h = checked_header(file.data(), file.size(), path);
        file.check_unchanged();
    } catch (const Error&) {
        file.check_unchanged();
        throw;
    }
    KdTreeParams p;
    if (h.builder >= kKdBuilderNames.size())
        fail_at(path, "header", -1, offsetof(FileHeader, builder), "unknown builder");
    p.builder = KdBuilder(h.builder);
    p.q = h.q;
    p.n0 = h.n0;
    p.max_depth = h.max_depth;
    p.use_median_split = (h.split_flags & kFlagMedian) != 0;
    p.use_center_split = (h.split_flags & kFlagCenter) != 0;
    p.use_cutoff_split = (h.split_flags & kFlagCutoff) != 0;
    p.thesis_all_axes = (h.split_flags & kFlagAllAxes) != 0;
    p.traversal_cost = h.traversal_cost;
    p.intersect_cost = h.intersect_cost;
    p.empty_bonus = h.empty_bonus;
    try {
        validate(p);
    } catch (const Error& e) {
        fail_at(path, "header", -1, offsetof(FileHeader, builder), e.what());
    }
    return p;
}

std::shared_ptr<const KdTree> load_kdtree_memory(const unsigned char* data, size_t size,
                                                 const std::string& path,
                                                 std::shared_ptr<const TriangleMesh> mesh,
                                                 const KdTreeParams& params,
                                                 double* verify_seconds) {
    return load_kdtree_image(data, size, path, std::move(mesh), params, true, verify_seconds);
}

namespace {

std::shared_ptr<const KdTree> load_kdtree_image(const unsigned char* data, size_t size,
                                                const std::string& path,
                                                std::shared_ptr<const TriangleMesh> mesh,
                                                const KdTreeParams& params, bool verify,
                                                double* verify_seconds) {
    if (!mesh) throw Error(ErrorLocation{path}, "no mesh to check the tree cache against");
    const FileHeader h = checked_header(data, size, path);
    const uint8_t want_flags = split_flags(params);
    if (h.builder != uint8_t(params.builder) || float_bits(h.q) != float_bits(params.q) ||
        h.n0 != params.n0 || h.max_depth != params.max_depth || h.split_flags != want_flags ||
        float_bits(h.traversal_cost) != float_bits(params.traversal_cost) ||
        float_bits(h.intersect_cost) != float_bits(params.intersect_cost) ||
        float_bits(h.empty_bonus) != float_bits(params.empty_bonus) ||
        h.params_hash != kdtree_params_hash(params)) {
        fail_at(path, "header", -1, offsetof(FileHeader, builder),
                "built with other parameters (" +
                    describe_params(h.builder, h.q, h.n0, h.max_depth, h.split_flags) +
                    "; wanted " +
                    describe_params(uint8_t(params.builder), params.q, params.n0, params.max_depth,
                                    want_flags) +
                    ")");
    }
    const uint64_t mesh_hash = mesh->content_hash();
    if (h.mesh_hash != mesh_hash || h.vertex_count != mesh->vertex_count() ||
        h.triangle_count != mesh->triangle_count()) {
        fail_at(path, "header", -1, offsetof(FileHeader, mesh_hash),
                "stale: built for another mesh (" + std::to_string(h.vertex_count) + " vertices, " +
                    std::to_string(h.triangle_count) + " triangles, hash " + hex64(h.mesh_hash) +
                    "; the model has " + std::to_string(mesh->vertex_count()) + " vertices, " +
                    std::to_string(mesh->triangle_count()) + " triangles, hash " +
                    hex64(mesh_hash) + ")");
    }
    // Node children are 30-bit indices and leaf ranges 32-bit: larger counts cannot be real.
    if (h.node_count == 0 || h.node_count > (uint64_t(1) << 30) || h.index_count > 0xffffffffull) {
        fail_at(path, "header", -1, offsetof(FileHeader, node_count),
                "implausible counts (" + std::to_string(h.node_count) + " nodes, " +
                    std::to_string(h.index_count) + " indices)");
    }
    // Statistics are informational (a builder may leave some zero); only bound what is read.
    if (h.depth_histogram_count > kMaxDepthHistogram) {
        fail_at(path, "header", -1, offsetof(FileHeader, leaves),
                "depth histogram longer than " + std::to_string(kMaxDepthHistogram));
    }
    const uint64_t expected =
        sizeof(FileHeader) + h.node_count * sizeof(KdNode) + h.index_count * 4;
    if (size != expected) {
        fail_at(path, "payload", -1, int64_t(std::min<uint64_t>(size, expected)),
                (size < expected ? "truncated: " : "trailing bytes: ") + std::to_string(size) +
                    " bytes, the header describes " + std::to_string(expected));
    }
    const unsigned char* payload = data + sizeof(FileHeader);
    if (checksum64(payload, size - sizeof(FileHeader)) != h.payload_checksum) {
        fail_at(path, "payload", -1, sizeof(FileHeader),
                "payload checksum mismatch (corrupt data)");
    }
    std::vector<KdNode> nodes(h.node_count);
    std::memcpy(nodes.data(), payload, nodes.size() * sizeof(KdNode));
    std::vector<uint32_t> indices(h.index_count);
    if (!indices.empty()) {
        std::memcpy(indices.data(), payload + nodes.size() * sizeof(KdNode), indices.size() * 4);
    }
    check_structure(path, nodes.data(), nodes.size(), indices.data(), indices.size(),
                    mesh->triangle_count(), sizeof(FileHeader));

    Bounds3f bounds;
    bounds.lower = Vec3f(h.bounds[0], h.bounds[1], h.bounds[2]);
    bounds.upper = Vec3f(h.bounds[3], h.bounds[4], h.bounds[5]);
    // The traversal clips rays to these bounds; an empty box (a tree of no triangles) is
    // +inf/-inf, anything else must be finite.
    if (!bounds.empty() && (!is_finite(bounds.lower) || !is_finite(bounds.upper))) {
        fail_at(path, "header", -1, offsetof(FileHeader, bounds), "bounds not finite");
    }
    // Rays are clipped to these bounds, so they must hold every triangle a ray can hit;
    // a smaller box (say, a resealed hostile file) would lose hits without a word.
    const Bounds3f need = hittable_triangle_bounds(*mesh);
    if (!need.empty() && (bounds.empty() || !contains(bounds, need))) {
        fail_at(path, "header", -1, offsetof(FileHeader, bounds),
                "bounds do not contain the mesh's triangles");
    }
    KdTreeStats s;
    s.nodes = h.node_count;
    s.leaves = h.leaves;
    s.empty_leaves = h.empty_leaves;
    s.references = h.references;
    s.refs_per_triangle = h.refs_per_triangle;
    s.mean_leaf_size = h.mean_leaf_size;
    s.max_leaf_size = h.max_leaf_size;
    s.max_depth_reached = h.max_depth_reached;
    s.depth_histogram.assign(h.depth_histogram, h.depth_histogram + h.depth_histogram_count);
    s.median_splits = h.median_splits;
    s.center_splits = h.center_splits;
    s.cutoff_splits = h.cutoff_splits;
    s.sah_splits = h.sah_splits;
    // bytes and bytes_per_triangle: the KdTree counts them from its arrays.
    s.build_seconds = h.build_seconds;
    s.peak_build_bytes = h.peak_build_bytes;
    std::shared_ptr<const KdTree> tree;
    try {
        tree = std::make_shared<const KdTree>(std::move(mesh), bounds, std::move(nodes),
                                              std::move(indices), params, std::move(s));
    } catch (const Error& e) {
        // The tree re-checks what it is given; whatever it still finds names this file.
        throw Error(ErrorLocation{path}, e.what());
    }
    // A resealed file can hold a well-formed tree that loses triangles.
    if (verify) {
        Timer timer;
        check_kdtree_complete(*tree, path);
        if (verify_seconds) *verify_seconds = timer.seconds();
    }
    return tree;
}

}  // namespace

void reseal_kdtree_cache_image(std::vector<unsigned char>& bytes) {
    if (bytes.size() < sizeof(FileHeader)) throw Error("tree cache image shorter than a header");
    FileHeader h;
    std::memcpy(&h, bytes.data(), sizeof(h));
    h.payload_checksum = checksum64(bytes.data() + sizeof(h), bytes.size() - sizeof(h));
    h.header_checksum = checksum64(&h, offsetof(FileHeader, header_checksum));
    std::memcpy(bytes.data(), &h, sizeof(h));
}

size_t kdtree_cache_payload_offset() { return sizeof(FileHeader); }

std::string default_kdtree_cache_dir() {
    if (const char* env = std::getenv("KDT_CACHE_DIR"); env && *env) {
        return (fs::path(env) / "trees").string();
    }
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
        return (fs::path(xdg) / "kdtrace" / "trees").string();
    }
    if (const char* home = std::getenv("HOME"); home && *home) {
        return (fs::path(home) / ".cache" / "kdtrace" / "trees").string();
    }
    return {};
}

std::shared_ptr<const KdTree> get_or_build_kdtree(const std::string& model_path,
                                                  std::shared_ptr<const TriangleMesh> mesh,
                                                  const KdTreeParams& params,
                                                  const std::string& cache_dir,
                                                  const KdCacheLog& log, KdCacheReport* report,
                                                  const std::atomic<bool>* cancel) {
    validate(params);
    const KdCacheLog& say = log ? log : KdCacheLog(default_log);
    Timer timer;
    KdCacheReport rep;

    // One directory: the one asked for, else the user's cache directory, where files of
    // models that share a file name are told apart by the mesh's content hash.
    const std::string hash = hex64(mesh->content_hash());
    const std::string params_part = kdtree_cache_file_name("", params).substr(1);
    std::string name;
    if (model_path.empty()) {
        name = "mesh-" + hash + "." + params_part;
    } else if (!cache_dir.empty()) {
        name = kdtree_cache_file_name(model_path, params);
    } else {
        name = fs::path(model_path).filename().string() + "-" + hash + "." + params_part;
    }
    std::vector<fs::path> dirs;
    if (!cache_dir.empty()) {
        dirs.push_back(cache_dir);
    } else if (std::string d = default_kdtree_cache_dir(); !d.empty()) {
        dirs.push_back(d);
    }

    std::string reasons;
    for (const fs::path& dir : dirs) {
        const fs::path file = dir / name;
        std::error_code ec;
        if (!fs::exists(fs::symlink_status(file, ec))) continue;
        try {
            auto tree = load_kdtree(file.string(), mesh, params, &rep.verify_seconds, true);
            rep.path = file.string();
            rep.loaded = true;
            rep.seconds = timer.seconds();
            char buf[96];
            if (rep.verify_seconds > 0.0) {
                std::snprintf(buf, sizeof(buf), " (%.3f s, of which %.3f s verifying the tree)",
                              rep.seconds, rep.verify_seconds);
            } else {
                std::snprintf(buf, sizeof(buf), " (%.3f s; tree verified on an earlier run)",
                              rep.seconds);
            }
            say("kd-tree cache: loaded " + printable(rep.path) + buf);
            if (const std::string w = kdtree_leaf_warning(*tree); !w.empty()) say("warning: " + w);
            if (report) *report = rep;
            return tree;
        } catch (const Error& e) {
            say("kd-tree cache: rebuilding: " + std::string(e.what()));
            if (!reasons.empty()) reasons += "; ";
            reasons += e.what();
        }
    }
    rep.reason = reasons;

    auto tree = build_kdtree(mesh, params, cancel);
    if (const std::string w = kdtree_leaf_warning(*tree); !w.empty()) say("warning: " + w);
    for (const fs::path& dir : dirs) {
        std::error_code ec;
        // Only the cache directory is ours to create; the model's directory must exist.
        if (&dir == &dirs.back() && !fs::exists(dir, ec)) create_private_directories(dir);
        if (!directory_writable(dir)) {
            if (&dir == &dirs.back() || !cache_dir.empty()) {
                say("warning: kd-tree cache: cannot write to " + printable(dir.string()) +
                    ": not a writable directory; tree not cached");
            }
            continue;
        }
        const fs::path file = dir / name;
        try {
            save_kdtree_file(file.string(), *tree, true);
            rep.path = file.string();
            rep.written = true;
            say("kd-tree cache: wrote " + printable(rep.path));
            break;
        } catch (const Error& e) {
            say("warning: kd-tree cache: " + std::string(e.what()) + "; tree not cached");
        }
    }
    rep.seconds = timer.seconds();
    if (report) *report = rep;
    return tree;
}

}  // namespace kdt
