// Helpers shared by the test executables: paths to the source tree, shared data, assets.
#pragma once

#include <filesystem>
#include <string>

namespace kdt::test {

/// Root of the source tree.
std::filesystem::path source_dir();
/// ../shared/data next to the repository, or empty when absent (tests then GTEST_SKIP
/// with a message saying so).
std::filesystem::path shared_data_dir();
/// Directory holding the fetched Stanford dragon (scripts/fetch_assets.sh), or empty.
std::filesystem::path dragon_dir();
/// A fresh temporary directory for one test.
std::filesystem::path temp_dir(const std::string& name);

}  // namespace kdt::test
