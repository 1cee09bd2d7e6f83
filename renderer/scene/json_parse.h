// JSON text parsed for kdtrace's input files (scene, views and options/session files), with
// a repeated key in any object refused. Depends on core/error.h and nlohmann/json.
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace kdt {

/// Arrays and objects nested deeper than this are refused: kdtrace's files nest 5 deep, and
/// each level costs the parser about 200 bytes, so 40 MB of '[' would take 4 GB.
inline constexpr size_t kMaxJsonNesting = 64;

/// Parses `text` as JSON. A key given twice in one object throws kdt::Error naming `path` and
/// the key's JSON path as `prefix` + the keys and array indices joined by "/", e.g.
/// "s.json: camera/vfov_degrees: repeated key" (prefix "") or "v.json: /views/1/eye: repeated
/// key" (prefix "/"): nlohmann would keep the last value without a word. Nesting deeper than
/// kMaxJsonNesting throws kdt::Error naming `path` as soon as the parser reaches it. Syntax
/// errors are nlohmann's exceptions (json::parse_error, json::out_of_range), which callers report.
nlohmann::json parse_json_without_repeats(std::string_view text, const std::string& path,
                                          const std::string& prefix);

}  // namespace kdt
