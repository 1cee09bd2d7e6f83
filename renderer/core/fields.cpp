#include "renderer/core/fields.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "renderer/core/error.h"

namespace kdt {

double field_number(const FieldRef& ref) {
    return std::visit(
        [](auto p) -> double {
            if constexpr (std::is_same_v<decltype(p), ChoiceRef>) {
                return double(*p.value);
            } else {
                return double(*p);
            }
        },
        ref);
}

void set_field_number(const FieldRef& ref, double value) {
    std::visit(
        [value](auto p) {
            if constexpr (std::is_same_v<decltype(p), ChoiceRef>) {
                *p.value = uint8_t(value);
            } else if constexpr (std::is_same_v<decltype(p), bool*>) {
                *p = value != 0.0;
            } else {
                *p = static_cast<std::remove_pointer_t<decltype(p)>>(value);
            }
        },
        ref);
}

double float_for_text(float v) {
    return std::isfinite(v) ? std::stod(detail::number_text(double(v))) : double(v);
}

namespace detail {

std::string number_text(double v) {
    // The shortest text that reads back as the same double; floats widened to double read
    // back exactly too, and print as the float's shortest form when that is shorter.
    char buf[64];
    const float f = float(v);
    if (double(f) == v) {
        auto r = std::to_chars(buf, buf + sizeof buf, f);
        return std::string(buf, r.ptr);
    }
    auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
}

std::string range_text(double min, double max, bool min_open, bool integral) {
    auto text = [integral](double v) {
        if (!integral) return number_text(v);
        if (v >= 18446744073709551615.0) return std::string("18446744073709551615");
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.0f", v);
        return std::string(buf);
    };
    return std::string(min_open ? "(" : "[") + text(min) + ", " + text(max) + "]";
}

std::string choices_text(std::span<const char* const> names) {
    std::string s = "one of: ";
    for (size_t i = 0; i < names.size(); ++i) s += (i ? ", " : "") + std::string(names[i]);
    return s;
}

std::string check_number(double v, double min, double max, bool min_open, bool integral,
                         bool as_float) {
    const std::string range = range_text(min, max, min_open, integral);
    // A whole number as typed (100000, not 1e+05) where the option takes whole numbers.
    const auto shown = [integral](double x) {
        if (!integral || x != std::trunc(x) || !(std::fabs(x) < 1e18)) return number_text(x);
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.0f", x);
        return std::string(buf);
    };
    if (!std::isfinite(v))
        return "must be a finite number in " + range + " (got " + number_text(v) + ")";
    // A float field holds its bounds rounded to float (3e38 is 3.0000000055e38 there).
    const double lo = as_float ? double(float(min)) : min, hi = as_float ? double(float(max)) : max;
    const bool below = min_open ? !(v > lo) : !(v >= lo);
    if (below || !(v <= hi)) return "must be in " + range + " (got " + shown(v) + ")";
    // A value within the bounds can still round out of them as a float: 1e-50 to 0 (which a
    // stop condition would read as off), 179.999999999 to 180.
    if (as_float) {
        const double f = double(float(v));
        if ((min_open ? !(f > lo) : !(f >= lo)) || !(f <= hi)) {
            return "must be in " + range + " (got " + number_text(v) + ", which is " +
                   number_text(f) + " as a float)";
        }
    }
    if (integral && v != std::trunc(v))
        return "must be a whole number in " + range + " (got " + number_text(v) + ")";
    return {};
}

bool parse_number(const std::string& text, double& out) {
    if (text.empty()) return false;
    const char* begin = text.data();
    const char* end = text.data() + text.size();
    if (*begin == '+') ++begin;
    auto r = std::from_chars(begin, end, out);
    return r.ec == std::errc() && r.ptr == end;
}

std::string number_error(const std::string& text, const std::string& range) {
    const char* begin = text.data();
    const char* end = text.data() + text.size();
    if (begin != end && *begin == '+') ++begin;
    double unused = 0.0;
    const auto r = std::from_chars(begin, end, unused);
    if (r.ec != std::errc::result_out_of_range || r.ptr != end || begin == end)
        return "must be a number " + got(text);
    // from_chars leaves the value unset when out of range; strtod says which way it went.
    const double v = std::strtod(std::string(begin, end).c_str(), nullptr);
    return "must be in " + range + " (got '" + excerpt(text) + "', " +
           (std::fabs(v) < 1.0 ? "too close to 0" : "too large") + " for a double)";
}

void throw_field_error(const char* group, const char* name, const std::string& reason) {
    throw Error(std::string(group) + "." + name + " " + reason);
}

std::string got(const std::string& text) { return "(got '" + excerpt(text) + "')"; }

}  // namespace detail

}  // namespace kdt
