// Tree cache files: round trip, and every way a cache file can be wrong (truncated, flipped
// bytes, foreign, stale, other parameters, empty, a directory, an unwritable location) is
// detected with a clear reason and rebuilt.
#include "renderer/accel/kdtree_cache.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/core/error.h"
#include "renderer/core/map_guard.h"
#include "renderer/scene/scene.h"
#include "tests/test_util.h"

namespace kdt {
namespace {

namespace fs = std::filesystem;
using test::read_bytes;
using test::write_bytes;

std::shared_ptr<const TriangleMesh> sphere_mesh(int levels = 3) {
    return std::make_shared<const TriangleMesh>(make_displaced_sphere(levels));
}

KdTreeParams thesis_params() {
    KdTreeParams p;
    p.builder = KdBuilder::thesis;
    p.q = 0.98f;
    p.n0 = 5;
    p.max_depth = 20;
    return p;
}

void expect_same_tree(const KdTree& a, const KdTree& b) {
    ASSERT_EQ(a.nodes().size(), b.nodes().size());
    ASSERT_EQ(a.indices().size(), b.indices().size());
    EXPECT_EQ(0,
              std::memcmp(a.nodes().data(), b.nodes().data(), a.nodes().size() * sizeof(KdNode)));
    EXPECT_EQ(a.indices(), b.indices());
    EXPECT_EQ(a.bounds().lower, b.bounds().lower);
    EXPECT_EQ(a.bounds().upper, b.bounds().upper);
    EXPECT_EQ(a.stats().median_splits, b.stats().median_splits);
    EXPECT_EQ(a.stats().center_splits, b.stats().center_splits);
    EXPECT_EQ(a.stats().cutoff_splits, b.stats().cutoff_splits);
    EXPECT_EQ(a.stats().sah_splits, b.stats().sah_splits);
    EXPECT_EQ(a.stats().leaves, b.stats().leaves);
    EXPECT_EQ(a.stats().depth_histogram, b.stats().depth_histogram);
    // Render data is not in the file: a loaded tree derives the same, and counts it alike.
    EXPECT_EQ(a.reference_triangles(), b.reference_triangles());
    EXPECT_EQ(a.stats().bytes, b.stats().bytes);
    EXPECT_EQ(a.stats().bytes_per_triangle, b.stats().bytes_per_triangle);
}

std::string load_error(const fs::path& file, std::shared_ptr<const TriangleMesh> mesh,
                       const KdTreeParams& params, bool use_stamps = true) {
    try {
        load_kdtree(file.string(), std::move(mesh), params, nullptr, use_stamps);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

// Runs get_or_build_kdtree with a captured log.
struct CacheRun {
    std::shared_ptr<const KdTree> tree;
    KdCacheReport report;
    std::string log;
};

CacheRun run_cache(const fs::path& model, std::shared_ptr<const TriangleMesh> mesh,
                   const KdTreeParams& params, const fs::path& cache_dir) {
    CacheRun r;
    r.tree = get_or_build_kdtree(
        model.string(), std::move(mesh), params, cache_dir.string(),
        [&](const std::string& line) { r.log += line + "\n"; }, &r.report);
    return r;
}

class CacheTest : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = test::temp_dir("kdt_cache");
        model_ = dir_ / "sphere.ply";
        mesh_ = sphere_mesh();
        params_ = thesis_params();
        file_ = dir_ / kdtree_cache_file_name(model_.string(), params_);
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }
    // First run writes the cache file; returns the tree it built.
    std::shared_ptr<const KdTree> prime() {
        CacheRun r = run_cache(model_, mesh_, params_, dir_);
        EXPECT_FALSE(r.report.loaded);
        EXPECT_TRUE(r.report.written) << r.log;
        EXPECT_EQ(r.report.path, file_.string());
        EXPECT_TRUE(fs::is_regular_file(file_));
        return r.tree;
    }
    // A damaged file is reported with `reason`, rebuilt and rewritten; the next run loads it.
    void expect_rebuilt(const std::string& reason) {
        CacheRun r = run_cache(model_, mesh_, params_, dir_);
        ASSERT_TRUE(r.tree);
        EXPECT_FALSE(r.report.loaded);
        EXPECT_NE(r.report.reason.find(reason), std::string::npos)
            << "reason: " << r.report.reason << "\nwanted: " << reason;
        EXPECT_NE(r.log.find("rebuilding"), std::string::npos) << r.log;
        EXPECT_NE(r.log.find(file_.string()), std::string::npos) << r.log;
        EXPECT_TRUE(r.report.written) << r.log;
        CacheRun again = run_cache(model_, mesh_, params_, dir_);
        EXPECT_TRUE(again.report.loaded) << again.log;
        expect_same_tree(*r.tree, *again.tree);
    }

    fs::path dir_, model_, file_;
    std::shared_ptr<const TriangleMesh> mesh_;
    KdTreeParams params_;
};

TEST_F(CacheTest, RoundTripGivesIdenticalTree) {
    auto built = build_kdtree(mesh_, params_);
    save_kdtree(file_.string(), *built);
    auto loaded = load_kdtree(file_.string(), mesh_, params_);
    ASSERT_TRUE(loaded);
    expect_same_tree(*built, *loaded);
    EXPECT_EQ(&loaded->mesh(), mesh_.get());
    // Queries agree on a fan of rays through the sphere.
    for (int i = 0; i < 200; ++i) {
        Ray ray;
        ray.origin = Vec3f(3.0f, 0.01f * float(i - 100), 0.3f);
        ray.dir = glm::normalize(Vec3f(-1.0f, 0.002f * float(i), -0.1f));
        Hit a, b;
        EXPECT_EQ(built->intersect(ray, a), loaded->intersect(ray, b));
        EXPECT_EQ(a.prim, b.prim);
        EXPECT_EQ(a.t, b.t);
    }
}

TEST_F(CacheTest, SecondRunLoadsTheFirstRunsFile) {
    auto first = prime();
    CacheRun second = run_cache(model_, mesh_, params_, dir_);
    EXPECT_TRUE(second.report.loaded);
    EXPECT_FALSE(second.report.written);
    EXPECT_NE(second.log.find("loaded"), std::string::npos);
    expect_same_tree(*first, *second.tree);
}

TEST_F(CacheTest, FileNameCarriesBuilderAndParameterHash) {
    const std::string name = kdtree_cache_file_name("/some/where/dragon.ply", params_);
    EXPECT_EQ(name.rfind("dragon.ply.thesis-", 0), 0u) << name;
    EXPECT_EQ(name.substr(name.size() - 4), ".kdt");
    KdTreeParams other = params_;
    other.q = 0.95f;
    EXPECT_NE(name, kdtree_cache_file_name("/some/where/dragon.ply", other));
    other = params_;
    other.threads = 7;  // threads do not change the tree
    EXPECT_EQ(name, kdtree_cache_file_name("/some/where/dragon.ply", other));
    other = params_;
    other.use_median_split = false;
    EXPECT_NE(kdtree_params_hash(params_), kdtree_params_hash(other));
}

TEST_F(CacheTest, TruncatedFileIsRebuilt) {
    prime();
    auto bytes = read_bytes(file_);
    bytes.resize(bytes.size() - 100);
    write_bytes(file_, bytes);
    EXPECT_NE(load_error(file_, mesh_, params_).find("truncated"), std::string::npos);
    expect_rebuilt("truncated");
}

std::string g_victim;  // the cache file the MapGuard test hook truncates to one page

void truncate_victim(const std::string& path) {
    if (path == g_victim) {
        ASSERT_EQ(::truncate(path.c_str(), ::sysconf(_SC_PAGESIZE)), 0);
    }
}

// Cut by another process after it was mapped: an error naming the file, not SIGBUS.
TEST_F(CacheTest, FileTruncatedWhileReadIsAnError) {
    mesh_ = sphere_mesh(5);
    file_ = dir_ / kdtree_cache_file_name(model_.string(), params_);
    prime();
    ASSERT_GT(fs::file_size(file_), uintmax_t(4 * ::sysconf(_SC_PAGESIZE)));
    g_victim = file_.string();
    set_map_guard_test_hook(truncate_victim);
    const std::string msg = load_error(file_, mesh_, params_);
    set_map_guard_test_hook(nullptr);
    EXPECT_EQ(msg, file_.string() + ": the file changed or was truncated while it was read");
}

TEST_F(CacheTest, FileCutInsideTheHeaderIsRebuilt) {
    prime();
    auto bytes = read_bytes(file_);
    bytes.resize(100);
    write_bytes(file_, bytes);
    expect_rebuilt("truncated");
}

TEST_F(CacheTest, FlippedPayloadByteIsRebuilt) {
    prime();
    auto bytes = read_bytes(file_);
    bytes[bytes.size() - 37] ^= 0x10;
    write_bytes(file_, bytes);
    expect_rebuilt("payload checksum mismatch");
}

TEST_F(CacheTest, FlippedHeaderByteIsRebuilt) {
    prime();
    auto bytes = read_bytes(file_);
    bytes[200] ^= 0x01;  // inside the statistics block
    write_bytes(file_, bytes);
    expect_rebuilt("header checksum mismatch");
}

TEST_F(CacheTest, TrailingBytesAreRebuilt) {
    prime();
    auto bytes = read_bytes(file_);
    bytes.insert(bytes.end(), 16, 0);
    write_bytes(file_, bytes);
    expect_rebuilt("trailing bytes");
}

TEST_F(CacheTest, WrongMagicIsRebuilt) {
    prime();
    auto bytes = read_bytes(file_);
    bytes[1] = 'X';
    write_bytes(file_, bytes);
    expect_rebuilt("wrong magic");
}

TEST_F(CacheTest, ForeignFileIsRebuilt) {
    std::ofstream(file_) << "ply\nformat ascii 1.0\nelement vertex 3\n";
    expect_rebuilt("wrong magic");
}

TEST_F(CacheTest, WrongVersionIsRebuilt) {
    prime();
    auto bytes = read_bytes(file_);
    const uint32_t version = kKdCacheVersion + 1;
    std::memcpy(bytes.data() + 12, &version, 4);  // after magic and byte-order mark
    write_bytes(file_, bytes);
    expect_rebuilt("cache format version " + std::to_string(version) + ", this kdtrace reads " +
                   std::to_string(kKdCacheVersion));
}

TEST_F(CacheTest, StaleFileForAnotherMeshIsRebuilt) {
    prime();
    mesh_ = sphere_mesh(2);  // the model changed on disk since the cache was written
    expect_rebuilt("stale");
}

TEST_F(CacheTest, SameCountsDifferentPositionsIsStale) {
    prime();
    auto moved = std::make_shared<TriangleMesh>(*mesh_);
    moved->positions[17].x += 1e-3f;
    mesh_ = moved;
    expect_rebuilt("stale");
}

TEST_F(CacheTest, OtherParametersAreDetected) {
    prime();
    KdTreeParams other = params_;
    other.q = 0.9f;
    const std::string err = load_error(file_, mesh_, other);
    EXPECT_NE(err.find("other parameters"), std::string::npos) << err;
    EXPECT_NE(err.find("q=0.98"), std::string::npos) << err;
    // A file renamed to another parameter set's name is not trusted either.
    fs::copy_file(file_, dir_ / kdtree_cache_file_name(model_.string(), other));
    params_ = other;
    file_ = dir_ / kdtree_cache_file_name(model_.string(), other);
    expect_rebuilt("other parameters");
}

TEST_F(CacheTest, EmptyFileIsRebuilt) {
    std::ofstream(file_).close();
    ASSERT_TRUE(fs::exists(file_));
    expect_rebuilt("empty file");
}

// A FIFO where the cache file should be must not block the loader (open() of a FIFO
// without a writer waits forever): it is reported and replaced by the rebuilt tree's file.
TEST_F(CacheTest, FifoInsteadOfFileIsReportedAndReplaced) {
    ASSERT_EQ(::mkfifo(file_.c_str(), 0600), 0);
    CacheRun r = run_cache(model_, mesh_, params_, dir_);
    ASSERT_TRUE(r.tree);
    EXPECT_FALSE(r.report.loaded);
    EXPECT_NE(r.report.reason.find("is a FIFO (pipe), not a cache file"), std::string::npos)
        << r.report.reason;
    EXPECT_TRUE(r.report.written) << r.log;
    EXPECT_TRUE(fs::is_regular_file(file_));
    CacheRun again = run_cache(model_, mesh_, params_, dir_);
    EXPECT_TRUE(again.report.loaded) << again.report.reason;
}

TEST_F(CacheTest, DirectoryInsteadOfFileIsReportedAndTreeStillBuilt) {
    fs::create_directories(file_ / "x");
    CacheRun r = run_cache(model_, mesh_, params_, dir_);
    ASSERT_TRUE(r.tree);
    EXPECT_GT(r.tree->nodes().size(), 0u);
    EXPECT_FALSE(r.report.loaded);
    EXPECT_NE(r.report.reason.find("is a directory"), std::string::npos) << r.report.reason;
    EXPECT_FALSE(r.report.written);
    EXPECT_NE(r.log.find("cannot write"), std::string::npos) << r.log;
    EXPECT_TRUE(fs::is_directory(file_));
    // No temporary files are left behind.
    for (const auto& e : fs::directory_iterator(dir_)) {
        EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos) << e.path();
    }
}

TEST_F(CacheTest, UnwritableCacheDirectoryIsReportedAndTreeStillBuilt) {
    // A path below a regular file can be neither created nor written, even by root.
    std::ofstream(dir_ / "not_a_dir") << "x";
    const fs::path cache = dir_ / "not_a_dir" / "trees";
    CacheRun r = run_cache(model_, mesh_, params_, cache);
    ASSERT_TRUE(r.tree);
    EXPECT_GT(r.tree->indices().size(), 0u);
    EXPECT_FALSE(r.report.loaded);
    EXPECT_FALSE(r.report.written);
    EXPECT_TRUE(r.report.path.empty());
    EXPECT_NE(r.log.find("cannot write"), std::string::npos) << r.log;
}

// The log names paths as errors do, through printable(): a cache directory holding an ESC
// or a newline can neither drive the terminal nor forge a log line.
TEST_F(CacheTest, LogLinesEscapeThePaths) {
    const fs::path cache = dir_ / "a\x1b[2Jb\nkdtrace: c";
    CacheRun wrote = run_cache(model_, mesh_, params_, cache);
    ASSERT_TRUE(wrote.report.written) << wrote.log;
    CacheRun loaded = run_cache(model_, mesh_, params_, cache);
    ASSERT_TRUE(loaded.report.loaded) << loaded.log;
    std::ofstream(dir_ / "file\x1b") << "x";
    CacheRun refused = run_cache(model_, mesh_, params_, dir_ / "file\x1b" / "trees\n");
    ASSERT_FALSE(refused.report.written) << refused.log;
    for (const CacheRun* r : {&wrote, &loaded, &refused}) {
        const std::string line = r->log.substr(0, r->log.find('\n') + 1);
        EXPECT_EQ(line, r->log) << "one line expected";
        EXPECT_EQ(r->log.find('\x1b'), std::string::npos) << r->log;
        EXPECT_NE(r->log.find("\\x1b"), std::string::npos) << r->log;
    }
    EXPECT_NE(wrote.log.find("kd-tree cache: wrote "), std::string::npos) << wrote.log;
    EXPECT_NE(wrote.log.find("b\\nkdtrace: c"), std::string::npos) << wrote.log;
    EXPECT_NE(loaded.log.find("kd-tree cache: loaded "), std::string::npos) << loaded.log;
    EXPECT_NE(refused.log.find("trees\\n: not a writable directory"), std::string::npos)
        << refused.log;
}

TEST_F(CacheTest, SaveToUnwritablePathThrowsNamingIt) {
    auto tree = build_kdtree(mesh_, params_);
    const std::string bad = (dir_ / "missing" / "t.kdt").string();
    try {
        save_kdtree(bad, *tree);
        FAIL() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
}

// Files whose checksums are right but whose structure is not: a valid file is patched and
// resealed, so only the structural checks can catch the change.
class CacheStructureTest : public CacheTest {
protected:
    void SetUp() override {
        CacheTest::SetUp();
        tree_ = build_kdtree(mesh_, params_);
        save_kdtree(file_.string(), *tree_);
        bytes_ = read_bytes(file_);
        ASSERT_GT(tree_->nodes().size(), 8u);
        ASSERT_FALSE(tree_->nodes()[0].is_leaf());
    }
    size_t node_offset(size_t i) const { return kdtree_cache_payload_offset() + 8 * i; }
    size_t index_offset(size_t i) const { return node_offset(tree_->nodes().size()) + 4 * i; }
    void set_node(size_t i, const KdNode& n) { std::memcpy(&bytes_[node_offset(i)], &n, 8); }
    size_t first_inner_after(size_t i) const {
        for (size_t k = i + 1; k < tree_->nodes().size(); ++k) {
            if (!tree_->nodes()[k].is_leaf()) return k;
        }
        return 0;
    }
    size_t first_leaf() const {
        for (size_t k = 0; k < tree_->nodes().size(); ++k) {
            if (tree_->nodes()[k].is_leaf()) return k;
        }
        return 0;
    }
    // Byte offset of the header's bounds (six floats, lower first), found by value; 0 if not.
    size_t bounds_offset() const {
        const float lower[3] = {tree_->bounds().lower.x, tree_->bounds().lower.y,
                                tree_->bounds().lower.z};
        for (size_t k = 4; k + sizeof(lower) <= kdtree_cache_payload_offset(); k += 4) {
            if (std::memcmp(&bytes_[k], lower, sizeof(lower)) == 0) return k;
        }
        return 0;
    }
    std::string error() {
        reseal_kdtree_cache_image(bytes_);
        write_bytes(file_, bytes_);
        return load_error(file_, mesh_, params_);
    }

    std::shared_ptr<const KdTree> tree_;
    std::vector<unsigned char> bytes_;
};

TEST_F(CacheStructureTest, ResealedUnchangedFileLoads) { EXPECT_EQ(error(), ""); }

TEST_F(CacheStructureTest, ChildIndexOutOfRange) {
    const uint32_t n = uint32_t(tree_->nodes().size());
    set_node(0, KdNode::make_inner(0, 0.0f, n + 5));
    const std::string err = error();
    EXPECT_NE(err.find("node 0: child index " + std::to_string(n + 5) + " out of range"),
              std::string::npos)
        << err;
    EXPECT_NE(err.find("byte " + std::to_string(node_offset(0))), std::string::npos) << err;
}

TEST_F(CacheStructureTest, ChildPointingBackwardsWouldLoop) {
    const size_t j = first_inner_after(0);
    ASSERT_GT(j, 0u);
    set_node(j, KdNode::make_inner(1, 0.0f, uint32_t(j)));
    const std::string err = error();
    EXPECT_NE(err.find("node " + std::to_string(j) + ": child index " + std::to_string(j) +
                       " out of range"),
              std::string::npos)
        << err;
}

TEST_F(CacheStructureTest, SharedChild) {
    const size_t j = first_inner_after(0);
    ASSERT_GT(j, 0u);
    // The root adopts j's children: they now have two parents (and the root's old ones none).
    set_node(0, KdNode::make_inner(0, 0.0f, tree_->nodes()[j].child()));
    const std::string err = error();
    EXPECT_NE(err.find("child of two parents"), std::string::npos) << err;
}

TEST_F(CacheStructureTest, LeafRangeOutOfRange) {
    const size_t leaf = first_leaf();
    const uint32_t n = uint32_t(tree_->indices().size());
    set_node(leaf, KdNode::make_leaf(2, n - 1));
    const std::string err = error();
    EXPECT_NE(
        err.find("node " + std::to_string(leaf) + ": leaf range [" + std::to_string(n - 1) + ", " +
                 std::to_string(n + 1) + ") outside the " + std::to_string(n) + " indices"),
        std::string::npos)
        << err;
}

TEST_F(CacheStructureTest, TriangleIndexOutOfRange) {
    const uint32_t n = uint32_t(mesh_->triangle_count());
    std::memcpy(&bytes_[index_offset(3)], &n, 4);
    const std::string err = error();
    EXPECT_NE(err.find("byte " + std::to_string(index_offset(3)) + ": index 3: triangle index " +
                       std::to_string(n) + " out of range"),
              std::string::npos)
        << err;
}

TEST_F(CacheStructureTest, NonFiniteSplit) {
    set_node(0, KdNode::make_inner(2, std::nanf(""), tree_->nodes()[0].child()));
    const std::string err = error();
    EXPECT_NE(err.find("split plane not finite"), std::string::npos) << err;
}

// Found by tests/fuzz/cache_fuzzer: NaN bounds in a resealed header passed the loader's
// checks and were only caught by the KdTree constructor, whose message did not name the file.
TEST_F(CacheStructureTest, NonFiniteBoundsNameTheFile) {
    const size_t at = bounds_offset();
    ASSERT_GT(at, 0u);
    const float nan = std::nanf("");
    std::memcpy(&bytes_[at + 4], &nan, 4);
    const std::string err = error();
    EXPECT_EQ(err.rfind(file_.string() + ": byte " + std::to_string(at) + ": header: ", 0), 0u)
        << err;
    EXPECT_NE(err.find("bounds not finite"), std::string::npos) << err;
}

// Rays are clipped to the stored bounds: a box that misses part of the mesh would lose
// hits silently, so it is refused (growing the box is harmless and loads).
TEST_F(CacheStructureTest, BoundsThatDoNotHoldTheMeshAreRefused) {
    const size_t at = bounds_offset();
    ASSERT_GT(at, 0u);
    const float lower[3] = {tree_->bounds().lower.x, tree_->bounds().lower.y,
                            tree_->bounds().lower.z};
    const std::vector<unsigned char> original = bytes_;
    // upper.y moved inwards by a tenth of the box.
    const float upper_y = tree_->bounds().upper.y - 0.1f * (tree_->bounds().upper.y - lower[1]);
    std::memcpy(&bytes_[at + 16], &upper_y, 4);
    std::string err = error();
    EXPECT_EQ(err.rfind(file_.string() + ": byte " + std::to_string(at) + ": header: ", 0), 0u)
        << err;
    EXPECT_NE(err.find("bounds do not contain the mesh's triangles"), std::string::npos) << err;
    bytes_ = original;
    const float lower_x = lower[0] - 1.0f;
    std::memcpy(&bytes_[at], &lower_x, 4);
    EXPECT_EQ(error(), "");
}

TEST_F(CacheStructureTest, StructureErrorTriggersRebuild) {
    set_node(first_leaf(), KdNode::make_leaf(5, uint32_t(tree_->indices().size())));
    error();
    expect_rebuilt("leaf range");
}

// Both builders leave out triangles they can never hit, and the thesis builder's box holds
// only the others: a far-away triangle with a repeated vertex index must not make the
// loader's bounds check refuse the tree it saved.
TEST(CacheBounds, TreesOverMeshesWithStrayDegenerateTrianglesLoad) {
    auto mesh = std::make_shared<TriangleMesh>(make_displaced_sphere(3));
    const uint32_t far = uint32_t(mesh->positions.size());
    mesh->positions.push_back(Vec3f(100.0f, 100.0f, 100.0f));
    mesh->positions.push_back(Vec3f(101.0f, 100.0f, 100.0f));
    mesh->triangles.push_back(Vec3u(far, far, far + 1));
    const std::shared_ptr<const TriangleMesh> m = mesh;
    const fs::path dir = test::temp_dir("kdt_cache_degenerate");
    KdTreeParams sah;
    for (const KdTreeParams& params : {thesis_params(), sah}) {
        const auto tree = build_kdtree(m, params);
        const fs::path file = dir / (std::string(kKdBuilderNames[size_t(params.builder)]) + ".kdt");
        save_kdtree(file.string(), *tree);
        EXPECT_EQ(load_error(file, m, params), "") << kKdBuilderNames[size_t(params.builder)];
    }
}

TEST(CacheLocations, UserCacheDirectoryUnlessAsked) {
    const fs::path dir = test::temp_dir("kdt_cache_loc");
    const fs::path cache = dir / "cache";
    // Other tests (and test_util's dragon_dir()) read KDT_CACHE_DIR: restore it afterwards.
    const char* old_env = std::getenv("KDT_CACHE_DIR");
    const std::string saved = old_env ? old_env : "";
    ::setenv("KDT_CACHE_DIR", cache.c_str(), 1);
    EXPECT_EQ(default_kdtree_cache_dir(), (cache / "trees").string());
    auto mesh = sphere_mesh(2);
    KdTreeParams params = thesis_params();
    std::string log;
    auto say = [&](const std::string& l) { log += l + "\n"; };

    // By default trees go to the user's cache directory, never next to the user's files, named
    // by the model's file name and the mesh's content hash.
    KdCacheReport rep;
    get_or_build_kdtree((dir / "m.ply").string(), mesh, params, "", say, &rep);
    EXPECT_TRUE(rep.written);
    EXPECT_EQ(fs::path(rep.path).parent_path(), cache / "trees");
    EXPECT_EQ(fs::path(rep.path).filename().string().rfind("m.ply-", 0), 0u) << rep.path;
    EXPECT_FALSE(fs::exists(dir / kdtree_cache_file_name("m.ply", params)));
    // The same mesh under the same file name elsewhere finds it; another mesh does not.
    get_or_build_kdtree((dir / "ro" / "m.ply").string(), mesh, params, "", say, &rep);
    EXPECT_TRUE(rep.loaded) << log;
    get_or_build_kdtree((dir / "ro" / "m.ply").string(), sphere_mesh(1), params, "", say, &rep);
    EXPECT_FALSE(rep.loaded) << log;
    EXPECT_TRUE(rep.written) << log;
    // Next to the model only when asked.
    get_or_build_kdtree((dir / "m.ply").string(), mesh, params, dir.string(), say, &rep);
    EXPECT_EQ(rep.path, (dir / kdtree_cache_file_name("m.ply", params)).string());

    // Generated meshes have no model path: named by the mesh hash, in the cache directory.
    get_or_build_kdtree("", mesh, params, "", say, &rep);
    EXPECT_TRUE(rep.written) << log;
    EXPECT_EQ(fs::path(rep.path).parent_path(), cache / "trees");
    EXPECT_EQ(fs::path(rep.path).filename().string().rfind("mesh-", 0), 0u) << rep.path;
    get_or_build_kdtree("", mesh, params, "", say, &rep);
    EXPECT_TRUE(rep.loaded) << log;

    if (old_env) {
        ::setenv("KDT_CACHE_DIR", saved.c_str(), 1);
    } else {
        ::unsetenv("KDT_CACHE_DIR");
    }
    std::error_code ec;
    fs::remove_all(dir, ec);
}

TEST(CacheParams, BadParametersStillThrow) {
    KdTreeParams p = thesis_params();
    p.q = 1.5f;
    EXPECT_THROW(
        get_or_build_kdtree("", sphere_mesh(1), p, test::temp_dir("kdt_cache_bad").string(),
                            [](const std::string&) {}),
        Error);
}

// Sets KDT_CACHE_DIR (where verified-stamps go) for one test and restores it.
class ScopedCacheDirEnv {
public:
    explicit ScopedCacheDirEnv(const fs::path& dir) {
        const char* old = std::getenv("KDT_CACHE_DIR");
        had_ = old != nullptr;
        if (old) old_ = old;
        ::setenv("KDT_CACHE_DIR", dir.c_str(), 1);
    }
    ~ScopedCacheDirEnv() {
        if (had_) {
            ::setenv("KDT_CACHE_DIR", old_.c_str(), 1);
        } else {
            ::unsetenv("KDT_CACHE_DIR");
        }
    }

private:
    bool had_ = false;
    std::string old_;
};

// Well-formed trees that lose triangles, each with a correct checksum (save_kdtree writes
// them as it would a real tree): only the completeness check can refuse them.
struct Forgery {
    std::string name;
    std::vector<KdNode> nodes;
    std::vector<uint32_t> indices;
    std::string expected;  ///< part of the refusal
};

// A leaf of at least two references and the index slot of one whose triangle's centroid
// lies strictly inside the leaf's box.
std::pair<uint32_t, uint32_t> required_reference(const KdTree& t) {
    struct Item {
        uint32_t node;
        Bounds3f box;
    };
    std::vector<Item> stack{{0, t.bounds()}};
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        const KdNode& n = t.nodes()[it.node];
        if (!n.is_leaf()) {
            Item lo{n.child(), it.box}, hi{n.child() + 1, it.box};
            lo.box.upper[n.axis()] = n.split;
            hi.box.lower[n.axis()] = n.split;
            stack.push_back(lo);
            stack.push_back(hi);
            continue;
        }
        for (uint32_t k = n.first; n.count() >= 2 && k < n.first + n.count(); ++k) {
            const Vec3u& tri = t.mesh().triangles[t.indices()[k]];
            const auto& p = t.mesh().positions;
            const Vec3f c = (p[tri.x] + p[tri.y] + p[tri.z]) / 3.0f;
            if (glm::all(glm::greaterThan(c, it.box.lower)) &&
                glm::all(glm::lessThan(c, it.box.upper)))
                return {it.node, k};
        }
    }
    ADD_FAILURE() << "no leaf holds a triangle's centroid";
    return {0, 0};
}

std::vector<Forgery> forgeries(const KdTree& t) {
    std::vector<Forgery> out;
    const std::string incomplete = "the tree is incomplete for its mesh";
    out.push_back({"empty tree", {KdNode::make_leaf(0, 0)}, {}, "triangle 0 reaches into"});
    out.push_back({"one triangle", {KdNode::make_leaf(1, 0)}, {7}, "triangle 0 reaches into"});
    // The root split moved by a quarter of the box: its children keep their triangles.
    {
        Forgery f{"moved root split", t.nodes(), t.indices(), incomplete};
        const int a = f.nodes[0].axis();
        const float extent = t.bounds().upper[a] - t.bounds().lower[a];
        f.nodes[0].split +=
            (f.nodes[0].split - t.bounds().lower[a] > 0.5f * extent ? -0.25f : 0.25f) * extent;
        out.push_back(f);
    }
    // The root split outside the box altogether.
    {
        Forgery f{"split outside its box", t.nodes(), t.indices(), "outside the node's box"};
        f.nodes[0].split = t.bounds().upper[f.nodes[0].axis()] + 1.0f;
        out.push_back(f);
    }
    {
        Forgery f{"zeroed indices", t.nodes(), t.indices(), incomplete};
        std::fill(f.indices.begin(), f.indices.end(), 0u);
        out.push_back(f);
    }
    // A reference a ray must find there (its triangle's centroid strictly inside the leaf's
    // box; a builder may add others) dropped: the leaf's range one shorter, or the
    // reference overwritten by its neighbour (counts unchanged).
    const auto [leaf, slot] = required_reference(t);
    {
        Forgery f{"dropped leaf reference", t.nodes(), t.indices(), "is not referenced by it"};
        const KdNode n = f.nodes[leaf];
        std::swap(f.indices[slot], f.indices[n.first + n.count() - 1]);
        f.nodes[leaf] = KdNode::make_leaf(n.count() - 1, n.first);
        out.push_back(f);
    }
    {
        Forgery f{"overwritten reference", t.nodes(), t.indices(), "is not referenced by it"};
        const KdNode n = f.nodes[leaf];
        f.indices[slot] = f.indices[slot == n.first ? slot + 1 : n.first];
        out.push_back(f);
    }
    return out;
}

TEST(CacheCompleteness, ForgedTreesWithGoodChecksumsAreRefusedAndRebuilt) {
    const fs::path dir = test::temp_dir("kdt_cache_forged");
    ScopedCacheDirEnv env(dir / "user_cache");
    const auto mesh = sphere_mesh(3);
    KdTreeParams sah;
    for (const KdTreeParams& params : {thesis_params(), sah}) {
        const auto built = build_kdtree(mesh, params);
        ASSERT_FALSE(built->nodes()[0].is_leaf());
        const fs::path model = dir / "sphere.ply";
        const fs::path file = dir / kdtree_cache_file_name(model.string(), params);
        for (const Forgery& f : forgeries(*built)) {
            const std::string what =
                std::string(kKdBuilderNames[size_t(params.builder)]) + ", " + f.name;
            const KdTree forged(mesh, built->bounds(), f.nodes, f.indices, params, built->stats());
            save_kdtree(file.string(), forged);
            const std::string err = load_error(file, mesh, params);
            EXPECT_EQ(err.rfind(file.string() + ": node ", 0), 0u) << what << ": " << err;
            EXPECT_NE(err.find(f.expected), std::string::npos) << what << ": " << err;
            // Refused every time (no stamp for a file that failed), and rebuilt by the cache.
            EXPECT_EQ(load_error(file, mesh, params), err) << what;
            CacheRun r = run_cache(model, mesh, params, dir);
            EXPECT_FALSE(r.report.loaded) << what;
            EXPECT_NE(r.report.reason.find(f.expected), std::string::npos) << what << ": " << r.log;
            expect_same_tree(*built, *r.tree);
            fs::remove(file);
        }
        // The genuine tree, saved the same way, loads (and is verified doing so).
        save_kdtree(file.string(), *built);
        EXPECT_EQ(load_error(file, mesh, params), "");
    }
}

TEST(CacheCompleteness, VerifiedOnFirstUseThenStampedUntilTheFileChanges) {
    const fs::path dir = test::temp_dir("kdt_cache_stamp");
    ScopedCacheDirEnv env(dir / "user_cache");
    const auto mesh = sphere_mesh(3);
    const KdTreeParams params = thesis_params();
    const auto built = build_kdtree(mesh, params);
    const fs::path file = dir / "t.kdt";
    save_kdtree(file.string(), *built);  // from outside: not stamped
    double first = -1.0, second = -1.0;
    load_kdtree(file.string(), mesh, params, &first, true);
    load_kdtree(file.string(), mesh, params, &second, true);
    EXPECT_GT(first, 0.0);   // verified ...
    EXPECT_EQ(second, 0.0);  // ... once
    // The stamp lives in the private cache directory, created with mode 0700.
    const fs::path stamps = dir / "user_cache" / "trees" / "verified";
    ASSERT_TRUE(fs::is_directory(stamps));
    for (const fs::path& p : {dir / "user_cache", dir / "user_cache" / "trees", stamps}) {
        struct stat st {};
        ASSERT_EQ(::stat(p.c_str(), &st), 0);
        EXPECT_EQ(st.st_mode & 0777, 0700u) << p;
    }
    // The same path now holding a forged tree (a new file, or the old one rewritten in
    // place) does not match the stamp: verified again, and refused.
    const Forgery f = forgeries(*built)[4];  // zeroed indices
    const KdTree forged(mesh, built->bounds(), f.nodes, f.indices, params, built->stats());
    save_kdtree(file.string(), forged);
    EXPECT_NE(load_error(file, mesh, params).find("incomplete"), std::string::npos);
    save_kdtree((dir / "good.kdt").string(), *built);
    const std::vector<unsigned char> bad = read_bytes(file);
    load_kdtree((dir / "good.kdt").string(), mesh, params, nullptr, true);  // stamped now
    {
        std::fstream out(dir / "good.kdt", std::ios::in | std::ios::out | std::ios::binary);
        out.write(reinterpret_cast<const char*>(bad.data()), std::streamsize(bad.size()));
    }
    EXPECT_NE(load_error(dir / "good.kdt", mesh, params).find("incomplete"), std::string::npos);
    // Trees the cache builds itself are stamped as they are written.
    CacheRun r = run_cache(dir / "m.ply", mesh, params, dir / "a" / "b");
    EXPECT_TRUE(r.report.written);
    CacheRun again = run_cache(dir / "m.ply", mesh, params, dir / "a" / "b");
    EXPECT_TRUE(again.report.loaded);
    EXPECT_EQ(again.report.verify_seconds, 0.0);
    EXPECT_NE(again.log.find("verified on an earlier run"), std::string::npos) << again.log;
    for (const fs::path& p : {dir / "a", dir / "a" / "b"}) {
        struct stat st {};
        ASSERT_EQ(::stat(p.c_str(), &st), 0);
        EXPECT_EQ(st.st_mode & 0777, 0700u) << p;
    }
}

// A file of the user's choice (`render --tree`, `--no-cache` or not) is loaded without
// stamps: verified in full on every load, and nothing is written to the cache directory.
TEST(CacheCompleteness, LoadWithoutStampsLeavesTheCacheDirectoryAlone) {
    const fs::path dir = test::temp_dir("kdt_cache_no_stamp");
    ScopedCacheDirEnv env(dir / "user_cache");
    const auto mesh = sphere_mesh(3);
    const KdTreeParams params = thesis_params();
    const fs::path file = dir / "t.kdt";
    save_kdtree(file.string(), *build_kdtree(mesh, params));
    for (int run = 0; run < 2; ++run) {
        double seconds = -1.0;
        load_kdtree(file.string(), mesh, params, &seconds);
        EXPECT_GT(seconds, 0.0) << "run " << run;  // verified every time
    }
    EXPECT_FALSE(fs::exists(dir / "user_cache"));
    // A stamp written with use_stamps is not read without it either.
    load_kdtree(file.string(), mesh, params, nullptr, true);
    ASSERT_TRUE(fs::is_directory(dir / "user_cache" / "trees" / "verified"));
    double seconds = -1.0;
    load_kdtree(file.string(), mesh, params, &seconds);
    EXPECT_GT(seconds, 0.0);
}

}  // namespace
}  // namespace kdt
