// Helpers shared by the test executables: paths to the source tree, shared data, assets.
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/core/math.h"
#include "renderer/geometry/mesh.h"

namespace kdt::test {

/// Root of the source tree.
std::filesystem::path source_dir();
/// ../shared/data next to the repository, or empty when absent (tests then GTEST_SKIP
/// with a message saying so).
std::filesystem::path shared_data_dir();
/// shared_data_dir() / "probes" / "grace.hdr" when that file exists, else empty; tests skip
/// with kNoGraceProbe.
std::filesystem::path grace_probe();
inline constexpr const char* kNoGraceProbe =
    "../shared/data/probes/grace.hdr not found (set KDT_SHARED_DATA)";
/// Directory holding the fetched Stanford dragon (scripts/fetch_assets.sh), or empty.
std::filesystem::path dragon_dir();
/// A fresh temporary directory for one test.
std::filesystem::path temp_dir(const std::string& name);
/// The whole file (empty when it cannot be read).
std::vector<unsigned char> read_bytes(const std::filesystem::path& p);
/// Writes the file, replacing it; throws kdt::Error naming it when that fails.
void write_bytes(const std::filesystem::path& p, const std::vector<unsigned char>& bytes);

/// A triangle by its corner positions.
using Tri = std::array<Vec3f, 3>;
/// The triangles of `mesh` by corner positions, in its order.
std::vector<Tri> triangles_of(const TriangleMesh& mesh);

/// The message of the kdt::Error that f() throws, or "" when it throws none.
template <class F>
std::string error_of_call(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

// Sanitizers reserve more address space than any RLIMIT_AS allows: tests that cap it skip.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define KDT_NO_ADDRESS_LIMIT 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define KDT_NO_ADDRESS_LIMIT 1
#endif
#endif

/// For a child process only (EXPECT_EXIT): caps the address space at `extra` bytes above what
/// the process uses, runs f(), prints the message of the kdt::Error it throws, if any, to
/// stderr and exits 0; exits 2 when the cap cannot be set.
template <class F>
[[noreturn]] void run_capped(size_t extra, F&& f) {
    long pages = 0;
    if (FILE* file = std::fopen("/proc/self/statm", "r")) {
        if (std::fscanf(file, "%ld", &pages) != 1) pages = 0;
        std::fclose(file);
    }
    const rlim_t limit = rlim_t(pages) * rlim_t(::sysconf(_SC_PAGESIZE)) + rlim_t(extra);
    const rlimit cap{limit, limit};
    if (pages == 0 || ::setrlimit(RLIMIT_AS, &cap) != 0) std::_Exit(2);
    const std::string msg = error_of_call(f);
    if (!msg.empty()) std::fprintf(stderr, "%s\n", msg.c_str());
    std::_Exit(0);
}

/// Seeded SplitMix64 stream for test inputs (not the renderer's sampler): fixed seeds only.
struct HashRng {
    uint64_t state;
    explicit HashRng(uint64_t seed) : state(seed * 0x9e3779b97f4a7c15ull + 0x632be59bd9b4e019ull) {}
    uint64_t next_u64() {
        uint64_t z = (state += 0x9e3779b97f4a7c15ull);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    /// Uniform in [0, 1) with 24 random bits.
    float next() { return float(next_u64() >> 40) * 0x1p-24f; }
    Vec2f next2() { return {next(), next()}; }
};

}  // namespace kdt::test
