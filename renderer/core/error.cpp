#include "renderer/core/error.h"

namespace kdt {
namespace {

std::string format(const ErrorLocation& w, const std::string& message) {
    std::string s;
    if (!w.path.empty()) s += w.path + ": ";
    if (w.line >= 0) s += "line " + std::to_string(w.line) + ": ";
    if (w.offset >= 0) s += "byte " + std::to_string(w.offset) + ": ";
    if (!w.element.empty()) {
        s += w.element;
        if (w.index >= 0) s += " " + std::to_string(w.index);
        s += ": ";
    }
    return s + message;
}

}  // namespace

Error::Error(ErrorLocation where, const std::string& message)
    : std::runtime_error(format(where, message)), where_(std::move(where)), message_(message) {}

}  // namespace kdt
