// The one error type for bad input: files, flags, scene descriptions, cache files.
// Carries the path and where in it (element, index, line or byte offset).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace kdt {

/// `text` made safe to print inside a message: printable ASCII and well-formed UTF-8 are
/// kept; tab, newline and carriage return become \t, \n, \r; other control bytes (NUL,
/// BEL, ESC, DEL) and bytes that are not valid UTF-8 become \xNN; C1 controls and
/// the invisible Unicode format and bidirectional controls become \uXXXX. So a token echoed
/// from a file can neither drive a terminal nor hide or cut short the rest of the message.
std::string printable(std::string_view text);

/// printable(text) for quoting a value in a message: when text is longer than max_bytes,
/// its first bytes (up to max_bytes, not splitting a UTF-8 sequence) followed by
/// "... [N bytes]", so a megabyte key or value cannot flood the terminal.
std::string excerpt(std::string_view text, size_t max_bytes = 120);

/// printable(message) for a whole message line: when longer than max_bytes, its head and
/// tail (where the reason usually is) around "... [N bytes left out] ...".
std::string printable_line(std::string_view message, size_t max_bytes = 4096);

/// printable(path) for naming a file in a message: when longer than max_bytes, its head and
/// its tail (which holds the file name) around "... [N bytes left out] ...".
std::string excerpt_path(std::string_view path, size_t max_bytes = 240);

/// The length of the well-formed UTF-8 sequence at text[i] (1 for ASCII; RFC 3629: no
/// overlong forms, no surrogates, nothing above U+10FFFF), or 0 when none starts there.
size_t utf8_length_at(std::string_view text, size_t i);

/// Where in a file an error was found; unset fields are left out of the message. The path
/// is shown through excerpt_path(), the element through excerpt().
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
