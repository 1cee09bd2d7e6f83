#include "renderer/scene/json_parse.h"

#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "renderer/core/error.h"

namespace kdt {

nlohmann::json parse_json_without_repeats(std::string_view text, const std::string& path,
                                          const std::string& prefix) {
    using json = nlohmann::json;
    // One frame per open object or array: an object's keys so far and its current key, or
    // an array's current element index.
    struct Frame {
        bool array = false;
        std::set<std::string> keys;
        std::string key;
        int64_t index = -1;
    };
    std::vector<Frame> stack;
    auto where = [&](const std::string& last) {
        std::string s = prefix;
        for (const Frame& f : stack) {
            if (&f == &stack.back()) break;
            s += (f.array ? std::to_string(f.index) : f.key) + "/";
        }
        return s + last;
    };
    // An element of an array (object, array or plain value) advances that array's index.
    auto next_element = [&stack] {
        if (!stack.empty() && stack.back().array) ++stack.back().index;
    };
    const json::parser_callback_t callback = [&](int /*depth*/, json::parse_event_t event,
                                                 json& parsed) {
        switch (event) {
            case json::parse_event_t::object_start:
            case json::parse_event_t::array_start:
                next_element();
                stack.push_back(Frame{event == json::parse_event_t::array_start, {}, {}, -1});
                // Before the parser builds any deeper (json_parse.h).
                if (stack.size() > kMaxJsonNesting) {
                    throw Error(ErrorLocation{path}, "arrays and objects nested deeper than " +
                                                         std::to_string(kMaxJsonNesting) +
                                                         " levels (not a kdtrace file?)");
                }
                break;
            case json::parse_event_t::object_end:
            case json::parse_event_t::array_end:
                if (!stack.empty()) stack.pop_back();
                break;
            case json::parse_event_t::key: {
                Frame& f = stack.back();
                f.key = parsed.get<std::string>();
                if (!f.keys.insert(f.key).second)
                    throw Error(ErrorLocation{path, where(f.key)}, "repeated key");
                break;
            }
            case json::parse_event_t::value:
                next_element();
                break;
        }
        return true;
    };
    return json::parse(text.begin(), text.end(), callback);
}

}  // namespace kdt
