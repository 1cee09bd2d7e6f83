// kd-tree cache files (.kdt): save a built tree, load it back by mmap after validating
// everything (magic, version, builder and parameters, mesh hash, counts, structure,
// checksum), and reuse-or-rebuild next to the model or in a cache directory.
// Depends on core, geometry and the kd-tree; touches files (the one accel file that does).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "renderer/accel/kdtree.h"

namespace kdt {

/// Format version written into every cache file; files of any other version are rebuilt.
inline constexpr uint32_t kKdCacheVersion = 2;  // 2: 28-bit child index, empty-child bits

/// Hash of the parameters that change the tree (builder, q, n0, depth, split flags, SAH
/// costs; not threads). Used in cache file names and stored in the header.
uint64_t kdtree_params_hash(const KdTreeParams& params);

/// File name of a tree cache for a model: "<model file name>.<builder>-<16 hex digits>.kdt".
std::string kdtree_cache_file_name(const std::string& model_path, const KdTreeParams& params);

/// Writes `tree` to `path` atomically (temporary file in the same directory, then rename).
/// Throws kdt::Error naming the path when it cannot be written.
void save_kdtree(const std::string& path, const KdTree& tree);

/// Maps `path` read-only and validates it against `mesh` and `params`: magic, byte order,
/// version, builder and parameters, mesh content hash, vertex/triangle/node/index counts,
/// file size, checksums, and the node structure (child indices in range and after their
/// parent, each node referenced once, depth <= 64, leaf ranges in range, triangle indices
/// < triangle count). Returns a tree sharing `mesh` (nodes and indices copied out of the
/// mapping). Throws kdt::Error with the path, the element and the byte offset on any
/// mismatch; never trusts a file it has not fully checked: last, check_kdtree_complete()
/// (whose time goes to `verify_seconds` when given).
/// With `use_stamps`, a file verified before (a verified-stamp in the user's cache directory,
/// default_kdtree_cache_dir()/verified, matches it) skips check_kdtree_complete(), and one
/// verified now gets a stamp; without (the default; `--tree` under `--no-cache`), the cache
/// directory is neither read nor written.
std::shared_ptr<const KdTree> load_kdtree(const std::string& path,
                                          std::shared_ptr<const TriangleMesh> mesh,
                                          const KdTreeParams& params,
                                          double* verify_seconds = nullptr,
                                          bool use_stamps = false);

/// The parameters a cache file (or a tree written by `kdtrace build -o`) was built with, after
/// checking its header (magic, version, checksum; values in range). Throws kdt::Error naming
/// the file otherwise.
KdTreeParams kdtree_file_params(const std::string& path);

/// load_kdtree() on a file image already in memory (`size` bytes at `data`, which need not
/// be aligned); `path` names it in error messages. For tests and fuzzers.
std::shared_ptr<const KdTree> load_kdtree_memory(const unsigned char* data, size_t size,
                                                 const std::string& path,
                                                 std::shared_ptr<const TriangleMesh> mesh,
                                                 const KdTreeParams& params,
                                                 double* verify_seconds = nullptr);

/// Verifies that `tree` is complete for its mesh, as the builders' contract (KdNode) says:
/// every split lies inside its node's box, and every hittable triangle is referenced by
/// every leaf whose box its clipped polygon reaches into, beyond a tolerance of 2^-20 of
/// the tree's largest coordinate (so that float rounding in a builder's clipping is never
/// taken for a missing reference; a triangle lying within that distance of a split plane
/// may be on either side). A checksum proves only that a file was not damaged; this proves
/// that the tree cannot lose a hit that a ray through the triangle's interior would find.
/// Throws kdt::Error naming `name`, the node and the triangle. Runs in parallel (OpenMP).
void check_kdtree_complete(const KdTree& tree, const std::string& name);

/// Recomputes both checksums of a cache file held in memory, for tests and tools that forge
/// or patch files (so that only the structural checks can catch what they changed).
/// Throws kdt::Error when `bytes` is shorter than a header.
void reseal_kdtree_cache_image(std::vector<unsigned char>& bytes);

/// Byte offset of the first node in a cache file (nodes, then indices, follow the header).
size_t kdtree_cache_payload_offset();

/// Receives one-line messages ("kd-tree cache: loaded ...", "kd-tree cache: rebuilding:
/// <reason>"); those the user must see even when progress is silenced start with "warning: "
/// (a cache that cannot be written, so that every run rebuilds; a degenerate tree).
using KdCacheLog = std::function<void(const std::string& line)>;

/// What get_or_build_kdtree() did, for reports and tests.
struct KdCacheReport {
    std::string path;             ///< cache file used or written; empty when none could be
    bool loaded = false;          ///< true: tree came from the cache file
    bool written = false;         ///< true: a fresh cache file was written
    std::string reason;           ///< why a cache file was not used (empty when loaded or absent)
    double seconds = 0.0;         ///< load or build (+ write) wall time
    double verify_seconds = 0.0;  ///< of `seconds`, check_kdtree_complete() on a loaded file
};

/// The default cache directory: $KDT_CACHE_DIR/trees, else $XDG_CACHE_HOME/kdtrace/trees,
/// else $HOME/.cache/kdtrace/trees (empty when none of these is set).
std::string default_kdtree_cache_dir();

/// Returns the tree for `mesh` (loaded from `model_path`) built with `params`, from a cache
/// file when a valid one exists, else built and written for the next run.
/// Location: with `cache_dir` set, "<model>.<builder>-<params hash>.kdt" there (`--cache-dir .`
/// puts trees next to the user's files only when asked); with it empty,
/// "<model>-<mesh hash>.<builder>-<params hash>.kdt" in default_kdtree_cache_dir(), so models
/// of one file name in different folders do not evict each other. `model_path` may be empty
/// for generated meshes: the name is then "mesh-<mesh hash>...".
/// Files are loaded with verified-stamps (load_kdtree), and the trees it writes are stamped.
/// A corrupt, truncated, stale or foreign file is reported through `log` (one line with the
/// reason; stderr when `log` is empty), rebuilt and rewritten atomically. A cache that cannot
/// be written is reported and the built tree still returned. Throws only what the build
/// throws (bad parameters; BuildCancelled once `cancel`, build_kdtree()'s, is set).
std::shared_ptr<const KdTree> get_or_build_kdtree(
    const std::string& model_path, std::shared_ptr<const TriangleMesh> mesh,
    const KdTreeParams& params, const std::string& cache_dir = {}, const KdCacheLog& log = {},
    KdCacheReport* report = nullptr, const std::atomic<bool>* cancel = nullptr);

}  // namespace kdt
