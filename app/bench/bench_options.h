// Checks the benches share for their list options (--rows, --configs, --ranks, ...) and
// output directories, run before any work. Depends on renderer/core/error.h and the
// standard library.
#pragma once

#include <cstddef>
#include <filesystem>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "renderer/core/error.h"

namespace kdt::app {

/// Throws Error naming `option` and the entry when an entry of `entries` is given twice: each
/// entry makes its own row, and a row run twice measures nothing new while the ratios between
/// the copies read as results. `entries` is streamed with operator<< for the message.
template <class T>
void refuse_repeated_entries(const std::string& option, const std::vector<T>& entries) {
    for (size_t i = 1; i < entries.size(); ++i) {
        for (size_t j = 0; j < i; ++j) {
            if (!(entries[i] == entries[j])) continue;
            std::ostringstream entry;
            entry << entries[i];
            throw Error(ErrorLocation{option}, "'" + entry.str() + "' is given twice");
        }
    }
}

/// Creates `dir`, the output directory given by `flag`, and its parents, unless it exists.
/// Throws Error naming the flag, the directory and the reason ("-o /proc/x: cannot create
/// the directory: No such file or directory"), not the library's bare filesystem_error.
inline void create_output_directory(const std::string& flag, const std::string& dir) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::is_directory(dir, ec)) return;
    if (fs::exists(fs::symlink_status(dir, ec)))
        throw Error(flag + " " + printable(dir) + ": exists and is not a directory");
    fs::create_directories(dir, ec);
    if (ec)
        throw Error(flag + " " + printable(dir) + ": cannot create the directory: " + ec.message());
}

}  // namespace kdt::app
