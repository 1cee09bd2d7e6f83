// The one error type for bad input: files, flags, scene descriptions, cache files.
// Carries the path and where in it (element, index, line or byte offset).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace kdt {

/// Where in a file an error was found; unset fields are left out of the message.
struct ErrorLocation {
    std::string path;     ///< file name as the user gave it; may be empty (flags)
    std::string element;  ///< e.g. "face", "vertex", "header", a JSON pointer
    int64_t index = -1;   ///< element index, -1 when not applicable
    int64_t line = -1;    ///< 1-based line number for text input, -1 when unknown
    int64_t offset = -1;  ///< byte offset for binary input, -1 when unknown
};

/// Thrown for expected bad input. what() is a complete sentence such as
/// "dragon.ply: face 1203: vertex index 912345 out of range (437645 vertices)".
class Error : public std::runtime_error {
public:
    Error(ErrorLocation where, const std::string& message);
    explicit Error(const std::string& message) : Error(ErrorLocation{}, message) {}

    const ErrorLocation& where() const { return where_; }
    const std::string& message() const { return message_; }

private:
    ErrorLocation where_;
    std::string message_;
};

}  // namespace kdt
