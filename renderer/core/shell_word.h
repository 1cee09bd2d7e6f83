// Text for commands that a user pastes into a POSIX shell.
#pragma once

#include <string>
#include <string_view>

namespace kdt {

/// `s` as one shell word: in single quotes, each quote inside written as '\''. Any byte
/// reaches the program as it is (no expansion of $, `, \ or globs).
inline std::string shell_word(std::string_view s) {
    std::string q = "'";
    for (char ch : s) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
    return q + "'";
}

}  // namespace kdt
