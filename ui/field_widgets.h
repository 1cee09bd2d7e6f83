// ImGui widgets generated from the range tables of the option structs (renderer/core/fields.h):
// one widget per field, its label, tooltip, limits and choices read from the table, so a new
// field is a new widget with no code here. Depends on core and Dear ImGui.
#pragma once

#include <span>
#include <string>

#include "renderer/core/error.h"
#include "renderer/core/fields.h"

namespace kdt::ui {

/// Draws the widgets of `fields` for `s` (a slider for a range of at most 10^4, else an input
/// box; a checkbox for a bool; a combo for a choice) and returns whether a value changed. An
/// edit outside the field's range is not applied; its reason goes to *error (named
/// "group.name") and the value stays.
template <class S>
bool field_widgets(const char* group, S& s, std::span<const Field<S>> fields, std::string* error);

/// The widget of one field; the same rules.
template <class S>
bool field_widget(const char* group, S& s, const Field<S>& field, std::string* error);

/// The field of `fields` named `name`, or null.
template <class S>
const Field<S>* find_field(std::span<const Field<S>> fields, const std::string& name) {
    for (const Field<S>& f : fields) {
        if (name == f.name) return &f;
    }
    return nullptr;
}

/// Whether a and b agree in every field of `fields` (as field_text() writes them).
template <class S>
bool same_fields(std::span<const Field<S>> fields, const S& a, const S& b) {
    for (const Field<S>& f : fields) {
        if (field_text(f, a) != field_text(f, b)) return false;
    }
    return true;
}

/// Parses `value` into the field of `fields` named `name`; false when there is none. Throws
/// kdt::Error ("group.name must be ...") for a value the field refuses.
template <class S>
bool set_field(std::span<const Field<S>> fields, S& s, const std::string& group,
               const std::string& name, const std::string& value) {
    const Field<S>* f = find_field(fields, name);
    if (!f) return false;
    if (std::string why = parse_field(*f, s, value); !why.empty())
        throw Error(group + "." + name + " " + why);
    return true;
}

}  // namespace kdt::ui
