// Helpers shared by the test executables: paths to the source tree, shared data, assets.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "renderer/core/error.h"
#include "renderer/core/math.h"

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
