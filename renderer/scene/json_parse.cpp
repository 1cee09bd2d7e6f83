#include "renderer/scene/json_parse.h"

#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "renderer/core/error.h"

namespace kdt {
namespace {

using json = nlohmann::json;

/// nlohmann's SAX events, checked (repeated keys, nesting) and passed on to its DOM builder.
/// Not json::parse() with a parser callback: that parser scans the enclosing array or object
/// at every object's end for a value the callback discarded (json_sax.hpp, 3.11.2), so an array
/// of n objects took time in n^2 (100,000 mesh instances: 2.2 s; 3.4 million, 64 MB: 40 min).
class CheckedDomBuilder {
public:
    CheckedDomBuilder(json& root, const std::string& path, const std::string& prefix)
        : dom_(root), path_(path), prefix_(prefix) {}

    bool null() {
        next_element();
        return dom_.null();
    }
    bool boolean(bool v) {
        next_element();
        return dom_.boolean(v);
    }
    bool number_integer(json::number_integer_t v) {
        next_element();
        return dom_.number_integer(v);
    }
    bool number_unsigned(json::number_unsigned_t v) {
        next_element();
        return dom_.number_unsigned(v);
    }
    bool number_float(json::number_float_t v, const json::string_t& s) {
        next_element();
        return dom_.number_float(v, s);
    }
    bool string(json::string_t& v) {
        next_element();
        return dom_.string(v);
    }
    bool binary(json::binary_t& v) {
        next_element();
        return dom_.binary(v);
    }
    bool start_object(std::size_t n) {
        open(false);
        return dom_.start_object(n);
    }
    bool start_array(std::size_t n) {
        open(true);
        return dom_.start_array(n);
    }
    bool end_object() {
        stack_.pop_back();
        return dom_.end_object();
    }
    bool end_array() {
        stack_.pop_back();
        return dom_.end_array();
    }
    bool key(json::string_t& k) {
        Frame& f = stack_.back();
        f.key = k;
        if (!f.keys.insert(f.key).second)
            throw Error(ErrorLocation{path_, where(f.key)}, "repeated key");
        return dom_.key(k);
    }
    /// Throws `ex` as its own type (json::parse_error, json::out_of_range), as json::parse().
    template <class Exception>
    bool parse_error(std::size_t position, const std::string& last_token, const Exception& ex) {
        return dom_.parse_error(position, last_token, ex);
    }

private:
    // One frame per open object or array: an object's keys so far and its current key, or
    // an array's current element index.
    struct Frame {
        bool array = false;
        std::set<std::string> keys;
        std::string key;
        int64_t index = -1;
    };

    // The JSON path of `last` in the innermost open object.
    std::string where(const std::string& last) const {
        std::string s = prefix_;
        for (size_t i = 0; i + 1 < stack_.size(); ++i)
            s += (stack_[i].array ? std::to_string(stack_[i].index) : stack_[i].key) + "/";
        return s + last;
    }
    // An element of an array (object, array or plain value) advances that array's index.
    void next_element() {
        if (!stack_.empty() && stack_.back().array) ++stack_.back().index;
    }
    void open(bool array) {
        next_element();
        stack_.push_back(Frame{array, {}, {}, -1});
        // Before the DOM grows any deeper (json_parse.h).
        if (stack_.size() > kMaxJsonNesting) {
            throw Error(ErrorLocation{path_}, "arrays and objects nested deeper than " +
                                                  std::to_string(kMaxJsonNesting) +
                                                  " levels (not a kdtrace file?)");
        }
    }

    nlohmann::detail::json_sax_dom_parser<json> dom_;
    const std::string& path_;
    const std::string& prefix_;
    std::vector<Frame> stack_;
};

}  // namespace

nlohmann::json parse_json_without_repeats(std::string_view text, const std::string& path,
                                          const std::string& prefix) {
    json root;
    CheckedDomBuilder builder(root, path, prefix);
    // Strict, as json::parse(): the whole text is one value, with at most white space after it.
    json::sax_parse(text.begin(), text.end(), &builder);
    return root;
}

}  // namespace kdt
