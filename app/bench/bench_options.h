// Checks the benches share for their list options (--rows, --configs, --ranks, ...), run
// before any work. Depends on renderer/core/error.h and the standard library.
#pragma once

#include <cstddef>
#include <sstream>
#include <string>
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

}  // namespace kdt::app
