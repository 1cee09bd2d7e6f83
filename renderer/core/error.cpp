#include "renderer/core/error.h"

#include <algorithm>
#include <cstdio>

namespace kdt {
namespace {

constexpr char kHex[] = "0123456789abcdef";

void append_hex(std::string& out, unsigned char c) {
    out += "\\x";
    out += kHex[c >> 4];
    out += kHex[c & 15];
}

// Length of the well-formed UTF-8 sequence at s[i] (2 to 4 bytes) and its code point, or 0
// (RFC 3629: no overlong forms, no surrogates, nothing above U+10FFFF).
size_t utf8_sequence(std::string_view s, size_t i, uint32_t& cp) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    size_t n;
    uint32_t min;
    if (c >= 0xc2 && c <= 0xdf) {
        n = 2, cp = c & 0x1fu, min = 0x80;
    } else if (c >= 0xe0 && c <= 0xef) {
        n = 3, cp = c & 0x0fu, min = 0x800;
    } else if (c >= 0xf0 && c <= 0xf4) {
        n = 4, cp = c & 0x07u, min = 0x10000;
    } else {
        return 0;
    }
    if (s.size() - i < n) return 0;
    for (size_t k = 1; k < n; ++k) {
        const unsigned char t = static_cast<unsigned char>(s[i + k]);
        if ((t & 0xc0) != 0x80) return 0;
        cp = (cp << 6) | (t & 0x3fu);
    }
    if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return 0;
    return n;
}

// C1 controls, and format characters that are invisible or reorder the text around them.
bool invisible_control(uint32_t cp) {
    return (cp >= 0x80 && cp <= 0x9f) || cp == 0xad || (cp >= 0x200b && cp <= 0x200f) ||
           (cp >= 0x2028 && cp <= 0x202e) || (cp >= 0x2060 && cp <= 0x206f) || cp == 0xfeff;
}

std::string format(const ErrorLocation& w, const std::string& message) {
    std::string s;
    if (!w.path.empty()) s += excerpt_path(w.path) + ": ";
    if (w.line >= 0) s += "line " + std::to_string(w.line) + ": ";
    if (w.offset >= 0) s += "byte " + std::to_string(w.offset) + ": ";
    if (!w.element.empty()) {
        s += excerpt(w.element, 240);
        if (w.index >= 0) s += " " + std::to_string(w.index);
        s += ": ";
    }
    return s + message;
}

}  // namespace

size_t utf8_length_at(std::string_view text, size_t i) {
    if (static_cast<unsigned char>(text[i]) < 0x80) return 1;
    uint32_t cp = 0;
    return utf8_sequence(text, i, cp);
}

std::string printable(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (size_t i = 0; i < text.size();) {
        const unsigned char c = static_cast<unsigned char>(text[i]);
        if (c >= 0x20 && c < 0x7f) {
            out += char(c);
            ++i;
            continue;
        }
        if (c == '\t' || c == '\n' || c == '\r') {
            out += c == '\t' ? "\\t" : c == '\n' ? "\\n" : "\\r";
            ++i;
            continue;
        }
        uint32_t cp = 0;
        const size_t n = c >= 0x80 ? utf8_sequence(text, i, cp) : 0;
        if (n == 0) {
            append_hex(out, c);
            ++i;
        } else if (invisible_control(cp)) {
            char buf[12];
            std::snprintf(buf, sizeof(buf), "\\u%04x", unsigned(cp));
            out += buf;
            i += n;
        } else {
            out.append(text.substr(i, n));
            i += n;
        }
    }
    return out;
}

namespace {

// The largest cut <= at that does not fall inside a UTF-8 sequence of text.
size_t sequence_boundary(std::string_view text, size_t at) {
    at = std::min(at, text.size());
    while (at > 0 && at < text.size() && (static_cast<unsigned char>(text[at]) & 0xc0) == 0x80)
        --at;
    return at;
}

}  // namespace

std::string excerpt(std::string_view text, size_t max_bytes) {
    if (text.size() <= max_bytes) return printable(text);
    return printable(text.substr(0, sequence_boundary(text, max_bytes))) + "... [" +
           std::to_string(text.size()) + " bytes]";
}

std::string printable_line(std::string_view message, size_t max_bytes) {
    if (message.size() <= max_bytes) return printable(message);
    const size_t head = sequence_boundary(message, max_bytes / 2);
    const size_t tail = sequence_boundary(message, message.size() - max_bytes / 4);
    return printable(message.substr(0, head)) + " ... [" + std::to_string(tail - head) +
           " bytes left out] ... " + printable(message.substr(tail));
}

std::string excerpt_path(std::string_view path, size_t max_bytes) {
    return printable_line(path, max_bytes);
}

Error::Error(ErrorLocation where, const std::string& message)
    : std::runtime_error(format(where, message)), where_(std::move(where)), message_(message) {}

}  // namespace kdt
