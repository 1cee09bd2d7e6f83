// Parameter structs described as data: each field's name, command-line flag, one-line help and
// range, read by validation, the CLI, the viewer's widgets and the JSON of image metadata and
// session files alike, so a limit or a default exists in exactly one place (the default is the
// struct's own initialiser). Depends on the standard library only.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <span>
#include <string>
#include <type_traits>
#include <variant>

namespace kdt {

/// An enum field's storage: every parameter enum has uint8_t as its underlying type, so its
/// value is read and written through a byte (char types may alias any object).
struct ChoiceRef {
    uint8_t* value;
};

/// A pointer to one field of one struct instance.
using FieldRef = std::variant<bool*, int*, float*, double*, uint64_t*, ChoiceRef>;

inline FieldRef field_ref(bool& v) { return &v; }
inline FieldRef field_ref(int& v) { return &v; }
inline FieldRef field_ref(float& v) { return &v; }
inline FieldRef field_ref(double& v) { return &v; }
inline FieldRef field_ref(uint64_t& v) { return &v; }
template <class E>
requires std::is_enum_v<E> FieldRef field_ref(E& v) {
    static_assert(std::is_same_v<std::underlying_type_t<E>, uint8_t>,
                  "parameter enums are stored in one byte");
    return ChoiceRef{reinterpret_cast<uint8_t*>(&v)};
}

/// One field of parameter struct S.
template <class S>
struct Field {
    const char* name;               ///< key in JSON and in messages ("max_depth")
    FieldRef (*ref)(S&) = nullptr;  ///< the field in a given instance
    /// Command-line flag ("--path-depth"); nullptr when the field has none. A bool field's
    /// flag sets it to true, unless it starts with "--no-", which sets it to false.
    const char* flag;
    const char* help;             ///< one line
    double min = 0.0, max = 0.0;  ///< inclusive range of numbers (choices: their indices)
    bool min_open = false;        ///< the lower bound itself is excluded: (min, max]
    std::span<const char* const> choices = {};  ///< an enum's names, by value
    /// 0 is valid and means "off" (a stop condition); parse_field() still refuses an explicit
    /// 0 outside the range, since a user who types it means something else.
    bool zero_is_off = false;

    FieldRef at(S& s) const { return ref(s); }
    FieldRef at(const S& s) const { return ref(const_cast<S&>(s)); }  // read through it only
};

/// Defines a Field of struct S for its member `member`.
// clang-format off
#define KDT_FIELD(S, member, ...) \
    ::kdt::Field<S>{#member, [](S& s) { return ::kdt::field_ref(s.member); }, __VA_ARGS__}
// clang-format on

/// The double whose shortest text is the float's shortest text (2.6f -> 2.6, where the plain
/// conversion prints 2.5999999046325684), which reads back as the same float: for writing
/// floats into JSON. Non-finite values pass through.
double float_for_text(float v);

/// The value of a numeric, bool or choice field as a double (a seed only when < 2^53).
double field_number(const FieldRef& ref);
/// Sets a numeric, bool or choice field from a double (rounded toward zero for integers;
/// the caller has range-checked it).
void set_field_number(const FieldRef& ref, double value);
/// The value as text: whole-number fields in digits, other numbers in the shortest form that
/// reads back the same, choices by name, bools as true/false.
template <class S>
std::string field_text(const Field<S>& f, const S& s);
/// "[0, 1024]", "(0, 1]", "one of: box, tent".
template <class S>
std::string field_range_text(const Field<S>& f);

/// Parses text into the field after checking it (numbers: finite, integral where the field
/// is, within range; choices: one of the names; bools: true/false/1/0). Returns an empty
/// string on success, else the reason ("must be in [0, 1024] (got -1)").
template <class S>
std::string parse_field(const Field<S>& f, S& s, const std::string& text);
/// Empty when the field's current value is valid, else the reason as parse_field gives it.
template <class S>
std::string check_field(const Field<S>& f, const S& s);

/// Throws kdt::Error for the first invalid field, naming it as group.name
/// ("trace.max_depth must be in [0, 1024] (got -1)").
template <class S>
void validate_fields(const S& s, std::span<const Field<S>> fields, const char* group);

// ---- implementation

namespace detail {
std::string number_text(double v);
std::string range_text(double min, double max, bool min_open, bool integral);
std::string choices_text(std::span<const char* const> names);
/// "" when v lies in the range, else why not. `as_float`: v is stored as a float, and both v
/// and v rounded to float are compared with the bounds as a float holds them, so that the
/// stated bounds themselves pass and no value within them rounds out of them.
std::string check_number(double v, double min, double max, bool min_open, bool integral,
                         bool as_float = false);
bool parse_number(const std::string& text, double& out);
/// Why parse_number() refused `text`, for a value that must lie in `range` ("[-20, 20]"):
/// "must be a number (got 'x')", or for a number no double holds (1e-400, 1e400) "must be
/// in [-20, 20] (got '1e-400', too close to 0 for a double)".
std::string number_error(const std::string& text, const std::string& range);
void throw_field_error(const char* group, const char* name, const std::string& reason);
/// "(got 'text')" with the text made safe to print.
std::string got(const std::string& text);
}  // namespace detail

inline bool field_is_integral(const FieldRef& r) {
    return std::holds_alternative<int*>(r) || std::holds_alternative<uint64_t*>(r);
}

template <class S>
std::string field_text(const Field<S>& f, const S& s) {
    const FieldRef r = f.at(s);
    if (auto* b = std::get_if<bool*>(&r)) return **b ? "true" : "false";
    if (auto* c = std::get_if<ChoiceRef>(&r)) {
        const size_t i = *c->value;
        return i < f.choices.size() ? f.choices[i] : std::to_string(i);
    }
    if (auto* u = std::get_if<uint64_t*>(&r)) return std::to_string(**u);
    if (auto* i = std::get_if<int*>(&r)) return std::to_string(**i);  // 100000, never 1e+05
    return detail::number_text(field_number(r));
}

template <class S>
std::string field_range_text(const Field<S>& f) {
    S probe{};
    const FieldRef r = f.at(probe);
    if (std::holds_alternative<ChoiceRef>(r)) return detail::choices_text(f.choices);
    if (std::holds_alternative<bool*>(r)) return "true or false";
    return detail::range_text(f.min, f.max, f.min_open, field_is_integral(r));
}

template <class S>
std::string check_field(const Field<S>& f, const S& s) {
    const FieldRef r = f.at(s);
    if (std::holds_alternative<bool*>(r)) return {};
    if (auto* c = std::get_if<ChoiceRef>(&r)) {
        if (*c->value < f.choices.size()) return {};
        return "must be " + detail::choices_text(f.choices) + " (got " + std::to_string(*c->value) +
               ")";
    }
    if (auto* u = std::get_if<uint64_t*>(&r)) {
        // Seeds span all 64 bits; their range is [min, max] only as far as a double says.
        if (double(**u) >= f.min && double(**u) <= f.max) return {};
        return "must be in " + field_range_text(f) + " (got " + std::to_string(**u) + ")";
    }
    if (f.zero_is_off && field_number(r) == 0.0) return {};
    return detail::check_number(field_number(r), f.min, f.max, f.min_open, field_is_integral(r),
                                std::holds_alternative<float*>(r));
}

template <class S>
std::string parse_field(const Field<S>& f, S& s, const std::string& text) {
    const FieldRef r = f.at(s);
    if (auto* b = std::get_if<bool*>(&r)) {
        if (text == "true" || text == "1" || text == "on") return **b = true, std::string();
        if (text == "false" || text == "0" || text == "off") return **b = false, std::string();
        return "must be true or false " + detail::got(text);
    }
    if (auto* c = std::get_if<ChoiceRef>(&r)) {
        for (size_t i = 0; i < f.choices.size(); ++i) {
            if (text == f.choices[i]) return *c->value = uint8_t(i), std::string();
        }
        return "must be " + detail::choices_text(f.choices) + " " + detail::got(text);
    }
    if (auto* u = std::get_if<uint64_t*>(&r)) {
        // Digits only: "-1" must not wrap around to 2^64 - 1, nor "2^64" to 0.
        if (text.empty() || text.size() > 20 || text.find_first_not_of("0123456789") != text.npos)
            return "must be a whole number in " + field_range_text(f) + " " + detail::got(text);
        const unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
        if (text.size() == 20 && text > "18446744073709551615")
            return "must be a whole number in " + field_range_text(f) + " " + detail::got(text);
        const uint64_t old = **u;
        **u = uint64_t(v);
        if (std::string why = check_field(f, s); !why.empty()) return **u = old, why;
        return {};
    }
    double v = 0.0;
    if (!detail::parse_number(text, v)) return detail::number_error(text, field_range_text(f));
    std::string why = detail::check_number(v, f.min, f.max, f.min_open, field_is_integral(r),
                                           std::holds_alternative<float*>(r));
    if (why.empty()) set_field_number(r, v);
    return why;
}

template <class S>
void validate_fields(const S& s, std::span<const Field<S>> fields, const char* group) {
    for (const Field<S>& f : fields) {
        if (std::string why = check_field(f, s); !why.empty())
            detail::throw_field_error(group, f.name, why);
    }
}

}  // namespace kdt
